//! Synthetic recordings the tests, benches and examples share, and a CPU clock for
//! the benches.

use ndarray::Array3;
use touchc_synth::{self as synth, Gesture, Mask, Sensor, SynthSpec, Tuning};

use crate::rng::Xorshift;

/// True where the 8 x 21 sleeve has a sensor cell: 142 cells (26 NaN at two edges).
pub fn sleeve_mask(r: usize, c: usize) -> bool {
    !((r == 0 || r == 7) && c < 13)
}

/// `[frames, 8, 21]` psi: quiet tare frames, then `blobs` Gaussian contacts moving along
/// the arm, 0.004 psi noise, NaN outside the 142-cell sleeve.
pub fn moving_blobs(frames: usize, blobs: usize, seed: u64) -> Array3<f64> {
    let mut noise = Xorshift::mixed(seed);
    let mut a = Array3::<f64>::zeros((frames, 8, 21));
    for t in 0..frames {
        for r in 0..8 {
            for c in 0..21 {
                if !sleeve_mask(r, c) {
                    a[[t, r, c]] = f64::NAN;
                    continue;
                }
                let mut v = 0.004 * noise.signed();
                if t >= 20 && t + 20 < frames {
                    for b in 0..blobs {
                        // Blob b recurs every 90 + 17 b frames, pressing for 60 of them
                        // while it slides along the arm: many contacts, some overlapping.
                        let period = 90 + 17 * b;
                        let age = (t + period - (20 + 13 * b) % period) % period;
                        if age >= 60 {
                            continue;
                        }
                        let x = 2.0 + age as f64 * 0.28 + (b as f64 * 1.3) % 5.0;
                        let y = 2.0 + (b % 4) as f64;
                        let d2 = (c as f64 - x).powi(2) + (r as f64 - y).powi(2);
                        v += 0.6 * (-d2 / 1.5).exp();
                    }
                }
                a[[t, r, c]] = v;
            }
        }
    }
    a
}

/// The compile bench's recording: `touchc synth stroke tap pat squeeze shake (x3)
/// stroke --seed 5 --quiet-frames 30`, 698 frames of the 142-cell sleeve.
pub fn combination_698() -> Array3<f64> {
    use Gesture::*;
    let mut gestures = Vec::new();
    for _ in 0..3 {
        gestures.extend([Stroke, Tap, Pat, Squeeze, Shake]);
    }
    gestures.push(Stroke);
    synth::generate(&SynthSpec {
        gestures,
        seed: 5,
        mask: Mask::Cells142,
        noise_psi: 0.004,
        quiet_frames: 30,
        ..SynthSpec::default()
    })
}

/// CPU seconds all of this process's threads have spent running (Linux schedstat, in
/// ns: the sum over `/proc/self/task/*/schedstat`, rayon's workers included), so a
/// benchmark on a machine shared with other work still gives comparable figures.
pub fn cpu_seconds() -> f64 {
    let Ok(tasks) = std::fs::read_dir("/proc/self/task") else {
        return f64::NAN;
    };
    let ns: f64 = tasks
        .flatten()
        .filter_map(|t| std::fs::read_to_string(t.path().join("schedstat")).ok())
        .filter_map(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .sum();
    ns * 1e-9
}

/// A case of [`touch_cases`]: `gestures` with `tuning` on `sensor`, 1.5 s of quiet on
/// each side.
pub(crate) fn touch_spec(sensor: Sensor, gestures: &[Gesture], tuning: Tuning) -> SynthSpec {
    SynthSpec {
        gestures: gestures.to_vec(),
        seed: 1,
        noise_psi: 0.003,
        // 1.5 s of quiet on each side: more than any tare window.
        quiet_frames: (sensor.rate_hz() * 1.5).round() as usize,
        sensor,
        tuning,
        ..SynthSpec::default()
    }
}

/// The real-touch cases on `sensor` (`host/tests/it/touch.rs` measures them,
/// `examples/sizes.rs` encodes them): a name and a spec each, seed 1.
pub fn touch_cases(sensor: Sensor) -> Vec<(String, SynthSpec)> {
    let mut out = Vec::new();
    let mut add = |name: String, spec: SynthSpec| out.push((name, spec));
    for v in [0.05, 0.3, 1.0, 1.5] {
        let t = Tuning {
            stroke_speed_mps: Some(v),
            ..Tuning::default()
        };
        add(
            format!("stroke {v} m/s"),
            touch_spec(sensor, &[Gesture::Stroke], t),
        );
    }
    for ms in [50.0, 100.0] {
        let t = Tuning {
            tap_s: Some(ms / 1000.0),
            ..Tuning::default()
        };
        add(
            format!("taps {ms} ms"),
            touch_spec(sensor, &[Gesture::Tap], t),
        );
    }
    add(
        "palm".into(),
        touch_spec(sensor, &[Gesture::Palm], Tuning::default()),
    );
    for hz in [2.0, 4.0] {
        let t = Tuning {
            shake_hz: Some(hz),
            shake_amplitude_mm: Some(40.0),
            ..Tuning::default()
        };
        add(
            format!("shake {hz} Hz 40 mm"),
            touch_spec(sensor, &[Gesture::Shake], t),
        );
    }
    let t = Tuning {
        gap_s: Some(0.15),
        ..Tuning::default()
    };
    add(
        "strokes 150 ms apart".into(),
        touch_spec(sensor, &[Gesture::Strokes], t),
    );
    add(
        "begins mid-touch (palm, stroke)".into(),
        SynthSpec {
            begin_mid_touch: true,
            ..touch_spec(sensor, &[Gesture::Palm, Gesture::Stroke], Tuning::default())
        },
    );
    add(
        "ends mid-touch (stroke, palm)".into(),
        SynthSpec {
            end_mid_touch: true,
            ..touch_spec(sensor, &[Gesture::Stroke, Gesture::Palm], Tuning::default())
        },
    );
    add(
        "flicker (strokes, palm)".into(),
        SynthSpec {
            flicker: 5.0,
            ..touch_spec(
                sensor,
                &[Gesture::Strokes, Gesture::Palm],
                Tuning::default(),
            )
        },
    );
    add(
        "noise only".into(),
        touch_spec(sensor, &[Gesture::Rest], Tuning::default()),
    );
    out
}
