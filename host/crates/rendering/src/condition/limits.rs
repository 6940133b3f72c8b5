//! The safety limits of a conditioned signal: the check every stimulus passes before it
//! is encoded, and the fit that scales a signal down until it passes
//! (docs/hardware.md, "Safety").

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::{CHANNELS, OUTPUT_RATE_HZ};

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

/// The first limit a signal breaks (earliest sample, then lowest channel), or why the
/// check could not run.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum LimitViolation {
    /// |I| above `peak_a`.
    #[error("channel {channel}, sample {sample}: {current_a} A exceeds the {limit_a} A peak")]
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
        "channel {channel}, sample {sample}: step of {step_a} A exceeds {limit_a_per_ms} A/ms"
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
        "channel {channel}, sample {sample}: thermal load {bucket_a2s} A^2 s \
         exceeds {budget_a2s} A^2 s"
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

/// The limit check of `scale * signal`, shared by [`check_limits`] (scale 1) and [`fit`]
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

/// Scans `scale * signal`: the first violation in time order (sample by sample, channel
/// by channel), if any, and the highest thermal bucket level reached. A peak, slew or
/// non-finite violation stops the scan; a thermal one does not, so that the level says
/// how far over the budget the whole signal goes ([`fit`] steers by it, with its slope).
///
/// [`fit`] scans an hour of signal several times, so the scan runs in blocks of
/// [`SCAN_BLOCK`] samples: each block first in lanes, the channels at once with no
/// branch per sample ([`Scan::block_passes`]), and only a block in which something is
/// to be reported (a broken peak or slew, a non-finite sample, the first bucket over
/// the budget) again from its start, sample by sample and channel by channel
/// ([`Scan::walk`]), to name the first violation. Both update the buckets with the same
/// operations in the same order, so the levels are the same numbers either way.
///
/// The channels do not interact, so on a pool of several threads channels 0-3 and 4-7
/// are scanned at once ([`scan_halves`]); the result is the one-thread scan's, bit for
/// bit.
fn scan(signal: &[[f64; CHANNELS]], scale: f64, limits: &Limits) -> Scanned {
    if rayon::current_num_threads() > 1 {
        scan_halves(signal, scale, limits)
    } else {
        scan_whole(signal, scale, limits)
    }
}

/// [`scan`] of all eight channels in one pass.
fn scan_whole(signal: &[[f64; CHANNELS]], scale: f64, limits: &Limits) -> Scanned {
    let (state, stop) = run_scan::<0, CHANNELS>(signal, scale, limits);
    Scanned::of(state.hottest(), state.thermal, stop)
}

/// [`scan`] as two halves of four channels on two threads, merged into what one scan of
/// all eight reports. A peak, slew or non-finite violation in either half stops the
/// whole scan at that sample and channel, which the other half ran past: the rare scan
/// that stops is then done again whole, so that its level ends where it stopped.
fn scan_halves(signal: &[[f64; CHANNELS]], scale: f64, limits: &Limits) -> Scanned {
    const HALF: usize = CHANNELS / 2;
    let ((low, low_stop), (high, high_stop)) = rayon::join(
        || run_scan::<0, HALF>(signal, scale, limits),
        || run_scan::<HALF, HALF>(signal, scale, limits),
    );
    if low_stop.is_some() || high_stop.is_some() {
        return scan_whole(signal, scale, limits);
    }
    // The first thermal violation in (sample, channel) order; the hottest channel, the
    // lower one on a tie (as one scan's fold over the channels picks it).
    let (l, h) = (low.hottest(), high.hottest());
    let thermal = match (low.thermal, high.thermal) {
        (Some(a), Some(b)) => Some(if first_sample(&b) < first_sample(&a) {
            b
        } else {
            a
        }),
        (a, b) => a.or(b),
    };
    Scanned::of(if h.hottest > l.hottest { h } else { l }, thermal, None)
}

/// [`Scan::run`], in its AVX2 build when the CPU runs AVX2 (the same numbers, see
/// [`touchc_wide`]).
fn run_scan<const FIRST: usize, const N: usize>(
    signal: &[[f64; CHANNELS]],
    scale: f64,
    limits: &Limits,
) -> (Scan<FIRST, N>, Option<LimitViolation>) {
    #[cfg(target_arch = "x86_64")]
    {
        if touchc_wide::avx2() {
            // SAFETY: the CPU runs AVX2 (checked just above).
            return unsafe { run_scan_avx2(signal, scale, limits) };
        }
    }
    Scan::run(signal, scale, limits)
}

