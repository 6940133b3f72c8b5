//! Coverage: how much of the recorded touch the tracked contacts explain.
//!
//! A compile can succeed and still convey little: if tracking loses a fast stroke or a
//! brief pat, the actuators render nothing for it and nobody is told. Coverage makes
//! that loss a number:
//!
//! > the share of touch pressure (the sum over cells above the touch threshold, over
//! > all frames) that lies within [`DEFAULT_RADIUS_CELLS`] cells of a tracked contact
//! > in the same frame.
//!
//! It is measured on the tared recording in sensor cells, independent of the
//! upsampling factor, so presets and sensors compare on one scale. The same mask of
//! unexplained cells lets a picture show the touch that no contact explains.

use ndarray::{Array3, ArrayView3, Axis};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use touchc_model::trajectory::Trajectory;

/// The radius of the coverage definition, in sensor cells.
pub const DEFAULT_RADIUS_CELLS: f64 = 2.0;

/// One tracked contact in one frame, in sensor-cell coordinates of the tared recording
/// (cell `(r, c)` has its centre at `(r, c)`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactPoint {
    /// Frame index after the tare and trim.
    pub frame: usize,
    /// Row, in cells (fractional).
    pub row: f64,
    /// Column, in cells (fractional).
    pub col: f64,
}

/// The contact points of `trajectories`, whose rows and columns are pixels of a grid
/// upsampled `upsample` times (pixel `p` covers cell `p / upsample`; its centre lies at
/// cell coordinate `(p + 0.5) / upsample - 0.5`).
pub fn contact_points(trajectories: &[Trajectory], upsample: usize) -> Vec<ContactPoint> {
    let k = upsample.max(1) as f64;
    let to_cell = |p: usize| (p as f64 + 0.5) / k - 0.5;
    trajectories
        .iter()
        .flat_map(|t| {
            t.points.iter().map(move |p| ContactPoint {
                frame: p.frame,
                row: to_cell(p.row),
                col: to_cell(p.col),
            })
        })
        .collect()
}

/// Touch pressure, and the part of it that tracked contacts explain.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Coverage {
    /// Sum of the readings above the touch threshold, over all cells and frames, psi.
    pub touch_psi: f64,
    /// The part of `touch_psi` within the radius of a contact in the same frame, psi.
    pub explained_psi: f64,
    /// Readings above the touch threshold.
    pub touch_cells: usize,
    /// Of those, the ones no contact explains.
    pub unexplained_cells: usize,
}

impl Coverage {
    /// `explained_psi / touch_psi`; 1 when there is no touch (nothing to miss).
    pub fn ratio(&self) -> f64 {
        if self.touch_psi > 0.0 {
            self.explained_psi / self.touch_psi
        } else {
            1.0
        }
    }
}

/// Which readings count as touch and whether a contact explains them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cell {
    /// At or below the touch threshold (or no cell).
    Quiet,
    /// Touch within the radius of a contact in the same frame.
    Explained,
    /// Touch that no contact explains.
    Unexplained,
}

/// Classifies every reading of `tared` (`[T, R, C]`, psi, NaN = no cell) against the
/// contact `points`: touch is a reading above `threshold_psi`; it is explained when a
/// point of the same frame lies within `radius_cells` (Euclidean, in cells) of the
/// cell's centre.
pub fn classify(
    tared: ArrayView3<f64>,
    threshold_psi: f64,
    points: &[ContactPoint],
    radius_cells: f64,
) -> Array3<Cell> {
    let (t, rows, cols) = tared.dim();
    let mut by_frame: Vec<Vec<(f64, f64)>> = vec![Vec::new(); t];
    for p in points.iter().filter(|p| p.frame < t) {
        by_frame[p.frame].push((p.row, p.col));
    }
    let r2 = radius_cells * radius_cells;
    // Frame by frame on the rayon pool (each frame's cells depend on that frame only).
    let frame_cells = rows * cols;
    let mut cells = vec![Cell::Quiet; t * frame_cells];
    cells
        .par_chunks_mut(frame_cells.max(1))
        .enumerate()
        .for_each(|(f, cells)| {
            let near = &by_frame[f];
            for ((r, readings), cells) in tared
                .index_axis(Axis(0), f)
                .outer_iter()
                .enumerate()
                .zip(cells.chunks_exact_mut(cols.max(1)))
            {
                for ((c, &v), cell) in readings.iter().enumerate().zip(cells) {
                    // NaN compares false: "no cell" is never touch.
                    if v > threshold_psi {
                        let hit = near.iter().any(|&(pr, pc)| {
                            let (dr, dc) = (pr - r as f64, pc - c as f64);
                            dr * dr + dc * dc <= r2
                        });
                        *cell = if hit {
                            Cell::Explained
                        } else {
                            Cell::Unexplained
                        };
                    }
                }
            }
        });
    // `t * rows * cols` cells by construction: the shape always fits.
    Array3::from_shape_vec((t, rows, cols), cells)
        .unwrap_or_else(|_| Array3::from_elem((t, rows, cols), Cell::Quiet))
}

