//! The stimulus encoder, behind a builder that takes only what the caller decides.
//!
//! A [`Header`] also holds what follows from the keyframes (their count and the
//! duration) and what the format fixes (channels, output rate); the container adds
//! magic, version, length and CRC. None of these can be given to the builder, so no
//! caller writes a value the encoder would overwrite or a file could contradict.

use crate::container;
use crate::{Error, Limits, CHANNELS};

use super::bits::{rice_len, BitWriter, MAX_RICE_K, MIN_RICE_K};
use super::{quantise, Header, HEADER_MAX_LEN, MAGIC, OUTPUT_RATE_HZ, VERSION};

/// The fields of a stimulus that its author decides, and the encoder.
///
/// ```
/// use touch_protocol::stimulus::{Builder, Stimulus};
/// let bytes = Builder::new("tap", 50)
///     .ramp_ms(20)
///     .quant_shift(4)
///     .layout("t", 1)
///     .encode(&[[0; 8], [1600, 0, 0, 0, 0, 0, 0, -160]])?;
/// assert_eq!(bytes.len(), 48); // 10 prefix + 30 header + 4 keyframes + 4 CRC
/// let decoded = Stimulus::decode(&bytes)?;
/// assert_eq!(decoded.duration_ms(), 50);
/// assert_eq!(decoded.keyframes().last(), Some([1600, 0, 0, 0, 0, 0, 0, -160]));
/// # Ok::<(), touch_protocol::Error>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Builder<'a> {
    name: &'a str,
    keyframe_period_ms: u16,
    ramp_ms: u16,
    full_scale_ma: u16,
    quant_shift: u8,
    layout: &'a str,
    layout_hash: u32,
    limits: Limits,
}

impl<'a> Builder<'a> {
    /// A stimulus named `name` with a keyframe every `keyframe_period_ms`, for the
    /// paper's sleeve ([`crate::layout::SLEEVE`]) and its limits ([`Limits::SLEEVE`]),
    /// 1 A full scale, a 10 ms ramp and every Q15 bit kept (quantisation shift 0);
    /// the other methods change these.
    pub const fn new(name: &'a str, keyframe_period_ms: u16) -> Self {
        Builder {
            name,
            keyframe_period_ms,
            ramp_ms: 10,
            full_scale_ma: 1000,
            quant_shift: 0,
            layout: crate::layout::SLEEVE_NAME,
            layout_hash: crate::layout::SLEEVE_HASH,
            limits: Limits::SLEEVE,
        }
    }

    /// What `header`'s author decided, to encode other keyframes the same way (or,
    /// changed by the other methods, almost the same way).
    pub const fn like(header: &Header<'a>) -> Self {
        Builder {
            name: header.name,
            keyframe_period_ms: header.keyframe_period_ms,
            ramp_ms: header.ramp_ms,
            full_scale_ma: header.full_scale_ma,
            quant_shift: header.quant_shift,
            layout: header.layout,
            layout_hash: header.layout_hash,
            limits: header.limits,
        }
    }

    /// The stimulus's name (at most [`super::MAX_NAME_LEN`] bytes).
    pub const fn name(self, name: &'a str) -> Self {
        Builder { name, ..self }
    }

    /// Time between keyframes, ms (1 to [`super::MAX_KEYFRAME_PERIOD_MS`]).
    pub const fn keyframe_period_ms(self, keyframe_period_ms: u16) -> Self {
        Builder {
            keyframe_period_ms,
            ..self
        }
    }

    /// The player's ramp from 0 A in, and back to 0 A after the end or a stop, ms.
    pub const fn ramp_ms(self, ramp_ms: u16) -> Self {
        Builder { ramp_ms, ..self }
    }

    /// The current that the Q15 value 32768 stands for, mA.
    pub const fn full_scale_ma(self, full_scale_ma: u16) -> Self {
        Builder {
            full_scale_ma,
            ..self
        }
    }

    /// Stored values keep Q15 `>> quant_shift` (0..=15): fewer bits, smaller files.
    pub const fn quant_shift(self, quant_shift: u8) -> Self {
        Builder {
            quant_shift,
            ..self
        }
    }

