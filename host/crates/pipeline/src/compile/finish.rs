//! Stage 7, the keyframe encoding ([`encode`]), and the compile's result with its
//! [`Report`] ([`compiled`]).

use touch_protocol::CHANNELS;
use touchc_encoding::keyframes::{self, HeaderFields, KeyframeError, KeyframeOptions};
use touchc_input::warning::InputWarning;
use touchc_model::config::Metadata;
use touchc_model::stage::StageSeconds;
use touchc_rendering::condition;

use super::{stimulus_name, CompileOptions, Compiled, Report, Scene, Warning};
use crate::coverage::Coverage;

/// With `--fit`: the factor by which a fitted signal is scaled again when its encoding
/// still trips a limit in the player, and how many times at most (0.99^20 = 0.82).
const REFIT_STEP: f64 = 0.99;
const MAX_REFITS: u32 = 20;

/// What the compile read, for the report: the recording's name and shape, and its
/// sampling with where each value came from.
pub(super) struct Read {
    pub(super) name: String,
    pub(super) shape: (usize, usize, usize),
    pub(super) metadata: Metadata,
}

/// Stage 7's output: the stimulus file and its figures, with the signal as encoded
/// (scaled down again if `--fit` had to refit it) and the factor `--fit` scaled it by in
/// all (1 without it).
pub(super) struct Encoding {
    encoded: keyframes::Encoded,
    signal: Vec<[f64; CHANNELS]>,
    fit_scale: f64,
}

/// Stage 7: the conditioned `signal` (scaled by `fit_scale` so far) encoded as the
/// stimulus [`CompileOptions::name`]; a signal that was fitted gets its warning.
pub(super) fn encode(
    mut signal: Vec<[f64; CHANNELS]>,
    mut fit_scale: f64,
    opts: &CompileOptions,
    warnings: &mut Vec<Warning>,
) -> Result<Encoding, KeyframeError> {
    let name = stimulus_name(&opts.name);
    let (encoded, refits) = encode_refitting(&mut signal, &mut fit_scale, name, opts)?;
    if fit_scale < 1.0 {
        warnings.push(Warning::Fitted {
            scale: fit_scale,
            refits,
            refit_step: REFIT_STEP,
        });
    }
    Ok(Encoding {
        encoded,
        signal,
        fit_scale,
    })
}

/// The compile's result: the stimulus of `encoding`, the [`Report`] of everything the
/// stages made (`scene`, `None` for a recording without touch) and took `seconds`
/// over, and the intermediate results for plots.
pub(super) fn compiled(
    read: Read,
    scene: Option<Scene>,
    encoding: Encoding,
    warnings: Vec<Warning>,
    seconds: StageSeconds,
    opts: &CompileOptions,
) -> Compiled {
    let Encoding {
        encoded,
        signal,
        fit_scale,
    } = encoding;
    let no_touch = scene.is_none();
    let trajectories = scene.as_ref().map(|s| s.trajectories);
    let (tracked, placement, signals, crop, covered, rendered) = match scene {
        Some(s) => (
            Some(s.tracked),
            s.placement,
            Some(s.signals),
            Some(s.crop),
            Some(s.covered),
            Some(s.rendered),
        ),
        None => (None, None, None, None, None, None),
    };
    let tare_erased = warnings
        .iter()
        .any(|w| matches!(w, Warning::Input(InputWarning::TareErasedTouch { .. })));
    let duration_s = (signal.len().saturating_sub(1)) as f64 / condition::OUTPUT_RATE_HZ;
    let bytes = encoded.bytes.len();
    let report = Report {
        input: read.name,
        shape: [read.shape.0, read.shape.1, read.shape.2],
        name: stimulus_name(&opts.name).to_string(),
        transform: placement.as_ref().map(|p| {
            let t = &p.transform;
            [t.x_mm, t.y_mm, t.scale, t.rotation, t.split_mm]
        }),
        score: placement.as_ref().map_or(0.0, |p| p.score),
        selected: placement
            .as_ref()
            .map_or_else(Vec::new, |p| p.selected.clone()),
        trajectories: trajectories.unwrap_or(0),
        transforms: placement.as_ref().map_or(0, |p| p.scores.len()),
        transforms_evaluated: placement.as_ref().map_or(0, |p| p.transforms_evaluated),
        transforms_inexact: placement.as_ref().map_or(0, |p| p.transforms_inexact),
        trajectory_limit_reached: trajectories
            .is_some_and(|n| n >= opts.config.track.max_trajectories),
        flow_work: tracked.as_ref().map_or(0, |t| t.flow_work),
        flow_budget_reached: tracked.as_ref().is_some_and(|t| t.flow_budget_reached),
        seconds,
        bytes,
        duration_s,
        bytes_per_second: if duration_s > 0.0 {
            bytes as f64 / duration_s
        } else {
            0.0
        },
        rms_error_fs: encoded.rms_error_fs,
        max_error_fs: encoded.max_error_fs,
        keyframe_period_ms: encoded.period_ms,
        quant_shift: encoded.quant_shift,
        line_tolerance_fs: encoded.tolerance_fs,
        fit_scale,
        no_touch,
        crop,
        coverage: played_ratio(covered.as_ref().map(|c| &c.0), tare_erased),
        coverage_detail: covered.map_or_else(Coverage::default, |c| c.0),
        misses: covered.map(|c| c.1),
        rendered_coverage: played_ratio(rendered.as_ref().map(|r| &r.0), tare_erased),
        rendered_detail: rendered.map_or_else(Coverage::default, |r| r.0),
        shortfall: rendered.and_then(|r| r.1),
        warnings,
        metadata: read.metadata,
        config: opts.config.clone(),
        layout: opts.layout.id().to_string(),
    };
    Compiled {
        stimulus: encoded.bytes,
        report,
        signal,
        tracked,
        placement,
        signals,
    }
}

/// Stage 7: `signal` encoded as stimulus `name`. With `--fit`, a signal whose played
/// codes trip a limit is scaled down by [`REFIT_STEP`] (and `fit_scale` with it) and
/// encoded again, at most [`MAX_REFITS`] times; returns the encoding and the number of
/// refits.
fn encode_refitting(
    signal: &mut [[f64; CHANNELS]],
    fit_scale: &mut f64,
    name: &str,
    opts: &CompileOptions,
) -> Result<(keyframes::Encoded, u32), KeyframeError> {
    let fields = HeaderFields {
        name,
        layout_hash: opts.layout.geometry_hash(),
        layout: opts.layout.id(),
        limits: opts.limits,
    };
    let options = KeyframeOptions::new(&opts.config.keyframes);
    let mut refits = 0;
    loop {
        match keyframes::encode(signal, fields, &options) {
            // A signal fitted to the limits in f64 sits on them; the player's
            // interpolation and rounding can land it just over (a long touch fitted to
            // the thermal budget). Step down until the played codes pass too.
            Err(KeyframeError::LimitHit(_)) if opts.fit && refits < MAX_REFITS => {
                for v in signal.iter_mut().flatten() {
                    *v *= REFIT_STEP;
                }
                *fit_scale *= REFIT_STEP;
                refits += 1;
            }
            result => return result.map(|e| (e, refits)),
        }
    }
}

/// A coverage's ratio; without one (no touch tracked), 1, or 0 when the tare removed
/// the recorded touch (none is played).
fn played_ratio(coverage: Option<&Coverage>, tare_erased: bool) -> f64 {
    match coverage {
        Some(c) => c.ratio(),
        None if tare_erased => 0.0,
        None => 1.0,
    }
}
