//! Every parameter of the mapping algorithm, in one typed config.
//!
//! [`Config::default`] is the `touch` preset: the paper's algorithm with the tracking
//! that real recordings need (fast strokes, brief taps, flat hands, flicker, touch at
//! the start). [`Preset::Paper`] is the values of the paper and of the authors'
//! published code (see `docs/algorithm.md`); every section's own `Default` is the
//! paper's. Stages read their own section and never hard-code a parameter.
//! [`Config::preset`] gives the other points of the trade ([`Preset`]); `touchc trade`
//! measures them.
//!
//! Every knob is physical and carries its unit in its name (`blur_sigma_mm`,
//! `max_speed_mm_s`, `tare_s`, ...): the same config means the same thing for any sensor
//! rate, cell pitch and upsampling factor. Pixels and frames are derived in one place,
//! [`Sampling`], from the recording's rate and pitch ([`Metadata`]) and the upsampling
//! factor. [`Config::validate`] checks every knob against a documented range before any
//! stage runs.

use serde::{Deserialize, Serialize};

mod bounds;
mod contacts;
mod sampling;
mod knob;
mod layers;
mod valid;
mod validate;
mod words;

pub use bounds::{
    grid_size, MAX_GRID_STEPS, MAX_TRANSFORMS, MAX_UPSAMPLE, PITCH_MM_RANGE, RATE_HZ_RANGE,
};
pub use contacts::{Bridge, Regions, Split};
pub use knob::{Knob, Unit};
pub use layers::{Layers, OffTable, Setting};
pub use sampling::{FileMetadata, Metadata, MetadataOverrides, Sampling, Source, Sourced};
pub use valid::ValidConfig;
pub use validate::{ConfigError, DerivedLimit, SamplingKnob};

/// All stage parameters. `Config::default()` is the `touch` preset;
/// `Config::preset(Preset::Paper)` reproduces the paper.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Config {
    /// Stage 0: loading and tare.
    pub input: InputConfig,
    /// Stage 1: upsampling and blur.
    pub preprocess: PreprocessConfig,
    /// Stage 2: detections.
    pub detect: DetectConfig,
    /// Stage 3: min-cost-flow tracking.
    pub track: TrackConfig,
    /// Stage 4: transform search and subset choice.
    pub placement: PlacementConfig,
    /// The active scene's crop before the heavy stages.
    pub crop: CropConfig,
    /// Stages 5 and 6: per-actuator signals and conditioning.
    pub signal: SignalConfig,
    /// Stage 7: the keyframe encoding's fidelity bounds and candidates.
    pub keyframes: KeyframeConfig,
}

impl Default for Config {
    fn default() -> Self {
        Config::preset(Preset::Touch)
    }
}

/// A named point of the speed/accuracy trade (`touchc compile --preset`).
///
/// `touchc trade` measures each one against `exact` (see `docs/trade.md`). Every preset
/// keeps the signal model (stages 5-6) of the paper; `fast` and `exact` differ from
/// `paper` only in how finely the touch is sampled in space and how thoroughly the
/// placement is searched, `touch` only in which touch is tracked.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// Real touch, the default: the paper's algorithm, with tracking that keeps what
    /// real recordings hold. Detections up to 3 m/s link (swipes to 2.5 m/s, 4 Hz shakes
    /// of +-40 mm, and a flat hand rubbing at 1 m/s, whose reported point jumps ahead
    /// of the hand); a contact is a moving region ([`Regions::MEASURED`]): the cells a
    /// hand presses, one trajectory per hand whose points are its footprint's cells, so
    /// a palm and a hand's weaker heel render on the actuators they cover and a hand
    /// that flickers or slides over a fabric grid stays one contact; a contact unseen for
    /// up to 100 ms goes on (sensor flicker); each cell's zero is a low quantile of the
    /// whole recording and nothing is trimmed (a recording may begin or end mid-touch).
    ///
    /// Gives up: the published results (a contact is its footprint, not one point), and
    /// some time in tracking and placement (`docs/trade.md`, measured).
    #[default]
    Touch,
    /// The published parameters and transform grid: what the paper's participants felt,
    /// and the reference vectors' results bit for bit.
    Paper,
    /// Upsampling x4 instead of x7 (blur sigma and link gate keep their physical size,
    /// being in mm and mm/s) and a coarse-to-fine placement search (every second grid point,
    /// then the full grid around the 32 best, then a local search).
    ///
    /// Gives up: detections sit on a 6.35 mm instead of a 3.63 mm pixel grid, so
    /// trajectories, their costs and the rendered pressures move by up to half a pixel;
    /// the search can miss a transform that is best only in a narrow gap between coarse
    /// points (with 8 instead of 32 kept it did, on `examples/tap_pat.npy`). Computation
    /// stays f64: the keyframe search, which no preset changes, takes half the time, and
    /// f32 would change every detection cost of the reference vectors.
    Fast,
    /// The paper's sampling with a transform grid 4 times finer along x and 2 times
    /// along y and the split (77 x 39: 60,060 transforms, every published grid point
    /// included, so its score is never worse than `paper`'s). f64 throughout.
    ///
    /// Gives up: time in the placement stage (about 12 times the paper's) and the
    /// published results: the chosen transform, and so which actuator renders which
    /// contact, can differ from the paper's. It has converged: a grid 34 times larger
    /// (305 x 115) improves the score of a 698-frame combination by 0.3 % more.
    Exact,
}

