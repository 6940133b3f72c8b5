//! The successive-shortest-path solver against brute force on small random DAGs.

use super::{min_cost_flow, min_cost_flow_by_parts, min_cost_flow_within, FlowGraph, FlowSolution};
use proptest::prelude::*;

/// Cheapest feasible unit-capacity flow of value <= max_units, by trying every edge set.
fn brute_force(n: usize, edges: &[(usize, usize, f64)], max_units: usize) -> f64 {
    let mut best = 0.0f64; // the empty flow
    for mask in 0u32..(1 << edges.len()) {
        let mut balance = vec![0i64; n];
        let mut cost = 0.0;
        for (i, &(a, b, c)) in edges.iter().enumerate() {
            if mask & (1 << i) != 0 {
                balance[a] -= 1;
                balance[b] += 1;
                cost += c;
            }
        }
        let inner_ok = balance[1..n - 1].iter().all(|&x| x == 0);
        let value = -balance[0];
        if inner_ok && value >= 0 && value as usize <= max_units && cost < best {
            best = cost;
        }
    }
    best
}

/// The reported flow is feasible, costs what it says, and decomposes into source-to-sink
/// paths that use each used edge exactly once.
fn consistent(
    edges: &[(usize, usize, f64)],
    sol: &FlowSolution,
    n: usize,
) -> Result<(), TestCaseError> {
    let used_cost: f64 = edges
        .iter()
        .zip(&sol.used)
        .filter(|(_, &u)| u)
        .map(|(e, _)| e.2)
        .sum();
    prop_assert!((used_cost - sol.total_cost).abs() < 1e-9);
    prop_assert_eq!(sol.paths.len(), sol.units);
    let mut covered = vec![false; edges.len()];
    for path in &sol.paths {
        prop_assert_eq!(edges[path[0]].0, 0);
        prop_assert_eq!(edges[path[path.len() - 1]].1, n - 1);
        for w in path.windows(2) {
            prop_assert_eq!(edges[w[0]].1, edges[w[1]].0);
        }
        for &e in path {
            prop_assert!(sol.used[e] && !covered[e]);
            covered[e] = true;
        }
    }
    prop_assert_eq!(covered, sol.used.clone());
    Ok(())
}

/// The graph of `n` nodes with `edges` as `(from, to, cost)`.
fn graph(n: usize, edges: &[(usize, usize, f64)]) -> FlowGraph {
    let mut g = FlowGraph::new(n);
    for &(a, b, c) in edges {
        g.add_edge(a, b, c).unwrap();
    }
    g
}

fn graph_strategy() -> impl Strategy<Value = (usize, Vec<(usize, usize, f64)>, usize)> {
    (4usize..8).prop_flat_map(|n| {
        let edge = (0..n - 1).prop_flat_map(move |a| {
            // Half-integer costs make exact ties between alternatives common; the
            // negative skew makes several units worth sending, so later paths must
            // reroute earlier ones through residual back edges.
            (Just(a), a + 1..n, (-12i32..5).prop_map(|c| c as f64 * 0.5))
        });
        (Just(n), prop::collection::vec(edge, 4..14), 1usize..5)
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(600))]
    #[test]
    fn optimal_and_consistent((n, edges, max_units) in graph_strategy()) {
        let g = graph(n, &edges);
        let sol = min_cost_flow(&g, 0, n - 1, max_units).unwrap();
        let best = brute_force(n, &edges, max_units);
        prop_assert!((sol.total_cost - best).abs() < 1e-9, "solver {} vs brute {}", sol.total_cost, best);
        prop_assert!(sol.units <= max_units);

        consistent(&edges, &sol, n)?;
    }
}

