//! The stimulus file: one haptic pattern for the eight channels.
//!
//! A container (see [`crate::container`]) with magic `b"TCHS"` whose payload is a
//! postcard [`Header`] followed by the keyframe body. The body is a string of bits
//! (most significant bit of each byte first, the last byte padded with zeros) that
//! describes `keyframe_count` keyframes, for all channels at once (so the player
//! streams it with a single cursor), as records:
//!
//! ```text
//! skip: Exp-Golomb (order 0)     keyframes in which every channel follows its prediction
//! then, unless the skip reached the last keyframe, one keyframe that changes:
//! mask: 8 bits, != 0             bit c (channel 0 first) set = channel c left its prediction
//! residual: Rice (header's k)    once per set bit, channel order: zigzag(residual) - 1
//! ```
//!
//! Each channel's stored value `s[k]` is predicted by extending the line through
//! the two before it, `2 s[k-1] - s[k-2]` (both 0 before the first keyframe), and
//! the record holds only the residual. A band-limited signal bends slowly, so the
//! residuals are small, and a stretch where every channel holds still or ramps costs
//! a few bits however long. The residuals' Rice parameter is the header's
//! `residual_k`, the one that makes the body shortest; a Rice quotient of 16 or more
//! escapes to the value in 18 bits, so no codeword is longer than 34 bits. The current
//! a stored value stands for is `(s << quant_shift) / 32768 * full_scale_ma` mA (Q15
//! of the full scale). A zero residual cannot be written, a mask of 0 is refused, and
//! so is an escape a shorter codeword could say: at a given `residual_k` every signal
//! has exactly one encoding. `SPEC.md` describes every bit.

use serde::{Deserialize, Serialize};

use crate::container::{self, Container};
use crate::{Error, Limits, CHANNELS};

mod bits;
#[cfg(any(test, feature = "std"))]
mod builder;

use bits::BitReader;
pub use bits::{rice_len, MAX_RICE_K, MIN_RICE_K};
#[cfg(any(test, feature = "std"))]
pub use builder::Builder;

/// Magic of a stimulus file.
pub const MAGIC: [u8; 4] = *b"TCHS";
/// The stimulus format version this build reads and writes.
pub const VERSION: u16 = 3;
/// The only output rate the format defines, Hz.
pub const OUTPUT_RATE_HZ: u16 = 1000;
/// Longest name, bytes of UTF-8.
pub const MAX_NAME_LEN: usize = 32;
/// Longest keyframe period, ms (one keyframe per second).
pub const MAX_KEYFRAME_PERIOD_MS: u16 = 1000;
/// Upper bound of an encoded header, bytes (fixed fields plus the longest names).
pub const HEADER_MAX_LEN: usize = 43 + crate::layout::MAX_NAME_LEN + MAX_NAME_LEN;
/// Largest full scale, mA: keeps the player's fixed-point products inside 32 bits.
pub const MAX_FULL_SCALE_MA: u16 = 10_000;
/// Longest keyframed signal, ms: 24 hours.
///
/// Far beyond any recording the compiler can hold (it keeps the whole pressure movie
/// in memory: a day at the sleeve's 20 Hz is 14.5 GB of f64 cells), so no real
/// stimulus meets it, while every time the player and the host tools count stays
/// far inside 32 bits (a day is 2^26.4 ms) and the host's per-tick outputs
/// stay countable. Decoding is O(bytes) whatever the duration (see [`Stimulus::decode`]).
pub const MAX_DURATION_MS: u32 = 24 * 60 * 60 * 1000;
/// Most keyframes: a day at the shortest period, 1 ms (`duration = (count - 1) * period`).
pub const MAX_KEYFRAMES: u32 = MAX_DURATION_MS + 1;

