//! Every knob at its extremes (issue 6): each either compiles to a finite stimulus or
//! refuses with an error that names the parameter. And the presets compile.

use crate::common;

use touchc_input::recording::Recording;
use touchc_model::config::grid_size;
use touchc_model::config::{CoarseToFine, Config, ConfigError, DerivedLimit, Knob, Preset};
use touchc_pipeline::compile::{compile, CompileError, CompileOptions, Compiled};

/// 100 frames, one contact sliding along the arm: short enough for debug builds.
fn recording() -> Recording {
    Recording::from_array("knobs", common::moving_blobs(100, 1, 5).view()).unwrap()
}

/// Compiles the recording under `cfg`, which is validated first (a knob out of range
/// stops the compile as it stops the command line's layers).
fn run(cfg: Config) -> Result<Compiled, CompileError> {
    compile(
        &recording(),
        &CompileOptions {
            config: cfg.validated()?,
            ..CompileOptions::default()
        },
    )
}

/// The knob out of range that stopped a compile.
fn config_error(err: &CompileError) -> &ConfigError {
    match err {
        CompileError::Config(e) => e,
        other => panic!("not a knob out of range: {other}"),
    }
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
    let mut c = touchc_model::config::Config::preset(touchc_model::config::Preset::Paper);
    f(&mut c);
    c
}

#[test]
fn upsample_1_and_15() {
    for k in [1, 15] {
        // Blur and gate are in mm, so they keep their size: the same touch, tracked as
        // the same one contact.
        let c = run(
            touchc_model::config::Config::preset(touchc_model::config::Preset::Paper).upsampled(k),
        )
        .unwrap();
        assert_finite(&format!("upsample {k}"), &c);
        assert_eq!(c.report.trajectories, 1, "upsample {k}");
    }
    let err = run(with(|c| c.preprocess.upsample = 0)).unwrap_err();
    assert!(
        matches!(
            config_error(&err),
            ConfigError::CountOutOfRange {
                knob: Knob::PreprocessUpsample,
                value: 0,
                ..
            }
        ),
        "{err}"
    );
    let err = run(with(|c| c.preprocess.upsample = 1000)).unwrap_err();
    assert!(
        matches!(
            config_error(&err),
            ConfigError::CountOutOfRange {
                min: 1,
                max: 32,
                ..
            }
        ),
        "{err}"
    );
}

#[test]
fn blur_sigma_half_and_ten() {
    // Half the paper's sigma (the narrowest kernel that still reaches half an upsampled
    // cell at x7) and ten pixels, in mm.
    let px = 25.4 / 7.0;
    for s in [1.5 * px, 10.0 * px] {
        let c = run(with(|c| c.preprocess.blur_sigma_mm = s)).unwrap();
        assert_finite(&format!("sigma {s} mm"), &c);
        assert!(c.report.trajectories >= 1, "sigma {s} mm");
    }
    let err = run(with(|c| c.preprocess.blur_sigma_mm = -1.0)).unwrap_err();
    assert!(
        matches!(
            config_error(&err),
            ConfigError::OutOfRange {
                knob: Knob::PreprocessBlurSigmaMm,
                value: -1.0,
                ..
            }
        ),
        "{err}"
    );
    // Half a pixel: the cells' flat tops survive the blur.
    let err = run(with(|c| c.preprocess.blur_sigma_mm = 0.5 * px)).unwrap_err();
    assert!(
        matches!(
            config_error(&err),
            ConfigError::Derived {
                knob: Knob::PreprocessBlurSigmaMm,
                limit: DerivedLimit::KernelTooNarrow { .. },
                ..
            }
        ),
        "{err}"
    );
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
    assert!(
        matches!(
            config_error(&err),
            ConfigError::OutOfRange {
                knob: Knob::TrackEntryCost,
                value,
                ..
            } if value.is_nan()
        ),
        "{err}"
    );
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
    let paper = run(touchc_model::config::Config::preset(
        touchc_model::config::Preset::Paper,
    ))
    .unwrap();
    let c = run(big).unwrap();
    assert_finite("grid 99,000", &c);
    assert_eq!(c.report.transforms, 99_000);
    // A finer grid finds a placement at least about as good.
    assert!(c.report.score <= paper.report.score * 0.99);

    let err = run(with(|c| c.placement.grid_x = usize::MAX)).unwrap_err();
    assert!(
        matches!(
            config_error(&err),
            ConfigError::CountOutOfRange {
                knob: Knob::PlacementGridX,
                ..
            }
        ),
        "{err}"
    );
    let err = run(with(|c| {
        c.placement.coarse_to_fine = Some(CoarseToFine { stride: 0, keep: 1 })
    }))
    .unwrap_err();
    assert!(
        matches!(
            config_error(&err),
            ConfigError::CountOutOfRange {
                knob: Knob::PlacementCoarseToFineStride,
                value: 0,
                ..
            }
        ),
        "{err}"
    );
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
