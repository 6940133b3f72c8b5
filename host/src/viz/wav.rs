//! `touchc render --wav`: the drive signal as an 8-channel WAV, for labs that drive
//! voice coils from a multichannel audio interface instead of the sleeve's board.
//!
//! Choices, each for that use:
//! - **16-bit PCM**, because every audio interface and player takes it, and it loses
//!   nothing: the player's codes are 12-bit, and a code maps to exactly
//!   `(code - 2048) * 16`, so code 0 (-full scale) is -32768 and 0 A is 0.
//!   Full scale of the file = the device's full scale (1 A on the sleeve at 1 A/V):
//!   an interface whose full-scale output drives the coil amplifier to the sleeve's
//!   full scale reproduces the sleeve's currents.
//! - **Linear interpolation between 1 kHz ticks.** A zero-order hold would repeat the
//!   DAC's 1 ms staircase, whose steps put energy at 1 kHz and its harmonics, well
//!   inside the coil's band and audible; the signal itself is band-limited to a few
//!   hertz, so the straight line between two ticks is closer to what the sleeve's
//!   output stage intends. Interpolation is integer arithmetic, so a file is the same
//!   on every machine, and at 1000 Hz the samples are the codes themselves.
//! - **WAVE_FORMAT_EXTENSIBLE** (a 68-byte header), because the plain 44-byte PCM header
//!   is only defined for up to 2 channels; the channel mask is 0: the channels are
//!   actuators, not speakers, so no speaker position is claimed and players keep the
//!   file's order, which is the sleeve's channel order (`row * 4 + column`).

use touch_protocol::{CHANNELS, IDLE_CODE};

/// Sample rates accepted, Hz: at least the player's 1 kHz (lower would alias the ticks),
/// at most what audio interfaces offer.
pub const RATE_HZ: (u32, u32) = (1000, 768_000);

/// Bytes before the samples: RIFF (12) + `fmt ` extensible (8 + 40) + `data` (8).
pub const HEADER_LEN: usize = 68;

/// Bytes per sample frame: 8 channels of 16 bits.
const BLOCK_ALIGN: u16 = (CHANNELS * 2) as u16;

/// KSDATAFORMAT_SUBTYPE_PCM, as stored (first three fields little-endian).
const SUBTYPE_PCM: [u8; 16] = [
    0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x10, 0x00, 0x80, 0x00, 0x00, 0xAA, 0x00, 0x38, 0x9B, 0x71,
];

/// Why a WAV could not be written.
#[derive(Debug, Clone, thiserror::Error, PartialEq, Eq)]
#[non_exhaustive]
pub enum WavError {
    /// The sample rate is outside [`RATE_HZ`].
    #[error("sample rate {0} Hz is outside 1000 ..= 768000 Hz")]
    Rate(u32),
    /// The samples would not fit in a RIFF file's 32-bit sizes (4 GiB).
    #[error("{frames} sample frames do not fit in a WAV file (4 GiB at most)")]
    TooLong {
        /// Sample frames that were asked for.
        frames: u64,
    },
}

/// The 68-byte header of a file holding `frames` sample frames at `rate` Hz.
pub fn header(rate: u32, frames: u32) -> Result<[u8; HEADER_LEN], WavError> {
    let data_len = u64::from(frames) * u64::from(BLOCK_ALIGN);
    let riff_len = data_len + HEADER_LEN as u64 - 8;
    let riff_len = u32::try_from(riff_len).map_err(|_| WavError::TooLong {
        frames: u64::from(frames),
    })?;
    let mut h = [0u8; HEADER_LEN];
    let mut at = 0;
    let mut put = |bytes: &[u8]| {
        h[at..at + bytes.len()].copy_from_slice(bytes);
        at += bytes.len();
    };
    put(b"RIFF");
    put(&riff_len.to_le_bytes());
    put(b"WAVE");
    put(b"fmt ");
    put(&40u32.to_le_bytes());
    put(&0xFFFEu16.to_le_bytes()); // WAVE_FORMAT_EXTENSIBLE
    put(&(CHANNELS as u16).to_le_bytes());
    put(&rate.to_le_bytes());
    put(&rate.saturating_mul(u32::from(BLOCK_ALIGN)).to_le_bytes()); // bytes per second
    put(&BLOCK_ALIGN.to_le_bytes());
    put(&16u16.to_le_bytes()); // bits per sample (container)
    put(&22u16.to_le_bytes()); // size of the extension
    put(&16u16.to_le_bytes()); // valid bits per sample
    put(&0u32.to_le_bytes()); // channel mask: no speaker positions
    put(&SUBTYPE_PCM);
    put(b"data");
    put(&(data_len as u32).to_le_bytes());
    Ok(h)
}