impl Preset {
    /// Every preset, fastest first (the order of `touchc trade`'s table).
    pub const ALL: [Preset; 4] = [Preset::Fast, Preset::Paper, Preset::Touch, Preset::Exact];

    /// The preset's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Touch => "touch",
            Preset::Paper => "paper",
            Preset::Fast => "fast",
            Preset::Exact => "exact",
        }
    }
}

impl Config {
    /// The parameters of `preset` (see [`Preset`] for what each gives up).
    ///
    /// # Example
    /// ```
    /// use touchc_model::config::{Config, Preset};
    /// assert_eq!(Config::preset(Preset::Touch), Config::default());
    /// let paper = Config::preset(Preset::Paper);
    /// let fast = Config::preset(Preset::Fast);
    /// assert_eq!(fast.preprocess.upsample, 4);
    /// // The blur keeps its width in mm (3 px of 25.4/7 mm), so x4 makes it 12/7 px.
    /// assert_eq!(fast.preprocess.blur_sigma_mm, paper.preprocess.blur_sigma_mm);
    /// ```
    pub fn preset(preset: Preset) -> Config {
        let paper = Config {
            input: InputConfig::default(),
            preprocess: PreprocessConfig::default(),
            detect: DetectConfig::default(),
            track: TrackConfig::default(),
            placement: PlacementConfig::default(),
            crop: CropConfig::default(),
            signal: SignalConfig::default(),
            keyframes: KeyframeConfig::default(),
        };
        match preset {
            Preset::Paper => paper,
            Preset::Touch => Config {
                input: InputConfig {
                    baseline: Baseline::Robust,
                    trim_s: 0.0,
                    ..paper.input
                },
                track: TrackConfig {
                    entry_cost: 1.5,
                    exit_cost: 1.5,
                    max_speed_mm_s: 3000.0,
                    max_trajectories: MAX_TRAJECTORIES,
                    // 100 ms: two frames at 20 Hz, five at 54 Hz, so a light fingertip
                    // unseen for two frames stays one contact; a lift of 150 ms (three
                    // frames at 20 Hz) still ends a stroke.
                    bridge: Some(Bridge {
                        max_missing_s: 0.1,
                        cost_per_missing: 0.5,
                    }),
                    regions: Some(Regions::MEASURED),
                },
                signal: SignalConfig {
                    ring_out: RingOut::Seconds,
                    ..paper.signal
                },
                ..paper
            },
            Preset::Fast => paper.upsampled(4).with_placement(PlacementConfig {
                coarse_to_fine: Some(CoarseToFine {
                    stride: 2,
                    keep: 32,
                }),
                ..PlacementConfig::default()
            }),
            Preset::Exact => paper.with_placement(PlacementConfig {
                grid_x: 77,
                grid_y: 39,
                ..PlacementConfig::default()
            }),
        }
    }

    /// This config with upsampling `k`. Every other knob is physical, so the blur and
    /// the link gate keep their size in mm; only their pixel values change.
    pub fn upsampled(mut self, k: usize) -> Config {
        self.preprocess.upsample = k;
        self
    }

