//! Every knob at its extremes (issue 6): each either compiles to a finite stimulus or
//! refuses with an error that names the parameter. And the presets compile.

mod common;

use touchc::compile::{compile, CompileError, CompileOptions, Compiled};
use touchc::config::{CoarseToFine, Config, Preset};
use touchc::placement::grid_size;
use touchc::recording::Recording;

/// 100 frames, one contact sliding along the arm: short enough for debug builds.
fn recording() -> Recording {
    Recording::from_array("knobs", common::moving_blobs(100, 1, 5).view()).unwrap()
}

fn run(cfg: Config) -> Result<Compiled, CompileError> {
    compile(
        &recording(),
        &CompileOptions {
            config: cfg,
            ..CompileOptions::default()
        },
    )
}

fn assert_finite(what: &str, c: &Compiled) {
    assert!(!c.stimulus.is_empty(), "{what}");
    assert!(
        c.signal.iter().flatten().all(|v| v.is_finite()),
        "{what}: signal"
    );
    assert!(
        c.report.score.is_finite() && c.report.score <= 0.0,
        "{what}"
    );
    assert!(c.report.rms_error_fs.is_finite(), "{what}");
}

fn with(f: impl FnOnce(&mut Config)) -> Config {
    let mut c = Config::default();
    f(&mut c);
    c
}

#[test]
fn upsample_1_and_15() {
    for k in [1, 15] {
        // The knob alone (blur and gate stay in pixels, so they change size in mm) ...
        let c = run(with(|c| c.preprocess.upsample = k)).unwrap();
        assert_finite(&format!("upsample {k}"), &c);
        // ... and with them rescaled: the same touch, tracked as the same one contact.
        let c = run(Config::default().resampled(k)).unwrap();
        assert_finite(&format!("resampled {k}"), &c);
        assert_eq!(c.report.trajectories, 1, "resampled {k}");
    }
    let err = run(with(|c| c.preprocess.upsample = 0)).unwrap_err();
    assert!(err.to_string().contains("upsampling factor"), "{err}");
    let err = run(with(|c| c.preprocess.upsample = 1000)).unwrap_err();
    assert!(err.to_string().contains("at most"), "{err}");
}

#[test]
fn blur_sigma_half_and_ten() {
    for s in [0.5, 10.0] {
        let c = run(with(|c| c.preprocess.blur_sigma = s)).unwrap();
        assert_finite(&format!("sigma {s}"), &c);
        assert!(c.report.trajectories >= 1, "sigma {s}");
    }
    let err = run(with(|c| c.preprocess.blur_sigma = -1.0)).unwrap_err();
    assert!(err.to_string().contains("sigma"), "{err}");
}

#[test]
fn entry_cost_tenth_and_hundred() {
    // Cheap entries: every detection may start its own trajectory; dear ones: one long one.
    let cheap = run(with(|c| c.track.entry_cost = 0.1)).unwrap();
    assert_finite("entry 0.1", &cheap);
    let dear = run(with(|c| c.track.entry_cost = 100.0)).unwrap();
    assert_finite("entry 100", &dear);
    assert!(cheap.report.trajectories >= dear.report.trajectories);
    let err = run(with(|c| c.track.entry_cost = f64::NAN)).unwrap_err();
    assert!(err.to_string().contains("tracking config"), "{err}");
}

#[test]
fn grid_of_one_and_of_a_hundred_thousand_transforms() {
    let one = with(|c| (c.placement.grid_x, c.placement.grid_y) = (1, 1));
    assert_eq!(grid_size(&one.placement), Some(1));
    let c = run(one).unwrap();
    assert_finite("grid 1", &c);
    assert_eq!(c.report.transforms, 1);

    let big = with(|c| (c.placement.grid_x, c.placement.grid_y) = (100, 44));
    assert_eq!(grid_size(&big.placement), Some(99_000));
    let paper = run(Config::default()).unwrap();
    let c = run(big).unwrap();
    assert_finite("grid 99,000", &c);
    assert_eq!(c.report.transforms, 99_000);
    // A finer grid finds a placement at least about as good.
    assert!(c.report.score <= paper.report.score * 0.99);

    let err = run(with(|c| c.placement.grid_x = usize::MAX)).unwrap_err();
    assert!(err.to_string().contains("at most 20,000,000"), "{err}");
    let err = run(with(|c| {
        c.placement.coarse_to_fine = Some(CoarseToFine { stride: 0, keep: 1 })
    }))
    .unwrap_err();
    assert!(err.to_string().contains("coarse_to_fine"), "{err}");
}

#[test]
fn every_preset_compiles_and_exact_is_never_worse() {
    let runs: Vec<_> = Preset::ALL
        .iter()
        .map(|&p| (p, run(Config::preset(p)).unwrap()))
        .collect();
    for (p, c) in &runs {
        assert_finite(p.name(), c);
    }
    let score = |want| {
        runs.iter()
            .find(|(p, _)| *p == want)
            .unwrap()
            .1
            .report
            .score
    };
    // Exact's grid holds every published grid point.
    assert!(score(Preset::Exact) <= score(Preset::Paper));
}
