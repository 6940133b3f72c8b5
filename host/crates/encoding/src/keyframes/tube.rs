//! Keyframes on straight lines through a tolerance tube around the 1 kHz signal: the
//! greedy longest lines per channel ([`tube_keyframes`]), with a tolerance per window
//! and channel ([`tube_scheduled`]) and what each window costs in bends and error.

use touch_protocol::CHANNELS;

/// A line this many keyframes long ends where another channel's bends (see
/// [`Line::nearly_done`]). Measured with [`LINE_SHIFTS`](super::lines::LINE_SHIFTS) on the same 40 stimuli: 4 with
/// the slope test gives 9% fewer bytes than never joining, 2% fewer than 6; on the
/// benchmark's busy synthetic scene, 21% fewer.
const JOIN_AFTER: usize = 4;

/// One keyframe's stored values (Q15 in units of `2^shift`): within `i16` by
/// construction, as a keyframe is, so an hour's keyframes take 5.8 MB instead of 23.
type Stored = [i16; CHANNELS];

/// `v` as a stored value: the tube clamps every slope and rounded value to the range.
#[inline(always)]
fn store(v: i64) -> i16 {
    debug_assert!(i64::from(i16::MIN) <= v && v <= i64::from(i16::MAX), "{v}");
    v as i16
}

/// One channel's current line in [`tube_keyframes`]: it leaves keyframe `start` at
/// stored value `base`; `lo..=hi` bound the slopes (stored units per keyframe) that
/// keep every tick so far within the tolerance, and `whole` is the range of whole
/// slopes among them at the last keyframe reached.
#[derive(Debug, Clone, Copy)]
struct Line {
    start: usize,
    base: i64,
    lo: f64,
    hi: f64,
    whole: (i64, i64),
    /// Sum over the ticks so far of `m v`, `m` the ticks since `start` and `v` the
    /// signal less `base`: the least-squares slope is `period * mv / sum(m^2)`.
    mv: f64,
}

impl Line {
    /// A line reaching keyframe `end` that a bend elsewhere may end there too: it is
    /// [`JOIN_AFTER`] keyframes long, or its slopes have narrowed until the spread they
    /// allow at `end` is under the tube's half-width (`tol`, stored units). It would
    /// likely end soon anyway, and ending with another channel shares that keyframe's
    /// record (a mask byte, and no run between).
    fn nearly_done(&self, end: usize, tol: f64) -> bool {
        let steps = end - self.start;
        steps >= JOIN_AFTER || (self.hi - self.lo) * (steps as f64) < tol
    }

    /// Narrows the slopes by tick `t`, where the signal is `x` (stored units).
    #[inline(always)]
    fn take(&mut self, t: usize, x: f64, period: usize, pf: f64, tol: f64) {
        let m = (t - self.start * period) as f64;
        let per_tick = pf / m;
        let v = x - self.base as f64;
        self.lo = larger(self.lo, (v - tol) * per_tick);
        self.hi = smaller(self.hi, (v + tol) * per_tick);
        self.mv += m * v;
    }

    /// Whether some whole slope is left after the ticks up to keyframe `end` that also
    /// keeps the line's end in `min..=max`; records those slopes.
    fn fits(&mut self, end: usize, min: i64, max: i64) -> bool {
        // Slopes are never NaN: the signal is finite (checked) and every tick narrows
        // them by finite bounds.
        if self.lo > self.hi {
            return false;
        }
        let steps = (end - self.start) as i64;
        let (mut lo, mut hi) = (ceil(self.lo), floor(self.hi));
        // Rarely binding (a line at full scale): only then the divisions.
        if self.base + lo * steps < min {
            lo = (min - self.base + steps - 1).div_euclid(steps);
        }
        if self.base + hi * steps > max {
            hi = (max - self.base).div_euclid(steps);
        }
        self.whole = (lo, hi);
        lo <= hi
    }

    /// Writes the line's keyframes after its start up to `end` into channel `c` of
    /// `stored`: the least-squares slope among the whole slopes that fit.
    fn commit(&self, stored: &mut [Stored], end: usize, c: usize, pf: f64) {
        // Sum of m^2 for m = 1..=ticks.
        let ticks = ((end - self.start) as f64) * pf;
        let mm = ticks * (ticks + 1.0) * (2.0 * ticks + 1.0) / 6.0;
        let slope = ((pf * self.mv / mm).round() as i64).clamp(self.whole.0, self.whole.1);
        for (k, s) in stored
            .iter_mut()
            .enumerate()
            .take(end + 1)
            .skip(self.start + 1)
        {
            s[c] = store(self.base + slope * (k - self.start) as i64);
        }
    }

