//! The bank: several stimuli, one per slot, flashed to the sleeve as one image.
//!
//! A container (see [`crate::container`]) with magic `b"TCHB"` whose payload is
//!
//! ```text
//! count: u16 LE                       number of slots, 1..=MAX_SLOTS
//! layout_hash: u32 LE                  geometry hash of the layout every slot was
//!                                      compiled for (see crate::layout)
//! index: count x (offset u32 LE, length u32 LE)
//!                                     each slot's stimulus, offset from the bank's first byte
//! stimuli                             complete stimulus files, back to back, in slot order
//! ```
//!
//! The fixed-width index makes a slot lookup O(1) and copy-free. Decoding checks
//! every stimulus, and that each was compiled for the bank's layout, so a bank that
//! decodes plays without further checks once its layout is the sleeve's.

use crate::container::{self, PREFIX_LEN};
use crate::{Error, Stimulus};

/// Magic of a bank image.
pub const MAGIC: [u8; 4] = *b"TCHB";
/// The bank format version this build reads and writes: the stimulus format's (a
/// bank holds stimuli, so an image of older stimuli is refused at its version).
pub const VERSION: u16 = crate::stimulus::VERSION;
/// Most slots a bank holds.
pub const MAX_SLOTS: u16 = 32;
/// Bytes of the sleeve's bank flash region (sectors 10-11 of the STM32F405RG, the
/// `BANK` region of `memory.x`; a firmware test keeps the two in step). A bank must
/// fit in it.
pub const REGION_LEN: usize = 256 * 1024;
/// Flash address of the bank region (`BANK` in `memory.x`).
pub const REGION_ADDR: usize = 0x080C_0000;

const INDEX_ENTRY_LEN: usize = 8;
/// Bytes of the payload before the index: count and layout hash.
const INDEX_AT: usize = 2 + 4;

/// A validated, zero-copy view of a bank image.
#[derive(Debug, Clone, Copy)]
pub struct Bank<'a> {
    bytes: &'a [u8],
    count: u16,
    layout_hash: u32,
}

impl<'a> Bank<'a> {
    /// Decodes and validates a bank and every stimulus in it.
    ///
    /// `bytes` may be longer than the bank (a whole flash region): the bank's
    /// own length field says where it ends.
    pub fn decode(bytes: &'a [u8]) -> Result<Self, Error> {
        let c = container::open(bytes, MAGIC, VERSION)?;
        if c.bytes.len() > REGION_LEN {
            return Err(Error::BankTooLarge {
                bytes: c.bytes.len() as u32,
                limit: REGION_LEN as u32,
            });
        }
        let payload = c.payload;
        if payload.len() < INDEX_AT {
            return Err(Error::InvalidField("count"));
        }
        let count = u16::from_le_bytes([payload[0], payload[1]]);
        if count == 0 || count > MAX_SLOTS {
            return Err(Error::InvalidField("count"));
        }
        let layout_hash = u32::from_le_bytes([payload[2], payload[3], payload[4], payload[5]]);
        let index_end = PREFIX_LEN + INDEX_AT + usize::from(count) * INDEX_ENTRY_LEN;
        let data_end = c.bytes.len() - container::CRC_LEN;
        if index_end > data_end {
            return Err(Error::InvalidField("count"));
        }
        let bank = Bank {
            bytes: c.bytes,
            count,
            layout_hash,
        };
        let mut expected_offset = index_end;
        for slot in 0..count {
            let (offset, len) = bank.entry(slot);
            if offset != expected_offset || offset.checked_add(len).is_none_or(|e| e > data_end) {
                return Err(Error::BadIndex(slot));
            }
            let stimulus = Stimulus::decode(&bank.bytes[offset..offset + len])?;
            if stimulus.as_bytes().len() != len {
                return Err(Error::BadIndex(slot));
            }
            stimulus.check_layout(layout_hash)?;
            expected_offset = offset + len;
        }
        if expected_offset != data_end {
            return Err(Error::TrailingBytes);
        }
        Ok(bank)
    }

    /// Index entry of `slot` as (offset, length); `slot` must be below `count`.
    fn entry(&self, slot: u16) -> (usize, usize) {
        let at = PREFIX_LEN + INDEX_AT + usize::from(slot) * INDEX_ENTRY_LEN;
        let b = &self.bytes[at..at + INDEX_ENTRY_LEN];
        let offset = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        let len = u32::from_le_bytes([b[4], b[5], b[6], b[7]]);
        (offset as usize, len as usize)
    }