/// [`Scan::run`] compiled for AVX2.
///
/// # Safety
/// Only on a CPU that runs AVX2 ([`touchc_wide::avx2`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn run_scan_avx2<const FIRST: usize, const N: usize>(
    signal: &[[f64; CHANNELS]],
    scale: f64,
    limits: &Limits,
) -> (Scan<FIRST, N>, Option<LimitViolation>) {
    Scan::run(signal, scale, limits)
}

/// The sample a violation names (the channel breaks ties: halves never share one).
fn first_sample(v: &LimitViolation) -> usize {
    match v {
        LimitViolation::Peak { sample, .. }
        | LimitViolation::Slew { sample, .. }
        | LimitViolation::Thermal { sample, .. }
        | LimitViolation::NotFinite { sample, .. } => *sample,
        LimitViolation::InvalidLimits { .. } => usize::MAX,
    }
}

/// Samples [`scan`] checks in lanes before it looks for what to report: long enough
/// that the block's one test is nothing beside its samples, short enough that walking
/// a block again costs nothing.
const SCAN_BLOCK: usize = 256;

/// What [`scan`] found.
#[derive(Debug, Clone, PartialEq)]
struct Scanned {
    /// The first thermal violation if there was one, else the first peak, slew or
    /// non-finite one (which stopped the scan).
    violation: Option<LimitViolation>,
    /// Whether a peak, slew or non-finite violation stopped the scan (the level is then
    /// that of the samples before it).
    stopped: bool,
    /// The highest bucket level of any channel, A^2 s.
    level: f64,
    /// How fast that level grows with the square of the scale, A^2 s: 1 ms times the sum
    /// of the unscaled current squared over the stretch that filled that bucket (from
    /// its last time at 0). The level is the largest over stretches of
    /// `(scale^2 x^2 - leak) 1 ms` summed, so it is convex in the square of the scale
    /// and this is its slope there.
    slope: f64,
}

impl Scanned {
    /// The scan's report from its hottest channel, its first thermal violation and
    /// what stopped it.
    fn of(hottest: Heat, thermal: Option<LimitViolation>, stop: Option<LimitViolation>) -> Self {
        Scanned {
            stopped: stop.is_some(),
            violation: thermal.or(stop),
            level: hottest.hottest,
            slope: hottest.hottest_run * (1.0 / OUTPUT_RATE_HZ),
        }
    }
}

/// [`scan`]'s state between samples, for the `N` channels from `FIRST` on.
#[derive(Clone)]
struct Scan<const FIRST: usize, const N: usize> {
    /// The last sample's currents (0 A before the first).
    previous: [f64; N],
    heat: [Heat; N],
    /// The first thermal violation, once there is one.
    thermal: Option<LimitViolation>,
}

/// One channel's thermal bucket as [`scan`] follows it.
#[derive(Debug, Clone, Copy, Default)]
struct Heat {
    /// The bucket, A^2 s.
    bucket: f64,
    /// Its highest level so far.
    hottest: f64,
    /// Sum of the unscaled current squared since the bucket was last at 0.
    run: f64,
    /// `run` when the bucket was at its highest.
    hottest_run: f64,
}

impl Heat {
    /// One 1 ms sample: `x` unscaled, `scale * x` the current.
    #[inline(always)]
    fn take(&mut self, x: f64, scale: f64, leak: f64) {
        self.bucket = heat(self.bucket, scale * x, leak);
        self.run = if self.bucket > 0.0 {
            self.run + x * x
        } else {
            0.0
        };
        let higher = self.bucket > self.hottest;
        self.hottest = if higher { self.bucket } else { self.hottest };
        self.hottest_run = if higher { self.run } else { self.hottest_run };
    }
}

impl<const FIRST: usize, const N: usize> Scan<FIRST, N> {
    /// Scans channels `FIRST..FIRST + N` of `scale * signal`: the state at the end (or
    /// where it stopped) and the first peak, slew or non-finite violation, if any.
    #[inline(always)]
    fn run(
        signal: &[[f64; CHANNELS]],
        scale: f64,
        limits: &Limits,
    ) -> (Self, Option<LimitViolation>) {
        let mut state = Scan {
            previous: [0.0; N],
            heat: [Heat::default(); N],
            thermal: None,
        };
        for (b, block) in signal.chunks(SCAN_BLOCK).enumerate() {
            let start = state.clone();
            if state.block_passes(block, scale, limits) {
                continue;
            }
            state = start;
            if let Some(stop) = state.walk(block, b * SCAN_BLOCK, scale, limits) {
                return (state, Some(stop));
            }
        }
        // The device rests at 0 A after playback: the last step is to 0 A.
        for (c, &current) in state.previous.iter().enumerate() {
            if current.abs() > limits.slew_a_per_ms {
                let v = LimitViolation::Slew {
                    channel: FIRST + c,
                    sample: signal.len(),
                    step_a: current.abs(),
                    limit_a_per_ms: limits.slew_a_per_ms,
                };
                return (state, Some(v));
            }
        }
        (state, None)
    }

