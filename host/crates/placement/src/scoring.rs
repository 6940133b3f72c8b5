//! One transform's score: which points lie in which circle, the best compatible subset
//! of trajectories, and its weighted cost.
//!
//! Cost: a transform visits only the trajectories whose bounding box meets one of its
//! circles, and only their points; conflicts are found by chaining the in-circle points
//! of each frame. Nothing here grows with the recording's length beyond what the
//! transform's circles meet (a one-hour recording has 8,008 trajectories, of which a
//! transform meets about a thousand).

use touchc_model::config::PlacementConfig;
use touchc_model::geometry::{pixel_centre_mm, Circle};
use touchc_model::layout::CHANNELS;
use touchc_model::trajectory::Trajectory;

use crate::bnb::SubsetProblem;
use crate::footprint::{footprint_hits, Footprint, PixelIndex, PixelMemo};

/// A trajectory point in mm, with what scoring and conflicts need.
#[derive(Debug, Clone, Copy)]
pub(super) struct Point {
    pub(super) x: f64,
    pub(super) y: f64,
    pub(super) frame: usize,
    pub(super) cost: f64,
    /// The pixel, for the per-row and per-column circle masks.
    pub(super) row: usize,
    pub(super) col: usize,
}

/// A trajectory's extent in mm: `[x_min, x_max, y_min, y_max]` of its points.
type Extent = [f64; 4];

/// The trajectories as the search needs them, computed once per call.
pub(super) struct Scene {
    /// Every detection, trajectory-major and in detection order.
    pub(super) points: Vec<Point>,
    /// `points[start[t]..start[t + 1]]` are trajectory `t`'s detections.
    pub(super) start: Vec<usize>,
    /// Per trajectory: the extent of its points (empty trajectories have none).
    pub(super) extent: Vec<Option<Extent>>,
    /// Per trajectory: what choosing it earns (`-total_cost`).
    pub(super) gains: Vec<f64>,
    /// One more than the last frame of any point (the size of the frame chains).
    pub(super) frames: usize,
    /// The y of each pixel row's centre up to the last row of any point (ascending).
    pub(super) row_y: Vec<f64>,
    /// The x of each pixel column's centre up to the last column of any point.
    pub(super) col_x: Vec<f64>,
    /// Per trajectory with several points in a frame (a region): its distinct pixels
    /// ([`Footprint`]), scored in their place.
    pub(super) footprints: Vec<Option<Footprint>>,
    /// The centres of the pixels the footprints cover, by their number.
    pub(super) footprint_pixels: Vec<(f64, f64)>,
}

/// An in-circle point of a trajectory that can be chosen, chained with the others of
/// its frame.
#[derive(Debug, Clone, Copy)]
pub(super) struct Hit {
    frame: usize,
    /// The trajectory's index among the transform's candidates.
    local: usize,
    /// Workspaces containing the point.
    mask: u32,
    /// The previous hit of the same frame (a later candidate's is later), or `NONE`.
    next: usize,
}

/// End of a chain of hits.
const NONE: usize = usize::MAX;

/// Per-transform work buffers, reused so the search allocates only when it must.
pub(super) struct Scratch {
    /// The circles (x, radius) that `near` was built for.
    near_for: Option<[(f64, f64); CHANNELS]>,
    /// Per pixel column: the circles whose x range (with slack) holds its centre.
    pub(super) col_mask: Vec<u32>,
    /// Per pixel row: the circles whose y range (with slack) holds its centre.
    pub(super) row_mask: Vec<u32>,
    /// Trajectories whose x extent meets a circle's, ascending, with the bitmask of those
    /// circles: all a transform with these circle x positions may touch. Grid transforms
    /// share x across 210 transforms, so this is rebuilt once per x.
    near: Vec<(usize, u32)>,
    /// In-circle points of candidate trajectories, candidate-major.
    hits: Vec<Hit>,
    /// Per frame: the last hit of that frame, or `NONE` (reset after each transform).
    head: Vec<usize>,
    /// Frames with at least two hits.
    shared: Vec<usize>,
    /// Members of one frame's group: (candidate, mask), ascending.
    group: Vec<(usize, u32)>,
    /// Candidates: trajectories with positive gain and a point inside a circle, ascending.
    candidates: Vec<usize>,
    /// Per candidate: the sum of `cost * D` over its in-circle points, in detection order.
    sums: Vec<f64>,
    /// Per candidate: chosen under the current transform.
    chosen: Vec<bool>,
    /// Set when the last subset search ran out of its node budget.
    pub(super) inexact: bool,
    /// Nodes each transform's subset search may visit ([`super::bnb::transform_budget`]).
    pub(super) node_budget: u64,
    /// Per distinct pixel of a footprint: the circles it is in ([`footprint_hits`]).
    pub(super) pixel_masks: Vec<u32>,
    /// Per pixel of the scene: its circles under the current transform.
    pub(super) memo: PixelMemo,
}