    /// Number of slots.
    pub fn len(&self) -> usize {
        usize::from(self.count)
    }

    /// Always false: a valid bank has at least one slot.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// [`crate::layout::geometry_hash`] of the layout every slot was compiled for.
    pub fn layout_hash(&self) -> u32 {
        self.layout_hash
    }

    /// Refuses a bank compiled for another layout geometry than `layout_hash`.
    pub fn check_layout(&self, layout_hash: u32) -> Result<(), Error> {
        if self.layout_hash == layout_hash {
            Ok(())
        } else {
            Err(Error::WrongLayout {
                found: self.layout_hash,
                expected: layout_hash,
            })
        }
    }

    /// The whole bank image, prefix to CRC.
    pub fn as_bytes(&self) -> &'a [u8] {
        self.bytes
    }

    /// The stimulus in `slot`, borrowed from the bank.
    ///
    /// O(header): [`Bank::decode`] validated every stimulus, so this reads the
    /// header again and trusts the rest (the bytes are borrowed, so unchanged).
    pub fn slot(&self, slot: usize) -> Result<Stimulus<'a>, Error> {
        let slot16 = u16::try_from(slot).unwrap_or(u16::MAX);
        if slot16 >= self.count {
            return Err(Error::NoSuchSlot(slot16));
        }
        let (offset, len) = self.entry(slot16);
        Stimulus::revalidated(&self.bytes[offset..offset + len])
    }

    /// All stimuli in slot order.
    pub fn stimuli(&self) -> impl Iterator<Item = Stimulus<'a>> + '_ {
        (0..self.len()).filter_map(|i| self.slot(i).ok())
    }
}

/// Builds a bank from encoded stimuli, one per slot, after checking each. The bank's
/// layout is the first stimulus's; a stimulus for another layout is refused
/// ([`Error::WrongLayout`]) with its hash and the bank's.
///
/// ```
/// use touch_protocol::{bank, stimulus};
/// let one = stimulus::Builder::new("a", 40).encode(&[[0; 8]])?;
/// let image = bank::encode(&[&one, &one])?;
/// assert_eq!(&image[..4], b"TCHB");
/// assert_eq!(bank::Bank::decode(&image)?.len(), 2);
/// # Ok::<(), touch_protocol::Error>(())
/// ```
///
/// Refuses more than [`MAX_SLOTS`] stimuli and an image larger than [`REGION_LEN`],
/// with the numbers.
#[cfg(any(test, feature = "std"))]
pub fn encode(stimuli: &[&[u8]]) -> Result<Vec<u8>, Error> {
    if stimuli.len() > usize::from(MAX_SLOTS) {
        return Err(Error::TooManySlots {
            count: u32::try_from(stimuli.len()).unwrap_or(u32::MAX),
            max: MAX_SLOTS,
        });
    }
    let count = u16::try_from(stimuli.len()).map_err(|_| Error::TooLarge)?;
    if count == 0 {
        return Err(Error::InvalidField("count"));
    }
    let decoded = stimuli
        .iter()
        .map(|s| Stimulus::decode(s))
        .collect::<Result<Vec<_>, _>>()?;
    let layout_hash = decoded[0].header().layout_hash;
    let mut payload = Vec::new();
    payload.extend_from_slice(&count.to_le_bytes());
    payload.extend_from_slice(&layout_hash.to_le_bytes());
    let mut offset = PREFIX_LEN + INDEX_AT + stimuli.len() * INDEX_ENTRY_LEN;
    let mut exact = Vec::with_capacity(stimuli.len());
    for s in &decoded {
        s.check_layout(layout_hash)?;
        let bytes = s.as_bytes();
        let off = u32::try_from(offset).map_err(|_| Error::TooLarge)?;
        let len = u32::try_from(bytes.len()).map_err(|_| Error::TooLarge)?;
        payload.extend_from_slice(&off.to_le_bytes());
        payload.extend_from_slice(&len.to_le_bytes());
        offset += bytes.len();
        exact.push(bytes);
    }
    for bytes in exact {
        payload.extend_from_slice(bytes);
    }
    let image = container::seal(MAGIC, VERSION, &payload)?;
    if image.len() > REGION_LEN {
        return Err(Error::BankTooLarge {
            bytes: u32::try_from(image.len()).unwrap_or(u32::MAX),
            limit: REGION_LEN as u32,
        });
    }
    Ok(image)
}