    /// Runs `block` in lanes; true when it has nothing to report (no peak, slew or
    /// non-finite sample, and no first thermal violation), else the state is to be
    /// thrown away and the block walked.
    #[inline(always)]
    fn block_passes(&mut self, block: &[[f64; CHANNELS]], scale: f64, limits: &Limits) -> bool {
        let leak = limits.continuous_a * limits.continuous_a;
        // Two passes over the block: peak and slew first (no chain from one sample to
        // the next, so the loads stream from memory at full speed), then the buckets
        // (a chain through every sample) on samples the first pass left in L1.
        // [`within`] is false for NaN, and an infinity is above any finite limit, so a
        // block without a raised flag is finite on every channel.
        let mut breaks = [false; N];
        let mut previous = self.previous;
        for frame in block {
            for c in 0..N {
                let current = scale * frame[FIRST + c];
                let step = current - previous[c];
                breaks[c] |= !(within(current, limits.peak_a) & within(step, limits.slew_a_per_ms));
                previous[c] = current;
            }
        }
        if breaks.iter().any(|&b| b) {
            return false;
        }
        // The buckets field by field in lanes (vectorises; the same steps as
        // [`Heat::take`]).
        let mut bucket = self.heat.map(|h| h.bucket);
        let mut hottest = self.heat.map(|h| h.hottest);
        let mut run = self.heat.map(|h| h.run);
        let mut hottest_run = self.heat.map(|h| h.hottest_run);
        for frame in block {
            for c in 0..N {
                let x = frame[FIRST + c];
                bucket[c] = heat(bucket[c], scale * x, leak);
                run[c] = if bucket[c] > 0.0 { run[c] + x * x } else { 0.0 };
                let higher = bucket[c] > hottest[c];
                hottest[c] = if higher { bucket[c] } else { hottest[c] };
                hottest_run[c] = if higher { run[c] } else { hottest_run[c] };
            }
        }
        let first_over =
            self.thermal.is_none() && hottest.iter().any(|&h| h > limits.thermal_budget_a2s);
        if first_over {
            return false;
        }
        self.previous = previous;
        self.heat = std::array::from_fn(|c| Heat {
            bucket: bucket[c],
            hottest: hottest[c],
            run: run[c],
            hottest_run: hottest_run[c],
        });
        true
    }

    /// Runs `block` (whose first sample is `start`) sample by sample, channel by
    /// channel: records the first thermal violation, and returns the first peak, slew
    /// or non-finite one (the channels before it still heat their buckets).
    fn walk(
        &mut self,
        block: &[[f64; CHANNELS]],
        start: usize,
        scale: f64,
        limits: &Limits,
    ) -> Option<LimitViolation> {
        let leak = limits.continuous_a * limits.continuous_a;
        for (sample, frame) in (start..).zip(block) {
            for (c, &value) in frame[FIRST..FIRST + N].iter().enumerate() {
                let channel = FIRST + c;
                let current = scale * value;
                let step_a = (current - self.previous[c]).abs();
                if !current.is_finite() {
                    return Some(LimitViolation::NotFinite { channel, sample });
                } else if current.abs() > limits.peak_a {
                    return Some(LimitViolation::Peak {
                        channel,
                        sample,
                        current_a: current,
                        limit_a: limits.peak_a,
                    });
                } else if step_a > limits.slew_a_per_ms {
                    return Some(LimitViolation::Slew {
                        channel,
                        sample,
                        step_a,
                        limit_a_per_ms: limits.slew_a_per_ms,
                    });
                }
                self.previous[c] = current;
                self.heat[c].take(value, scale, leak);
                let b = self.heat[c].bucket;
                if self.thermal.is_none() && b > limits.thermal_budget_a2s {
                    self.thermal = Some(LimitViolation::Thermal {
                        channel,
                        sample,
                        bucket_a2s: b,
                        budget_a2s: limits.thermal_budget_a2s,
                    });
                }
            }
        }
        None
    }

    /// The hottest of these channels, the lowest on a tie.
    fn hottest(&self) -> Heat {
        self.heat.iter().fold(
            Heat::default(),
            |m, &h| if h.hottest > m.hottest { h } else { m },
        )
    }
}

/// `|x| <= limit`; false when `x` is NaN.
#[inline(always)]
fn within(x: f64, limit: f64) -> bool {
    x.abs() <= limit
}

