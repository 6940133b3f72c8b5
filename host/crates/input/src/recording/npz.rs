//! The `.npz` format: a zip archive of `.npy` entries, as numpy's `savez` and
//! `savez_compressed` write it (stored or deflated, zip64 extra fields included).
//!
//! An entry is never inflated past what its own `.npy` header says it needs: the
//! header is read first (at most [`npy::MAX_HEADER_LEN`] bytes), the size it needs must
//! be within [`MEMBER_BUDGET_BYTES`] and equal the size the archive declares, and the
//! data is read through a limit one byte above that, in pieces whose memory is asked
//! for fallibly: a zip bomb is refused after at most one extra byte, and memory grows
//! with the bytes that really arrive, not with what any field claims.
//!
//! The zip reader looks for the end-of-central-directory record from the end of the
//! file, trying every candidate until one leads to a directory, each try a scan of the
//! file: an archive crafted with thousands of such records takes quadratic time. numpy
//! writes one; an archive with more than [`MAX_END_RECORDS`] (a count taken in one
//! pass) is refused before the zip reader sees it.

use std::io::{Cursor, Read};

use ndarray::Array3;
use zip::ZipArchive;

use super::npy::{self, Header};
use super::{RecordingError, MEMBER_BUDGET_BYTES};

/// The start of a zip archive: a local file header, or the end record of an empty one.
pub(super) fn is_zip(bytes: &[u8]) -> bool {
    bytes.starts_with(b"PK\x03\x04") || bytes.starts_with(b"PK\x05\x06")
}

/// What a `.npz` recording holds.
pub(super) struct Npz {
    pub pressure: Array3<f64>,
    pub rate_hz: Option<f64>,
    pub pitch_mm: Option<f64>,
}

type Archive<'a> = ZipArchive<Cursor<&'a [u8]>>;

fn not_npz(name: &str, detail: impl std::fmt::Display) -> RecordingError {
    RecordingError::NotNpz {
        name: name.to_owned(),
        detail: detail.to_string(),
    }
}

/// The most end-of-central-directory signatures an archive may hold: numpy writes one;
/// the rest allows for the 4-byte signature turning up by chance in an entry's data
/// (about once in 4 GB of random bytes).
pub(crate) const MAX_END_RECORDS: usize = 16;

/// End-of-central-directory signatures in `bytes`, counted up to one past
/// [`MAX_END_RECORDS`], in one pass.
fn end_records(bytes: &[u8]) -> usize {
    const SIG: &[u8; 4] = b"PK\x05\x06";
    let mut found = 0;
    let mut at = 0;
    while found <= MAX_END_RECORDS {
        // The signature's first byte, then the other three.
        match bytes[at..].iter().position(|&b| b == SIG[0]) {
            Some(i) => {
                at += i;
                if bytes[at..].starts_with(SIG) {
                    found += 1;
                }
                at += 1;
            }
            None => break,
        }
    }
    found
}

/// The archive, once [`end_records`] has found it plausible.
fn open<'a>(name: &str, bytes: &'a [u8]) -> Result<Archive<'a>, RecordingError> {
    let found = end_records(bytes);
    if found > MAX_END_RECORDS {
        return Err(RecordingError::EndRecords {
            name: name.to_owned(),
            found,
        });
    }
    ZipArchive::new(Cursor::new(bytes)).map_err(|e| not_npz(name, e))
}

/// Reads the archive: `pressure` (required), then the optional scalars. The scalars
/// come first, so a bad one is reported before a large array is inflated.
pub(super) fn read(name: &str, bytes: &[u8]) -> Result<Npz, RecordingError> {
    let mut zip = open(name, bytes)?;
    let Some(pressure) = find(&zip, "pressure") else {
        const SHOWN: usize = 8;
        let mut names: Vec<String> = zip
            .file_names()
            .take(SHOWN)
            .map(|n| format!("{n:?}"))
            .collect();
        if zip.len() > SHOWN {
            names.push(format!("{} more", zip.len() - SHOWN));
        }
        return Err(RecordingError::MissingPressure {
            name: name.to_owned(),
            found: if names.is_empty() {
                "no entries".to_owned()
            } else {
                names.join(", ")
            },
        });
    };
    let rate_hz = scalar(name, &mut zip, "rate_hz")?;
    let pitch_mm = scalar(name, &mut zip, "pitch_mm")?;
    let (label, header, body) = entry(name, &mut zip, pressure, |label, h| {
        npy::pressure_shape(label, h).map(|_| ())
    })?;
    Ok(Npz {
        pressure: npy::pressure(&label, &header, &body)?,
        rate_hz,
        pitch_mm,
    })
}

