//! The framing shared by stimulus and bank files: magic, version, length, CRC.
//!
//! ```text
//! offset  size  field
//! 0       4     magic (b"TCHS" stimulus, b"TCHB" bank)
//! 4       2     format version, u16 little-endian
//! 6       4     total length in bytes including this prefix and the CRC, u32 LE
//! 10      n     payload (format-specific)
//! len-4   4     CRC-32/ISO-HDLC (zlib's) of bytes [0, len-4), u32 LE
//! ```
//!
//! The length makes a container self-delimiting, so a bank can be read straight
//! out of a flash region larger than itself, and stimuli can be nested in a bank.

use crate::Error;

/// Bytes before the payload.
pub const PREFIX_LEN: usize = 10;
/// Bytes of the trailing CRC.
pub const CRC_LEN: usize = 4;

const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// CRC-32/ISO-HDLC (the zlib and PNG CRC) of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    CRC32.checksum(bytes)
}

/// [`crc32`] of `bytes` following `state`: the running register, `!0` before the
/// first bytes; the CRC of everything fed is `!state` at the end. For a CRC over
/// pieces held apart (a bank's head in RAM and its body in flash, frames of codes
/// as they are played): `!crc32_update(crc32_update(!0, a), b) == crc32(a ++ b)`.
pub fn crc32_update(state: u32, bytes: &[u8]) -> u32 {
    // The crate's register runs reflected for this reflected algorithm, and its
    // digest reflects the initial value it is given.
    let mut d = CRC32.digest_with_initial(state.reverse_bits());
    d.update(bytes);
    !d.finalize()
}

/// [`crc32`] at compile time.
pub(crate) const fn crc32_const(bytes: &[u8]) -> u32 {
    CRC32.checksum(bytes)
}

/// A verified container: the whole byte range and its payload.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Container<'a> {
    /// Exactly the container's bytes, prefix to CRC.
    pub bytes: &'a [u8],
    /// The payload between the prefix and the CRC.
    pub payload: &'a [u8],
}

fn le_u16(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

fn le_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Checks magic, length, CRC and version in that order, so that a corrupted file
/// is reported as corrupted even when the damage hit the version field.
pub(crate) fn open<'a>(
    bytes: &'a [u8],
    magic: [u8; 4],
    version: u16,
) -> Result<Container<'a>, Error> {
    let available = u32::try_from(bytes.len()).unwrap_or(u32::MAX);
    let min = (PREFIX_LEN + CRC_LEN) as u32;
    if available < 4 {
        return Err(Error::Truncated {
            needed: min,
            available,
        });
    }
    let found = [bytes[0], bytes[1], bytes[2], bytes[3]];
    if found != magic {
        return Err(Error::BadMagic {
            expected: magic,
            found,
        });
    }
    if available < min {
        return Err(Error::Truncated {
            needed: min,
            available,
        });
    }
    let len = le_u32(bytes, 6);
    if len < min {
        return Err(Error::BadLength(len));
    }
    if len > available {
        return Err(Error::Truncated {
            needed: len,
            available,
        });
    }
    let bytes = &bytes[..len as usize];
    let body_end = bytes.len() - CRC_LEN;
    let stored = le_u32(bytes, body_end);
    let computed = crc32(&bytes[..body_end]);
    if stored != computed {
        return Err(Error::BadCrc { stored, computed });
    }
    let found = le_u16(bytes, 4);
    if found != version {
        return Err(Error::UnsupportedVersion {
            found,
            supported: version,
        });
    }
    Ok(Container {
        bytes,
        payload: &bytes[PREFIX_LEN..body_end],
    })
}

/// The framing of bytes that [`open`] already accepted (inside a validated bank):
/// length only, no CRC. Still never indexes out of bounds.
pub(crate) fn open_unchecked(bytes: &[u8]) -> Result<Container<'_>, Error> {
    let min = PREFIX_LEN + CRC_LEN;
    let len = if bytes.len() >= min {
        le_u32(bytes, 6) as usize
    } else {
        0
    };
    if len < min || len > bytes.len() {
        return Err(Error::BadLength(len as u32));
    }
    Ok(Container {
        bytes: &bytes[..len],
        payload: &bytes[PREFIX_LEN..len - CRC_LEN],
    })
}

/// Wraps `payload` in a container with the given magic and version (also for tests
/// and fuzzers that craft payloads an encoder would not write).
#[cfg(any(test, feature = "std"))]
pub fn seal(magic: [u8; 4], version: u16, payload: &[u8]) -> Result<Vec<u8>, Error> {
    let len = u32::try_from(PREFIX_LEN + payload.len() + CRC_LEN).map_err(|_| Error::TooLarge)?;
    let mut out = Vec::with_capacity(len as usize);
    out.extend_from_slice(&magic);
    out.extend_from_slice(&version.to_le_bytes());
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(payload);
    let crc = crc32(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_is_zlibs() {
        // The check value of CRC-32/ISO-HDLC.
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn crc_runs_over_pieces() {
        assert_eq!(!crc32_update(!0, b"123456789"), 0xCBF4_3926);
        let whole = b"a bank's head, then its body";
        for cut in 0..=whole.len() {
            let (a, b) = whole.split_at(cut);
            assert_eq!(
                !crc32_update(crc32_update(!0, a), b),
                crc32(whole),
                "cut at {cut}"
            );
        }
        assert_eq!(!crc32_update(!0, b""), crc32(b""));
    }

    #[test]
    fn checks_run_in_order() {
        let sealed = seal(*b"TEST", 3, b"abc").unwrap();
        assert!(open(&sealed, *b"TEST", 3).is_ok());
        assert!(matches!(
            open(&sealed, *b"NOPE", 3),
            Err(Error::BadMagic { .. })
        ));
        assert!(matches!(
            open(&sealed, *b"TEST", 4),
            Err(Error::UnsupportedVersion {
                found: 3,
                supported: 4
            })
        ));
        let mut bad = sealed.clone();
        bad[4] ^= 1; // damage to the version is corruption, not a new version
        assert!(matches!(open(&bad, *b"TEST", 3), Err(Error::BadCrc { .. })));
        assert!(matches!(
            open(&sealed[..sealed.len() - 1], *b"TEST", 3),
            Err(Error::Truncated { .. })
        ));
        // Trailing bytes after a container (flash padding) are ignored.
        let mut padded = sealed.clone();
        padded.extend_from_slice(&[0xFF; 7]);
        assert_eq!(open(&padded, *b"TEST", 3).unwrap().bytes, &sealed[..]);
    }
}
