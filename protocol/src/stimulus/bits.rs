//! The keyframe body's bit codes: an Exp-Golomb code for the keyframes a record skips
//! and a length-limited Rice code for the residuals, read most significant bit first.
//!
//! Both are prefix codes with one codeword per value (a value is escaped only when its
//! Rice quotient reaches [`RICE_LIMIT`]), so a body has exactly one reading, and
//! every codeword is at least one bit, so reading is O(bits) whatever a body claims.

use crate::Error;

/// Largest Rice parameter a header may name: a residual's code value is below
/// 2^18, so a larger parameter would only lengthen every codeword.
pub const MAX_RICE_K: u8 = 17;

/// Smallest Rice parameter a header may name: every residual then takes at least
/// three bits, which bounds the residuals a byte can hold and so the work of checking
/// a body (the emoji bank's stimuli take 3 to 5).
pub const MIN_RICE_K: u8 = 2;

/// A Rice quotient of this many one bits is an escape: the value follows in
/// [`ESCAPE_BITS`] plain bits.
pub const RICE_LIMIT: u32 = 16;

/// Bits of an escaped value. A residual is the difference between a stored value
/// (within i16) and a prediction `2 a - b` of two of them, so its magnitude is below
/// 2^17 and its code value (zigzag minus one) below 2^18.
pub const ESCAPE_BITS: u32 = 18;

/// Longest run of leading zeros of an Exp-Golomb codeword the body may hold: the
/// largest skip is [`super::MAX_KEYFRAMES`], below 2^27.
const MAX_EG_ZEROS: u32 = 26;

/// A cursor over a body's bits, most significant bit of each byte first.
///
/// The bits ahead sit in a 32-bit register, refilled a byte at a time, and each code's
/// prefix is counted with one leading-zeros instruction: the sleeve reads a record in
/// its 1 kHz tick and checks a whole bank at boot, so a residual costs a few
/// instructions rather than a loop per bit.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BitReader<'a> {
    bytes: &'a [u8],
    /// The next byte to load into `buf`.
    pos: usize,
    /// The next `have` bits, the first at bit 31; the bits below them are zero.
    buf: u32,
    have: u32,
}

/// Bits `buf` holds after a refill, unless the body ends first.
const FULL: u32 = 25;

impl<'a> BitReader<'a> {
    /// A reader at the first bit of `bytes`.
    pub(crate) const fn new(bytes: &'a [u8]) -> Self {
        BitReader {
            bytes,
            pos: 0,
            buf: 0,
            have: 0,
        }
    }

    /// Bits read so far.
    pub(crate) fn at(&self) -> usize {
        self.pos * 8 - self.have as usize
    }

    /// Loads whole bytes until at least [`FULL`] bits are ahead or the body ends.
    #[inline(always)]
    fn refill(&mut self) {
        if self.have < FULL {
            self.load();
        }
    }

    /// [`BitReader::refill`]'s loads, one copy for every code.
    #[inline(never)]
    fn load(&mut self) {
        while self.have < FULL {
            let Some(&byte) = self.bytes.get(self.pos) else {
                return;
            };
            self.buf |= u32::from(byte) << (24 - self.have);
            self.have += 8;
            self.pos += 1;
        }
    }

    /// Drops `n <= 25` bits the caller has looked at (and checked are there).
    #[inline(always)]
    fn consume(&mut self, n: u32) {
        self.buf <<= n;
        self.have -= n;
    }

    /// The next `n <= 25` bits as a number, first bit most significant.
    #[inline(always)]
    pub(crate) fn bits(&mut self, n: u32) -> Result<u32, Error> {
        self.refill();
        if n > self.have {
            return Err(Error::BadKeyframes);
        }
        // `n = 0`: no bits, 0 (the double shift keeps the shift under 32).
        let value = (self.buf >> 1) >> (31 - n);
        self.consume(n);
        Ok(value)
    }

    /// An order-0 Exp-Golomb codeword: `z` zero bits, then the `z + 1` bits of
    /// `value + 1` (whose first is one).
    #[inline(never)]
    pub(crate) fn exp_golomb(&mut self) -> Result<u32, Error> {
        self.refill();
        // Bits below `have` are zero: a one among the first `have` is the prefix's end.
        let zeros = self.buf.leading_zeros();
        if zeros >= self.have || zeros >= FULL {
            return self.exp_golomb_long();
        }
        self.consume(zeros);
        Ok(self.bits(zeros + 1)? - 1)
    }

    /// [`BitReader::exp_golomb`] past a prefix longer than the register holds (only
    /// the longest skips), or one the body ends in.
    #[cold]
    fn exp_golomb_long(&mut self) -> Result<u32, Error> {
        let mut zeros = 0u32;
        while self.bits(1)? == 0 {
            zeros += 1;
            if zeros > MAX_EG_ZEROS {
                return Err(Error::BadKeyframes);
            }
        }
        let mut x = 1u32;
        for _ in 0..zeros {
            x = (x << 1) | self.bits(1)?;
        }
        Ok(x - 1)
    }

