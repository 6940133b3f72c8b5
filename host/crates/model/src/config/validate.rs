//! Every knob held to its range (the knob table's), checked before any stage runs.
//!
//! A range says what makes physical sense (positive, finite, below a cap that a real
//! sleeve or sensor never needs) and, with [`Config::validate_for`], bounds the work the
//! derived pixel and frame values ask for: the blur kernel, the upsampled frame, the link
//! gate, the filter. Outside a range the compile stops with the knob's name, the value
//! and the range, instead of running for minutes, allocating gigabytes or panicking in a
//! third-party routine.

use std::fmt;

use super::knob::{Range, Value};
use super::{
    grid_size, Config, Knob, OffTable, Preset, Sampling, Unit, MAX_TRANSFORMS, PITCH_MM_RANGE,
    RATE_HZ_RANGE,
};

/// The recording's sampling, as resolved (from the caller, the file or the config).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SamplingKnob {
    /// The frame rate, Hz.
    RateHz,
    /// The cell pitch, mm.
    PitchMm,
}

impl fmt::Display for SamplingKnob {
    /// The name of the quantity in a `.npz` recording and in [`super::Metadata`].
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            SamplingKnob::RateHz => "rate_hz",
            SamplingKnob::PitchMm => "pitch_mm",
        })
    }
}

/// What a knob becomes at a recording's sampling, and the bound it breaks.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum DerivedLimit {
    /// The blur kernel does not reach half an upsampled cell.
    KernelTooNarrow {
        /// The kernel radius, pixels.
        radius_px: f64,
        /// `preprocess.blur_truncate`.
        truncate: f64,
        /// The least radius, pixels.
        min_px: f64,
    },
    /// The blur kernel is wider than a 2,049-tap kernel.
    KernelTooWide {
        /// The kernel radius, pixels.
        radius_px: f64,
        /// The largest radius, pixels.
        max_px: f64,
    },
    /// The upsampled frame is too large along its longer side.
    FrameTooLarge {
        /// The longer side, pixels.
        side_px: usize,
        /// The recording's rows.
        rows: usize,
        /// The recording's columns.
        cols: usize,
        /// The largest side, pixels.
        max_px: usize,
    },
    /// The link gate is wider than any frame needs.
    GateTooWide {
        /// The gate's radius, pixels per frame.
        gate_px: f64,
        /// The largest radius, pixels.
        max_px: f64,
    },
    /// The low-pass cut-off is not below the Nyquist frequency.
    AboveNyquist {
        /// Half the frame rate, Hz.
        nyquist_hz: f64,
    },
}

/// A layer that does not read as config keys ([`super::Layers`]), or a knob outside its
/// range: the layer, the knob, the value and the range as values, worded by its
/// `Display` (`config/words.rs`) in the terms of the config file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// A preset's parameters did not serialise as TOML (a bug: every preset does).
    Preset {
        /// The preset.
        preset: Preset,
        /// The serialiser's message.
        message: String,
    },
    /// A config file is not TOML, or holds a key the config lacks or a value of the
    /// wrong kind.
    File {
        /// The file, as the caller named it.
        name: String,
        /// Where and what.
        source: Box<toml::de::Error>,
    },
    /// An assignment is not `SECTION.KEY=VALUE`.
    AssignmentSyntax {
        /// The assignment as given.
        assignment: String,
    },
    /// An assignment's value (or key) is not TOML.
    AssignmentValue {
        /// The assignment as given.
        assignment: String,
        /// Where and what.
        source: Box<toml::de::Error>,
    },
    /// The keys laid over the preset do not make a config (a key the config lacks, a
    /// value of the wrong kind, a table missing keys).
    Keys {
        /// The assignments given, any of which may be the one.
        assignments: Vec<String>,
        /// The assignments into tables the preset leaves out (the likely cause).
        off: Vec<OffTable>,
        /// The preset under the layers.
        preset: Preset,
        /// What serde refused.
        source: Box<toml::de::Error>,
    },
    /// A real-valued knob is not finite or outside `[min, max]`.
    OutOfRange {
        /// The knob.
        knob: Knob,
        /// The value given.
        value: f64,
        /// The least value accepted.
        min: f64,
        /// The largest value accepted.
        max: f64,
        /// The unit of all three.
        unit: Unit,
    },
    /// A whole-number knob is outside `[min, max]`.
    CountOutOfRange {
        /// The knob.
        knob: Knob,
        /// The value given.
        value: usize,
        /// The least value accepted.
        min: usize,
        /// The largest value accepted.
        max: usize,
    },
    /// A list knob has too few or too many entries.
    LengthOutOfRange {
        /// The knob.
        knob: Knob,
        /// Its entries.
        len: usize,
        /// The fewest accepted.
        min: usize,
        /// The most accepted.
        max: usize,
    },
    /// The placement grid has more transforms than the search takes.
    TooManyTransforms {
        /// `placement.grid_x`.
        grid_x: usize,
        /// `placement.grid_y`.
        grid_y: usize,
        /// The most transforms.
        max: usize,
    },
    /// The recording's rate or pitch is outside the range any recording may have.
    SamplingOutOfRange {
        /// Which.
        knob: SamplingKnob,
        /// The value.
        value: f64,
        /// The least value accepted.
        min: f64,
        /// The largest value accepted.
        max: f64,
    },
    /// The value is in range, but what it becomes at this recording's sampling is not.
    Derived {
        /// The knob.
        knob: Knob,
        /// The value given.
        value: f64,
        /// The sampling it was derived at.
        sampling: Sampling,
        /// What it became, and the bound.
        limit: DerivedLimit,
    },
}