/// Everything about a stimulus but its keyframes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header<'a> {
    /// Number of output channels; always [`CHANNELS`].
    pub channels: u8,
    /// Player output rate in Hz; always [`OUTPUT_RATE_HZ`].
    pub output_rate_hz: u16,
    /// Time between keyframes, ms (the keyframe rate is `1000 / period` Hz).
    pub keyframe_period_ms: u16,
    /// Number of keyframes; at least one.
    pub keyframe_count: u32,
    /// Length of the keyframed signal, `(keyframe_count - 1) * keyframe_period_ms`.
    pub duration_ms: u32,
    /// Length of the player's ramp from 0 A in, and back to 0 A after the end or a stop.
    pub ramp_ms: u16,
    /// Current that the Q15 value 32768 stands for, mA.
    pub full_scale_ma: u16,
    /// Quantisation: a stored value `s` stands for Q15 `s << quant_shift` (0..=15).
    pub quant_shift: u8,
    /// Rice parameter of the residuals ([`MIN_RICE_K`]..=[`MAX_RICE_K`]): the encoder's
    /// choice, the one that makes the body shortest.
    pub residual_k: u8,
    /// [`crate::layout::geometry_hash`] of the actuator layout the channels were
    /// compiled for: what a player compares before it plays.
    #[serde(with = "postcard::fixint::le")]
    pub layout_hash: u32,
    /// That layout's name (at most [`crate::layout::MAX_NAME_LEN`] bytes), so that a
    /// refusal can name both layouts; never compared.
    pub layout: &'a str,
    /// The safety limits the signal was compiled and checked against.
    pub limits: Limits,
    /// A short name ("love", "calming", ...).
    pub name: &'a str,
}

impl Header<'_> {
    /// Checks every field's range; the error names the first bad field.
    pub fn validate(&self) -> Result<(), Error> {
        let bad = |field| Err(Error::InvalidField(field));
        if usize::from(self.channels) != CHANNELS {
            return bad("channels");
        }
        if self.output_rate_hz != OUTPUT_RATE_HZ {
            return bad("output_rate_hz");
        }
        if self.keyframe_period_ms == 0 || self.keyframe_period_ms > MAX_KEYFRAME_PERIOD_MS {
            return bad("keyframe_period_ms");
        }
        if self.keyframe_count == 0 || self.keyframe_count > MAX_KEYFRAMES {
            return bad("keyframe_count");
        }
        let span = u64::from(self.keyframe_count - 1) * u64::from(self.keyframe_period_ms);
        if span != u64::from(self.duration_ms) || self.duration_ms > MAX_DURATION_MS {
            return bad("duration_ms");
        }
        if self.ramp_ms == 0 {
            return bad("ramp_ms");
        }
        if self.full_scale_ma == 0 || self.full_scale_ma > MAX_FULL_SCALE_MA {
            return bad("full_scale_ma");
        }
        if self.quant_shift > 15 {
            return bad("quant_shift");
        }
        if !(MIN_RICE_K..=MAX_RICE_K).contains(&self.residual_k) {
            return bad("residual_k");
        }
        if self.layout.len() > crate::layout::MAX_NAME_LEN {
            return bad("layout");
        }
        if self.name.len() > MAX_NAME_LEN {
            return bad("name");
        }
        Ok(())
    }

    /// Keyframe rate in Hz.
    pub fn keyframe_rate_hz(&self) -> f64 {
        1000.0 / f64::from(self.keyframe_period_ms)
    }

    /// Ticks the player runs for: the signal, then the ramp back to 0 A.
    pub fn playback_ms(&self) -> u32 {
        self.duration_ms.saturating_add(u32::from(self.ramp_ms))
    }
}

/// A validated, zero-copy view of a stimulus file.
///
/// [`Stimulus::decode`] checks the container, the header and every keyframe once,
/// so playing it can never meet malformed data; nothing is copied or allocated.
#[derive(Debug, Clone, Copy)]
pub struct Stimulus<'a> {
    header: Header<'a>,
    body: &'a [u8],
    bytes: &'a [u8],
}

impl<'a> Stimulus<'a> {
    /// Decodes and fully validates a stimulus. `bytes` may extend past its end.
    ///
    /// The work is O(bytes), whatever the keyframe count: a channel is checked where
    /// each of its lines ends (the values between lie on the way), and a record costs
    /// its skip, its mask and one step per residual, each at least three bits.
    pub fn decode(bytes: &'a [u8]) -> Result<Self, Error> {
        let stimulus = Stimulus::parse(bytes, true)?;
        validate(stimulus.body, &stimulus.header)?;
        Ok(stimulus)
    }