    fn at(start: usize, base: i64) -> Self {
        Line {
            start,
            base,
            lo: f64::NEG_INFINITY,
            hi: f64::INFINITY,
            whole: (0, 0),
            mv: 0.0,
        }
    }
}

/// Keyframes on straight lines through a tube of half-width `tol` (Q15 units) around
/// the 1 kHz signal, at `period` ms and `2^shift` Q15 units per stored step.
///
/// The format predicts each stored value as `2 s[k-1] - s[k-2]` and codes keyframes
/// in which every channel meets its prediction as one run, so a channel costs nothing
/// while it moves on a straight line and a residual where it bends. Each channel's
/// line leaves its corner and is extended keyframe by keyframe while some whole slope
/// keeps every tick so far within the tube (each tick narrows the slope interval; this
/// is the greedy longest line, which for a tube is the fewest corners up to one per
/// line); it then takes the middle of the slopes left and the next line starts at its
/// end. Where not even one segment fits (a bend sharper than the period resolves),
/// the keyframe is the signal's value, rounded, as without a tube.
///
/// Returns the keyframes (Q15, multiples of `2^shift`) and the RMS and max of the
/// linear interpolation's error over the signal's ticks, in Q15 units (f64; the
/// player's integer arithmetic and 12-bit output add under a code). O(ticks x
/// channels), in one pass through time plus one to measure.
pub(super) fn tube_keyframes(
    signal: &[[f64; CHANNELS]],
    fs_a: f64,
    period: usize,
    shift: u8,
    tol: f64,
) -> (Vec<[i16; CHANNELS]>, f64, f64) {
    let uniform = Schedule {
        keyframes: usize::MAX,
        tols: vec![[tol; CHANNELS]],
    };
    let (keyframes, rms, max, _) =
        tube_scheduled(signal, fs_a, period, shift, &uniform, false, None);
    (keyframes, rms, max)
}

/// Tube half-widths (Q15 units) per channel, in windows of `keyframes` keyframes: the
/// segment that ends at keyframe `j` has the tolerances `tols[(j - 1) / keyframes]`
/// (the last entry's past the end).
#[derive(Debug, Clone)]
pub(super) struct Schedule {
    pub(super) keyframes: usize,
    pub(super) tols: Vec<[f64; CHANNELS]>,
}

impl Schedule {
    /// The tolerances of the segment after keyframe `k`.
    pub(super) fn at(&self, k: usize) -> [f64; CHANNELS] {
        let w = (k / self.keyframes).min(self.tols.len().saturating_sub(1));
        self.tols.get(w).copied().unwrap_or([0.0; CHANNELS])
    }
}

/// Per window of a [`Schedule`] and channel: the bends (keyframes where the line's
/// slope changes, each a residual in the file) and the squared model error, Q15 units
/// squared.
pub(super) type WindowCosts = Vec<[(u32, f64); CHANNELS]>;

