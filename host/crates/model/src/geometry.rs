//! Shared geometry: where an upsampled pixel sits on the arm, and the actuator circles.
//!
//! x runs along the arm (columns), y across it (rows), both in mm from the corner of
//! the sensor frame.

use serde::{Deserialize, Serialize};

/// The published sleeve sensor's grid, `(rows, cols)` of one-inch cells: the public data
/// set pads every frame to it, with NaN outside the sleeve.
pub const PAPER_GRID: (usize, usize) = (8, 21);

/// Centre of upsampled pixel `(row, col)` in mm, as `(x, y)`.
///
/// `pitch_mm` is the cell pitch divided by the upsampling factor (25.4 / 7 on the
/// published sleeve).
pub fn pixel_centre_mm(row: usize, col: usize, pitch_mm: f64) -> (f64, f64) {
    ((col as f64 + 0.5) * pitch_mm, (row as f64 + 0.5) * pitch_mm)
}

/// One actuator's workspace circle, placed on the recording's frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Circle {
    /// Centre along the arm, mm.
    pub x_mm: f64,
    /// Centre across the arm, mm.
    pub y_mm: f64,
    /// Radius, mm.
    pub r_mm: f64,
    /// Placement weight `w_a` (1.02 for the paper's column 1, 1 otherwise).
    pub weight: f64,
}

impl Circle {
    /// Squared distance from the centre to `(x, y)`, in mm^2.
    pub fn dist2(&self, x: f64, y: f64) -> f64 {
        let (dx, dy) = (x - self.x_mm, y - self.y_mm);
        dx * dx + dy * dy
    }

    /// True when `(x, y)` lies inside or on the circle.
    pub fn contains(&self, x: f64, y: f64) -> bool {
        self.dist2(x, y) <= self.r_mm * self.r_mm
    }
}
