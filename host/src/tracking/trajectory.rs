//! The hand-off between tracking (stage 3) and placement (stage 4).

use serde::{Deserialize, Serialize};

/// One tracked contact: a time-contiguous run of detections.
///
/// Frames are indices after the tare/trim; rows and cols are pixels of the
/// upsampled, blurred frame (the grid of `touchc track` and the reference JSON).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Trajectory {
    /// Frame index of each detection, strictly increasing by one.
    pub frames: Vec<usize>,
    /// Pixel row (y) of each detection.
    pub rows: Vec<usize>,
    /// Pixel column (x) of each detection.
    pub cols: Vec<usize>,
    /// Detection cost `ln((1 - P) / P)` of each detection.
    pub costs: Vec<f64>,
    /// Blurred pressure at each detection, in psi (what an actuator renders).
    pub values: Vec<f64>,
}

impl Trajectory {
    /// Sum of the detection costs (the reference's `total_cost`).
    pub fn total_cost(&self) -> f64 {
        self.costs.iter().sum()
    }

    /// Number of detections.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// True when the trajectory holds no detection.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }
}
