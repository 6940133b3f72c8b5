//! The knobs of [`Config`]: one table names each knob once, with its key in the config
//! file, where its value sits in a [`Config`] and the range [`Config::validate`] holds it
//! to.
//!
//! The serde field names are the config file's keys; a test walks the serialised
//! config of every preset and fails on a key the table lacks, a knob the config lacks,
//! and a knob whose value, set out of its range under its key, is not refused as that
//! knob. So a knob added in one place only does not pass the tests.

use std::fmt;
use std::ops::RangeInclusive;

use super::{
    Config, MAX_GRID_STEPS, MAX_TRAJECTORIES, MAX_TRANSFORMS, MAX_UPSAMPLE, PITCH_MM_RANGE,
    RATE_HZ_RANGE,
};

/// Declares [`Knob`] from one table of rows
/// `Variant => "section", "key", |config| value, range;`: the variant, its doc (the
/// key's path), its key, the value it reads from a [`Config`] and its [`Range`] come
/// from the same row.
macro_rules! knobs {
    ($($variant:ident => $section:literal, $key:literal, |$c:ident| $get:expr, $range:expr;)*) => {
        /// A knob of [`Config`], by its section and key.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        #[non_exhaustive]
        pub enum Knob {
            $(
                #[doc = concat!("`", $section, ".", $key, "`")]
                $variant,
            )*
        }

        impl Knob {
            /// Every knob, in the config's order: the order [`Config::validate`] checks them.
            pub const ALL: &'static [Knob] = &[$(Knob::$variant),*];

            /// The section of the config the knob is in (its TOML table).
            pub const fn section(self) -> &'static str {
                match self {
                    $(Knob::$variant => $section,)*
                }
            }

            /// The knob's key in its section (dotted below an optional table).
            pub const fn key(self) -> &'static str {
                match self {
                    $(Knob::$variant => $key,)*
                }
            }

            /// The values the knob accepts, before any other knob narrows them (see
            /// [`Config::range_of`]).
            pub(crate) const fn range(self) -> Range {
                match self {
                    $(Knob::$variant => $range,)*
                }
            }

            /// The knob's value in `config`; `None` for a knob under an optional table
            /// that `config` leaves out, and for a knob without a range ([`Range::Free`]).
            pub(crate) fn value(self, config: &Config) -> Option<Value<'_>> {
                match self {
                    $(Knob::$variant => {
                        let $c = config;
                        $get
                    })*
                }
            }
        }
    };
}