/// The entry numpy's `np.load(f)[key]` reads: one named exactly `key`, else `key.npy`
/// (the name `savez` writes).
fn find(zip: &Archive<'_>, key: &str) -> Option<usize> {
    zip.index_for_name(key)
        .or_else(|| zip.index_for_name(&format!("{key}.npy")))
}

/// An optional scalar: any float or integer type, one element (0-d, or of shape
/// `(1,)`, `(1, 1)`...). Its range is checked with the rest of the recording.
fn scalar(
    name: &str,
    zip: &mut Archive<'_>,
    field: &'static str,
) -> Result<Option<f64>, RecordingError> {
    let Some(index) = find(zip, field) else {
        return Ok(None);
    };
    let bad = |found: String| RecordingError::BadMetadata {
        name: name.to_owned(),
        field,
        found,
    };
    let (_, header, body) = entry(name, zip, index, |_, h| match &h.dtype {
        Ok(_) if h.shape.iter().all(|&d| d == 1) => Ok(()),
        Ok(d) => Err(bad(format!("shape {} of {}", h.shape_str(), d.descr))),
        Err(descr) => Err(bad(format!("element type {descr}"))),
    })?;
    let value = match &header.dtype {
        Ok(d) => npy::to_f64(d, &body).first().copied(),
        Err(_) => None,
    };
    value
        .map(Some)
        .ok_or_else(|| bad(format!("{} data bytes", body.len())))
}

/// Reads entry `index`: its header, which `accept` must approve, then exactly the
/// data bytes that header needs (fewer if the entry is short; the caller's length
/// check reports that). Returns the label used in messages ("file, entry ..."), the
/// header and the data.
fn entry(
    name: &str,
    zip: &mut Archive<'_>,
    index: usize,
    accept: impl FnOnce(&str, &Header) -> Result<(), RecordingError>,
) -> Result<(String, Header, Vec<u8>), RecordingError> {
    let mut file = zip.by_index(index).map_err(|e| not_npz(name, e))?;
    let entry = file.name().to_owned();
    let label = format!("{name}, entry {entry:?}");
    let declared = file.size();
    let read_err = |e: std::io::Error| not_npz(name, format_args!("entry {entry:?}: {e}"));
    let mut head = Vec::new();
    (&mut file)
        .take(npy::PREAMBLE_LEN as u64)
        .read_to_end(&mut head)
        .map_err(read_err)?;
    let (_, end) = npy::header_extent(&label, &head)?;
    let more = end.saturating_sub(head.len()) as u64;
    (&mut file)
        .take(more)
        .read_to_end(&mut head)
        .map_err(read_err)?;
    let header = npy::parse_header(&label, &head)?;
    accept(&label, &header)?;
    let data_len = header.data_len().ok_or_else(|| RecordingError::TooLarge {
        name: label.clone(),
        shape: header.shape.clone(),
        descr: header
            .dtype
            .as_ref()
            .map_or_else(Clone::clone, |d| d.descr.clone()),
    })?;
    let needed = (header.data_start as u64).saturating_add(data_len);
    if needed > MEMBER_BUDGET_BYTES {
        return Err(RecordingError::MemberTooLarge {
            name: name.to_owned(),
            entry,
            needed,
            budget: MEMBER_BUDGET_BYTES,
        });
    }
    if declared != needed {
        return Err(RecordingError::EntrySize {
            name: name.to_owned(),
            entry,
            declared,
            needed,
        });
    }
    // A header shorter than the preamble leaves data bytes in `head`.
    let mut body = head.split_off(header.data_start.min(head.len()));
    let limit = data_len.saturating_add(1).saturating_sub(body.len() as u64);
    read_fallibly(&mut (&mut file).take(limit), &mut body)
        .map_err(read_err)?
        .map_err(|read| RecordingError::OutOfMemory {
            name: name.to_owned(),
            entry: entry.clone(),
            read,
            needed,
        })?;
    if body.len() as u64 > data_len {
        return Err(RecordingError::Inflated {
            name: name.to_owned(),
            entry,
            needed,
        });
    }
    Ok((label, header, body))
}

