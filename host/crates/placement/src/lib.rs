//! Stage 4: where to put the sleeve's workspaces on the recording, and which trajectories
//! to render (the paper's "actuator workspace restriction").
//!
//! For every transform of the published grid this stage finds which trajectory points lie
//! in which workspace circle, chooses the best compatible subset of trajectories
//! (the exact branch-and-bound of `bnb.rs`), and scores the transform; the lowest score wins, ties going to the
//! first transform in grid order. It reproduces the authors' published code score for
//! score (pinned against its outputs in `tests/reference.rs`), with two
//! deliberate differences: the subset is exact (the published code uses ECOS_BB, which
//! stops at a 0.1 % gap) and ties between subsets follow a documented rule.
//!
//! Speed ("search only placements that can matter"): a transform walks the points of
//! only the trajectories whose bounding box meets one of its circles, finds same-frame
//! conflicts by chaining the in-circle points of each frame rather than by sorting, and
//! scores 0 without further work when its circles meet no point. The trajectories near a
//! circle's x range are listed once per x (210 transforms of the grid share one), so what
//! still grows with the recording's length is a bounding-box test per listed trajectory;
//! the rest follows what the circles meet (one hour: 8,008 trajectories, about a thousand
//! met per transform). Transforms are scored in parallel chunks (rayon) when there are
//! more than a thousand: each score depends on its transform only, so the result does
//! not depend on the number of threads.
//!
//! `PlacementConfig::coarse_to_fine` (the `fast` preset) scores a sub-grid first and the
//! full grid only near its best transforms; every score it computes is the full grid's.

#![deny(missing_docs)]

mod bnb;

mod footprint;
mod grid;
mod scoring;
mod search;
mod validation;

pub use grid::transform_grid;

use thiserror::Error;

use touchc_model::config::PlacementConfig;
use touchc_model::geometry::Circle;
use touchc_model::layout::{Layout, CHANNELS};
use touchc_model::trajectory::Trajectory;

use crate::scoring::{score_transform, Scene, Scratch};
use crate::search::{coarse_to_fine, Scores, Search};
use crate::validation::check_inputs;

/// One placement of the layout on the frame.
///
/// The published grid searches translations and a vertical split only; `scale` and
/// `rotation` are carried because the reference's transform format has them (always 1
/// and 0 there), and [`Transform::circles`] honours them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transform {
    /// Translation along the arm, mm.
    pub x_mm: f64,
    /// Translation across the arm, mm.
    pub y_mm: f64,
    /// Scale about the layout's origin, applied to centres and radii.
    pub scale: f64,
    /// Rotation about the layout's origin, radians.
    pub rotation: f64,
    /// Extra offset of row 1 across the arm (row `r` moves by `r * split_mm`), mm.
    pub split_mm: f64,
}

impl Transform {
    /// The layout's circles placed on the frame, in channel order.
    ///
    /// The order of operations (rotate, scale, then translate with `y + split * row`)
    /// follows the published code so that centres agree to the last bit.
    pub fn circles(&self, layout: &Layout) -> [Circle; CHANNELS] {
        layout.workspaces().map(|w| {
            let (mut x, mut y, mut r) = (w.x_mm, w.y_mm, w.radius_mm);
            if self.rotation != 0.0 || self.scale != 1.0 {
                let (s, c) = self.rotation.sin_cos();
                (x, y) = (x * c - y * s, x * s + y * c);
                (x, y, r) = (x * self.scale, y * self.scale, r * self.scale);
            }
            Circle {
                x_mm: x + self.x_mm,
                y_mm: y + (self.y_mm + self.split_mm * w.row as f64),
                r_mm: r,
                weight: w.weight,
            }
        })
    }
}

