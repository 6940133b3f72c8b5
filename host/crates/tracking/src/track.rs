//! Stage 3: trajectories by min-cost flow over the detections (Zhang, Li, Nevatia 2008)
//! ([`link`]); `touchc-pipeline`'s `track` runs stages 0 to 3 with it.
//!
//! Graph layout, matching the published code's node and edge order (it decides ties):
//! source = node 0; detection `k` (frame-major, row-major) has an entry node `2k + 1` and
//! an exit node `2k + 2` joined by its detection cost; sink = `2n + 1`. Per detection the
//! edges are added as: detection edge, source -> entry (`entry_cost`), exit -> sink
//! (`exit_cost`), then one link from each detection of the previous frame (in that
//! frame's order) closer than the gate, cost `-ln(1 - d^2 / gate)`; a lattice point of
//! a flat contact links only from the same cell (see `hops`).
//!
//! Trajectories are reported in the order the published solver reports them: by the
//! augmentation that first routed flow into the trajectory's last detection's exit edge
//! (so the strongest trajectory usually comes first).

use ndarray::Array3;

use crate::detect::{Detection, Detections};
use crate::flow::{min_cost_flow_by_parts, FlowError, FlowGraph};
use crate::preprocess::{Blurred, PreprocessError};
use touchc_model::config::{Sampling, TrackConfig};
use touchc_model::trajectory::{Point, Trajectory};

/// Any failure of stages 0 to 3.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TrackError {
    /// The preprocessing parameters are unusable.
    #[error("preprocess config")]
    Preprocess(#[from] PreprocessError),
    /// The tracking parameters produced an unsolvable graph (e.g. a NaN entry cost).
    #[error("tracking config")]
    Flow(#[from] FlowError),
    /// The detections link into a flow graph above `MAX_FLOW_EDGES` (a tare that left
    /// noise, or a link gate wider than the touch needs).
    #[error(
        "the scene is too dense to track: {detections} detections would link into more \
         than {limit} edges"
    )]
    TooDense {
        /// Detections in the graph.
        detections: usize,
        /// The edge limit reached.
        limit: usize,
    },
}

/// Everything later stages need from tracking.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackOutput {
    /// Blurred frames (f64, `[T, R k, C k]`), global mean/std and pixel pitch; the signal
    /// stage reads actuator-circle pressures from these frames.
    pub blurred: Blurred,
    /// Every detection with its cost (empty when the tracking streamed, see
    /// `track_streaming`; `detection_count` counts them either way).
    pub detections: Detections,
    /// Detections scored in the tracked frames and cells.
    pub detection_count: usize,
    /// The trajectories, in the solver's report order (see the module docs).
    pub trajectories: Vec<Trajectory>,
    /// The min-cost flow's work, in edges scanned.
    pub flow_work: u64,
    /// The flow stopped at `flow_work_budget` before it was optimal: weaker contacts
    /// may be untracked (the compile warns).
    pub flow_budget_reached: bool,
}

/// Trajectories and what finding them took ([`link`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Linked {
    /// The trajectories, in the solver's report order.
    pub trajectories: Vec<Trajectory>,
    /// Edges the min-cost flow scanned.
    pub work: u64,
    /// The flow stopped at `flow_work_budget` before it was optimal.
    pub budget_reached: bool,
}

/// The min-cost flow's work budget, in edges scanned, for a graph of `edges` edges:
/// [`FLOW_WORK_PER_EDGE`] per edge plus [`FLOW_WORK_BASE`].
///
/// Each unit of flow scans at most the edges of its part of the graph, so real touch,
/// a few contacts per part, scans a few times the graph: at most 20.5 per edge on the
/// shipped examples, the 698-frame recording and an hour of repeated dense touch (24.6 M
/// scans of a 1.44 M-edge graph, 0.4 s). A scene that links every detection to every
/// other and sends hundreds of units through one part (dense noise on a small sensor
/// under a gate wider than the sensor, when tied pixels counted as a detection each,
/// took 600-860 scans per edge) is stopped at about a second with a warning.
pub(crate) fn flow_work_budget(edges: usize) -> u64 {
    FLOW_WORK_PER_EDGE
        .saturating_mul(edges as u64)
        .saturating_add(FLOW_WORK_BASE)
}

