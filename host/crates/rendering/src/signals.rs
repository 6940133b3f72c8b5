//! Stage 5: per-actuator pressure signals (docs/algorithm.md section 5).
//!
//! Placement hands over the eight workspace circles (in channel order) and the chosen
//! trajectories; this stage decides, frame by frame, what pressure each actuator renders:
//!
//! 1. a chosen trajectory point inside the actuator's circle: that trajectory's pressure;
//! 2. otherwise, when a row neighbour renders a trajectory at that frame: the maximum
//!    blurred pressure inside the actuator's own circle (neighbour fill);
//! 3. otherwise silence (0 psi).
//!
//! Frames stay in time order: sample `t` of every channel is frame `t` of the recording
//! (the published code appends silent frames after the active ones; that is a bug).

use ndarray::{ArrayView2, ArrayView3, Axis};
use rayon::prelude::*;

use touchc_model::config::{Config, Sampling};
use touchc_model::geometry::{pixel_centre_mm, Circle};
use touchc_model::trajectory::Trajectory;
use touchc_placement::Placement;
use touchc_tracking::preprocess::{Blur, BlurOperator, PreprocessError};
use touchc_tracking::track::TrackOutput;

/// Actuator rows, columns per row (column 0 nearest the elbow) and channels, numbered
/// `row * COLUMNS + column` (docs/hardware.md): the layout's, which are the protocol's.
pub use touchc_model::layout::{CHANNELS, COLUMNS, ROWS};

/// Why an actuator renders what it renders at one frame; kept next to the pressure so
/// plots and tests can tell a trajectory from neighbour fill from silence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// Nothing to render: the sample is 0 psi.
    Silent,
    /// The trajectory with this index into the `trajs` slice passed to
    /// `actuator_signals` lies inside the circle.
    Trajectory(usize),
    /// A row neighbour renders a trajectory; the sample is the maximum blurred pressure
    /// inside this actuator's circle.
    NeighbourFill,
}

/// Stage-5 output: one pressure signal per channel at the frame rate, in psi.
///
/// `psi[ch][t]` is what channel `ch` renders at frame `t`; `source[ch][t]` says why.
/// All channels have the length of the blurred recording.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelSignals {
    /// Pressure per channel and frame, psi.
    pub psi: [Vec<f64>; CHANNELS],
    /// Origin of each sample.
    pub source: [Vec<Source>; CHANNELS],
}

impl ChannelSignals {
    /// `frames` frames of silence on every channel.
    pub fn silent(frames: usize) -> Self {
        ChannelSignals {
            psi: std::array::from_fn(|_| vec![0.0; frames]),
            source: std::array::from_fn(|_| vec![Source::Silent; frames]),
        }
    }

    /// Number of frames (the same on every channel).
    pub fn frames(&self) -> usize {
        self.psi[0].len()
    }
}

/// The pixels whose centres lie inside each circle, found once by a bounding-box scan so
/// that neighbour fill reads only those pixels at every frame (not the whole frame).
fn circle_pixels(circle: &Circle, rows: usize, cols: usize, pitch_mm: f64) -> Vec<(usize, usize)> {
    let usable =
        pitch_mm > 0.0 && pitch_mm.is_finite() && circle.r_mm >= 0.0 && circle.r_mm.is_finite();
    if !usable {
        return Vec::new();
    }
    // Pixel c has its centre at (c + 0.5) * pitch: the range of c whose centre can be
    // within r of the centre, widened by one pixel against rounding and clamped to the frame.
    let span = |centre: f64, len: usize| -> (usize, usize) {
        let lo = ((centre - circle.r_mm) / pitch_mm - 0.5).floor() - 1.0;
        let hi = ((centre + circle.r_mm) / pitch_mm - 0.5).ceil() + 1.0;
        let clamp = |v: f64| -> usize {
            if v.is_nan() || v <= 0.0 {
                0
            } else if v >= len as f64 {
                len
            } else {
                v as usize
            }
        };
        (clamp(lo), clamp(hi + 1.0))
    };
    let (r0, r1) = span(circle.y_mm, rows);
    let (c0, c1) = span(circle.x_mm, cols);
    let mut pixels = Vec::new();
    for r in r0..r1 {
        for c in c0..c1 {
            let (x, y) = pixel_centre_mm(r, c, pitch_mm);
            if circle.contains(x, y) {
                pixels.push((r, c));
            }
        }
    }
    pixels
}