impl Scene {
    /// Points in mm, each trajectory's extent and gain.
    pub(super) fn new(trajs: &[Trajectory], pitch_mm: f64) -> Scene {
        let mut points = Vec::new();
        let mut start = Vec::with_capacity(trajs.len() + 1);
        let mut extent = Vec::with_capacity(trajs.len());
        let (mut frames, mut rows, mut cols) = (0, 0, 0);
        for traj in trajs {
            start.push(points.len());
            let mut e: Option<Extent> = None;
            for d in &traj.points {
                let (x, y) = pixel_centre_mm(d.row, d.col, pitch_mm);
                points.push(Point {
                    x,
                    y,
                    frame: d.frame,
                    cost: d.cost,
                    row: d.row,
                    col: d.col,
                });
                frames = frames.max(d.frame + 1);
                rows = rows.max(d.row + 1);
                cols = cols.max(d.col + 1);
                let [x0, x1, y0, y1] = e.get_or_insert([x, x, y, y]);
                (*x0, *x1) = (x0.min(x), x1.max(x));
                (*y0, *y1) = (y0.min(y), y1.max(y));
            }
            extent.push(e);
        }
        start.push(points.len());
        // The published objective: maximise the summed -total_cost of the chosen set.
        let gains = trajs.iter().map(|t| -t.total_cost()).collect();
        // Trajectories present per frame: a footprint's frames that no other
        // trajectory shares can conflict with nothing, so they need no hit.
        let mut present = vec![0u32; frames];
        for traj in trajs {
            let mut last = None;
            for p in &traj.points {
                if last != Some(p.frame) {
                    present[p.frame] += 1;
                    last = Some(p.frame);
                }
            }
        }
        let mut pixels = PixelIndex::default();
        let footprints = (0..trajs.len())
            .map(|t| {
                Footprint::of(&points[start[t]..start[t + 1]], &mut pixels, |f| {
                    present[f] > 1
                })
            })
            .collect();
        Scene {
            points,
            start,
            extent,
            gains,
            frames,
            row_y: (0..rows)
                .map(|r| pixel_centre_mm(r, 0, pitch_mm).1)
                .collect(),
            col_x: (0..cols)
                .map(|c| pixel_centre_mm(0, c, pitch_mm).0)
                .collect(),
            footprints,
            footprint_pixels: pixels.centres,
        }
    }
}

impl Scratch {
    pub(super) fn new(scene: &Scene, node_budget: u64) -> Scratch {
        Scratch {
            near_for: None,
            col_mask: vec![0; scene.col_x.len()],
            row_mask: vec![0; scene.row_y.len()],
            near: Vec::new(),
            hits: Vec::new(),
            head: vec![NONE; scene.frames],
            shared: Vec::new(),
            group: Vec::new(),
            candidates: Vec::new(),
            sums: Vec::new(),
            chosen: Vec::new(),
            inexact: false,
            node_budget,
            pixel_masks: Vec::new(),
            memo: PixelMemo::new(&scene.footprint_pixels),
        }
    }

    /// Chains an in-circle hit of the current candidate (the next in `candidates`) in
    /// `frame`; another of its hits in the same frame (the cells of one footprint)
    /// takes its circles instead.
    #[inline]
    pub(super) fn push_hit(&mut self, frame: usize, mask: u32) {
        let local = self.candidates.len();
        let next = self.head[frame];
        if next != NONE && self.hits[next].local == local {
            self.hits[next].mask |= mask;
            return;
        }
        if next != NONE && self.hits[next].next == NONE {
            self.shared.push(frame);
        }
        self.head[frame] = self.hits.len();
        self.hits.push(Hit {
            frame,
            local,
            mask,
            next,
        });
    }

    /// Makes `near` the trajectories that circles at these x positions may contain.
    fn near_circles(&mut self, circles: &[Circle; CHANNELS], scene: &Scene) {
        let key = circles.map(|c| (c.x_mm, c.r_mm));
        let same = self.near_for.is_some_and(|k| {
            k.iter()
                .zip(&key)
                .all(|(a, b)| a.0.to_bits() == b.0.to_bits() && a.1.to_bits() == b.1.to_bits())
        });
        if same {
            return;
        }
        self.near_for = Some(key);
        self.near.clear();
        mask_lines(
            &mut self.col_mask,
            &scene.col_x,
            circles.map(|c| (c.x_mm, c.r_mm)),
        );
        for (t, e) in scene.extent.iter().enumerate() {
            let Some([x0, x1, _, _]) = *e else { continue };
            let mut mask = 0;
            for (a, c) in circles.iter().enumerate() {
                let slack = slack(c.x_mm, c.r_mm);
                if x1 >= c.x_mm - c.r_mm - slack && x0 <= c.x_mm + c.r_mm + slack {
                    mask |= 1 << a;
                }
            }
            if mask != 0 {
                self.near.push((t, mask));
            }
        }
    }
}