knobs! {
    InputRateHz => "input", "rate_hz", |c| real(c.input.rate_hz), reals(RATE_HZ_RANGE, Unit::Hz);
    InputPitchMm => "input", "pitch_mm",
        |c| real(c.input.pitch_mm), reals(PITCH_MM_RANGE, Unit::Mm);
    InputBaseline => "input", "baseline", |_c| None, Range::Free;
    InputTareS => "input", "tare_s", |c| real(c.input.tare_s), reals(0.0..=60.0, Unit::S);
    InputTrimS => "input", "trim_s", |c| real(c.input.trim_s), reals(0.0..=60.0, Unit::S);
    InputBaselineQuantile => "input", "baseline_quantile",
        |c| real(c.input.baseline_quantile), reals(0.0..=0.5, Unit::None);
    InputMinTouchReadings => "input", "min_touch_readings", |_c| None, Range::Free;
    InputTouchThresholdPsi => "input", "touch_threshold_psi",
        |c| real(c.input.touch_threshold_psi), reals(0.0..=1e300, Unit::Psi);
    PreprocessUpsample => "preprocess", "upsample",
        |c| count(c.preprocess.upsample), counts(1..=MAX_UPSAMPLE);
    PreprocessBlurSigmaMm => "preprocess", "blur_sigma_mm",
        |c| real(c.preprocess.blur_sigma_mm), reals(0.01..=500.0, Unit::Mm);
    PreprocessBlurTruncate => "preprocess", "blur_truncate",
        |c| real(c.preprocess.blur_truncate), reals(1.0..=10.0, Unit::Sigmas);
    // Thresholds bound no work; any finite scale of the data is a valid problem.
    DetectMinValuePsi => "detect", "min_value_psi",
        |c| real(c.detect.min_value_psi), reals(0.0..=1e300, Unit::Psi);
    DetectSigmaK => "detect", "sigma_k",
        |c| real(c.detect.sigma_k), reals(-10.0..=10.0, Unit::StandardDeviations);
    DetectMaxProbability => "detect", "max_probability",
        |c| real(c.detect.max_probability), reals(1e-6..=0.999_999, Unit::None);
    DetectSplitMinCells => "detect", "split.min_cells", |_c| None, Range::Free;
    DetectSplitLevel => "detect", "split.level",
        |c| c.detect.split.map(|s| Value::Real(s.level)), reals(1e-6..=1.0, Unit::None);
    DetectSplitSpacingCells => "detect", "split.spacing_cells", |_c| None, Range::Free;
    // At most `split.level` too: see `Config::range_of`.
    DetectSplitExtent => "detect", "split.extent",
        |c| c.detect.split.and_then(|s| s.extent).map(Value::Real), reals(1e-6..=1.0, Unit::None);
    TrackEntryCost => "track", "entry_cost",
        |c| real(c.track.entry_cost), reals(0.0..=1000.0, Unit::None);
    TrackExitCost => "track", "exit_cost",
        |c| real(c.track.exit_cost), reals(0.0..=1000.0, Unit::None);
    TrackMaxSpeedMmS => "track", "max_speed_mm_s",
        |c| real(c.track.max_speed_mm_s), reals(1.0..=20_000.0, Unit::MmPerS);
    TrackMaxTrajectories => "track", "max_trajectories",
        |c| count(c.track.max_trajectories), counts(1..=MAX_TRAJECTORIES);
    TrackBridgeMaxMissingS => "track", "bridge.max_missing_s", |_c| None, Range::Free;
    TrackBridgeCostPerMissing => "track", "bridge.cost_per_missing", |_c| None, Range::Free;
    TrackRegionsSeedPsi => "track", "regions.seed_psi",
        |c| c.track.regions.map(|r| Value::Real(r.seed_psi)), reals(0.0..=1e300, Unit::Psi);
    TrackRegionsFootprintPsi => "track", "regions.footprint_psi",
        |c| c.track.regions.map(|r| Value::Real(r.footprint_psi)), reals(0.0..=1e300, Unit::Psi);
    TrackRegionsJoinCells => "track", "regions.join_cells",
        |c| c.track.regions.map(|r| Value::Count(r.join_cells)), counts(1..=8);
    // With the grid's size: see `Config::validate`.
    PlacementGridX => "placement", "grid_x",
        |c| count(c.placement.grid_x), counts(1..=MAX_GRID_STEPS);
    PlacementGridY => "placement", "grid_y",
        |c| count(c.placement.grid_y), counts(1..=MAX_GRID_STEPS);
    PlacementCentreBonus => "placement", "centre_bonus",
        |c| real(c.placement.centre_bonus), reals(0.0..=10.0, Unit::None);
    PlacementCoarseToFineStride => "placement", "coarse_to_fine.stride",
        |c| c.placement.coarse_to_fine.map(|s| Value::Count(s.stride)), counts(1..=1000);
    PlacementCoarseToFineKeep => "placement", "coarse_to_fine.keep",
        |c| c.placement.coarse_to_fine.map(|s| Value::Count(s.keep)), counts(1..=MAX_TRANSFORMS);
    CropTimeMarginS => "crop", "time_margin_s",
        |c| real(c.crop.time_margin_s), reals(0.0..=60.0, Unit::S);
    CropSpaceMarginMm => "crop", "space_margin_mm",
        |c| real(c.crop.space_margin_mm), reals(0.0..=10_000.0, Unit::Mm);
    SignalSpikeFraction => "signal", "spike_fraction",
        |c| real(c.signal.spike_fraction), reals(0.0..=1.0, Unit::None);
    SignalLowpassOrder => "signal", "lowpass_order",
        |c| count(c.signal.lowpass_order), counts(1..=16);
    SignalLowpassHz => "signal", "lowpass_hz",
        |c| real(c.signal.lowpass_hz), reals(0.01..=500.0, Unit::Hz);
    SignalZeroPhase => "signal", "zero_phase", |_c| None, Range::Free;
    SignalRingOut => "signal", "ring_out", |_c| None, Range::Free;
    SignalPreDentA => "signal", "pre_dent_a",
        |c| real(c.signal.pre_dent_a), reals(-1.0..=1.0, Unit::A);
    SignalPeakA => "signal", "peak_a", |c| real(c.signal.peak_a), reals(-1.0..=1.0, Unit::A);
    SignalRampS => "signal", "ramp_s", |c| real(c.signal.ramp_s), reals(0.0..=60.0, Unit::S);
    SignalFitThermalShare => "signal", "fit_thermal_share",
        |c| real(c.signal.fit_thermal_share), reals(0.01..=1.0, Unit::None);
    KeyframesMaxRmsErrorFs => "keyframes", "max_rms_error_fs",
        |c| real(c.keyframes.max_rms_error_fs), reals(1e-6..=1.0, Unit::FullScale);
    KeyframesMaxAbsErrorFs => "keyframes", "max_abs_error_fs",
        |c| real(c.keyframes.max_abs_error_fs), reals(1e-6..=1.0, Unit::FullScale);
    KeyframesRampMs => "keyframes", "ramp_ms",
        |c| count(usize::from(c.keyframes.ramp_ms)), counts(0..=10_000);
    KeyframesAllocateAboveBytesPerS => "keyframes", "allocate_above_bytes_per_s",
        |c| real(c.keyframes.allocate_above_bytes_per_s), reals(0.0..=1e9, Unit::BytesPerS);
    KeyframesPeriodsMs => "keyframes", "periods_ms",
        |c| Some(Value::Counts(&c.keyframes.periods_ms)),
        Range::Counts { len: (1, 1000), each: (1, 1000) };
    KeyframesMaxQuantShift => "keyframes", "max_quant_shift",
        |c| count(usize::from(c.keyframes.max_quant_shift)), counts(0..=15);
}

