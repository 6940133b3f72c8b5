//! Stage 0's tare: each cell's baseline, subtracted from its readings, and the trim at
//! both ends of the recording.

use ndarray::{Array2, Array3, ArrayView3, Axis};

use super::{Recording, RecordingError};
use crate::warning::InputWarning;
use touchc_model::config::{Baseline, InputConfig, Sampling};

impl Recording {
    /// Tare and trim: subtract each cell's baseline, drop `trim_s` at both ends, and turn
    /// NaN into 0. `sampling` turns the config's seconds into frames.
    ///
    /// The `leading` baseline (the paper) is each cell's mean over the first `tare_s`,
    /// of the readings it has there: a missing (NaN) reading in the window does not
    /// make the whole cell "no cell" (numpy's `mean` would), and a cell with no reading
    /// in the window but some later is tared by its `baseline_quantile` over the whole
    /// recording. A cell never read is 0 ("no cell"); a NaN reading elsewhere is 0 in
    /// that frame only. The `robust` baseline is each cell's `baseline_quantile` over
    /// the whole recording (NaN readings ignored; a cell with none is 0), so a recording
    /// may begin or end mid-touch.
    pub fn tare(
        &self,
        cfg: &InputConfig,
        sampling: &Sampling,
    ) -> Result<Array3<f64>, RecordingError> {
        self.tare_noting(cfg, sampling).map(|(tared, _)| tared)
    }

    /// [`Self::tare`], and what the tare had to work around: missing readings in the
    /// leading baseline's window ([`InputWarning::NanInTareWindow`]).
    pub fn tare_noting(
        &self,
        cfg: &InputConfig,
        sampling: &Sampling,
    ) -> Result<(Array3<f64>, Option<InputWarning>), RecordingError> {
        let tare = match cfg.baseline {
            Baseline::Leading => sampling.frames(cfg.tare_s),
            Baseline::Robust => 0,
        };
        let trim = sampling.frames(cfg.trim_s);
        let (t, _, _) = self.dim();
        let min = trim.saturating_mul(2).saturating_add(1).max(tare);
        if t < min {
            return Err(RecordingError::TooShort {
                name: self.name.clone(),
                frames: t,
                tare,
                min,
            });
        }
        let (baseline, note) = match cfg.baseline {
            Baseline::Leading => leading_baseline(self.data.view(), tare, cfg.baseline_quantile),
            Baseline::Robust => (
                robust_baseline(self.data.view(), cfg.baseline_quantile),
                None,
            ),
        };
        let kept = self.data.slice(ndarray::s![trim..t - trim, .., ..]);
        let tared = |v: f64, m: f64| {
            let x = v - m;
            if x.is_nan() {
                0.0
            } else {
                x
            }
        };
        let mut out = Array3::<f64>::zeros(kept.dim());
        match (out.as_slice_mut(), kept.as_slice(), baseline.as_slice()) {
            // Runs of frames on the rayon pool (an hour is 97 MB), each written once; a
            // short recording on this thread (handing it to the pool costs more).
            (Some(dst), Some(src), Some(base)) if !base.is_empty() => {
                use rayon::prelude::*;
                let run = base.len() * 256;
                let min_runs = if dst.len() < PARALLEL_TARE_VALUES {
                    usize::MAX
                } else {
                    1
                };
                dst.par_chunks_mut(run)
                    .zip(src.par_chunks(run))
                    .with_min_len(min_runs)
                    .for_each(|(dst, src)| {
                        for (d, s) in dst
                            .chunks_exact_mut(base.len())
                            .zip(src.chunks_exact(base.len()))
                        {
                            for ((d, &v), &m) in d.iter_mut().zip(s).zip(base) {
                                *d = tared(v, m);
                            }
                        }
                    });
            }
            _ => {
                out.assign(&kept);
                for mut frame in out.axis_iter_mut(Axis(0)) {
                    frame.zip_mut_with(&baseline, |v, &m| *v = tared(*v, m));
                }
            }
        }
        Ok((out, note))
    }
}

/// Below this many readings (about 6,000 frames of the paper's sleeve) the tare stays on
/// the calling thread.
const PARALLEL_TARE_VALUES: usize = 1 << 20;

