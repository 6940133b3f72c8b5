//! Rendered coverage: how much of the recorded touch the sleeve plays.
//!
//! Coverage ([`crate::coverage`]) says how much of the touch the tracked
//! contacts explain; the placement then renders only the trajectories that pass through
//! a workspace, and an actuator plays only near its own circle. Rendered coverage is
//!
//! > the share of touch pressure (the sum over cells above the touch threshold, over
//! > all frames) whose cell centre lies within the workspace circle of an actuator that
//! > is driven (not silent) in that frame.
//!
//! A touch the tracker follows but no actuator plays is lost to the wearer as surely as
//! an untracked one; [`Shortfall`] flags a sleeve that plays much less than the tracker
//! follows.

use ndarray::{ArrayView3, Axis};
use serde::{Deserialize, Serialize};

use touchc_model::geometry::Circle;
use touchc_rendering::signals::{ChannelSignals, Source, CHANNELS};

use crate::coverage::Coverage;

/// Rendered coverage below this share of the tracking coverage is a [`Shortfall`].
///
/// Even a fully tracked stroke plays about a third of its pressure (a workspace of
/// 18.5 mm radius holds one or two of the one-inch cells a fingertip presses;
/// `examples/stroke.npy`: coverage 0.99, played 0.31), so only a fifth or less is a
/// sleeve that misses the touch rather than the cells' size.
pub const SHORTFALL_SHARE: f64 = 0.2;

/// The rendered coverage of `tared` (`[T, R, C]` psi, NaN = no cell, cells `pitch_mm`
/// apart, cell `(r, c)` centred at `((c + 0.5), (r + 0.5)) * pitch_mm`) by the actuators
/// whose workspaces are `circles` and whose frames are `signals` (see the module docs).
/// In the result, `explained_psi` is the played pressure.
pub(crate) fn measure(
    tared: ArrayView3<f64>,
    threshold_psi: f64,
    pitch_mm: f64,
    circles: &[Circle; CHANNELS],
    signals: &ChannelSignals,
) -> Coverage {
    let mut cov = Coverage::default();
    // Per cell, the circles that hold its centre: tested once, not once a frame.
    let (_, rows, cols) = tared.dim();
    let holding: Vec<u32> = (0..rows * cols)
        .map(|i| {
            let (r, c) = (i / cols, i % cols);
            let (x, y) = ((c as f64 + 0.5) * pitch_mm, (r as f64 + 0.5) * pitch_mm);
            (0..CHANNELS)
                .filter(|&ch| circles[ch].contains(x, y))
                .fold(0, |m, ch| m | 1 << ch)
        })
        .collect();
    for (f, frame) in tared.axis_iter(Axis(0)).enumerate() {
        let driven = (0..CHANNELS)
            .filter(|&ch| {
                signals.source[ch]
                    .get(f)
                    .is_some_and(|s| *s != Source::Silent)
            })
            .fold(0u32, |m, ch| m | 1 << ch);
        // Row-major, as the cells are numbered.
        for (&v, &held) in frame.iter().zip(&holding) {
            // NaN is no cell, never touch.
            if v.is_nan() || v <= threshold_psi {
                continue;
            }
            cov.touch_psi += v;
            cov.touch_cells += 1;
            if held & driven != 0 {
                cov.explained_psi += v;
            } else {
                cov.unexplained_cells += 1;
            }
        }
    }
    cov
}

/// The sleeve plays much less of the touch than the tracker follows: rendered coverage
/// under [`SHORTFALL_SHARE`] of the tracking coverage. More actuators under the touch
/// (another placement grid, or a layout with more or larger workspaces) is what helps.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Shortfall {
    /// Share of the touch pressure the tracked contacts explain.
    pub tracked: f64,
    /// Share of the touch pressure a driven actuator plays.
    pub rendered: f64,
}

impl Shortfall {
    /// A shortfall when `rendered` is under [`SHORTFALL_SHARE`] of `tracked`.
    pub fn of(tracked: f64, rendered: f64) -> Option<Shortfall> {
        (rendered < SHORTFALL_SHARE * tracked).then_some(Shortfall { tracked, rendered })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array3;

    fn circle(x_mm: f64, y_mm: f64) -> Circle {
        Circle {
            x_mm,
            y_mm,
            r_mm: 10.0,
            weight: 1.0,
        }
    }

    #[test]
    fn counts_touch_inside_a_driven_circle_only() {
        // 2 frames of 1 x 4 cells, 10 mm apart (centres at 5, 15, 25, 35 mm).
        let mut rec = Array3::<f64>::zeros((2, 1, 4));
        rec[[0, 0, 0]] = 1.0;
        rec[[0, 0, 3]] = 3.0;
        rec[[1, 0, 0]] = 2.0;
        rec[[1, 0, 1]] = 0.05; // below the threshold
        let mut circles = [circle(1000.0, 1000.0); CHANNELS];
        circles[0] = circle(5.0, 5.0); // over cell 0
        circles[1] = circle(35.0, 5.0); // over cell 3
        let mut signals = ChannelSignals::silent(2);
        // Channel 0 driven in frame 1 only, channel 1 in frame 0.
        signals.source[0][1] = Source::Trajectory(0);
        signals.source[1][0] = Source::NeighbourFill;
        let cov = measure(rec.view(), 0.08, 10.0, &circles, &signals);
        assert_eq!((cov.touch_cells, cov.unexplained_cells), (3, 1));
        assert!((cov.touch_psi - 6.0).abs() < 1e-12);
        // Frame 0: cell 3 (3 psi) under the driven channel 1; cell 0 under silent 0.
        // Frame 1: cell 0 (2 psi) under the driven channel 0.
        assert!((cov.explained_psi - 5.0).abs() < 1e-12);
        assert!((cov.ratio() - 5.0 / 6.0).abs() < 1e-12);
    }

    #[test]
    fn a_shortfall_is_under_a_fifth_of_what_is_tracked() {
        assert_eq!(Shortfall::of(0.9, 0.3), None);
        assert_eq!(
            Shortfall::of(0.9, 0.15),
            Some(Shortfall {
                tracked: 0.9,
                rendered: 0.15
            })
        );
    }
}