/// Reads `from` to its end into `into`, growing it a piece at a time with fallible
/// allocation (never by a size anyone declared): `Ok(Err(bytes read))` when memory
/// for the next piece cannot be had.
fn read_fallibly(from: &mut impl Read, into: &mut Vec<u8>) -> std::io::Result<Result<(), u64>> {
    const PIECE: usize = 1 << 20;
    loop {
        if into.capacity() - into.len() < PIECE {
            // Doubling, as `Vec` grows, but asked for: a refusal is an error, not an abort.
            let more = into.len().max(PIECE);
            if into.try_reserve_exact(more).is_err() {
                return Ok(Err(into.len() as u64));
            }
        }
        let start = into.len();
        let room = (into.capacity() - start).min(PIECE);
        into.resize(start + room, 0);
        let n = loop {
            match from.read(&mut into[start..]) {
                Ok(n) => break n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    into.truncate(start);
                    return Err(e);
                }
            }
        };
        into.truncate(start + n);
        if n == 0 {
            return Ok(Ok(()));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reader that counts the bytes read from it.
    struct Counted<'a> {
        inner: Cursor<&'a [u8]>,
        read: u64,
    }

    impl Read for Counted<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let n = self.inner.read(buf)?;
            self.read += n as u64;
            Ok(n)
        }
    }

    impl std::io::Seek for Counted<'_> {
        fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
            self.inner.seek(pos)
        }
    }

    /// A local header, then `n` end records that each claim one entry at offset 0,
    /// where no directory is: each candidate makes the zip reader scan the file.
    fn end_record_bomb(n: usize) -> Vec<u8> {
        let mut v = b"PK\x03\x04".to_vec();
        v.extend_from_slice(&[20, 0, 0, 0, 0, 0, 0, 0, 0x21, 0]);
        v.extend_from_slice(&[0; 16]);
        for _ in 0..n {
            v.extend_from_slice(b"PK\x05\x06");
            v.extend_from_slice(&[0, 0, 0, 0, 1, 0, 1, 0, 46, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
        }
        v
    }

    /// The zip reader on its own reads the crafted file once per end record (quadratic);
    /// the count refuses it after one pass. Bytes read, not seconds, are the measure.
    #[test]
    fn many_end_records_are_refused_in_one_pass() {
        let bytes = end_record_bomb(2_000);
        let mut counted = Counted {
            inner: Cursor::new(&bytes),
            read: 0,
        };
        assert!(ZipArchive::new(&mut counted).is_err());
        let len = bytes.len() as u64;
        assert!(
            counted.read > 100 * len,
            "the zip reader read {} bytes",
            counted.read
        );
        assert_eq!(end_records(&bytes), MAX_END_RECORDS + 1);
        assert!(matches!(
            open("bomb.npz", &bytes),
            Err(RecordingError::EndRecords { found, .. }) if found == MAX_END_RECORDS + 1
        ));
        // A few records are tried as before.
        assert!(matches!(
            open("few.npz", &end_record_bomb(3)),
            Err(RecordingError::NotNpz { .. })
        ));
    }

    #[test]
    fn reading_fallibly_reads_everything_in_pieces() {
        let data: Vec<u8> = (0..3_000_000u32).map(|i| i as u8).collect();
        let mut into = b"head".to_vec();
        read_fallibly(&mut Cursor::new(&data[..]), &mut into)
            .unwrap()
            .unwrap();
        assert_eq!(&into[..4], b"head");
        assert_eq!(&into[4..], &data[..]);
    }
}
