//! The whole chain, recording to stimulus file: stages 0 to 7 in order, timed.
//!
//! Each stage lives in its own crate (`touchc-input` to `touchc-encoding`); this module
//! only hands each stage's output to the next, measures it, and gathers the figures of
//! the [`Report`].

use ndarray::Array3;

use crate::coverage::{self, Coverage, Misses, Tracking, DEFAULT_RADIUS_CELLS};
use crate::rendered::{self, Shortfall};
use touch_protocol::{Limits, CHANNELS};
use touchc_encoding::keyframes::KeyframeError;
use touchc_input::recording::{Recording, RecordingError};
use touchc_input::warning::InputWarning;
use touchc_model::config::{
    Config, ConfigError, Metadata, MetadataOverrides, Sampling, ValidConfig,
};
use touchc_model::crop::Crop;
use touchc_model::layout::Layout;
use touchc_model::stage::{Stage, StageSeconds};
use touchc_placement::{self as placement, Placement, PlacementError};
use touchc_rendering::condition::{self, ConditionError, LimitViolation};
use touchc_rendering::signals::{self, ChannelSignals};
use touchc_tracking::preprocess::PreprocessError;
use touchc_tracking::scene;
use touchc_tracking::track::{TrackError, TrackOutput};

mod clock;
mod finish;
mod warning;

use clock::Clock;
use finish::Read;

pub use warning::Warning;

/// Everything `compile` needs besides the recording.
#[derive(Debug, Clone)]
pub struct CompileOptions {
    /// Algorithm parameters, validated (the default preset's by default); what they
    /// become at the recording's sampling is checked before any stage runs.
    pub config: ValidConfig,
    /// The actuator layout (the paper's sleeve by default).
    pub layout: Layout,
    /// The actuator profile's safety limits the signal must pass.
    pub limits: Limits,
    /// Scale the signal down to pass the limits instead of refusing it.
    pub fit: bool,
    /// Crop time and space to the active scene before the heavy stages.
    pub crop: bool,
    /// Keep the blurred movie and the scored detections in [`Compiled::tracked`] (what
    /// a preview draws; with `crop` off, the whole recording's). Off, the compile
    /// streams through the frames and keeps neither: memory follows the touch, not the
    /// recording's length.
    pub keep_scene: bool,
    /// Keep the trajectories in [`Compiled::tracked`] (plots, previews and evaluations
    /// read them; the report counts them either way). Off, they are freed once the
    /// actuator signals are made (stage 5), before the 1 kHz signal is: an hour of real
    /// touch's regions are 27 MB of the compile's peak. `touchc compile` keeps none.
    pub keep_trajectories: bool,
    /// The recording's rate and pitch from the command line (over the file's, over the
    /// config's `input.rate_hz` / `input.pitch_mm`).
    pub metadata: MetadataOverrides,
    /// The stimulus name written into the file (at most 32 bytes).
    pub name: String,
}

impl Default for CompileOptions {
    fn default() -> Self {
        CompileOptions {
            config: ValidConfig::default(),
            layout: Layout::paper(),
            limits: Limits::SLEEVE,
            fit: false,
            crop: true,
            keep_scene: false,
            keep_trajectories: true,
            metadata: MetadataOverrides::default(),
            name: String::from("touch"),
        }
    }
}

