//! Reading a recording from something whose size is not known beforehand: standard
//! input, a pipe, a device.
//!
//! A regular file's size is on the disk, so it is read whole. A stream can be endless
//! (`/dev/zero`, `yes |`), so it is read in steps that each look before they read
//! more: the magic number first (a stream that is neither a `.npy` nor a `.npz` stops
//! after a dozen bytes), then a `.npy` header and exactly the data its shape claims,
//! and an archive up to [`STREAM_BUDGET_BYTES`].

use std::io::Read;

use super::{npy, npz, RecordingError, MEMBER_BUDGET_BYTES};

/// The most bytes read from a stream for one recording: the budget of an archive entry
/// (512 MiB, eleven hours of the paper's sleeve at 20 Hz), since an archive or a `.npy`
/// holding more could not be loaded from a file either.
pub const STREAM_BUDGET_BYTES: u64 = MEMBER_BUDGET_BYTES;

/// Reads the bytes of one recording from `reader`, bounded as the module says; `name`
/// is used in errors. What comes back is handed to the parser, which names any
/// problem the bytes still have (a bad magic number, a short body).
pub(super) fn read_bounded(name: &str, reader: &mut dyn Read) -> Result<Vec<u8>, RecordingError> {
    let io = |source| RecordingError::Io {
        name: name.to_owned(),
        source,
    };
    let mut bytes = Vec::new();
    read_up_to(reader, &mut bytes, npy::PREAMBLE_LEN as u64).map_err(io)?;
    if npz::is_zip(&bytes) {
        // The directory is at the end: the whole archive is needed, up to the budget.
        read_up_to(reader, &mut bytes, STREAM_BUDGET_BYTES + 1).map_err(io)?;
        if bytes.len() as u64 > STREAM_BUDGET_BYTES {
            return Err(too_long(name));
        }
        return Ok(bytes);
    }
    if !bytes.starts_with(npy::MAGIC) {
        return Ok(bytes);
    }
    let Ok((_, end)) = npy::header_extent(name, &bytes) else {
        return Ok(bytes);
    };
    read_up_to(reader, &mut bytes, end as u64).map_err(io)?;
    let Ok(header) = npy::parse_header(name, &bytes) else {
        return Ok(bytes);
    };
    let Some(total) = header
        .data_len()
        .and_then(|len| len.checked_add(header.data_start as u64))
    else {
        return Ok(bytes);
    };
    if total > STREAM_BUDGET_BYTES {
        return Err(RecordingError::StreamClaimTooLarge {
            name: name.to_owned(),
            shape: header.shape.clone(),
            needed: total,
            budget: STREAM_BUDGET_BYTES,
        });
    }
    // One byte past the claim, so that data after it is reported as such.
    read_up_to(reader, &mut bytes, total + 1).map_err(io)?;
    Ok(bytes)
}

fn too_long(name: &str) -> RecordingError {
    RecordingError::StreamTooLong {
        name: name.to_owned(),
        budget: STREAM_BUDGET_BYTES,
    }
}

/// Reads from `reader` until `bytes` holds `total` bytes or the stream ends.
fn read_up_to(reader: &mut dyn Read, bytes: &mut Vec<u8>, total: u64) -> std::io::Result<()> {
    let more = total.saturating_sub(bytes.len() as u64);
    reader.take(more).read_to_end(bytes)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reader that never ends and counts what it gave.
    struct Endless {
        byte: u8,
        given: u64,
    }

    impl Read for Endless {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            buf.fill(self.byte);
            self.given += buf.len() as u64;
            Ok(buf.len())
        }
    }

    #[test]
    fn an_endless_stream_without_a_magic_number_stops_after_the_preamble() {
        let mut zero = Endless { byte: 0, given: 0 };
        let bytes = read_bounded("zeros", &mut zero).unwrap();
        assert_eq!(bytes.len(), npy::PREAMBLE_LEN);
        assert!(zero.given < 1 << 20, "{}", zero.given);
    }

    #[test]
    fn a_header_is_followed_by_the_data_it_claims_and_one_byte_more() {
        let header = b"{'descr': '<f4', 'fortran_order': False, 'shape': (3, 2, 2), }";
        let mut file = b"\x93NUMPY\x01\x00".to_vec();
        file.extend_from_slice(&(header.len() as u16).to_le_bytes());
        file.extend_from_slice(header);
        let data_start = file.len();
        let mut stream = std::io::Cursor::new(file).chain(Endless { byte: 0, given: 0 });
        let bytes = read_bounded("s", &mut stream).unwrap();
        assert_eq!(bytes.len(), data_start + 3 * 2 * 2 * 4 + 1);
    }

    #[test]
    fn a_claim_beyond_the_budget_is_refused_before_the_data_is_read() {
        let header = b"{'descr': '<f8', 'fortran_order': False, 'shape': (100000000, 8, 21), }";
        let mut file = b"\x93NUMPY\x01\x00".to_vec();
        file.extend_from_slice(&(header.len() as u16).to_le_bytes());
        file.extend_from_slice(header);
        let mut stream = std::io::Cursor::new(file).chain(Endless { byte: 0, given: 0 });
        let err = read_bounded("s", &mut stream).unwrap_err();
        assert!(
            matches!(err, RecordingError::StreamClaimTooLarge { .. }),
            "{err}"
        );
    }
}