/// Sets in `masks[i]` the bit of each circle `(centre, radius)` whose range holds
/// `lines[i]` (ascending pixel centres along one axis), with slack: a point off that range
/// is outside the circle, so the exact test is needed only where both its row and its
/// column say so.
fn mask_lines(masks: &mut [u32], lines: &[f64], circles: [(f64, f64); CHANNELS]) {
    masks.fill(0);
    for (a, (centre, r)) in circles.into_iter().enumerate() {
        let slack = slack(centre, r);
        let lo = lines.partition_point(|&v| v < centre - r - slack);
        let hi = lines.partition_point(|&v| v <= centre + r + slack);
        for m in masks.get_mut(lo..hi.max(lo)).unwrap_or_default() {
            *m |= 1 << a;
        }
    }
}

/// How far past a circle's bounding box a point may be found inside it by the exact
/// test (`dist2 <= r^2` in f64): far more than rounding, far less than a pixel.
fn slack(centre: f64, r: f64) -> f64 {
    1e-9 * (1.0 + centre.abs() + r)
}

/// Scores one transform; `None` when no point lies in any circle (score 0).
///
/// When `selected` is given, the chosen trajectories with a point inside a circle are
/// written to it.
pub(super) fn score_transform(
    circles: &[Circle; CHANNELS],
    scene: &Scene,
    cfg: &PlacementConfig,
    s: &mut Scratch,
    selected: Option<&mut Vec<usize>>,
) -> Option<f64> {
    s.near_circles(circles, scene);
    if s.near.is_empty() {
        return None;
    }
    s.memo.next_transform();
    let test = InCircle {
        circles,
        r2: circles.map(|c| c.r_mm * c.r_mm),
        bonus: cfg.centre_bonus,
    };
    if !collect_hits(&test, scene, s) {
        return None;
    }
    let problem = conflicts(s, &scene.gains);
    choose(s, problem.as_ref());

    let mut score = 0.0;
    for (&sum, &chosen) in s.sums.iter().zip(&s.chosen) {
        if chosen {
            score += sum;
        }
    }
    if let Some(out) = selected {
        out.clear();
        let chosen = s.candidates.iter().zip(&s.chosen).filter(|c| *c.1);
        out.extend(chosen.map(|c| *c.0));
    }
    for h in &s.hits {
        s.head[h.frame] = NONE;
    }
    s.hits.clear();
    s.shared.clear();
    s.candidates.clear();
    s.sums.clear();
    Some(score)
}

/// A transform's circles with what the exact in-circle test needs.
pub(super) struct InCircle<'a> {
    circles: &'a [Circle; CHANNELS],
    /// Per circle: its radius squared.
    r2: [f64; CHANNELS],
    /// The centre bonus of the weight.
    bonus: f64,
}

impl InCircle<'_> {
    /// The circles among `bits` that contain `pt`, and the point's weight.
    #[inline]
    pub(super) fn test(&self, pt: &Point, mut bits: u32) -> (u32, f64) {
        let mut mask = 0u32;
        let mut weight = 0.0;
        // Channel order, later circles overwriting the weight, as the published code does.
        while bits != 0 {
            let a = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let c = &self.circles[a];
            let d2 = c.dist2(pt.x, pt.y);
            if d2 <= self.r2[a] {
                mask |= 1 << a;
                weight = c.weight * ((1.0 + self.bonus) - self.bonus * d2 / self.r2[a]);
            }
        }
        (mask, weight)
    }
}