/// Largest blur kernel radius, pixels: a 2,049-tap kernel (the paper's is 25).
pub(crate) const MAX_KERNEL_RADIUS_PX: f64 = 1024.0;
/// Largest upsampled frame, pixels per side.
pub(crate) const MAX_FRAME_PX: usize = 4096;
/// Largest link gate radius, pixels per frame (a gate wider than the frame links
/// everything anyway).
pub(crate) const MAX_GATE_PX: f64 = 4096.0;

/// `value` must lie in `range`.
fn check(knob: Knob, value: Value<'_>, range: Range) -> Result<(), ConfigError> {
    match (value, range) {
        (Value::Real(v), Range::Real { min, max, unit }) => within(knob, v, min, max, unit),
        (Value::Count(n), Range::Count { min, max }) => count(knob, n, min, max),
        (Value::Counts(list), Range::Counts { len, each }) => {
            if !(len.0..=len.1).contains(&list.len()) {
                return Err(ConfigError::LengthOutOfRange {
                    knob,
                    len: list.len(),
                    min: len.0,
                    max: len.1,
                });
            }
            list.iter()
                .try_for_each(|&n| count(knob, usize::from(n), each.0, each.1))
        }
        // A value of another kind than its range is a row of the table in error (its
        // tests catch it); the knob's type alone checks a free one.
        _ => Ok(()),
    }
}

/// `knob` must be finite and within `[min, max]` (in `unit`).
fn within(knob: Knob, v: f64, min: f64, max: f64, unit: Unit) -> Result<(), ConfigError> {
    if v.is_finite() && (min..=max).contains(&v) {
        return Ok(());
    }
    Err(ConfigError::OutOfRange {
        knob,
        value: v,
        min,
        max,
        unit,
    })
}

/// `knob` must be within `[min, max]`.
fn count(knob: Knob, v: usize, min: usize, max: usize) -> Result<(), ConfigError> {
    if (min..=max).contains(&v) {
        return Ok(());
    }
    Err(ConfigError::CountOutOfRange {
        knob,
        value: v,
        min,
        max,
    })
}

/// The recording's `knob` must be finite and within `range`.
fn sampled(
    knob: SamplingKnob,
    v: f64,
    range: &std::ops::RangeInclusive<f64>,
) -> Result<(), ConfigError> {
    if v.is_finite() && range.contains(&v) {
        return Ok(());
    }
    Err(ConfigError::SamplingOutOfRange {
        knob,
        value: v,
        min: *range.start(),
        max: *range.end(),
    })
}

impl Config {
    /// Checks every knob against its range (see the module docs), in the config's
    /// order; the first one out of range is the error.
    pub fn validate(&self) -> Result<(), ConfigError> {
        for &knob in Knob::ALL {
            if let Some(value) = knob.value(self) {
                check(knob, value, self.range_of(knob))?;
            }
            // The grid's size bounds the search's work and memory, whatever its sides.
            if knob == Knob::PlacementGridY
                && grid_size(&self.placement).is_none_or(|n| n > MAX_TRANSFORMS)
            {
                return Err(ConfigError::TooManyTransforms {
                    grid_x: self.placement.grid_x,
                    grid_y: self.placement.grid_y,
                    max: MAX_TRANSFORMS,
                });
            }
        }
        Ok(())
    }

    /// The values `knob` accepts in this config: its table's range, narrowed where
    /// another knob bounds it.
    pub(crate) fn range_of(&self, knob: Knob) -> Range {
        match (knob, knob.range(), self.detect.split) {
            // The lattice reaches down from the top: an extent above the level would
            // shrink it below the top it is meant to cover.
            (Knob::DetectSplitExtent, Range::Real { min, max, unit }, Some(split)) => Range::Real {
                min,
                max: max.min(split.level),
                unit,
            },
            (_, range, _) => range,
        }
    }

