//! The reference vectors of the published Python code (`tests/data/*.reference.json`,
//! copied from `shared/reference/`), shared by the tests and the bench.

// Each test crate and the bench use a different part of this module.
#![allow(dead_code)]

use serde::Deserialize;
use touchc::trajectory::Trajectory;

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
            .map(|t| Trajectory {
                frames: t.times.clone(),
                rows: t.rows.clone(),
                cols: t.cols.clone(),
                costs: t.costs.clone(),
                values: vec![0.0; t.times.len()],
            })
            .collect()
    }
}