/// Records the in-circle points of the near trajectories: each candidate's sum and its
/// hits chained by frame. Trajectories in ascending order, each trajectory's points in
/// detection order (the published sums run in that order). Returns whether any point
/// lies in a circle.
fn collect_hits(test: &InCircle, scene: &Scene, s: &mut Scratch) -> bool {
    let y_range = test.circles.map(|c| {
        let slack = slack(c.y_mm, c.r_mm);
        (c.y_mm - c.r_mm - slack, c.y_mm + c.r_mm + slack)
    });
    let mut row_mask_ready = false;
    let mut touched = false;
    for i in 0..s.near.len() {
        let (t, x_mask) = s.near[i];
        let Some([_, _, y0, y1]) = scene.extent[t] else {
            continue;
        };
        let near = near_in_y(x_mask, y0, y1, &y_range);
        if near == 0 {
            continue;
        }
        // Conflicts only involve trajectories that can be chosen (positive gain) and
        // that meet a circle; the rest are chosen or dropped on their own and never score.
        let candidate = scene.gains[t] > 0.0;
        let (inside, sum) = match &scene.footprints[t] {
            Some(fp) => footprint_hits(test, fp, candidate, s),
            None => {
                // A trajectory near many circles (a long one, or noise) tests each point
                // only against the circles its row and column allow; near one or two,
                // the exact test costs less than the look-ups.
                let per_point = near.count_ones() > 2;
                if per_point && !row_mask_ready {
                    let lines = test.circles.map(|c| (c.y_mm, c.r_mm));
                    mask_lines(&mut s.row_mask, &scene.row_y, lines);
                    row_mask_ready = true;
                }
                let points = &scene.points[scene.start[t]..scene.start[t + 1]];
                trajectory_hits(test, points, near, per_point, candidate, s)
            }
        };
        touched |= inside;
        if candidate && inside {
            s.candidates.push(t);
            s.sums.push(sum);
        }
    }
    touched
}

/// The circles of `x_mask` whose y range (with slack) meets `[y0, y1]`.
#[inline]
fn near_in_y(x_mask: u32, y0: f64, y1: f64, y_range: &[(f64, f64); CHANNELS]) -> u32 {
    let mut near = 0u32;
    let mut bits = x_mask;
    while bits != 0 {
        let a = bits.trailing_zeros() as usize;
        bits &= bits - 1;
        if y1 >= y_range[a].0 && y0 <= y_range[a].1 {
            near |= 1 << a;
        }
    }
    near
}

/// Tests one trajectory's points against the circles of `near`; a candidate's in-circle
/// points are chained as hits of their frames (as the next candidate). Returns whether a
/// point lies in a circle and the sum of `cost * weight` over those that do.
#[inline]
fn trajectory_hits(
    test: &InCircle,
    points: &[Point],
    near: u32,
    per_point: bool,
    candidate: bool,
    s: &mut Scratch,
) -> (bool, f64) {
    let mut inside = false;
    let mut sum = 0.0;
    for pt in points {
        let bits = if per_point {
            near & s.col_mask[pt.col] & s.row_mask[pt.row]
        } else {
            near
        };
        let (mask, weight) = test.test(pt, bits);
        if mask == 0 {
            continue;
        }
        inside = true;
        sum += pt.cost * weight;
        if candidate {
            s.push_hit(pt.frame, mask);
        }
    }
    (inside, sum)
}

/// The subset problem of the candidates, or `None` when nothing constrains them. A frame
/// where two candidates are inside circles constrains them. Frames in ascending order,
/// members in candidate order, as the published grouping by frame.
fn conflicts(s: &mut Scratch, gains: &[f64]) -> Option<SubsetProblem> {
    s.shared.sort_unstable();
    let mut problem: Option<SubsetProblem> = None;
    let new_problem = || SubsetProblem::new(s.candidates.iter().map(|&t| gains[t]).collect());
    for &frame in &s.shared {
        s.group.clear();
        let mut h = s.head[frame];
        while h != NONE {
            s.group.push((s.hits[h].local, s.hits[h].mask));
            h = s.hits[h].next;
        }
        s.group.reverse();
        let group = &s.group;
        for (i, &(la, ma)) in group.iter().enumerate() {
            for &(lb, mb) in &group[i + 1..] {
                // Two trajectories whose only workspace is the same one.
                if ma == mb && ma.count_ones() == 1 {
                    problem.get_or_insert_with(new_problem).add_conflict(la, lb);
                }
            }
        }
        if group.len() >= 3 && group.iter().any(|h| h.1.count_ones() > 1) {
            problem
                .get_or_insert_with(new_problem)
                .add_hall_group(group.clone());
        }
    }
    problem
}

/// Sets `chosen` per candidate: all of them when nothing constrains them, else the best
/// compatible subset the node budget finds (noting when it is not proven best).
fn choose(s: &mut Scratch, problem: Option<&SubsetProblem>) {
    s.chosen.clear();
    match problem {
        None => s.chosen.resize(s.candidates.len(), true),
        Some(p) => {
            s.chosen.resize(s.candidates.len(), false);
            let solution = p.solve_within(s.node_budget);
            s.inexact |= !solution.exact;
            for l in solution.chosen {
                s.chosen[l] = true;
            }
        }
    }
}
