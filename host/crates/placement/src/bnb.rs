//! The trajectory subset of one transform: an exact maximum-weight compatible subset.
//!
//! The paper calls this step convex; it is a 0/1 program. Each trajectory (a vertex) has
//! a weight (`-total_cost` in the published code) and the chosen set must be compatible:
//! at every frame, the chosen trajectories inside workspaces must be matched to distinct
//! workspaces (a perfect matching, Hall's theorem). With disjoint circles that is a
//! pairwise conflict ("never two in one circle at once"), i.e. maximum-weight independent
//! set; where circles overlap a frame is a [`SubsetProblem::add_hall_group`] that is
//! checked by bipartite matching.
//!
//! Solver: depth-first branch-and-bound over a conflict bitset, per connected component.
//! Instances are small (tens of vertices, and components of a few), so an exact search is
//! cheaper than any LP machinery: measured 30x faster than `good_lp` + `microlp` on the
//! published workloads, and it has no tolerance (ECOS_BB, which the authors used, stops
//! at a 0.1 % relative gap). `good_lp` stays as the test oracle.
//!
//! Ties: vertices with weight <= 0 are never chosen (they cannot raise the objective).
//! Among subsets with equal objective (summed in ascending vertex order, in f64), the one
//! whose inclusion vector is lexicographically greatest wins, i.e. the lowest-indexed
//! vertex is kept. This makes the result independent of solver internals.

/// A fixed-width set of vertex indices, one bit each.
#[derive(Debug, Clone, PartialEq, Eq)]
struct BitSet {
    words: Vec<u64>,
}

impl BitSet {
    fn new(n: usize) -> Self {
        Self {
            words: vec![0; n.div_ceil(64)],
        }
    }
    fn insert(&mut self, i: usize) {
        self.words[i / 64] |= 1 << (i % 64);
    }
    fn remove(&mut self, i: usize) {
        self.words[i / 64] &= !(1 << (i % 64));
    }
    fn contains(&self, i: usize) -> bool {
        self.words[i / 64] >> (i % 64) & 1 == 1
    }
    fn intersects(&self, other: &BitSet) -> bool {
        self.words.iter().zip(&other.words).any(|(a, b)| a & b != 0)
    }
}

/// True when every left vertex can be matched to a distinct right vertex (workspace).
///
/// `masks[i]` has bit `a` set when left vertex `i` may use workspace `a`. Kuhn's
/// augmenting paths; at most 32 workspaces, so the matching fits in a small array.
pub(crate) fn has_matching(masks: &[u32]) -> bool {
    if masks.len() > 32 {
        return false;
    }
    let mut owner = [usize::MAX; 32];
    for (i, &mask) in masks.iter().enumerate() {
        let mut seen = 0u32;
        if !augment(i, mask, masks, &mut owner, &mut seen) {
            return false;
        }
    }
    true
}

fn augment(i: usize, mask: u32, masks: &[u32], owner: &mut [usize; 32], seen: &mut u32) -> bool {
    let mut free = mask & !*seen;
    while free != 0 {
        let a = free.trailing_zeros() as usize;
        free &= free - 1;
        *seen |= 1 << a;
        let current = owner[a];
        if current == usize::MAX || augment(current, masks[current], masks, owner, seen) {
            owner[a] = i;
            return true;
        }
    }
    false
}

/// Nodes the subset search of one transform may visit, over all its connected
/// components, before it keeps the best subset found so far: 80 times what the
/// published workloads and the shipped examples need (at most 50 per component).
pub(crate) const NODE_BUDGET: u64 = 1 << 12;

/// Nodes the subset searches of one whole placement may visit: each transform gets an
/// equal share, at most [`NODE_BUDGET`] and at least [`MIN_NODE_BUDGET`]. A dense
/// scene (noise tracked as hundreds of crossing trajectories, found by fuzzing) then
/// costs a bounded time per compile, whatever the grid: 16.8 M nodes on the paper's
/// 4,200 transforms, 61 M on `exact`'s 60,060 (about a second and a few seconds).
pub(crate) const COMPILE_NODE_BUDGET: u64 = 1 << 24;

