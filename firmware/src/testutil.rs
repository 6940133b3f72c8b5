//! Stimuli and banks for the host tests, made with the protocol crate's encoder.

use touch_protocol::{bank as tbank, stimulus, Limits, Stimulus, CHANNELS};

/// Ramp used by the test stimuli: slow enough for a 1 A step under the slew limit.
pub const RAMP_MS: u16 = 40;

/// A stimulus file from keyframes (Q15 of 1 A) every `period_ms`.
pub fn stimulus_from(
    name: &str,
    period_ms: u16,
    keyframes: &[[i16; CHANNELS]],
    limits: Limits,
) -> Vec<u8> {
    stimulus::Builder::new(name, period_ms)
        .ramp_ms(RAMP_MS)
        .limits(limits)
        .encode(keyframes)
        .expect("test stimulus encodes")
}

/// `file` encoded again for the layout geometry `layout_hash` under the same layout
/// name, as a compile for another sleeve would carry it.
pub fn for_layout(file: &[u8], layout_hash: u32) -> Vec<u8> {
    let s = Stimulus::decode(file).expect("test stimulus decodes");
    let frames: Vec<_> = s.keyframes().collect();
    stimulus::Builder::like(s.header())
        .layout(s.header().layout, layout_hash)
        .encode(&frames)
        .expect("test stimulus encodes")
}

/// All channels at `ma` milliamperes (channel c at `ma` * (c + 1) / 8) for `duration_ms`.
pub fn constant_stimulus(name: &str, ma: i32, duration_ms: u16) -> Vec<u8> {
    let mut frame = [0i16; CHANNELS];
    for (c, v) in frame.iter_mut().enumerate() {
        *v = (ma * 32767 / 1000 * (c as i32 + 1) / CHANNELS as i32) as i16;
    }
    let period = 40;
    let count = usize::from(duration_ms / period).max(1) + 1;
    stimulus_from(name, period, &vec![frame; count], Limits::SLEEVE)
}

/// A bank of the given stimulus files, slot order.
pub fn bank(stimuli: &[Vec<u8>]) -> Vec<u8> {
    let refs: Vec<&[u8]> = stimuli.iter().map(Vec::as_slice).collect();
    tbank::encode(&refs).expect("test bank encodes")
}

/// The boot check's worst case per byte: a bank of one stimulus in which every
/// keyframe changes one channel by one step (about 10.5 bits a keyframe, each a full
/// pass over the eight channels: the most records a byte can hold), as large as fits
/// in `limit` bytes.
pub fn dense_bank(limit: usize) -> Vec<u8> {
    // Channel 0's residuals +1, -1, -1, +1 (Rice codes `10`, `0`, `0`, `10`): its line
    // turns up, flat, down and flat again, so it stays in range.
    const RESIDUALS: [i32; 4] = [1, -1, -1, 1];
    let frames = |n: usize| -> Vec<[i16; CHANNELS]> {
        let (mut before, mut last) = (0i32, 0i32);
        (0..n)
            .map(|k| {
                let next = 2 * last - before + RESIDUALS[k % 4];
                (before, last) = (last, next);
                let mut f = [0i16; CHANNELS];
                f[0] = next as i16;
                f
            })
            .collect()
    };
    // Keyframes per byte measured on a sample; then shrink by the excess until the
    // bank (the stimulus plus 28 bytes of framing, layout hash and index) fits.
    let room = limit - 28;
    let sample = 8_000;
    let per_byte =
        sample as f64 / stimulus_from("dense", 1, &frames(sample), Limits::SLEEVE).len() as f64;
    let mut n = (room as f64 * per_byte) as usize;
    let mut one = stimulus_from("dense", 1, &frames(n), Limits::SLEEVE);
    while one.len() > room {
        n -= ((one.len() - room) as f64 * per_byte).ceil() as usize;
        one = stimulus_from("dense", 1, &frames(n), Limits::SLEEVE);
    }
    // Then more while they fit, in steps of most of the room left.
    loop {
        let step = (((room - one.len()) as f64 * per_byte * 0.8) as usize).max(4);
        let more = stimulus_from("dense", 1, &frames(n + step), Limits::SLEEVE);
        if more.len() > room {
            if step == 4 {
                return bank(&[one]);
            }
            // The estimate overshot: the next step is smaller.
            let fewer = stimulus_from("dense", 1, &frames(n + 4), Limits::SLEEVE);
            if fewer.len() > room {
                return bank(&[one]);
            }
            (n, one) = (n + 4, fewer);
            continue;
        }
        (n, one) = (n + step, more);
    }
}