/// Number of sample frames at `rate` Hz for `ticks` 1 kHz ticks: from the first tick's
/// instant through the last one's, inclusive.
pub fn frames_for(ticks: usize, rate: u32) -> u64 {
    match ticks {
        0 => 0,
        n => (n as u64 - 1) * u64::from(rate) / 1000 + 1,
    }
}

/// Most 1 kHz ticks a WAV at `rate` Hz can hold (its sizes are 32-bit), so that a caller
/// counting a stimulus's ticks can stop counting there.
pub fn max_ticks(rate: u32) -> usize {
    // The RIFF size (everything after its first 8 bytes) is the binding 32-bit field.
    let frames = (u64::from(u32::MAX) - (HEADER_LEN as u64 - 8)) / u64::from(BLOCK_ALIGN);
    // The largest n with (n - 1) * rate / 1000 + 1 <= frames (see `frames_for`).
    let ticks = (1000 * frames - 1) / u64::from(rate.max(1)) + 1;
    usize::try_from(ticks).unwrap_or(usize::MAX)
}

/// A WAV file's shape: `ticks` ticks of the player resampled to `rate` Hz, checked to
/// fit the format before a byte is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Wav {
    rate: u32,
    ticks: usize,
    frames: u32,
}

impl Wav {
    /// Checks the rate against [`RATE_HZ`] and the length against the format's 4 GiB.
    pub fn new(ticks: usize, rate: u32) -> Result<Wav, WavError> {
        if !(RATE_HZ.0..=RATE_HZ.1).contains(&rate) {
            return Err(WavError::Rate(rate));
        }
        let frames = frames_for(ticks, rate);
        let too_long = WavError::TooLong { frames };
        let frames = u32::try_from(frames).map_err(|_| too_long.clone())?;
        header(rate, frames)?;
        Ok(Wav {
            rate,
            ticks,
            frames,
        })
    }

    /// Bytes of the whole file.
    pub fn len(&self) -> u64 {
        HEADER_LEN as u64 + u64::from(self.frames) * u64::from(BLOCK_ALIGN)
    }

    /// Whether the file holds no samples (a stimulus of no ticks).
    pub fn is_empty(&self) -> bool {
        self.frames == 0
    }

    /// Streams the file into `out`: the header, then the samples interpolated from
    /// `codes` (the player's output, one entry per 1 kHz tick, see [`super::play`]),
    /// holding two ticks at a time. `codes` must yield the `ticks` given to
    /// [`Wav::new`]; missing ticks repeat the last one, extra ones are ignored.
    pub fn write(
        &self,
        out: &mut impl std::io::Write,
        codes: impl IntoIterator<Item = [u16; CHANNELS]>,
    ) -> std::io::Result<()> {
        let head = header(self.rate, self.frames).map_err(std::io::Error::other)?;
        out.write_all(&head)?;
        let mut codes = codes.into_iter().take(self.ticks);
        let Some(mut a) = codes.next() else {
            return Ok(());
        };
        let mut next = codes.next();
        let mut at = 0i64;
        let rate = i64::from(self.rate);
        let mut frame = [0u8; BLOCK_ALIGN as usize];
        for m in 0..i64::from(self.frames) {
            // Sample m sits at m / rate s = tick (m * 1000 / rate) plus a fraction.
            let pos = m * 1000;
            let (n, frac) = (pos / rate, pos % rate);
            while at < n {
                a = next.unwrap_or(a);
                next = codes.next();
                at += 1;
            }
            let b = next.unwrap_or(a);
            for ch in 0..CHANNELS {
                let (ca, cb) = (offset(a[ch]), offset(b[ch]));
                // Rounded to nearest, half away from zero, in units of 1/16 code.
                let num = (ca * (rate - frac) + cb * frac) * 16;
                let v = (num + num.signum() * (rate / 2)) / rate;
                let v = v.clamp(i64::from(i16::MIN), i64::from(i16::MAX)) as i16;
                frame[2 * ch..2 * ch + 2].copy_from_slice(&v.to_le_bytes());
            }
            out.write_all(&frame)?;
        }
        Ok(())
    }
}