/// The least share of [`COMPILE_NODE_BUDGET`] a transform gets on a very fine grid.
pub(crate) const MIN_NODE_BUDGET: u64 = 1 << 10;

/// The node budget of each transform's subset search on a grid of `transforms`.
pub(crate) fn transform_budget(transforms: usize) -> u64 {
    let share = COMPILE_NODE_BUDGET / (transforms.max(1) as u64);
    share.clamp(MIN_NODE_BUDGET, NODE_BUDGET)
}

/// What `SubsetProblem::solve_within` found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Solution {
    /// Chosen vertices, ascending.
    pub chosen: Vec<usize>,
    /// True when the search proved `chosen` optimal within its node budget.
    pub exact: bool,
}

/// One instance: vertex weights and the constraints between vertices.
#[derive(Debug, Clone)]
pub struct SubsetProblem {
    weights: Vec<f64>,
    /// Conflicting pairs as added (repeats allowed). A list, not an `n x n` bit matrix:
    /// on a long recording a transform has about a thousand vertices with a few
    /// conflicts each, and the matrix made every transform quadratic in that count.
    conflicts: Vec<(usize, usize)>,
    /// Each group: the vertices present at one frame with their workspace masks.
    groups: Vec<Vec<(usize, u32)>>,
}

impl SubsetProblem {
    /// An instance without constraints; `weights[i]` is what choosing vertex `i` earns.
    pub fn new(weights: Vec<f64>) -> Self {
        Self {
            weights,
            conflicts: Vec::new(),
            groups: Vec::new(),
        }
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.weights.len()
    }

    /// Forbids choosing both `a` and `b` (two trajectories alone in one workspace at once).
    ///
    /// # Panics
    /// If `a` or `b` is not a vertex (a caller bug, not a data condition).
    pub fn add_conflict(&mut self, a: usize, b: usize) {
        if a != b {
            let n = self.len();
            assert!(a < n && b < n, "conflict ({a}, {b}) outside {n} vertices");
            self.conflicts.push((a, b));
        }
    }

    /// Requires that the chosen members of `members` (vertex, workspace mask) always have
    /// a matching into distinct workspaces: the general constraint where circles overlap.
    pub fn add_hall_group(&mut self, members: Vec<(usize, u32)>) {
        if members.len() >= 2 {
            self.groups.push(members);
        }
    }

    /// Summed weight of `chosen`, in the order given (ascending for the canonical value).
    #[cfg(test)]
    pub(crate) fn objective(&self, chosen: &[usize]) -> f64 {
        chosen
            .iter()
            .map(|&i| self.weights[i])
            .fold(0.0, |s, w| s + w)
    }

    /// True when `chosen` violates no conflict and every group has a matching.
    #[cfg(test)]
    pub(crate) fn is_feasible(&self, chosen: &[usize]) -> bool {
        let mut set = BitSet::new(self.len());
        for &i in chosen {
            set.insert(i);
        }
        if self
            .conflicts
            .iter()
            .any(|&(a, b)| set.contains(a) && set.contains(b))
        {
            return false;
        }
        self.groups.iter().all(|g| {
            let masks: Vec<u32> = g
                .iter()
                .filter(|(v, _)| set.contains(*v))
                .map(|&(_, m)| m)
                .collect();
            has_matching(&masks)
        })
    }

    /// The exact optimum, ascending; see the module docs for the tie rule. Unbounded
    /// work: for tests and oracles. The pipeline calls `SubsetProblem::solve_within`.
    #[cfg(test)]
    pub(crate) fn solve(&self) -> Vec<usize> {
        self.solve_within(u64::MAX).chosen
    }

