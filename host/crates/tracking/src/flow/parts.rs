//! The flow solved part by part: the weakly connected parts of a tracking graph (one
//! per group of detections that can link) are independent problems, so a recording's
//! cost follows its touch, not its length.

use super::{
    check_nodes, min_cost_flow, min_cost_flow_within, FlowEdge, FlowError, FlowGraph, FlowSolution,
};

/// [`min_cost_flow`] solved separately on each part of the graph that paths cannot
/// cross: the weakly connected components of the graph without `source` and `sink`.
///
/// A unit of flow never leaves the part it enters, so the min-cost flow is the union of
/// the parts' min-cost flows, and the work is the sum over the parts of (paths x part
/// size) instead of (all paths x whole graph): a long recording costs in proportion to
/// its touch. The parts' augmentations are merged in order of their true cost (the
/// order in which one solver over the whole graph makes them; the part and the
/// augmentation break exact ties), which orders the paths as [`min_cost_flow`] does and
/// decides which units fall within `max_units`. A part that loses units to the cap is
/// solved again with its share, so the flow is a min-cost flow of at most `max_units`.
///
/// The parts share a budget of `budget` edges scanned (in node order; each part's two
/// first passes always run, so the work is at most the budget plus two passes over the
/// graph). Once it is spent the remaining parts send only their first path, and
/// `budget_reached` is set: each part's flow is then a min-cost flow of its units. The
/// parts are solved on the rayon pool with the result of that loop in part order, bit
/// for bit (`solve_in_order`).
pub fn min_cost_flow_by_parts(
    g: &FlowGraph,
    source: usize,
    sink: usize,
    max_units: usize,
    budget: u64,
) -> Result<FlowSolution, FlowError> {
    check_nodes(g, source, sink)?;
    let parts = Parts::of(g, source, sink);
    let (mut solved, work) = solve_in_order(
        parts.len(),
        budget,
        |p| parts.edges(p).len() as u64,
        |p, left| solve_part(g, &parts, p, max_units, left),
    )?;
    let budget_reached = solved.iter().any(|s| s.budget_reached);
    // Every augmentation of every part, in the order one solver would make them.
    let mut order: Vec<(f64, usize, usize)> = solved
        .iter()
        .enumerate()
        .flat_map(|(p, s)| s.marginals.iter().enumerate().map(move |(a, &m)| (m, p, a)))
        .collect();
    order.sort_by(|x, y| x.0.total_cmp(&y.0).then((x.1, x.2).cmp(&(y.1, y.2))));
    let mut share = vec![0usize; solved.len()];
    for &(_, p, _) in order.iter().take(max_units) {
        share[p] += 1;
    }
    for (p, s) in solved.iter_mut().enumerate() {
        if share[p] < s.units {
            // The same first `share[p]` augmentations again: no more work than they
            // took within the budget.
            let sub = parts.graph(g, p);
            *s = min_cost_flow(&sub, 0, sub.n_nodes - 1, share[p])?;
        }
    }

    let mut used = vec![false; g.edges.len()];
    let mut keyed = Vec::new();
    let mut total_cost = 0.0;
    let mut units = 0;
    for (p, s) in solved.iter().enumerate() {
        let global = parts.edges(p);
        for (e, &u) in s.used.iter().enumerate() {
            used[global[e]] |= u;
        }
        for (path, &at) in s.paths.iter().zip(&s.found_at) {
            let edges: Vec<usize> = path.iter().map(|&e| global[e]).collect();
            keyed.push(((s.marginals[at], p, at), edges));
        }
        total_cost += s.total_cost;
        units += s.units;
    }
    keyed.sort_by(|(x, _), (y, _)| x.0.total_cmp(&y.0).then((x.1, x.2).cmp(&(y.1, y.2))));
    let marginals: Vec<f64> = keyed.iter().map(|((m, _, _), _)| *m).collect();
    Ok(FlowSolution {
        units,
        total_cost,
        used,
        found_at: (0..keyed.len()).collect(),
        paths: keyed.into_iter().map(|(_, edges)| edges).collect(),
        marginals,
        work,
        budget_reached,
    })
}