/// The outcome of the search: the winning transform and what it renders.
#[derive(Debug, Clone, PartialEq)]
pub struct Placement {
    /// The winning transform.
    pub transform: Transform,
    /// Its position in grid order (the reference's `best_transform_index`).
    pub index: usize,
    /// Its score (lower is better; 0 when nothing lies in any circle).
    pub score: f64,
    /// Trajectories to render: chosen and inside a circle at least once, ascending.
    pub selected: Vec<usize>,
    /// The workspaces placed by `transform`, in channel order.
    pub circles: [Circle; CHANNELS],
    /// Score of every transform, in grid order (for plots and for tests).
    pub scores: Vec<f64>,
    /// Transforms whose circles met a point and so needed a subset choice.
    pub transforms_evaluated: usize,
    /// Nodes each transform's subset search could visit: the compile's budget
    /// (`bnb::COMPILE_NODE_BUDGET`) shared over the grid (`bnb::transform_budget`).
    pub node_budget: u64,
    /// Transforms whose subset search ran out of its node budget and kept the best
    /// subset found by then: their score may be worse than the optimum. 0 on every
    /// published and shipped scene.
    pub transforms_inexact: usize,
}

/// Why placement could not run: bad parameters or malformed trajectories.
#[derive(Debug, Error, PartialEq)]
#[non_exhaustive]
pub enum PlacementError {
    /// A placement parameter is out of range.
    #[error("invalid placement config: {field} = {value} ({reason})")]
    InvalidConfig {
        /// Config field name.
        field: &'static str,
        /// The value given.
        value: String,
        /// What it must satisfy.
        reason: &'static str,
    },
    /// The frame has no pixels, so there is no grid to search.
    #[error("empty frame: {rows} x {cols} pixels")]
    EmptyFrame {
        /// Frame height in pixels.
        rows: usize,
        /// Frame width in pixels.
        cols: usize,
    },
    /// The pixel pitch is not a positive finite length.
    #[error("pixel pitch must be positive and finite, got {0} mm")]
    BadPitch(f64),
    /// A detection cost is NaN or infinite: scores would be meaningless.
    #[error("trajectory {trajectory}, detection {detection}: cost {cost} is not finite")]
    NonFiniteCost {
        /// Trajectory index.
        trajectory: usize,
        /// Detection index within the trajectory.
        detection: usize,
        /// The cost.
        cost: f64,
    },
    /// Points must follow in frame order, and within one frame (the cells of a
    /// region's footprint) in increasing row-major order, or one trajectory would sit
    /// twice on one pixel of one frame.
    #[error("trajectory {trajectory}, detection {detection}: frame {frame} does not follow frame {previous}")]
    FramesNotIncreasing {
        /// Trajectory index.
        trajectory: usize,
        /// Detection index within the trajectory.
        detection: usize,
        /// Its frame.
        frame: usize,
        /// The frame before it.
        previous: usize,
    },
    /// A detection lies outside the frame: trajectories and frame size disagree (for
    /// example, cropped coordinates passed with the full frame's size).
    #[error("trajectory {trajectory}, detection {detection}: pixel ({row}, {col}) is outside the {rows} x {cols} frame")]
    OutsideFrame {
        /// Trajectory index.
        trajectory: usize,
        /// Detection index within the trajectory.
        detection: usize,
        /// Pixel row.
        row: usize,
        /// Pixel column.
        col: usize,
        /// Frame height in pixels.
        rows: usize,
        /// Frame width in pixels.
        cols: usize,
    },
}