touchc_wide::kernel! {
    /// [`tube_keyframes`] with a tolerance per window and channel. With `costs`, also what
    /// each window and channel cost in bends and squared error (else an empty list).
    ///
    /// With `bounds = (rms, max)` (fractions of full scale), gives up as soon as the
    /// model's error is sure to miss them (the squared error only grows, and so does the
    /// largest) and reports no keyframes and `(INFINITY, INFINITY)`: a caller that only
    /// wants a passing tube is spared the rest of a failing one.
    ///
    /// Compiled for AVX2 too (`touchc_wide`): an allocation runs the tube some 25 times.
    pub(super) fn tube_scheduled / tube_scheduled_baseline / tube_scheduled_avx2 (
        signal: &[[f64; CHANNELS]],
        fs_a: f64,
        period: usize,
        shift: u8,
        schedule: &Schedule,
        costs: bool,
        bounds: Option<(f64, f64)>,
    ) -> (Vec<[i16; CHANNELS]>, f64, f64, WindowCosts) {
        let n = signal.len();
        let unit = f64::from(1u32 << shift);
        let tube = Tube {
            signal,
            to_stored: 32768.0 / fs_a / unit,
            period,
            pf: period as f64,
            per_tick: per_tick(period as f64, n),
            min_s: i64::from(i16::MIN) >> shift,
            max_s: i64::from(i16::MAX) >> shift,
        };
        let count = (n - 1).div_ceil(period) + 1;
        let mut stored: Vec<Stored> = vec![[0; CHANNELS]; count];
        let windows = if costs {
            (count - 1).div_ceil(schedule.keyframes).max(1)
        } else {
            0
        };
        let mut error = ModelError {
            sum2: 0.0,
            max: [0.0; CHANNELS],
            done: 0,
            cost: vec![[(0, 0.0); CHANNELS]; windows],
            window_keyframes: schedule.keyframes,
            unit,
        };
        let mut lines: [Line; CHANNELS] = std::array::from_fn(|c| Line::at(0, tube.rounded(0, c)));
        stored[0] = lines.map(|l| store(l.base));
        for j in 1..count {
            let tol = schedule.at(j - 1).map(|t| t / unit);
            let extended = tube.extended(&lines, j, &tol);
            tube.advance(&mut lines, extended, &mut stored, j, &tol);
            let upto = lines.iter().map(|l| l.start).min().unwrap_or(0);
            error.measure_to(&tube, &stored, upto);
            if bounds.is_some_and(|b| error.misses(b, n)) {
                return (Vec::new(), f64::INFINITY, f64::INFINITY, error.cost);
            }
        }
        for (c, line) in lines.iter().enumerate() {
            if line.start + 1 < count {
                line.commit(&mut stored, count - 1, c, tube.pf);
            }
        }
        // The rest of the model's error.
        error.measure_to(&tube, &stored, count - 1);
        if (count - 1) * period < n {
            // A signal of one tick: its only keyframe.
            let (a, x) = (stored[count - 1], tube.row((count - 1) * period));
            for c in 0..CHANNELS {
                let e = f64::from(a[c]) - x[c];
                error.sum2 += e * e;
                error.max[c] = error.max[c].max(e.abs());
            }
        }
        // In range by construction (every slope and rounded value is clamped to it);
        // in place, the stored values' own allocation.
        let keyframes = stored
            .into_iter()
            .map(|s| {
                s.map(|v| (i64::from(v) << shift).clamp(i64::from(i16::MIN), i64::from(i16::MAX)) as i16)
            })
            .collect();
        (
            keyframes,
            unit * (error.sum2 / (n * CHANNELS) as f64).sqrt(),
            unit * error.largest(),
            error.cost,
        )
    }
}

/// What each step of [`tube_scheduled`] reads: the signal, converted to stored units,
/// the keyframe period and the range of stored values.
struct Tube<'s> {
    signal: &'s [[f64; CHANNELS]],
    /// Stored units per ampere.
    to_stored: f64,
    period: usize,
    /// `period` as f64.
    pf: f64,
    /// `pf / m` for the ticks `m` since a line's start, up to [`PER_TICK_TABLE`]: a
    /// load where the tube's inner loop would divide (the same quotient, correctly
    /// rounded either way).
    per_tick: Vec<f64>,
    min_s: i64,
    max_s: i64,
}

