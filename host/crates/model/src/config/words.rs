//! A layer in error or a knob out of range in words: [`ConfigError`]'s `Display`, in the
//! terms of the config file (`section.key`, the range and its unit). The command line
//! words the layers by its flags, and adds the flag that sets a knob where one does.

use std::fmt;

use super::{ConfigError, DerivedLimit, Knob, OffTable, Preset, SamplingKnob, Unit};
use crate::display::Shortest;

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConfigError::Preset { preset, message } => write!(
                f,
                "the {} preset does not serialise as TOML: {message}",
                preset.name()
            ),
            ConfigError::File { name, .. } => write!(f, "{name}: invalid config"),
            ConfigError::AssignmentSyntax { assignment } => {
                write!(f, "`{assignment}`: expected SECTION.KEY=VALUE")
            }
            ConfigError::AssignmentValue { assignment, .. } => {
                write!(f, "`{assignment}`: not a TOML value")
            }
            ConfigError::Keys {
                assignments,
                off,
                preset,
                ..
            } => keys_words(f, assignments, off, *preset),
            ConfigError::OutOfRange {
                knob,
                value,
                min,
                max,
                unit,
            } => write!(
                f,
                "{knob} = {} is out of range: must be finite, in [{}, {}]{}",
                Shortest(*value),
                Shortest(*min),
                Shortest(*max),
                unit_suffix(*unit)
            ),
            ConfigError::CountOutOfRange {
                knob,
                value,
                min,
                max,
            } => write!(
                f,
                "{knob} = {value} is out of range: must be in [{min}, {max}]"
            ),
            ConfigError::LengthOutOfRange {
                knob,
                len,
                min,
                max,
            } => write!(
                f,
                "{knob} (count) = {len} is out of range: must be in [{min}, {max}]"
            ),
            ConfigError::TooManyTransforms {
                grid_x,
                grid_y,
                max,
            } => write!(
                f,
                "{} * grid_y * (grid_y + 1) / 2 = {grid_x} x {grid_y} is out of range: must be \
                 at most {max} transforms",
                Knob::PlacementGridX
            ),
            ConfigError::SamplingOutOfRange {
                knob,
                value,
                min,
                max,
            } => write!(
                f,
                "{knob} = {} is out of range: must be finite, in [{}, {}]{}",
                Shortest(*value),
                Shortest(*min),
                Shortest(*max),
                unit_suffix(match knob {
                    SamplingKnob::RateHz => Unit::Hz,
                    SamplingKnob::PitchMm => Unit::Mm,
                })
            ),
            ConfigError::Derived {
                knob,
                value,
                sampling,
                limit,
            } => {
                let (derived, range) = derived_words(*limit);
                write!(
                    f,
                    "{knob} = {} is {derived} at {} Hz, {} mm cells, x{}: must be {range}",
                    Shortest(*value),
                    sampling.rate_hz,
                    sampling.pitch_mm,
                    sampling.upsample
                )
            }
        }
    }
}

/// Keys laid over `preset` that do not make a config: the assignments given (any may be
/// the one), and the tables among them that the preset leaves out.
fn keys_words(
    f: &mut fmt::Formatter<'_>,
    assignments: &[String],
    off: &[OffTable],
    preset: Preset,
) -> fmt::Result {
    for (i, a) in assignments.iter().enumerate() {
        write!(f, "{}`{a}`", if i == 0 { "" } else { ", " })?;
    }
    let sep = if assignments.is_empty() { "" } else { ": " };
    write!(f, "{sep}invalid parameter")?;
    for t in off {
        write!(f, "; {}", off_words(t, preset))?;
    }
    Ok(())
}

/// Why an assignment into a table `preset` leaves out cannot be taken alone, and what
/// would do.
fn off_words(t: &OffTable, preset: Preset) -> String {
    format!(
        "`{}` is off under the {} preset: set its keys ({}) or start from the {} preset",
        t.table,
        preset.name(),
        t.keys.join(", "),
        Preset::default().name()
    )
}

/// What a knob became at the recording's sampling, and the bound it had to meet.
fn derived_words(limit: DerivedLimit) -> (String, String) {
    match limit {
        DerivedLimit::KernelTooNarrow {
            radius_px,
            truncate,
            min_px,
        } => (
            format!("a kernel radius of {radius_px} px (truncate {truncate})"),
            format!("at least {min_px} px, half an upsampled cell"),
        ),
        DerivedLimit::KernelTooWide { radius_px, max_px } => (
            format!("a kernel radius of {radius_px:.0} px"),
            format!("at most {max_px} px"),
        ),
        DerivedLimit::FrameTooLarge {
            side_px,
            rows,
            cols,
            max_px,
        } => (
            format!("{side_px} px along the longer side of {rows} x {cols} cells"),
            format!("at most {max_px} px"),
        ),
        DerivedLimit::GateTooWide { gate_px, max_px } => (
            format!("{gate_px:.0} px per frame"),
            format!("at most {max_px} px"),
        ),
        DerivedLimit::AboveNyquist { nyquist_hz } => (
            "the low-pass cut-off".to_string(),
            format!("below the Nyquist frequency, {nyquist_hz} Hz"),
        ),
    }
}