    /// The optimum when the search proves it within `node_budget` nodes over all its
    /// connected components, else the best subset found by then (always feasible), with
    /// [`Solution::exact`] false. The search is exponential in the worst case: a scene of
    /// a hundred trajectories all crossing the same workspaces (noise, found by fuzzing)
    /// took 24 M nodes for one transform, while the published workloads and the shipped
    /// examples never need more than 50.
    pub(crate) fn solve_within(&self, node_budget: u64) -> Solution {
        let n = self.len();
        // Union-find over constraints: independent components are solved separately.
        // Roots are the least vertex of their set, so the partition and its order do not
        // depend on the order constraints were added in.
        let mut parent: Vec<usize> = (0..n).collect();
        fn find(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        fn union(p: &mut [usize], a: usize, b: usize) {
            let (ra, rb) = (find(p, a), find(p, b));
            p[ra.max(rb)] = ra.min(rb);
        }
        let positive = |i: usize| self.weights[i] > 0.0;
        for &(a, b) in &self.conflicts {
            if positive(a) && positive(b) {
                union(&mut parent, a, b);
            }
        }
        for g in &self.groups {
            let mut members = g.iter().map(|&(v, _)| v).filter(|&v| positive(v));
            if let Some(first) = members.next() {
                for v in members {
                    union(&mut parent, first, v);
                }
            }
        }
        // Components in order of their least vertex; `local[v]`: v's place in its own.
        let mut components: Vec<Vec<usize>> = Vec::new();
        let mut slot = vec![usize::MAX; n];
        let mut local = vec![usize::MAX; n];
        for v in (0..n).filter(|&v| positive(v)) {
            let root = find(&mut parent, v);
            if slot[root] == usize::MAX {
                slot[root] = components.len();
                components.push(Vec::new());
            }
            local[v] = components[slot[root]].len();
            components[slot[root]].push(v);
        }
        let comp_of = |parent: &mut [usize], v: usize| slot[find(parent, v)];
        // Each component's conflicts (local indices) and groups, gathered in one pass
        // each rather than one pass per component.
        let mut edges: Vec<Vec<(usize, usize)>> = vec![Vec::new(); components.len()];
        for &(a, b) in &self.conflicts {
            if positive(a) && positive(b) {
                edges[comp_of(&mut parent, a)].push((local[a], local[b]));
            }
        }
        let mut groups: Vec<Vec<usize>> = vec![Vec::new(); components.len()];
        for (g, members) in self.groups.iter().enumerate() {
            if let Some(&(v, _)) = members.iter().find(|&&(v, _)| positive(v)) {
                groups[comp_of(&mut parent, v)].push(g);
            }
        }
        let mut chosen = Vec::new();
        let mut exact = true;
        let mut remaining = node_budget;
        for ((comp, edges), groups) in components.iter().zip(&edges).zip(&groups) {
            if comp.len() == 1 {
                chosen.extend_from_slice(comp);
            } else {
                // Components share the budget: once it is spent, each later one keeps
                // its first (greedy) leaf.
                let mut search = Search::new(self, comp, edges, groups, &local);
                search.budget = remaining;
                let (best, proved, nodes) = search.run();
                remaining = remaining.saturating_sub(nodes);
                chosen.extend(best);
                exact &= proved;
            }
        }
        chosen.sort_unstable();
        Solution { chosen, exact }
    }

    /// Exhaustive search with the same tie rule as [`SubsetProblem::solve`]; exponential,
    /// kept public as the reference that tests and benches compare the solver against.
    #[cfg(test)]
    pub(crate) fn solve_brute_force(&self) -> Vec<usize> {
        let n = self.len();
        assert!(n <= 24, "brute force is for small instances");
        let mut best: Option<(f64, Vec<usize>)> = None;
        // Descending masks with vertex 0 as the most significant bit: the first subset of
        // a given objective met is the lexicographically greatest.
        for code in (0..1u32 << n).rev() {
            let chosen: Vec<usize> = (0..n).filter(|&i| code >> (n - 1 - i) & 1 == 1).collect();
            if chosen.iter().any(|&i| self.weights[i] <= 0.0) || !self.is_feasible(&chosen) {
                continue;
            }
            let value = self.objective(&chosen);
            if best.as_ref().is_none_or(|(b, _)| value > *b) {
                best = Some((value, chosen));
            }
        }
        best.map(|(_, c)| c).unwrap_or_default()
    }
}

/// Branch-and-bound over one connected component, vertices in ascending order.
struct Search<'a> {
    problem: &'a SubsetProblem,
    /// Component vertices, ascending (global indices).
    vertices: &'a [usize],
    /// Conflicts restricted to the component, in local indices.
    conflicts: Vec<BitSet>,
    /// Per local vertex: the groups it belongs to.
    groups_of: Vec<Vec<usize>>,
    chosen: BitSet,
    stack: Vec<usize>,
    /// Nodes visited so far, and how many the search may visit.
    nodes: u64,
    budget: u64,
    best_value: f64,
    best: Vec<usize>,
    found: bool,
    /// Slack for rounding in the bound: a branch is cut only if it cannot win by more.
    slack: f64,
    masks: Vec<u32>,
}