impl Tube<'_> {
    /// The signal at tick `t` in stored units; 0 after its end (the last keyframe may
    /// lie beyond).
    #[inline(always)]
    fn row(&self, t: usize) -> [f64; CHANNELS] {
        self.signal
            .get(t)
            .map_or([0.0; CHANNELS], |s| s.map(|a| a * self.to_stored))
    }

    /// Channel `c` of the signal at tick `t`, rounded to a stored value.
    #[inline(always)]
    fn rounded(&self, t: usize, c: usize) -> i64 {
        (self.row(t)[c].round() as i64).clamp(self.min_s, self.max_s)
    }

    /// Every channel's line over the segment ending at keyframe `j`, in step (one pass
    /// over the rows, eight independent chains), at the tube half-widths `tol`.
    #[inline(always)]
    fn extended(
        &self,
        lines: &[Line; CHANNELS],
        j: usize,
        tol: &[f64; CHANNELS],
    ) -> [Line; CHANNELS] {
        let (period, pf) = (self.period, self.pf);
        let mut extended = *lines;
        let from = lines.map(|l| l.start * period);
        let base = lines.map(|l| l.base as f64);
        let (mut lo, mut hi) = (lines.map(|l| l.lo), lines.map(|l| l.hi));
        let mut mv = lines.map(|l| l.mv);
        for t in (j - 1) * period + 1..=j * period {
            let x = self.row(t);
            for c in 0..CHANNELS {
                let m = t - from[c];
                let per_tick = match self.per_tick.get(m) {
                    Some(&q) => q,
                    None => pf / m as f64,
                };
                let m = m as f64;
                let v = x[c] - base[c];
                lo[c] = larger(lo[c], (v - tol[c]) * per_tick);
                hi[c] = smaller(hi[c], (v + tol[c]) * per_tick);
                mv[c] += m * v;
            }
        }
        for (c, e) in extended.iter_mut().enumerate() {
            (e.lo, e.hi, e.mv) = (lo[c], hi[c], mv[c]);
        }
        extended
    }

    /// Each channel's line at keyframe `j`: the `extended` one where it still fits
    /// (unless another channel bends there and the line is nearly done); else the
    /// line ends at the keyframe before, written to `stored`, and a new one leaves
    /// there, or, where not even one segment fits, at the signal's rounded value.
    #[inline(always)]
    fn advance(
        &self,
        lines: &mut [Line; CHANNELS],
        mut extended: [Line; CHANNELS],
        stored: &mut [Stored],
        j: usize,
        tol: &[f64; CHANNELS],
    ) {
        let (period, pf) = (self.period, self.pf);
        let fits: [bool; CHANNELS] =
            std::array::from_fn(|c| extended[c].fits(j, self.min_s, self.max_s));
        let bends = (0..CHANNELS).any(|c| !fits[c] && lines[c].start + 1 < j);
        for c in 0..CHANNELS {
            let line = &mut lines[c];
            let early = bends && line.start + 1 < j && line.nearly_done(j - 1, tol[c]);
            if fits[c] && !early {
                *line = extended[c];
                continue;
            }
            if line.start + 1 < j {
                // The line ends at the last keyframe it reached; a new one leaves there.
                line.commit(stored, j - 1, c, pf);
                let mut fresh = Line::at(j - 1, i64::from(stored[j - 1][c]));
                for t in (j - 1) * period + 1..=j * period {
                    fresh.take(t, self.row(t)[c], period, pf, tol[c]);
                }
                if fresh.fits(j, self.min_s, self.max_s) {
                    *line = fresh;
                    continue;
                }
            }
            let rounded = self.rounded(j * period, c);
            stored[j][c] = store(rounded);
            *line = Line::at(j, rounded);
        }
    }
}

/// Ticks since a line's start whose `pf / m` [`Tube`] looks up (512 KB): beyond, a line
/// is over a minute long and its channel still, where the division is rare enough.
const PER_TICK_TABLE: usize = 65_536;

/// `pf / m` for `m` in `0..=min(n, PER_TICK_TABLE)` (`m = 0`, never a tick since a
/// start, is infinite).
fn per_tick(pf: f64, n: usize) -> Vec<f64> {
    (0..=n.min(PER_TICK_TABLE)).map(|m| pf / m as f64).collect()
}

/// The model's error in [`tube_scheduled`], segment by segment, as soon as both ends
/// of a segment are final on every channel (keyframes up to the earliest line start):
/// those rows were read lately and are still in cache, where a pass after the tube
/// reads a long signal from memory again. Segments are taken in order, so the sums
/// are the same.
struct ModelError {
    /// Sum of squared errors, stored units squared.
    sum2: f64,
    /// Largest error per channel, stored units (the same in any order; one running
    /// maximum would be a chain through every tick and channel).
    max: [f64; CHANNELS],
    /// Segments measured.
    done: usize,
    /// Per window and channel (none when the caller wants no costs).
    cost: WindowCosts,
    /// Keyframes per window of `cost`.
    window_keyframes: usize,
    /// Q15 units per stored unit.
    unit: f64,
}

impl ModelError {
    /// Whether the figures [`tube_scheduled`] reports for a signal of `n` ticks, from
    /// the error measured so far and computed as it computes them, already miss
    /// `(rms, max)` (fractions of full scale): they only grow from here.
    #[inline(always)]
    fn misses(&self, (rms, max): (f64, f64), n: usize) -> bool {
        let so_far = self.unit * (self.sum2 / (n * CHANNELS) as f64).sqrt();
        so_far / 32768.0 > rms || self.unit * self.largest() / 32768.0 > max
    }

    /// Largest error over the channels, stored units.
    #[inline(always)]
    fn largest(&self) -> f64 {
        self.max.iter().fold(0.0, |m, &e| larger(m, e))
    }