/// Finds the best transform of `layout` over the frame and the trajectories it renders.
///
/// `trajs` are in full-frame pixel coordinates of a `frame_rows_px` x `frame_cols_px`
/// upsampled frame (a cropped scene must pass the uncropped size and coordinates, so
/// that the grid, and hence the result, does not depend on the crop); `pitch_mm` is the
/// pixel pitch (`cell_mm / upsample`).
///
/// # Example
/// ```
/// use touchc_model::config::PlacementConfig;
/// use touchc_model::layout::Layout;
/// use touchc_placement::place;
/// use touchc_model::trajectory::{Point, Trajectory};
///
/// // One strong contact held still for three frames on a 56 x 147 px (8 x 21 cell) frame.
/// let touch: Trajectory = (0..3)
///     .map(|frame| Point { frame, row: 28, col: 70, cost: -3.9, value: 1.0 })
///     .collect();
/// let cfg = PlacementConfig::default();
/// let p = place(&[touch], 56, 147, 25.4 / 7.0, &Layout::paper(), &cfg)?;
/// assert_eq!(p.scores.len(), 4200);
/// assert_eq!(p.selected, vec![0]);
/// // The winner puts the contact in column 1, whose weight is 1.02.
/// assert!(p.score <= -3.0 * 3.9 * 1.02);
/// # Ok::<(), touchc_placement::PlacementError>(())
/// ```
pub fn place(
    trajs: &[Trajectory],
    frame_rows_px: usize,
    frame_cols_px: usize,
    pitch_mm: f64,
    layout: &Layout,
    cfg: &PlacementConfig,
) -> Result<Placement, PlacementError> {
    check_inputs(trajs, frame_rows_px, frame_cols_px, pitch_mm, cfg)?;
    let grid = transform_grid(frame_rows_px, frame_cols_px, pitch_mm, layout, cfg);
    let scene = Scene::new(trajs, pitch_mm);
    let search = Search {
        grid: &grid,
        layout,
        cfg,
        scene: &scene,
        inexact: std::sync::atomic::AtomicUsize::new(0),
        node_budget: bnb::transform_budget(grid.len()),
    };
    let mut state = Scores {
        score: vec![0.0; grid.len()],
        scored: vec![false; grid.len()],
        evaluated: 0,
    };
    match cfg.coarse_to_fine {
        None => state.run(&search, (0..grid.len()).collect()),
        Some(c) => coarse_to_fine(&search, &mut state, c.stride, c.keep),
    }
    let scores = state.score;

    // Lowest score wins; strict comparison keeps the first of equal scores.
    let mut index = 0;
    for (k, &s) in scores.iter().enumerate() {
        if s < scores[index] {
            index = k;
        }
    }
    let transform = grid[index];
    let circles = transform.circles(layout);
    let mut selected = Vec::new();
    let mut scratch = Scratch::new(&scene, search.node_budget);
    score_transform(&circles, &scene, cfg, &mut scratch, Some(&mut selected));
    Ok(Placement {
        transform,
        index,
        score: scores[index],
        selected,
        circles,
        scores,
        transforms_evaluated: state.evaluated,
        node_budget: search.node_budget,
        transforms_inexact: search.inexact.into_inner(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{grid_indices, grid_position, linspace};
    use touchc_model::config::grid_size;
    use touchc_model::trajectory::Columns;

    #[test]
    fn linspace_matches_numpy() {
        let v: Vec<f64> = linspace(-18.5, 533.4 - 111.0, 20).collect();
        // numpy.linspace(-18.5, 533.4 - 6 * 18.5, 20)[[1, 7, 19]]; [10] is the stroke
        // reference's best x.
        assert_eq!(v[1], 4.705263157894734);
        assert_eq!(v[7], 143.93684210526314);
        assert_eq!(v[10], 213.55263157894734);
        assert_eq!(v[19], 422.4);
        assert_eq!(linspace(3.0, 5.0, 1).collect::<Vec<_>>(), vec![3.0]);
        assert_eq!(linspace(0.0, 0.0, 3).collect::<Vec<_>>(), vec![0.0; 3]);
        assert_eq!(linspace(0.0, 1.0, 0).count(), 0);
    }

    #[test]
    fn grid_has_the_published_size_and_order() {
        let layout = Layout::paper();
        let cfg = PlacementConfig::default();
        let grid = transform_grid(56, 147, 25.4 / 7.0, &layout, &cfg);
        assert_eq!(grid.len(), 4200);
        assert_eq!(grid[0].x_mm, -18.5);
        assert_eq!(grid[4199].x_mm, 533.4 - 111.0);
        // Within one x: 20 splits for y_0, then 19 for y_1, ...
        assert_eq!(grid[19].y_mm, 0.0);
        assert_eq!(grid[19].split_mm, 203.2);
        assert_ne!(grid[20].y_mm, 0.0);
        assert_eq!(grid[209].y_mm, 203.2);
        assert_eq!(grid[209].split_mm, 0.0);
        assert_ne!(grid[210].x_mm, -18.5);
    }

    #[test]
    fn lattice_positions_are_grid_order() {
        for (gx, gy) in [(1, 1), (3, 1), (2, 5), (20, 20)] {
            let cfg = PlacementConfig {
                grid_x: gx,
                grid_y: gy,
                ..PlacementConfig::default()
            };
            let idx = grid_indices(&cfg);
            assert_eq!(Some(idx.len()), grid_size(&cfg));
            for (k, &i) in idx.iter().enumerate() {
                assert_eq!(grid_position(gy, i), k, "{gx} x {gy}: {i:?}");
            }
        }
    }

    fn traj(frames: &[usize], rows: &[usize], cols: &[usize], costs: &[f64]) -> Trajectory {
        Trajectory::try_from(Columns {
            frames: frames.to_vec(),
            rows: rows.to_vec(),
            cols: cols.to_vec(),
            costs: costs.to_vec(),
            values: vec![1.0; frames.len()],
        })
        .unwrap()
    }

    #[test]
    fn no_trajectories_means_the_first_transform_and_nothing_selected() {
        let p = place(
            &[],
            56,
            147,
            25.4 / 7.0,
            &Layout::paper(),
            &PlacementConfig::default(),
        )
        .unwrap();
        assert_eq!(p.index, 0);
        assert_eq!(p.score, 0.0);
        assert!(p.selected.is_empty());
        assert_eq!(p.transforms_evaluated, 0);
        assert!(p.scores.iter().all(|&s| s == 0.0));
    }

    /// Two trajectories on the same pixel at the same time can never share a circle:
    /// only the stronger (more negative total cost) is rendered.
    #[test]
    fn conflicting_trajectories_render_only_the_stronger() {
        let a = traj(
            &[0, 1, 2],
            &[20, 20, 20],
            &[40, 40, 40],
            &[-1.0, -1.0, -1.0],
        );
        let b = traj(
            &[1, 2, 3, 4],
            &[20, 20, 20, 20],
            &[40, 40, 40, 40],
            &[-1.0; 4],
        );
        let cfg = PlacementConfig::default();
        let p = place(&[a, b], 56, 147, 25.4 / 7.0, &Layout::paper(), &cfg).unwrap();
        assert_eq!(p.selected, vec![1]);
        assert!(
            p.score < -4.0 && p.score >= -4.0 * 1.02 * 1.04,
            "{}",
            p.score
        );
    }

    #[test]
    fn malformed_input_is_rejected() {
        let layout = Layout::paper();
        let cfg = PlacementConfig::default();
        let pitch = 25.4 / 7.0;
        // Ragged arrays never become a trajectory (a point holds all five fields).
        let ragged = Columns {
            frames: vec![0, 1],
            rows: vec![1],
            cols: vec![1, 1],
            costs: vec![-1.0, -1.0],
            values: vec![1.0, 1.0],
        };
        assert!(Trajectory::try_from(ragged).is_err());
        let nan = traj(&[0], &[1], &[1], &[f64::NAN]);
        assert!(matches!(
            place(&[nan], 56, 147, pitch, &layout, &cfg),
            Err(PlacementError::NonFiniteCost { .. })
        ));
        let back = traj(&[3, 3], &[1, 1], &[1, 1], &[-1.0, -1.0]);
        assert!(matches!(
            place(&[back], 56, 147, pitch, &layout, &cfg),
            Err(PlacementError::FramesNotIncreasing { detection: 1, .. })
        ));
        let outside = traj(&[0], &[56], &[1], &[-1.0]);
        assert!(matches!(
            place(&[outside], 56, 147, pitch, &layout, &cfg),
            Err(PlacementError::OutsideFrame { row: 56, .. })
        ));
        assert_eq!(
            place(&[], 0, 147, pitch, &layout, &cfg),
            Err(PlacementError::EmptyFrame { rows: 0, cols: 147 })
        );
        assert_eq!(
            place(&[], 56, 147, 0.0, &layout, &cfg),
            Err(PlacementError::BadPitch(0.0))
        );
        let zero_grid = PlacementConfig {
            grid_x: 0,
            ..cfg.clone()
        };
        assert!(matches!(
            place(&[], 56, 147, pitch, &layout, &zero_grid),
            Err(PlacementError::InvalidConfig {
                field: "grid_x",
                ..
            })
        ));
        let bad_bonus = PlacementConfig {
            centre_bonus: f64::NAN,
            ..cfg
        };
        assert!(matches!(
            place(&[], 56, 147, pitch, &layout, &bad_bonus),
            Err(PlacementError::InvalidConfig {
                field: "centre_bonus",
                ..
            })
        ));
    }
}

#[cfg(test)]
mod oracles;
