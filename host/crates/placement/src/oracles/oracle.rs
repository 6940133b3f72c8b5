//! `place` against the naive re-statement of the published algorithm (`naive.rs`) on
//! random scenes with crossing trajectories of one point a frame. Scores must agree
//! bit for bit. Costs are small binary fractions
//! so that sums are exact and ties between subsets (common in real data) are exercised.

use super::naive::naive;
use crate::place;
use proptest::prelude::*;
use touchc_model::config::PlacementConfig;
use touchc_model::layout::Layout;
use touchc_model::trajectory::{Columns, Trajectory};

const ROWS: usize = 56;
const COLS: usize = 147;
const PITCH: f64 = 25.4 / 7.0;

fn trajectory() -> impl Strategy<Value = Trajectory> {
    (0usize..6, 1usize..=8, 10usize..40, 30usize..90).prop_flat_map(|(start, len, r0, c0)| {
        let steps = prop::collection::vec((-3i32..=3, -4i32..=4), len);
        let costs =
            prop::collection::vec(prop::sample::select(vec![-0.5, -1.0, -2.0, -4.0, 0.5]), len);
        (steps, costs).prop_map(move |(steps, costs)| {
            let (mut r, mut c) = (r0 as i32, c0 as i32);
            let (mut rows, mut cols) = (Vec::new(), Vec::new());
            for (dr, dc) in steps {
                r = (r + dr).clamp(0, ROWS as i32 - 1);
                c = (c + dc).clamp(0, COLS as i32 - 1);
                rows.push(r as usize);
                cols.push(c as usize);
            }
            Trajectory::try_from(Columns {
                frames: (start..start + len).collect(),
                rows,
                cols,
                costs,
                values: vec![0.0; len],
            })
            .expect("equal lengths")
        })
    })
}

/// The paper's sleeve with radius 26 mm: neighbouring circles overlap, so a point can be
/// in two workspaces and compatibility needs a matching, not just pairwise checks.
fn overlapping_layout() -> Layout {
    let text = Layout::paper()
        .to_toml_string()
        .unwrap()
        .replace("radius_mm = 18.5", "radius_mm = 26.0");
    Layout::from_toml_str(&text, "overlapping").unwrap()
}

fn check(trajs: &[Trajectory], layout: &Layout) -> Result<(), TestCaseError> {
    let cfg = PlacementConfig::default();
    let p = place(trajs, ROWS, COLS, PITCH, layout, &cfg).unwrap();
    let expected = naive(trajs, (ROWS, COLS, PITCH), layout, &cfg);
    for (k, (ours, (theirs, _))) in p.scores.iter().zip(&expected).enumerate() {
        prop_assert_eq!(
            ours.to_bits(),
            theirs.to_bits(),
            "transform {}: {} vs {}",
            k,
            ours,
            theirs
        );
    }
    let mut best = 0;
    for (k, (s, _)) in expected.iter().enumerate() {
        if *s < expected[best].0 {
            best = k;
        }
    }
    prop_assert_eq!(p.index, best);
    prop_assert_eq!(&p.selected, &expected[best].1);
    let hits = expected.iter().filter(|(_, sel)| !sel.is_empty()).count();
    prop_assert!(p.transforms_evaluated >= hits);
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn place_equals_the_naive_search(trajs in prop::collection::vec(trajectory(), 1..=6)) {
        check(&trajs, &Layout::paper())?;
    }

    #[test]
    fn place_equals_the_naive_search_with_overlapping_circles(
        trajs in prop::collection::vec(trajectory(), 1..=6)
    ) {
        check(&trajs, &overlapping_layout())?;
    }
}