    /// [`Config::validate`], then the values derived at `sampling` for a recording of
    /// `rows x cols` cells: the rate and pitch themselves, the blur kernel, the
    /// upsampled frame, the link gate and the low-pass against the Nyquist frequency.
    pub fn validate_for(
        &self,
        sampling: &Sampling,
        (rows, cols): (usize, usize),
    ) -> Result<(), ConfigError> {
        self.validate()?;
        // The same ranges a file's own metadata must meet (one source for each fact).
        sampled(SamplingKnob::RateHz, sampling.rate_hz, &RATE_HZ_RANGE)?;
        sampled(SamplingKnob::PitchMm, sampling.pitch_mm, &PITCH_MM_RANGE)?;
        let derived = |knob, value, limit| ConfigError::Derived {
            knob,
            value,
            sampling: *sampling,
            limit,
        };
        let p = &self.preprocess;
        // scipy's kernel radius, as the blur computes it.
        let radius = (p.blur_truncate * sampling.px(p.blur_sigma_mm) + 0.5).floor();
        // A kernel that does not reach half an upsampled cell leaves pixels that see only
        // their own cell: the cell's flat top survives the blur, every pixel of it is a
        // local maximum, and the flow solver drowns in detections (minutes, gigabytes).
        let min_radius = (p.upsample as f64 / 2.0).ceil();
        if radius < min_radius {
            return Err(derived(
                Knob::PreprocessBlurSigmaMm,
                p.blur_sigma_mm,
                DerivedLimit::KernelTooNarrow {
                    radius_px: radius,
                    truncate: p.blur_truncate,
                    min_px: min_radius,
                },
            ));
        }
        if radius > MAX_KERNEL_RADIUS_PX {
            return Err(derived(
                Knob::PreprocessBlurSigmaMm,
                p.blur_sigma_mm,
                DerivedLimit::KernelTooWide {
                    radius_px: radius,
                    max_px: MAX_KERNEL_RADIUS_PX,
                },
            ));
        }
        let side = rows.max(cols).saturating_mul(p.upsample);
        if side > MAX_FRAME_PX {
            return Err(derived(
                Knob::PreprocessUpsample,
                p.upsample as f64,
                DerivedLimit::FrameTooLarge {
                    side_px: side,
                    rows,
                    cols,
                    max_px: MAX_FRAME_PX,
                },
            ));
        }
        let gate = sampling.gate_px2(self.track.max_speed_mm_s).sqrt();
        if gate > MAX_GATE_PX {
            return Err(derived(
                Knob::TrackMaxSpeedMmS,
                self.track.max_speed_mm_s,
                DerivedLimit::GateTooWide {
                    gate_px: gate,
                    max_px: MAX_GATE_PX,
                },
            ));
        }
        let nyquist = sampling.rate_hz / 2.0;
        if self.signal.lowpass_hz >= nyquist {
            return Err(derived(
                Knob::SignalLowpassHz,
                self.signal.lowpass_hz,
                DerivedLimit::AboveNyquist {
                    nyquist_hz: nyquist,
                },
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Split;

    #[test]
    fn every_preset_is_valid() {
        for p in crate::config::Preset::ALL {
            let c = Config::preset(p);
            c.validate_for(&Sampling::PAPER, (8, 21)).unwrap();
        }
    }

    /// The split's extent reaches down from its level: the level is its largest value,
    /// whatever the table's own bound.
    #[test]
    fn the_extent_is_held_below_the_level() {
        for extent in [0.75, 2.0] {
            let mut c = Config::default();
            c.detect.split = Some(Split {
                level: 0.5,
                extent: Some(extent),
                ..Split::LATTICE
            });
            assert_eq!(
                c.validate(),
                Err(ConfigError::OutOfRange {
                    knob: Knob::DetectSplitExtent,
                    value: extent,
                    min: 1e-6,
                    max: 0.5,
                    unit: Unit::None,
                })
            );
        }
    }

    #[test]
    fn the_error_holds_knob_value_and_range() {
        let mut c = Config::default();
        c.detect.sigma_k = f64::NAN;
        match c.validate() {
            Err(ConfigError::OutOfRange {
                knob: Knob::DetectSigmaK,
                value,
                min: -10.0,
                max: 10.0,
                unit: Unit::StandardDeviations,
            }) if value.is_nan() => {}
            other => panic!("{other:?}"),
        }
        let mut c = Config::default();
        c.signal.lowpass_hz = 10.0;
        assert_eq!(
            c.validate_for(&Sampling::PAPER, (8, 21)),
            Err(ConfigError::Derived {
                knob: Knob::SignalLowpassHz,
                value: 10.0,
                sampling: Sampling::PAPER,
                limit: DerivedLimit::AboveNyquist { nyquist_hz: 10.0 },
            })
        );
    }
}
