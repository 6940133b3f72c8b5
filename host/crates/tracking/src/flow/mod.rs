//! Min-cost flow with unit capacities on a time-ordered DAG, by successive shortest paths.
//!
//! Every edge goes from a lower to a higher node index (tracking numbers nodes in time
//! order), so the first shortest path is one dynamic-programming sweep in index order,
//! which also copes with the negative detection costs. Its distances become potentials
//! that make every residual reduced cost non-negative, and each further unit of flow is
//! one Dijkstra search (Johnson's reweighting). Flow is added one unit at a time while
//! the marginal (true, not reduced) path cost is negative: the total cost is convex in
//! the amount of flow, so the first non-negative path marks the optimum.
//!
//! Tie-breaking, fixed so results never depend on hashing or allocation:
//! - the DP keeps the first incoming edge (in insertion order) that strictly improves;
//! - Dijkstra pops the smallest `(distance, node index)` and relaxes on strict
//!   improvement only, scanning a node's unused out-edges in insertion order, then its
//!   used in-edges (residual back edges) in insertion order;
//! - reduced costs that rounding pushes below zero are clamped to zero;
//! - each Dijkstra stops when the sink is settled (unsettled nodes' potentials grow by
//!   the sink distance, which keeps reduced costs non-negative).
//!
//! Work is counted in edges scanned, and a solve may be given a budget of them
//! ([`min_cost_flow_by_parts`]): when it runs out the flow found so far is returned (the
//! min-cost flow of that many units) and [`FlowSolution::budget_reached`] says so. A
//! scene of dense noise on a small sensor under a wide gate is otherwise units x edges.

use std::cmp::{Ordering, Reverse};
use std::collections::BinaryHeap;

/// Why a graph cannot be solved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FlowError {
    /// An edge does not go from a lower to a higher node index.
    #[error("edge {from} -> {to} is not forward in node order")]
    NotForward {
        /// Tail node.
        from: usize,
        /// Head node.
        to: usize,
    },
    /// A node index is not below the node count.
    #[error("node {node} out of range (graph has {n_nodes} nodes)")]
    NodeOutOfRange {
        /// The offending index.
        node: usize,
        /// Nodes in the graph.
        n_nodes: usize,
    },
    /// The graph would hold more edges than its limit (`FlowGraph::with_edge_limit`).
    #[error("the graph would exceed its limit of {limit} edges")]
    TooManyEdges {
        /// The most edges the graph may hold.
        limit: usize,
    },
    /// An edge cost is NaN or infinite.
    #[error("edge {from} -> {to} has a non-finite cost {cost}")]
    NonFiniteCost {
        /// Tail node.
        from: usize,
        /// Head node.
        to: usize,
        /// The cost.
        cost: f64,
    },
}

/// A directed edge of capacity one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlowEdge {
    /// Tail node.
    pub from: usize,
    /// Head node (greater than `from`).
    pub to: usize,
    /// Cost of one unit of flow.
    pub cost: f64,
}

/// A DAG whose edges all point to higher node indices.
#[derive(Debug, Clone)]
pub struct FlowGraph {
    n_nodes: usize,
    edges: Vec<FlowEdge>,
    max_edges: usize,
}

impl Default for FlowGraph {
    fn default() -> Self {
        Self::new(0)
    }
}

impl FlowGraph {
    /// An empty graph with `n_nodes` nodes and no limit on its edges.
    pub fn new(n_nodes: usize) -> Self {
        Self::with_edge_limit(n_nodes, usize::MAX)
    }

    /// An empty graph with `n_nodes` nodes that refuses its `max_edges + 1`-th edge
    /// ([`FlowError::TooManyEdges`]) before allocating for it: a caller that builds a
    /// graph from data bounds its memory with this (the edge list grows by doubling, so
    /// a power of two is never overshot).
    pub(crate) fn with_edge_limit(n_nodes: usize, max_edges: usize) -> Self {
        Self {
            n_nodes,
            edges: Vec::new(),
            max_edges,
        }
    }