/// A range's unit as it follows the range (`[0, 60] s`).
fn unit_suffix(unit: Unit) -> &'static str {
    match unit {
        Unit::None => "",
        Unit::Hz => " Hz",
        Unit::Mm => " mm",
        Unit::S => " s",
        Unit::Psi => " psi",
        Unit::Sigmas => " sigmas",
        Unit::StandardDeviations => " standard deviations",
        Unit::MmPerS => " mm/s",
        Unit::A => " A",
        Unit::FullScale => " of full scale",
        Unit::BytesPerS => " B/s",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Sampling;

    /// A layer in error in the config file's words, naming no command-line flag: the
    /// layer, then (as the error's source) what TOML or serde said.
    #[test]
    fn every_layer_error_reads_without_flags() {
        use crate::config::{Layers, Preset};
        let file = Layers::new(Preset::Touch)
            .file("mine.toml", "[detect")
            .build();
        let value = Layers::new(Preset::Touch).set("detect.sigma_k=one").build();
        let keys = Layers::new(Preset::Paper)
            .set("track.regions.seed_psi=0.1")
            .build();
        let words: Vec<String> = [file, value, keys]
            .into_iter()
            .map(|r| r.unwrap_err().to_string())
            .collect();
        assert_eq!(
            words,
            [
                "mine.toml: invalid config",
                "`detect.sigma_k=one`: not a TOML value",
                "`track.regions.seed_psi=0.1`: invalid parameter; `track.regions` is off under \
                 the paper preset: set its keys (footprint_psi, join_cells, seed_psi) or start \
                 from the touch preset",
            ]
        );
        assert!(words.iter().all(|w| !w.contains("--")), "{words:?}");
    }

    /// Each error in its words.
    #[test]
    fn every_config_error_reads_in_the_config_files_words() {
        let at = Sampling {
            upsample: 32,
            ..Sampling::PAPER
        };
        let cases = [
            (
                ConfigError::OutOfRange {
                    knob: Knob::CropTimeMarginS,
                    value: 1e308,
                    min: 0.0,
                    max: 60.0,
                    unit: Unit::S,
                },
                "crop.time_margin_s = 1e308 is out of range: must be finite, in [0, 60] s",
            ),
            (
                ConfigError::OutOfRange {
                    knob: Knob::KeyframesMaxRmsErrorFs,
                    value: f64::NAN,
                    min: 1e-6,
                    max: 1.0,
                    unit: Unit::FullScale,
                },
                "keyframes.max_rms_error_fs = NaN is out of range: must be finite, in [0.000001, \
                 1] of full scale",
            ),
            (
                ConfigError::CountOutOfRange {
                    knob: Knob::PreprocessUpsample,
                    value: 300,
                    min: 1,
                    max: 32,
                },
                "preprocess.upsample = 300 is out of range: must be in [1, 32]",
            ),
            (
                ConfigError::LengthOutOfRange {
                    knob: Knob::KeyframesPeriodsMs,
                    len: 0,
                    min: 1,
                    max: 1000,
                },
                "keyframes.periods_ms (count) = 0 is out of range: must be in [1, 1000]",
            ),
            (
                ConfigError::TooManyTransforms {
                    grid_x: 1000,
                    grid_y: 1000,
                    max: 20_000_000,
                },
                "placement.grid_x * grid_y * (grid_y + 1) / 2 = 1000 x 1000 is out of range: \
                 must be at most 20000000 transforms",
            ),
            (
                ConfigError::SamplingOutOfRange {
                    knob: SamplingKnob::RateHz,
                    value: 5000.0,
                    min: 1.0,
                    max: 1000.0,
                },
                "rate_hz = 5000 is out of range: must be finite, in [1, 1000] Hz",
            ),
            (
                ConfigError::Derived {
                    knob: Knob::PreprocessBlurSigmaMm,
                    value: 0.01,
                    sampling: Sampling::PAPER,
                    limit: DerivedLimit::KernelTooNarrow {
                        radius_px: 0.0,
                        truncate: 4.0,
                        min_px: 4.0,
                    },
                },
                "preprocess.blur_sigma_mm = 0.01 is a kernel radius of 0 px (truncate 4) at 20 \
                 Hz, 25.4 mm cells, x7: must be at least 4 px, half an upsampled cell",
            ),
            (
                ConfigError::Derived {
                    knob: Knob::PreprocessUpsample,
                    value: 32.0,
                    sampling: at,
                    limit: DerivedLimit::FrameTooLarge {
                        side_px: 6400,
                        rows: 8,
                        cols: 200,
                        max_px: 4096,
                    },
                },
                "preprocess.upsample = 32 is 6400 px along the longer side of 8 x 200 cells at \
                 20 Hz, 25.4 mm cells, x32: must be at most 4096 px",
            ),
            (
                ConfigError::Derived {
                    knob: Knob::TrackMaxSpeedMmS,
                    value: 20000.0,
                    sampling: at,
                    limit: DerivedLimit::GateTooWide {
                        gate_px: 4999.6,
                        max_px: 4096.0,
                    },
                },
                "track.max_speed_mm_s = 20000 is 5000 px per frame at 20 Hz, 25.4 mm cells, \
                 x32: must be at most 4096 px",
            ),
        ];
        for (e, want) in cases {
            assert_eq!(e.to_string(), want, "{e:?}");
        }
    }
}
