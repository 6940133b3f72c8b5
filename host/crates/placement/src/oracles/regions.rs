//! `place` on region trajectories (several points a frame: the cells of a contact's
//! footprint, revisiting the same pixels frame after frame) against the naive
//! re-statement (`naive.rs`). The scoring of regions sums per distinct pixel and
//! tests each pixel once per transform for all regions; the naive sum runs per point,
//! so scores agree to rounding (1e-12 relative) and the choice exactly.

use super::naive::naive;
use crate::place;
use proptest::prelude::*;
use touchc_model::config::PlacementConfig;
use touchc_model::layout::Layout;
use touchc_model::trajectory::{Point, Trajectory};

const ROWS: usize = 24;
const COLS: usize = 63;
const PITCH: f64 = 25.4 / 3.0;

/// A region: 1 to 6 frames from a start, each a footprint of 1 to 5 distinct pixels
/// (row-major) near a centre that wanders a few pixels a frame.
fn region() -> impl Strategy<Value = Trajectory> {
    let frame = (
        (-2i32..=2, -3i32..=3),
        prop::collection::btree_set((0i32..3, 0i32..3), 1..=5),
        prop::collection::vec(prop::sample::select(vec![-0.5, -1.0, -2.0, -0.75]), 5),
    );
    (
        0usize..5,
        4usize..18,
        8usize..50,
        prop::collection::vec(frame, 1..=6),
    )
        .prop_map(|(start, r0, c0, frames)| {
            let (mut r, mut c) = (r0 as i32, c0 as i32);
            let mut points = Vec::new();
            for (f, ((dr, dc), cells, costs)) in frames.into_iter().enumerate() {
                r = (r + dr).clamp(0, ROWS as i32 - 3);
                c = (c + dc).clamp(0, COLS as i32 - 3);
                // The set is ordered by (row, col): the footprint is row-major.
                for ((rr, cc), cost) in cells.into_iter().zip(costs) {
                    points.push(Point {
                        frame: start + f,
                        row: (r + rr) as usize,
                        col: (c + cc) as usize,
                        cost,
                        value: 0.0,
                    });
                }
            }
            Trajectory { points }
        })
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * (1.0 + a.abs().max(b.abs()))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn regions_are_placed_as_the_naive_search_places_them(
        trajs in prop::collection::vec(region(), 1..=6)
    ) {
        let (layout, cfg) = (Layout::paper(), PlacementConfig::default());
        let p = place(&trajs, ROWS, COLS, PITCH, &layout, &cfg).unwrap();
        let expected = naive(&trajs, (ROWS, COLS, PITCH), &layout, &cfg);
        prop_assert_eq!(p.scores.len(), expected.len());
        for (k, (ours, (theirs, _))) in p.scores.iter().zip(&expected).enumerate() {
            prop_assert!(close(*ours, *theirs), "transform {}: {} vs {}", k, ours, theirs);
        }
        let best = expected.iter().map(|e| e.0).fold(f64::INFINITY, f64::min);
        prop_assert!(close(expected[p.index].0, best));
        prop_assert_eq!(&p.selected, &expected[p.index].1);
    }
}