/// Part `p`'s min-cost flow of at most `max_units` within `budget`.
fn solve_part(
    g: &FlowGraph,
    parts: &Parts,
    p: usize,
    max_units: usize,
    budget: u64,
) -> Result<FlowSolution, FlowError> {
    // One part's graph at a time (per thread): the parts' copies of the edges never all
    // exist.
    let sub = parts.graph(g, p);
    // A part where no path can be negative sends nothing: most parts of a tracking
    // graph are one noise detection with a positive cost.
    let last = sub.n_nodes - 1;
    let units = if lowest_path_bound(&sub, 0, last) < 0.0 {
        max_units
    } else {
        0
    };
    min_cost_flow_within(&sub, 0, last, units, budget)
}

/// What the loop `for p in 0..parts { solve(p, budget left) }` gives, part by part,
/// with the work it took in all: each part is given the budget the parts before it
/// left, and an error is the first part's in order.
///
/// The parts are tried on the rayon pool, [`WAVE_PARTS`] at a time, each with the budget
/// left at the wave's start but at most [`TRY_WORK_PER_EDGE`] per edge of its own (so a
/// dense wave wastes a bounded amount). A try is kept when it did not reach its budget
/// and took no more than the loop would have left it: within that, a solve does not
/// depend on its budget (it stops only once its work exceeds it), so the loop would
/// have found the same flow. Any other part is solved again, in order, with what is
/// left: on one thread, or once the budget is spent, that is the loop itself.
fn solve_in_order(
    parts: usize,
    budget: u64,
    edges: impl Fn(usize) -> u64 + Sync,
    solve: impl Fn(usize, u64) -> Result<FlowSolution, FlowError> + Sync,
) -> Result<(Vec<FlowSolution>, u64), FlowError> {
    use rayon::prelude::*;
    let pooled = rayon::current_num_threads() > 1;
    let mut work = 0u64;
    let mut solved = Vec::with_capacity(parts);
    for wave in (0..parts).step_by(WAVE_PARTS) {
        let range = wave..(wave + WAVE_PARTS).min(parts);
        let left = budget.saturating_sub(work);
        let tries: Vec<Option<FlowSolution>> = if pooled && left > 0 && range.len() > 1 {
            range
                .clone()
                .into_par_iter()
                .map(|p| {
                    let cap = TRY_WORK_PER_EDGE
                        .saturating_mul(edges(p))
                        .saturating_add(TRY_WORK_BASE);
                    solve(p, left.min(cap)).ok()
                })
                .collect()
        } else {
            vec![None; range.len()]
        };
        for (p, tried) in range.zip(tries) {
            let left = budget.saturating_sub(work);
            let s = match tried {
                Some(s) if !s.budget_reached && s.work <= left => s,
                _ => solve(p, left)?,
            };
            work = work.saturating_add(s.work);
            solved.push(s);
        }
    }
    Ok((solved, work))
}

/// Parts [`solve_in_order`] tries at a time.
const WAVE_PARTS: usize = 256;

/// The most work a pooled try of a part may take, per edge of the part and in all
/// beyond that: well above the 20.5 per edge real touch needs, so only a part the
/// budget would have stopped anyway is solved twice.
const TRY_WORK_PER_EDGE: u64 = 64;
const TRY_WORK_BASE: u64 = 1_024;

/// A lower bound on the cost of any `source -> sink` path: its cheapest first and last
/// edges plus every negative edge in between, or an edge straight to the sink.
fn lowest_path_bound(g: &FlowGraph, source: usize, sink: usize) -> f64 {
    let (mut first, mut last, mut between) = (f64::INFINITY, f64::INFINITY, 0.0);
    let mut direct = f64::INFINITY;
    for e in &g.edges {
        if e.from == source && e.to == sink {
            direct = direct.min(e.cost);
        } else if e.from == source {
            first = first.min(e.cost);
        } else if e.to == sink {
            last = last.min(e.cost);
        } else {
            between += e.cost.min(0.0);
        }
    }
    (first + last + between).min(direct)
}

