//! Stage 4: where to put the sleeve's workspaces on the recording, and which trajectories
//! to render (the paper's "actuator workspace restriction").
//!
//! For every transform of the published grid this stage finds which trajectory points lie
//! in which workspace circle, chooses the best compatible subset of trajectories
//! ([`crate::placement::bnb`]), and scores the transform; the lowest score wins, ties going to the
//! first transform in grid order. It reproduces the authors' published code score for
//! score (pinned against its outputs in `tests/placement_reference.rs`), with two
//! deliberate differences: the subset is exact (the published code uses ECOS_BB, which
//! stops at a 0.1 % gap) and ties between subsets follow a documented rule.
//!
//! Speed ("search only placements that can matter"): points are sorted along the arm, so
//! a circle only looks at the points in its x range, and a transform whose circles meet no
//! point scores 0 without any further work. Transforms are scored in parallel chunks
//! (rayon) when there are more than a thousand: each score depends on its transform only,
//! so the result does not depend on the number of threads.
//!
//! `PlacementConfig::coarse_to_fine` (the `fast` preset) scores a sub-grid first and the
//! full grid only near its best transforms; every score it computes is the full grid's.

pub mod bnb;
pub mod layout;

use thiserror::Error;

use crate::config::PlacementConfig;
use crate::geometry::{pixel_centre_mm, Circle};
use crate::placement::bnb::SubsetProblem;
use crate::placement::layout::{Layout, CHANNELS};
use crate::tracking::trajectory::Trajectory;

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
    /// A trajectory's per-detection vectors disagree in length.
    #[error(
        "trajectory {trajectory}: {frames} frames but {rows} rows, {cols} cols, {costs} costs"
    )]
    LengthMismatch {
        /// Trajectory index.
        trajectory: usize,
        /// Length of `frames`.
        frames: usize,
        /// Length of `rows`.
        rows: usize,
        /// Length of `cols`.
        cols: usize,
        /// Length of `costs`.
        costs: usize,
    },
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
    /// Frames must increase, or one trajectory would sit twice in one frame.
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

/// `numpy.linspace(start, stop, num)` value for value, so that grid points match the
/// published code bit for bit (the last point is `stop` exactly).
fn linspace(start: f64, stop: f64, num: usize) -> impl Iterator<Item = f64> {
    let div = num.saturating_sub(1) as f64;
    let delta = stop - start;
    let step = delta / div;
    (0..num).map(move |i| {
        if num == 1 {
            start
        } else if i + 1 == num {
            stop
        } else if step == 0.0 {
            (i as f64 / div) * delta + start
        } else {
            i as f64 * step + start
        }
    })
}

/// The published transform grid, in its order: x outer, then the y index, then the split.
///
/// x runs from "first column's centre half a circle off the near edge" to "last column's
/// centre on the far edge" (`linspace(-18.5, W - 6 * 18.5, 20)` for the paper's sleeve);
/// y over `linspace(0, H, n)`, and for the i-th y the split over
/// `linspace(0, H - y_i, n - i)`, so row 1 never leaves the frame: 4,200 transforms.
pub fn transform_grid(
    frame_rows_px: usize,
    frame_cols_px: usize,
    pitch_mm: f64,
    layout: &Layout,
    cfg: &PlacementConfig,
) -> Vec<Transform> {
    let width = frame_cols_px as f64 * pitch_mm;
    let height = frame_rows_px as f64 * pitch_mm;
    let ws = layout.workspaces();
    let (mut first, mut last) = (ws[0], ws[0]);
    for w in ws {
        if w.x_mm < first.x_mm {
            first = *w;
        }
        if w.x_mm > last.x_mm {
            last = *w;
        }
    }
    let x_lo = -first.radius_mm - first.x_mm;
    let x_hi = width - last.x_mm;
    let ys: Vec<f64> = linspace(0.0, height, cfg.grid_y).collect();
    let mut grid = Vec::with_capacity(grid_size(cfg).unwrap_or(0));
    for x in linspace(x_lo, x_hi, cfg.grid_x) {
        for (i, &y) in ys.iter().enumerate() {
            for split in linspace(0.0, height - y, cfg.grid_y - i) {
                grid.push(Transform {
                    x_mm: x,
                    y_mm: y,
                    scale: 1.0,
                    rotation: 0.0,
                    split_mm: split,
                });
            }
        }
    }
    grid
}

/// Transforms in the grid of `cfg` (`grid_x * grid_y * (grid_y + 1) / 2`); `None` if that
/// overflows.
pub fn grid_size(cfg: &PlacementConfig) -> Option<usize> {
    let per_x = cfg.grid_y.checked_mul(cfg.grid_y.checked_add(1)?)? / 2;
    cfg.grid_x.checked_mul(per_x)
}

