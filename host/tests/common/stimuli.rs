//! Stimulus files built in the tests (`#[path]`-included by the CLI tests).

use touch_protocol::{stimulus, Limits};

/// A stimulus named `name` with keyframes every 40 ms (`keyframes` in amperes, 1 A full
/// scale), a 10 ms ramp and the sleeve's limits.
pub fn stimulus(name: &str, keyframes: &[[f64; 8]]) -> Vec<u8> {
    let header = stimulus::Header {
        channels: 8,
        output_rate_hz: 1000,
        keyframe_period_ms: 40,
        keyframe_count: 0,
        duration_ms: 0,
        ramp_ms: 10,
        full_scale_ma: 1000,
        quant_shift: 5,
        layout_id: touch_protocol::SLEEVE_LAYOUT_ID,
        limits: Limits::SLEEVE,
        name,
    };
    let q = |a: f64| (a * 32768.0).round().clamp(-32768.0, 32767.0) as i16;
    let kf: Vec<[i16; 8]> = keyframes.iter().map(|k| k.map(q)).collect();
    stimulus::encode(header, &kf).unwrap()
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
