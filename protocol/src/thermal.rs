//! The coils' heat: one leaky I^2 t bucket per channel, owned by the device.
//!
//! A coil's temperature does not reset when a new stimulus starts, so the bucket is
//! not part of a [`crate::Player`]: the device keeps one [`Thermal`] for as long as it
//! is powered, moves it into each player it starts ([`crate::Player::with_thermal`]),
//! takes it back when the player is done ([`crate::Player::thermal`]) and cools it
//! with [`Thermal::idle_tick`] on every tick nothing plays. A fresh [`Thermal::COLD`]
//! is a coil at rest (the host simulation starts every render from it).
//!
//! Units: heat is the integral of `I^2 - continuous^2` in mA^2 ms, never below 0.

use crate::{Limits, CHANNELS};

/// Heat of the eight coils, mA^2 ms above the continuous rating (a leaky bucket per
/// channel that never drains below empty).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Thermal {
    pub(crate) heat: [u64; CHANNELS],
}

/// Why a start was refused: the coil has not cooled enough (see [`Thermal::check_start`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TooHot {
    /// The hottest channel.
    pub channel: u8,
    /// Its heat, per mille of the budget.
    pub permille: u16,
    /// Idle milliseconds until a start is accepted again.
    pub cooldown_ms: u32,
}

impl Thermal {
    /// Every coil at rest.
    pub const COLD: Thermal = Thermal {
        heat: [0; CHANNELS],
    };

    /// The heat of each channel, mA^2 ms above the continuous rating.
    pub fn heat_ma2ms(&self) -> [u64; CHANNELS] {
        self.heat
    }

    /// The coils with the heat [`Thermal::heat_ma2ms`] gave: a state read back
    /// from a copy (the firmware publishes the tick's heat as plain words).
    pub const fn from_heat_ma2ms(heat: [u64; CHANNELS]) -> Thermal {
        Thermal { heat }
    }

    /// The hottest channel and its heat, mA^2 ms.
    pub fn hottest(&self) -> (u8, u64) {
        let mut best = (0u8, self.heat[0]);
        for (c, &h) in self.heat.iter().enumerate().skip(1) {
            if h > best.1 {
                best = (c as u8, h);
            }
        }
        best
    }

    /// One millisecond at 0 A: every channel cools at the continuous rating.
    pub fn idle_tick(&mut self, limits: &Limits) {
        let cool = continuous_ma2(limits);
        for h in &mut self.heat {
            *h = h.saturating_sub(cool);
        }
    }

    /// One millisecond at `ma2` (mA^2) on channel `c`, cooling at `cool` (mA^2); returns
    /// the new heat.
    #[inline(always)]
    pub(crate) fn add(&mut self, c: usize, ma2: u64, cool: u64) -> u64 {
        let h = (self.heat[c] + ma2).saturating_sub(cool);
        self.heat[c] = h;
        h
    }

    /// A start is accepted only once every channel is at or below half the budget.
    ///
    /// The player never lets the heat pass the budget (it ramps down early enough,
    /// see `SPEC.md`), so this is not what keeps the coil safe; it is the hysteresis
    /// that makes a tripped coil cool for a while instead of playing a few
    /// milliseconds on every press: at the sleeve's 600 mA rating, half of the 30 A^2 s
    /// budget drains in 42 s.
    pub fn check_start(&self, limits: &Limits) -> Result<(), TooHot> {
        let budget = budget_ma2ms(limits);
        let rearm = budget / 2;
        let (channel, heat) = self.hottest();
        if heat <= rearm {
            return Ok(());
        }
        let cool = continuous_ma2(limits).max(1);
        let excess = heat - rearm;
        Err(TooHot {
            channel,
            permille: (heat.saturating_mul(1000) / budget.max(1)).min(u64::from(u16::MAX)) as u16,
            cooldown_ms: excess.div_ceil(cool).min(u64::from(u32::MAX)) as u32,
        })
    }
}

impl Default for Thermal {
    fn default() -> Self {
        Thermal::COLD
    }
}

/// The continuous rating squared, mA^2 (the bucket's leak per millisecond).
pub(crate) fn continuous_ma2(limits: &Limits) -> u64 {
    u64::from(limits.continuous_ma) * u64::from(limits.continuous_ma)
}

/// The budget in the bucket's unit, mA^2 ms.
pub(crate) fn budget_ma2ms(limits: &Limits) -> u64 {
    u64::from(limits.i2t_budget_ma2s) * 1000
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn idle_cools_at_the_rating_and_stops_at_empty() {
        let l = Limits::SLEEVE;
        let mut t = Thermal::COLD;
        t.add(3, 1_000_000, 0);
        t.idle_tick(&l);
        assert_eq!(t.heat_ma2ms()[3], 1_000_000 - 360_000);
        t.idle_tick(&l);
        t.idle_tick(&l);
        assert_eq!(t.heat_ma2ms(), [0; CHANNELS]);
    }

    #[test]
    fn a_hot_coil_refuses_a_start_until_half_cooled() {
        let l = Limits::SLEEVE;
        let mut t = Thermal::COLD;
        assert!(t.check_start(&l).is_ok());
        t.add(5, 30_000_000_000, 0);
        let e = t.check_start(&l).unwrap_err();
        assert_eq!((e.channel, e.permille), (5, 1000));
        // 15e9 mA^2 ms over the re-arm level at 360,000 mA^2 per ms.
        assert_eq!(e.cooldown_ms, 41_667);
        for _ in 0..e.cooldown_ms - 1 {
            t.idle_tick(&l);
        }
        assert!(t.check_start(&l).is_err());
        t.idle_tick(&l);
        assert!(t.check_start(&l).is_ok());
    }
}
