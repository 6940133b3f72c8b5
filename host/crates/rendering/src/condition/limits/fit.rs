//! The fit: the largest factor in `[0, 1]` by which a signal passes the limits, and the
//! signal scaled by it.

use super::scan::{scan, Scanned};
use super::{check_scaled, validate_limits, LimitViolation, Limits};
use crate::condition::{CHANNELS, OUTPUT_RATE_HZ};

/// Scales `signal` down, in place, by the largest factor in `[0, 1]` that makes it pass
/// [`check_limits`](super::check_limits), and returns the factor (1 and no change when it already passes).
///
/// Peak and slew scale linearly, so the largest factor they allow is a ratio, found in
/// one pass. When the thermal bucket refuses that factor too, a root search below it
/// (Newton's method on the hottest bucket level, a few passes) finds
/// the largest passing factor to within 2^-32 (the bucket gets monotonically easier as
/// the scale shrinks, by induction over samples, and scale 0 always passes). The
/// returned factor is always one that was checked. Errors only for non-finite samples
/// or invalid limits.
///
/// ```
/// use touchc_rendering::condition::{check_limits, fit, Limits};
///
/// // 1.5 A on channel 0 after a gentle 100 ms rise: over the 1 A peak.
/// let mut signal: Vec<[f64; 8]> = (0..=100)
///     .map(|t| { let mut f = [0.0; 8]; f[0] = 0.015 * t as f64; f })
///     .chain((0..=100).rev().map(|t| { let mut f = [0.0; 8]; f[0] = 0.015 * t as f64; f }))
///     .collect();
/// assert!(check_limits(&signal, &Limits::default()).is_err());
/// let scale = fit(&mut signal, &Limits::default())?;
/// assert!((scale - 1.0 / 1.5).abs() < 1e-12);
/// assert_eq!(check_limits(&signal, &Limits::default()), Ok(()));
/// # Ok::<(), touchc_rendering::condition::LimitViolation>(())
/// ```
pub fn fit(signal: &mut [[f64; CHANNELS]], limits: &Limits) -> Result<f64, LimitViolation> {
    fit_to(signal, limits, 1.0, 0.0)
}

/// [`fit`], but a signal that breaks `limits` is fitted with room for what the
/// encoding and the player add to the heat: to `thermal_share` of the thermal budget
/// (`signal.fit_thermal_share`: the keyframes' error and the player's ramp-down
/// reserve), with the bucket leaking as if each sample carried `accounting_a` more
/// current (the player accounts each tick at its code's current rounded up,
/// [`touch_protocol::player::heat_accounting_margin_ua`]; at the peak that is
/// `2 accounting_a peak + accounting_a^2` more A^2 a second, which over an hour of
/// touch is a fifth of the budget, more than any fixed share leaves). Peak and slew
/// in full. A signal that passes `limits` is left alone, so the factor is 1 exactly
/// when [`fit`]'s is.
pub fn fit_to(
    signal: &mut [[f64; CHANNELS]],
    limits: &Limits,
    thermal_share: f64,
    accounting_a: f64,
) -> Result<f64, LimitViolation> {
    validate_limits(limits)?;
    if !(accounting_a.is_finite() && accounting_a >= 0.0) {
        return Err(LimitViolation::InvalidLimits {
            name: "accounting_a",
            value: accounting_a,
        });
    }
    let extra = accounting_a * (2.0 * limits.peak_a + accounting_a);
    let shared = &Limits {
        thermal_budget_a2s: limits.thermal_budget_a2s * thermal_share,
        continuous_a: (limits.continuous_a * limits.continuous_a - extra)
            .max(0.0)
            .sqrt(),
        ..*limits
    };
    validate_limits(shared)?;
    // One scan at scale 1 answers for both budgets when the leak is the same: the
    // budget only decides where a thermal violation is named, not the levels, and a
    // scan that did not stop breaks a budget exactly when its hottest level is above
    // it. A slower leak makes the levels higher, by at most `extra` a second of the
    // signal (a level is the heat of one stretch of it): a signal within the budget
    // there is within it at the real leak, one over it by more than that is over it at
    // the real leak too, and one between is scanned at the real leak.
    let at_one = scan(signal, 1.0, shared);
    if let Some(e @ LimitViolation::NotFinite { .. }) = at_one.violation {
        return Err(e);
    }
    let within = |level: f64| level <= limits.thermal_budget_a2s;
    // (With a margin for the sums' rounding: a scan too many costs time, not truth.)
    let seconds = signal.len() as f64 / OUTPUT_RATE_HZ;
    let maybe_within = extra > 0.0 && within(at_one.level - 1.001 * extra * seconds);
    if !at_one.stopped
        && (within(at_one.level) || (maybe_within && within(scan(signal, 1.0, limits).level)))
    {
        return Ok(1.0);
    }
    let linear = linear_limit(signal, shared);
    let at_linear = if linear == 1.0 && !at_one.stopped {
        at_one
    } else {
        scan(signal, linear, shared)
    };
    let lo = match at_linear.violation {
        None => linear,
        Some(LimitViolation::Thermal { .. }) => fit_thermal(signal, shared, linear, &at_linear),
        // Peak or slew refused by rounding at their own exact factor: bisect below it.
        Some(_) => bisect(|s| check_scaled(signal, s, shared).is_ok(), 0.0, linear),
    };
    scale_in_place(signal, lo);
    Ok(lo)
}

