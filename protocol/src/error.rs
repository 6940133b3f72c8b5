//! The one error type of the protocol crate.

use core::fmt;

/// Why a stimulus or bank was refused, or could not be encoded.
///
/// Each variant names the check that failed, so a user (or the firmware's LED
/// code) can tell a corrupted file from one written by a newer compiler.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// Fewer bytes than the fixed prefix and the CRC, or than the length field says.
    Truncated {
        /// Bytes the container needs.
        needed: u32,
        /// Bytes that were there.
        available: u32,
    },
    /// The first four bytes are not the expected magic: not a stimulus (or not a bank).
    BadMagic {
        /// The magic that was expected.
        expected: [u8; 4],
        /// The bytes found instead.
        found: [u8; 4],
    },
    /// The length field is smaller than the smallest valid container.
    BadLength(u32),
    /// The CRC-32 stored at the end does not match the contents: the file is corrupted.
    BadCrc {
        /// CRC stored in the file.
        stored: u32,
        /// CRC computed over the contents.
        computed: u32,
    },
    /// A format version this build does not know (written by a newer compiler).
    UnsupportedVersion {
        /// Version found in the file.
        found: u16,
        /// Version this build reads.
        supported: u16,
    },
    /// The postcard header could not be decoded.
    BadHeader,
    /// A header field is outside its allowed range; the string names the field.
    InvalidField(&'static str),
    /// The keyframe body ended early, or a residual is not a valid varint.
    BadKeyframes,
    /// A keyframe value left the 16-bit range, or a residual of zero was encoded (non-canonical).
    KeyframeOutOfRange,
    /// Bytes remain between the last keyframe (or bank entry) and the CRC.
    TrailingBytes,
    /// A bank index entry does not give its stimulus's place: the stimuli follow the
    /// index back to back, each entry giving the offset where the previous one ended
    /// (the first, the end of the index) and the stimulus's exact length, before the CRC.
    BadIndex(u16),
    /// The requested bank slot does not exist.
    NoSuchSlot(u16),
    /// Too many keyframes, slots or bytes for the format's fields.
    TooLarge,
    /// The stimulus was compiled for another actuator layout than the target's.
    WrongLayout {
        /// The stimulus's (or bank's) layout geometry hash.
        found: u32,
        /// The target's (the bank's, the firmware's).
        expected: u32,
    },
    /// More slots than a bank holds.
    TooManySlots {
        /// Slots asked for.
        count: u32,
        /// [`crate::bank::MAX_SLOTS`].
        max: u16,
    },
    /// The bank image does not fit the sleeve's bank flash region.
    BankTooLarge {
        /// Bytes of the image.
        bytes: u32,
        /// [`crate::bank::REGION_LEN`].
        limit: u32,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Error::Truncated { needed, available } => {
                write!(f, "truncated: needs {needed} bytes, has {available}")
            }
            Error::BadMagic { expected, found } => write!(
                f,
                "bad magic: expected {:?}, found {:?}",
                Bytes(&expected),
                Bytes(&found)
            ),
            Error::BadLength(len) => write!(f, "length field {len} is too small to be valid"),
            Error::BadCrc { stored, computed } => write!(
                f,
                "bad CRC-32: stored {stored:#010x}, contents give {computed:#010x} (corrupted)"
            ),
            Error::UnsupportedVersion { found, supported } => write!(
                f,
                "unsupported format version {found} (this build reads version {supported})"
            ),
            Error::BadHeader => write!(f, "header does not decode"),
            Error::InvalidField(name) => write!(f, "header field `{name}` is out of range"),
            Error::BadKeyframes => write!(f, "keyframe data is truncated or malformed"),
            Error::KeyframeOutOfRange => {
                write!(f, "keyframe value out of range or non-canonical residual")
            }
            Error::TrailingBytes => write!(f, "unexpected bytes before the CRC"),
            Error::BadIndex(slot) => write!(
                f,
                "bank index entry {slot} does not give the offset and length of stimulus {slot}, \
                 which must follow the index and the stimuli before it back to back"
            ),
            Error::NoSuchSlot(slot) => write!(f, "bank has no slot {slot}"),
            Error::TooLarge => write!(f, "too large for the format"),
            Error::WrongLayout { found, expected } => write!(
                f,
                "compiled for layout geometry {found:#010x}, but the target's is {expected:#010x}"
            ),
            Error::TooManySlots { count, max } => {
                write!(f, "{count} slots, but a bank holds at most {max}")
            }
            Error::BankTooLarge { bytes, limit } => write!(
                f,
                "bank image of {bytes} bytes does not fit the sleeve's {limit}-byte bank flash region"
            ),
        }
    }
}

impl core::error::Error for Error {}

/// Shows a magic as text when it is printable ASCII, else as bytes.
struct Bytes<'a>(&'a [u8; 4]);

impl fmt::Debug for Bytes<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0.iter().all(|b| b.is_ascii_graphic()) {
            f.write_str("\"")?;
            for &b in self.0 {
                write!(f, "{}", b as char)?;
            }
            f.write_str("\"")
        } else {
            write!(f, "{:02x?}", self.0)
        }
    }
}