    /// Adds a unit-capacity edge and returns its index; insertion order breaks ties.
    pub fn add_edge(&mut self, from: usize, to: usize, cost: f64) -> Result<usize, FlowError> {
        for node in [from, to] {
            if node >= self.n_nodes {
                return Err(FlowError::NodeOutOfRange {
                    node,
                    n_nodes: self.n_nodes,
                });
            }
        }
        if from >= to {
            return Err(FlowError::NotForward { from, to });
        }
        if !cost.is_finite() {
            return Err(FlowError::NonFiniteCost { from, to, cost });
        }
        if self.edges.len() >= self.max_edges {
            return Err(FlowError::TooManyEdges {
                limit: self.max_edges,
            });
        }
        let idx = self.edges.len();
        self.edges.push(FlowEdge { from, to, cost });
        Ok(idx)
    }

    /// The edges, in insertion order.
    pub fn edges(&self) -> &[FlowEdge] {
        &self.edges
    }
}

/// The optimal flow.
#[derive(Debug, Clone, PartialEq)]
pub struct FlowSolution {
    /// Units of flow sent (0 when no path has negative cost).
    pub units: usize,
    /// Total cost of the flow (sum of the costs of used edges).
    pub total_cost: f64,
    /// Whether each edge (by index) carries flow.
    pub used: Vec<bool>,
    /// The flow decomposed into source-to-sink paths (edge indices, source first),
    /// ordered by the augmentation that first put flow on each path's last edge.
    pub paths: Vec<Vec<usize>>,
    /// For each path, that augmentation (an index into `marginals`).
    pub found_at: Vec<usize>,
    /// The true cost of each augmentation, in order (non-decreasing: the total cost is
    /// convex in the amount of flow).
    pub marginals: Vec<f64>,
    /// Edges scanned: two passes over the graph, then the Dijkstra searches.
    pub work: u64,
    /// The work budget ran out before the flow was optimal: more negative paths may
    /// remain (for one graph, the flow is the min-cost flow of `units` units; by parts,
    /// each part's is of its own units).
    pub budget_reached: bool,
}

/// Nodes whose best path through them costs at least this are pruned; slightly above 0
/// so that rounding never prunes a node of a (barely) negative path.
const PRUNE_MARGIN: f64 = 1e-9;

