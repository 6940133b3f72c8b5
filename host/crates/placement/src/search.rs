//! The search over the grid: every transform (in parallel chunks), or coarse to fine.

use touchc_model::config::PlacementConfig;
use touchc_model::layout::Layout;

use crate::grid::{grid_indices, grid_position};
use crate::scoring::{score_transform, Scene, Scratch};
use crate::Transform;

/// The coarse-to-fine search: the sub-grid of every `stride`-th point, then the full
/// grid within `stride - 1` steps of its `keep` best, then steepest descent over the
/// full grid's 26 neighbours of the best until no neighbour is left to score. If no
/// coarse transform meets a trajectory, the whole grid is scored (the coarse grid may
/// have stepped over a small, brief contact).
pub(super) fn coarse_to_fine(search: &Search, state: &mut Scores, stride: usize, keep: usize) {
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
pub(super) struct Search<'a> {
    pub(super) grid: &'a [Transform],
    pub(super) layout: &'a Layout,
    pub(super) cfg: &'a PlacementConfig,
    pub(super) scene: &'a Scene,
    /// Transforms scored with a subset search that ran out of budget (all threads).
    pub(super) inexact: std::sync::atomic::AtomicUsize,
    /// Nodes each transform's subset search may visit.
    pub(super) node_budget: u64,
}

/// Scores found so far (0 for a transform that meets no point or was not scored).
pub(super) struct Scores {
    pub(super) score: Vec<f64>,
    pub(super) scored: Vec<bool>,
    /// Transforms that met a point and needed a subset choice.
    pub(super) evaluated: usize,
}

/// Below this many transforms a batch runs on the calling thread: splitting costs more
/// than it saves (one transform takes about a microsecond).
pub(super) const PARALLEL_MIN: usize = 1024;

impl Scores {
    /// Scores the transforms `ks` (ascending grid positions), in parallel chunks when
    /// there are enough of them. Each transform's score depends on that transform only,
    /// so the result is the same on any number of threads.
    pub(super) fn run(&mut self, search: &Search, ks: Vec<usize>) {
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
    pub(super) fn score_seq(&self, ks: &[usize]) -> Vec<Option<f64>> {
        let mut scratch = Scratch::new(self.scene, self.node_budget);
        ks.iter()
            .map(|&k| {
                let circles = self.grid[k].circles(self.layout);
                let score = score_transform(&circles, self.scene, self.cfg, &mut scratch, None);
                if std::mem::take(&mut scratch.inexact) {
                    self.inexact
                        .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                }
                score
            })
            .collect()
    }
}