    fn with_placement(mut self, placement: PlacementConfig) -> Config {
        self.placement = placement;
        self
    }
}

/// Stage 0 parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InputConfig {
    /// Sensor frame rate in Hz when neither `--rate` nor the file gives one (the
    /// published sleeve: 20 Hz).
    pub rate_hz: f64,
    /// Sensor cell pitch in mm when neither `--pitch-mm` nor the file gives one (the
    /// published sleeve: one inch).
    pub pitch_mm: f64,
    /// How the per-cell zero is found (paper: the mean of the leading `tare_s`).
    pub baseline: Baseline,
    /// Leading window averaged per cell by the `leading` baseline, seconds (paper 1 s =
    /// 20 frames at 20 Hz).
    pub tare_s: f64,
    /// Dropped at each end of the recording after the tare, seconds (paper 1 s).
    pub trim_s: f64,
    /// The `robust` baseline: each cell's zero is this quantile of its readings over the
    /// whole recording (0.02: a cell may be pressed for up to 98 % of the recording, so a
    /// press held through a whole capture but for a second at either end keeps its
    /// pressure; a lower quantile would follow the noise's negative tail).
    pub baseline_quantile: f64,
    /// A recording with at most this many readings above `touch_threshold_psi` is "no touch".
    pub min_touch_readings: usize,
    /// Pressure above which a reading counts as touch, in psi.
    pub touch_threshold_psi: f64,
}

impl Default for InputConfig {
    fn default() -> Self {
        Self {
            rate_hz: Sampling::PAPER.rate_hz,
            pitch_mm: Sampling::PAPER.pitch_mm,
            baseline: Baseline::Leading,
            tare_s: 1.0,
            trim_s: 1.0,
            baseline_quantile: 0.02,
            min_touch_readings: 5,
            touch_threshold_psi: 0.08,
        }
    }
}

/// Where each cell's zero comes from (`input.baseline`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Baseline {
    /// The mean of the first `tare_s` seconds (the paper): needs a quiet start; touch
    /// in that window is subtracted from the whole recording.
    #[default]
    Leading,
    /// A low quantile (`baseline_quantile`) of each cell over the whole recording: a
    /// recording may begin or end mid-touch, as long as each cell is at rest for a
    /// larger share of the recording than the quantile.
    Robust,
}

/// The crop of the active scene (see `touchc_tracking::scene`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CropConfig {
    /// Quiet time kept on each side of the active window, seconds (paper 0.5 s = 10
    /// frames at 20 Hz).
    pub time_margin_s: f64,
    /// Quiet space kept on each side of the active cells, mm (paper 76.2 mm = 3 cells:
    /// the blur reaches 4 sigma, under two cells, and a link about one cell).
    pub space_margin_mm: f64,
}

impl Default for CropConfig {
    fn default() -> Self {
        Self {
            time_margin_s: 0.5,
            space_margin_mm: 3.0 * 25.4,
        }
    }
}

/// Stage 1 parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PreprocessConfig {
    /// Nearest-neighbour upsampling factor `k` (each cell becomes k x k pixels).
    pub upsample: usize,
    /// Gaussian blur sigma, mm (paper: 3 pixels of 25.4/7 mm = 10.886 mm).
    pub blur_sigma_mm: f64,
    /// Kernel half-width in sigmas (scipy's `truncate`).
    pub blur_truncate: f64,
}

/// The paper's pixel: a one-inch cell upsampled x7, mm.
const PAPER_PIXEL_MM: f64 = Sampling::PAPER.pitch_mm / Sampling::PAPER.upsample as f64;

impl Default for PreprocessConfig {
    fn default() -> Self {
        Self {
            upsample: 7,
            blur_sigma_mm: 3.0 * PAPER_PIXEL_MM,
            blur_truncate: 4.0,
        }
    }
}

/// Stage 2 parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DetectConfig {
    /// A detection must exceed this blurred pressure, in psi.
    pub min_value_psi: f64,
    /// `sigma_k` of the detection probability `P = m * Phi(z - sigma_k)`.
    pub sigma_k: f64,
    /// `m`, the ceiling of the detection probability.
    pub max_probability: f64,
    /// Also detect flat contacts on a lattice of their top (the `touch` preset's before
    /// contacts were regions; no preset's now, kept to measure against: the paper: none).
    pub split: Option<Split>,
}