/// `signal *= scale`, in runs on the rayon pool (each sample's product is the same).
fn scale_in_place(signal: &mut [[f64; CHANNELS]], scale: f64) {
    use rayon::prelude::*;
    signal.par_chunks_mut(1 << 14).for_each(|run| {
        for v in run.iter_mut().flatten() {
            *v *= scale;
        }
    });
}

/// How close [`fit`] gets to the largest passing factor: within 2^-32 of it.
const FIT_TOLERANCE: f64 = 1.0 / 4_294_967_296.0;

/// The largest factor in `[lo, hi]` at which `passes`, for a `passes` true at `lo`, false
/// at `hi` and monotone in between, to within [`FIT_TOLERANCE`]: one that passed.
fn bisect(passes: impl Fn(f64) -> bool, mut lo: f64, mut hi: f64) -> f64 {
    while hi - lo > FIT_TOLERANCE {
        let mid = 0.5 * (lo + hi);
        if passes(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The largest factor below `hi` (which peak and slew allow, and at which the scan
/// found the bucket over the budget: `at_hi`) that keeps the bucket within the budget,
/// to within [`FIT_TOLERANCE`], and one that [`scan`] passed.
///
/// The hottest bucket level is convex in the square of the factor ([`Scanned::slope`]),
/// so Newton's step in that square from a failing factor lands at or above the root, and
/// on it where one stretch of heat decides the level on both: the failing end walks down
/// onto the root in a few scans (at an hour of touch 4 instead of regula falsi's 11).
/// Each step is kept half a tolerance inside the bracket, so a step that has all but
/// arrived tries just beside the root and ends the search. A step without a slope (a
/// failure by rounding at peak or slew) or past [`NEWTON_STEPS`] bisects instead, so the
/// search never takes more than those steps and bisection's 32.
fn fit_thermal(signal: &[[f64; CHANNELS]], limits: &Limits, hi: f64, at_hi: &Scanned) -> f64 {
    let (mut lo, mut hi) = (0.0_f64, hi);
    let (mut excess, mut slope) = (at_hi.level - limits.thermal_budget_a2s, at_hi.slope);
    let mut steps = 0;
    while hi - lo > FIT_TOLERANCE {
        let newton = (hi * hi - excess / slope).max(0.0).sqrt();
        let margin = 0.5 * FIT_TOLERANCE;
        // NaN (no slope) fails the test and bisects.
        let s = if steps < NEWTON_STEPS && newton >= 0.0 {
            newton.clamp(lo + margin, hi - margin)
        } else {
            0.5 * (lo + hi)
        };
        steps += 1;
        let scanned = scan(signal, s, limits);
        match scanned.violation {
            None => lo = s,
            Some(LimitViolation::Thermal { .. }) => {
                hi = s;
                (excess, slope) = (scanned.level - limits.thermal_budget_a2s, scanned.slope);
            }
            // Peak or slew by rounding below their factor: a failure without a level.
            Some(_) => {
                hi = s;
                slope = f64::NAN;
            }
        }
    }
    lo
}

/// Newton steps [`fit_thermal`] takes before it only bisects: a few more than a
/// recording needs (4 at an hour of touch).
const NEWTON_STEPS: usize = 12;

/// The largest factor in `[0, 1]` that peak and slew allow (both linear in the scale),
/// the steps from and back to 0 A included; 1 for a silent signal.
fn linear_limit(signal: &[[f64; CHANNELS]], limits: &Limits) -> f64 {
    use rayon::prelude::*;
    // Per channel, in lanes (vectorises; one chain of maxima does not), by runs on the
    // rayon pool: maxima are the same in any order. A comparison, not `f64::max`: the
    // same maximum of these finite values, in one instruction.
    let larger = |m: f64, v: f64| if v > m { v } else { m };
    const RUN: usize = 1 << 16;
    let (peak, step) = signal
        .par_chunks(RUN)
        .enumerate()
        .map(|(i, run)| {
            let mut peak = [0.0_f64; CHANNELS];
            let mut step = [0.0_f64; CHANNELS];
            // The step into a run is from the sample before it (0 A before the first).
            let mut previous = (i * RUN)
                .checked_sub(1)
                .map_or([0.0; CHANNELS], |before| signal[before]);
            for frame in run {
                for c in 0..CHANNELS {
                    peak[c] = larger(peak[c], frame[c].abs());
                    step[c] = larger(step[c], (frame[c] - previous[c]).abs());
                    previous[c] = frame[c];
                }
            }
            (
                peak.into_iter().fold(0.0, larger),
                step.into_iter().fold(0.0, larger),
            )
        })
        .reduce(|| (0.0, 0.0), |a, b| (larger(a.0, b.0), larger(a.1, b.1)));
    // The device rests at 0 A after playback: the last step is back to 0 A.
    let last = signal
        .last()
        .map_or(0.0, |f| f.iter().fold(0.0, |m, v| larger(m, v.abs())));
    let step = larger(step, last);
    let ratio = |limit: f64, value: f64| if value > 0.0 { limit / value } else { 1.0 };
    ratio(limits.peak_a, peak)
        .min(ratio(limits.slew_a_per_ms, step))
        .min(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The linear limit by runs on the pool is the plain loop's, wherever the largest
    /// step falls: inside a run, across the boundary between two, into the first
    /// sample, or back to 0 A after the last.
    #[test]
    fn linear_limit_by_runs_is_the_plain_loops() {
        let plain = |signal: &[[f64; CHANNELS]], limits: &Limits| {
            let (mut peak, mut step, mut previous) = (0.0_f64, 0.0_f64, [0.0; CHANNELS]);
            for frame in signal.iter().chain(std::iter::once(&[0.0; CHANNELS])) {
                for c in 0..CHANNELS {
                    peak = peak.max(frame[c].abs());
                    step = step.max((frame[c] - previous[c]).abs());
                    previous[c] = frame[c];
                }
            }
            (limits.peak_a / peak)
                .min(limits.slew_a_per_ms / step)
                .min(1.0)
        };
        let n = 3 * 65_536 + 17;
        let base: Vec<[f64; CHANNELS]> = (0..n)
            .map(|t| std::array::from_fn(|c| 0.3 * ((t as f64) * 1e-3 + c as f64).sin()))
            .collect();
        let limits = Limits::default();
        for (at, jump) in [
            (1000, 0.2),
            (65_536, 0.3),
            (2 * 65_536, -0.25),
            (0, 0.2),
            (n - 1, 0.4),
        ] {
            let mut signal = base.clone();
            signal[at][3] += jump;
            let got = linear_limit(&signal, &limits);
            assert_eq!(
                got.to_bits(),
                plain(&signal, &limits).to_bits(),
                "jump at {at}"
            );
            assert!(got < 1.0, "jump at {at}: {got}");
        }
    }
}
