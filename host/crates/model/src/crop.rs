//! The active scene: the window of a recording in frames and cells that the heavy
//! stages run on.

use std::ops::Range;

use serde::Serialize;

/// The part of a tared recording the heavy stages look at, in frames and sensor cells.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Crop {
    /// Frames `[start, end)` after the tare and trim.
    pub frames: Range<usize>,
    /// Cell rows `[start, end)`.
    pub rows: Range<usize>,
    /// Cell columns `[start, end)`.
    pub cols: Range<usize>,
}

impl Crop {
    /// No crop: the whole recording of shape `(frames, rows, cols)`.
    pub fn whole((t, r, c): (usize, usize, usize)) -> Self {
        Crop {
            frames: 0..t,
            rows: 0..r,
            cols: 0..c,
        }
    }
}
