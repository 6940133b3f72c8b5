//! The subset solver against two independent oracles: exhaustive search (same tie rule,
//! so the subsets must be equal) and an ILP in the published form, solved by `good_lp` +
//! `microlp` (objectives must be equal; ILP ties are arbitrary). Hall matching against
//! Hall's condition checked subset by subset.

use crate::bnb::{has_matching, SubsetProblem};
use good_lp::{microlp, variable, variables, Expression, Solution, SolverModel};
use proptest::prelude::*;

/// Hall's condition by brute force: every subset needs as many workspaces as members.
fn hall(masks: &[u32]) -> bool {
    (1u32..1 << masks.len()).all(|s| {
        let union = (0..masks.len())
            .filter(|&i| s >> i & 1 == 1)
            .fold(0, |u, i| u | masks[i]);
        union.count_ones() >= s.count_ones()
    })
}

#[derive(Debug, Clone)]
struct Instance {
    weights: Vec<f64>,
    conflicts: Vec<(usize, usize)>,
    groups: Vec<Vec<(usize, u32)>>,
}

impl Instance {
    fn problem(&self) -> SubsetProblem {
        let mut p = SubsetProblem::new(self.weights.clone());
        for &(a, b) in &self.conflicts {
            p.add_conflict(a, b);
        }
        for g in &self.groups {
            p.add_hall_group(g.clone());
        }
        p
    }

    /// The published formulation: one constraint per Hall-violating set,
    /// `sum(x in S) <= |S| - 1`, and maximise the summed weight.
    fn ilp_objective(&self) -> f64 {
        let mut vars = variables!();
        let x: Vec<_> = self
            .weights
            .iter()
            .map(|_| vars.add(variable().binary()))
            .collect();
        let objective: Expression = x.iter().zip(&self.weights).map(|(&v, &w)| w * v).sum();
        let mut model = vars.maximise(objective).using(microlp);
        for &(a, b) in &self.conflicts {
            if a != b {
                model = model.with((x[a] + x[b]).leq(1));
            }
        }
        for g in &self.groups {
            for s in 1u32..1 << g.len() {
                let members: Vec<usize> = (0..g.len()).filter(|&i| s >> i & 1 == 1).collect();
                let masks: Vec<u32> = members.iter().map(|&i| g[i].1).collect();
                if !hall(&masks) {
                    let sum: Expression = members.iter().map(|&i| x[g[i].0]).sum();
                    model = model.with(sum.leq(members.len() as f64 - 1.0));
                }
            }
        }
        let solution = model.solve().unwrap();
        x.iter()
            .zip(&self.weights)
            .filter(|(&v, _)| solution.value(v) > 0.5)
            .map(|(_, &w)| w)
            .sum()
    }
}

/// Random instances; integer weights make exact ties common, to exercise the tie rule.
fn instance(max_n: usize, integer_weights: bool) -> impl Strategy<Value = Instance> {
    (1..=max_n).prop_flat_map(move |n| {
        let weights = if integer_weights {
            prop::collection::vec((-2i32..=6).prop_map(f64::from), n).boxed()
        } else {
            prop::collection::vec(-1.0f64..5.0, n).boxed()
        };
        let conflicts = prop::collection::vec((0..n, 0..n), 0..=2 * n);
        let groups = prop::collection::vec(prop::collection::vec((0..n, 1u32..8), 3..=5), 0..3);
        (weights, conflicts, groups).prop_map(|(weights, conflicts, groups)| {
            let groups = groups
                .into_iter()
                .map(|mut g| {
                    // One entry per vertex: a trajectory is in a frame once.
                    g.sort_by_key(|m| m.0);
                    g.dedup_by_key(|m| m.0);
                    g
                })
                .collect();
            Instance {
                weights,
                conflicts,
                groups,
            }
        })
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn matching_agrees_with_halls_condition(masks in prop::collection::vec(0u32..32, 0..=7)) {
        prop_assert_eq!(has_matching(&masks), hall(&masks));
    }

    #[test]
    fn branch_and_bound_equals_brute_force_with_ties(inst in instance(10, true)) {
        let p = inst.problem();
        let ours = p.solve();
        prop_assert!(p.is_feasible(&ours));
        prop_assert_eq!(ours, p.solve_brute_force());
    }

    #[test]
    fn branch_and_bound_equals_brute_force_real_weights(inst in instance(12, false)) {
        let p = inst.problem();
        prop_assert_eq!(p.solve(), p.solve_brute_force());
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(60))]

    #[test]
    fn branch_and_bound_matches_the_ilp_oracle(inst in instance(24, false)) {
        let p = inst.problem();
        let ours = p.solve();
        prop_assert!(p.is_feasible(&ours));
        let ilp = inst.ilp_objective();
        let value = p.objective(&ours);
        prop_assert!((value - ilp).abs() <= 1e-6 * (1.0 + ilp.abs()), "{} vs ILP {}", value, ilp);
    }
}