/// Why a recording could not be compiled.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CompileError {
    /// A knob is out of its range (names the knob, the value and the range).
    #[error("config")]
    Config(#[from] ConfigError),
    /// The recording is unusable (the message names the file).
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// Tracking failed (stages 1-3).
    #[error(transparent)]
    Track(#[from] TrackError),
    /// The actuator signals could not be recomputed from the tared frames (stage 5).
    #[error("actuator signals")]
    Signals(#[from] PreprocessError),
    /// Placement failed.
    #[error("placement")]
    Placement(#[from] PlacementError),
    /// Conditioning failed.
    #[error("conditioning")]
    Condition(#[from] ConditionError),
    /// The signal breaks the actuator profile's limits (and `fit` was not asked for:
    /// [`CompileOptions::fit`] would scale it down).
    #[error("the signal breaks the safety limits")]
    Limits(#[from] LimitViolation),
    /// No encoding met the fidelity bounds, or the protocol refused the header.
    #[error("encoding")]
    Keyframes(#[from] KeyframeError),
}

/// The figures of one compile (`touchc compile --report`).
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    /// The recording's name (its file).
    pub input: String,
    /// The recording's shape as read, `[frames, rows, cols]`.
    pub shape: [usize; 3],
    /// The stimulus name.
    pub name: String,
    /// Chosen transform `[x_mm, y_mm, scale, rotation, split_mm]`; `None` without touch.
    pub transform: Option<[f64; 5]>,
    /// Its score (lower is better); 0 without touch.
    pub score: f64,
    /// Selected trajectories, indices in `touchc track` order.
    pub selected: Vec<usize>,
    /// Trajectories found.
    pub trajectories: usize,
    /// Transforms in the grid.
    pub transforms: usize,
    /// Transforms whose subset was actually solved (the others meet no trajectory).
    pub transforms_evaluated: usize,
    /// Transforms whose subset search ran out of its node budget (a warning says so).
    pub transforms_inexact: usize,
    /// True when the flow used every unit of `track.max_trajectories` (a warning says so).
    pub trajectory_limit_reached: bool,
    /// Edges the min-cost flow scanned (its work; 0 without touch).
    pub flow_work: u64,
    /// True when the min-cost flow stopped at its work budget (a warning says so).
    pub flow_budget_reached: bool,
    /// Wall seconds per stage that ran, and [`Stage::Total`].
    pub seconds: StageSeconds,
    /// Size of the stimulus file.
    pub bytes: usize,
    /// Length of the stimulus signal, seconds.
    pub duration_s: f64,
    /// `bytes / duration_s`.
    pub bytes_per_second: f64,
    /// RMS error of the player's output against the compiler's f64 1 kHz signal,
    /// fraction of full scale.
    pub rms_error_fs: f64,
    /// Largest such error.
    pub max_error_fs: f64,
    /// Keyframe period chosen, ms.
    pub keyframe_period_ms: u16,
    /// Quantisation shift chosen.
    pub quant_shift: u8,
    /// How far the keyframes' lines may stray from the signal, fraction of full scale
    /// (0 when every keyframe is the signal's value, rounded; see `encoding::keyframes`).
    pub line_tolerance_fs: f64,
    /// Scale applied to pass the limits (1 = unchanged).
    pub fit_scale: f64,
    /// True when the recording holds no touch (a silent stimulus).
    pub no_touch: bool,
    /// The crop applied: frames `[start, end)`, cells rows/cols `[start, end)`.
    pub crop: Option<Crop>,
    /// Share of the touch pressure within two cells of a tracked contact (1 without
    /// touch, 0 when the tare removed the touch the raw frames hold: none of it is
    /// played; see [`crate::coverage`]).
    pub coverage: f64,
    /// The figures behind `coverage`: touch and explained pressure, touch readings.
    pub coverage_detail: Coverage,
    /// Where the unexplained touch lies (absent without touch).
    pub misses: Option<Misses>,
    /// Share of the touch pressure a driven actuator plays, within its workspace circle
    /// (1 without touch, 0 when the tare removed it; see [`crate::rendered`]).
    pub rendered_coverage: f64,
    /// The figures behind `rendered_coverage` (`explained_psi` is the played pressure).
    pub rendered_detail: Coverage,
    /// The sleeve plays much less of the touch than the tracker follows (also among
    /// [`Report::warnings`]).
    pub shortfall: Option<Shortfall>,
    /// Things the user should know, the input stage's first (what the later ones say
    /// may follow from them).
    pub warnings: Vec<Warning>,
    /// The recording's rate and pitch as used, each with its source (cli, file,
    /// default).
    pub metadata: Metadata,
    /// Every algorithm parameter this compile used (preset and overrides applied), so
    /// the report says how to reproduce it.
    pub config: ValidConfig,
    /// The actuator layout's id.
    pub layout: String,
}

impl Report {
    /// The input stage's warnings among [`Report::warnings`].
    pub fn input_warnings(&self) -> impl Iterator<Item = &InputWarning> {
        self.warnings.iter().filter_map(|w| match w {
            Warning::Input(w) => Some(w),
            _ => None,
        })
    }
}

/// A compiled stimulus with its report and the intermediate results (for plots).
#[derive(Debug, Clone)]
pub struct Compiled {
    /// The stimulus file.
    pub stimulus: Vec<u8>,
    /// Its figures.
    pub report: Report,
    /// The compiler's own 1 kHz signal, amperes (what the player approximates).
    pub signal: Vec<[f64; CHANNELS]>,
    /// Tracking output (absent for a recording without touch).
    pub tracked: Option<TrackOutput>,
    /// Placement (absent without trajectories).
    pub placement: Option<Placement>,
    /// Per-actuator pressures at the frame rate (absent without touch).
    pub signals: Option<ChannelSignals>,
}

/// Stimulus names are at most this many bytes.
const MAX_NAME: usize = touch_protocol::stimulus::MAX_NAME_LEN;

/// `name` cut to the format's limit at a character boundary.
pub fn stimulus_name(name: &str) -> &str {
    let mut end = name.len().min(MAX_NAME);
    while !name.is_char_boundary(end) {
        end -= 1;
    }
    &name[..end]
}

/// Compiles `rec` into a stimulus.
pub fn compile(rec: &Recording, opts: &CompileOptions) -> Result<Compiled, CompileError> {
    compile_from(Input::Borrowed(rec), opts)
}

/// [`compile`], taking the recording: its frames are freed once tared, so the later
/// stages do not hold the raw recording beside the tared copy (at an hour of the
/// paper's sleeve, 97 MB of the peak). Same result.
pub fn compile_owned(rec: Recording, opts: &CompileOptions) -> Result<Compiled, CompileError> {
    compile_from(Input::Owned(rec), opts)
}

/// The recording a compile reads: the caller's, or its own to free early.
enum Input<'a> {
    Borrowed(&'a Recording),
    Owned(Recording),
}

impl std::ops::Deref for Input<'_> {
    type Target = Recording;

    fn deref(&self) -> &Recording {
        match self {
            Input::Borrowed(r) => r,
            Input::Owned(r) => r,
        }
    }
}

fn compile_from(rec: Input<'_>, opts: &CompileOptions) -> Result<Compiled, CompileError> {
    let cfg = &opts.config;
    let mut clock = Clock::new();

    // Every knob, in the units of this recording, before any work.
    let metadata = Metadata::resolve(&opts.metadata, &rec.file_metadata(), cfg);
    let sampling = Sampling::new(&metadata, cfg);
    let (_, rows, cols) = rec.dim();
    cfg.validate_for(&sampling, (rows, cols))?;

    let (tared, mut warnings, silent) = tare_stage(&rec, cfg, &sampling)?;
    // Nothing reads the raw frames after this: only the name and shape.
    let read = Read {
        name: rec.name().to_string(),
        shape: rec.dim(),
        metadata,
    };
    drop(rec);
    clock.stage(Stage::Tare);

    // A recording without touch compiles to silence.
    let (signal, fit_scale, scene) = if silent {
        (vec![[0.0; CHANNELS]], 1.0, None)
    } else {
        let (signal, fit_scale, scene) =
            touch_stages(tared, opts, &sampling, &mut clock, &mut warnings)?;
        (signal, fit_scale, Some(scene))
    };

    let encoding = finish::encode(signal, fit_scale, opts, &mut warnings)?;
    clock.stage(Stage::Keyframes);
    Ok(finish::compiled(
        read,
        scene,
        encoding,
        warnings,
        clock.finish(),
        opts,
    ))
}

/// Stages 1-6 on a recording with touch: the conditioned signal, the factor `--fit`
/// scaled it by, and what the stages made of the touch.
fn touch_stages(
    tared: Array3<f64>,
    opts: &CompileOptions,
    sampling: &Sampling,
    clock: &mut Clock,
    warnings: &mut Vec<Warning>,
) -> Result<(Vec<[f64; CHANNELS]>, f64, Scene), CompileError> {
    let cfg = &opts.config;
    // Stages 1-3, on the active scene only.
    let crop = if opts.crop {
        scene::active_crop(tared.view(), cfg, sampling)
    } else {
        Crop::whole(tared.dim())
    };
    let (mut tracked, crop) = scene::track_cropped(
        tared.view(),
        &crop,
        cfg,
        sampling,
        opts.keep_scene,
        &mut |shares| clock.split(shares),
    )?;
    let covered = measure_coverage(tared.view(), &tracked, cfg, sampling, warnings);
    clock.stage(Stage::Coverage);

    let placement = place_stage(&tracked, &covered.0, tared.dim(), opts, warnings)?;
    clock.stage(Stage::Placement);

    let (signals, rendered) = signals_stage(
        tared.view(),
        &tracked,
        placement.as_ref(),
        &covered.0,
        opts,
        sampling,
        warnings,
    )?;
    // The tared copy of the recording is not read after stage 5, nor the trajectories
    // unless the caller keeps them.
    drop(tared);
    let trajectories = tracked.trajectories.len();
    if !opts.keep_trajectories {
        tracked.trajectories = Vec::new();
    }
    clock.stage(Stage::Signals);

    let (signal, fit_scale) = condition_stage(&signals, opts, sampling)?;
    clock.stage(Stage::Condition);

    let scene = Scene {
        tracked,
        trajectories,
        placement,
        signals,
        crop,
        covered,
        rendered,
    };
    Ok((signal, fit_scale, scene))
}

/// Stage 0: tare and trim, and the paper's "no touch" filter. Returns the tared frames,
/// the warnings so far (the input's own first: what the later ones say may follow from
/// them), and whether the recording has too little touch to compile.
fn tare_stage(
    rec: &Recording,
    cfg: &Config,
    sampling: &Sampling,
) -> Result<(Array3<f64>, Vec<Warning>, bool), CompileError> {
    let (tared, tare_note) = rec.tare_noting(&cfg.input, sampling)?;
    let mut notes: Vec<InputWarning> = touchc_input::sanity::transposed(rec.dim())
        .into_iter()
        .chain(tare_note)
        .collect();
    let sanity = touchc_input::sanity::check(rec, tared.view(), cfg, sampling);
    let touched = scene::touch_readings(tared.view(), cfg.input.touch_threshold_psi);
    let silent = touched <= cfg.input.min_touch_readings;
    if silent {
        notes.extend(touchc_input::sanity::erased_touch(rec, cfg, sampling));
    }
    let mut warnings: Vec<Warning> = notes.into_iter().map(Warning::Input).collect();
    warnings.extend(sanity.into_iter().map(Warning::Sanity));
    if silent {
        warnings.push(Warning::NoTouch {
            readings: touched,
            threshold_psi: cfg.input.touch_threshold_psi,
            min_readings: cfg.input.min_touch_readings,
        });
    }
    Ok((tared, warnings, silent))
}

/// Stage 4: the placement of the tracked trajectories on a recording of `dim` (frames,
/// rows, cols), `None` without any; warns when tracking stopped at one of its limits
/// (`covered` is the coverage it reached).
fn place_stage(
    tracked: &TrackOutput,
    covered: &Coverage,
    dim: (usize, usize, usize),
    opts: &CompileOptions,
    warnings: &mut Vec<Warning>,
) -> Result<Option<Placement>, CompileError> {
    let cfg = &opts.config;
    let (rows_px, cols_px) = (
        dim.1 * cfg.preprocess.upsample,
        dim.2 * cfg.preprocess.upsample,
    );
    if tracked.trajectories.len() >= cfg.track.max_trajectories {
        // The flow stops at this many units: a further contact would have needed one more.
        warnings.push(Warning::TrajectoryLimit {
            trajectories: tracked.trajectories.len(),
            max_trajectories: cfg.track.max_trajectories,
            coverage: covered.ratio(),
        });
    }
    if tracked.flow_budget_reached {
        warnings.push(Warning::FlowBudget {
            flow_work: tracked.flow_work,
            work_per_edge: touchc_tracking::track::FLOW_WORK_PER_EDGE,
            trajectories: tracked.trajectories.len(),
            coverage: covered.ratio(),
        });
    }
    if tracked.trajectories.is_empty() {
        warnings.push(Warning::NoTrajectory);
        return Ok(None);
    }
    Ok(Some(placement::place(
        &tracked.trajectories,
        rows_px,
        cols_px,
        tracked.pitch_mm(),
        &opts.layout,
        &cfg.placement,
    )?))
}

/// Stage 5: the actuator signals of `placement` (silent without one), and the share of
/// the touch pressure they render, with its shortfall against the tracked `covered`.
fn signals_stage(
    tared: ndarray::ArrayView3<f64>,
    tracked: &TrackOutput,
    placement: Option<&Placement>,
    covered: &Coverage,
    opts: &CompileOptions,
    sampling: &Sampling,
    warnings: &mut Vec<Warning>,
) -> Result<(ChannelSignals, (Coverage, Option<Shortfall>)), CompileError> {
    let cfg = &opts.config;
    let signals = match placement {
        Some(p) => signals::recomputed_actuator_signals(tracked, p, tared, cfg, sampling)?,
        None => ChannelSignals::silent(tared.dim().0),
    };
    if let Some(p) = placement.filter(|p| p.transforms_inexact > 0) {
        warnings.push(Warning::SubsetBudget {
            node_budget: p.node_budget,
            transforms_inexact: p.transforms_inexact,
            transforms_evaluated: p.transforms_evaluated,
            trajectories: tracked.trajectories.len(),
        });
    }
    if placement.is_some_and(|p| p.selected.is_empty()) {
        warnings.push(Warning::OutsideWorkspaces);
    }
    let rendered = match placement {
        Some(p) => rendered::measure(
            tared,
            cfg.input.touch_threshold_psi,
            sampling.pitch_mm,
            &p.circles,
            &signals,
        ),
        None => Coverage {
            explained_psi: 0.0,
            ..*covered
        },
    };
    let shortfall = Shortfall::of(covered.ratio(), rendered.ratio());
    if let Some(s) = shortfall {
        warnings.push(Warning::Shortfall(s));
    }
    Ok((signals, (rendered, shortfall)))
}

/// Stage 6: the signals conditioned to the output rate and, with `--fit`, fitted to the
/// limits (else checked against them); returns the signal and the fit's scale.
fn condition_stage(
    signals: &ChannelSignals,
    opts: &CompileOptions,
    sampling: &Sampling,
) -> Result<(Vec<[f64; CHANNELS]>, f64), CompileError> {
    let cfg = &opts.config;
    let conditioned = condition::condition(&signals.psi, &cfg.signal, sampling.rate_hz)?;
    let mut signal = conditioned.output;
    let limits = condition::Limits::from(opts.limits);
    let fit_scale = if opts.fit {
        // The played codes heat the coil a little more than the f64 signal (the
        // keyframes' error, and the player's accounting of each tick at its code's
        // current rounded up): fitted to the whole thermal budget, a long touch trips
        // the player's limit and is encoded again (a second stage 7, 0.4 s at an hour).
        // Fitted with room for both, once; the refit in stage 7 stays the backstop.
        let device = touch_protocol::DeviceConfig::default();
        let accounting_ua = touch_protocol::player::heat_accounting_margin_ua(device.full_scale_ma);
        condition::fit_to(
            &mut signal,
            &limits,
            cfg.signal.fit_thermal_share,
            f64::from(accounting_ua) / 1e6,
        )?
    } else {
        condition::check_limits(&signal, &limits)?;
        1.0
    };
    Ok((signal, fit_scale))
}

/// What stages 1-5 made of a recording with touch.
struct Scene {
    tracked: TrackOutput,
    /// The trajectories tracked (kept in `tracked` or not).
    trajectories: usize,
    placement: Option<Placement>,
    signals: ChannelSignals,
    crop: Crop,
    covered: (Coverage, Misses),
    rendered: (Coverage, Option<Shortfall>),
}

/// Coverage below this share of the touch pressure is a warning.
pub const COVERAGE_WARNING: f64 = 0.8;

/// The coverage of the tracked contacts on `tared`, and where the rest lies; below
/// [`COVERAGE_WARNING`] a warning with the likely causes.
fn measure_coverage(
    tared: ndarray::ArrayView3<f64>,
    tracked: &TrackOutput,
    cfg: &Config,
    sampling: &Sampling,
    warnings: &mut Vec<Warning>,
) -> (Coverage, Misses) {
    let points = coverage::contact_points(&tracked.trajectories, sampling.upsample);
    let threshold = cfg.input.touch_threshold_psi;
    let cells = coverage::classify(tared, threshold, &points, DEFAULT_RADIUS_CELLS);
    let cov = coverage::measure_classified(tared, &cells);
    let tracking = tracking_figures(cfg, sampling);
    let misses = coverage::explain(tared, &cells, &points, &tracking);
    if cov.ratio() < COVERAGE_WARNING {
        warnings.push(Warning::LowCoverage {
            coverage: cov.ratio(),
            threshold: COVERAGE_WARNING,
            causes: misses.causes(&tracking),
            touch_tracking: tracking.touch_tracking,
        });
    }
    (cov, misses)
}

/// What the config's tracking can follow, in the units of [`Tracking`].
fn tracking_figures(cfg: &Config, sampling: &Sampling) -> Tracking {
    let strongest = -touchc_tracking::detect::detection_cost(1e6, &cfg.detect);
    let pay = cfg.track.entry_cost + cfg.track.exit_cost;
    let min_frames = if strongest > 0.0 {
        (pay / strongest).floor() as usize + 1
    } else {
        usize::MAX
    };
    Tracking {
        rate_hz: sampling.rate_hz,
        cell_mm: sampling.pitch_mm,
        gate_mm_s: cfg.track.max_speed_mm_s,
        min_frames,
        touch_tracking: cfg.track.bridge.is_some()
            && (cfg.detect.split.is_some() || cfg.track.regions.is_some()),
    }
}