impl Default for DetectConfig {
    fn default() -> Self {
        Self {
            min_value_psi: 1e-5,
            sigma_k: 1.25,
            max_probability: 0.98,
            split: None,
        }
    }
}

/// Stage 3 parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrackConfig {
    /// Cost of the source -> detection edge (`-ln P_entr`).
    pub entry_cost: f64,
    /// Cost of the detection -> sink edge (`-ln P_exit`).
    pub exit_cost: f64,
    /// Links join detections in consecutive frames that moved less than this speed,
    /// mm/s (paper: 50 squared pixels per frame, sqrt(50) x 25.4/7 mm x 20 Hz = 513 mm/s).
    pub max_speed_mm_s: f64,
    /// At most this many units of flow (trajectories). The paper's 200 is a count from
    /// its short recordings; the `touch` preset sets `MAX_TRAJECTORIES`, no limit in
    /// practice: the flow ends by itself when no further contact pays for its entry and
    /// exit, so the number of trajectories follows the touch, however long the
    /// recording. Reaching the limit is a warning. With `regions` (no flow), the
    /// contacts of lowest total cost are kept, at most this many.
    pub max_trajectories: usize,
    /// Links across frames where a contact is unseen (`touch`; the paper: none).
    pub bridge: Option<Bridge>,
    /// Track contacts as moving regions instead of linking local maxima (`touch`; the
    /// paper: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub regions: Option<Regions>,
}

impl Default for TrackConfig {
    fn default() -> Self {
        Self {
            entry_cost: 8.0,
            exit_cost: 8.0,
            max_speed_mm_s: PAPER_MAX_SPEED_MM_S,
            max_trajectories: 200,
            bridge: None,
            regions: None,
        }
    }
}

/// The largest `track.max_trajectories` a config may set, and the `touch` preset's.
pub(crate) const MAX_TRAJECTORIES: usize = 1_000_000;

/// The paper's link gate, `d^2 < 50` pixels^2 per frame at 20 Hz on 25.4/7 mm pixels, as
/// a speed. [`Sampling::gate_px2`] turns it back into exactly 50.
const PAPER_MAX_SPEED_MM_S: f64 =
    7.071_067_811_865_475_5 * PAPER_PIXEL_MM * Sampling::PAPER.rate_hz;

/// Stage 4 parameters: the transform grid of the published code.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlacementConfig {
    /// Grid points along x (the published grid: 20).
    pub grid_x: usize,
    /// Grid points along y, and the most vertical splits per y (the published grid: 20).
    pub grid_y: usize,
    /// Weight at a circle's centre is `1 + centre_bonus`, falling to 1 at the rim
    /// (`D = w_a * (1 + b - b * d^2 / r^2)`, b = 0.04 in the paper).
    pub centre_bonus: f64,
    /// Search a coarse sub-grid first and the full grid only near its best transforms;
    /// `None` (the paper) scores every transform of the grid.
    pub coarse_to_fine: Option<CoarseToFine>,
}

impl Default for PlacementConfig {
    fn default() -> Self {
        Self {
            grid_x: 20,
            grid_y: 20,
            centre_bonus: 0.04,
            coarse_to_fine: None,
        }
    }
}

/// The coarse-to-fine placement search (the `fast` preset).
///
/// Every transform it scores is a transform of the full grid with the full grid's score,
/// so its result is never better than the exhaustive search, and equal to it whenever
/// the best transform lies near one of the `keep` best coarse ones (see
/// `touchc_placement::place`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CoarseToFine {
    /// The coarse grid takes every `stride`-th point along x, y and the split (and the
    /// last point of each); 1 degenerates to the full grid.
    pub stride: usize,
    /// Coarse transforms whose neighbourhoods (`stride - 1` grid steps each way) are then
    /// scored on the full grid, before a local search around the best.
    pub keep: usize,
}

