//! The bank writer: a new bank over the link, safe against a power cut or a vanished
//! host at any byte.
//!
//! The order is what makes it safe. `begin` erases the sectors the image needs; the
//! chunks are programmed in order, except the image's first [`HEAD_LEN`] bytes (the
//! magic, version, length and slot count), which are kept in RAM. Until `commit`
//! programs them last, the region's first bytes read erased, so a restart finds "no
//! bank flashed" and plays the built-in bank ([`crate::boot::bank_source`]): a
//! partial image never reaches the boot check, let alone the player. `commit` checks
//! the whole image's CRC (the RAM head and the flash body) before it programs the
//! head, then checks the image as the boot does; a refused image is erased again.
//! The head's words are programmed from the last to the first, the magic's word
//! last: a cut while the head is programmed leaves a first word that is not the
//! magic yet, which the boot reads as an unfinished commit and plays the built-in
//! bank ([`crate::boot::committed`]); see the flash-model tests below.

use touch_protocol::bank::REGION_LEN;
use touch_protocol::container::{crc32, crc32_update};
use touch_protocol::link::LinkError;

use crate::boot::{check_bank, BootError};

/// Bytes of one flash sector of the bank region (sectors 10 and 11 of the F405).
pub const SECTOR_LEN: usize = 128 * 1024;

/// Bytes of the image held back and programmed last: the container prefix, the slot
/// count and the first index entry's offset. Any 16 bytes would do if they cover the
/// magic; these are the ones the boot reads first.
pub const HEAD_LEN: usize = 16;

/// Flash programming unit (x32 parallelism).
const WORD: usize = 4;

/// The bank region of flash, as the writer needs it.
pub trait Flash {
    /// Erases sector `sector` of the region (0 or 1): every byte reads 0xFF after.
    fn erase(&mut self, sector: usize) -> Result<(), FlashError>;
    /// Programs the erased word at `offset` (a multiple of 4) of the region.
    fn program(&mut self, offset: usize, word: u32) -> Result<(), FlashError>;
    /// The whole region as it reads now.
    fn region(&self) -> &[u8];
}

/// The flash refused an erase or a program.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(all(target_os = "none", feature = "hw"), derive(defmt::Format))]
pub enum FlashError {
    /// Programming a word that is not erased, or not aligned.
    NotErased,
    /// The controller reported an error (or power was lost, in the model).
    Failed,
}

/// An upload in progress.
#[derive(Debug, Clone)]
struct Upload {
    len: usize,
    crc: u32,
    /// Bytes received so far.
    next: usize,
    /// The image's first bytes, programmed by `commit`.
    head: [u8; HEAD_LEN],
    /// Bytes of the word being filled (`next` is inside it).
    word: [u8; WORD],
}

/// A committed bank.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Committed {
    /// CRC-32 of the whole image.
    pub crc: u32,
    /// Its slots.
    pub slots: u8,
}

/// Stages a bank image into flash (see the module docs for the order).
#[derive(Debug, Clone, Default)]
pub struct BankWriter {
    upload: Option<Upload>,
}

impl BankWriter {
    /// No upload.
    pub const fn new() -> Self {
        BankWriter { upload: None }
    }

    /// Bytes received of the upload in progress, if any.
    pub fn progress(&self) -> Option<u32> {
        self.upload.as_ref().map(|u| u.next as u32)
    }

    /// True while an upload is in progress.
    pub fn active(&self) -> bool {
        self.upload.is_some()
    }

    /// Starts an upload of `len` bytes whose CRC-32 is `crc`: erases the sectors the
    /// image needs (the first always: it holds the old bank's head). The old bank is
    /// gone from here on; until `commit`, the region reads as erased.
    pub fn begin<F: Flash>(&mut self, flash: &mut F, len: u32, crc: u32) -> Result<(), LinkError> {
        self.upload = None;
        let len = len as usize;
        let min = touch_protocol::container::PREFIX_LEN + touch_protocol::container::CRC_LEN;
        if !(min.max(HEAD_LEN)..=REGION_LEN).contains(&len) {
            return Err(LinkError::OutOfRange);
        }
        for sector in 0..len.div_ceil(SECTOR_LEN) {
            flash.erase(sector).map_err(|_| LinkError::Flash)?;
        }
        self.upload = Some(Upload {
            len,
            crc,
            next: 0,
            head: [0xFF; HEAD_LEN],
            word: [0xFF; WORD],
        });
        Ok(())
    }

