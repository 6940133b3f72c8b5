//! The pipeline's errors say each fact once: an error that carries a source leaves its
//! text to the source, so whoever prints the chain (the command line joins it with
//! ": ") says it once, and no printer has to find and cut a repeated text.

use std::error::Error;

use touchc_encoding::keyframes::KeyframeError;
use touchc_model::config::{ConfigError, Knob};
use touchc_pipeline::compile::CompileError;
use touchc_placement::PlacementError;
use touchc_tracking::preprocess::PreprocessError;
use touchc_tracking::track::TrackError;

/// Every cause of `err`'s chain, outermost first, as printed.
fn chain(err: &(dyn Error + 'static)) -> Vec<String> {
    let mut texts = Vec::new();
    let mut cause = Some(err);
    while let Some(e) = cause {
        texts.push(e.to_string());
        cause = e.source();
    }
    texts
}

#[test]
fn no_error_repeats_its_source() {
    let errors: Vec<CompileError> = vec![
        CompileError::Config(ConfigError::CountOutOfRange {
            knob: Knob::PlacementGridX,
            value: 0,
            min: 1,
            max: 77,
        }),
        CompileError::Placement(PlacementError::InvalidConfig {
            field: "grid_x",
            value: "0".into(),
            reason: "must be at least 1",
        }),
        CompileError::Signals(PreprocessError::BadUpsample(0)),
        CompileError::Track(TrackError::Preprocess(PreprocessError::BadUpsample(0))),
        CompileError::Keyframes(KeyframeError::BadSignal),
    ];
    for err in &errors {
        let texts = chain(err);
        assert!(texts.len() >= 2, "{err:?} has no source to say");
        for pair in texts.windows(2) {
            assert!(
                !pair[0].contains(&pair[1]),
                "{err:?}: `{}` repeats its source `{}`",
                pair[0],
                pair[1]
            );
        }
    }
}

#[test]
fn a_tracking_failure_and_a_rendering_failure_read_differently() {
    // Stage 5 recomputes the blurred frames; its failure is not a tracking failure.
    let tracking = CompileError::Track(TrackError::Preprocess(PreprocessError::BadUpsample(0)));
    let rendering = CompileError::Signals(PreprocessError::BadUpsample(0));
    assert_ne!(tracking.to_string(), rendering.to_string());
    assert!(
        rendering.to_string().contains("actuator signals"),
        "{rendering}"
    );
}