impl fmt::Display for Knob {
    /// `section.key`, as in a config file's tables or `--set`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}", self.section(), self.key())
    }
}

/// The unit of a range.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Unit {
    /// A plain number.
    None,
    /// Hertz.
    Hz,
    /// Millimetres.
    Mm,
    /// Seconds.
    S,
    /// Pounds per square inch.
    Psi,
    /// Standard deviations of the blur.
    Sigmas,
    /// Standard deviations of the detection score.
    StandardDeviations,
    /// Millimetres per second.
    MmPerS,
    /// Amperes.
    A,
    /// A fraction of the player's full scale.
    FullScale,
    /// Bytes per second.
    BytesPerS,
}

/// The values a knob accepts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Range {
    /// A finite real number in `[min, max]`, in `unit`.
    Real { min: f64, max: f64, unit: Unit },
    /// A whole number in `[min, max]`.
    Count { min: usize, max: usize },
    /// A list of `len.0` to `len.1` whole numbers, each in `[each.0, each.1]`.
    Counts {
        len: (usize, usize),
        each: (usize, usize),
    },
    /// Any value of the knob's type: a choice or a switch, or a figure that every
    /// stage reading it copes with whatever it is.
    Free,
}

/// A knob's value in a config, as its range reads it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Value<'a> {
    /// A real number.
    Real(f64),
    /// A whole number.
    Count(usize),
    /// A list of whole numbers.
    Counts(&'a [u16]),
}

/// `[range]` in `unit`.
const fn reals(range: RangeInclusive<f64>, unit: Unit) -> Range {
    Range::Real {
        min: *range.start(),
        max: *range.end(),
        unit,
    }
}

/// `[range]` of whole numbers.
const fn counts(range: RangeInclusive<usize>) -> Range {
    Range::Count {
        min: *range.start(),
        max: *range.end(),
    }
}

/// A real knob's value.
fn real<'a>(v: f64) -> Option<Value<'a>> {
    Some(Value::Real(v))
}

