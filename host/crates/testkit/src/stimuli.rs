//! Stimulus files built in the tests that drive the CLI.

use touch_protocol::stimulus::Builder;
use touch_protocol::Stimulus;

/// A stimulus named `name` with keyframes every 40 ms (`keyframes` in amperes, 1 A full
/// scale), a 10 ms ramp and the sleeve's limits.
pub fn stimulus(name: &str, keyframes: &[[f64; 8]]) -> Vec<u8> {
    let q = |a: f64| (a * 32768.0).round().clamp(-32768.0, 32767.0) as i16;
    let kf: Vec<[i16; 8]> = keyframes.iter().map(|k| k.map(q)).collect();
    builder(name, 40).encode(&kf).unwrap()
}

/// The encoder the tests' stimuli share: the sleeve's (1 A full scale, a 10 ms ramp,
/// its layout and limits), 5 bits dropped.
fn builder(name: &str, keyframe_period_ms: u16) -> Builder<'_> {
    Builder::new(name, keyframe_period_ms).quant_shift(5)
}

/// `file` encoded again with what `change` makes of its author's decisions (a field
/// the tests want otherwise), the keyframes as they were.
pub fn reencoded<'a>(file: &'a [u8], change: impl FnOnce(Builder<'a>) -> Builder<'a>) -> Vec<u8> {
    let s = Stimulus::decode(file).unwrap();
    let keyframes: Vec<_> = s.keyframes().collect();
    change(Builder::like(s.header()))
        .encode(&keyframes)
        .unwrap()
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
    let hold = (0.3f64 * 32768.0).round() as i16;
    let kf: Vec<[i16; 8]> = (0..=seconds)
        .map(|k| if k == 0 { [0; 8] } else { [hold; 8] })
        .collect();
    builder(name, 1000).encode(&kf).unwrap()
}