    /// The actuator layout the channels were compiled for: its name (for messages)
    /// and its [`crate::layout::geometry_hash`] (what a player compares).
    pub const fn layout(self, name: &'a str, geometry_hash: u32) -> Self {
        Builder {
            layout: name,
            layout_hash: geometry_hash,
            ..self
        }
    }

    /// The safety limits the signal was compiled and checked against.
    pub const fn limits(self, limits: Limits) -> Self {
        Builder { limits, ..self }
    }

    /// Encodes `keyframes`, Q15 values of the full scale a keyframe period apart,
    /// quantised to the builder's shift, with the Rice parameter that makes the body
    /// shortest (the smallest of equals). Refuses a field out of its range
    /// ([`Error::InvalidField`], naming it; no keyframe is `keyframe_count`) and a
    /// signal longer than the format holds.
    pub fn encode(&self, keyframes: &[[i16; CHANNELS]]) -> Result<Vec<u8>, Error> {
        let mut header = self.header(keyframes.len())?;
        let records = records(keyframes, header.quant_shift);
        header.residual_k = best_k(&records);
        let k = u32::from(header.residual_k);
        let mut head = [0u8; HEADER_MAX_LEN];
        let mut payload = postcard::to_slice(&header, &mut head)
            .map_err(|_| Error::BadHeader)?
            .to_vec();
        let mut body = BitWriter::default();
        for record in &records {
            body.exp_golomb(record.skip);
            if let Some((mask, residuals)) = &record.change {
                body.bits(u32::from(*mask), 8);
                for &v in residuals {
                    body.rice(v, k);
                }
            }
        }
        payload.extend_from_slice(&body.into_bytes());
        container::seal(MAGIC, VERSION, &payload)
    }

    /// The validated header of `count` keyframes: the builder's fields, the format's
    /// constants, and the count and duration that follow from `count`.
    fn header(&self, count: usize) -> Result<Header<'a>, Error> {
        let keyframe_count = u32::try_from(count).map_err(|_| Error::TooLarge)?;
        let span = u64::from(keyframe_count.saturating_sub(1)) * u64::from(self.keyframe_period_ms);
        let header = Header {
            channels: CHANNELS as u8,
            output_rate_hz: OUTPUT_RATE_HZ,
            keyframe_period_ms: self.keyframe_period_ms,
            keyframe_count,
            duration_ms: u32::try_from(span).map_err(|_| Error::TooLarge)?,
            ramp_ms: self.ramp_ms,
            full_scale_ma: self.full_scale_ma,
            quant_shift: self.quant_shift,
            residual_k: MIN_RICE_K,
            layout_hash: self.layout_hash,
            layout: self.layout,
            limits: self.limits,
            name: self.name,
        };
        header.validate()?;
        Ok(header)
    }
}

/// One record of the body: the keyframes it skips, then (unless they are the last)
/// a changing keyframe's mask (channel 0 in the first bit) and its residuals' code
/// values, `zigzag(residual) - 1`, in channel order.
struct Record {
    skip: u32,
    change: Option<(u8, Vec<u32>)>,
}

/// The records of `keyframes` stored at `shift`: each residual from the line through
/// the two stored values before it.
fn records(keyframes: &[[i16; CHANNELS]], shift: u8) -> Vec<Record> {
    let mut last = [0i32; CHANNELS];
    let mut before = [0i32; CHANNELS];
    let mut out = Vec::new();
    let mut skip = 0u32;
    for frame in keyframes {
        let mut mask = 0u8;
        let mut residuals = Vec::new();
        for (c, &q15) in frame.iter().enumerate() {
            let stored = quantise(q15, shift);
            let residual = stored - (2 * last[c] - before[c]);
            if residual != 0 {
                mask |= 0x80 >> c;
                // Nonzero, and below 2^17 in magnitude (stored values are i16).
                let zigzag = ((residual << 1) ^ (residual >> 31)) as u32;
                residuals.push(zigzag - 1);
            }
            before[c] = last[c];
            last[c] = stored;
        }
        if mask == 0 {
            skip += 1;
        } else {
            out.push(Record {
                skip,
                change: Some((mask, residuals)),
            });
            skip = 0;
        }
    }
    if skip > 0 {
        out.push(Record { skip, change: None });
    }
    out
}

