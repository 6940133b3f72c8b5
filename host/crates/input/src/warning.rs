//! What the input stage noticed about a recording that still compiles: typed, so a
//! report can carry the figures and a front end can word them.

use serde::Serialize;

use touchc_model::config::Baseline;

/// Something about the recording's tare a user should know: touch or readings the
/// compile could not use as recorded.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
#[non_exhaustive]
pub enum InputWarning {
    /// The leading baseline's window holds missing (NaN) readings of cells that are
    /// read elsewhere: each such cell is tared by the mean of the readings it has in
    /// the window, and a cell with none there by its low quantile over the whole
    /// recording (the robust baseline's zero), so no cell is lost.
    NanInTareWindow {
        /// Frames in the tare window.
        tare_frames: usize,
        /// Cells with at least one missing reading in the window.
        cells: usize,
        /// Missing readings of those cells in the window.
        readings: usize,
        /// Of those cells, the ones with no reading at all in the window.
        unread_cells: usize,
        /// The quantile those cells were tared by.
        quantile: f64,
    },
    /// The tare removed the touch: the raw frames hold touch (cells standing out from
    /// the rest of their frame by more than the touch threshold) but the tared frames
    /// hold none, so the stimulus is silent.
    TareErasedTouch {
        /// The baseline that was used.
        baseline: Baseline,
        /// Frames in the recording.
        frames: usize,
        /// Raw readings above the rest of their frame by more than the threshold.
        raw_touch_readings: usize,
        /// The largest such excess, psi.
        highest_psi: f64,
        /// Why: a recording too short for the baseline, or touch held through it.
        cause: ErasedBy,
    },
    /// The array's shape reads better as `[rows, cols, frames]` than as the
    /// `[frames, rows, cols]` it is taken for: a recording saved with time last.
    LikelyTransposed {
        /// The shape as read, `[frames, rows, cols]`.
        shape: [usize; 3],
        /// Why: the last axis is far longer than the others, or the first two axes
        /// are the sleeve's grid.
        reason: TransposedBy,
    },
}

/// What makes a shape look like `[rows, cols, frames]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TransposedBy {
    /// The last axis is at least `crate::sanity::TIME_LAST_RATIO` times as long
    /// as either other one: recordings have many more frames than cells a side.
    LastAxisLongest,
    /// The first two axes are the sleeve's 8 x 21 cells.
    SleeveGridFirst,
}

/// Why the tare could remove a recording's touch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ErasedBy {
    /// Fewer frames than a baseline can be told from touch in (a single frame is its
    /// own baseline).
    TooShort {
        /// Frames the recording would need.
        needed: usize,
    },
    /// The leading baseline's window holds the touch (the recording begins mid-touch).
    TouchInTareWindow,
    /// Each touched cell is pressed for most of the recording, so its low quantile is
    /// the touch itself.
    TouchThroughout,
}