/// Several small DAGs side by side between one source and one sink: the parts that
/// `min_cost_flow_by_parts` solves one by one.
fn parts_strategy() -> impl Strategy<Value = (usize, Vec<(usize, usize, f64)>, usize)> {
    (
        prop::collection::vec(
            (2usize..6, prop::collection::vec(any::<u32>(), 2..10)),
            1..5,
        ),
        1usize..7,
    )
        .prop_map(|(parts, max_units)| {
            // Inner nodes 1..=total; each part owns a consecutive block, interleaved
            // edge by edge so the parts' edges are mixed in insertion order.
            let total: usize = parts.iter().map(|p| p.0).sum();
            let sink = total + 1;
            let mut blocks = Vec::new();
            let mut first = 1;
            for (size, picks) in &parts {
                let mut edges = Vec::new();
                for (i, &r) in picks.iter().enumerate() {
                    let a = (r as usize) % (size + 1); // 0 = the source
                    let b = a + 1 + (r as usize / 7) % (size + 1 - a); // size + 1 = the sink
                    let cost = ((r % 17) as f64 - 11.0) * 0.5 + i as f64 * 1e-3;
                    let node = |v: usize| match v {
                        0 => 0,
                        v if v > *size => sink,
                        v => first + v - 1,
                    };
                    edges.push((node(a), node(b), cost));
                }
                blocks.push(edges);
                first += size;
            }
            let longest = blocks.iter().map(Vec::len).max().unwrap_or(0);
            let mut edges = Vec::new();
            for i in 0..longest {
                edges.extend(blocks.iter().filter_map(|b| b.get(i).copied()));
            }
            (sink + 1, edges, max_units)
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(600))]
    #[test]
    fn solving_by_parts_is_solving_the_whole((n, edges, max_units) in parts_strategy()) {
        let g = graph(n, &edges);
        let whole = min_cost_flow(&g, 0, n - 1, max_units).unwrap();
        let parts = min_cost_flow_by_parts(&g, 0, n - 1, max_units, u64::MAX).unwrap();
        prop_assert!((whole.total_cost - parts.total_cost).abs() < 1e-9,
            "whole {} vs parts {}", whole.total_cost, parts.total_cost);
        prop_assert_eq!(whole.units, parts.units);
        consistent(&edges, &parts, n)?;
        // Paths come in the order one solver finds them: by the cost of their augmentation.
        prop_assert!(parts.found_at.iter().map(|&a| parts.marginals[a]).collect::<Vec<_>>()
            .windows(2).all(|w| w[0] <= w[1]));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]
    /// Out of budget, one graph's flow is still the min-cost flow of the units it found;
    /// within budget it is the optimum.
    #[test]
    fn a_budget_stops_at_a_min_cost_flow_of_fewer_units(
        (n, edges, max_units) in graph_strategy(),
        budget in 0u64..120,
    ) {
        let g = graph(n, &edges);
        let whole = min_cost_flow(&g, 0, n - 1, max_units).unwrap();
        let bounded = min_cost_flow_within(&g, 0, n - 1, max_units, budget).unwrap();
        consistent(&edges, &bounded, n)?;
        prop_assert!(bounded.units <= whole.units);
        let same_units = min_cost_flow(&g, 0, n - 1, bounded.units).unwrap();
        prop_assert!((bounded.total_cost - same_units.total_cost).abs() < 1e-9);
        if !bounded.budget_reached {
            prop_assert_eq!(bounded.units, whole.units);
            prop_assert!((bounded.total_cost - whole.total_cost).abs() < 1e-9);
        } else {
            prop_assert!(bounded.work > budget);
        }
    }

    /// By parts with a budget: a valid flow, never more units than the optimum, and the
    /// optimum itself when the budget was not reached.
    #[test]
    fn parts_share_one_budget((n, edges, max_units) in parts_strategy(), budget in 0u64..200) {
        let g = graph(n, &edges);
        let whole = min_cost_flow(&g, 0, n - 1, max_units).unwrap();
        let bounded = min_cost_flow_by_parts(&g, 0, n - 1, max_units, budget).unwrap();
        consistent(&edges, &bounded, n)?;
        prop_assert!(bounded.units <= whole.units);
        prop_assert!(bounded.total_cost >= whole.total_cost - 1e-9);
        if !bounded.budget_reached {
            prop_assert_eq!(bounded.units, whole.units);
            prop_assert!((bounded.total_cost - whole.total_cost).abs() < 1e-9);
        }
    }
}
