//! The published Python reference's outputs on its two synthetic recordings.

use crate::common;
use touchc::trajectory::Columns;

use touchc::input::recording::Recording;
use touchc::track::track;
use touchc::tracking::detect::detect;

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
}

fn check(name: &str) {
    let dir = common::reference_dir();
    let rec = Recording::load(dir.join(format!("{name}.npy"))).unwrap();
    let text = std::fs::read_to_string(dir.join(format!("{name}.reference.json"))).unwrap();
    let reference: serde_json::Value = serde_json::from_str(&text).unwrap();
    let out = track(
        &rec,
        &touchc::config::Config::preset(touchc::config::Preset::Paper),
    )
    .unwrap();
    // The pipeline finds maxima during the blur; the standalone stage must agree.
    assert_eq!(
        detect(
            &out.blurred,
            &touchc::config::Config::preset(touchc::config::Preset::Paper).detect
        ),
        out.detections
    );

    let mean = reference["whole_mean"].as_f64().unwrap();
    let std = reference["whole_std"].as_f64().unwrap();
    assert!(
        rel(out.mean(), mean) < 1e-9,
        "mean {} vs {mean}",
        out.mean()
    );
    assert!(rel(out.std(), std) < 1e-9, "std {} vs {std}", out.std());

    let expected = reference["trajectories"].as_array().unwrap();
    assert_eq!(out.trajectories.len(), expected.len(), "trajectory count");
    // Same order as the reference (the solver's augmentation order), not just same set.
    for (i, (trajectory, want)) in out.trajectories.iter().zip(expected).enumerate() {
        let got = Columns::from(trajectory);
        let ints = |k: &str| -> Vec<usize> {
            want[k]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_u64().unwrap() as usize)
                .collect()
        };
        assert_eq!(got.frames, ints("times"), "trajectory {i} frames");
        assert_eq!(got.rows, ints("rows"), "trajectory {i} rows");
        assert_eq!(got.cols, ints("cols"), "trajectory {i} cols");
        let costs: Vec<f64> = want["costs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        for (j, (g, w)) in got.costs.iter().zip(&costs).enumerate() {
            assert!(
                rel(*g, *w) < 1e-9,
                "trajectory {i} detection {j}: cost {g} vs {w}"
            );
        }
        let total = want["total_cost"].as_f64().unwrap();
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