/// The most edges a tracking graph may have: 2^24, about 0.4 GB for the edge list and
/// at most 1.5 GB for the solve's indexes, twelve times the graph of an hour of dense
/// touch (1.44 M edges). Beyond it [`link`] stops building and returns
/// [`FlowError::TooManyEdges`] (the tracking reports [`TrackError::TooDense`]) instead
/// of asking for memory the scene does not justify; with the work budget
/// ([`flow_work_budget`]) it bounds both the memory and the time of every part's solve.
pub(crate) const MAX_FLOW_EDGES: usize = 1 << 24;

/// Edges scanned per graph edge the flow may spend (`flow_work_budget`): six times
/// what real touch needs.
pub const FLOW_WORK_PER_EDGE: u64 = 128;

/// Work any graph may spend, however small ([`flow_work_budget`]): 2^24 edges scanned,
/// about 0.1 s.
pub(crate) const FLOW_WORK_BASE: u64 = 1 << 24;

impl TrackOutput {
    /// Global mean of the blurred frames (psi).
    pub fn mean(&self) -> f64 {
        self.blurred.mean
    }

    /// Global population standard deviation of the blurred frames (psi).
    pub fn std(&self) -> f64 {
        self.blurred.std
    }

    /// Pixel pitch of the blurred frames, mm.
    pub fn pitch_mm(&self) -> f64 {
        self.blurred.pitch_mm
    }

    /// The blurred frames `[T, R k, C k]`, psi.
    pub fn frames(&self) -> &Array3<f64> {
        &self.blurred.frames
    }
}

/// Whether a link from `a` to `b` would hop between cells of a flat contact's lattice:
/// a lattice point is a fixed cell and links only to the same cell; the contact's
/// motion is its local maximum's.
///
/// A hop follows no motion, and it lets the flow trade paths: the link cost is convex
/// in the squared step, so two medium steps (the maximum onto a lattice cell, a lattice
/// cell onto the maximum) cost less than the maximum's own short step plus a long one,
/// and a sliding hand's trajectory is handed to another at every turn of a rub.
fn hops(a: &Detection, b: &Detection) -> bool {
    (a.fixed || b.fixed) && (a.row, a.col) != (b.row, b.col)
}

/// Builds the flow graph of `detections`, solves it and extracts the trajectories. The
/// link gate is `cfg.max_speed_mm_s` in squared pixels per frame at `sampling`; with
/// `cfg.bridge` links also skip missing frames (see `Bridge`), without it the graph is
/// the paper's. The flow stops at `flow_work_budget` edges scanned (`budget_reached`).
pub fn link(
    detections: &Detections,
    cfg: &TrackConfig,
    sampling: &Sampling,
) -> Result<Linked, FlowError> {
    link_within(detections, cfg, sampling, MAX_FLOW_EDGES)
}

