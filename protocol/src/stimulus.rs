//! The stimulus file: one haptic pattern for the eight channels.
//!
//! A container (see [`crate::container`]) with magic `b"TCHS"` whose payload is a
//! postcard [`Header`] followed by the keyframe body. The body holds
//! `keyframe_count` records, one per keyframe, for all channels at once (so the
//! player streams it with a single cursor):
//!
//! ```text
//! mask: u8 != 0                  bit c set = channel c left its linear prediction
//! residual: postcard i32 (zigzag varint), once per set bit, channel order
//! ```
//!
//! or, for a run of keyframes in which every channel follows its prediction,
//!
//! ```text
//! 0x00, run: postcard u32 (varint) number of keyframes in the run (>= 1)
//! ```
//!
//! Each channel's stored value `s[k]` is predicted by extending the line through
//! the two before it, `2 s[k-1] - s[k-2]` (both 0 before the first keyframe), and
//! the record holds only the residual. A band-limited signal bends slowly, so the
//! residuals are small (one varint byte) where plain deltas would need two, and a
//! stretch where every channel holds still or ramps costs two bytes however long.
//! The current a stored value stands for is `(s << quant_shift) / 32768 *
//! full_scale_ma` mA (Q15 of the full scale). A set bit with a zero residual, or two
//! runs in a row, is refused, so every signal
//! has exactly one encoding. `SPEC.md` describes every byte.

use serde::{Deserialize, Serialize};

use crate::container::{self, Container};
use crate::{Error, Limits, CHANNELS};

#[cfg(any(test, feature = "std"))]
mod builder;
#[cfg(any(test, feature = "std"))]
pub use builder::Builder;

/// Magic of a stimulus file.
pub const MAGIC: [u8; 4] = *b"TCHS";
/// The stimulus format version this build reads and writes.
pub const VERSION: u16 = 2;
/// The only output rate the format defines, Hz.
pub const OUTPUT_RATE_HZ: u16 = 1000;
/// Longest name, bytes of UTF-8.
pub const MAX_NAME_LEN: usize = 32;
/// Longest keyframe period, ms (one keyframe per second).
pub const MAX_KEYFRAME_PERIOD_MS: u16 = 1000;
/// Upper bound of an encoded header, bytes (fixed fields plus the longest names).
pub const HEADER_MAX_LEN: usize = 42 + crate::layout::MAX_NAME_LEN + MAX_NAME_LEN;
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
    /// The work is O(bytes), whatever the keyframe count: a run record is checked
    /// in one step (each channel moves along a line, so its ends bound it), and
    /// every other record is at least one byte.
    pub fn decode(bytes: &'a [u8]) -> Result<Self, Error> {
        let stimulus = Stimulus::parse(bytes, true)?;
        let mut cursor = stimulus.keyframes();
        while cursor.remaining > 0 {
            cursor.skip_record()?;
        }
        if !cursor.rest.is_empty() {
            return Err(Error::TrailingBytes);
        }
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
            rest: self.body,
            stored: [0; CHANNELS],
            before: [0; CHANNELS],
            idle_left: 0,
            after_run: false,
            shift: self.header.quant_shift,
            remaining: self.header.keyframe_count,
        }
    }
}

/// Streaming keyframe decoder: one cursor over the body and the running values.
#[derive(Debug, Clone)]
pub struct Keyframes<'a> {
    rest: &'a [u8],
    /// Stored values of the last keyframe, `s[k-1]`.
    stored: [i32; CHANNELS],
    /// Stored values of the keyframe before it, `s[k-2]`.
    before: [i32; CHANNELS],
    /// Keyframes left in the current idle run.
    idle_left: u32,
    /// The last record read was an idle run (two in a row are not canonical).
    after_run: bool,
    shift: u8,
    remaining: u32,
}

