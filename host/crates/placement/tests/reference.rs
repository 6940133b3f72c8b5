//! Placement against the published Python code's outputs on the two reference inputs
//! (`tests/data/reference/*.reference.json`): every one of the
//! 4,200 transform scores, the chosen transform and the selected trajectories.

use touchc_testkit as common;

use common::Reference;
use touchc_model::config::{CoarseToFine, Config, Preset};
use touchc_model::layout::Layout;
use touchc_placement::place;

fn check(name: &str) {
    let r = Reference::load(name);
    let cfg = touchc_model::config::Config::preset(touchc_model::config::Preset::Paper);
    let k = cfg.preprocess.upsample;
    let trajs = r.trajectories();
    for (t, rt) in trajs.iter().zip(&r.trajectories) {
        // The objective's weights are the published `total_cost`, to the last bit.
        assert_eq!(t.total_cost(), rt.total_cost);
    }
    let (rows, cols) = (r.tared_shape[1] * k, r.tared_shape[2] * k);
    let p = place(
        &trajs,
        rows,
        cols,
        cfg.input.pitch_mm / k as f64,
        &Layout::paper(),
        &cfg.placement,
    )
    .unwrap();

    assert_eq!(p.scores.len(), r.n_transforms);
    let mut nonzero = 0;
    for (i, (&ours, &theirs)) in p.scores.iter().zip(&r.transform_scores).enumerate() {
        if theirs == 0.0 {
            assert_eq!(ours, 0.0, "{name}: transform {i}");
        } else {
            nonzero += 1;
            let rel = ((ours - theirs) / theirs).abs();
            assert!(
                rel <= 1e-9,
                "{name}: transform {i}: {ours} vs {theirs} (rel {rel:e})"
            );
        }
    }
    assert!(p.transforms_evaluated >= nonzero);
    assert!(
        p.transforms_evaluated < r.n_transforms,
        "nothing was skipped"
    );

    assert_eq!(p.index, r.best_transform_index, "{name}");
    let t = p.transform;
    assert_eq!(
        [t.x_mm, t.y_mm, t.scale, t.rotation, t.split_mm],
        r.best_transform,
        "{name}"
    );
    assert!(
        ((p.score - r.best_score) / r.best_score).abs() <= 1e-9,
        "{name}: {}",
        p.score
    );
    assert_eq!(p.selected, r.selected_trajectories, "{name}");
    // The circles are the layout moved by the transform, split applied to row 1 only.
    for (ch, c) in p.circles.iter().enumerate() {
        let (row, col) = ((ch / 4) as f64, (ch % 4) as f64);
        assert_eq!(c.x_mm, 37.0 * col + t.x_mm);
        assert_eq!(c.y_mm, 50.0 * row + (t.y_mm + t.split_mm * row));
    }
}

#[test]
fn stroke_60_matches_the_published_code() {
    check("stroke_60");
}

#[test]
fn tap_pat_200_matches_the_published_code() {
    check("tap_pat_200");
}

/// The `fast` preset's coarse-to-fine search scores a subset of the published grid with
/// the published scores, and on both reference inputs finds the published winner.
#[test]
fn coarse_to_fine_finds_the_published_winner() {
    for name in ["stroke_60", "tap_pat_200"] {
        let r = Reference::load(name);
        let cfg = touchc_model::config::Config::preset(touchc_model::config::Preset::Paper);
        let k = cfg.preprocess.upsample;
        let (rows, cols) = (r.tared_shape[1] * k, r.tared_shape[2] * k);
        let fast = Config::preset(Preset::Fast).placement;
        assert_eq!(
            fast.coarse_to_fine,
            Some(CoarseToFine {
                stride: 2,
                keep: 32
            })
        );
        let p = place(
            &r.trajectories(),
            rows,
            cols,
            cfg.input.pitch_mm / k as f64,
            &Layout::paper(),
            &fast,
        )
        .unwrap();
        assert_eq!(p.index, r.best_transform_index, "{name}");
        assert_eq!(p.selected, r.selected_trajectories, "{name}");
        assert!(p.transforms_evaluated < r.n_transforms / 2, "{name}");
        for (i, (&ours, &theirs)) in p.scores.iter().zip(&r.transform_scores).enumerate() {
            if ours != 0.0 {
                assert!(((ours - theirs) / theirs).abs() <= 1e-9, "{name}: {i}");
            }
        }
    }
}
