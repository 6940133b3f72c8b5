//! The bounds the player holds the outputs to: the peak and slew limits made safe
//! for rounding to codes, and the heat at which it stops playing the signal so
//! that the ramp down still fits the thermal budget.

use crate::thermal::budget_ma2ms;
use crate::Limits;

/// The current the code for `ua_abs` stands for, rounded up to a whole mA.
// `(x + 999) / 1000` is one multiply and shift on the Cortex-M4; `div_ceil` adds a
// remainder test that cost 50 instructions in the worst tick.
#[allow(clippy::manual_div_ceil)]
#[inline(always)]
pub(super) fn accounted_ma(ua_abs: u32, half_step_ua: u32) -> u64 {
    u64::from((ua_abs + half_step_ua + 999) / 1000)
}

/// The slew bound the player enforces, uA per tick: the limit less one output step.
///
/// Two values `d` apart round to codes at most `d / step + 1` apart, so values kept
/// `slew - step` apart give code steps below `slew / step`: the limit holds on the
/// codes, not only on the values they were rounded from (a full-scale step of
/// 50 mA/ms would otherwise round to 103 codes, 50.3 mA).
pub fn slew_bound_ua(slew_ma_per_ms: u16, step_ua: u32) -> i32 {
    (i32::from(slew_ma_per_ms) * 1000 - step_ua as i32).max(0)
}

/// The peak bound the player enforces, uA: the limit rounded down to the current of
/// a whole output code, so the code a value at the bound rounds to stands for no more
/// than the limit (at 1 A full scale the sleeve's 1 A is a whole code already; a
/// 10 mA peak on a 0.1 A scale would otherwise round to 8 codes, 0.39 mA over).
pub fn peak_bound_ua(peak_ma: u16, device_full_scale_ua: i64) -> i32 {
    let fs = device_full_scale_ua.max(1);
    let codes = i64::from(peak_ma) * 1000 * 2048 / fs;
    (codes * fs / 2048).min(i64::from(peak_ma) * 1000) as i32
}

/// Heat above which the player plays no further signal tick, mA^2 ms: the budget
/// less the most that one more tick and then a ramp down can add.
///
/// A ramp down from `|f| <= peak` never leaves `[-|f|, |f|]` and ends within
/// `ramp_ms + ceil(peak / slew)` ticks, so with the tick before it, it adds at most
/// `ramp_ms + ceil(peak / slew) + 1` times `acc(peak)^2`, where `acc` is the
/// accounted (rounded-up) current; the threshold keeps one tick more as margin. A
/// tick is played only when the heat before it is at most this, so a ramp down from
/// any played tick stays within the budget.
///
/// A budget below that reserve cannot carry a single tick: the player does not start
/// (see [`Player::with_thermal`](super::Player::with_thermal)).
pub(super) fn trip_ma2ms(
    limits: &Limits,
    peak_ua: i32,
    slew_ua: i32,
    ramp_ms: u32,
    half_step_ua: u32,
) -> u64 {
    budget_ma2ms(limits).saturating_sub(ramp_down_ma2ms(peak_ua, slew_ua, ramp_ms, half_step_ua))
}

/// The most one more tick, a ramp down and a tick of margin add, mA^2 ms.
pub(super) fn ramp_down_ma2ms(peak_ua: i32, slew_ua: i32, ramp_ms: u32, half_step_ua: u32) -> u64 {
    let peak = peak_ua.unsigned_abs();
    let acc = accounted_ma(peak, half_step_ua);
    let descent = u64::from(peak.div_ceil(slew_ua.unsigned_abs().max(1)));
    acc * acc * (u64::from(ramp_ms) + descent + 2)
}