/// The largest grid [`place`] accepts: 20 million transforms hold 800 MB of transforms
/// and scores, and take minutes; no placement needs them (the grid converges well before,
/// see `docs/trade.md`).
pub const MAX_TRANSFORMS: usize = 20_000_000;

/// Position in grid order of the transform with lattice indices `(ix, iy, is)`:
/// `x` index, `y` index and split index (`is < grid_y - iy`).
fn grid_position(grid_y: usize, [ix, iy, is]: [usize; 3]) -> usize {
    let per_x = grid_y * (grid_y + 1) / 2;
    // Splits of the y rows before `iy`: grid_y + (grid_y - 1) + ... (iy terms).
    ix * per_x + iy * grid_y - iy * iy.saturating_sub(1) / 2 + is
}

/// The lattice indices of every grid transform, in grid order (see [`grid_position`]).
fn grid_indices(cfg: &PlacementConfig) -> Vec<[usize; 3]> {
    let mut out = Vec::with_capacity(grid_size(cfg).unwrap_or(0));
    for ix in 0..cfg.grid_x {
        for iy in 0..cfg.grid_y {
            for is in 0..cfg.grid_y - iy {
                out.push([ix, iy, is]);
            }
        }
    }
    out
}

fn check_inputs(
    trajs: &[Trajectory],
    rows: usize,
    cols: usize,
    pitch_mm: f64,
    cfg: &PlacementConfig,
) -> Result<(), PlacementError> {
    for (field, value) in [("grid_x", cfg.grid_x), ("grid_y", cfg.grid_y)] {
        if value == 0 {
            return Err(PlacementError::InvalidConfig {
                field,
                value: value.to_string(),
                reason: "the grid needs at least one point",
            });
        }
    }
    if grid_size(cfg).is_none_or(|n| n > MAX_TRANSFORMS) {
        return Err(PlacementError::InvalidConfig {
            field: "grid_x * grid_y * (grid_y + 1) / 2",
            value: format!("{} x {}", cfg.grid_x, cfg.grid_y),
            reason: "at most 20,000,000 transforms",
        });
    }
    if let Some(c) = &cfg.coarse_to_fine {
        if c.stride == 0 || c.keep == 0 {
            return Err(PlacementError::InvalidConfig {
                field: "coarse_to_fine",
                value: format!("stride {}, keep {}", c.stride, c.keep),
                reason: "stride and keep must be at least 1",
            });
        }
    }
    if !(cfg.centre_bonus.is_finite() && cfg.centre_bonus >= 0.0) {
        return Err(PlacementError::InvalidConfig {
            field: "centre_bonus",
            value: cfg.centre_bonus.to_string(),
            reason: "must be finite and >= 0 so that every point inside a circle weighs > 0",
        });
    }
    if rows == 0 || cols == 0 {
        return Err(PlacementError::EmptyFrame { rows, cols });
    }
    if !(pitch_mm.is_finite() && pitch_mm > 0.0) {
        return Err(PlacementError::BadPitch(pitch_mm));
    }
    for (t, traj) in trajs.iter().enumerate() {
        let n = traj.frames.len();
        if traj.rows.len() != n || traj.cols.len() != n || traj.costs.len() != n {
            return Err(PlacementError::LengthMismatch {
                trajectory: t,
                frames: n,
                rows: traj.rows.len(),
                cols: traj.cols.len(),
                costs: traj.costs.len(),
            });
        }
        for d in 0..n {
            let (row, col, cost) = (traj.rows[d], traj.cols[d], traj.costs[d]);
            if !cost.is_finite() {
                return Err(PlacementError::NonFiniteCost {
                    trajectory: t,
                    detection: d,
                    cost,
                });
            }
            if d > 0 && traj.frames[d] <= traj.frames[d - 1] {
                return Err(PlacementError::FramesNotIncreasing {
                    trajectory: t,
                    detection: d,
                    frame: traj.frames[d],
                    previous: traj.frames[d - 1],
                });
            }
            if row >= rows || col >= cols {
                return Err(PlacementError::OutsideFrame {
                    trajectory: t,
                    detection: d,
                    row,
                    col,
                    rows,
                    cols,
                });
            }
        }
    }
    Ok(())
}

/// A trajectory point in mm, with what scoring and conflicts need.
#[derive(Debug, Clone, Copy)]
struct Point {
    x: f64,
    y: f64,
    traj: usize,
    frame: usize,
    cost: f64,
}