/// Each cell's mean over the readings it has in the first `frames` frames (0 when
/// `frames` is 0), summed frame by frame as numpy reduces a non-contiguous axis: a cell
/// read in every one of them gets numpy's `mean`, bit for bit. A cell with no reading
/// there gets its `q`-quantile over the whole recording, or NaN ("no cell") when it is
/// never read. The note counts the cells with missing readings in the window.
fn leading_baseline(
    data: ArrayView3<f64>,
    frames: usize,
    q: f64,
) -> (Array2<f64>, Option<InputWarning>) {
    let (_, r, c) = data.dim();
    let mut baseline = Array2::<f64>::zeros((r, c));
    if frames == 0 {
        return (baseline, None);
    }
    let mut read = Array2::<usize>::zeros((r, c));
    for frame in data.axis_iter(Axis(0)).take(frames) {
        ndarray::Zip::from(&mut baseline)
            .and(&mut read)
            .and(&frame)
            .for_each(|sum, n, &v| {
                if !v.is_nan() {
                    *sum += v;
                    *n += 1;
                }
            });
    }
    let (mut cells, mut readings, mut unread_cells) = (0, 0, 0);
    for ((cell, sum), &n) in baseline.indexed_iter_mut().zip(&read) {
        if n == frames {
            *sum /= frames as f64;
            continue;
        }
        if n > 0 {
            *sum /= n as f64;
        } else {
            let mut series: Vec<f64> = data
                .slice(ndarray::s![.., cell.0, cell.1])
                .iter()
                .copied()
                .filter(|v| !v.is_nan())
                .collect();
            // NaN for a cell never read: "no cell", as the sleeve's padding.
            *sum = quantile(&mut series, q);
            if sum.is_nan() {
                continue;
            }
            unread_cells += 1;
        }
        cells += 1;
        readings += frames - n;
    }
    let note = (cells > 0).then_some(InputWarning::NanInTareWindow {
        tare_frames: frames,
        cells,
        readings,
        unread_cells,
        quantile: q,
    });
    (baseline, note)
}

/// Each cell's `q`-quantile over every frame (linear interpolation between order
/// statistics, numpy's default), NaN readings ignored; NaN for a cell that is never
/// read, which the tare then turns into 0 ("no cell").
fn robust_baseline(data: ArrayView3<f64>, q: f64) -> Array2<f64> {
    let (_, r, c) = data.dim();
    let quantiles = map_cell_series(data, |values| {
        values.retain(|v| !v.is_nan());
        quantile(values, q)
    });
    Array2::from_shape_fn((r, c), |(i, j)| quantiles[i * c + j])
}

/// `f(series)` for every cell of `data` (`[T, R, C]`), in row-major cell order, with the
/// cell's readings in time order (a scratch buffer `f` may reorder). The series are
/// gathered eight cells at a time in one pass over the frames: a cell's readings lie a
/// frame apart, so a pass per cell reads a whole cache line for each reading (an hour of
/// the paper's sleeve, 97 MB, read 168 times over). The groups of eight run on the rayon
/// pool, a few at a time (memory: eight series per thread), and the results come back
/// in cell order whatever the number of threads.
pub(crate) fn map_cell_series<R: Send>(
    data: ArrayView3<f64>,
    f: impl Fn(&mut Vec<f64>) -> R + Sync,
) -> Vec<R> {
    use rayon::prelude::*;
    const GROUP: usize = 8;
    let (t, r, c) = data.dim();
    let cells = r * c;
    let firsts: Vec<usize> = (0..cells).step_by(GROUP).collect();
    let groups: Vec<Vec<R>> = firsts
        .into_par_iter()
        .map(|first| {
            let n = GROUP.min(cells - first);
            // Eight series side by side, `t` readings each, filled by index (a push per
            // reading costs more than the reading).
            let mut group = vec![0.0; n * t];
            for (i, frame) in data.axis_iter(Axis(0)).enumerate() {
                match frame.as_slice() {
                    Some(readings) => {
                        for (k, &v) in readings[first..first + n].iter().enumerate() {
                            group[k * t + i] = v;
                        }
                    }
                    None => {
                        for k in 0..n {
                            let cell = first + k;
                            group[k * t + i] = frame[[cell / c, cell % c]];
                        }
                    }
                }
            }
            let mut series = Vec::with_capacity(t);
            group
                .chunks_exact(t.max(1))
                .take(n)
                .map(|readings| {
                    series.clear();
                    series.extend_from_slice(readings);
                    f(&mut series)
                })
                .collect()
        })
        .collect();
    groups.into_iter().flatten().collect()
}