    /// Takes the bytes at `offset`; returns the offset of the next chunk.
    ///
    /// `offset` must be where the last chunk ended. A chunk that was taken already
    /// (its reply lost) is acknowledged again if its bytes are the ones written.
    pub fn chunk<F: Flash>(
        &mut self,
        flash: &mut F,
        offset: u32,
        bytes: &[u8],
    ) -> Result<u32, LinkError> {
        let up = self.upload.as_mut().ok_or(LinkError::NoUpload)?;
        let offset = offset as usize;
        let end = offset
            .checked_add(bytes.len())
            .ok_or(LinkError::OutOfRange)?;
        if end > up.len {
            return Err(LinkError::OutOfRange);
        }
        if offset != up.next {
            let again = end <= up.next
                && bytes
                    .iter()
                    .enumerate()
                    .all(|(i, &b)| up.written(flash.region(), offset + i) == b);
            return if again {
                Ok(up.next as u32)
            } else {
                Err(LinkError::OutOfOrder {
                    expected: up.next as u32,
                })
            };
        }
        for &b in bytes {
            let at = up.next;
            if at < HEAD_LEN {
                up.head[at] = b;
            } else {
                up.word[at % WORD] = b;
                if at % WORD == WORD - 1 {
                    let word = u32::from_le_bytes(up.word);
                    up.word = [0xFF; WORD];
                    if let Err(e) = flash.program(at - (WORD - 1), word) {
                        self.upload = None;
                        return Err(flash_error(e));
                    }
                }
            }
            up.next += 1;
        }
        Ok(up.next as u32)
    }

    /// Abandons the upload (the region stays erased: the built-in bank plays).
    pub fn abort(&mut self) -> Result<(), LinkError> {
        self.upload.take().map(|_| ()).ok_or(LinkError::NoUpload)
    }

    /// Completes the upload: every byte received, the whole image's CRC as announced;
    /// then programs the head and checks the image as the boot will (and every
    /// slot's layout). A refused image is erased again.
    pub fn commit<F: Flash>(&mut self, flash: &mut F) -> Result<Committed, LinkError> {
        let up = self.upload.take().ok_or(LinkError::NoUpload)?;
        if up.next != up.len {
            self.upload = Some(up);
            return Err(LinkError::OutOfRange);
        }
        // The last partial word, padded with the erased value.
        if up.len % WORD != 0 && up.len > HEAD_LEN {
            let at = up.len - up.len % WORD;
            flash
                .program(at, u32::from_le_bytes(up.word))
                .map_err(flash_error)?;
        }
        let head_len = HEAD_LEN.min(up.len);
        let computed = image_crc(&up.head[..head_len], &flash.region()[head_len..up.len]);
        if computed != up.crc {
            return Err(LinkError::BadCrc {
                expected: up.crc,
                computed,
            });
        }
        // The magic's word last: until it is programmed, whole, the region reads as
        // an unfinished commit and the built-in bank boots
        // ([`crate::boot::committed`]).
        for at in (0..HEAD_LEN).step_by(WORD).rev() {
            let word = [
                up.head[at],
                up.head[at + 1],
                up.head[at + 2],
                up.head[at + 3],
            ];
            flash
                .program(at, u32::from_le_bytes(word))
                .map_err(flash_error)?;
        }
        match check(flash.region()) {
            Ok(slots) => Ok(Committed { crc: up.crc, slots }),
            Err(e) => {
                for sector in 0..up.len.div_ceil(SECTOR_LEN) {
                    flash.erase(sector).map_err(|_| LinkError::Flash)?;
                }
                Err(e)
            }
        }
    }
}

impl Upload {
    /// The image byte at `at` (< `next`) as written: the held head, the word being
    /// filled, or flash.
    fn written(&self, region: &[u8], at: usize) -> u8 {
        if at < HEAD_LEN {
            self.head[at]
        } else if at >= self.next - self.next % WORD && self.next >= HEAD_LEN {
            self.word[at % WORD]
        } else {
            region[at]
        }
    }
}

fn flash_error(_: FlashError) -> LinkError {
    LinkError::Flash
}

/// CRC-32 of the image given as its head and the rest.
fn image_crc(head: &[u8], body: &[u8]) -> u32 {
    !crc32_update(crc32_update(!0, head), body)
}