/// The trajectories as the search needs them, computed once per call.
struct Scene {
    /// Every detection, trajectory-major and in detection order.
    points: Vec<Point>,
    /// Point indices sorted by x, so a circle finds its candidates by binary search.
    by_x: Vec<usize>,
    /// The x of each point of `by_x`.
    sorted_x: Vec<f64>,
    /// Per trajectory: what choosing it earns (`-total_cost`).
    gains: Vec<f64>,
}

/// Per-transform work buffers, reused so the search allocates only when it must.
struct Scratch {
    /// Workspace bitmask of each point under the current transform.
    mask: Vec<u32>,
    /// Weight `D` of each point (of the last workspace containing it, as published).
    weight: Vec<f64>,
    /// Points with a non-zero mask, to reset and to visit.
    touched: Vec<usize>,
    /// (frame, trajectory, mask) of touched points of candidate trajectories.
    hits: Vec<(usize, usize, u32)>,
    /// Per trajectory: chosen under the current transform.
    chosen: Vec<bool>,
    /// Per trajectory: local index in the subset problem, or `usize::MAX`.
    local: Vec<usize>,
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
/// use touchc::{config::PlacementConfig, layout::Layout, placement::place};
/// use touchc::tracking::trajectory::Trajectory;
///
/// // One strong contact held still for three frames on a 56 x 147 px (8 x 21 cell) frame.
/// let touch = Trajectory {
///     frames: vec![0, 1, 2],
///     rows: vec![28; 3],
///     cols: vec![70; 3],
///     costs: vec![-3.9; 3],
///     values: vec![1.0; 3],
/// };
/// let cfg = PlacementConfig::default();
/// let p = place(&[touch], 56, 147, 25.4 / 7.0, &Layout::paper(), &cfg)?;
/// assert_eq!(p.scores.len(), 4200);
/// assert_eq!(p.selected, vec![0]);
/// // The winner puts the contact in column 1, whose weight is 1.02.
/// assert!(p.score <= -3.0 * 3.9 * 1.02);
/// # Ok::<(), touchc::placement::PlacementError>(())
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
    let all = [(0, scene.by_x.len()); CHANNELS];
    let mut selected = Vec::new();
    let mut scratch = Scratch::new(&scene, trajs.len());
    score_transform(
        &circles,
        &all,
        &scene,
        cfg,
        &mut scratch,
        Some(&mut selected),
    );
    Ok(Placement {
        transform,
        index,
        score: scores[index],
        selected,
        circles,
        scores,
        transforms_evaluated: state.evaluated,
    })
}

/// The coarse-to-fine search: the sub-grid of every `stride`-th point, then the full
/// grid within `stride - 1` steps of its `keep` best, then steepest descent over the
/// full grid's 26 neighbours of the best until no neighbour is left to score. If no
/// coarse transform meets a trajectory, the whole grid is scored (the coarse grid may
/// have stepped over a small, brief contact).
fn coarse_to_fine(search: &Search, state: &mut Scores, stride: usize, keep: usize) {
    let cfg = search.cfg;
    let index = grid_indices(cfg);
    let on = |i: usize, last: usize| i.is_multiple_of(stride) || i == last;
    let coarse: Vec<usize> = (0..index.len())
        .filter(|&k| {
            let [ix, iy, is] = index[k];
            on(ix, cfg.grid_x - 1) && on(iy, cfg.grid_y - 1) && on(is, cfg.grid_y - 1 - iy)
        })
        .collect();
    state.run(search, coarse.clone());
    let mut best: Vec<usize> = coarse
        .into_iter()
        .filter(|&k| state.score[k] < 0.0)
        .collect();
    best.sort_by(|&a, &b| state.score[a].total_cmp(&state.score[b]).then(a.cmp(&b)));
    best.truncate(keep);
    if best.is_empty() {
        let rest = (0..index.len()).filter(|&k| !state.scored[k]).collect();
        state.run(search, rest);
        return;
    }
    let near = |k: usize, r: usize| {
        let [ix, iy, is] = index[k];
        let span = |i: usize, n: usize| i.saturating_sub(r)..(i + r + 1).min(n);
        let mut out = Vec::new();
        for x in span(ix, cfg.grid_x) {
            for y in span(iy, cfg.grid_y) {
                for s in span(is, cfg.grid_y - y) {
                    out.push(grid_position(cfg.grid_y, [x, y, s]));
                }
            }
        }
        out
    };
    let mut todo: Vec<usize> = best.iter().flat_map(|&k| near(k, stride - 1)).collect();
    loop {
        todo.sort_unstable();
        todo.dedup();
        todo.retain(|&k| !state.scored[k]);
        if todo.is_empty() {
            return;
        }
        state.run(search, std::mem::take(&mut todo));
        let mut top = 0;
        for (k, &s) in state.score.iter().enumerate() {
            if s < state.score[top] {
                top = k;
            }
        }
        todo = near(top, 1);
    }
}