    /// A Rice codeword of parameter `k`: the quotient `value >> k` in unary (one bits
    /// closed by a zero), then the low `k` bits; a quotient of [`RICE_LIMIT`] or more
    /// is [`RICE_LIMIT`] one bits and the value in [`ESCAPE_BITS`] bits. An escaped
    /// value whose quotient is below the limit has a shorter codeword and is refused
    /// ([`Error::KeyframeOutOfRange`]: each value has one encoding).
    #[inline(never)]
    pub(crate) fn rice(&mut self, k: u32) -> Result<u32, Error> {
        self.refill();
        // Bits below `have` are zero, so the ones counted are all there.
        let q = self.buf.leading_ones();
        if q >= RICE_LIMIT {
            self.consume(RICE_LIMIT);
            let value = self.bits(ESCAPE_BITS)?;
            if value >> k < RICE_LIMIT {
                return Err(Error::KeyframeOutOfRange);
            }
            return Ok(value);
        }
        if q >= self.have {
            // No closing zero: the body ends inside the quotient.
            return Err(Error::BadKeyframes);
        }
        self.consume(q + 1);
        Ok((q << k) | self.bits(k)?)
    }

    /// Checks that the body ends with this byte: nothing after it, and the bits left
    /// in it zero.
    pub(crate) fn finish(&self) -> Result<(), Error> {
        let at = self.at();
        if self.bytes.len() > at.div_ceil(8) {
            return Err(Error::TrailingBytes);
        }
        // The rest of the last byte, loaded (it holds the last bit read), is at the top.
        let pad = ((8 - at % 8) % 8) as u32;
        if pad > 0 && self.buf >> (32 - pad) != 0 {
            return Err(Error::BadKeyframes);
        }
        Ok(())
    }
}

/// Bits of the Rice codeword of `value` at parameter `k` (the stimulus format's residual
/// code: see the module documentation of [`crate::stimulus`]).
pub fn rice_len(value: u32, k: u32) -> u32 {
    let q = value >> k;
    if q >= RICE_LIMIT {
        RICE_LIMIT + ESCAPE_BITS
    } else {
        q + 1 + k
    }
}

/// The bit writer of the encoder.
#[cfg(any(test, feature = "std"))]
#[derive(Debug, Default)]
pub(crate) struct BitWriter {
    bytes: Vec<u8>,
    /// Bits used in the last byte (0..8; 0 when a new byte is due).
    used: u32,
}

#[cfg(any(test, feature = "std"))]
impl BitWriter {
    /// Appends the low `n <= 32` bits of `value`, most significant first.
    pub(crate) fn bits(&mut self, value: u32, n: u32) {
        for i in (0..n).rev() {
            if self.used == 0 {
                self.bytes.push(0);
            }
            let bit = ((value >> i) & 1) as u8;
            if let Some(last) = self.bytes.last_mut() {
                *last |= bit << (7 - self.used);
            }
            self.used = (self.used + 1) % 8;
        }
    }

    /// Appends the Exp-Golomb codeword of `value < 2^31`.
    pub(crate) fn exp_golomb(&mut self, value: u32) {
        let x = value + 1;
        let len = 32 - x.leading_zeros();
        self.bits(0, len - 1);
        self.bits(x, len);
    }

    /// Appends the Rice codeword of `value < 2^ESCAPE_BITS` at parameter `k`.
    pub(crate) fn rice(&mut self, value: u32, k: u32) {
        let q = value >> k;
        if q >= RICE_LIMIT {
            self.bits(u32::MAX, RICE_LIMIT);
            self.bits(value, ESCAPE_BITS);
        } else {
            self.bits(u32::MAX, q);
            self.bits(0, 1);
            self.bits(value, k);
        }
    }