/// A channel's thermal bucket after one 1 ms sample of `current`: it fills at the
/// square of the current, leaks at `leak` (A^2) and never drops below 0.
#[inline(always)]
fn heat(bucket: f64, current: f64, leak: f64) -> f64 {
    let b = bucket + (current * current - leak) * (1.0 / OUTPUT_RATE_HZ);
    if b > 0.0 {
        b
    } else {
        0.0
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

/// Scales `signal` down, in place, by the largest factor in `[0, 1]` that makes it pass
/// [`check_limits`], and returns the factor (1 and no change when it already passes).
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
    fit_to(signal, limits, 1.0)
}

/// [`fit`], but a signal that breaks `limits` is fitted to `thermal_share` of the
/// thermal budget (peak and slew in full): room for what the encoding adds to the heat
/// (`signal.fit_thermal_share`). A signal that passes `limits` is left alone, so the
/// factor is 1 exactly when [`fit`]'s is.
pub fn fit_to(
    signal: &mut [[f64; CHANNELS]],
    limits: &Limits,
    thermal_share: f64,
) -> Result<f64, LimitViolation> {
    validate_limits(limits)?;
    let shared = &Limits {
        thermal_budget_a2s: limits.thermal_budget_a2s * thermal_share,
        ..*limits
    };
    validate_limits(shared)?;
    // One scan at scale 1 answers for both budgets: the budget only decides where a
    // thermal violation is named, not the levels, and a scan that did not stop breaks
    // a budget exactly when its hottest level is above it.
    let at_one = scan(signal, 1.0, shared);
    if let Some(e @ LimitViolation::NotFinite { .. }) = at_one.violation {
        return Err(e);
    }
    if !at_one.stopped && at_one.level <= limits.thermal_budget_a2s {
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
    use proptest::prelude::*;

    /// The scan as the check is defined, one sample and one channel at a time: the
    /// oracle for [`scan`]'s lanes and blocks.
    fn plain_scan(signal: &[[f64; CHANNELS]], scale: f64, limits: &Limits) -> Scanned {
        let dt_s = 1.0 / OUTPUT_RATE_HZ;
        let leak = limits.continuous_a * limits.continuous_a;
        let mut previous = [0.0_f64; CHANNELS];
        let mut bucket = [0.0_f64; CHANNELS];
        // Per channel: the highest level, and the sum of x^2 since the bucket was last
        // empty at that moment; the sum so far.
        let mut hottest = [(0.0_f64, 0.0_f64); CHANNELS];
        let mut run = [0.0_f64; CHANNELS];
        let mut thermal = None;
        let done = |hottest: [(f64, f64); CHANNELS], violation, stopped| {
            let mut top = (0.0, 0.0);
            for h in hottest {
                if h.0 > top.0 {
                    top = h;
                }
            }
            Scanned {
                stopped,
                violation,
                level: top.0,
                slope: top.1 * dt_s,
            }
        };
        for (sample, frame) in signal.iter().enumerate() {
            for channel in 0..CHANNELS {
                let current = scale * frame[channel];
                let step_a = (current - previous[channel]).abs();
                let stop = if !current.is_finite() {
                    Some(LimitViolation::NotFinite { channel, sample })
                } else if current.abs() > limits.peak_a {
                    Some(LimitViolation::Peak {
                        channel,
                        sample,
                        current_a: current,
                        limit_a: limits.peak_a,
                    })
                } else if step_a > limits.slew_a_per_ms {
                    Some(LimitViolation::Slew {
                        channel,
                        sample,
                        step_a,
                        limit_a_per_ms: limits.slew_a_per_ms,
                    })
                } else {
                    None
                };
                if let Some(v) = stop {
                    return done(hottest, Some(thermal.unwrap_or(v)), true);
                }
                previous[channel] = current;
                bucket[channel] = (bucket[channel] + (current * current - leak) * dt_s).max(0.0);
                let x = frame[channel];
                run[channel] = if bucket[channel] > 0.0 {
                    run[channel] + x * x
                } else {
                    0.0
                };
                if bucket[channel] > hottest[channel].0 {
                    hottest[channel] = (bucket[channel], run[channel]);
                }
                if thermal.is_none() && bucket[channel] > limits.thermal_budget_a2s {
                    thermal = Some(LimitViolation::Thermal {
                        channel,
                        sample,
                        bucket_a2s: bucket[channel],
                        budget_a2s: limits.thermal_budget_a2s,
                    });
                }
            }
        }
        for (channel, &current) in previous.iter().enumerate() {
            if current.abs() > limits.slew_a_per_ms {
                let v = LimitViolation::Slew {
                    channel,
                    sample: signal.len(),
                    step_a: current.abs(),
                    limit_a_per_ms: limits.slew_a_per_ms,
                };
                return done(hottest, Some(thermal.unwrap_or(v)), true);
            }
        }
        done(hottest, thermal, false)
    }

    /// Slow random walks per channel (within the slew limit) with ramps at both ends,
    /// sometimes with one odd sample: a jump, a NaN or an infinity.
    fn signals() -> impl Strategy<Value = Vec<[f64; CHANNELS]>> {
        (1usize..1200, any::<u64>(), 0usize..4, any::<usize>()).prop_map(|(n, seed, odd, at)| {
            let mut rng = touchc_test_rng::Xorshift::new(seed);
            let mut next = move || rng.uniform();
            let mut level = [0.0_f64; CHANNELS];
            let mut signal: Vec<[f64; CHANNELS]> = (0..n)
                .map(|t| {
                    let edge = (t.min(n - 1 - t) as f64 / 20.0).min(1.0);
                    for l in level.iter_mut() {
                        *l = (*l + 0.08 * (next() - 0.5)).clamp(-0.95, 0.95);
                    }
                    level.map(|l| l * edge)
                })
                .collect();
            let (t, c) = (at % n, (at / n) % CHANNELS);
            signal[t][c] = match odd {
                1 => signal[t][c] + 0.3,
                2 => f64::NAN,
                3 => f64::INFINITY,
                _ => signal[t][c],
            };
            signal
        })
    }

    /// Channels at `levels` (A), each reached by a 40 ms ramp, held for `n` ms.
    fn held(levels: [f64; CHANNELS], n: usize) -> Vec<[f64; CHANNELS]> {
        (0..n)
            .map(|t| levels.map(|a| a * (t as f64 / 40.0).min(1.0)))
            .collect()
    }

    /// Where the halves' first thermal violations meet, the merged scan names the
    /// earlier sample, and on the same sample the lower channel: what one pass names.
    #[test]
    fn halves_name_the_first_thermal_violation_as_one_scan_does() {
        let limits = Limits {
            thermal_budget_a2s: 0.02,
            continuous_a: 0.1,
            ..Limits::default()
        };
        let cases = [
            // Channels 2 and 5 (one per half) cross on the same sample: channel 2.
            ([0.0, 0.0, 0.5, 0.0, 0.0, 0.5, 0.0, 0.0], 2),
            // Channel 6 is hotter and crosses first: channel 6, not the lower channel 1.
            ([0.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.7, 0.0], 6),
            // Only the low half: channel 3.
            ([0.0, 0.0, 0.0, 0.6, 0.0, 0.0, 0.0, 0.0], 3),
        ];
        for (levels, expected) in cases {
            let signal = held(levels, 2_000);
            let plain = plain_scan(&signal, 1.0, &limits);
            let halves = scan_halves(&signal, 1.0, &limits);
            assert!(
                matches!(halves.violation, Some(LimitViolation::Thermal { channel, .. }) if channel == expected),
                "{:?}",
                halves.violation
            );
            assert_eq!(halves, plain);
            assert_eq!(scan_whole(&signal, 1.0, &limits), plain);
        }
    }

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

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// The lanes and blocks report exactly what the plain loop reports: the same
        /// first violation (sample, channel, figure), whether it stopped, hottest level
        /// and slope; whole or in halves.
        #[test]
        fn scan_reports_what_the_plain_loop_reports(
            signal in signals(),
            scale in 0.0f64..3.0,
            budget in prop_oneof![Just(30.0), 0.0f64..0.05],
            continuous in 0.0f64..0.7,
        ) {
            let limits = Limits {
                thermal_budget_a2s: budget,
                continuous_a: continuous,
                ..Limits::default()
            };
            let plain = plain_scan(&signal, scale, &limits);
            // One pass over all channels, and two halves on two threads (both in the
            // AVX2 build on a CPU that runs it), and the baseline build of one pass.
            let (state, stop) = Scan::<0, CHANNELS>::run(&signal, scale, &limits);
            let baseline = Scanned::of(state.hottest(), state.thermal, stop);
            for fast in [
                scan_whole(&signal, scale, &limits),
                scan_halves(&signal, scale, &limits),
                baseline,
            ] {
                prop_assert_eq!(&fast.violation, &plain.violation);
                prop_assert_eq!(fast.stopped, plain.stopped);
                prop_assert_eq!(fast.level.to_bits(), plain.level.to_bits());
                prop_assert_eq!(fast.slope.to_bits(), plain.slope.to_bits());
            }
        }
    }
}