/// What the search shares between threads: the grid and the trajectories.
struct Search<'a> {
    grid: &'a [Transform],
    layout: &'a Layout,
    cfg: &'a PlacementConfig,
    scene: &'a Scene,
}

/// Scores found so far (0 for a transform that meets no point or was not scored).
struct Scores {
    score: Vec<f64>,
    scored: Vec<bool>,
    /// Transforms that met a point and needed a subset choice.
    evaluated: usize,
}

/// Below this many transforms a batch runs on the calling thread: splitting costs more
/// than it saves (one transform takes about a microsecond).
const PARALLEL_MIN: usize = 1024;

impl Scores {
    /// Scores the transforms `ks` (ascending grid positions), in parallel chunks when
    /// there are enough of them. Each transform's score depends on that transform only,
    /// so the result is the same on any number of threads.
    fn run(&mut self, search: &Search, ks: Vec<usize>) {
        use rayon::prelude::*;
        let results: Vec<Option<f64>> = if ks.len() < PARALLEL_MIN {
            search.score_seq(&ks)
        } else {
            let chunk = (ks.len() / (4 * rayon::current_num_threads())).max(PARALLEL_MIN / 4);
            ks.par_chunks(chunk)
                .map(|c| search.score_seq(c))
                .collect::<Vec<_>>()
                .concat()
        };
        for (&k, r) in ks.iter().zip(results) {
            self.scored[k] = true;
            if let Some(v) = r {
                self.score[k] = v;
                self.evaluated += 1;
            }
        }
    }
}

impl Search<'_> {
    /// Scores `ks` one after another with one set of buffers; `None` = meets no point.
    fn score_seq(&self, ks: &[usize]) -> Vec<Option<f64>> {
        let scene = self.scene;
        let mut scratch = Scratch::new(scene, scene.gains.len());
        let mut ranges = [(0usize, 0usize); CHANNELS];
        let mut current_x = f64::NAN;
        ks.iter()
            .map(|&k| {
                let transform = &self.grid[k];
                let circles = transform.circles(self.layout);
                if transform.x_mm != current_x {
                    // Grid transforms have scale 1 and no rotation, so circle x positions
                    // depend on x only: find each circle's slice of points once per x.
                    current_x = transform.x_mm;
                    for (range, c) in ranges.iter_mut().zip(&circles) {
                        // Widened by a hair: the exact test below decides membership.
                        let slack = 1e-9 * (1.0 + c.x_mm.abs() + c.r_mm);
                        let lo = scene
                            .sorted_x
                            .partition_point(|&x| x < c.x_mm - c.r_mm - slack);
                        let hi = scene
                            .sorted_x
                            .partition_point(|&x| x <= c.x_mm + c.r_mm + slack);
                        *range = (lo, hi.max(lo));
                    }
                }
                if ranges.iter().all(|&(lo, hi)| lo == hi) {
                    return None;
                }
                score_transform(&circles, &ranges, scene, self.cfg, &mut scratch, None)
            })
            .collect()
    }
}

impl Scene {
    /// Points in mm, sorted by x, and each trajectory's gain.
    fn new(trajs: &[Trajectory], pitch_mm: f64) -> Scene {
        let mut points = Vec::new();
        for (t, traj) in trajs.iter().enumerate() {
            for d in 0..traj.len() {
                let (x, y) = pixel_centre_mm(traj.rows[d], traj.cols[d], pitch_mm);
                points.push(Point {
                    x,
                    y,
                    traj: t,
                    frame: traj.frames[d],
                    cost: traj.costs[d],
                });
            }
        }
        let mut by_x: Vec<usize> = (0..points.len()).collect();
        by_x.sort_by(|&a, &b| points[a].x.total_cmp(&points[b].x));
        let sorted_x = by_x.iter().map(|&p| points[p].x).collect();
        // The published objective: maximise the summed -total_cost of the chosen set.
        let gains = trajs.iter().map(|t| -t.total_cost()).collect();
        Scene {
            points,
            by_x,
            sorted_x,
            gains,
        }
    }
}

impl Scratch {
    fn new(scene: &Scene, trajectories: usize) -> Scratch {
        Scratch {
            mask: vec![0; scene.points.len()],
            weight: vec![0.0; scene.points.len()],
            touched: Vec::new(),
            hits: Vec::new(),
            chosen: vec![false; trajectories],
            local: vec![usize::MAX; trajectories],
        }
    }
}

