//! The one place where physical knobs become pixels and frames.
//!
//! A recording is sampled at `rate_hz` frames per second on cells `pitch_mm` apart, and
//! stage 1 upsamples each cell into `upsample x upsample` pixels. Every stage asks
//! [`Sampling`] for its pixel and frame values, so `--upsample`, `--rate` or another
//! sensor never silently changes what a knob means.
//!
//! Unit conversion in floating point is not exact: `3 x 25.4 / 7` mm back in pixels is
//! `3.0000000000000004`, and the paper's link gate is a strict `d^2 < 50` on integer
//! pixel offsets, where `50.000000000000007` would admit a link the paper refuses. So
//! every derived value is rounded to a multiple of 2^-20 (about 1e-6 of a pixel or a
//! frame, far below anything a sensor resolves) before it is used: round physical
//! values come back as round pixel values, bit for bit.

use serde::Serialize;

use super::Config;

/// How a recording was sampled, and how finely stage 1 resamples it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Sampling {
    /// Sensor frames per second.
    pub rate_hz: f64,
    /// Distance between neighbouring sensor cells, mm.
    pub pitch_mm: f64,
    /// Pixels per cell along each axis after upsampling.
    pub upsample: usize,
}

/// The grid derived values are rounded to: 2^-20.
const SNAP: f64 = 1_048_576.0;

/// `x` rounded to the nearest multiple of 2^-20 (exact: scaling by a power of two).
/// Values too large to hold that resolution are returned unchanged.
fn snap(x: f64) -> f64 {
    if x.abs() < 1e15 / SNAP {
        (x * SNAP).round() / SNAP
    } else {
        x
    }
}

impl Sampling {
    /// The paper's sampling: 20 Hz, one-inch cells, x7.
    pub const PAPER: Sampling = Sampling {
        rate_hz: 20.0,
        pitch_mm: 25.4,
        upsample: 7,
    };

    /// The sampling of `metadata` with `config`'s upsampling factor.
    pub fn new(metadata: &Metadata, config: &Config) -> Self {
        Sampling {
            rate_hz: metadata.rate_hz.value,
            pitch_mm: metadata.pitch_mm.value,
            upsample: config.preprocess.upsample,
        }
    }

    /// Width of one upsampled pixel, mm.
    pub fn pixel_mm(&self) -> f64 {
        self.pitch_mm / self.upsample as f64
    }

    /// A length in mm as upsampled pixels.
    pub fn px(&self, mm: f64) -> f64 {
        snap(mm * self.upsample as f64 / self.pitch_mm)
    }

    /// A length in mm as sensor cells, rounded up (a margin keeps at least its length).
    pub fn cells_ceil(&self, mm: f64) -> usize {
        to_count(snap(mm / self.pitch_mm).ceil())
    }

    /// A duration in seconds as frames, to the nearest frame.
    pub fn frames(&self, seconds: f64) -> usize {
        to_count(snap(seconds * self.rate_hz).round())
    }

    /// A duration in seconds as frames, rounded up (a margin keeps at least its length).
    pub fn frames_ceil(&self, seconds: f64) -> usize {
        to_count(snap(seconds * self.rate_hz).ceil())
    }

    /// A speed in mm/s as the squared pixel distance a contact covers in one frame: the
    /// link gate. Squared before rounding, so the paper's sqrt(50) px per frame is 50.
    pub fn gate_px2(&self, speed_mm_s: f64) -> f64 {
        let px_per_frame = speed_mm_s * self.upsample as f64 / (self.pitch_mm * self.rate_hz);
        snap(px_per_frame * px_per_frame)
    }
}

/// A non-negative whole number as a count; NaN and negatives give 0, huge values
/// saturate (validation keeps real configs far below either).
fn to_count(x: f64) -> usize {
    if x.is_finite() && x > 0.0 {
        x as usize
    } else {
        0
    }
}

/// Where a recording's rate or pitch came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Source {
    /// The command line (`--rate`, `--pitch-mm`).
    Cli,
    /// The recording file (`rate_hz`, `pitch_mm` in a `.npz`).
    File,
    /// The config's `input.rate_hz` / `input.pitch_mm` (the published sleeve's).
    Default,
}

impl Source {
    /// The source's name in messages and reports.
    pub fn name(self) -> &'static str {
        match self {
            Source::Cli => "cli",
            Source::File => "file",
            Source::Default => "default",
        }
    }
}

