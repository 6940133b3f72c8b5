//! One transform's score: which points lie in which circle, the best compatible subset
//! of trajectories, and its weighted cost.

use super::*;

/// A trajectory point in mm, with what scoring and conflicts need.
#[derive(Debug, Clone, Copy)]
pub(super) struct Point {
    pub(super) x: f64,
    pub(super) y: f64,
    pub(super) traj: usize,
    pub(super) frame: usize,
    pub(super) cost: f64,
}

/// The trajectories as the search needs them, computed once per call.
pub(super) struct Scene {
    /// Every detection, trajectory-major and in detection order.
    pub(super) points: Vec<Point>,
    /// Point indices sorted by x, so a circle finds its candidates by binary search.
    pub(super) by_x: Vec<usize>,
    /// The x of each point of `by_x`.
    pub(super) sorted_x: Vec<f64>,
    /// Per trajectory: what choosing it earns (`-total_cost`).
    pub(super) gains: Vec<f64>,
}

/// Per-transform work buffers, reused so the search allocates only when it must.
pub(super) struct Scratch {
    /// Workspace bitmask of each point under the current transform.
    pub(super) mask: Vec<u32>,
    /// Weight `D` of each point (of the last workspace containing it, as published).
    pub(super) weight: Vec<f64>,
    /// Points with a non-zero mask, to reset and to visit.
    pub(super) touched: Vec<usize>,
    /// (frame, trajectory, mask) of touched points of candidate trajectories.
    pub(super) hits: Vec<(usize, usize, u32)>,
    /// Per trajectory: chosen under the current transform.
    pub(super) chosen: Vec<bool>,
    /// Per trajectory: local index in the subset problem, or `usize::MAX`.
    pub(super) local: Vec<usize>,
    /// Set when the last subset search ran out of its node budget.
    pub(super) inexact: bool,
    /// Nodes each transform's subset search may visit ([`super::bnb::transform_budget`]).
    pub(super) node_budget: u64,
}

impl Scene {
    /// Points in mm, sorted by x, and each trajectory's gain.
    pub(super) fn new(trajs: &[Trajectory], pitch_mm: f64) -> Scene {
        let mut points = Vec::new();
        for (t, traj) in trajs.iter().enumerate() {
            for d in &traj.points {
                let (x, y) = pixel_centre_mm(d.row, d.col, pitch_mm);
                points.push(Point {
                    x,
                    y,
                    traj: t,
                    frame: d.frame,
                    cost: d.cost,
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
    pub(super) fn new(scene: &Scene, trajectories: usize, node_budget: u64) -> Scratch {
        Scratch {
            mask: vec![0; scene.points.len()],
            weight: vec![0.0; scene.points.len()],
            touched: Vec::new(),
            hits: Vec::new(),
            chosen: vec![false; trajectories],
            local: vec![usize::MAX; trajectories],
            inexact: false,
            node_budget,
        }
    }
}

/// Scores one transform; `None` when no point lies in any circle (score 0).
///
/// `ranges[a]` is the slice of `scene.by_x` that circle `a` may contain. When `selected`
/// is given, the chosen trajectories with a point inside a circle are written to it.
pub(super) fn score_transform(
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
        Some(p) => {
            let solution = p.solve_within(s.node_budget);
            s.inexact |= !solution.exact;
            for l in solution.chosen {
                s.chosen[candidates[l]] = true;
            }
        }
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