/// The boot's check of a region (its format, every CRC, the layout's geometry hash):
/// the number of slots, or why the image is refused.
pub fn check(region: &[u8]) -> Result<u8, LinkError> {
    match check_bank(region) {
        Ok(bank) => Ok(bank.len() as u8),
        // A bank holds one layout: every slot was compiled for the other one.
        Err(BootError::OtherLayout(_)) => Err(LinkError::WrongLayout { slot: 0 }),
        Err(e) => Err(LinkError::BadBank { blinks: e.blinks() }),
    }
}

/// CRC-32 of a whole bank image (as [`touch_protocol::link::Command::BankBegin`]
/// takes it). An intact image ends with the CRC of what precedes it, so this is the
/// same constant (0x2144DF1C) for every intact bank: it checks an image, it does not
/// tell two apart ([`stored_crc`] does).
pub fn bank_crc(image: &[u8]) -> u32 {
    crc32(image)
}

/// The CRC-32 a bank image carries in its last four bytes, over every byte before
/// them: the one the boot checks, different from bank to bank (`Info` reports it).
/// 0 for an image too short to hold one (never a bank that decoded).
pub fn stored_crc(image: &[u8]) -> u32 {
    match image.len().checked_sub(4).and_then(|at| image.get(at..)) {
        Some(&[a, b, c, d]) => u32::from_le_bytes([a, b, c, d]),
        _ => 0,
    }
}

#[cfg(any(test, feature = "sim"))]
pub mod model {
    //! A flash model for the tests: erase-before-write, word granularity, and a
    //! power cut after a chosen number of bytes erased or programmed.

    use super::{Flash, FlashError, SECTOR_LEN, WORD};
    use touch_protocol::bank::REGION_LEN;

    /// The bank region in RAM, with the rules of the F405's flash. Programming a
    /// word that is not erased panics: the writer must never do it.
    #[derive(Debug, Clone)]
    pub struct FlashModel {
        /// The region's bytes.
        pub bytes: Vec<u8>,
        /// Bytes that may still be erased or programmed before the power goes
        /// (`usize::MAX`: never).
        pub budget: usize,
        /// Set once the power went.
        pub dead: bool,
        /// Sector erases so far.
        pub erases: usize,
    }

    impl FlashModel {
        /// A region holding `image` (the rest erased).
        pub fn with(image: &[u8]) -> Self {
            let mut bytes = vec![0xFF; REGION_LEN];
            bytes[..image.len()].copy_from_slice(image);
            FlashModel {
                bytes,
                budget: usize::MAX,
                dead: false,
                erases: 0,
            }
        }

        /// Spends one byte of the budget; false once the power is gone.
        fn spend(&mut self) -> bool {
            if self.dead || self.budget == 0 {
                self.dead = true;
                return false;
            }
            self.budget = self.budget.saturating_sub(1);
            true
        }
    }

    impl Flash for FlashModel {
        fn erase(&mut self, sector: usize) -> Result<(), FlashError> {
            assert!(sector < 2);
            self.erases += 1;
            // An erase cut short leaves the sector partly erased: model it as erased
            // from its start (a prefix of 0xFF, the old bytes after), in 4 KB steps.
            for page in (0..SECTOR_LEN).step_by(4096) {
                if !self.spend() {
                    return Err(FlashError::Failed);
                }
                let at = sector * SECTOR_LEN + page;
                self.bytes[at..at + 4096].fill(0xFF);
            }
            Ok(())
        }

        fn program(&mut self, offset: usize, word: u32) -> Result<(), FlashError> {
            if !offset.is_multiple_of(WORD) || offset + WORD > self.bytes.len() {
                return Err(FlashError::NotErased);
            }
            if self.bytes[offset..offset + WORD].iter().any(|&b| b != 0xFF) {
                panic!("program over a word that is not erased at {offset:#x}");
            }
            // Byte by byte: a cut inside a word leaves its first bytes programmed.
            for (i, b) in word.to_le_bytes().into_iter().enumerate() {
                if !self.spend() {
                    return Err(FlashError::Failed);
                }
                self.bytes[offset + i] = b;
            }
            Ok(())
        }

        fn region(&self) -> &[u8] {
            &self.bytes
        }
    }
}

#[cfg(test)]
mod tests {
    use super::model::FlashModel;
    use super::*;
    use crate::boot::{bank_source, check_bank};
    use crate::testutil::{bank, constant_stimulus, for_layout};

    fn upload(flash: &mut FlashModel, image: &[u8], chunk: usize) -> Result<Committed, LinkError> {
        let mut w = BankWriter::new();
        w.begin(flash, image.len() as u32, bank_crc(image))?;
        for (i, c) in image.chunks(chunk).enumerate() {
            w.chunk(flash, (i * chunk) as u32, c)?;
        }
        w.commit(flash)
    }