/// A whole-number knob's value.
fn count<'a>(n: usize) -> Option<Value<'a>> {
    Some(Value::Count(n))
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeSet;

    use super::*;
    use crate::config::{Bridge, CoarseToFine, ConfigError, Preset, Regions, Split};

    /// Every preset, and one config holding every optional table (the lattice is set
    /// in no preset), so that every key appears in some config.
    fn configs() -> Vec<Config> {
        let mut full = Config::preset(Preset::Touch);
        full.detect.split = Some(Split::LATTICE);
        full.track.bridge = Some(Bridge {
            max_missing_s: 0.1,
            cost_per_missing: 0.5,
        });
        full.track.regions = Some(Regions {
            seed_psi: 0.08,
            footprint_psi: 0.03,
            join_cells: 2,
        });
        full.placement.coarse_to_fine = Some(CoarseToFine {
            stride: 2,
            keep: 32,
        });
        Preset::ALL
            .iter()
            .map(|&p| Config::preset(p))
            .chain([full])
            .collect()
    }

    /// The config with every optional table.
    fn full() -> Config {
        configs().pop().expect("configs")
    }

    /// The dotted path of every value in `table` that is not itself a table.
    fn leaves(prefix: &str, table: &toml::Table, out: &mut BTreeSet<String>) {
        for (key, value) in table {
            let path = if prefix.is_empty() {
                key.clone()
            } else {
                format!("{prefix}.{key}")
            };
            match value {
                toml::Value::Table(t) => leaves(&path, t, out),
                _ => {
                    out.insert(path);
                }
            }
        }
    }

    /// The value under `knob`'s section and key in `table`, to be written.
    fn slot(table: &mut toml::Table, knob: Knob) -> &mut toml::Value {
        let mut v = table.get_mut(knob.section()).expect("section");
        for part in knob.key().split('.') {
            v = v
                .as_table_mut()
                .and_then(|t| t.get_mut(part))
                .unwrap_or_else(|| panic!("{knob} is not a key"));
        }
        v
    }

    /// The config file's keys (the serde names of every preset's serialised config) and
    /// the table's knobs are the same set: a field added or renamed without its row, or
    /// a row without its field, fails here.
    #[test]
    fn every_key_of_the_config_is_a_knob_and_every_knob_a_key() {
        let mut keys = BTreeSet::new();
        for c in configs() {
            let table = toml::Table::try_from(c).expect("a config serialises");
            leaves("", &table, &mut keys);
        }
        let knobs: BTreeSet<String> = Knob::ALL.iter().map(|k| k.to_string()).collect();
        let unnamed: Vec<_> = keys.difference(&knobs).collect();
        assert!(
            unnamed.is_empty(),
            "keys of the config without a knob: {unnamed:?}"
        );
        let unkeyed: Vec<_> = knobs.difference(&keys).collect();
        assert!(
            unkeyed.is_empty(),
            "knobs that are no key of the config: {unkeyed:?}"
        );
        assert_eq!(knobs.len(), Knob::ALL.len(), "a knob is in the table twice");
    }

    /// Every knob with a range, set outside it under its own key in a config file, is
    /// refused as that knob: the row's value reads the field serde names by its key, and
    /// validation holds it to the row's range.
    #[test]
    fn every_knob_out_of_its_range_under_its_key_is_refused_as_that_knob() {
        let base = toml::Table::try_from(full()).expect("a config serialises");
        for &knob in Knob::ALL {
            let bad = match knob.range() {
                Range::Free => {
                    assert_eq!(knob.value(&full()), None, "{knob} is free but read");
                    continue;
                }
                Range::Real { .. } => toml::Value::Float(f64::NAN),
                Range::Count { min, max } => {
                    let n = if min > 0 { min - 1 } else { max + 1 };
                    toml::Value::Integer(i64::try_from(n).expect("a small bound"))
                }
                Range::Counts { .. } => toml::Value::Array(Vec::new()),
            };
            let mut table = base.clone();
            *slot(&mut table, knob) = bad.clone();
            let config: Config = table
                .try_into()
                .unwrap_or_else(|e| panic!("{knob} = {bad}: {e}"));
            let refused = match config.validate() {
                Err(
                    ConfigError::OutOfRange { knob, .. }
                    | ConfigError::CountOutOfRange { knob, .. }
                    | ConfigError::LengthOutOfRange { knob, .. },
                ) => Some(knob),
                _ => None,
            };
            assert_eq!(refused, Some(knob), "{knob} = {bad}");
        }
    }

    /// A knob's value is of its range's kind (else validation would pass it unchecked).
    #[test]
    fn every_knob_reads_a_value_of_its_ranges_kind() {
        let config = full();
        for &knob in Knob::ALL {
            let value = knob.value(&config);
            let fits = matches!(
                (value, knob.range()),
                (None, Range::Free)
                    | (Some(Value::Real(_)), Range::Real { .. })
                    | (Some(Value::Count(_)), Range::Count { .. })
                    | (Some(Value::Counts(_)), Range::Counts { .. })
            );
            assert!(fits, "{knob}: {value:?} against {:?}", knob.range());
        }
    }
}
