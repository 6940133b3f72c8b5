//! The `.npz` format: a zip archive of `.npy` entries, as numpy's `savez` and
//! `savez_compressed` write it (stored or deflated, zip64 extra fields included).
//!
//! An entry is never inflated past what its own `.npy` header says it needs: the
//! header is read first (at most [`npy::MAX_HEADER_LEN`] bytes), the size the archive
//! declares must equal the size the header needs, and the data is read through a limit
//! one byte above that, so a zip bomb is refused after at most one extra byte, and
//! memory grows with the bytes that really arrive, not with what any field claims.

use std::io::{Cursor, Read};

use ndarray::Array3;
use zip::ZipArchive;

use super::npy::{self, Header};
use super::RecordingError;

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

/// Reads the archive: `pressure` (required), then the optional scalars. The scalars
/// come first, so a bad one is reported before a large array is inflated.
pub(super) fn read(name: &str, bytes: &[u8]) -> Result<Npz, RecordingError> {
    let mut zip = ZipArchive::new(Cursor::new(bytes)).map_err(|e| not_npz(name, e))?;
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

/// The entry numpy writes for `key` (`key.npy`), or one named plainly `key`.
fn find(zip: &Archive<'_>, key: &str) -> Option<usize> {
    zip.index_for_name(&format!("{key}.npy"))
        .or_else(|| zip.index_for_name(key))
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
    (&mut file)
        .take(limit)
        .read_to_end(&mut body)
        .map_err(read_err)?;
    if body.len() as u64 > data_len {
        return Err(RecordingError::Inflated {
            name: name.to_owned(),
            entry,
            needed,
        });
    }
    Ok((label, header, body))
}
