//! Every parameter of the mapping algorithm, in one typed config.
//!
//! [`Config::default`] is the `paper` preset: the values of the paper and of the
//! authors' published code (see `shared/design/ALGORITHM.md`). Stages read their own
//! section and never hard-code a parameter.

use serde::{Deserialize, Serialize};

/// All stage parameters. `Config::default()` reproduces the paper.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
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
    /// Stages 5 and 6: per-actuator signals and conditioning.
    pub signal: SignalConfig,
}

/// Stage 0 parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InputConfig {
    /// Sensor frame rate in Hz.
    pub frame_rate_hz: f64,
    /// Frames averaged per cell for the tare, and dropped at both ends (`B`).
    pub tare_frames: usize,
    /// Sensor cell pitch in mm (one inch on the published sleeve).
    pub cell_mm: f64,
    /// A recording with at most this many readings above `touch_threshold_psi` is "no touch".
    pub min_touch_readings: usize,
    /// Pressure above which a reading counts as touch, in psi.
    pub touch_threshold_psi: f64,
}

impl Default for InputConfig {
    fn default() -> Self {
        Self {
            frame_rate_hz: 20.0,
            tare_frames: 20,
            cell_mm: 25.4,
            min_touch_readings: 5,
            touch_threshold_psi: 0.08,
        }
    }
}

/// Stage 1 parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PreprocessConfig {
    /// Nearest-neighbour upsampling factor `k` (each cell becomes k x k pixels).
    pub upsample: usize,
    /// Gaussian blur sigma, in upsampled pixels.
    pub blur_sigma: f64,
    /// Kernel half-width in sigmas (scipy's `truncate`).
    pub blur_truncate: f64,
}

impl Default for PreprocessConfig {
    fn default() -> Self {
        Self {
            upsample: 7,
            blur_sigma: 3.0,
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
}

impl Default for DetectConfig {
    fn default() -> Self {
        Self {
            min_value_psi: 1e-5,
            sigma_k: 1.25,
            max_probability: 0.98,
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
    /// Links join detections in consecutive frames closer than this squared pixel distance.
    pub link_gate_px2: f64,
    /// At most this many units of flow (trajectories).
    pub max_trajectories: usize,
}

impl Default for TrackConfig {
    fn default() -> Self {
        Self {
            entry_cost: 8.0,
            exit_cost: 8.0,
            link_gate_px2: 50.0,
            max_trajectories: 200,
        }
    }
}

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
}

impl Default for PlacementConfig {
    fn default() -> Self {
        Self {
            grid_x: 20,
            grid_y: 20,
            centre_bonus: 0.04,
        }
    }
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
    /// Resting (pre-indented) current, in amperes; the signal spans `[pre_dent, peak]`.
    pub pre_dent_a: f64,
    /// Current at the strongest pressure of the scene, in amperes.
    pub peak_a: f64,
    /// Length of the ramps from 0 A to the pre-dent and back, in seconds.
    pub ramp_s: f64,
}

impl Default for SignalConfig {
    fn default() -> Self {
        Self {
            spike_fraction: 1.0 / 8.0,
            lowpass_order: 5,
            lowpass_hz: 4.0,
            zero_phase: false,
            pre_dent_a: -0.9,
            peak_a: 1.0,
            ramp_s: 0.5,
        }
    }
}