    #[test]
    fn an_upload_replaces_the_bank() {
        let old = bank(&[constant_stimulus("old", 200, 100)]);
        let new = bank(&[
            constant_stimulus("a", 300, 200),
            constant_stimulus("b", -300, 200),
        ]);
        for chunk in [1, 3, 4, 7, 16, 256] {
            let mut f = FlashModel::with(&old);
            assert_eq!(
                upload(&mut f, &new, chunk),
                Ok(Committed {
                    crc: bank_crc(&new),
                    slots: 2
                })
            );
            assert_eq!(check_bank(f.region()).unwrap().as_bytes(), &new[..]);
        }
    }

    #[test]
    fn chunks_out_of_order_are_refused_and_a_repeat_is_acknowledged() {
        let new = bank(&[constant_stimulus("a", 300, 200)]);
        let mut f = FlashModel::with(&[]);
        let mut w = BankWriter::new();
        assert_eq!(w.chunk(&mut f, 0, &new[..4]), Err(LinkError::NoUpload));
        w.begin(&mut f, new.len() as u32, bank_crc(&new)).unwrap();
        assert_eq!(w.chunk(&mut f, 0, &new[..10]), Ok(10));
        // The same chunk again (a lost reply): acknowledged, nothing written twice.
        assert_eq!(w.chunk(&mut f, 0, &new[..10]), Ok(10));
        assert_eq!(w.chunk(&mut f, 10, &new[10..30]), Ok(30));
        assert_eq!(w.chunk(&mut f, 10, &new[10..30]), Ok(30));
        assert_eq!(w.chunk(&mut f, 27, &new[27..29]), Ok(30));
        // Other bytes at an old offset, or a gap: refused with the offset expected.
        assert_eq!(
            w.chunk(&mut f, 10, &[0; 20]),
            Err(LinkError::OutOfOrder { expected: 30 })
        );
        assert_eq!(
            w.chunk(&mut f, 40, &new[40..50]),
            Err(LinkError::OutOfOrder { expected: 30 })
        );
        assert_eq!(
            w.chunk(&mut f, 30, &vec![0; new.len()]),
            Err(LinkError::OutOfRange)
        );
        // Commit before the last byte: refused, the upload goes on.
        assert_eq!(w.commit(&mut f), Err(LinkError::OutOfRange));
        assert_eq!(w.chunk(&mut f, 30, &new[30..]), Ok(new.len() as u32));
        assert!(w.commit(&mut f).is_ok());
        assert_eq!(w.commit(&mut f), Err(LinkError::NoUpload));
        assert_eq!(w.abort(), Err(LinkError::NoUpload));
    }

    #[test]
    fn a_bad_crc_or_a_bad_bank_is_refused_and_never_boots() {
        let old = bank(&[constant_stimulus("old", 200, 100)]);
        let new = bank(&[constant_stimulus("a", 300, 200)]);
        // The announced CRC is not the image's.
        let mut f = FlashModel::with(&old);
        let mut w = BankWriter::new();
        w.begin(&mut f, new.len() as u32, bank_crc(&new) ^ 1)
            .unwrap();
        w.chunk(&mut f, 0, &new).unwrap();
        assert_eq!(
            w.commit(&mut f),
            Err(LinkError::BadCrc {
                expected: bank_crc(&new) ^ 1,
                computed: bank_crc(&new)
            })
        );
        assert!(f.region()[..HEAD_LEN].iter().all(|&b| b == 0xFF));
        // A consistent CRC over bytes that are not a valid bank (damaged inside, the
        // container CRC no longer matches): refused with the boot's LED code, erased.
        let mut bad = new.clone();
        bad[30] ^= 0x40;
        let mut f = FlashModel::with(&old);
        assert_eq!(
            upload(&mut f, &bad, 64),
            Err(LinkError::BadBank { blinks: 4 })
        );
        assert!(f.region().iter().all(|&b| b == 0xFF));
        // Too short, too long.
        let mut w = BankWriter::new();
        assert_eq!(w.begin(&mut f, 3, 0), Err(LinkError::OutOfRange));
        assert_eq!(
            w.begin(&mut f, (REGION_LEN + 1) as u32, 0),
            Err(LinkError::OutOfRange)
        );
    }

