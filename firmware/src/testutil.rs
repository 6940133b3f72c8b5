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

/// The boot check's worst case per byte: a bank of one stimulus whose records
/// alternate a one-residual change and a run of one (two bytes per keyframe, each
/// keyframe a full pass over the eight channels), as large as fits in `limit` bytes.
pub fn dense_bank(limit: usize) -> Vec<u8> {
    // Channel 0's residuals +1, 0, -1, 0, -1, 0, +1, 0 (the zeros are runs of one):
    // its line turns up, flat, down and flat again, so it stays in range.
    const RESIDUALS: [i32; 8] = [1, 0, -1, 0, -1, 0, 1, 0];
    let frames = |n: usize| -> Vec<[i16; CHANNELS]> {
        let (mut before, mut last) = (0i32, 0i32);
        (0..n)
            .map(|k| {
                let next = 2 * last - before + RESIDUALS[k % 8];
                (before, last) = (last, next);
                let mut f = [0i16; CHANNELS];
                f[0] = next as i16;
                f
            })
            .collect()
    };
    // About two bytes a keyframe; shrink by the excess until the bank (the stimulus
    // plus 28 bytes of framing, layout hash and index) fits.
    let room = limit - 28;
    let mut n = room / 2;
    loop {
        let one = stimulus_from("dense", 1, &frames(n), Limits::SLEEVE);
        if one.len() <= room {
            return bank(&[one]);
        }
        n -= (one.len() - room).div_ceil(2);
    }
}