    /// Adds the segments before keyframe `upto` not yet measured.
    #[inline(always)]
    fn measure_to(&mut self, tube: &Tube<'_>, stored: &[Stored], upto: usize) {
        let (period, pf, n) = (tube.period, tube.pf, tube.signal.len());
        let (unit, windows) = (self.unit, self.cost.len());
        for k in self.done..upto {
            let (a, b) = (stored[k].map(f64::from), stored[k + 1].map(f64::from));
            let mut segment = [0.0f64; CHANNELS];
            for (i, t) in (k * period..((k + 1) * period).min(n)).enumerate() {
                let w = i as f64 / pf;
                let x = tube.row(t);
                for c in 0..CHANNELS {
                    let e = a[c] + (b[c] - a[c]) * w - x[c];
                    segment[c] += e * e;
                    self.max[c] = larger(self.max[c], e.abs());
                }
            }
            self.sum2 += segment.iter().sum::<f64>();
            if let Some(window) = self
                .cost
                .get_mut((k / self.window_keyframes).min(windows.saturating_sub(1)))
            {
                for c in 0..CHANNELS {
                    window[c].1 += segment[c] * unit * unit;
                    // A bend at keyframe k: the residual of keyframe k + 1.
                    let at = |k: usize| i64::from(stored[k][c]);
                    let before = if k == 0 { 0 } else { at(k - 1) };
                    if at(k + 1) - 2 * at(k) + before != 0 {
                        window[c].0 += 1;
                    }
                }
            }
        }
        self.done = self.done.max(upto);
    }
}

/// `x.ceil()` for the slopes of a line (finite, far inside i64), without the libm
/// call that `f64::ceil` is on baseline x86-64.
#[inline(always)]
pub(super) fn ceil(x: f64) -> i64 {
    let i = x as i64;
    if (i as f64) < x {
        i + 1
    } else {
        i
    }
}

/// `x.floor()`, as [`ceil`].
#[inline(always)]
pub(super) fn floor(x: f64) -> i64 {
    let i = x as i64;
    if (i as f64) > x {
        i - 1
    } else {
        i
    }
}

/// The larger of two numbers that are not NaN (`f64::max` also orders NaN, at several
/// instructions a call in the tube's inner loop).
#[inline(always)]
pub(super) fn larger(a: f64, b: f64) -> f64 {
    if b > a {
        b
    } else {
        a
    }
}

/// The smaller of two numbers that are not NaN.
#[inline(always)]
pub(super) fn smaller(a: f64, b: f64) -> f64 {
    if b < a {
        b
    } else {
        a
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{busy, stroke};
    use super::*;

    /// The AVX2 build of the tube gives the baseline's keyframes, figures and costs to
    /// the bit ([`touchc_wide`]), uniform and scheduled, with and without bounds.
    #[test]
    fn the_avx2_build_runs_the_baseline_tube() {
        if !touchc_wide::avx2_or_skip(
            "keyframes::tube::tests::the_avx2_build_runs_the_baseline_tube",
        ) {
            return;
        }
        let uniform = |tol: f64| Schedule {
            keyframes: 40,
            tols: vec![[tol * 32768.0; CHANNELS]],
        };
        let scheduled = Schedule {
            keyframes: 80,
            tols: (0..8)
                .map(|w| std::array::from_fn(|c| (0.003 + 0.002 * ((w + c) % 4) as f64) * 32768.0))
                .collect(),
        };
        let bits = |r: &(Vec<[i16; CHANNELS]>, f64, f64, WindowCosts)| {
            let costs: Vec<(u32, u64)> =
                r.3.iter()
                    .flatten()
                    .map(|&(b, e)| (b, e.to_bits()))
                    .collect();
            (r.0.clone(), r.1.to_bits(), r.2.to_bits(), costs)
        };
        let mut cases = 0;
        for signal in [busy(6.0), stroke(4.0)] {
            for schedule in [uniform(0.004), uniform(0.012), scheduled.clone()] {
                for (shift, period) in [(5, 10), (6, 10), (6, 5)] {
                    for bounds in [None, Some((0.004, 0.015)), Some((0.0005, 0.015))] {
                        let a = tube_scheduled_baseline(
                            &signal, 1.0, period, shift, &schedule, true, bounds,
                        );
                        // SAFETY: the CPU runs AVX2 (checked above).
                        let b = unsafe {
                            tube_scheduled_avx2(
                                &signal, 1.0, period, shift, &schedule, true, bounds,
                            )
                        };
                        assert_eq!(
                            bits(&a),
                            bits(&b),
                            "shift {shift} period {period} {bounds:?}"
                        );
                        cases += 1;
                    }
                }
            }
        }
        assert_eq!(cases, 54);
    }
}