    #[test]
    fn a_bank_for_another_layout_is_refused_at_commit() {
        let good = constant_stimulus("good", 300, 200);
        let other = for_layout(&good, crate::output::LAYOUT_HASH.wrapping_add(1));
        let image = bank(&[other.clone(), other]);
        let mut f = FlashModel::with(&[]);
        assert_eq!(
            upload(&mut f, &image, 100),
            Err(LinkError::WrongLayout { slot: 0 })
        );
        assert!(f.region().iter().all(|&b| b == 0xFF));
    }

    /// What a restart would play.
    #[derive(Debug, PartialEq, Eq)]
    enum Boot {
        Old,
        New,
        Builtin,
        Refused(u8),
    }

    fn boot(region: &[u8], old: &[u8], new: &[u8], builtin: &[u8]) -> Boot {
        match check_bank(bank_source(region, builtin)) {
            Ok(b) if b.as_bytes() == old => Boot::Old,
            Ok(b) if b.as_bytes() == new => Boot::New,
            Ok(b) if b.as_bytes() == builtin => Boot::Builtin,
            Ok(b) => panic!(
                "boot accepted a bank that is none of the three: {} bytes",
                b.len()
            ),
            Err(e) => Boot::Refused(e.blinks()),
        }
    }

    /// Test (b): the power goes after every possible number of bytes erased or
    /// programmed, for an upload in chunks of a size that does not divide the words
    /// (and a vanished host after every chunk): a restart plays the old bank, the
    /// built-in one, or the new one once committed. Never a mix, never a refused
    /// region (a cut inside the head included), and the new bank only once its
    /// commit completed.
    #[test]
    fn a_power_cut_at_any_byte_never_boots_a_mix() {
        let old = bank(&[
            constant_stimulus("old", 200, 300),
            constant_stimulus("old2", 100, 300),
        ]);
        let new = bank(&[
            constant_stimulus("new", 300, 500),
            constant_stimulus("b", -300, 200),
            constant_stimulus("c", 500, 100),
        ]);
        let builtin = bank(&[constant_stimulus("builtin", 100, 100)]);
        // Bytes an uncut upload spends: the erase (32 steps of 4 KB) and the image
        // rounded up to words.
        let mut probe = FlashModel::with(&old);
        upload(&mut probe, &new, 37).unwrap();
        let total = usize::MAX - probe.budget;
        let mut seen = std::collections::BTreeMap::<String, usize>::new();
        for cut in 0..=total {
            let mut f = FlashModel::with(&old);
            f.budget = cut;
            let result = upload(&mut f, &new, 37);
            let outcome = boot(f.region(), &old, &new, &builtin);
            match &outcome {
                Boot::New => assert!(
                    cut >= total && result.is_ok(),
                    "cut {cut}: the new bank boots before its commit completed"
                ),
                Boot::Old => assert!(cut == 0, "cut {cut}: old bank after its erase began"),
                Boot::Builtin => assert!(result.is_err(), "cut {cut}"),
                Boot::Refused(blinks) => {
                    panic!("cut {cut} of {total}: the region is refused (LED code {blinks})")
                }
            }
            *seen.entry(format!("{outcome:?}")).or_default() += 1;
        }
        eprintln!("{total} cut points: {seen:?}");
        // The cut points cover all three outcomes (the old bank only when nothing was
        // erased).
        assert_eq!(seen.len(), 3, "{seen:?}");

        // A host that vanishes after any chunk (no power cut): the built-in bank.
        for stop in 0..new.len().div_ceil(37) {
            let mut f = FlashModel::with(&old);
            let mut w = BankWriter::new();
            w.begin(&mut f, new.len() as u32, bank_crc(&new)).unwrap();
            for (i, c) in new.chunks(37).take(stop).enumerate() {
                w.chunk(&mut f, (i * 37) as u32, c).unwrap();
            }
            assert_eq!(
                boot(f.region(), &old, &new, &builtin),
                Boot::Builtin,
                "after chunk {stop}"
            );
        }
    }

    /// A bank larger than one sector erases both, and the cut check holds across the
    /// sector boundary.
    #[test]
    fn a_two_sector_bank_uploads() {
        let big = crate::testutil::dense_bank(SECTOR_LEN + 5000);
        assert!(big.len() > SECTOR_LEN);
        let old = bank(&[constant_stimulus("old", 200, 300)]);
        let mut f = FlashModel::with(&old);
        upload(&mut f, &big, 256).unwrap();
        assert_eq!(f.erases, 2);
        assert_eq!(check_bank(f.region()).unwrap().as_bytes(), &big[..]);
    }
}