    /// The container and the header; with `check_crc` false, for bytes that a
    /// [`Stimulus::decode`] (or a bank's) already validated.
    fn parse(bytes: &'a [u8], check_crc: bool) -> Result<Self, Error> {
        let Container { bytes, payload } = if check_crc {
            container::open(bytes, MAGIC, VERSION)?
        } else {
            container::open_unchecked(bytes)?
        };
        let (header, body) =
            postcard::take_from_bytes::<Header<'a>>(payload).map_err(|_| Error::BadHeader)?;
        header.validate()?;
        Ok(Stimulus {
            header,
            body,
            bytes,
        })
    }

    /// The view of a stimulus inside a bank that [`crate::Bank::decode`] validated:
    /// the header only, O(header) instead of O(bytes).
    pub(crate) fn revalidated(bytes: &'a [u8]) -> Result<Self, Error> {
        Stimulus::parse(bytes, false)
    }

    /// The header.
    pub fn header(&self) -> &Header<'a> {
        &self.header
    }

    /// The stimulus's name.
    pub fn name(&self) -> &'a str {
        self.header.name
    }

    /// Length of the keyframed signal, ms (playback adds one ramp, see [`Header::playback_ms`]).
    pub fn duration_ms(&self) -> u32 {
        self.header.duration_ms
    }

    /// Refuses a stimulus compiled for another layout geometry than `layout_hash` (see
    /// [`crate::layout`]; the channel count is the format's, checked by [`Stimulus::decode`]).
    pub fn check_layout(&self, layout_hash: u32) -> Result<(), Error> {
        if self.header.layout_hash == layout_hash {
            Ok(())
        } else {
            Err(Error::WrongLayout {
                found: self.header.layout_hash,
                expected: layout_hash,
            })
        }
    }

    /// The limits the stimulus was compiled for.
    pub fn limits(&self) -> Limits {
        self.header.limits
    }

    /// The whole file, prefix to CRC.
    pub fn as_bytes(&self) -> &'a [u8] {
        self.bytes
    }

    /// The stored CRC-32.
    pub fn crc(&self) -> u32 {
        let n = self.bytes.len();
        u32::from_le_bytes([
            self.bytes[n - 4],
            self.bytes[n - 3],
            self.bytes[n - 2],
            self.bytes[n - 1],
        ])
    }

    /// Streams the keyframes as Q15 values of the full scale, without copying.
    pub fn keyframes(&self) -> Keyframes<'a> {
        Keyframes {
            bits: BitReader::new(self.body),
            stored: [0; CHANNELS],
            before: [0; CHANNELS],
            idle_left: 0,
            change_due: false,
            shift: self.header.quant_shift,
            residual_k: u32::from(self.header.residual_k),
            remaining: self.header.keyframe_count,
        }
    }
}

/// Streaming keyframe decoder: one cursor over the body and the running values.
#[derive(Debug, Clone)]
pub struct Keyframes<'a> {
    bits: BitReader<'a>,
    /// Stored values of the last keyframe, `s[k-1]`.
    stored: [i32; CHANNELS],
    /// Stored values of the keyframe before it, `s[k-2]`.
    before: [i32; CHANNELS],
    /// Keyframes left in the current record's skip.
    idle_left: u32,
    /// The current record's changing keyframe is still to come (after its skip).
    change_due: bool,
    shift: u8,
    residual_k: u32,
    remaining: u32,
}