impl Keyframes<'_> {
    /// Decodes the next keyframe, or reports malformed data.
    ///
    /// On a [`Stimulus`] this cannot fail: decoding validated every keyframe.
    pub fn try_next(&mut self) -> Result<[i16; CHANNELS], Error> {
        if self.idle_left > 0 {
            self.idle_left -= 1;
            self.follow(1)?;
        } else {
            self.record()?;
        }
        self.remaining = self.remaining.saturating_sub(1);
        let mut out = [0i16; CHANNELS];
        for (o, &s) in out.iter_mut().zip(&self.stored) {
            // In range by the checks in `follow` and `record`: |s << shift| fits i16.
            *o = (s << self.shift) as i16;
        }
        Ok(out)
    }

    /// Validates the next record whole: one keyframe, or a whole run in one step.
    fn skip_record(&mut self) -> Result<(), Error> {
        if self.idle_left == 0 {
            self.record()?;
            self.remaining -= 1;
        }
        let n = self.idle_left;
        if n > 0 {
            self.idle_left = 0;
            self.follow(n)?;
            self.remaining -= n;
        }
        Ok(())
    }

    /// Reads one record and applies its first keyframe (a run leaves `idle_left`).
    fn record(&mut self) -> Result<(), Error> {
        let (&mask, rest) = self.rest.split_first().ok_or(Error::BadKeyframes)?;
        self.rest = rest;
        if mask == 0 {
            // A run of keyframes that all follow their prediction.
            if self.after_run {
                return Err(Error::KeyframeOutOfRange);
            }
            let (run, rest) = take_varint(self.rest).ok_or(Error::BadKeyframes)?;
            self.rest = rest;
            if run == 0 || run > self.remaining {
                return Err(Error::BadKeyframes);
            }
            self.after_run = true;
            self.idle_left = run - 1;
            return self.follow(1);
        }
        self.after_run = false;
        let (lo, hi) = self.range();
        // The cursor and the mask stay in registers for the whole record: this runs
        // in the sleeve's tick at every keyframe boundary.
        let mut rest = self.rest;
        let mut bits = mask;
        for c in 0..CHANNELS {
            // In range: stored values are within i16, so the prediction fits in i32.
            let mut next = 2 * self.stored[c] - self.before[c];
            if bits & 1 != 0 {
                let (zigzag, tail) = take_varint(rest).ok_or(Error::BadKeyframes)?;
                rest = tail;
                if zigzag == 0 {
                    return Err(Error::KeyframeOutOfRange);
                }
                let residual = ((zigzag >> 1) as i32) ^ -((zigzag & 1) as i32);
                next = next
                    .checked_add(residual)
                    .ok_or(Error::KeyframeOutOfRange)?;
            }
            bits >>= 1;
            if next < lo || next > hi {
                return Err(Error::KeyframeOutOfRange);
            }
            self.before[c] = self.stored[c];
            self.stored[c] = next;
        }
        self.rest = rest;
        Ok(())
    }

    /// `n >= 1` keyframes in which every channel follows its prediction: each moves
    /// `n` steps along its line. The line is monotone, so checking where it ends
    /// checks every keyframe on the way.
    fn follow(&mut self, n: u32) -> Result<(), Error> {
        let (lo, hi) = self.range();
        for c in 0..CHANNELS {
            let step = self.stored[c] - self.before[c];
            let last = i64::from(self.stored[c]) + i64::from(n) * i64::from(step);
            if last < i64::from(lo) || last > i64::from(hi) {
                return Err(Error::KeyframeOutOfRange);
            }
            // In range: `last` is, and so is the value before it on the line.
            self.stored[c] = last as i32;
            self.before[c] = last as i32 - step;
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

/// Takes one postcard varint `u32` off `bytes`, accepting exactly what
/// `postcard::take_from_bytes::<u32>` does (at most five bytes, the fifth below 16,
/// a longer than needed encoding allowed): the same bytes give the same value and
/// the same rest, or a refusal from both. Postcard's general deserializer costs the
/// sleeve's keyframe boundary tick some hundred instructions more; most residuals
/// are one byte, the first test.
#[inline(always)]
fn take_varint(bytes: &[u8]) -> Option<(u32, &[u8])> {
    let (&first, mut rest) = bytes.split_first()?;
    if first & 0x80 == 0 {
        return Some((u32::from(first), rest));
    }
    let mut out = u32::from(first & 0x7F);
    for i in 1..5 {
        let (&byte, tail) = rest.split_first()?;
        rest = tail;
        out |= u32::from(byte & 0x7F) << (7 * i);
        if byte & 0x80 == 0 {
            return (i < 4 || byte <= 0x0F).then_some((out, rest));
        }
    }
    None
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

    /// The body's varint reader against postcard's own, over every length, the
    /// values at each byte's edges, over-long encodings, bad last bytes and
    /// truncation: the same value and the same bytes left, or a refusal from both.
    #[test]
    fn varint_reads_what_postcard_reads() {
        let edges = [0x00u8, 0x01, 0x0F, 0x10, 0x7F, 0x80, 0x81, 0x8F, 0x90, 0xFF];
        let mut inputs: Vec<Vec<u8>> = vec![vec![]];
        for len in 1..=6 {
            let mut next = Vec::new();
            for prefix in inputs.iter().filter(|p| p.len() == len - 1) {
                for &b in &edges {
                    let mut v = prefix.clone();
                    v.push(b);
                    next.push(v);
                }
            }
            inputs.extend(next);
        }
        for v in [
            0u32,
            1,
            63,
            64,
            127,
            128,
            16_383,
            16_384,
            u32::MAX / 2,
            u32::MAX,
        ] {
            let mut buf = [0u8; 5];
            inputs.push(postcard::to_slice(&v, &mut buf).unwrap().to_vec());
        }
        for bytes in &inputs {
            let mut with_tail = bytes.clone();
            with_tail.push(0xAA);
            for input in [bytes, &with_tail] {
                let ours = take_varint(input);
                let theirs = postcard::take_from_bytes::<u32>(input).ok();
                assert_eq!(ours, theirs, "{input:02x?}");
            }
        }
    }
}
