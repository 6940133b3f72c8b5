//! Stimulus files built in the tests that drive the CLI.

use touch_protocol::{stimulus, Limits};

/// A stimulus named `name` with keyframes every 40 ms (`keyframes` in amperes, 1 A full
/// scale), a 10 ms ramp and the sleeve's limits.
pub fn stimulus(name: &str, keyframes: &[[f64; 8]]) -> Vec<u8> {
    let header = header(name, 40);
    let q = |a: f64| (a * 32768.0).round().clamp(-32768.0, 32767.0) as i16;
    let kf: Vec<[i16; 8]> = keyframes.iter().map(|k| k.map(q)).collect();
    stimulus::encode(header, &kf).unwrap()
}

/// The header the tests' stimuli share: 1 A full scale, a 10 ms ramp, the sleeve's
/// limits; the encoder fills in the counts.
fn header(name: &str, keyframe_period_ms: u16) -> stimulus::Header<'_> {
    stimulus::Header {
        channels: 8,
        output_rate_hz: 1000,
        keyframe_period_ms,
        keyframe_count: 0,
        duration_ms: 0,
        ramp_ms: 10,
        full_scale_ma: 1000,
        quant_shift: 5,
        layout_hash: touch_protocol::layout::SLEEVE_HASH,
        layout: touch_protocol::layout::SLEEVE_NAME,
        limits: Limits::SLEEVE,
        name,
    }
}

/// A channel's current in amperes over the stimulus, `x` from 0 to 1.
pub type Shape = fn(f64) -> f64;

/// 26 keyframes (1 s): every channel ramps to `rest(x)` A and back, except that
/// `special` channels follow their own function of `x` in `[0, 1]` (scaled by the same
/// ramp).
pub fn one_second(rest: f64, special: &[(usize, Shape)]) -> Vec<[f64; 8]> {
    (0..26)
        .map(|k| {
            let x = k as f64 / 25.0;
            let ramp = (x * 5.0).min(1.0).min((1.0 - x) * 5.0);
            let mut f = [rest * ramp; 8];
            for &(ch, shape) in special {
                f[ch] = ramp * shape(x);
            }
            f
        })
        .collect()
}

/// A stimulus of `seconds` s, `name`d as given: one keyframe per second, every channel
/// rising to 0.3 A in the first second and holding there (a run, so a few dozen bytes
/// however long).
pub fn long(name: &str, seconds: u32) -> Vec<u8> {
    let header = header(name, 1000);
    let hold = (0.3f64 * 32768.0).round() as i16;
    let kf: Vec<[i16; 8]> = (0..=seconds)
        .map(|k| if k == 0 { [0; 8] } else { [hold; 8] })
        .collect();
    stimulus::encode(header, &kf).unwrap()
}