/// The parts of a graph for [`min_cost_flow_by_parts`]: which original edges each
/// part holds, from which [`Parts::graph`] builds the part's own graph on demand (node
/// 0 its source, its last node its sink, the other nodes and the edges in their
/// original order, which keeps every tie-break). Kept as edge indices (8 bytes an edge),
/// not as graphs (32): at an hour of touch the graph has millions of edges.
struct Parts {
    source: usize,
    sink: usize,
    /// Local index of each inner node in its part (1-based; 0 is the part's source).
    local: Vec<usize>,
    /// Each part's node count, source and sink included.
    nodes: Vec<usize>,
    /// The original edge indices, part after part, each part's in original order.
    edges: Vec<usize>,
    /// `starts[p]..starts[p + 1]` indexes part `p`'s in `edges`.
    starts: Vec<usize>,
}

impl Parts {
    fn of(g: &FlowGraph, source: usize, sink: usize) -> Self {
        let n = g.n_nodes;
        let mut parent: Vec<usize> = (0..n).collect();
        fn root(parent: &mut [usize], mut v: usize) -> usize {
            while parent[v] != v {
                parent[v] = parent[parent[v]];
                v = parent[v];
            }
            v
        }
        let inner = |v: usize| v != source && v != sink;
        for e in &g.edges {
            if inner(e.from) && inner(e.to) {
                let (a, b) = (root(&mut parent, e.from), root(&mut parent, e.to));
                // The smaller index as the root: parts come out in node order.
                parent[a.max(b)] = a.min(b);
            }
        }
        // Part of each inner node, numbered by each part's first node; the root's
        // entry of `parent` is reused for its part number once read.
        let mut part_of = vec![usize::MAX; n];
        let mut local = vec![0usize; n];
        let mut sizes: Vec<usize> = Vec::new();
        let mut part_of_root = vec![usize::MAX; n];
        for v in (0..n).filter(|&v| inner(v)) {
            let r = root(&mut parent, v);
            if part_of_root[r] == usize::MAX {
                part_of_root[r] = sizes.len();
                sizes.push(0);
            }
            let p = part_of_root[r];
            part_of[v] = p;
            sizes[p] += 1;
            local[v] = sizes[p];
        }
        drop((parent, part_of_root));
        // An edge from the source straight to the sink gets a part of its own, last.
        let direct = sizes.len();
        // Edges into the source or out of the sink can carry no source-to-sink flow;
        // they keep their place in the original edge list only. (Every other edge
        // keeps `from < to` in its part: local numbers keep the node order.)
        let carries = |e: &FlowEdge| e.from != sink && e.to != source;
        let part_of_edge = |e: &FlowEdge| {
            let owner = if inner(e.from) { e.from } else { e.to };
            if inner(owner) {
                part_of[owner]
            } else {
                direct
            }
        };
        // Counting sort of the edges by part, stable (original order within a part).
        let mut starts = vec![0usize; direct + 2];
        for e in g.edges.iter().filter(|e| carries(e)) {
            starts[part_of_edge(e) + 1] += 1;
        }
        for p in 0..=direct {
            starts[p + 1] += starts[p];
        }
        let mut next = starts.clone();
        let mut edges = vec![0usize; starts[direct + 1]];
        for (idx, e) in g.edges.iter().enumerate().filter(|(_, e)| carries(e)) {
            let p = part_of_edge(e);
            edges[next[p]] = idx;
            next[p] += 1;
        }
        let mut nodes: Vec<usize> = sizes.iter().map(|&size| size + 2).collect();
        if starts[direct + 1] > starts[direct] {
            nodes.push(2);
        } else {
            starts.pop();
        }
        Parts {
            source,
            sink,
            local,
            nodes,
            edges,
            starts,
        }
    }

    /// Number of parts.
    fn len(&self) -> usize {
        self.nodes.len()
    }

