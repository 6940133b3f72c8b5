//! Input sanity: warnings (never failures) for recordings that compile but probably do
//! not mean what the compile assumes.
//!
//! A recording in the wrong unit, from a sensor whose reading falls with pressure, that
//! begins mid-touch under the paper's leading baseline, or given at the wrong rate or
//! pitch, still compiles to a valid stimulus: the result is just not the touch that was
//! recorded. Each check here gives the figure it saw and what to try. The unit checks
//! (`raw_counts`, `falls_with_touch`) come first: when either fires, the psi
//! thresholds the later checks use mean nothing, so those are skipped.

use ndarray::{ArrayView2, ArrayView3, Axis};

use crate::recording::{map_cell_series, Recording};
use crate::warning::{ErasedBy, InputWarning, TransposedBy};
use touchc_model::config::{Baseline, Config, Sampling};

/// A median reading above this many "psi" is far above skin touch (rarely over ~10 psi)
/// and looks like raw ADC counts.
pub const RAW_COUNTS_MEDIAN: f64 = 100.0;

/// Contacts whose centroid moves at a median speed above this, mm/s, are implausibly
/// fast for a hand (strokes reach about 1.5 m/s, shakes about 1 m/s).
pub(crate) const MAX_PLAUSIBLE_SPEED_MM_S: f64 = 3000.0;

/// Fewest frame-to-frame centroid steps for the speed check to say anything.
const MIN_STEPS: usize = 5;

/// Fewest separate touches, all a single frame long, before that is called implausible.
const MIN_SINGLE_FRAME_TOUCHES: usize = 3;

/// A recording that compiles but probably does not mean what the compile assumes, with
/// the figures that say so (a front end words them, with what to try).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum SanityWarning {
    /// The median reading is at least [`RAW_COUNTS_MEDIAN`] from 0: raw ADC counts
    /// rather than psi.
    RawCounts {
        /// The median of the finite readings.
        median: f64,
    },
    /// Readings deviate from their cell's resting level mostly downwards: a sensor whose
    /// reading falls with pressure.
    FallsWithTouch {
        /// Readings more than the threshold below their cell's rest.
        below: usize,
        /// Readings more than the threshold above it.
        above: usize,
        /// The touch threshold the deviations are counted against, psi.
        threshold_psi: f64,
        /// The deepest fall below a cell's rest (negative).
        deepest: f64,
    },
    /// Cells read well above their rest in the leading baseline's window, which is
    /// subtracted from the whole recording: the recording may begin mid-touch.
    TouchInTareWindow {
        /// Cells whose mean in the window lies above their rest by more than the
        /// touch threshold.
        cells: usize,
        /// The largest such excess, psi.
        highest_psi: f64,
        /// The window, seconds (`input.tare_s`).
        tare_s: f64,
        /// The window, frames.
        frames: usize,
    },
    /// The touch's centroid moves faster than a hand at this rate and pitch.
    ImplausibleSpeed {
        /// The median centroid speed, mm/s.
        median_mm_s: f64,
        /// The frame rate it was measured at, Hz.
        rate_hz: f64,
        /// The cell pitch it was measured at, mm.
        pitch_mm: f64,
    },
    /// Every touch lasts a single frame.
    SingleFrameTouches {
        /// Separate touches.
        touches: usize,
        /// The frame rate, Hz.
        rate_hz: f64,
    },
}

/// Every sanity warning for `rec`, whose tared and trimmed frames are `tared`, compiled
/// with `cfg` at `sampling`.
pub fn check(
    rec: &Recording,
    tared: ArrayView3<f64>,
    cfg: &Config,
    sampling: &Sampling,
) -> Vec<SanityWarning> {
    let raw = rec.data();
    let threshold = cfg.input.touch_threshold_psi;
    let mut out = Vec::new();
    // The checks of the raw readings and those of the tared touch side by side (an hour
    // is 12 M readings); the warnings in the same order either way.
    let (units, (in_tare, centroids)) = rayon::join(
        || [raw_counts(raw), falls_with_touch(raw, threshold)],
        || {
            rayon::join(
                || {
                    (cfg.input.baseline == Baseline::Leading)
                        .then(|| touch_in_tare_window(raw, cfg, sampling))
                        .flatten()
                },
                || centroids(tared, threshold),
            )
        },
    );
    let units_wrong = units.iter().any(Option::is_some);
    out.extend(units.into_iter().flatten());
    if units_wrong {
        return out;
    }
    out.extend(in_tare);
    out.extend(speed_of(&centroids, sampling));
    out.extend(single_frames_of(&centroids, sampling));
    out
}