impl Keyframes<'_> {
    /// Decodes the next keyframe, or reports malformed data.
    ///
    /// On a [`Stimulus`] this cannot fail: decoding validated every keyframe.
    pub fn try_next(&mut self) -> Result<[i16; CHANNELS], Error> {
        if self.idle_left == 0 && !self.change_due {
            self.record()?;
        }
        if self.idle_left > 0 {
            self.idle_left -= 1;
            self.follow()?;
        } else {
            self.change()?;
        }
        self.remaining = self.remaining.saturating_sub(1);
        let mut out = [0i16; CHANNELS];
        for (o, &s) in out.iter_mut().zip(&self.stored) {
            // In range by the checks in `follow` and `change`: |s << shift| fits i16.
            *o = (s << self.shift) as i16;
        }
        Ok(out)
    }

    /// Reads a record's skip: the keyframes that follow their prediction, and whether a
    /// changing keyframe comes after them (it does unless they are the last ones).
    fn record(&mut self) -> Result<(), Error> {
        if self.remaining == 0 {
            return Err(Error::BadKeyframes);
        }
        let skip = self.bits.exp_golomb()?;
        if skip > self.remaining {
            return Err(Error::BadKeyframes);
        }
        self.idle_left = skip;
        self.change_due = skip < self.remaining;
        Ok(())
    }

    /// Reads the mask and residuals of a changing keyframe and applies them.
    fn change(&mut self) -> Result<(), Error> {
        self.change_due = false;
        // The reader stays in registers while the residuals are read, before the
        // channels are updated: this runs in the sleeve's tick at a keyframe boundary.
        let mut bits = self.bits;
        let mask = bits.bits(8)?;
        if mask == 0 {
            // A keyframe that follows its prediction belongs in a skip.
            return Err(Error::KeyframeOutOfRange);
        }
        let k = self.residual_k;
        let mut residuals = [0i32; CHANNELS];
        let mut set = mask << 24;
        while set != 0 {
            let c = set.leading_zeros() as usize;
            set ^= 0x8000_0000 >> c;
            residuals[c] = unzigzag(bits.rice(k)?);
        }
        self.bits = bits;
        let (lo, hi) = self.range();
        for (c, residual) in residuals.into_iter().enumerate() {
            // In range: stored values are within i16 and a residual within 2^17.
            let next = 2 * self.stored[c] - self.before[c] + residual;
            if next < lo || next > hi {
                return Err(Error::KeyframeOutOfRange);
            }
            self.before[c] = self.stored[c];
            self.stored[c] = next;
        }
        Ok(())
    }

    /// A keyframe in which every channel follows its prediction.
    fn follow(&mut self) -> Result<(), Error> {
        let (lo, hi) = self.range();
        for c in 0..CHANNELS {
            // In range: stored values are within i16, so the prediction fits in i32.
            let next = 2 * self.stored[c] - self.before[c];
            if next < lo || next > hi {
                return Err(Error::KeyframeOutOfRange);
            }
            self.before[c] = self.stored[c];
            self.stored[c] = next;
        }
        Ok(())
    }

    /// Stored values allowed at this quantisation.
    fn range(&self) -> (i32, i32) {
        (
            i32::from(i16::MIN) >> self.shift,
            i32::from(i16::MAX) >> self.shift,
        )
    }

    /// Keyframes not yet decoded.
    pub fn remaining(&self) -> u32 {
        self.remaining
    }
}

impl Iterator for Keyframes<'_> {
    type Item = [i16; CHANNELS];

    fn next(&mut self) -> Option<Self::Item> {
        if self.remaining == 0 {
            return None;
        }
        self.try_next().ok()
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let n = self.remaining as usize;
        (n, Some(n))
    }
}

/// A residual from its code value, `zigzag(residual) - 1` (below 2^18, see
/// `bits::ESCAPE_BITS`, so the zigzag and the residual fit).
#[inline(always)]
fn unzigzag(code: u32) -> i32 {
    let zigzag = code + 1;
    ((zigzag >> 1) as i32) ^ -((zigzag & 1) as i32)
}

/// Checks a whole keyframe body against its header: every code, every stored value
/// in range, the padding and the end.
///
/// The work is O(bytes), whatever the keyframe count claims: a record costs its skip,
/// its mask and one step per channel it changes (each at least three bits, as the
/// Rice parameter is at least [`MIN_RICE_K`]). A channel between two of its changes,
/// and after its last, moves along a straight line, so it is checked where each line
/// ends: the values between lie on the way. This is the same test as playing every
/// keyframe with [`Keyframes`] (a property test holds them equal).
fn validate(body: &[u8], header: &Header<'_>) -> Result<(), Error> {
    let count = header.keyframe_count;
    let k = u32::from(header.residual_k);
    let lo = i64::from(i16::MIN >> header.quant_shift);
    let hi = i64::from(i16::MAX >> header.quant_shift);
    let mut bits = BitReader::new(body);
    // Per channel: the keyframes known (`known[c]`), the last one's stored value and
    // the step to it from the one before (all 0 before the first keyframe).
    let mut known = [0u32; CHANNELS];
    let mut value = [0i64; CHANNELS];
    let mut step = [0i64; CHANNELS];
    let in_range = |v: i64| {
        if v < lo || v > hi {
            Err(Error::KeyframeOutOfRange)
        } else {
            Ok(())
        }
    };
    // Keyframes described so far.
    let mut t = 0u32;
    while t < count {
        let skip = bits.exp_golomb()?;
        if skip > count - t {
            return Err(Error::BadKeyframes);
        }
        t += skip;
        if t == count {
            break;
        }
        let mask = bits.bits(8)?;
        if mask == 0 {
            return Err(Error::KeyframeOutOfRange);
        }
        let mut set = mask << 24;
        while set != 0 {
            let c = set.leading_zeros() as usize;
            set ^= 0x8000_0000 >> c;
            // Along the line to the keyframe before this one, then this one.
            let before = value[c] + i64::from(t - known[c]) * step[c];
            in_range(before)?;
            step[c] += i64::from(unzigzag(bits.rice(k)?));
            value[c] = before + step[c];
            in_range(value[c])?;
            known[c] = t + 1;
        }
        t += 1;
    }
    for c in 0..CHANNELS {
        in_range(value[c] + i64::from(count - known[c]) * step[c])?;
    }
    bits.finish()
}