/// The `q`-quantile of `values` (reordered in place); NaN when empty.
fn quantile(values: &mut [f64], q: f64) -> f64 {
    let n = values.len();
    if n == 0 {
        return f64::NAN;
    }
    let pos = q.clamp(0.0, 1.0) * (n - 1) as f64;
    let lo = (pos.floor() as usize).min(n - 1);
    let w = pos - lo as f64;
    // Two order statistics, not a sort: linear in the recording's length.
    let (_, &mut below, above) = values.select_nth_unstable_by(lo, f64::total_cmp);
    let next = above
        .iter()
        .copied()
        .min_by(f64::total_cmp)
        .unwrap_or(below);
    below + w * (next - below)
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array3;

    /// A recording long enough for the tare to run on the pool gives, reading for
    /// reading, the baseline subtracted (NaN as 0), trimmed at both ends.
    #[test]
    fn a_long_tare_on_the_pool_is_the_reading_minus_its_baseline() {
        let (t, r, c) = (6_400, 8, 21);
        assert!(t * r * c >= PARALLEL_TARE_VALUES);
        let a = Array3::from_shape_fn((t, r, c), |(f, i, j)| {
            if (f * 7 + i * 3 + j) % 101 == 0 {
                f64::NAN
            } else {
                ((f * 31 + i * 17 + j * 5) % 97) as f64 * 0.01 + i as f64
            }
        });
        let rec = Recording::from_array("long", a.view()).unwrap();
        let cfg = InputConfig {
            baseline: Baseline::Leading,
            tare_s: 0.5,
            trim_s: 1.0,
            ..InputConfig::default()
        };
        let tared = rec.tare(&cfg, &Sampling::PAPER).unwrap();
        let (base, _) = leading_baseline(a.view(), 10, 0.02);
        assert_eq!(tared.dim(), (t - 40, r, c));
        for ((f, i, j), &v) in tared.indexed_iter() {
            let x = a[[f + 20, i, j]] - base[[i, j]];
            let expected = if x.is_nan() { 0.0 } else { x };
            assert_eq!(
                v.to_bits(),
                expected.to_bits(),
                "frame {f}, cell ({i}, {j})"
            );
        }
    }

    #[test]
    fn tare_subtracts_baseline_and_trims() {
        let mut a = Array3::<f64>::zeros((5, 1, 2));
        for t in 0..5 {
            a[[t, 0, 0]] = t as f64;
            a[[t, 0, 1]] = 10.0;
        }
        let rec = Recording::from_array("x", a.view()).unwrap();
        // 2 frames of tare and trim at 20 Hz.
        let cfg = InputConfig {
            tare_s: 0.1,
            trim_s: 0.1,
            ..InputConfig::default()
        };
        let tared = rec.tare(&cfg, &Sampling::PAPER).unwrap();
        assert_eq!(tared.dim(), (1, 1, 2));
        assert_eq!(tared[[0, 0, 0]], 2.0 - 0.5);
        assert_eq!(tared[[0, 0, 1]], 0.0);
    }

    #[test]
    fn too_short_names_minimum() {
        let a = Array3::<f64>::zeros((40, 2, 2));
        let rec = Recording::from_array("short.npy", a.view()).unwrap();
        let err = rec
            .tare(&InputConfig::default(), &Sampling::PAPER)
            .unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("short.npy") && msg.contains("41"), "{msg}");
    }

    /// A recording that starts mid-press: the leading baseline tares the press away,
    /// the robust one keeps it.
    #[test]
    fn robust_baseline_keeps_a_press_at_the_start() {
        let mut a = Array3::<f64>::from_elem((100, 1, 2), 0.3);
        for t in 0..40 {
            a[[t, 0, 0]] = 2.3; // pressed by 2 psi for the first 2 s
        }
        let rec = Recording::from_array("mid-press", a.view()).unwrap();
        let leading = rec.tare(&InputConfig::default(), &Sampling::PAPER).unwrap();
        assert!(
            leading[[0, 0, 0]].abs() < 1e-12,
            "the paper's tare removes the press"
        );
        let robust = InputConfig {
            baseline: Baseline::Robust,
            ..InputConfig::default()
        };
        let tared = rec.tare(&robust, &Sampling::PAPER).unwrap();
        assert_eq!(tared.dim(), (60, 1, 2));
        // Frames 20..40 of the recording are the first 20 after the trim.
        assert!((tared[[0, 0, 0]] - 2.0).abs() < 1e-12);
        assert!((tared[[19, 0, 0]] - 2.0).abs() < 1e-12);
        assert!(tared[[20, 0, 0]].abs() < 1e-12);
        assert!(tared
            .slice(ndarray::s![.., 0, 1])
            .iter()
            .all(|v| v.abs() < 1e-12));
    }

    #[test]
    fn quantile_by_selection_equals_quantile_by_sorting() {
        let mut rng = touchc_test_rng::Xorshift::new(0x2545_f491_4f6c_dd1d);
        for n in [1usize, 2, 3, 10, 101, 1000] {
            let values: Vec<f64> = (0..n)
                .map(|_| {
                    // Repeats are common in sensor data: a few hundred distinct levels.
                    (rng.next_u64() % 300) as f64 * 0.01 - 0.5
                })
                .collect();
            for q in [0.0, 0.02, 0.1, 0.5, 0.98, 1.0] {
                let mut sorted = values.clone();
                sorted.sort_by(f64::total_cmp);
                let pos = q * (n - 1) as f64;
                let (lo, hi) = (pos.floor() as usize, (pos.floor() as usize + 1).min(n - 1));
                let want = sorted[lo] + (pos - lo as f64) * (sorted[hi] - sorted[lo]);
                assert_eq!(quantile(&mut values.clone(), q), want, "n {n}, q {q}");
            }
        }
    }

    #[test]
    fn quantile_interpolates_like_numpy() {
        // numpy.quantile([4, 1, 3, 2], 0.1) = 1.3
        assert!((quantile(&mut [4.0, 1.0, 3.0, 2.0], 0.1) - 1.3).abs() < 1e-12);
        assert!(quantile(&mut [], 0.1).is_nan());
    }
}
