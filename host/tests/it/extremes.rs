//! Stages 0-3 on degenerate and extreme recordings.

use crate::common;

use ndarray::{s, Array3};
use touchc_input::recording::{Recording, RecordingError};
use touchc_model::config::Config;
use touchc_model::trajectory::Columns;
use touchc_pipeline::compile::CompileError;
use touchc_pipeline::track::track;
use touchc_tracking::track::TrackOutput;

fn run_cfg(a: &Array3<f64>, cfg: &Config) -> TrackOutput {
    let cfg = cfg.clone().validated().unwrap();
    track(&Recording::from_array("synthetic", a.view()).unwrap(), &cfg).unwrap()
}

fn run(a: &Array3<f64>) -> TrackOutput {
    run_cfg(
        a,
        &touchc_model::config::Config::preset(touchc_model::config::Preset::Paper),
    )
}

fn assert_costs_finite(out: &TrackOutput) {
    assert!(out.mean().is_finite() && out.std().is_finite());
    for d in &out.detections.all {
        assert!(d.cost.is_finite(), "{d:?}");
    }
}

#[test]
fn constant_and_all_zero_recordings_have_no_detections() {
    for v in [0.0, 3.5] {
        let out = run(&Array3::from_elem((60, 8, 21), v));
        assert_eq!(out.std(), 0.0);
        assert!(out.detections.all.is_empty() && out.trajectories.is_empty());
    }
}

#[test]
fn a_million_psi_spike_keeps_costs_finite() {
    // A 1e6 psi poke held for six frames (file frames 50-55 = frames 30-35 after trim).
    let mut a = common::moving_blobs(100, 1, 11);
    a.slice_mut(s![50..56, 3, 15]).fill(1e6);
    let out = run(&a);
    assert_costs_finite(&out);
    let saturated = (0.02f64 / 0.98).ln();
    let spike = out
        .detections
        .in_frame(30)
        .iter()
        .max_by(|p, q| p.value.total_cmp(&q.value))
        .unwrap();
    assert!(spike.value > 1e4 && (spike.cost - saturated).abs() < 1e-12);
    let t = out
        .trajectories
        .iter()
        .find(|t| t.at_frame(30).is_some())
        .unwrap();
    assert_eq!(Columns::from(t).frames, (30..36).collect::<Vec<_>>());
}

#[test]
fn scaling_by_1e30_and_1e_minus_30() {
    let a = common::moving_blobs(100, 2, 13);
    let base = run(&a);
    assert!(!base.trajectories.is_empty());

    let big = run(&a.mapv(|v| v * 1e30));
    assert!((big.mean() / (base.mean() * 1e30) - 1.0).abs() < 1e-12);
    assert!((big.std() / (base.std() * 1e30) - 1.0).abs() < 1e-12);
    assert_costs_finite(&big);
    // With the psi threshold scaled too, the problem is the same one.
    let mut cfg = touchc_model::config::Config::preset(touchc_model::config::Preset::Paper);
    cfg.detect.min_value_psi *= 1e30;
    let big_same = run_cfg(&a.mapv(|v| v * 1e30), &cfg);
    assert_eq!(big_same.trajectories.len(), base.trajectories.len());
    for (x, y) in big_same.trajectories.iter().zip(&base.trajectories) {
        let (x, y) = (Columns::from(x), Columns::from(y));
        assert_eq!((&x.frames, &x.rows, &x.cols), (&y.frames, &y.rows, &y.cols));
        for (p, q) in x.costs.iter().zip(&y.costs) {
            assert!((p - q).abs() <= 1e-9 * q.abs());
        }
    }

    // 1e-30 psi is far below the 1e-5 psi detection floor: statistics, but no contacts.
    let tiny = run(&a.mapv(|v| v * 1e-30));
    assert!((tiny.std() / (base.std() * 1e-30) - 1.0).abs() < 1e-12);
    assert!(tiny.detections.all.is_empty() && tiny.trajectories.is_empty());
}

#[test]
fn negative_dips_after_tare_are_never_detections() {
    // The sleeve rests loaded during the tare, then is released: everything dips below 0.
    let mut a = common::moving_blobs(100, 1, 17);
    a.slice_mut(s![..20, .., ..]).mapv_inplace(|v| v + 0.5);
    let out = run(&a);
    assert_costs_finite(&out);
    assert!(out.frames().iter().any(|&v| v < -0.1));
    assert!(out.detections.all.iter().all(|d| d.value > 1e-5));
    // The blob rises above the (negative) floor only where it is stronger than the dip.
    let only_dip = {
        let mut d = Array3::from_elem((60, 8, 21), 0.0);
        d.slice_mut(s![..20, .., ..]).fill(0.5);
        d
    };
    let out = run(&only_dip);
    assert!(out.detections.all.is_empty() && out.trajectories.is_empty());
}

#[test]
fn nan_cells_and_a_whole_nan_frame() {
    let mut a = common::moving_blobs(120, 1, 19);
    a.slice_mut(s![60, .., ..]).fill(f64::NAN);
    let out = run(&a);
    assert_costs_finite(&out);
    // File frame 60 is frame 40 after the trim: all zero, so no detection there.
    assert!(out.frames().slice(s![40, .., ..]).iter().all(|&v| v == 0.0));
    assert!(out.detections.in_frame(40).is_empty());
    assert!(out.trajectories.iter().all(|t| t.at_frame(40).is_none()));
    assert!(!out.trajectories.is_empty());
}

#[test]
fn infinities_are_errors() {
    let mut a = common::moving_blobs(60, 1, 23);
    a[[40, 2, 20]] = f64::NEG_INFINITY;
    let err = Recording::from_array("dip.npy", a.view()).unwrap_err();
    assert!(matches!(
        err,
        RecordingError::Infinite {
            frame: 40,
            row: 2,
            col: 20,
            ..
        }
    ));
    assert!(err.to_string().contains("dip.npy"));
}

#[test]
fn shorter_than_the_tare_buffer_is_an_error() {
    let a = common::moving_blobs(30, 1, 29);
    let rec = Recording::from_array("short", a.view()).unwrap();
    let err = track(
        &rec,
        &touchc_model::config::ValidConfig::preset(touchc_model::config::Preset::Paper),
    )
    .unwrap_err();
    assert!(matches!(
        err,
        CompileError::Recording(RecordingError::TooShort { min: 41, .. })
    ));
}

#[test]
fn seven_thousand_frames() {
    let a = common::moving_blobs(7_000, 6, 31);
    let out = run(&a);
    assert_eq!(out.frames().dim(), (6_960, 56, 147));
    assert_costs_finite(&out);
    assert!(
        out.trajectories.len() > 50,
        "{} trajectories",
        out.trajectories.len()
    );
    for t in &out.trajectories {
        assert!(t.points.windows(2).all(|w| w[1].frame == w[0].frame + 1));
    }
}