/// The coverage of `tared` by the contact `points` (see the module docs).
pub fn measure(
    tared: ArrayView3<f64>,
    threshold_psi: f64,
    points: &[ContactPoint],
    radius_cells: f64,
) -> Coverage {
    let cells = classify(tared, threshold_psi, points, radius_cells);
    measure_classified(tared, &cells)
}

/// The coverage of `tared` given its readings classified by [`classify`].
pub(crate) fn measure_classified(tared: ArrayView3<f64>, cells: &Array3<Cell>) -> Coverage {
    let mut cov = Coverage::default();
    for (&v, &cell) in tared.iter().zip(cells.iter()) {
        match cell {
            Cell::Quiet => {}
            Cell::Explained => {
                cov.touch_psi += v;
                cov.explained_psi += v;
                cov.touch_cells += 1;
            }
            Cell::Unexplained => {
                cov.touch_psi += v;
                cov.touch_cells += 1;
                cov.unexplained_cells += 1;
            }
        }
    }
    cov
}

/// What tracking settings a recording would need, for the warning that explains low
/// coverage: the figures `explain` derives from the tared recording and the config.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tracking {
    /// Frame rate, Hz.
    pub rate_hz: f64,
    /// Cell pitch, mm.
    pub cell_mm: f64,
    /// The fastest contact the link gate follows, mm/s.
    pub gate_mm_s: f64,
    /// The fewest frames a trajectory of strong detections needs to pay its entry and
    /// exit costs.
    pub min_frames: usize,
    /// The `touch` preset's tracking is on already (links across missing frames and
    /// contact splitting), so advice does not suggest it.
    pub touch_tracking: bool,
}

/// Where the touch no contact explains lies, as shares of the unexplained pressure, and
/// the figures that point at a cause.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Misses {
    /// In touches (runs of frames with any touch) shorter than `Tracking::min_frames`.
    pub brief: f64,
    /// In frames of longer touches where no contact was tracked at all.
    pub untracked: f64,
    /// In frames with a tracked contact, but more than the radius away from it: a large
    /// contact, or a second one.
    pub beside: f64,
    /// Touches that resume after a gap of one or two frames (flicker, or taps in quick
    /// succession).
    pub dropouts: usize,
    /// The 90th percentile speed of the touch's pressure centroid between consecutive
    /// touched frames, mm/s.
    pub speed_p90_mm_s: f64,
}

/// A likely cause of touch no contact explains, with the figures that point at it
/// (from [`Misses::causes`]; a front end words it, with what to try).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MissCause {
    /// Touches too short for a trajectory to pay its entry and exit costs.
    Brief {
        /// Share of the missed touch, 0 to 1.
        share: f64,
        /// The fewest frames a trajectory of strong detections needs.
        min_frames: usize,
        /// Those frames, ms.
        min_ms: f64,
    },
    /// Frames of longer touches where no contact was tracked at all.
    Untracked {
        /// Share of the missed touch, 0 to 1.
        share: f64,
        /// Why, as far as the figures tell.
        why: UntrackedBy,
    },
    /// Touch beyond the radius of the contact tracked in its frame: a large contact or a
    /// second one.
    Beside {
        /// Share of the missed touch, 0 to 1.
        share: f64,
        /// The radius, cells ([`DEFAULT_RADIUS_CELLS`]).
        radius_cells: f64,
    },
}