impl<'a> Search<'a> {
    /// The search over `vertices` (one component, ascending), given its conflicts in
    /// local indices, the groups that involve it (ascending) and each vertex's local
    /// index (`local`, indexed by global vertex; `usize::MAX` outside any component).
    fn new(
        problem: &'a SubsetProblem,
        vertices: &'a [usize],
        edges: &[(usize, usize)],
        groups: &[usize],
        local: &[usize],
    ) -> Self {
        let k = vertices.len();
        let mut conflicts = vec![BitSet::new(k); k];
        for &(a, b) in edges {
            conflicts[a].insert(b);
            conflicts[b].insert(a);
        }
        let mut groups_of: Vec<Vec<usize>> = vec![Vec::new(); k];
        for &g in groups {
            for &(v, _) in &problem.groups[g] {
                // Non-positive members have no local index: they are never chosen.
                if let Some(of) = groups_of.get_mut(local[v]) {
                    if !of.contains(&g) {
                        of.push(g);
                    }
                }
            }
        }
        let total: f64 = vertices.iter().map(|&v| problem.weights[v].abs()).sum();
        Self {
            problem,
            vertices,
            conflicts,
            groups_of,
            chosen: BitSet::new(k),
            stack: Vec::with_capacity(k),
            best_value: f64::NEG_INFINITY,
            best: Vec::new(),
            found: false,
            nodes: 0,
            budget: u64::MAX,
            slack: 1e-9 * total.max(1.0),
            masks: Vec::new(),
        }
    }

    /// The best subset found, whether the search proved it optimal (it did not when
    /// the node budget ran out first), and the nodes it visited.
    fn run(mut self) -> (Vec<usize>, bool, u64) {
        self.descend(0, 0.0);
        (self.best, self.nodes <= self.budget, self.nodes)
    }

    fn weight(&self, l: usize) -> f64 {
        self.problem.weights[self.vertices[l]]
    }

    /// Can local vertex `l` join the current set?
    fn admits(&mut self, l: usize) -> bool {
        if self.conflicts[l].intersects(&self.chosen) {
            return false;
        }
        let v = self.vertices[l];
        for &g in &self.groups_of[l] {
            self.masks.clear();
            for &(u, m) in &self.problem.groups[g] {
                let in_set = u == v
                    || self
                        .vertices
                        .binary_search(&u)
                        .is_ok_and(|lu| self.chosen.contains(lu));
                if in_set {
                    self.masks.push(m);
                }
            }
            if !has_matching(&self.masks) {
                return false;
            }
        }
        true
    }