/// A value and where it came from.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Sourced {
    /// The value used.
    pub value: f64,
    /// Where it came from.
    pub source: Source,
}

/// Rate and pitch given on the command line, overriding the file and the config.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MetadataOverrides {
    /// `--rate HZ`.
    pub rate_hz: Option<f64>,
    /// `--pitch-mm MM`.
    pub pitch_mm: Option<f64>,
}

/// The rate and pitch a recording file declares, where it declares them (a `.npz`'s
/// `rate_hz` and `pitch_mm`), already checked against the accepted ranges.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FileMetadata {
    /// Frames per second the file declares.
    pub rate_hz: Option<f64>,
    /// Cell pitch the file declares, mm.
    pub pitch_mm: Option<f64>,
}

/// The recording's rate and pitch as used, each with its source.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Metadata {
    /// Frames per second.
    pub rate_hz: Sourced,
    /// Cell pitch, mm.
    pub pitch_mm: Sourced,
}

impl Metadata {
    /// Command line over file over config default.
    pub fn resolve(overrides: &MetadataOverrides, file: &FileMetadata, config: &Config) -> Self {
        let pick = |cli: Option<f64>, file: Option<f64>, default: f64| match (cli, file) {
            (Some(value), _) => Sourced {
                value,
                source: Source::Cli,
            },
            (None, Some(value)) => Sourced {
                value,
                source: Source::File,
            },
            (None, None) => Sourced {
                value: default,
                source: Source::Default,
            },
        };
        Metadata {
            rate_hz: pick(overrides.rate_hz, file.rate_hz, config.input.rate_hz),
            pitch_mm: pick(overrides.pitch_mm, file.pitch_mm, config.input.pitch_mm),
        }
    }

    /// `rate 20 Hz (default), pitch 25.4 mm (default)`: for summaries.
    pub fn describe(&self) -> String {
        format!(
            "rate {} Hz ({}), pitch {} mm ({})",
            self.rate_hz.value,
            self.rate_hz.source.name(),
            self.pitch_mm.value,
            self.pitch_mm.source.name()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;

    /// The paper's physical values come back as the published pixel and frame values,
    /// bit for bit: 3.0 px sigma, 50.0 px^2 gate, 20 tare frames, 10 frames and 3 cells
    /// of crop margin.
    #[test]
    fn paper_values_are_exact() {
        let c = Config::preset(crate::config::Preset::Paper);
        let s = Sampling::PAPER;
        assert_eq!(s.px(c.preprocess.blur_sigma_mm), 3.0);
        assert_eq!(s.gate_px2(c.track.max_speed_mm_s), 50.0);
        assert_eq!(s.frames(c.input.tare_s), 20);
        assert_eq!(s.frames(c.input.trim_s), 20);
        assert_eq!(s.frames_ceil(c.crop.time_margin_s), 10);
        assert_eq!(s.cells_ceil(c.crop.space_margin_mm), 3);
        // Without the rounding the conversions are off in the last bits: this is what
        // the rounding is for.
        let raw = c.preprocess.blur_sigma_mm * 7.0 / 25.4;
        assert!((raw - 3.0).abs() < 1e-14);
    }

    #[test]
    fn fast_keeps_millimetres() {
        let fast = Sampling {
            upsample: 4,
            ..Sampling::PAPER
        };
        let c = Config::preset(crate::config::Preset::Paper);
        assert!((fast.px(c.preprocess.blur_sigma_mm) - 12.0 / 7.0).abs() < 1e-6);
        assert!((fast.gate_px2(c.track.max_speed_mm_s) - 50.0 * 16.0 / 49.0).abs() < 1e-6);
    }

    #[test]
    fn other_rates_keep_seconds() {
        let s = Sampling {
            rate_hz: 54.0,
            ..Sampling::PAPER
        };
        assert_eq!(s.frames(1.0), 54);
        assert_eq!(s.frames_ceil(0.5), 27);
        // A speed is per second: at 54 Hz a contact moves 20/54 as far per frame.
        let g = s.gate_px2(
            Config::preset(crate::config::Preset::Paper)
                .track
                .max_speed_mm_s,
        );
        assert!((g - 50.0 * (20.0f64 / 54.0).powi(2)).abs() < 1e-5);
    }
}
