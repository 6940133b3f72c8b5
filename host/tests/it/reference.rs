//! The published Python reference's outputs on its two synthetic recordings.

use crate::common;
use touchc_model::trajectory::Columns;

use touchc_input::recording::Recording;
use touchc_pipeline::track::track;
use touchc_tracking::detect::detect;

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}

fn check(name: &str) {
    let dir = common::reference_dir();
    let rec = Recording::load(dir.join(format!("{name}.npy"))).unwrap();
    let reference = common::Reference::load(name);
    let out = track(
        &rec,
        &touchc_model::config::ValidConfig::preset(touchc_model::config::Preset::Paper),
    )
    .unwrap();
    // The pipeline finds maxima during the blur; the standalone stage must agree.
    assert_eq!(
        detect(
            &out.blurred,
            &touchc_model::config::ValidConfig::preset(touchc_model::config::Preset::Paper).detect
        ),
        out.detections
    );

    let (mean, std) = (reference.whole_mean, reference.whole_std);
    assert!(
        rel(out.mean(), mean) < 1e-9,
        "mean {} vs {mean}",
        out.mean()
    );
    assert!(rel(out.std(), std) < 1e-9, "std {} vs {std}", out.std());

    let expected = &reference.trajectories;
    assert_eq!(out.trajectories.len(), expected.len(), "trajectory count");
    // Same order as the reference (the solver's augmentation order), not just same set.
    for (i, (trajectory, want)) in out.trajectories.iter().zip(expected).enumerate() {
        let got = Columns::from(trajectory);
        assert_eq!(got.frames, want.times, "trajectory {i} frames");
        assert_eq!(got.rows, want.rows, "trajectory {i} rows");
        assert_eq!(got.cols, want.cols, "trajectory {i} cols");
        for (j, (g, w)) in got.costs.iter().zip(&want.costs).enumerate() {
            assert!(
                rel(*g, *w) < 1e-9,
                "trajectory {i} detection {j}: cost {g} vs {w}"
            );
        }
        let total = want.total_cost;
        assert!(
            rel(trajectory.total_cost(), total) < 1e-9,
            "trajectory {i} total {} vs {total}",
            trajectory.total_cost()
        );
        // The rendered pressure is the blurred frame at the detection.
        for (j, &f) in got.frames.iter().enumerate() {
            assert_eq!(got.values[j], out.frames()[[f, got.rows[j], got.cols[j]]]);
        }
    }
}

#[test]
fn stroke_60_matches_reference() {
    check("stroke_60");
}

#[test]
fn tap_pat_200_matches_reference() {
    check("tap_pat_200");
}