/// A code's distance from the idle code (0 A).
fn offset(code: u16) -> i64 {
    i64::from(code) - i64::from(IDLE_CODE)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The whole file in memory.
    fn encode(codes: &[[u16; CHANNELS]], rate: u32) -> Result<Vec<u8>, WavError> {
        let wav = Wav::new(codes.len(), rate)?;
        let mut out = Vec::new();
        wav.write(&mut out, codes.iter().copied()).unwrap();
        assert_eq!(out.len() as u64, wav.len());
        Ok(out)
    }

    #[test]
    fn header_bytes_are_pinned() {
        let h = header(48_000, 3).unwrap();
        #[rustfmt::skip]
        let expected: [u8; HEADER_LEN] = [
            b'R', b'I', b'F', b'F', 0x6C, 0x00, 0x00, 0x00, b'W', b'A', b'V', b'E', // 108 bytes follow
            b'f', b'm', b't', b' ', 0x28, 0x00, 0x00, 0x00, // fmt chunk, 40 bytes
            0xFE, 0xFF, 0x08, 0x00, // extensible, 8 channels
            0x80, 0xBB, 0x00, 0x00, // 48000 Hz
            0x00, 0xB8, 0x0B, 0x00, // 768000 bytes per second
            0x10, 0x00, 0x10, 0x00, // block align 16, 16 bits
            0x16, 0x00, 0x10, 0x00, // 22 extension bytes, 16 valid bits
            0x00, 0x00, 0x00, 0x00, // no speaker mask
            0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x10, 0x00,
            0x80, 0x00, 0x00, 0xAA, 0x00, 0x38, 0x9B, 0x71, // PCM subtype GUID
            b'd', b'a', b't', b'a', 0x30, 0x00, 0x00, 0x00, // 3 frames x 16 bytes
        ];
        assert_eq!(h, expected);
    }

    #[test]
    fn at_1khz_samples_are_the_codes_times_16() {
        let codes = [[2048, 0, 4095, 2049, 2047, 2048, 3072, 1024]; 3];
        let wav = encode(&codes, 1000).unwrap();
        assert_eq!(wav.len(), HEADER_LEN + 3 * 16);
        let s: Vec<i16> = wav[HEADER_LEN..]
            .chunks(2)
            .map(|b| i16::from_le_bytes([b[0], b[1]]))
            .collect();
        assert_eq!(&s[..8], &[0, -32768, 32752, 16, -16, 0, 16384, -16384]);
        assert_eq!(&s[8..16], &s[..8]);
    }

    #[test]
    fn resampling_interpolates_linearly_between_ticks() {
        // Channel 0 goes 0 -> +100 codes over one tick; channel 1 holds -1 code.
        let codes = [
            [2048, 2047, 2048, 2048, 2048, 2048, 2048, 2048],
            [2148, 2047, 2048, 2048, 2048, 2048, 2048, 2048],
        ];
        let wav = encode(&codes, 4000).unwrap();
        // Two ticks 1 ms apart at 4 kHz: samples at 0, 0.25, 0.5, 0.75, 1 ms.
        assert_eq!(frames_for(2, 4000), 5);
        assert_eq!(wav.len(), HEADER_LEN + 5 * 16);
        let ch = |c: usize| -> Vec<i16> {
            (0..5)
                .map(|m| {
                    let i = HEADER_LEN + m * 16 + 2 * c;
                    i16::from_le_bytes([wav[i], wav[i + 1]])
                })
                .collect()
        };
        assert_eq!(ch(0), [0, 400, 800, 1200, 1600]);
        assert_eq!(ch(1), [-16; 5]);
        // 44.1 kHz: not a multiple of 1 kHz; sample 22 is at 0.4989 ms.
        let wav = encode(&codes, 44_100).unwrap();
        let i = HEADER_LEN + 22 * 16;
        let v = i16::from_le_bytes([wav[i], wav[i + 1]]);
        assert_eq!(v, (1600.0f64 * 22.0 * 1000.0 / 44_100.0).round() as i16);
    }

    #[test]
    fn bad_rates_and_oversized_files_are_refused() {
        let codes = [[2048; 8]];
        assert_eq!(encode(&codes, 999), Err(WavError::Rate(999)));
        assert_eq!(encode(&codes, 768_001), Err(WavError::Rate(768_001)));
        assert!(matches!(
            header(48_000, u32::MAX / 8),
            Err(WavError::TooLong { .. })
        ));
        let empty = encode(&[], 48_000).unwrap();
        assert_eq!(empty.len(), HEADER_LEN);
        // The longest WAV at each rate fits, one tick more does not.
        for rate in [1000, 44_100, 48_000, 768_000] {
            assert!(Wav::new(max_ticks(rate), rate).is_ok(), "{rate}");
            assert!(Wav::new(max_ticks(rate) + 1, rate).is_err(), "{rate}");
        }
    }
}
