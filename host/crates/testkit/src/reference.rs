//! The published Python code's reference vectors on its two synthetic recordings
//! (`tests/data/reference/`, whose README says where they come from), and their loader.

use std::path::PathBuf;

use serde::Deserialize;
use touchc_model::trajectory::{Columns, Trajectory};

/// The folder of the reference vectors: `NAME.npy` the recording, `NAME.reference.json`
/// what the published code computed from it.
pub fn reference_dir() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../tests/data/reference"
    ))
}

/// One trajectory as the reference stores it: a detection per frame, on the
/// upsampled grid.
#[derive(Debug, Deserialize)]
pub struct RefTrajectory {
    /// The frame of each detection.
    pub times: Vec<usize>,
    /// Its row on the upsampled grid.
    pub rows: Vec<usize>,
    /// Its column on the upsampled grid.
    pub cols: Vec<usize>,
    /// Its cost in the min-cost flow.
    pub costs: Vec<f64>,
    /// The trajectory's cost in all.
    pub total_cost: f64,
}

/// What the published code computed from one recording: tracking (stages 0-3) and
/// placement (stage 4).
#[derive(Debug, Deserialize)]
pub struct Reference {
    /// `[T, rows, cols]` of the tared frames, in sensor cells.
    pub tared_shape: [usize; 3],
    /// The blurred movie's global mean.
    pub whole_mean: f64,
    /// The blurred movie's global standard deviation.
    pub whole_std: f64,
    /// The trajectories, in the solver's augmentation order.
    pub trajectories: Vec<RefTrajectory>,
    /// How many transforms placement scored.
    pub n_transforms: usize,
    /// Every transform's score, in grid order.
    pub transform_scores: Vec<f64>,
    /// The chosen transform's place in the grid.
    pub best_transform_index: usize,
    /// The chosen transform's parameters.
    pub best_transform: [f64; 5],
    /// The chosen transform's score.
    pub best_score: f64,
    /// The trajectories the chosen transform renders, by index.
    pub selected_trajectories: Vec<usize>,
}

impl Reference {
    /// Reads `NAME.reference.json` from [`reference_dir`]; a missing or malformed file
    /// fails the test with its path.
    pub fn load(name: &str) -> Reference {
        let path = reference_dir().join(format!("{name}.reference.json"));
        let text =
            std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
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

#[cfg(test)]
mod tests {
    use super::Reference;

    #[test]
    fn both_references_load_whole() {
        for name in ["stroke_60", "tap_pat_200"] {
            let r = Reference::load(name);
            assert_eq!(r.transform_scores.len(), r.n_transforms, "{name}");
            assert_eq!(r.trajectories().len(), r.trajectories.len(), "{name}");
            assert!(r.best_transform_index < r.n_transforms, "{name}");
        }
    }
}