/// Why frames of a touch went untracked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum UntrackedBy {
    /// The touch moves faster than the link gate follows.
    TooFast {
        /// The touch's 90th percentile speed, mm/s.
        speed_p90_mm_s: f64,
        /// The link gate's speed, mm/s.
        gate_mm_s: f64,
    },
    /// The touch drops out for a frame or two and the pieces are too short (only
    /// without the `touch` preset's tracking, which links across such gaps).
    Dropouts {
        /// How many times.
        count: usize,
    },
    /// Its detections are too weak to start a trajectory.
    Weak,
}

impl MissCause {
    /// The share of the missed touch this cause holds, 0 to 1.
    pub(crate) fn share(&self) -> f64 {
        match *self {
            MissCause::Brief { share, .. }
            | MissCause::Untracked { share, .. }
            | MissCause::Beside { share, .. } => share,
        }
    }
}

impl Misses {
    /// The likely causes, largest first.
    pub fn causes(&self, t: &Tracking) -> Vec<MissCause> {
        let mut out = Vec::new();
        if self.brief > 0.0 {
            out.push(MissCause::Brief {
                share: self.brief,
                min_frames: t.min_frames,
                min_ms: 1000.0 * t.min_frames as f64 / t.rate_hz,
            });
        }
        if self.untracked > 0.0 {
            let why = if self.speed_p90_mm_s > t.gate_mm_s {
                UntrackedBy::TooFast {
                    speed_p90_mm_s: self.speed_p90_mm_s,
                    gate_mm_s: t.gate_mm_s,
                }
            } else if self.dropouts > 0 && !t.touch_tracking {
                UntrackedBy::Dropouts {
                    count: self.dropouts,
                }
            } else {
                UntrackedBy::Weak
            };
            out.push(MissCause::Untracked {
                share: self.untracked,
                why,
            });
        }
        if self.beside > 0.0 {
            out.push(MissCause::Beside {
                share: self.beside,
                radius_cells: DEFAULT_RADIUS_CELLS,
            });
        }
        out.sort_by(|a, b| b.share().total_cmp(&a.share()));
        out
    }
}

/// One frame's touch, for [`explain`].
struct FrameTouch {
    /// Any reading above the threshold.
    touched: bool,
    /// The pressure no contact explains, psi.
    missed: f64,
    /// The touch's pressure centroid, cells.
    centroid: Option<(f64, f64)>,
}

