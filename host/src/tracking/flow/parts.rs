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
/// `budget_reached` is set: each part's flow is then a min-cost flow of its units.
pub fn min_cost_flow_by_parts(
    g: &FlowGraph,
    source: usize,
    sink: usize,
    max_units: usize,
    budget: u64,
) -> Result<FlowSolution, FlowError> {
    check_nodes(g, source, sink)?;
    let parts = Parts::of(g, source, sink);
    let mut work = 0u64;
    let mut solved = Vec::with_capacity(parts.graphs.len());
    for (sub, _) in &parts.graphs {
        // A part where no path can be negative sends nothing: most parts of a
        // tracking graph are one noise detection with a positive cost.
        let last = sub.n_nodes - 1;
        let units = if lowest_path_bound(sub, 0, last) < 0.0 {
            max_units
        } else {
            0
        };
        let s = min_cost_flow_within(sub, 0, last, units, budget.saturating_sub(work))?;
        work = work.saturating_add(s.work);
        solved.push(s);
    }
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
            let sub = &parts.graphs[p].0;
            *s = min_cost_flow(sub, 0, sub.n_nodes - 1, share[p])?;
        }
    }

    let mut used = vec![false; g.edges.len()];
    let mut keyed = Vec::new();
    let mut total_cost = 0.0;
    let mut units = 0;
    for (p, s) in solved.iter().enumerate() {
        let global = &parts.graphs[p].1;
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

/// The parts of a graph for [`min_cost_flow_by_parts`]: each part's own graph (node 0
/// its source, its last node its sink, the other nodes and the edges in their original
/// order, which keeps every tie-break) and the original index of each of its edges.
struct Parts {
    graphs: Vec<(FlowGraph, Vec<usize>)>,
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
        // Part of each inner node, numbered by each part's first node.
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
        // Inner nodes keep their relative order; source first, sink last. An edge
        // from the source straight to the sink gets a part of its own.
        let mut graphs: Vec<(FlowGraph, Vec<usize>)> = sizes
            .iter()
            .map(|&size| (FlowGraph::new(size + 2), Vec::new()))
            .collect();
        let mut direct: Option<(FlowGraph, Vec<usize>)> = None;
        for (idx, e) in g.edges.iter().enumerate() {
            let owner = if inner(e.from) { e.from } else { e.to };
            let (graph, map) = if inner(owner) {
                &mut graphs[part_of[owner]]
            } else {
                direct.get_or_insert_with(|| (FlowGraph::new(2), Vec::new()))
            };
            let last = graph.n_nodes - 1;
            let end = |v: usize| {
                if v == source {
                    0
                } else if v == sink {
                    last
                } else {
                    local[v]
                }
            };
            // Edges into the source or out of the sink can carry no source-to-sink
            // flow; they keep their place in the original edge list only.
            let (from, to) = (end(e.from), end(e.to));
            if from < to && e.from != sink && e.to != source {
                graph.edges.push(FlowEdge {
                    from,
                    to,
                    cost: e.cost,
                });
                map.push(idx);
            }
        }
        graphs.extend(direct);
        Parts { graphs }
    }
}