/// The median of `values` (reordered in place); `None` when empty.
fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mid = values.len() / 2;
    let (_, m, _) = values.select_nth_unstable_by(mid, f64::total_cmp);
    Some(*m)
}

/// Values in the hundreds or more: raw ADC counts rather than psi.
///
/// Whether the median is that far out is decided by counting, without a copy of the
/// recording (97 MB for an hour of the paper's sleeve); only a recording that is
/// warned about is copied, to name its median.
pub(crate) fn raw_counts(raw: ArrayView3<f64>) -> Option<SanityWarning> {
    use rayon::prelude::*;
    // Counts, so any order gives the same; by frames on the rayon pool.
    let count = |frame: ArrayView2<f64>| {
        let (mut finite, mut high, mut low) = (0usize, 0usize, 0usize);
        for &v in frame.iter().filter(|v| v.is_finite()) {
            finite += 1;
            high += usize::from(v >= RAW_COUNTS_MEDIAN);
            low += usize::from(v <= -RAW_COUNTS_MEDIAN);
        }
        (finite, high, low)
    };
    let (finite, high, low) = (0..raw.dim().0)
        .into_par_iter()
        .map(|f| count(raw.index_axis(Axis(0), f)))
        .reduce(|| (0, 0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
    // The median is the reading at sorted position `finite / 2` ([`median`]): at or
    // above the bound when the readings from there on all are, at or below minus the
    // bound when those up to there all are.
    let mid = finite / 2;
    if finite == 0 || (high < finite - mid && low < mid + 1) {
        return None;
    }
    let mut values: Vec<f64> = raw.iter().copied().filter(|v| v.is_finite()).collect();
    let m = median(&mut values)?;
    (m.abs() >= RAW_COUNTS_MEDIAN).then_some(SanityWarning::RawCounts { median: m })
}

/// The dominant deviation from each cell's resting level (its median) is negative: a
/// sensor whose reading falls with pressure (e.g. 10-bit counts near 1020 at rest).
///
/// A cell's median is its rest only while it is touched for less than half the
/// recording: a press held longer makes its median the touch, and the quiet readings
/// then look like falls. So the same question is also asked across each frame (a
/// reading against the median of its frame, where untouched cells are the many): a
/// long touch rises above its frame, touch on a falling sensor falls below it. The
/// warning needs the frames to say "falls", and either the cells to say so too or the
/// falls to be a small minority of their frames (a touch too small to be a frame's
/// median: a contact covering most of the sleeve falls below nothing). A frame of
/// fewer than [`MIN_FRAME_CELLS`] cells has no such median, and then the cells' answer
/// stands alone.
pub(crate) fn falls_with_touch(raw: ArrayView3<f64>, threshold: f64) -> Option<SanityWarning> {
    // Per cell: readings below and above its rest by more than `threshold`, and the
    // deepest fall.
    let cells = map_cell_series(raw, |cell| {
        cell.retain(|v| v.is_finite());
        let Some(rest) = median(cell) else {
            return (0usize, 0usize, 0.0f64);
        };
        let (mut below, mut above, mut deepest) = (0, 0, 0.0f64);
        for &v in cell.iter() {
            let d = v - rest;
            if d < -threshold {
                below += 1;
                deepest = deepest.min(d);
            } else if d > threshold {
                above += 1;
            }
        }
        (below, above, deepest)
    });
    let (below, above, deepest) = cells
        .into_iter()
        .fold((0, 0, 0.0f64), |(b, a, d), (cb, ca, cd)| {
            (b + cb, a + ca, d.min(cd))
        });
    // Noise deviates both ways about equally; touch on a falling sensor only down.
    let falls = |below: usize, above: usize| below > 2 * above && below >= 10;
    let across = frame_deviations(raw, threshold, 0..raw.dim().0);
    let by_cells = falls(below, above);
    let decided = if across.frames == 0 {
        by_cells
    } else {
        let minority = (across.below as f64) < MINORITY * across.deviating_frame_cells as f64;
        falls(across.below, across.above) && (by_cells || minority)
    };
    if !decided {
        return None;
    }
    Some(SanityWarning::FallsWithTouch {
        below,
        above,
        threshold_psi: threshold,
        deepest,
    })
}

/// Fewest cells a frame needs for its median to stand for the untouched sleeve.
pub(crate) const MIN_FRAME_CELLS: usize = 8;

/// Readings that stand out from the rest of their frame, over some frames.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Deviations {
    /// Frames with at least [`MIN_FRAME_CELLS`] cells, the ones counted.
    frames: usize,
    /// Readings more than the threshold above their frame's median.
    above: usize,
    /// Readings more than the threshold below it.
    below: usize,
    /// The largest excess above the median, psi.
    highest: f64,
    /// Cells in the frames with a reading that deviates, either way.
    deviating_frame_cells: usize,
}

/// Share of a frame's cells below which its falls are a touch on a falling sensor
/// whatever its length, not the rest beside a contact covering most of the sleeve.
const MINORITY: f64 = 0.25;

/// [`Deviations`] of `raw`'s frames in `range`, on the rayon pool. Touch covers a
/// small part of a sleeve in any frame, so a frame's median is its untouched cells'
/// level, however long the touch lasts.
fn frame_deviations(
    raw: ArrayView3<f64>,
    threshold: f64,
    range: std::ops::Range<usize>,
) -> Deviations {
    use rayon::prelude::*;
    range
        .into_par_iter()
        .map_init(Vec::new, |values, f| {
            let frame = raw.index_axis(Axis(0), f);
            values.clear();
            values.extend(frame.iter().copied().filter(|v| v.is_finite()));
            if values.len() < MIN_FRAME_CELLS {
                return Deviations::default();
            }
            let Some(rest) = median(values) else {
                return Deviations::default();
            };
            let mut d = Deviations {
                frames: 1,
                ..Deviations::default()
            };
            for &v in values.iter() {
                if v - rest > threshold {
                    d.above += 1;
                    d.highest = d.highest.max(v - rest);
                } else if rest - v > threshold {
                    d.below += 1;
                }
            }
            if d.above + d.below > 0 {
                d.deviating_frame_cells = values.len();
            }
            d
        })
        .reduce(Deviations::default, |a, b| Deviations {
            frames: a.frames + b.frames,
            above: a.above + b.above,
            below: a.below + b.below,
            highest: a.highest.max(b.highest),
            deviating_frame_cells: a.deviating_frame_cells + b.deviating_frame_cells,
        })
}

/// When the tared frames hold no touch: whether the raw frames did, and so the tare
/// (not the recording) made the stimulus silent. Touch in the raw frames is a reading
/// more than the touch threshold above its frame's median, counted in the frames the
/// trim keeps; more than `input.min_touch_readings` of them is touch.
pub fn erased_touch(rec: &Recording, cfg: &Config, sampling: &Sampling) -> Option<InputWarning> {
    let raw = rec.data();
    let frames = raw.dim().0;
    let threshold = cfg.input.touch_threshold_psi;
    let trim = sampling.frames(cfg.input.trim_s).min(frames / 2);
    let kept = frame_deviations(raw, threshold, trim..frames - trim);
    if kept.above <= cfg.input.min_touch_readings {
        return None;
    }
    let tare = sampling.frames(cfg.input.tare_s).min(frames);
    let cause = if frames < MIN_TARE_FRAMES {
        ErasedBy::TooShort {
            needed: MIN_TARE_FRAMES,
        }
    } else if cfg.input.baseline == Baseline::Leading
        && frame_deviations(raw, threshold, 0..tare).above > 0
    {
        ErasedBy::TouchInTareWindow
    } else {
        ErasedBy::TouchThroughout
    };
    Some(InputWarning::TareErasedTouch {
        baseline: cfg.input.baseline,
        frames,
        raw_touch_readings: kept.above,
        highest_psi: kept.highest,
        cause,
    })
}

/// A last axis this many times as long as each of the others reads as time.
pub(crate) const TIME_LAST_RATIO: usize = 4;

/// The shape of a recording saved as `[rows, cols, frames]` instead of `[frames,
/// rows, cols]`: a last axis far longer than the other two (a recording holds more
/// frames than its grid has cells a side, a grid is rarely that elongated), or the
/// sleeve's grid in the first two axes. A warning, not a
/// refusal: a short recording on an unusual grid can look the same, and its summary
/// line shows the frames and grid read.
pub fn transposed(shape: (usize, usize, usize)) -> Option<InputWarning> {
    let (a, b, c) = shape;
    let sleeve = touchc_model::geometry::PAPER_GRID;
    let reason = if c >= TIME_LAST_RATIO * a.max(b) {
        TransposedBy::LastAxisLongest
    } else if (a, b) == sleeve {
        TransposedBy::SleeveGridFirst
    } else {
        return None;
    };
    Some(InputWarning::LikelyTransposed {
        shape: [a, b, c],
        reason,
    })
}

/// Fewest frames in which a cell's rest can be told from its touch: one frame is its
/// own baseline under either tare.
pub(crate) const MIN_TARE_FRAMES: usize = 2;

/// The paper's leading baseline averages the first `tare_s`: touch there is subtracted
/// from the whole recording. Compares each cell's mean in that window with its low
/// quantile over the whole recording (the `robust` baseline's zero).
pub(crate) fn touch_in_tare_window(
    raw: ArrayView3<f64>,
    cfg: &Config,
    sampling: &Sampling,
) -> Option<SanityWarning> {
    let frames = sampling.frames(cfg.input.tare_s).min(raw.dim().0);
    if frames == 0 {
        return None;
    }
    let threshold = cfg.input.touch_threshold_psi;
    let q = cfg.input.baseline_quantile.clamp(0.0, 1.0);
    // Per cell: how far its mean in the window lies above its rest, if it is read there.
    let excess = map_cell_series(raw, |values| {
        // The leading baseline's zero: the mean of the readings the cell has there.
        let (sum, read) = values[..frames]
            .iter()
            .filter(|v| v.is_finite())
            .fold((0.0, 0usize), |(sum, n), &v| (sum + v, n + 1));
        if read == 0 {
            return None; // tared by its quantile, not by this window
        }
        let mean = sum / read as f64;
        values.retain(|v| v.is_finite());
        let at = (q * (values.len() - 1) as f64).round() as usize;
        let (_, &mut rest, _) = values.select_nth_unstable_by(at, f64::total_cmp);
        Some(mean - rest)
    });
    let over: Vec<f64> = excess
        .into_iter()
        .flatten()
        .filter(|&e| e > threshold)
        .collect();
    let (cells, highest) = (over.len(), over.iter().fold(0.0f64, |m, &e| m.max(e)));
    (cells > 0).then_some(SanityWarning::TouchInTareWindow {
        cells,
        highest_psi: highest,
        tare_s: cfg.input.tare_s,
        frames,
    })
}

/// The pressure-weighted centroid, in cells, of the readings above `threshold` in each
/// frame (`None` in a frame without touch); frames on the rayon pool.
fn centroids(tared: ArrayView3<f64>, threshold: f64) -> Vec<Option<(f64, f64)>> {
    use rayon::prelude::*;
    (0..tared.dim().0)
        .into_par_iter()
        .map(|f| {
            let frame = tared.index_axis(Axis(0), f);
            let (mut w, mut r, mut c) = (0.0, 0.0, 0.0);
            for (row, readings) in frame.outer_iter().enumerate() {
                for (col, &v) in readings.iter().enumerate() {
                    if v > threshold {
                        w += v;
                        r += v * row as f64;
                        c += v * col as f64;
                    }
                }
            }
            (w > 0.0).then(|| (r / w, c / w))
        })
        .collect()
}

/// Touch whose centroid (`cs`, one per frame) moves faster than a hand: the rate or
/// the pitch given is probably too high.
fn speed_of(cs: &[Option<(f64, f64)>], sampling: &Sampling) -> Option<SanityWarning> {
    let mut speeds: Vec<f64> = cs
        .windows(2)
        .filter_map(|w| match (w[0], w[1]) {
            (Some(a), Some(b)) => {
                let cells = (a.0 - b.0).hypot(a.1 - b.1);
                Some(cells * sampling.pitch_mm * sampling.rate_hz)
            }
            _ => None,
        })
        .collect();
    if speeds.len() < MIN_STEPS {
        return None;
    }
    let m = median(&mut speeds)?;
    (m > MAX_PLAUSIBLE_SPEED_MM_S).then_some(SanityWarning::ImplausibleSpeed {
        median_mm_s: m,
        rate_hz: sampling.rate_hz,
        pitch_mm: sampling.pitch_mm,
    })
}

/// Every touch lasts a single frame (`cs`: the centroids, one per frame): the rate
/// given is probably far too low for the recording, or the sensor was sampled too
/// slowly to follow touch.
fn single_frames_of(cs: &[Option<(f64, f64)>], sampling: &Sampling) -> Option<SanityWarning> {
    let mut runs = Vec::new();
    let mut len = 0usize;
    for touched in cs.iter().map(Option::is_some).chain([false]) {
        if touched {
            len += 1;
        } else if len > 0 {
            runs.push(len);
            len = 0;
        }
    }
    (runs.len() >= MIN_SINGLE_FRAME_TOUCHES && runs.iter().all(|&n| n == 1)).then_some(
        SanityWarning::SingleFrameTouches {
            touches: runs.len(),
            rate_hz: sampling.rate_hz,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array3;

    /// The counting rule of [`raw_counts`] against the median itself, on readings
    /// around the bound (ties at exactly +-100 included) and with NaN among them.
    #[test]
    fn raw_counts_fires_exactly_when_the_median_is_out_of_bounds() {
        let levels = [f64::NAN, -150.0, -100.0, -99.0, 0.0, 99.0, 100.0, 150.0];
        let mut rng = touchc_test_rng::Xorshift::new(0x9e37_79b9_7f4a_7c15);
        for n in 1..40usize {
            for _ in 0..20 {
                let values: Vec<f64> = (0..n)
                    .map(|_| levels[(rng.next_u64() % levels.len() as u64) as usize])
                    .collect();
                let mut finite: Vec<f64> =
                    values.iter().copied().filter(|v| v.is_finite()).collect();
                finite.sort_by(f64::total_cmp);
                let expected = finite
                    .get(finite.len() / 2)
                    .is_some_and(|m| m.abs() >= RAW_COUNTS_MEDIAN);
                let raw = Array3::from_shape_vec((n, 1, 1), values.clone()).unwrap();
                assert_eq!(raw_counts(raw.view()).is_some(), expected, "{values:?}");
            }
        }
    }

    /// The cells' series, gathered eight at a time, are the time lanes of the
    /// recording, for a standard and a transposed (not contiguous) layout.
    #[test]
    fn cell_series_are_the_time_lanes() {
        let data = Array3::from_shape_fn((5, 3, 7), |(t, r, c)| (t * 100 + r * 10 + c) as f64);
        let transposed = data.view().reversed_axes().to_owned();
        let transposed = transposed.view().reversed_axes();
        for view in [data.view(), transposed] {
            let seen = map_cell_series(view, |s| s.clone());
            let lanes: Vec<Vec<f64>> = view
                .lanes(Axis(0))
                .into_iter()
                .map(|lane| lane.to_vec())
                .collect();
            assert_eq!(seen, lanes);
        }
    }

    /// 100 frames of 6 x 10 cells at rest `rest` with +-0.004 noise and, from frame
    /// 40 to 70, a 2 x 2 press of `press` (added) sliding one column every `step` frames
    /// (and back to column 0 after column 8).
    fn recording(rest: f64, press: f64, step: usize) -> Array3<f64> {
        let mut a = Array3::<f64>::zeros((100, 6, 10));
        let mut seed = 1u64;
        for v in a.iter_mut() {
            seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            *v = rest + 0.004 * ((seed >> 40) as f64 / (1u64 << 24) as f64 * 2.0 - 1.0);
        }
        for t in 40..70 {
            let c = ((t - 40) / step) % 9;
            for (r, c) in [(2, c), (3, c), (2, c + 1), (3, c + 1)] {
                a[[t, r, c]] += press;
            }
        }
        a
    }

    fn run(a: &Array3<f64>, cfg: &Config, sampling: &Sampling) -> Vec<SanityWarning> {
        let rec = Recording::from_array("x", a.view()).unwrap();
        let tared = rec.tare(&cfg.input, sampling).unwrap();
        check(&rec, tared.view(), cfg, sampling)
    }

    #[test]
    fn an_ordinary_recording_gets_no_warning() {
        let w = run(
            &recording(0.0, 2.0, 5),
            &Config::default(),
            &Sampling::PAPER,
        );
        assert!(w.is_empty(), "{w:?}");
    }

    #[test]
    fn raw_counts_are_named_with_the_median() {
        let w = run(
            &recording(512.0, 40.0, 5),
            &Config::default(),
            &Sampling::PAPER,
        );
        assert!(
            matches!(w[..], [SanityWarning::RawCounts { median }] if (median - 512.0).abs() < 0.5),
            "{w:?}"
        );
    }

    #[test]
    fn a_falling_sensor_is_named() {
        // 10-bit counts near 1020 at rest that fall by 300 under the press.
        let w = run(
            &recording(1020.0, -300.0, 5),
            &Config::default(),
            &Sampling::PAPER,
        );
        assert!(
            matches!(
                w[..],
                [
                    SanityWarning::RawCounts { .. },
                    SanityWarning::FallsWithTouch { below: 120, .. }
                ]
            ),
            "{w:?}"
        );
        // The same in psi-like units: only the falling warning.
        let w = run(
            &recording(5.0, -2.0, 5),
            &Config::default(),
            &Sampling::PAPER,
        );
        assert!(
            matches!(w[..], [SanityWarning::FallsWithTouch { deepest, .. }] if (deepest + 2.0).abs() < 0.01),
            "{w:?}"
        );
    }

    #[test]
    fn touch_in_the_tare_window_suggests_the_robust_baseline() {
        let mut a = recording(0.0, 2.0, 5);
        for t in 0..30 {
            a[[t, 0, 0]] += 1.5;
        }
        // The paper's leading baseline is the one the warning is about.
        let paper = Config::preset(touchc_model::config::Preset::Paper);
        let w = run(&a, &paper, &Sampling::PAPER);
        assert!(
            matches!(
                w[..],
                [SanityWarning::TouchInTareWindow { cells: 1, highest_psi, frames: 20, .. }]
                    if (highest_psi - 1.5).abs() < 0.005
            ),
            "{w:?}"
        );
        let mut robust = paper;
        robust.input.baseline = Baseline::Robust;
        assert!(run(&a, &robust, &Sampling::PAPER).is_empty());
    }

    #[test]
    fn a_rate_too_high_makes_the_touch_too_fast() {
        // One column per frame: 25.4 mm x 20 Hz = 0.5 m/s; at 200 Hz, 5.1 m/s.
        let a = recording(0.0, 2.0, 1);
        assert!(run(&a, &Config::default(), &Sampling::PAPER).is_empty());
        let fast = Sampling {
            rate_hz: 200.0,
            ..Sampling::PAPER
        };
        let mut short = Config::default();
        (short.input.tare_s, short.input.trim_s) = (0.1, 0.1);
        let w = run(&a, &short, &fast);
        assert!(
            matches!(
                w[..],
                [SanityWarning::ImplausibleSpeed { median_mm_s, rate_hz: 200.0, .. }]
                    if (median_mm_s / 1000.0 - 5.1).abs() < 0.05
            ),
            "{w:?}"
        );
    }

    #[test]
    fn single_frame_touches_suggest_the_rate() {
        let mut a = recording(0.0, 0.0, 5);
        for t in [30, 45, 60, 75] {
            a[[t, 3, 3]] += 1.0;
        }
        let w = run(&a, &Config::default(), &Sampling::PAPER);
        assert_eq!(
            w,
            [SanityWarning::SingleFrameTouches {
                touches: 4,
                rate_hz: 20.0
            }]
        );
        // Two frames each: plausible.
        for t in [31, 46, 61, 76] {
            a[[t, 3, 3]] += 1.0;
        }
        assert!(run(&a, &Config::default(), &Sampling::PAPER).is_empty());
    }
}