/// Builds the eight per-actuator pressure signals (stage 5) in time order.
///
/// * `trajs`: every trajectory of the recording; `selected` indexes the chosen ones.
/// * `circles`: the placed workspaces in channel order (`row * 4 + column`).
/// * `blurred`: the blurred frames `[T, rows_px, cols_px]`, psi; its `T` is the length of
///   every output channel.
/// * `pitch_mm`: upsampled pixel pitch (25.4 / 7 mm on the published sleeve).
///
/// A trajectory point is inside a circle when its pixel centre is (`Circle::contains`).
/// When several chosen trajectories are inside one circle at one frame (possible only
/// where circles overlap or touch, or placement allowed it), the actuator renders the
/// strongest; equal pressures go to the one listed first in `selected`. Neighbour fill
/// copies from a neighbour only its *trajectory* state (a neighbour that is itself
/// filling does not propagate fill). A circle that covers no pixel centre of the frame
/// cannot fill and stays silent (as in the published code). Selected indices outside
/// `trajs` and trajectory points outside `[0, T)` are ignored; tracking never makes them.
#[cfg(test)]
pub(crate) fn actuator_signals(
    trajs: &[Trajectory],
    selected: &[usize],
    circles: &[Circle; CHANNELS],
    blurred: ArrayView3<f64>,
    pitch_mm: f64,
) -> ChannelSignals {
    actuator_signals_with(
        trajs,
        selected,
        circles,
        blurred.dim(),
        pitch_mm,
        |t, read| read(blurred.index_axis(Axis(0), t)),
    )
}

/// `actuator_signals` without the blurred movie: `dim` is its shape `[T, rows_px,
/// cols_px]`, and `frame(t, read)` calls `read` with blurred frame `t`. Only the
/// neighbour fill reads pixels, so `frame` is asked only for the frames where some
/// channel fills, once each, from the threads of the rayon pool in any order: a caller
/// can recompute just those frames instead of keeping every one.
pub(crate) fn actuator_signals_with(
    trajs: &[Trajectory],
    selected: &[usize],
    circles: &[Circle; CHANNELS],
    dim: (usize, usize, usize),
    pitch_mm: f64,
    frame: impl Fn(usize, &mut dyn FnMut(ArrayView2<f64>)) + Sync,
) -> ChannelSignals {
    let (frames, rows, cols) = dim;
    let mut psi: [Vec<f64>; CHANNELS] = std::array::from_fn(|_| vec![0.0; frames]);
    let mut source: [Vec<Source>; CHANNELS] = std::array::from_fn(|_| vec![Source::Silent; frames]);

    // Rule 1: trajectory points inside circles. Iterating `selected` in order and
    // replacing only on a strictly stronger value makes the first-listed win ties.
    for &ti in selected {
        let Some(traj) = trajs.get(ti) else { continue };
        for p in &traj.points {
            let (t, r, c, v) = (p.frame, p.row, p.col, p.value);
            if t >= frames {
                continue;
            }
            let (x, y) = pixel_centre_mm(r, c, pitch_mm);
            for (ch, circle) in circles.iter().enumerate() {
                if !circle.contains(x, y) {
                    continue;
                }
                let replace = match source[ch][t] {
                    Source::Trajectory(_) => v > psi[ch][t],
                    _ => true,
                };
                if replace {
                    psi[ch][t] = v;
                    source[ch][t] = Source::Trajectory(ti);
                }
            }
        }
    }

    // Rule 2: neighbour fill, decided from rule-1 states only.
    let pixels: Vec<Vec<(usize, usize)>> = circles
        .iter()
        .map(|c| circle_pixels(c, rows, cols, pitch_mm))
        .collect();
    let renders = |source: &[Vec<Source>; CHANNELS], ch: usize, t: usize| {
        matches!(source[ch][t], Source::Trajectory(_))
    };
    // The frames where some channel fills, and which channels: decided from rule-1
    // states only, so all of them first; then their pixels, frames on the rayon pool.
    let fills: Vec<(usize, [bool; CHANNELS])> = (0..frames)
        .filter_map(|t| {
            let mut fill = [false; CHANNELS];
            for (ch, f) in fill.iter_mut().enumerate() {
                if renders(&source, ch, t) || pixels[ch].is_empty() {
                    continue;
                }
                let (row, col) = (ch / COLUMNS, ch % COLUMNS);
                let left = col > 0 && renders(&source, row * COLUMNS + col - 1, t);
                let right = col + 1 < COLUMNS && renders(&source, row * COLUMNS + col + 1, t);
                *f = left || right;
            }
            fill.contains(&true).then_some((t, fill))
        })
        .collect();
    let values: Vec<[f64; CHANNELS]> = fills
        .par_iter()
        .map(|&(t, fill)| {
            let mut value = [f64::NEG_INFINITY; CHANNELS];
            frame(t, &mut |blurred| {
                for ch in (0..CHANNELS).filter(|&ch| fill[ch]) {
                    value[ch] = pixels[ch]
                        .iter()
                        .map(|&(r, c)| blurred[[r, c]])
                        .fold(f64::NEG_INFINITY, f64::max);
                }
            });
            value
        })
        .collect();
    for (&(t, fill), value) in fills.iter().zip(&values) {
        for ch in (0..CHANNELS).filter(|&ch| fill[ch]) {
            psi[ch][t] = value[ch];
            source[ch][t] = Source::NeighbourFill;
        }
    }

    ChannelSignals { psi, source }
}

