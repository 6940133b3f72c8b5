//! Fixtures shared by the integration tests and the benches: synthetic recordings,
//! and the published Python code's reference vectors.

// Each test crate and bench uses a different part of this module.
#![allow(dead_code)]

use ndarray::Array3;
use touchc::input::synth::{self, Gesture, Mask, Sensor, SynthSpec, Tuning};

/// Deterministic uniform noise in [-1, 1) (xorshift), so fixtures need no RNG crate.
pub struct Noise(u64);

impl Noise {
    pub fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    pub fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// True where the 8 x 21 sleeve has a sensor cell: 142 cells (26 NaN at two edges).
pub fn sleeve_mask(r: usize, c: usize) -> bool {
    !((r == 0 || r == 7) && c < 13)
}

/// `[frames, 8, 21]` psi: quiet tare frames, then `blobs` Gaussian contacts moving along
/// the arm, 0.004 psi noise, NaN outside the 142-cell sleeve.
pub fn moving_blobs(frames: usize, blobs: usize, seed: u64) -> Array3<f64> {
    let mut noise = Noise::new(seed);
    let mut a = Array3::<f64>::zeros((frames, 8, 21));
    for t in 0..frames {
        for r in 0..8 {
            for c in 0..21 {
                if !sleeve_mask(r, c) {
                    a[[t, r, c]] = f64::NAN;
                    continue;
                }
                let mut v = 0.004 * noise.next();
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

/// The reference vectors shipped with the repository (`tests/data/reference/`, see its
/// README for where they come from).
pub fn reference_dir() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/reference")
}

use serde::Deserialize;
use touchc::tracking::trajectory::{Columns, Trajectory};

/// One trajectory as the reference stores it.
#[derive(Deserialize)]
pub struct RefTrajectory {
    pub times: Vec<usize>,
    pub rows: Vec<usize>,
    pub cols: Vec<usize>,
    pub costs: Vec<f64>,
    pub total_cost: f64,
}

/// The parts of a reference file that placement is checked against.
#[derive(Deserialize)]
pub struct Reference {
    /// `[T, rows, cols]` of the tared frames, in sensor cells.
    pub tared_shape: [usize; 3],
    pub trajectories: Vec<RefTrajectory>,
    pub n_transforms: usize,
    pub transform_scores: Vec<f64>,
    pub best_transform_index: usize,
    pub best_transform: [f64; 5],
    pub best_score: f64,
    pub selected_trajectories: Vec<usize>,
}

impl Reference {
    /// Reads `tests/data/{name}.reference.json` (exact float parsing is on for tests).
    pub fn load(name: &str) -> Reference {
        let path = format!(
            "{}/tests/data/{name}.reference.json",
            env!("CARGO_MANIFEST_DIR")
        );
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("{path}: {e}"))
    }

    /// The trajectories as the tracking stage hands them over (pressures are not stored
    /// in the reference and placement does not read them).
    pub fn trajectories(&self) -> Vec<Trajectory> {
        self.trajectories
            .iter()
            .map(|t| {
                Trajectory::try_from(Columns {
                    frames: t.times.clone(),
                    rows: t.rows.clone(),
                    cols: t.cols.clone(),
                    costs: t.costs.clone(),
                    values: vec![0.0; t.times.len()],
                })
                .expect("a reference trajectory's arrays have one length")
            })
            .collect()
    }
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
pub fn touch_spec(sensor: Sensor, gestures: &[Gesture], tuning: Tuning) -> SynthSpec {
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

/// The real-touch cases of issue 12 on `sensor` (`host/tests/it/touch.rs` measures them,
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