/// f64 with a total order, for the Dijkstra heap.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Dist(f64);
impl Eq for Dist {}
impl PartialOrd for Dist {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Dist {
    fn cmp(&self, other: &Self) -> Ordering {
        self.0.total_cmp(&other.0)
    }
}

/// Edge lists per node in compressed form (one allocation, not one per node), each
/// node's list in insertion order: that order is the documented tie-break.
struct Adjacency {
    start: Vec<usize>,
    list: Vec<usize>,
}

impl Adjacency {
    fn new(n: usize, edges: &[FlowEdge], node_of: impl Fn(&FlowEdge) -> usize) -> Self {
        let mut start = vec![0usize; n + 1];
        for e in edges {
            start[node_of(e) + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut list = vec![0usize; edges.len()];
        for (idx, e) in edges.iter().enumerate() {
            let v = node_of(e);
            list[fill[v]] = idx;
            fill[v] += 1;
        }
        Self { start, list }
    }

    fn of(&self, v: usize) -> &[usize] {
        &self.list[self.start[v]..self.start[v + 1]]
    }
}

/// How a node was reached: over an edge forwards, or backwards over a used edge.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Step {
    None,
    Forward(usize),
    Backward(usize),
}

/// `source` and `sink` must be nodes of `g`.
fn check_nodes(g: &FlowGraph, source: usize, sink: usize) -> Result<(), FlowError> {
    match [source, sink].into_iter().find(|&node| node >= g.n_nodes) {
        Some(node) => Err(FlowError::NodeOutOfRange {
            node,
            n_nodes: g.n_nodes,
        }),
        None => Ok(()),
    }
}

/// Solves min-cost flow from `source` to `sink`, at most `max_units` units.
pub fn min_cost_flow(
    g: &FlowGraph,
    source: usize,
    sink: usize,
    max_units: usize,
) -> Result<FlowSolution, FlowError> {
    min_cost_flow_within(g, source, sink, max_units, u64::MAX)
}

/// [`min_cost_flow`] that stops once `budget` edges have been scanned (the two first
/// passes always run): the solution is then the min-cost flow of the units found, with
/// `budget_reached` set.
pub(crate) fn min_cost_flow_within(
    g: &FlowGraph,
    source: usize,
    sink: usize,
    max_units: usize,
    budget: u64,
) -> Result<FlowSolution, FlowError> {
    check_nodes(g, source, sink)?;
    let n = g.n_nodes;
    let net = Net {
        g,
        out_edges: Adjacency::new(n, &g.edges, |e| e.from),
        in_edges: Adjacency::new(n, &g.edges, |e| e.to),
        source,
        sink,
    };
    let mut used = vec![false; g.edges.len()];
    let mut first_used_at = vec![usize::MAX; g.edges.len()];
    let mut units = 0usize;
    let mut total_cost = 0.0f64;
    let mut marginals = Vec::new();
    if max_units == 0 || source >= sink {
        return Ok(FlowSolution {
            units,
            total_cost,
            used,
            paths: Vec::new(),
            found_at: Vec::new(),
            marginals,
            work: 0,
            budget_reached: false,
        });
    }
    // The DP and the pruning pass each scan every edge once.
    let mut work = 2 * g.edges.len() as u64;
    let mut budget_reached = false;

    let (mut pot, pred) = first_path(&net);
    prune(&net, &mut pot);

    let mut search = Search {
        dist: vec![f64::INFINITY; n],
        pred,
        heap: BinaryHeap::new(),
    };
    loop {
        if !pot[sink].is_finite() {
            break;
        }
        let Some((path, marginal)) = trace(&net, &search.pred) else {
            break;
        };
        if marginal >= 0.0 {
            break;
        }
        augment(&path, &mut used, &mut first_used_at, units);
        units += 1;
        total_cost += marginal;
        marginals.push(marginal);
        if units >= max_units {
            break;
        }
        let Some(reached_sink) = next_path(&net, &used, &pot, &mut search, &mut work, budget)
        else {
            // This search did not finish: the flow so far is the answer.
            budget_reached = true;
            break;
        };
        // Early exit: nodes not settled before the sink get the sink's distance, which
        // keeps every reduced cost non-negative (for a settled u and unsettled v,
        // dist(sink) <= dist(v) <= dist(u) + c'). Unreachable stays unreachable: pruned
        // nodes keep their infinite potential.
        for (p, &d) in pot.iter_mut().zip(&search.dist) {
            *p += d.min(reached_sink);
        }
    }

    let (paths, found_at) = decompose(g, &net.in_edges, source, sink, &used, &first_used_at);
    Ok(FlowSolution {
        units,
        total_cost,
        used,
        paths,
        found_at,
        marginals,
        work,
        budget_reached,
    })
}

/// The graph with its edge lists, and the two ends of the flow.
struct Net<'a> {
    g: &'a FlowGraph,
    out_edges: Adjacency,
    in_edges: Adjacency,
    source: usize,
    sink: usize,
}

/// The Dijkstra state, kept across searches so each one reuses its allocations.
struct Search {
    dist: Vec<f64>,
    pred: Vec<Step>,
    heap: BinaryHeap<Reverse<(Dist, usize)>>,
}

/// First path: DP in index order (edges only go forward); the shortest distance of
/// every node from the source, and the edge each was reached by.
fn first_path(net: &Net) -> (Vec<f64>, Vec<Step>) {
    let (g, source, n) = (net.g, net.source, net.g.n_nodes);
    let mut pot = vec![f64::INFINITY; n];
    let mut pred = vec![Step::None; n];
    pot[source] = 0.0;
    for v in source + 1..n {
        let mut best = f64::INFINITY;
        for &e in net.in_edges.of(v) {
            let edge = &g.edges[e];
            let d = pot[edge.from] + edge.cost;
            if d < best {
                best = d;
                pred[v] = Step::Forward(e);
            }
        }
        pot[v] = best;
    }
    (pot, pred)
}

/// Prune nodes on no negative source-sink path (shortest prefix plus shortest suffix
/// at least 0). Exact: every path of a min-cost k-flow is negative (else dropping it would
/// beat the min-cost (k-1)-flow), so no accepted flow ever uses a pruned node. On
/// tracking graphs this removes nearly all noise detections before any Dijkstra.
fn prune(net: &Net, pot: &mut [f64]) {
    let (g, source, sink, n) = (net.g, net.source, net.sink, net.g.n_nodes);
    let mut suffix = vec![f64::INFINITY; n];
    suffix[sink] = 0.0;
    for u in (source..sink).rev() {
        for &e in net.out_edges.of(u) {
            let edge = &g.edges[e];
            suffix[u] = suffix[u].min(edge.cost + suffix[edge.to]);
        }
    }
    for v in 0..n {
        let through = pot[v] + suffix[v];
        if v != source && v != sink && through.partial_cmp(&PRUNE_MARGIN) != Some(Ordering::Less) {
            pot[v] = f64::INFINITY;
        }
    }
}

/// The path `pred` leads back from the sink, sink first, with its true marginal cost
/// (reduced costs only steer the search); `None` if it does not reach the source.
fn trace(net: &Net, pred: &[Step]) -> Option<(Vec<Step>, f64)> {
    let g = net.g;
    let mut path = Vec::new();
    let mut marginal = 0.0;
    let mut v = net.sink;
    while v != net.source {
        match pred[v] {
            Step::Forward(e) => {
                marginal += g.edges[e].cost;
                path.push(Step::Forward(e));
                v = g.edges[e].from;
            }
            Step::Backward(e) => {
                marginal -= g.edges[e].cost;
                path.push(Step::Backward(e));
                v = g.edges[e].to;
            }
            Step::None => break,
        }
    }
    (v == net.source).then_some((path, marginal))
}

/// Sends one unit along `path`, the augmentation numbered `units`.
fn augment(path: &[Step], used: &mut [bool], first_used_at: &mut [usize], units: usize) {
    for &step in path {
        match step {
            Step::Forward(e) => {
                used[e] = true;
                if first_used_at[e] == usize::MAX {
                    first_used_at[e] = units;
                }
            }
            Step::Backward(e) => used[e] = false,
            Step::None => {}
        }
    }
}

/// Next path: Dijkstra on reduced costs c + pot[u] - pot[v] >= 0, leaving the tree in
/// `search`; the sink's distance (infinite if unreached), or `None` once `work` passes
/// `budget`.
fn next_path(
    net: &Net,
    used: &[bool],
    pot: &[f64],
    search: &mut Search,
    work: &mut u64,
    budget: u64,
) -> Option<f64> {
    let (g, source, sink) = (net.g, net.source, net.sink);
    let Search { dist, pred, heap } = search;
    dist.iter_mut().for_each(|d| *d = f64::INFINITY);
    pred.iter_mut().for_each(|p| *p = Step::None);
    dist[source] = 0.0;
    heap.clear();
    heap.push(Reverse((Dist(0.0), source)));
    let mut reached_sink = f64::INFINITY;
    while let Some(Reverse((Dist(d), u))) = heap.pop() {
        if d > dist[u] {
            continue;
        }
        *work += (net.out_edges.of(u).len() + net.in_edges.of(u).len()) as u64;
        if *work > budget {
            return None;
        }
        if u == sink {
            // The sink's path is final; nothing popped later can change it.
            reached_sink = d;
            break;
        }
        let mut relax = |v: usize, cost: f64, step: Step, heap: &mut BinaryHeap<_>| {
            if !pot[v].is_finite() {
                return;
            }
            let nd = d + (cost + pot[u] - pot[v]).max(0.0);
            if nd < dist[v] {
                dist[v] = nd;
                pred[v] = step;
                heap.push(Reverse((Dist(nd), v)));
            }
        };
        for &e in net.out_edges.of(u) {
            if !used[e] {
                relax(g.edges[e].to, g.edges[e].cost, Step::Forward(e), heap);
            }
        }
        for &e in net.in_edges.of(u) {
            if used[e] {
                relax(g.edges[e].from, -g.edges[e].cost, Step::Backward(e), heap);
            }
        }
    }
    Some(reached_sink)
}

/// Splits the flow into paths, walking back from each used sink edge; with each path,
/// the augmentation that first used its sink edge.
fn decompose(
    g: &FlowGraph,
    in_edges: &Adjacency,
    source: usize,
    sink: usize,
    used: &[bool],
    first_used_at: &[usize],
) -> (Vec<Vec<usize>>, Vec<usize>) {
    let mut ends: Vec<usize> = in_edges
        .of(sink)
        .iter()
        .copied()
        .filter(|&e| used[e])
        .collect();
    ends.sort_by_key(|&e| (first_used_at[e], e));
    let mut taken = vec![false; g.edges.len()];
    let mut paths = Vec::with_capacity(ends.len());
    let found_at = ends.iter().map(|&e| first_used_at[e]).collect();
    for end in ends {
        let mut path = vec![end];
        taken[end] = true;
        let mut v = g.edges[end].from;
        while v != source {
            let next = in_edges
                .of(v)
                .iter()
                .copied()
                .find(|&e| used[e] && !taken[e]);
            match next {
                Some(e) => {
                    taken[e] = true;
                    path.push(e);
                    v = g.edges[e].from;
                }
                // Conservation guarantees an unused unit in; stop rather than loop.
                None => break,
            }
        }
        path.reverse();
        paths.push(path);
    }
    (paths, found_at)
}

mod parts;

#[cfg(test)]
mod oracle;

pub use parts::min_cost_flow_by_parts;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_disjoint_negative_paths() {
        let mut g = FlowGraph::new(4);
        g.add_edge(0, 1, -2.0).unwrap();
        g.add_edge(0, 2, -1.0).unwrap();
        g.add_edge(1, 3, 0.5).unwrap();
        g.add_edge(2, 3, 0.5).unwrap();
        let s = min_cost_flow(&g, 0, 3, 10).unwrap();
        assert_eq!(s.units, 2);
        assert_eq!(s.total_cost, -2.0);
        assert_eq!(s.paths, vec![vec![0, 2], vec![1, 3]]);
    }

