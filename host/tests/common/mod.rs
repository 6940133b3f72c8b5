//! Fixtures shared by the integration tests and the benches: synthetic recordings,
//! and the published Python code's reference vectors.

// Each test crate and bench uses a different part of this module.
#![allow(dead_code)]

use ndarray::Array3;

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
