//! The boot decision: play from the bank in flash, or refuse it and say why.

use touch_protocol::{Bank, Error};

/// Why the bank in flash is not used. Nothing plays; the LED shows a long light, then
/// [`BootError::blinks`] short blinks, a pause, and repeats ([`crate::led`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(all(target_os = "none", feature = "hw"), derive(defmt::Format))]
pub enum BootError {
    /// The region is erased (all 0xFF): no bank was flashed.
    Empty,
    /// Not a bank, or a bank of a format version this firmware does not read.
    NotABank(Error),
    /// The bank's CRC (or a stimulus's) does not match: corrupted or half-flashed.
    Corrupt(Error),
    /// The bank decodes but a stimulus in it is malformed.
    Invalid(Error),
    /// The bank was compiled for another actuator layout geometry
    /// ([`Error::WrongLayout`]): its channels would play in the wrong places.
    OtherLayout(Error),
}

impl BootError {
    /// LED blink count after the long light: 2 empty, 3 not a bank / wrong version,
    /// 4 CRC, 5 malformed, 6 another layout.
    pub fn blinks(&self) -> u8 {
        match self {
            BootError::Empty => 2,
            BootError::NotABank(_) => 3,
            BootError::Corrupt(_) => 4,
            BootError::Invalid(_) => 5,
            BootError::OtherLayout(_) => 6,
        }
    }
}

/// The bank to boot from: the flash region, or `builtin` when no bank was committed
/// there ([`committed`]: an erased region, or an upload whose commit did not finish).
/// Anything else in the region, a corrupt bank included, is the region's: it is
/// checked and refused, never silently replaced by the built-in bank.
pub fn bank_source<'a>(region: &'a [u8], builtin: &'a [u8]) -> &'a [u8] {
    if committed(region) {
        region
    } else {
        builtin
    }
}

/// False when the region holds no committed bank: its first word is not the bank
/// magic yet but could still be programmed into it (every bit the magic has set is
/// still set: flash programming only clears bits). An erased region reads so, and
/// so does one whose upload was cut before or while its commit programmed that word,
/// which the upload programs last ([`crate::link::bank`]): a cut anywhere in the
/// commit leaves the built-in bank or the new one, never a refused region.
pub fn committed(region: &[u8]) -> bool {
    let magic = touch_protocol::bank::MAGIC;
    let first = region.get(..magic.len()).unwrap_or(region);
    let unfinished = first.len() == magic.len()
        && first != magic
        && first.iter().zip(magic).all(|(&b, m)| b & m == m);
    !unfinished
}

