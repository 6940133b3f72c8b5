//! The placement restated naively, the oracle of `oracle.rs` and `regions.rs`: every
//! point tested against every circle (no x ranges, no skipping, no memo), a
//! trajectory's points of one frame one member of that frame's group in the circles of
//! all of them (a trajectory of one point a frame is the published algorithm's case),
//! one Hall constraint per frame (no pairwise shortcut), the subset found by exhaustive
//! search, and each chosen trajectory's in-circle points summed in detection order.

use crate::bnb::SubsetProblem;
use crate::transform_grid;
use touchc_model::config::PlacementConfig;
use touchc_model::geometry::pixel_centre_mm;
use touchc_model::layout::Layout;
use touchc_model::trajectory::Trajectory;

/// Per transform of the grid of a `rows` x `cols` frame of pixels `pitch` mm apart:
/// (score, chosen trajectories with a point in a circle).
pub(super) fn naive(
    trajs: &[Trajectory],
    (rows, cols, pitch): (usize, usize, f64),
    layout: &Layout,
    cfg: &PlacementConfig,
) -> Vec<(f64, Vec<usize>)> {
    let b = cfg.centre_bonus;
    let gains: Vec<f64> = trajs.iter().map(|t| -t.total_cost()).collect();
    let last_frame = trajs
        .iter()
        .flat_map(|t| t.points.iter().map(|p| p.frame))
        .max()
        .unwrap_or(0);
    transform_grid(rows, cols, pitch, layout, cfg)
        .iter()
        .map(|t| {
            let circles = t.circles(layout);
            // Per trajectory, per point: its circles and the weight of the last.
            let tested: Vec<Vec<(u32, f64)>> = trajs
                .iter()
                .map(|traj| {
                    traj.points
                        .iter()
                        .map(|p| {
                            let (x, y) = pixel_centre_mm(p.row, p.col, pitch);
                            let (mut m, mut w) = (0u32, 0.0);
                            for (a, c) in circles.iter().enumerate() {
                                if c.contains(x, y) {
                                    m |= 1 << a;
                                    let r2 = c.r_mm * c.r_mm;
                                    w = c.weight * ((1.0 + b) - b * c.dist2(x, y) / r2);
                                }
                            }
                            (m, w)
                        })
                        .collect()
                })
                .collect();
            let mut problem = SubsetProblem::new(gains.clone());
            for frame in 0..=last_frame {
                let group: Vec<(usize, u32)> = trajs
                    .iter()
                    .enumerate()
                    .filter_map(|(i, tr)| {
                        let mask = tr
                            .points
                            .iter()
                            .zip(&tested[i])
                            .filter(|(p, _)| p.frame == frame)
                            .fold(0, |m, (_, t)| m | t.0);
                        (mask != 0).then_some((i, mask))
                    })
                    .collect();
                problem.add_hall_group(group);
            }
            let mut score = 0.0;
            let mut selected = Vec::new();
            for i in problem.solve_brute_force() {
                if tested[i].iter().any(|t| t.0 != 0) {
                    score += trajs[i]
                        .points
                        .iter()
                        .zip(&tested[i])
                        .filter(|(_, t)| t.0 != 0)
                        .fold(0.0, |s, (p, t)| s + p.cost * t.1);
                    selected.push(i);
                }
            }
            (score, selected)
        })
        .collect()
}
