//! The scan behind every limit check: `scale * signal` walked once, in lanes and
//! blocks, for the first violation and the hottest thermal bucket.

use super::{LimitViolation, Limits};
use crate::condition::{CHANNELS, OUTPUT_RATE_HZ};

/// Scans `scale * signal`: the first violation in time order (sample by sample, channel
/// by channel), if any, and the highest thermal bucket level reached. A peak, slew or
/// non-finite violation stops the scan; a thermal one does not, so that the level says
/// how far over the budget the whole signal goes ([`fit`](super::fit()) steers by it, with its slope).
///
/// [`fit`](super::fit()) scans an hour of signal several times, so the scan runs in blocks of
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
pub(super) fn scan(signal: &[[f64; CHANNELS]], scale: f64, limits: &Limits) -> Scanned {
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
pub(super) struct Scanned {
    /// The first thermal violation if there was one, else the first peak, slew or
    /// non-finite one (which stopped the scan).
    pub(super) violation: Option<LimitViolation>,
    /// Whether a peak, slew or non-finite violation stopped the scan (the level is then
    /// that of the samples before it).
    pub(super) stopped: bool,
    /// The highest bucket level of any channel, A^2 s.
    pub(super) level: f64,
    /// How fast that level grows with the square of the scale, A^2 s: 1 ms times the sum
    /// of the unscaled current squared over the stretch that filled that bucket (from
    /// its last time at 0). The level is the largest over stretches of
    /// `(scale^2 x^2 - leak) 1 ms` summed, so it is convex in the square of the scale
    /// and this is its slope there.
    pub(super) slope: f64,
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