/// The Rice parameter (from [`MIN_RICE_K`]) that codes every residual of `records` in
/// the fewest bits, the smallest of equals.
fn best_k(records: &[Record]) -> u8 {
    let mut bits = [0u64; (MAX_RICE_K - MIN_RICE_K) as usize + 1];
    for record in records {
        if let Some((_, residuals)) = &record.change {
            for &v in residuals {
                for (k, b) in (u32::from(MIN_RICE_K)..).zip(bits.iter_mut()) {
                    *b += u64::from(rice_len(v, k));
                }
            }
        }
    }
    (MIN_RICE_K..)
        .zip(bits)
        .min_by_key(|&(k, b)| (b, k))
        .map_or(MIN_RICE_K, |(k, _)| k)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::{SLEEVE_HASH, SLEEVE_NAME};
    use crate::Stimulus;

    #[test]
    fn the_defaults_are_the_sleeves_and_the_counts_follow_the_keyframes() {
        let bytes = Builder::new("still", 40).encode(&[[0; 8]; 26]).unwrap();
        let h = *Stimulus::decode(&bytes).unwrap().header();
        assert_eq!(
            h,
            Header {
                channels: 8,
                output_rate_hz: 1000,
                keyframe_period_ms: 40,
                keyframe_count: 26,
                duration_ms: 1000,
                ramp_ms: 10,
                full_scale_ma: 1000,
                quant_shift: 0,
                residual_k: 2,
                layout_hash: SLEEVE_HASH,
                layout: SLEEVE_NAME,
                limits: Limits::SLEEVE,
                name: "still",
            }
        );
    }

    #[test]
    fn every_decided_field_reaches_the_header() {
        let hot = Limits {
            peak_ma: 900,
            ..Limits::SLEEVE
        };
        let bytes = Builder::new("a", 40)
            .name("b")
            .keyframe_period_ms(25)
            .ramp_ms(7)
            .full_scale_ma(2000)
            .quant_shift(3)
            .layout("other", 0x0403_0201)
            .limits(hot)
            .encode(&[[0; 8], [800; 8]])
            .unwrap();
        let s = Stimulus::decode(&bytes).unwrap();
        let h = s.header();
        assert_eq!((h.name, h.keyframe_period_ms, h.ramp_ms), ("b", 25, 7));
        assert_eq!((h.full_scale_ma, h.quant_shift), (2000, 3));
        assert_eq!(
            (h.layout, h.layout_hash, h.limits),
            ("other", 0x0403_0201, hot)
        );
        assert_eq!((h.keyframe_count, h.duration_ms), (2, 25));
        assert_eq!(s.keyframes().last(), Some([800; 8]));
    }

    #[test]
    fn like_a_header_encodes_the_same_file_again() {
        let first = Builder::new("wave", 20)
            .quant_shift(2)
            .layout("t", 9)
            .encode(&[[0; 8], [400; 8], [-1200; 8], [0; 8], [0; 8]])
            .unwrap();
        let s = Stimulus::decode(&first).unwrap();
        let frames: Vec<_> = s.keyframes().collect();
        assert_eq!(Builder::like(s.header()).encode(&frames).unwrap(), first);
    }

    #[test]
    fn a_field_out_of_range_is_named() {
        let long = "a name longer than thirty-two bytes";
        let cases = [
            (Builder::new("x", 40).encode(&[]), "keyframe_count"),
            (Builder::new("x", 0).encode(&[[0; 8]]), "keyframe_period_ms"),
            (
                Builder::new("x", 40).ramp_ms(0).encode(&[[0; 8]]),
                "ramp_ms",
            ),
            (Builder::new(long, 40).encode(&[[0; 8]]), "name"),
            (
                Builder::new("x", 40).quant_shift(16).encode(&[[0; 8]]),
                "quant_shift",
            ),
        ];
        for (result, field) in cases {
            assert_eq!(result, Err(Error::InvalidField(field)));
        }
    }
}