/// [`link`] with a graph of at most `max_edges` edges ([`FlowError::TooManyEdges`]
/// beyond).
pub fn link_within(
    detections: &Detections,
    cfg: &TrackConfig,
    sampling: &Sampling,
    max_edges: usize,
) -> Result<Linked, FlowError> {
    let gate_px2 = sampling.gate_px2(cfg.max_speed_mm_s);
    let (missing, cost_per_missing) = cfg.bridge.map_or((0, 0.0), |b| {
        (b.missing_frames(sampling.rate_hz), b.cost_per_missing)
    });
    // Graph nodes only for the detections that can take part (see [`Bridge`]): all of
    // them without bridging (the paper's graph, node for node), else those cheaper
    // than a missing frame. `node_of[k]` numbers detection `k`'s node pair.
    let takes_part = |cost: f64| cfg.bridge.is_none() || cost < cost_per_missing;
    let mut node_of = vec![usize::MAX; detections.all.len()];
    let mut kept = Vec::new();
    for (k, d) in detections.all.iter().enumerate() {
        if takes_part(d.cost) {
            node_of[k] = kept.len();
            kept.push(k);
        }
    }
    let n = kept.len();
    let (source, sink) = (0, 2 * n + 1);
    let mut g = FlowGraph::with_edge_limit(2 * n + 2, max_edges);
    for &k in &kept {
        let d = &detections.all[k];
        let t = d.frame;
        let (entry, exit) = (2 * node_of[k] + 1, 2 * node_of[k] + 2);
        g.add_edge(entry, exit, d.cost)?;
        g.add_edge(source, entry, cfg.entry_cost)?;
        g.add_edge(exit, sink, cfg.exit_cost)?;
        // Links from `gap` frames back: the previous frame (the paper's only link),
        // then across missing frames when bridging.
        for gap in 1..=(missing + 1).min(t) {
            let gate = gate_px2 * (gap * gap) as f64;
            let radius = if gate > 0.0 { gate.sqrt() } else { 0.0 };
            let (back, first_back) = (
                detections.in_frame(t - gap),
                detections.frame_start[t - gap],
            );
            // Earlier detections are sorted by row: skip rows too far above to link.
            let lo = back.partition_point(|p| (p.row as f64) < d.row as f64 - radius);
            for (j, p) in back.iter().enumerate().skip(lo) {
                let dr = p.row as f64 - d.row as f64;
                if dr > radius {
                    break;
                }
                let from = node_of[first_back + j];
                if from == usize::MAX {
                    continue;
                }
                let dc = p.col as f64 - d.col as f64;
                let d2 = dr * dr + dc * dc;
                if d2 < gate && !hops(p, d) {
                    let mut cost = -(-d2 / gate).ln_1p();
                    if gap > 1 {
                        cost += cost_per_missing * (gap - 1) as f64;
                    }
                    g.add_edge(2 * from + 2, entry, cost)?;
                }
            }
        }
    }
    drop(node_of);
    let budget = flow_work_budget(g.edges().len());
    let solution = min_cost_flow_by_parts(&g, source, sink, cfg.max_trajectories, budget)?;
    // The detection edges are the only ones leaving an odd node (an entry node,
    // `2 i + 1` for the `i`-th kept detection): source edges leave node 0, exit and
    // link edges leave exit nodes, which are even. No per-edge table is kept.
    let detection_of = |e: usize| {
        let from = g.edges()[e].from;
        (from % 2 == 1).then(|| kept[(from - 1) / 2])
    };
    let trajectories = solution
        .paths
        .iter()
        .map(|path| {
            path.iter()
                .filter_map(|&e| detection_of(e))
                .map(|k| {
                    let d = &detections.all[k];
                    Point {
                        frame: d.frame,
                        row: d.row,
                        col: d.col,
                        cost: d.cost,
                        value: d.value,
                    }
                })
                .collect::<Trajectory>()
        })
        .collect();
    Ok(Linked {
        trajectories,
        work: solution.work,
        budget_reached: solution.budget_reached,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use touchc_model::config::{Config, Preset};

    /// Strong detections, one per frame, at `(row, col, fixed)`.
    fn one_per_frame(points: &[(usize, usize, bool)]) -> Detections {
        let all: Vec<Detection> = points
            .iter()
            .enumerate()
            .map(|(frame, &(row, col, fixed))| Detection {
                frame,
                row,
                col,
                value: 1.0,
                cost: -3.9,
                fixed,
            })
            .collect();
        Detections {
            frame_start: (0..=all.len()).collect(),
            all,
        }
    }

    fn trajectories(points: &[(usize, usize, bool)]) -> usize {
        let cfg = Config::preset(Preset::Touch).track;
        // 7 pixels per cell at 20 Hz: the gate is far wider than the steps below.
        let sampling = Sampling {
            rate_hz: 20.0,
            pitch_mm: 25.4,
            upsample: 7,
        };
        link(&one_per_frame(points), &cfg, &sampling)
            .unwrap()
            .trajectories
            .len()
    }

    #[test]
    fn a_lattice_point_links_only_to_its_own_cell() {
        // A maximum moving 7 pixels a frame is one trajectory.
        assert_eq!(
            trajectories(&[(3, 3, false), (3, 10, false), (3, 17, false)]),
            1
        );
        // A lattice cell held is one trajectory.
        assert_eq!(trajectories(&[(3, 3, true), (3, 3, true), (3, 3, true)]), 1);
        // Lattice cells in turn are a cell each.
        assert_eq!(
            trajectories(&[(3, 3, true), (3, 17, true), (3, 31, true)]),
            3
        );
        // A maximum does not pass through one: it bridges the frame, the cell is its own.
        assert_eq!(
            trajectories(&[(3, 3, false), (3, 17, true), (3, 24, false)]),
            2
        );
    }
}