    fn descend(&mut self, depth: usize, value: f64) {
        let k = self.vertices.len();
        self.nodes += 1;
        if depth == k {
            if !self.found || value > self.best_value {
                self.found = true;
                self.best_value = value;
                self.best = self.stack.iter().map(|&l| self.vertices[l]).collect();
            }
            return;
        }
        if self.found && self.nodes > self.budget {
            // Out of budget: keep the incumbent (the first leaf is the greedy subset in
            // vertex order, so there always is one after `k` nodes).
            return;
        }
        if self.found {
            // Optimistic: every later vertex not already excluded by a pairwise conflict.
            let bound = value
                + (depth..k)
                    .filter(|&l| !self.conflicts[l].intersects(&self.chosen))
                    .map(|l| self.weight(l))
                    .sum::<f64>();
            if bound + self.slack < self.best_value {
                return;
            }
        }
        if self.admits(depth) {
            self.chosen.insert(depth);
            self.stack.push(depth);
            self.descend(depth + 1, value + self.weight(depth));
            self.stack.pop();
            self.chosen.remove(depth);
        }
        self.descend(depth + 1, value);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matching_handles_shared_and_private_workspaces() {
        assert!(has_matching(&[]));
        assert!(has_matching(&[0b1]));
        assert!(!has_matching(&[0b1, 0b1]));
        assert!(has_matching(&[0b11, 0b01]));
        assert!(!has_matching(&[0b11, 0b11, 0b11]));
        assert!(has_matching(&[0b011, 0b110, 0b011]));
        assert!(!has_matching(&[0]));
    }

    #[test]
    fn path_graph_prefers_the_heavier_ends() {
        // 0 - 1 - 2 with weights 2, 3, 2: {0, 2} (4) beats {1} (3).
        let mut p = SubsetProblem::new(vec![2.0, 3.0, 2.0]);
        p.add_conflict(0, 1);
        p.add_conflict(1, 2);
        assert_eq!(p.solve(), vec![0, 2]);
    }

    #[test]
    fn ties_keep_the_lowest_index_and_non_positive_weights_are_dropped() {
        let mut p = SubsetProblem::new(vec![1.0, 1.0, 0.0, -1.0]);
        p.add_conflict(0, 1);
        assert_eq!(p.solve(), vec![0]);
        assert_eq!(p.solve_brute_force(), vec![0]);
    }

    #[test]
    fn hall_group_limits_three_trajectories_sharing_two_circles() {
        let mut p = SubsetProblem::new(vec![1.0, 2.0, 3.0]);
        p.add_hall_group(vec![(0, 0b11), (1, 0b11), (2, 0b11)]);
        assert_eq!(p.solve(), vec![1, 2]);
    }

    /// A scene like the fuzzed noise: 90 trajectories of nearly equal weight, each in
    /// conflict with about a tenth of the others, so the bound prunes little.
    fn noisy(n: usize) -> SubsetProblem {
        let mut rng = touchc_test_rng::Xorshift::new(0x2545_f491_4f6c_dd1d);
        let mut next = move || rng.next_u64();
        let mut p = SubsetProblem::new((0..n).map(|i| 100.0 - i as f64 * 0.01).collect());
        for a in 0..n {
            for b in a + 1..n {
                if next() % 10 == 0 {
                    p.add_conflict(a, b);
                }
            }
        }
        p
    }

    #[test]
    fn the_budget_bounds_the_search_and_keeps_a_feasible_subset() {
        let p = noisy(90);
        let bounded = p.solve_within(1 << 10);
        assert!(
            !bounded.exact,
            "a 90-vertex dense scene needs more than 1,024 nodes"
        );
        assert!(p.is_feasible(&bounded.chosen));
        assert!(!bounded.chosen.is_empty());
    }

    #[test]
    fn within_the_budget_the_solution_is_the_exact_one() {
        let mut p = SubsetProblem::new(vec![2.0, 3.0, 2.0, 1.0]);
        p.add_conflict(0, 1);
        p.add_conflict(1, 2);
        let s = p.solve_within(NODE_BUDGET);
        assert!(s.exact);
        assert_eq!(s.chosen, p.solve_brute_force());
    }
}
