//! The safety limits of a conditioned signal: the check every stimulus passes before it
//! is encoded, and the fit that scales a signal down until it passes
//! (docs/hardware.md, "Safety").

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::CHANNELS;

mod fit;
mod scan;

pub use fit::{fit, fit_to};
use scan::scan;

/// Safety limits for a 1 kHz current signal, per channel (docs/hardware.md, "Safety"). The
/// firmware enforces the lower of its own and the stimulus's; the compiler checks here
/// first so that a stimulus never depends on being cut off.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Limits {
    /// Largest absolute current, A.
    pub peak_a: f64,
    /// Largest change between consecutive 1 kHz samples, A per ms.
    pub slew_a_per_ms: f64,
    /// Current the coil carries indefinitely, A (the thermal bucket leaks at its square).
    pub continuous_a: f64,
    /// Thermal budget, A^2 s: the bucket (integral of `I^2 - continuous_a^2`, never below
    /// 0) may not exceed it.
    pub thermal_budget_a2s: f64,
}

impl Default for Limits {
    /// The sleeve's hard limits, [`touch_protocol::Limits::SLEEVE`], in amperes: the
    /// compiler checks against the same numbers the firmware enforces.
    fn default() -> Self {
        touch_protocol::Limits::SLEEVE.into()
    }
}

impl From<touch_protocol::Limits> for Limits {
    fn from(l: touch_protocol::Limits) -> Self {
        Self {
            peak_a: f64::from(l.peak_ma) / 1e3,
            slew_a_per_ms: f64::from(l.slew_ma_per_ms) / 1e3,
            continuous_a: f64::from(l.continuous_ma) / 1e3,
            thermal_budget_a2s: f64::from(l.i2t_budget_ma2s) / 1e6,
        }
    }
}

/// A value over a limit, with the fewest decimals that still show it over (`30.00005`,
/// not the 17 digits of `30.000045740926335`, nor a rounded `30` that seems within it).
struct Beyond(f64, f64);

impl std::fmt::Display for Beyond {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let Beyond(value, limit) = *self;
        let shortest = value.to_string();
        if shortest.len() <= 8 {
            return f.write_str(&shortest);
        }
        for decimals in 0..=9 {
            let text = format!("{value:.decimals$}");
            if text.parse::<f64>().is_ok_and(|v| v.abs() > limit.abs()) {
                return f.write_str(&text);
            }
        }
        write!(f, "{value}")
    }
}

/// The first limit a signal breaks (earliest sample, then lowest channel), or why the
/// check could not run.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum LimitViolation {
    /// |I| above `peak_a`.
    #[error("channel {channel}, sample {sample}: {} A exceeds the {limit_a} A peak", Beyond(*.current_a, *.limit_a))]
    Peak {
        /// Channel.
        channel: usize,
        /// 1 kHz sample index.
        sample: usize,
        /// The current, A.
        current_a: f64,
        /// The limit, A.
        limit_a: f64,
    },
    /// A step between samples above `slew_a_per_ms`.
    #[error(
        "channel {channel}, sample {sample}: step of {} A exceeds {limit_a_per_ms} A/ms", Beyond(*.step_a, *.limit_a_per_ms)
    )]
    Slew {
        /// Channel.
        channel: usize,
        /// 1 kHz sample index the step arrives at (`len` for the final step to 0 A).
        sample: usize,
        /// Size of the step, A (absolute).
        step_a: f64,
        /// The limit, A per ms.
        limit_a_per_ms: f64,
    },
    /// The thermal bucket above `thermal_budget_a2s`.
    #[error(
        "channel {channel}, sample {sample}: thermal load {} A^2 s \
         exceeds {budget_a2s} A^2 s", Beyond(*.bucket_a2s, *.budget_a2s)
    )]
    Thermal {
        /// Channel.
        channel: usize,
        /// 1 kHz sample index.
        sample: usize,
        /// Bucket content, A^2 s.
        bucket_a2s: f64,
        /// The budget, A^2 s.
        budget_a2s: f64,
    },
    /// The signal holds a NaN or an infinity: no limit can vouch for it.
    #[error("channel {channel}, sample {sample}: current is not finite")]
    NotFinite {
        /// Channel.
        channel: usize,
        /// 1 kHz sample index.
        sample: usize,
    },
    /// A limit is negative, NaN or infinite.
    #[error("limit `{name}` = {} is not a finite, non-negative number", touchc_model::display::Shortest(*.value))]
    InvalidLimits {
        /// Field name.
        name: &'static str,
        /// Its value.
        value: f64,
    },
}

fn validate_limits(limits: &Limits) -> Result<(), LimitViolation> {
    let fields = [
        ("peak_a", limits.peak_a),
        ("slew_a_per_ms", limits.slew_a_per_ms),
        ("continuous_a", limits.continuous_a),
        ("thermal_budget_a2s", limits.thermal_budget_a2s),
    ];
    for (name, value) in fields {
        if !(value.is_finite() && value >= 0.0) {
            return Err(LimitViolation::InvalidLimits { name, value });
        }
    }
    Ok(())
}

/// The limit check of `scale * signal`, shared by [`check_limits`] (scale 1) and [`fit()`]
/// so that the factor `fit` returns is checked on exactly the numbers it produces.
fn check_scaled(
    signal: &[[f64; CHANNELS]],
    scale: f64,
    limits: &Limits,
) -> Result<(), LimitViolation> {
    match scan(signal, scale, limits).violation {
        Some(v) => Err(v),
        None => Ok(()),
    }
}

/// Checks a 1 kHz current signal (amperes, one `[f64; 8]` per ms) against `limits`.
///
/// The device sits at 0 A before and after playback, so the step from 0 A to the first
/// sample and from the last sample back to 0 A count as slew. The thermal bucket of each
/// channel starts empty, grows by `(I^2 - continuous_a^2) * 1 ms` per sample and never
/// drops below 0; it may not exceed `thermal_budget_a2s`.
pub fn check_limits(signal: &[[f64; CHANNELS]], limits: &Limits) -> Result<(), LimitViolation> {
    validate_limits(limits)?;
    check_scaled(signal, 1.0, limits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_value_over_its_limit_shows_the_fewest_decimals_that_are_still_over() {
        let thermal = LimitViolation::Thermal {
            channel: 5,
            sample: 30_000,
            bucket_a2s: 30.000045740926335,
            budget_a2s: 30.0,
        };
        assert_eq!(
            thermal.to_string(),
            "channel 5, sample 30000: thermal load 30.00005 A^2 s exceeds 30 A^2 s"
        );
        assert_eq!(Beyond(30.5, 30.0).to_string(), "30.5");
        assert_eq!(Beyond(-1.2500000001, 1.0).to_string(), "-1.3");
        assert_eq!(Beyond(-1.0000001, 1.0).to_string(), "-1.0000001");
    }
}