/// Quantises a Q15 value to the stored resolution, rounding to nearest.
pub fn quantise(q15: i16, shift: u8) -> i32 {
    let shift = u32::from(shift.min(15));
    let lo = i32::from(i16::MIN) >> shift;
    let hi = i32::from(i16::MAX) >> shift;
    let half = if shift == 0 { 0 } else { 1 << (shift - 1) };
    ((i32::from(q15) + half) >> shift).clamp(lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A header of `count` keyframes for a body read at `shift` and `residual_k`.
    fn header(count: u32, shift: u8, residual_k: u8) -> Header<'static> {
        Header {
            channels: CHANNELS as u8,
            output_rate_hz: OUTPUT_RATE_HZ,
            keyframe_period_ms: 1,
            keyframe_count: count,
            duration_ms: count - 1,
            ramp_ms: 1,
            full_scale_ma: 1000,
            quant_shift: shift,
            residual_k,
            layout_hash: 0,
            layout: "t",
            limits: Limits::SLEEVE,
            name: "t",
        }
    }

    /// What playing every keyframe makes of `body`: accepted when each decodes and the
    /// body ends where the last does.
    fn played(body: &[u8], header: &Header<'_>) -> Result<(), Error> {
        let mut cursor = Keyframes {
            bits: BitReader::new(body),
            stored: [0; CHANNELS],
            before: [0; CHANNELS],
            idle_left: 0,
            change_due: false,
            shift: header.quant_shift,
            residual_k: u32::from(header.residual_k),
            remaining: header.keyframe_count,
        };
        for _ in 0..header.keyframe_count {
            cursor.try_next()?;
        }
        cursor.bits.finish()
    }

    proptest! {
        /// The check at decode, line ends only, accepts exactly the bodies that play
        /// keyframe by keyframe: from random bytes, and from encoded signals (steep
        /// ones, near the range's ends) with one bit flipped.
        #[test]
        fn validating_agrees_with_playing_every_keyframe(
            body in prop::collection::vec(any::<u8>(), 0..32),
            count in 1u32..64,
            shift in 0u8..=15,
            k in MIN_RICE_K..=MAX_RICE_K,
        ) {
            let h = header(count, shift, k);
            prop_assert_eq!(validate(&body, &h).is_ok(), played(&body, &h).is_ok());
        }

        #[test]
        fn validating_agrees_with_playing_a_damaged_encoding(
            frames in prop::collection::vec(prop::array::uniform8(any::<i16>()), 1..24),
            shift in 0u8..=15,
            flip in any::<prop::sample::Index>(),
            flipped in any::<bool>(),
        ) {
            let bytes = Builder::new("t", 1).quant_shift(shift).encode(&frames).unwrap();
            let s = Stimulus::decode(&bytes).unwrap();
            let (h, mut body) = (*s.header(), s.body.to_vec());
            prop_assert!(played(&body, &h).is_ok());
            if flipped && !body.is_empty() {
                let bit = flip.index(body.len() * 8);
                body[bit / 8] ^= 0x80 >> (bit % 8);
            }
            prop_assert_eq!(validate(&body, &h).is_ok(), played(&body, &h).is_ok());
        }
    }
}