/// Scores one transform; `None` when no point lies in any circle (score 0).
///
/// `ranges[a]` is the slice of `scene.by_x` that circle `a` may contain. When `selected`
/// is given, the chosen trajectories with a point inside a circle are written to it.
fn score_transform(
    circles: &[Circle; CHANNELS],
    ranges: &[(usize, usize); CHANNELS],
    scene: &Scene,
    cfg: &PlacementConfig,
    s: &mut Scratch,
    selected: Option<&mut Vec<usize>>,
) -> Option<f64> {
    let Scene {
        points,
        by_x,
        gains,
        ..
    } = scene;
    let bonus = cfg.centre_bonus;
    // Channel order, later circles overwriting the weight, as the published code does.
    for (a, (c, &(lo, hi))) in circles.iter().zip(ranges).enumerate() {
        let r2 = c.r_mm * c.r_mm;
        for &p in &by_x[lo..hi] {
            let pt = &points[p];
            let d2 = c.dist2(pt.x, pt.y);
            if d2 <= r2 {
                if s.mask[p] == 0 {
                    s.touched.push(p);
                }
                s.mask[p] |= 1 << a;
                s.weight[p] = c.weight * ((1.0 + bonus) - bonus * d2 / r2);
            }
        }
    }
    if s.touched.is_empty() {
        return None;
    }
    // Trajectory-major order: per-trajectory sums run in detection order, as published.
    s.touched.sort_unstable();

    // Conflicts only involve trajectories that can be chosen (positive gain) and that
    // meet a circle; the rest are chosen or dropped on their own and never score.
    s.hits.clear();
    for &p in &s.touched {
        let pt = &points[p];
        if gains[pt.traj] > 0.0 {
            s.hits.push((pt.frame, pt.traj, s.mask[p]));
        }
    }
    let mut candidates: Vec<usize> = s.hits.iter().map(|h| h.1).collect();
    candidates.dedup();
    for (l, &t) in candidates.iter().enumerate() {
        s.local[t] = l;
    }
    s.hits.sort_unstable();
    let mut problem: Option<SubsetProblem> = None;
    let new_problem = || SubsetProblem::new(candidates.iter().map(|&t| gains[t]).collect());
    for group in s.hits.chunk_by(|a, b| a.0 == b.0) {
        if group.len() < 2 {
            continue;
        }
        for (i, &(_, ta, ma)) in group.iter().enumerate() {
            for &(_, tb, mb) in &group[i + 1..] {
                // Two trajectories whose only workspace is the same one.
                if ma == mb && ma.count_ones() == 1 {
                    problem
                        .get_or_insert_with(new_problem)
                        .add_conflict(s.local[ta], s.local[tb]);
                }
            }
        }
        if group.len() >= 3 && group.iter().any(|h| h.2.count_ones() > 1) {
            let members = group.iter().map(|&(_, t, m)| (s.local[t], m)).collect();
            problem
                .get_or_insert_with(new_problem)
                .add_hall_group(members);
        }
    }
    match &problem {
        None => candidates.iter().for_each(|&t| s.chosen[t] = true),
        Some(p) => p
            .solve()
            .into_iter()
            .for_each(|l| s.chosen[candidates[l]] = true),
    }

    let mut score = 0.0;
    let mut i = 0;
    while i < s.touched.len() {
        let traj = points[s.touched[i]].traj;
        let mut sum = 0.0;
        while i < s.touched.len() && points[s.touched[i]].traj == traj {
            let p = s.touched[i];
            sum += points[p].cost * s.weight[p];
            i += 1;
        }
        if s.chosen[traj] {
            score += sum;
        }
    }
    if let Some(out) = selected {
        out.clear();
        out.extend(candidates.iter().copied().filter(|&t| s.chosen[t]));
    }
    for &t in &candidates {
        s.chosen[t] = false;
        s.local[t] = usize::MAX;
    }
    for &p in &s.touched {
        s.mask[p] = 0;
        s.weight[p] = 0.0;
    }
    s.touched.clear();
    Some(score)
}

#[cfg(test)]
mod tests {
    use super::*;

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
        Trajectory {
            frames: frames.to_vec(),
            rows: rows.to_vec(),
            cols: cols.to_vec(),
            costs: costs.to_vec(),
            values: vec![1.0; frames.len()],
        }
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
        let bad_len = traj(&[0, 1], &[1], &[1, 1], &[-1.0, -1.0]);
        assert!(matches!(
            place(&[bad_len], 56, 147, pitch, &layout, &cfg),
            Err(PlacementError::LengthMismatch { trajectory: 0, .. })
        ));
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