    /// The bytes, the last one padded with zero bits.
    pub(crate) fn into_bytes(self) -> Vec<u8> {
        self.bytes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_code_reads_back_and_says_its_length() {
        let mut w = BitWriter::default();
        let mut expect = Vec::new();
        let mut bits = 0u32;
        for k in 0..=u32::from(MAX_RICE_K) {
            for v in [
                0u32,
                1,
                2,
                3,
                15,
                16,
                17,
                255,
                1 << 16,
                (1 << 18) - 1,
                1 << 24,
                86_400_001,
            ] {
                let rice = v.min((1 << ESCAPE_BITS) - 1);
                w.rice(rice, k);
                w.exp_golomb(v);
                bits += rice_len(rice, k) + 2 * (32 - (v + 1).leading_zeros()) - 1;
                expect.push((rice, v, k));
            }
        }
        let bytes = w.into_bytes();
        assert_eq!(bytes.len(), bits.div_ceil(8) as usize);
        let mut r = BitReader::new(&bytes);
        for &(rice, v, k) in &expect {
            assert_eq!(r.rice(k), Ok(rice), "rice {rice} at {k}");
            assert_eq!(r.exp_golomb(), Ok(v), "exp-golomb {v}");
        }
        assert_eq!(r.finish(), Ok(()));
    }

    #[test]
    fn codewords_are_the_documented_bits() {
        // Rice k = 2 of 9: quotient 2 -> `110`, remainder 1 -> `01`; Exp-Golomb of 4:
        // 5 = `101` after two zeros -> `00101`; then three zero bits of padding.
        let mut w = BitWriter::default();
        w.rice(9, 2);
        w.exp_golomb(4);
        assert_eq!(w.into_bytes(), [0b1100_1001, 0b0100_0000]);
        // An escape: sixteen ones, then the value in eighteen bits.
        let mut w = BitWriter::default();
        w.rice(16, 0);
        assert_eq!(w.into_bytes(), [0xFF, 0xFF, 0x00, 0x04, 0x00]);
    }

    #[test]
    fn a_short_value_escaped_or_a_dirty_pad_is_refused() {
        // Value 3 escaped at k = 0 (its own codeword is `1110`).
        let escaped = [0xFF, 0xFF, 0x00, 0x00, 0xC0];
        assert_eq!(
            BitReader::new(&escaped).rice(0),
            Err(Error::KeyframeOutOfRange)
        );
        // `0` is Rice k = 0 of 0; the pad after it must be zero, and nothing follow.
        let mut r = BitReader::new(&[0x00]);
        assert_eq!(r.rice(0), Ok(0));
        assert_eq!(r.finish(), Ok(()));
        let mut r = BitReader::new(&[0x01]);
        assert_eq!(r.rice(0), Ok(0));
        assert_eq!(r.finish(), Err(Error::BadKeyframes));
        let mut r = BitReader::new(&[0x00, 0x00]);
        assert_eq!(r.rice(0), Ok(0));
        assert_eq!(r.finish(), Err(Error::TrailingBytes));
        // Past the end, and an Exp-Golomb prefix longer than any skip.
        assert_eq!(BitReader::new(&[0xFF]).rice(0), Err(Error::BadKeyframes));
        assert_eq!(
            BitReader::new(&[0, 0, 0, 0, 0xFF]).exp_golomb(),
            Err(Error::BadKeyframes)
        );
    }

    /// A reader of one bit at a time, as SPEC.md words the codes: the oracle of the
    /// windowed reader.
    struct Naive<'a> {
        bytes: &'a [u8],
        at: usize,
    }

    impl Naive<'_> {
        fn bit(&mut self) -> Result<u32, Error> {
            let byte = *self.bytes.get(self.at / 8).ok_or(Error::BadKeyframes)?;
            self.at += 1;
            Ok(u32::from(byte >> (7 - (self.at - 1) % 8)) & 1)
        }

        fn bits(&mut self, n: u32) -> Result<u32, Error> {
            (0..n).try_fold(0, |v, _| Ok((v << 1) | self.bit()?))
        }

        fn exp_golomb(&mut self) -> Result<u32, Error> {
            let mut zeros = 0;
            while self.bit()? == 0 {
                zeros += 1;
                if zeros > MAX_EG_ZEROS {
                    return Err(Error::BadKeyframes);
                }
            }
            Ok(((1 << zeros) | self.bits(zeros)?) - 1)
        }

        fn rice(&mut self, k: u32) -> Result<u32, Error> {
            let mut q = 0;
            while self.bit()? == 1 {
                q += 1;
                if q == RICE_LIMIT {
                    let v = self.bits(ESCAPE_BITS)?;
                    return if v >> k < RICE_LIMIT {
                        Err(Error::KeyframeOutOfRange)
                    } else {
                        Ok(v)
                    };
                }
            }
            Ok((q << k) | self.bits(k)?)
        }
    }

    proptest::proptest! {
        /// Any bytes, read as any sequence of codes: the same values, the same errors
        /// and the same position as the bit-by-bit reader.
        #[test]
        fn the_windowed_reader_reads_what_the_spec_says(
            bytes in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..24),
            ops in proptest::collection::vec(0u32..20, 1..24),
        ) {
            let mut fast = BitReader::new(&bytes);
            let mut slow = Naive { bytes: &bytes, at: 0 };
            for op in ops {
                let (a, b) = match op {
                    0 => (fast.exp_golomb(), slow.exp_golomb()),
                    1 => (fast.bits(8), slow.bits(8)),
                    k => (fast.rice(k - 2), slow.rice(k - 2)),
                };
                proptest::prop_assert_eq!(a, b);
                if a.is_err() {
                    break;
                }
                proptest::prop_assert_eq!(fast.at(), slow.at);
            }
        }
    }
}