    #[test]
    fn rerouting_through_a_back_edge() {
        // The cheapest single path 0-1-2-3 blocks two paths 0-1-3 and 0-2-3 that are
        // better together; the second augmentation must cancel edge 1->2.
        let mut g = FlowGraph::new(4);
        g.add_edge(0, 1, -1.0).unwrap();
        g.add_edge(1, 2, -5.0).unwrap();
        g.add_edge(2, 3, -1.0).unwrap();
        g.add_edge(0, 2, -4.0).unwrap();
        g.add_edge(1, 3, -4.0).unwrap();
        let s = min_cost_flow(&g, 0, 3, 10).unwrap();
        assert_eq!(s.units, 2);
        assert_eq!(s.total_cost, -10.0);
        assert!(!s.used[1]);
    }

    #[test]
    fn a_limited_graph_refuses_the_edge_past_its_limit() {
        let mut g = FlowGraph::with_edge_limit(4, 2);
        g.add_edge(0, 1, -1.0).unwrap();
        g.add_edge(1, 3, -1.0).unwrap();
        assert_eq!(
            g.add_edge(0, 2, 0.0),
            Err(FlowError::TooManyEdges { limit: 2 })
        );
        assert_eq!(g.edges().len(), 2);
        assert_eq!(min_cost_flow(&g, 0, 3, 5).unwrap().units, 1);
    }

    #[test]
    fn rejects_backward_edges() {
        let mut g = FlowGraph::new(3);
        assert!(matches!(
            g.add_edge(2, 1, 0.0),
            Err(FlowError::NotForward { .. })
        ));
        assert!(matches!(
            g.add_edge(0, 3, 0.0),
            Err(FlowError::NodeOutOfRange { .. })
        ));
        assert!(matches!(
            g.add_edge(0, 1, f64::NAN),
            Err(FlowError::NonFiniteCost { .. })
        ));
    }
}