/// Stages 5 and 6 parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SignalConfig {
    /// A sample that rises and falls back by more than this share of the total pressure
    /// range between neighbouring frames is a spike.
    pub spike_fraction: f64,
    /// Butterworth low-pass order.
    pub lowpass_order: usize,
    /// Butterworth cut-off in Hz.
    pub lowpass_hz: f64,
    /// Filter forward and backward (zero phase) instead of causally from zero state.
    pub zero_phase: bool,
    /// How long the silence the low-pass rings out into lasts (paper: until the filter
    /// at the frame rate settles, in whole frames; real touch: in seconds, the same at
    /// every frame rate).
    pub ring_out: RingOut,
    /// Resting (pre-indented) current, in amperes; the signal spans `[pre_dent, peak]`.
    pub pre_dent_a: f64,
    /// Current at the strongest pressure of the scene, in amperes.
    pub peak_a: f64,
    /// Length of the ramps from 0 A to the pre-dent and back, in seconds.
    pub ramp_s: f64,
    /// With `--fit`, the share of the coil's thermal budget a signal that exceeds it is
    /// fitted to: the played codes heat the coil a little more or less than the f64
    /// signal (the keyframes' error), and the player keeps a reserve for its ramp down,
    /// so a signal fitted to the whole budget can trip the player's limit and be
    /// encoded again, 1% quieter. (The player's accounting of each tick at its code's
    /// current rounded up grows with the touch's length; the fit leaves room for it
    /// apart, in the leak.) 0.96 costs 0.05 dB against the whole budget.
    pub fit_thermal_share: f64,
}

impl Default for SignalConfig {
    fn default() -> Self {
        Self {
            spike_fraction: 1.0 / 8.0,
            lowpass_order: 5,
            lowpass_hz: 4.0,
            zero_phase: false,
            ring_out: RingOut::Frames,
            pre_dent_a: -0.9,
            peak_a: 1.0,
            ramp_s: 0.5,
            fit_thermal_share: 0.96,
        }
    }
}

/// How long the low-pass rings out after the recording (`signal.ring_out`), and how
/// much silence leads into it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RingOut {
    /// The paper's: until the impulse response of the filter at the frame rate falls
    /// below 1e-6 of its peak, in whole frames, with one frame of silence before the
    /// recording (all of the ring-out's length before it, zero phase). The same touch
    /// then lasts longer at 20 Hz than at 54 Hz (the bilinear design settles later at a
    /// low rate, and frames are coarser).
    #[default]
    Frames,
    /// The settling time of the same Butterworth at the 1 kHz output rate (where it is
    /// the analog filter's), in seconds, and 50 ms of silence before the recording (the
    /// paper's one frame at 20 Hz; zero phase: the settling time): the stimulus is cut
    /// at those instants, on 1 kHz ticks, whatever the frame rate.
    Seconds,
}

/// Stage 7 parameters: how faithful the keyframes must be, and what to try.
///
/// The signal is band-limited by the low-pass, so the file holds keyframes the player
/// interpolates; every candidate period and quantisation is played through the real
/// player and compared with the compiler's f64 signal (see `touchc_encoding::keyframes`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct KeyframeConfig {
    /// Largest RMS difference between the player's output and the f64 signal, as a
    /// fraction of the full scale (over all channels and ticks).
    pub max_rms_error_fs: f64,
    /// Largest difference at any tick and channel, fraction of the full scale.
    pub max_abs_error_fs: f64,
    /// Player ramp in and out, ms.
    pub ramp_ms: u16,
    /// Keyframe periods to try, ms (the longest that meets the bounds wins).
    pub periods_ms: Vec<u16>,
    /// Coarsest quantisation to try (`2^shift` Q15 units per step).
    pub max_quant_shift: u8,
    /// A file denser than this with one line tolerance for the whole signal, bytes per
    /// second, is tried again with a tolerance per second and channel: about 14% fewer
    /// bytes, for 3 to 6 times stage 7's time on a signal searched whole. Sparse files
    /// gain little from it; 0 tries it on every file.
    pub allocate_above_bytes_per_s: f64,
}

impl Default for KeyframeConfig {
    fn default() -> Self {
        Self {
            max_rms_error_fs: 0.005,
            max_abs_error_fs: 0.02,
            ramp_ms: 10,
            periods_ms: vec![250, 200, 125, 100, 80, 50, 40, 25, 20, 10, 5, 2, 1],
            max_quant_shift: 9,
            allocate_above_bytes_per_s: 100.0,
        }
    }
}