/// Checks the bank region (the whole flash region; the bank says its own length).
///
/// Never panics, whatever the bytes: a refused bank leaves every output at 0 A.
///
/// Bounded: this is the one validation of the bank ([`Bank::decode`]: its CRC, then
/// each stimulus's CRC and records once), O(bytes) of a region of at most
/// [`touch_protocol::bank::REGION_LEN`] bytes, whatever the keyframe counts claim (a
/// run of keyframes is checked in one step). The worst case for a full region, a
/// record every two bytes, is measured under QEMU by `firmware/ci.sh` and must stay
/// under the boot watchdog's timeout (`src/hw/tick.rs`).
pub fn check_bank(region: &[u8]) -> Result<Bank<'_>, BootError> {
    let head = region.get(..16).unwrap_or(region);
    if head.iter().all(|&b| b == 0xFF) {
        return Err(BootError::Empty);
    }
    match Bank::decode(region) {
        Ok(bank) if !bank.is_empty() => bank
            .check_layout(crate::output::LAYOUT_HASH)
            .map(|()| bank)
            .map_err(BootError::OtherLayout),
        Ok(_) => Err(BootError::Empty),
        Err(e @ (Error::BadMagic { .. } | Error::UnsupportedVersion { .. })) => {
            Err(BootError::NotABank(e))
        }
        Err(e @ (Error::BadCrc { .. } | Error::Truncated { .. } | Error::BadLength(_))) => {
            Err(BootError::Corrupt(e))
        }
        Err(e) => Err(BootError::Invalid(e)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testutil::{bank, constant_stimulus, for_layout};
    use proptest::prelude::*;

    fn region_with(image: &[u8]) -> Vec<u8> {
        let mut region = vec![0xFF; 256 * 1024];
        region[..image.len()].copy_from_slice(image);
        region
    }

    #[test]
    fn good_bank_in_a_whole_region_boots() {
        let image = bank(&[
            constant_stimulus("a", 200, 100),
            constant_stimulus("b", -200, 100),
        ]);
        let region = region_with(&image);
        assert_eq!(check_bank(&region).unwrap().len(), 2);
    }

    #[test]
    fn a_bank_for_another_layout_geometry_is_refused_at_boot() {
        let s = constant_stimulus("mirrored", 200, 100);
        // Same name as the sleeve's layout, other geometry: refused on the hash.
        let image = bank(&[for_layout(&s, crate::output::LAYOUT_HASH.rotate_left(8))]);
        let e = check_bank(&region_with(&image)).unwrap_err();
        assert!(
            matches!(e, BootError::OtherLayout(Error::WrongLayout { .. })),
            "{e:?}"
        );
        assert_eq!(e.blinks(), 6);
    }

    #[test]
    fn erased_region_is_empty() {
        assert_eq!(check_bank(&[0xFF; 4096]).unwrap_err(), BootError::Empty);
        assert_eq!(check_bank(&[]).unwrap_err(), BootError::Empty);
    }

    #[test]
    fn refusals_have_distinct_blink_codes() {
        let image = bank(&[constant_stimulus("a", 200, 100)]);
        let mut corrupt = region_with(&image);
        corrupt[image.len() - 6] ^= 1;
        let e = check_bank(&corrupt).unwrap_err();
        assert!(matches!(e, BootError::Corrupt(_)), "{e:?}");
        let mut not_bank = region_with(&image);
        not_bank[0] = b'X';
        let e2 = check_bank(&not_bank).unwrap_err();
        assert!(matches!(e2, BootError::NotABank(_)), "{e2:?}");
        let zeros = vec![0u8; 4096];
        assert!(check_bank(&zeros).is_err());
        assert_ne!(e.blinks(), e2.blinks());
        assert_ne!(e.blinks(), BootError::Empty.blinks());
    }

    #[test]
    fn erased_region_boots_the_builtin_bank_and_a_flashed_one_wins() {
        let builtin = bank(&[constant_stimulus("b", 200, 100)]);
        let flashed = region_with(&bank(&[
            constant_stimulus("f", 300, 100),
            constant_stimulus("g", 300, 100),
        ]));
        let erased = vec![0xFF; 4096];
        assert_eq!(check_bank(bank_source(&erased, &builtin)).unwrap().len(), 1);
        assert_eq!(
            check_bank(bank_source(&flashed, &builtin)).unwrap().len(),
            2
        );
        let mut corrupt = flashed.clone();
        corrupt[40] ^= 1;
        let e = check_bank(bank_source(&corrupt, &builtin)).unwrap_err();
        assert!(matches!(e, BootError::Corrupt(_)), "{e:?}");
    }

    /// A first word on its way to the magic (bits still to be cleared) is an
    /// unfinished commit: the built-in bank. Anything else there is the region's.
    #[test]
    fn a_magic_word_programmed_in_part_boots_the_builtin_bank() {
        let builtin = bank(&[constant_stimulus("b", 200, 100)]);
        let flashed = region_with(&bank(&[constant_stimulus("f", 300, 100)]));
        let magic = touch_protocol::bank::MAGIC;
        for bit in 0..32 {
            let (byte, mask) = (bit / 8, 1u8 << (bit % 8));
            let mut region = flashed.clone();
            if magic[byte] & mask == 0 {
                // A bit the commit had still to clear: unfinished.
                region[byte] |= mask;
                assert!(!committed(&region), "bit {bit}");
                assert_eq!(check_bank(bank_source(&region, &builtin)).unwrap().len(), 1);
            } else {
                // A bit the magic keeps set, cleared: not a bank.
                region[byte] &= !mask;
                assert!(committed(&region), "bit {bit}");
                let e = check_bank(bank_source(&region, &builtin)).unwrap_err();
                assert!(matches!(e, BootError::NotABank(_)), "bit {bit}: {e:?}");
            }
        }
    }

    /// `memory.x` and the protocol's bank region agree (address and length).
    #[test]
    fn bank_region_matches_memory_x() {
        use touch_protocol::bank::{REGION_ADDR, REGION_LEN};
        let text = include_str!("../../memory.x");
        let line = text
            .lines()
            .find(|l| l.trim_start().starts_with("BANK"))
            .expect("memory.x has a BANK region");
        let field = |name: &str| {
            let at = line.find(name).expect(name) + name.len();
            let rest = line[at..].trim_start().trim_start_matches('=').trim_start();
            rest.split(|c: char| c == ',' || c.is_whitespace())
                .next()
                .unwrap()
                .to_string()
        };
        let origin = usize::from_str_radix(field("ORIGIN").trim_start_matches("0x"), 16).unwrap();
        let length = field("LENGTH");
        let length = match length.strip_suffix('K') {
            Some(k) => k.parse::<usize>().unwrap() * 1024,
            None => length.parse().unwrap(),
        };
        assert_eq!((origin, length), (REGION_ADDR, REGION_LEN), "{line}");
    }

    /// Four slots claiming the most keyframes the format allows, in a few hundred
    /// bytes (the old check walked 100 M keyframes per slot, three times), and a full
    /// region of dense records: both checked in one pass over the bytes.
    #[test]
    fn huge_claims_in_few_bytes_and_a_full_region_are_checked_in_one_pass() {
        use touch_protocol::container;
        use touch_protocol::stimulus::{self, MAX_KEYFRAMES};
        let frames = vec![[0i16; 8]; 2];
        let one =
            crate::testutil::stimulus_from("long", 1, &frames, touch_protocol::Limits::SLEEVE);
        // The same header claiming the maximum, over one record skipping that many.
        let s = touch_protocol::Stimulus::decode(&one).unwrap();
        let mut h = *s.header();
        h.keyframe_count = MAX_KEYFRAMES;
        h.duration_ms = MAX_KEYFRAMES - 1;
        let mut head = [0u8; touch_protocol::stimulus::HEADER_MAX_LEN];
        let mut payload = postcard::to_slice(&h, &mut head).unwrap().to_vec();
        // One record skipping all keyframes: Exp-Golomb of MAX_KEYFRAMES, 26 zero bits
        // and the 27 bits of MAX_KEYFRAMES + 1 (SPEC.md), padded to 7 bytes.
        let bits = (u64::from(MAX_KEYFRAMES) + 1) << (64 - 53);
        payload.extend_from_slice(&bits.to_be_bytes()[..7]);
        let file = container::seal(stimulus::MAGIC, stimulus::VERSION, &payload).unwrap();
        let image = bank(&[file.clone(), file.clone(), file.clone(), file]);
        assert!(image.len() < 360, "{} bytes", image.len());
        let region = region_with(&image);
        let b = check_bank(&region).unwrap();
        assert_eq!(b.slot(3).unwrap().duration_ms(), MAX_KEYFRAMES - 1);

        let dense = crate::testutil::dense_bank(touch_protocol::bank::REGION_LEN);
        assert!(dense.len() > touch_protocol::bank::REGION_LEN - 64);
        assert!(check_bank(&dense).is_ok());
    }

    proptest! {
        #[test]
        fn any_bytes_are_refused_without_panic(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
            let _ = check_bank(&bytes);
        }

        #[test]
        fn any_single_bit_flip_is_refused(bit in 0usize..(8 * 200)) {
            let image = bank(&[constant_stimulus("a", 200, 100)]);
            let mut region = region_with(&image);
            let bit = bit % (8 * image.len());
            region[bit / 8] ^= 1 << (bit % 8);
            prop_assert!(check_bank(&region).is_err());
        }
    }
}