    /// The original indices of part `p`'s edges, in its graph's edge order.
    fn edges(&self, p: usize) -> &[usize] {
        &self.edges[self.starts[p]..self.starts[p + 1]]
    }

    /// Part `p`'s own graph.
    fn graph(&self, g: &FlowGraph, p: usize) -> FlowGraph {
        let last = self.nodes[p] - 1;
        let end = |v: usize| {
            if v == self.source {
                0
            } else if v == self.sink {
                last
            } else {
                self.local[v]
            }
        };
        let mut graph = FlowGraph::new(self.nodes[p]);
        graph.edges = self
            .edges(p)
            .iter()
            .map(|&idx| {
                let e = &g.edges[idx];
                FlowEdge {
                    from: end(e.from),
                    to: end(e.to),
                    cost: e.cost,
                }
            })
            .collect();
        graph
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use touchc_test_rng::Xorshift;

    /// The loop [`solve_in_order`] stands for: the oracle.
    fn in_order(
        parts: usize,
        budget: u64,
        solve: impl Fn(usize, u64) -> Result<FlowSolution, FlowError>,
    ) -> Result<(Vec<FlowSolution>, u64), FlowError> {
        let mut work = 0u64;
        let mut solved = Vec::new();
        for p in 0..parts {
            let s = solve(p, budget.saturating_sub(work))?;
            work = work.saturating_add(s.work);
            solved.push(s);
        }
        Ok((solved, work))
    }

    /// A tracking-like graph of `groups` separate groups of 1-8 detections: an entry
    /// and an exit edge per detection, and links forward within its group, with costs
    /// that make some paths worth taking and some not.
    fn scattered(rng: &mut Xorshift, groups: usize) -> FlowGraph {
        let sizes: Vec<usize> = (0..groups)
            .map(|_| 1 + (rng.next_u64() % 8) as usize)
            .collect();
        let n = sizes.iter().sum::<usize>() + 2;
        let (source, sink) = (0, n - 1);
        let mut g = FlowGraph::new(n);
        let mut first = 1;
        for size in sizes {
            for v in first..first + size {
                for (from, to) in [(source, v), (v, sink)] {
                    g.add_edge(from, to, 2.0 * rng.uniform() - 0.5).unwrap();
                }
                for w in v + 1..first + size {
                    if rng.uniform() < 0.6 {
                        g.add_edge(v, w, -3.0 * rng.uniform() + 0.5).unwrap();
                    }
                }
            }
            first += size;
        }
        g
    }

    /// On the pool, in waves, with tries kept or solved again: what the loop in part
    /// order gives, flow for flow, at every budget from none to plenty, with waves that
    /// run out of budget in their middle.
    #[test]
    fn parts_on_the_pool_are_the_loop_in_part_order() {
        let mut rng = Xorshift::new(11);
        for groups in [1, 3, 300, 700] {
            let g = scattered(&mut rng, groups);
            let (source, sink) = (0, g.n_nodes - 1);
            let parts = Parts::of(&g, source, sink);
            assert!(parts.len() >= groups);
            for max_units in [1, usize::MAX] {
                for budget in [0, 50, 2_000, 20_000, 200_000, u64::MAX] {
                    let solve = |p, left| solve_part(&g, &parts, p, max_units, left);
                    let pooled =
                        solve_in_order(parts.len(), budget, |p| parts.edges(p).len() as u64, solve);
                    let looped = in_order(parts.len(), budget, solve);
                    if groups == 700 && max_units == usize::MAX && budget == 20_000 {
                        // The budget runs out part-way through the parts: some solved in
                        // full before it, the rest stopped.
                        let flows = &looped.as_ref().unwrap().0;
                        let first = flows.iter().position(|s| s.budget_reached);
                        assert!(
                            first.is_some_and(|i| i > 1 && flows[..i].iter().any(|s| s.units > 1))
                        );
                    }
                    assert_eq!(pooled, looped, "{groups} groups, budget {budget}");
                }
            }
        }
    }
}
