//! Safety limits: what a stimulus was compiled for and what a device allows.

use serde::{Deserialize, Serialize};

/// Per-channel safety limits, in integer milliamperes.
///
/// A stimulus carries the limits it was compiled against; the firmware has its own
/// compiled-in hard limits; the player enforces the lower of the two
/// ([`Limits::min`]) on every tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Limits {
    /// Largest magnitude of the coil current, mA.
    pub peak_ma: u16,
    /// Largest change of the current between two 1 kHz ticks, mA per ms.
    pub slew_ma_per_ms: u16,
    /// Current the coil carries indefinitely without heating up, mA (RMS).
    pub continuous_ma: u16,
    /// Thermal budget: the integral of `I^2 - continuous^2` (a leaky bucket that
    /// never drains below empty) may not exceed this, in mA^2 * s.
    pub i2t_budget_ma2s: u32,
}

impl Limits {
    /// The sleeve's default hard limits (TEAX19C01-8 coils on LM675T amplifiers).
    ///
    /// The paper's signals span -0.9 A to +1 A with a 4 Hz low-pass: they peak at
    /// 1 A, slew below 30 mA/ms, and hold the -0.9 A pre-dent for the length of a
    /// touch. The coil is rated 3 W RMS into 8 ohm (0.61 A continuous); the budget
    /// of 30 A^2 s lets the pre-dent (0.45 A^2 over the rating) run for a minute.
    pub const SLEEVE: Limits = Limits {
        peak_ma: 1000,
        slew_ma_per_ms: 50,
        continuous_ma: 600,
        i2t_budget_ma2s: 30_000_000,
    };

    /// The field-wise stricter of two limit sets.
    pub const fn min(self, other: Limits) -> Limits {
        const fn min16(a: u16, b: u16) -> u16 {
            if a < b {
                a
            } else {
                b
            }
        }
        Limits {
            peak_ma: min16(self.peak_ma, other.peak_ma),
            slew_ma_per_ms: min16(self.slew_ma_per_ms, other.slew_ma_per_ms),
            continuous_ma: min16(self.continuous_ma, other.continuous_ma),
            i2t_budget_ma2s: if self.i2t_budget_ma2s < other.i2t_budget_ma2s {
                self.i2t_budget_ma2s
            } else {
                other.i2t_budget_ma2s
            },
        }
    }
}

impl Default for Limits {
    fn default() -> Self {
        Limits::SLEEVE
    }
}