/// Sorts the unexplained touch of `cells` (from [`classify`] on `tared`) by likely cause
/// (see [`Misses`]); `points` are the contact points `cells` was classified against.
pub(crate) fn explain(
    tared: ArrayView3<f64>,
    cells: &Array3<Cell>,
    points: &[ContactPoint],
    t: &Tracking,
) -> Misses {
    let frames = tared.dim().0;
    let mut tracked = vec![false; frames];
    for p in points.iter().filter(|p| p.frame < frames) {
        tracked[p.frame] = true;
    }
    // Per frame (on the rayon pool): touch present, unexplained pressure, pressure
    // centroid.
    let per_frame: Vec<FrameTouch> = (0..frames)
        .into_par_iter()
        .map(|f| {
            let (frame, class) = (tared.index_axis(Axis(0), f), cells.index_axis(Axis(0), f));
            let (mut touched, mut missed) = (false, 0.0);
            let (mut w, mut sr, mut sc) = (0.0, 0.0, 0.0);
            for (((r, c), &v), &cell) in frame.indexed_iter().zip(class.iter()) {
                if cell == Cell::Quiet {
                    continue;
                }
                touched = true;
                w += v;
                sr += v * r as f64;
                sc += v * c as f64;
                if cell == Cell::Unexplained {
                    missed += v;
                }
            }
            FrameTouch {
                touched,
                missed,
                centroid: (w > 0.0).then(|| (sr / w, sc / w)),
            }
        })
        .collect();
    let touched: Vec<bool> = per_frame.iter().map(|p| p.touched).collect();
    let missed: Vec<f64> = per_frame.iter().map(|p| p.missed).collect();
    let centroid: Vec<Option<(f64, f64)>> = per_frame.iter().map(|p| p.centroid).collect();
    let total: f64 = missed.iter().sum();
    let mut m = Misses::default();
    // Runs of touched frames, and the gaps between them.
    let mut f = 0;
    let mut last_end: Option<usize> = None;
    while f < frames {
        if !touched[f] {
            f += 1;
            continue;
        }
        let start = f;
        while f < frames && touched[f] {
            f += 1;
        }
        if last_end.is_some_and(|e| start - e <= 2) {
            m.dropouts += 1;
        }
        last_end = Some(f);
        for g in start..f {
            if f - start < t.min_frames {
                m.brief += missed[g];
            } else if !tracked[g] {
                m.untracked += missed[g];
            } else {
                m.beside += missed[g];
            }
        }
    }
    if total > 0.0 {
        m.brief /= total;
        m.untracked /= total;
        m.beside /= total;
    }
    let mut speeds: Vec<f64> = centroid
        .windows(2)
        .filter_map(|w| match (w[0], w[1]) {
            (Some(a), Some(b)) => {
                Some(((a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)).sqrt() * t.cell_mm * t.rate_hz)
            }
            _ => None,
        })
        .collect();
    if !speeds.is_empty() {
        speeds.sort_by(f64::total_cmp);
        m.speed_p90_mm_s = speeds[(speeds.len() - 1) * 9 / 10];
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array3;
    use touchc_model::trajectory::Columns;

    fn traj(frames: &[usize], rows: &[usize], cols: &[usize]) -> Trajectory {
        Trajectory::try_from(Columns {
            frames: frames.to_vec(),
            rows: rows.to_vec(),
            cols: cols.to_vec(),
            costs: vec![-1.0; frames.len()],
            values: vec![1.0; frames.len()],
        })
        .unwrap()
    }

    #[test]
    fn pixel_centres_map_to_cell_centres() {
        // x7: pixel 3 is the centre of cell 0, pixel 10 of cell 1.
        let pts = contact_points(&[traj(&[4, 5], &[3, 10], &[52, 0])], 7);
        assert_eq!(pts[0].frame, 4);
        assert!((pts[0].row - 0.0).abs() < 1e-12);
        assert!((pts[1].row - 1.0).abs() < 1e-12);
        assert!((pts[0].col - 7.0).abs() < 1e-12);
        // Pixel 0 lies 3/7 of a cell before the first centre.
        assert!((pts[1].col + 3.0 / 7.0).abs() < 1e-12);
    }

    #[test]
    fn counts_pressure_within_the_radius_in_the_same_frame_only() {
        let mut rec = Array3::<f64>::zeros((2, 1, 10));
        // Frame 0: touch at columns 0 (1 psi) and 5 (3 psi); frame 1: column 0 (2 psi).
        rec[[0, 0, 0]] = 1.0;
        rec[[0, 0, 5]] = 3.0;
        rec[[1, 0, 0]] = 2.0;
        rec[[1, 0, 9]] = 0.05; // below the threshold: not touch
        let pts = [ContactPoint {
            frame: 0,
            row: 0.0,
            col: 2.0,
        }];
        let cov = measure(rec.view(), 0.08, &pts, 2.0);
        assert_eq!(cov.touch_cells, 3);
        assert_eq!(cov.unexplained_cells, 2);
        assert!((cov.touch_psi - 6.0).abs() < 1e-12);
        // Only frame 0's column 0 is within 2 cells of the contact.
        assert!((cov.explained_psi - 1.0).abs() < 1e-12);
        assert!((cov.ratio() - 1.0 / 6.0).abs() < 1e-12);
        // The radius is inclusive and Euclidean.
        let diag = [ContactPoint {
            frame: 1,
            row: 0.0,
            col: 2.0,
        }];
        assert_eq!(measure(rec.view(), 0.08, &diag, 2.0).explained_psi, 2.0);
        assert_eq!(measure(rec.view(), 0.08, &diag, 1.999).explained_psi, 0.0);
    }

    #[test]
    fn no_touch_is_full_coverage_and_nan_is_never_touch() {
        let rec = Array3::from_elem((3, 2, 2), f64::NAN);
        let cov = measure(rec.view(), 0.08, &[], 2.0);
        assert_eq!(cov.touch_cells, 0);
        assert_eq!(cov.ratio(), 1.0);
    }

    #[test]
    fn classify_marks_what_no_contact_explains() {
        let mut rec = Array3::<f64>::zeros((1, 1, 6));
        rec[[0, 0, 0]] = 1.0;
        rec[[0, 0, 5]] = 1.0;
        let pts = [ContactPoint {
            frame: 0,
            row: 0.0,
            col: 0.0,
        }];
        let cells = classify(rec.view(), 0.08, &pts, 2.0);
        assert_eq!(cells[[0, 0, 0]], Cell::Explained);
        assert_eq!(cells[[0, 0, 1]], Cell::Quiet);
        assert_eq!(cells[[0, 0, 5]], Cell::Unexplained);
    }

    #[test]
    fn misses_sorted_by_cause() {
        let t = Tracking {
            rate_hz: 20.0,
            cell_mm: 25.4,
            gate_mm_s: 500.0,
            min_frames: 3,
            touch_tracking: false,
        };
        // 1 x 20 cells, 12 frames: a one-frame tap at frame 1 (missed); frames 4-9 a
        // contact moving 3 cells a frame (untracked); frames 4-9 also a second reading
        // 10 cells beside a tracked point at frame 9.
        let mut rec = Array3::<f64>::zeros((12, 1, 20));
        rec[[1, 0, 0]] = 1.0;
        for f in 4..10 {
            rec[[f, 0, (f - 4) * 3]] = 1.0;
        }
        rec[[9, 0, 19]] = 2.0;
        let pts = [ContactPoint {
            frame: 9,
            row: 0.0,
            col: 15.0,
        }];
        let cells = classify(rec.view(), 0.08, &pts, 2.0);
        let m = explain(rec.view(), &cells, &pts, &t);
        // Missed: tap 1, frames 4-8 five readings of 1, frame 9 the 2 beside (the moving
        // contact at col 15 is explained).
        assert!((m.brief - 1.0 / 8.0).abs() < 1e-12, "{m:?}");
        assert!((m.untracked - 5.0 / 8.0).abs() < 1e-12, "{m:?}");
        assert!((m.beside - 2.0 / 8.0).abs() < 1e-12, "{m:?}");
        assert_eq!(m.dropouts, 1);
        // 3 cells a frame at 20 Hz and 25.4 mm = 1.52 m/s, above the 0.5 m/s gate.
        assert!(m.speed_p90_mm_s > 1000.0, "{m:?}");
        let causes = m.causes(&t);
        assert!(
            matches!(
                causes[..],
                [
                    MissCause::Untracked {
                        why: UntrackedBy::TooFast { .. },
                        ..
                    },
                    MissCause::Beside {
                        radius_cells: 2.0,
                        ..
                    },
                    MissCause::Brief { min_frames: 3, .. },
                ]
            ),
            "{causes:?}"
        );
        // Slower than the gate, the dropout is the cause named; under the touch preset's
        // tracking (which links across dropouts) the detections are too weak instead.
        let slow = Tracking {
            gate_mm_s: 5000.0,
            ..t
        };
        let why = |t: &Tracking| {
            m.causes(t).iter().find_map(|c| match c {
                MissCause::Untracked { why, .. } => Some(*why),
                _ => None,
            })
        };
        assert_eq!(why(&slow), Some(UntrackedBy::Dropouts { count: 1 }));
        let on_touch = Tracking {
            touch_tracking: true,
            ..slow
        };
        assert_eq!(why(&on_touch), Some(UntrackedBy::Weak));
    }
}