/// Stage 5 (`actuator_signals`) for the whole recording: silent outside the
/// trajectories' frames, which lie in the crop. The blurred frames the neighbour fill
/// reads are recomputed from `tared`, those frames only (bit for bit the pass's: the
/// same operator on the same frame).
pub fn recomputed_actuator_signals(
    tracked: &TrackOutput,
    placement: &Placement,
    tared: ArrayView3<f64>,
    cfg: &Config,
    sampling: &Sampling,
) -> Result<ChannelSignals, PreprocessError> {
    let (t, r, c) = tared.dim();
    let op = BlurOperator::new(r, c, &Blur::new(&cfg.preprocess, sampling))?;
    let (h, w) = op.out_dim();
    Ok(actuator_signals_with(
        &tracked.trajectories,
        &placement.selected,
        &placement.circles,
        (t, h, w),
        tracked.pitch_mm(),
        |f, read| read(op.apply(tared.index_axis(Axis(0), f)).view()),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array3;
    use touchc_model::trajectory::Point;

    const PITCH: f64 = 25.4 / 7.0;

    /// The paper's layout at the origin: centres 37 mm apart along a row, 50 mm between
    /// rows, radius 18.5 mm; offset so every circle sits inside a 40 x 50 pixel frame.
    fn layout() -> [Circle; CHANNELS] {
        std::array::from_fn(|ch| Circle {
            x_mm: 20.0 + 37.0 * (ch % COLUMNS) as f64,
            y_mm: 20.0 + 50.0 * (ch / COLUMNS) as f64,
            r_mm: 18.5,
            weight: 1.0,
        })
    }

    /// Pixel whose centre is closest to (x, y) mm.
    fn px(x: f64, y: f64) -> (usize, usize) {
        (
            (y / PITCH - 0.5).round() as usize,
            (x / PITCH - 0.5).round() as usize,
        )
    }

    fn traj(points: &[(usize, f64, f64, f64)]) -> Trajectory {
        points
            .iter()
            .map(|&(frame, x, y, value)| {
                let (row, col) = px(x, y);
                Point {
                    frame,
                    row,
                    col,
                    cost: -3.0,
                    value,
                }
            })
            .collect()
    }

    #[test]
    fn circle_pixels_match_a_full_scan() {
        let circles = layout();
        let (rows, cols) = (40, 50);
        let mut moved = circles[3];
        moved.x_mm = 175.0; // partly off the right edge
        moved.y_mm = -5.0; // and off the top
        for c in circles.iter().chain(std::iter::once(&moved)) {
            let fast = circle_pixels(c, rows, cols, PITCH);
            let mut full = vec![];
            for r in 0..rows {
                for col in 0..cols {
                    let (x, y) = pixel_centre_mm(r, col, PITCH);
                    if c.contains(x, y) {
                        full.push((r, col));
                    }
                }
            }
            assert_eq!(fast, full);
        }
        let off = Circle {
            x_mm: -100.0,
            y_mm: -100.0,
            r_mm: 18.5,
            weight: 1.0,
        };
        assert!(circle_pixels(&off, rows, cols, PITCH).is_empty());
    }

    /// A stroke along row 0 visits columns 0..3 in order; each channel of row 0 renders
    /// it exactly while it is inside, neighbours of the rendering actuator fill, row 1 is
    /// silent, and sample t is frame t.
    #[test]
    fn stroke_along_a_row_activates_channels_in_order() {
        let circles = layout();
        let frames = 12;
        let mut blurred = Array3::<f64>::zeros((frames, 40, 50));
        // A distinct blurred value everywhere (so fill values are recognisable): 0.01 * t.
        for t in 0..frames {
            blurred
                .index_axis_mut(ndarray::Axis(0), t)
                .fill(0.01 * t as f64);
        }
        // Frames 2..10, x from 20 mm to 131 mm (centres of columns 0..3), pressure 1 + t.
        let pts: Vec<_> = (2..10)
            .map(|t| (t, 20.0 + 111.0 * (t - 2) as f64 / 7.0, 20.0, 1.0 + t as f64))
            .collect();
        let trajs = vec![traj(&pts)];
        let s = actuator_signals(&trajs, &[0], &circles, blurred.view(), PITCH);
        assert_eq!(s.frames(), frames);

        // First frame each channel of row 0 renders the trajectory: strictly increasing.
        let first: Vec<usize> = (0..COLUMNS)
            .map(|ch| {
                s.source[ch]
                    .iter()
                    .position(|&k| k == Source::Trajectory(0))
                    .unwrap_or(usize::MAX)
            })
            .collect();
        assert!(first.windows(2).all(|w| w[0] < w[1]), "{first:?}");
        for (t, &(f, x, y, v)) in pts.iter().enumerate() {
            assert_eq!(f, t + 2);
            let (r, c) = px(x, y);
            let (cx, cy) = pixel_centre_mm(r, c, PITCH);
            for (ch, circle) in circles.iter().enumerate().take(COLUMNS) {
                if circle.contains(cx, cy) {
                    assert_eq!(s.psi[ch][f], v, "ch {ch} frame {f}");
                    assert_eq!(s.source[ch][f], Source::Trajectory(0));
                }
            }
        }
        for t in 0..frames {
            let rendering: Vec<usize> = (0..CHANNELS)
                .filter(|&ch| s.source[ch][t] == Source::Trajectory(0))
                .collect();
            for ch in 0..CHANNELS {
                let col = ch % COLUMNS;
                let next_to = rendering
                    .iter()
                    .any(|&o| o / COLUMNS == ch / COLUMNS && (o % COLUMNS).abs_diff(col) == 1);
                match s.source[ch][t] {
                    Source::Trajectory(_) => assert!(rendering.contains(&ch)),
                    Source::NeighbourFill => {
                        assert!(next_to, "fill at ch {ch} frame {t} without a neighbour");
                        assert_eq!(s.psi[ch][t], 0.01 * t as f64);
                    }
                    Source::Silent => {
                        assert!(!next_to, "ch {ch} frame {t} should fill");
                        assert_eq!(s.psi[ch][t], 0.0);
                    }
                }
            }
        }
        // Outside the stroke's frames, and on row 1 at all times, everything is silent.
        for ch in 0..CHANNELS {
            for t in [0, 1, 10, 11] {
                assert_eq!(s.source[ch][t], Source::Silent);
            }
        }
        for ch in COLUMNS..CHANNELS {
            assert!(s.psi[ch].iter().all(|&v| v == 0.0));
        }
        // The fill fired at all (left neighbour of column 1 while the stroke is there, ...).
        assert!(s
            .source
            .iter()
            .flatten()
            .any(|&k| k == Source::NeighbourFill));
    }

    #[test]
    fn fill_takes_the_maximum_inside_the_own_circle_only() {
        let circles = layout();
        let mut blurred = Array3::<f64>::zeros((3, 40, 50));
        // Channel 1's circle has a hot pixel; a hotter pixel lies outside every circle
        // and one inside channel 5 (row 1), neither of which may leak into channel 1.
        let (r1, c1) = px(57.0 + 5.0, 20.0 - 3.0);
        blurred[[1, r1, c1]] = 2.5;
        let (ro, co) = px(37.0 + 20.0 + 18.0, 45.0);
        assert!(circles.iter().all(|c| {
            let (x, y) = pixel_centre_mm(ro, co, PITCH);
            !c.contains(x, y)
        }));
        blurred[[1, ro, co]] = 9.0;
        let (r5, c5) = px(57.0, 70.0);
        blurred[[1, r5, c5]] = 7.0;
        blurred[[1, 0, 0]] = -1.0;
        let trajs = vec![traj(&[(1, 20.0, 20.0, 3.0)])]; // inside channel 0 at frame 1
        let s = actuator_signals(&trajs, &[0], &circles, blurred.view(), PITCH);
        assert_eq!(s.source[1][1], Source::NeighbourFill);
        assert_eq!(s.psi[1][1], 2.5);
        // Column 2 is not next to column 0, row 1 is not a row neighbour.
        assert_eq!(s.source[2][1], Source::Silent);
        assert_eq!(s.source[4][1], Source::Silent);
        assert_eq!(s.source[5][1], Source::Silent);
        for t in [0, 2] {
            assert!(s.source.iter().all(|src| src[t] == Source::Silent));
        }
    }

    /// Channels 3 (row 0, last column) and 4 (row 1, first column) are consecutive
    /// numbers but not neighbours: fill must not wrap across rows.
    #[test]
    fn fill_never_wraps_across_rows() {
        let circles = layout();
        let blurred = Array3::<f64>::from_elem((2, 40, 50), 1.0);
        let in_4 = traj(&[(0, 20.0, 70.0, 3.0)]);
        let in_3 = traj(&[(1, 131.0, 20.0, 3.0)]);
        let s = actuator_signals(&[in_4, in_3], &[0, 1], &circles, blurred.view(), PITCH);
        assert_eq!(s.source[4][0], Source::Trajectory(0));
        assert_eq!((s.source[5][0], s.psi[5][0]), (Source::NeighbourFill, 1.0));
        assert_eq!(s.source[3][1], Source::Trajectory(1));
        assert_eq!((s.source[2][1], s.psi[2][1]), (Source::NeighbourFill, 1.0));
        for (ch, t) in [(3, 0), (0, 0), (4, 1), (7, 1), (0, 1)] {
            assert_eq!(s.source[ch][t], Source::Silent, "ch {ch} frame {t}");
        }
    }

    #[test]
    fn strongest_trajectory_wins_and_ties_go_to_the_first_selected() {
        let circles = layout();
        let blurred = Array3::<f64>::zeros((2, 40, 50));
        let a = traj(&[(0, 20.0, 20.0, 1.0), (1, 20.0, 20.0, 2.0)]);
        let b = traj(&[(0, 22.0, 21.0, 1.5), (1, 22.0, 21.0, 2.0)]);
        let unused = traj(&[(0, 20.0, 20.0, 99.0)]);
        let trajs = vec![a, b, unused];
        let s = actuator_signals(&trajs, &[1, 0, 7], &circles, blurred.view(), PITCH);
        assert_eq!((s.psi[0][0], s.source[0][0]), (1.5, Source::Trajectory(1)));
        assert_eq!((s.psi[0][1], s.source[0][1]), (2.0, Source::Trajectory(1)));
        let s = actuator_signals(&trajs, &[0, 1], &circles, blurred.view(), PITCH);
        assert_eq!(s.source[0][1], Source::Trajectory(0));
    }

    #[test]
    fn points_past_the_recording_are_ignored_not_a_panic() {
        let circles = layout();
        let blurred = Array3::<f64>::zeros((2, 40, 50));
        let trajs = vec![traj(&[(5, 20.0, 20.0, 1.0)])];
        let s = actuator_signals(&trajs, &[0], &circles, blurred.view(), PITCH);
        assert!(s.psi.iter().flatten().all(|&v| v == 0.0));
        let empty = Array3::<f64>::zeros((0, 40, 50));
        assert_eq!(
            actuator_signals(&trajs, &[0], &circles, empty.view(), PITCH).frames(),
            0
        );
    }
}
