//! Stage 1: nearest-neighbour upsampling and Gaussian blur, plus the global statistics.
//!
//! The blur follows `scipy.ndimage.gaussian_filter` defaults (reflect boundary, i.e.
//! `d c b a | a b c d | d c b a`; kernel radius `int(truncate * sigma + 0.5)`). Upsampling
//! and the separable blur are both linear, so each frame is blurred as one matrix product
//! `A * F * B^T` where `A` (`R k x R`) and `B` (`C k x C`) fold the k x k block replication
//! and the reflected kernel together: about 30 times fewer operations than blurring the
//! upsampled frame, and no upsampled temporary.
//!
//! Everything is computed and kept in f64: the reference matches to 1e-9 relative, and
//! local maxima compare neighbouring values that often differ only in the last digits.

use std::ops::Range;
use std::time::{Duration, Instant};

use ndarray::{Array2, Array3, ArrayView1, ArrayView2, ArrayView3, ArrayViewMut2, Axis};

use touchc_model::config::{PreprocessConfig, Sampling, MAX_UPSAMPLE};

/// Why a preprocessing configuration cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PreprocessError {
    /// `upsample` must be at least 1 and at most [`MAX_UPSAMPLE`].
    #[error("upsampling factor must be at least 1 and at most {MAX_UPSAMPLE}, got {0}")]
    BadUpsample(usize),
    /// The blur's sigma and truncate must be finite and non-negative.
    #[error(
        "blur sigma and truncate must be finite and >= 0, got sigma {sigma}, truncate {truncate}"
    )]
    BadBlur {
        /// The configured sigma.
        sigma: f64,
        /// The configured truncate.
        truncate: f64,
    },
}

/// The blur in pixels: what [`BlurOperator`] builds its matrices from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Blur {
    /// Nearest-neighbour upsampling factor `k`.
    pub upsample: usize,
    /// Gaussian sigma, upsampled pixels.
    pub sigma_px: f64,
    /// Kernel half-width in sigmas (scipy's `truncate`).
    pub truncate: f64,
}

impl Blur {
    /// The blur `cfg` asks for at `sampling` (its sigma in mm as pixels).
    pub fn new(cfg: &PreprocessConfig, sampling: &Sampling) -> Self {
        Blur {
            upsample: sampling.upsample,
            sigma_px: sampling.px(cfg.blur_sigma_mm),
            truncate: cfg.blur_truncate,
        }
    }
}

/// The blurred movie and its global statistics: the input of detection and of the
/// per-actuator signal stage.
#[derive(Debug, Clone, PartialEq)]
pub struct Blurred {
    /// Blurred frames `[T, R k, C k]` in psi, f64.
    pub frames: Array3<f64>,
    /// Mean over every pixel of every frame.
    pub mean: f64,
    /// Population standard deviation over every pixel of every frame.
    pub std: f64,
    /// Pixel pitch after upsampling, mm (cell pitch / k).
    pub pitch_mm: f64,
}

/// scipy's 1-D Gaussian weights: `exp(-x^2 / (2 sigma^2))` for `|x| <= radius`, normalised.
///
/// `sigma = 0` is the identity (scipy would divide by zero).
pub fn gaussian_kernel(sigma: f64, truncate: f64) -> Vec<f64> {
    if sigma == 0.0 {
        return vec![1.0];
    }
    // scipy: radius = int(truncate * sigma + 0.5); the cast truncates toward zero.
    let radius = (truncate * sigma + 0.5) as i64;
    let w: Vec<f64> = (-radius..=radius)
        .map(|x| (-0.5 / (sigma * sigma) * (x * x) as f64).exp())
        .collect();
    let sum: f64 = w.iter().sum();
    w.into_iter().map(|v| v / sum).collect()
}

/// Index of `i` under scipy's `reflect` extension of a length-`n` axis.
///
/// The extension is periodic with period `2n`, which also covers kernels wider than the
/// axis (a 1-row recording upsampled x7 is narrower than the 25-tap kernel).
pub(crate) fn reflect_index(i: i64, n: usize) -> usize {
    let n = n as i64;
    let m = i.rem_euclid(2 * n);
    (if m >= n { 2 * n - 1 - m } else { m }) as usize
}

/// Matrix `(n k) x n` that upsamples a length-`n` axis by `k` and then blurs it with
/// `kernel` under reflect boundaries.
fn axis_operator(n: usize, k: usize, kernel: &[f64]) -> Array2<f64> {
    let big = n * k;
    let radius = (kernel.len() / 2) as i64;
    let mut op = Array2::<f64>::zeros((big, n));
    for i in 0..big {
        for (d, &w) in (-radius..=radius).zip(kernel) {
            let j = reflect_index(i as i64 + d, big);
            op[[i, j / k]] += w;
        }
    }
    op
}

/// The per-frame linear map `F -> A F B^T` (upsample then blur), built once per shape.
///
/// `A` and `B` are banded (a pixel only sees cells within the kernel radius), so each
/// row keeps the range of its non-zero columns and the products skip the zeros: about
/// half the work of a dense product, with no temporary allocation per frame.
#[derive(Debug, Clone)]
pub struct BlurOperator {
    a: Banded,
    b: Banded,
    rows: usize,
    cols: usize,
}

/// A dense matrix plus, per row, the half-open range of columns that can be non-zero.
#[derive(Debug, Clone)]
struct Banded {
    m: Array2<f64>,
    range: Vec<(usize, usize)>,
    /// The transpose, per column `c` the rows `j` whose range holds `c` (`B^T` row `c`
    /// over those rows), when they are contiguous for every column, as a band is.
    by_column: Option<ByColumn>,
}

/// `B^T` with, per row `c` of it, the half-open range of `j` in which `c` lies in row
/// `j`'s range of `B`.
#[derive(Debug, Clone)]
struct ByColumn {
    /// `B^T`, `cols x w`, row-major, zero outside each row's range.
    t: Vec<f64>,
    range: Vec<(usize, usize)>,
}

impl Banded {
    fn new(m: Array2<f64>) -> Self {
        let range: Vec<(usize, usize)> = m
            .outer_iter()
            .map(|row| {
                let lo = row.iter().position(|&v| v != 0.0).unwrap_or(0);
                let hi = row.iter().rposition(|&v| v != 0.0).map_or(lo, |i| i + 1);
                (lo, hi)
            })
            .collect();
        let by_column = ByColumn::new(&m, &range);
        Self {
            m,
            range,
            by_column,
        }
    }
}

impl ByColumn {
    /// `None` when some column's rows are not contiguous (a kernel folded over a
    /// narrow axis more than once may do that; a band never does).
    fn new(m: &Array2<f64>, range: &[(usize, usize)]) -> Option<Self> {
        let (w, cols) = m.dim();
        let mut t = vec![0.0; cols * w];
        let mut by_c = Vec::with_capacity(cols);
        for c in 0..cols {
            let holds = |j: usize| range[j].0 <= c && c < range[j].1;
            let lo = (0..w).find(|&j| holds(j)).unwrap_or(0);
            let hi = (0..w).rfind(|&j| holds(j)).map_or(lo, |j| j + 1);
            if !(lo..hi).all(holds) {
                return None;
            }
            for j in lo..hi {
                t[c * w + j] = m[[j, c]];
            }
            by_c.push((lo, hi));
        }
        Some(ByColumn { t, range: by_c })
    }
}

impl BlurOperator {
    /// Builds the operator for `rows x cols` frames.
    pub fn new(rows: usize, cols: usize, cfg: &Blur) -> Result<Self, PreprocessError> {
        validate(cfg)?;
        let kernel = gaussian_kernel(cfg.sigma_px, cfg.truncate);
        let a = Banded::new(axis_operator(rows, cfg.upsample, &kernel));
        let b = Banded::new(axis_operator(cols, cfg.upsample, &kernel));
        Ok(Self { a, b, rows, cols })
    }

    /// Upsamples and blurs one frame (no NaN: a NaN would spread over whole rows).
    ///
    /// Panics if the frame shape differs from the one the operator was built for.
    pub fn apply(&self, frame: ArrayView2<f64>) -> Array2<f64> {
        let mut out = Array2::zeros(self.out_dim());
        let mut scratch = Vec::new();
        self.apply_into(frame, out.view_mut(), &mut scratch);
        out
    }

    /// [`Self::apply`] into a caller-owned frame, reusing `scratch` between calls.
    pub(crate) fn apply_into(
        &self,
        frame: ArrayView2<f64>,
        out: ArrayViewMut2<f64>,
        scratch: &mut Vec<f64>,
    ) {
        blur_into(self, frame, out, scratch);
    }

    /// Output frame shape `(R k, C k)`.
    pub fn out_dim(&self) -> (usize, usize) {
        (self.a.m.nrows(), self.b.m.nrows())
    }
}

touchc_wide::kernel! {
    /// [`BlurOperator::apply_into`]; compiled for AVX2 too (`touchc_wide`).
    fn blur_into / blur_into_baseline / blur_into_avx2 (
        op: &BlurOperator,
        frame: ArrayView2<f64>,
        out: ArrayViewMut2<f64>,
        scratch: &mut Vec<f64>,
    ) {
        let mut out = out;
            assert_eq!(frame.dim(), (op.rows, op.cols), "frame shape");
            let (h, w) = op.out_dim();
            assert_eq!(out.dim(), (h, w), "output shape");
            // Y = F B^T, rows x w. Each `Y[r, j]` is the sum over `c` in row `j`'s range,
            // in ascending `c`, from -0.0 (as `Iterator::sum`): by columns of `B^T` when it
            // has them (whole runs of `j` at once, which vectorises), else row by row; the
            // same additions in the same order either way.
            scratch.clear();
            scratch.resize(op.rows * w, -0.0);
            for (r, src) in frame.outer_iter().enumerate() {
                let y = &mut scratch[r * w..(r + 1) * w];
                match &op.b.by_column {
                    Some(bt) => {
                        for (c, (&f, &(lo, hi))) in src.iter().zip(&bt.range).enumerate() {
                            let col = &bt.t[c * w + lo..c * w + hi];
                            for (yj, &b) in y[lo..hi].iter_mut().zip(col) {
                                *yj += f * b;
                            }
                        }
                    }
                    None => {
                        for (j, yj) in y.iter_mut().enumerate() {
                            let (lo, hi) = op.b.range[j];
                            let brow = op.b.m.row(j);
                            *yj = (lo..hi).map(|c| src[c] * brow[c]).sum();
                        }
                    }
                }
            }
            // out = A Y: each output row is a short sum of whole Y rows (vectorises).
            for (i, mut orow) in out.outer_iter_mut().enumerate() {
                let (lo, hi) = op.a.range[i];
                let weights = op.a.m.row(i);
                let sum = |o: &mut [f64]| {
                    o.fill(0.0);
                    for r in lo..hi {
                        let wgt = weights[r];
                        for (o, &y) in o.iter_mut().zip(&scratch[r * w..(r + 1) * w]) {
                            *o += wgt * y;
                        }
                    }
                };
                match orow.as_slice_mut() {
                    Some(o) => sum(o),
                    None => {
                        let mut o = orow.to_vec();
                        sum(&mut o);
                        orow.assign(&ArrayView1::from(&o));
                    }
                }
            }
    }
}

fn validate(cfg: &Blur) -> Result<(), PreprocessError> {
    if cfg.upsample == 0 || cfg.upsample > MAX_UPSAMPLE {
        return Err(PreprocessError::BadUpsample(cfg.upsample));
    }
    let ok = |v: f64| v.is_finite() && v >= 0.0;
    if !ok(cfg.sigma_px) || !ok(cfg.truncate) {
        return Err(PreprocessError::BadBlur {
            sigma: cfg.sigma_px,
            truncate: cfg.truncate,
        });
    }
    Ok(())
}

/// Upsamples and blurs every tared frame and computes the global mean and std: the
/// whole blurred movie, for the stage benchmarks, the tests and the previews (the
/// pipeline itself streams, see `blur_stream`).
///
/// `tared` must be NaN-free (see [`touchc_input::recording::Recording::tare`]); `sampling` gives
/// the cell pitch and upsampling factor.
pub fn preprocess(
    tared: ArrayView3<f64>,
    cfg: &PreprocessConfig,
    sampling: &Sampling,
) -> Result<Blurred, PreprocessError> {
    let (t, r, c) = tared.dim();
    let (h, w) = BlurOperator::new(r, c, &Blur::new(cfg, sampling))?.out_dim();
    let mut frames = Array3::<f64>::zeros((t, h, w));
    let stats = blur_stream(tared, cfg, sampling, |f, frame| {
        frames.index_axis_mut(Axis(0), f).assign(&frame);
    })?;
    Ok(Blurred {
        frames,
        mean: stats.mean,
        std: stats.std,
        pitch_mm: stats.pitch_mm,
    })
}

/// What the blurred movie's detection needs of it as a whole, from [`blur_stream`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct BlurStats {
    /// Mean of every blurred pixel of every frame.
    pub mean: f64,
    /// Population standard deviation of the same.
    pub std: f64,
    /// Pixel pitch after upsampling, mm.
    pub pitch_mm: f64,
    /// Shape of one blurred frame, `(rows, cols)` in pixels.
    pub frame_dim: (usize, usize),
}

/// Upsamples and blurs the tared frames one at a time, calls `visit(t, frame)` on each
/// and keeps none: memory is one frame, whatever the recording's length. The mean and
/// std are those [`preprocess`] gives, bit for bit (per-frame moments combined in the
/// same order).
pub(crate) fn blur_stream(
    tared: ArrayView3<f64>,
    cfg: &PreprocessConfig,
    sampling: &Sampling,
    mut visit: impl FnMut(usize, ArrayView2<f64>),
) -> Result<BlurStats, PreprocessError> {
    let (t, r, c) = tared.dim();
    let op = BlurOperator::new(r, c, &Blur::new(cfg, sampling))?;
    let mut blur = FrameBlur::new(&op);
    let mut moments = Vec::with_capacity(t);
    for (f, src) in tared.axis_iter(Axis(0)).enumerate() {
        moments.push(blur.next(src));
        visit(f, blur.frame.view());
    }
    Ok(BlurStats::of(&moments, blur.frame.dim(), sampling))
}

/// Frames per run of [`blur_chunks`]: enough that a run's set-up (a frame buffer) is
/// nothing beside its frames, few enough that a short recording still splits.
const CHUNK_FRAMES: usize = 64;

/// [`blur_stream`] on the current rayon pool: the frames are blurred in runs of
/// 64 frames, each run on one thread, visited in frame order within the run
/// (`visit(&mut state, t, frame)`, with `state = start(run)`), and the runs' states
/// handed to `merge` in frame order with the run's wall time. A few runs per thread
/// are in flight at a time, so memory is what `merge` keeps plus those runs' states.
/// The statistics are [`blur_stream`]'s, bit for bit: each frame's moments do not
/// depend on the run it is in, and they are combined in frame order.
pub(crate) fn blur_chunks<S: Send>(
    tared: ArrayView3<f64>,
    cfg: &PreprocessConfig,
    sampling: &Sampling,
    start: impl Fn(Range<usize>) -> S + Sync,
    visit: impl Fn(&mut S, usize, ArrayView2<f64>) + Sync,
    mut merge: impl FnMut(S, Duration),
) -> Result<BlurStats, PreprocessError> {
    use rayon::prelude::*;
    let (t, r, c) = tared.dim();
    let op = BlurOperator::new(r, c, &Blur::new(cfg, sampling))?;
    let dim = op.out_dim();
    let wave = CHUNK_FRAMES * 2 * rayon::current_num_threads().max(1);
    let mut moments = Vec::with_capacity(t);
    for first in (0..t).step_by(wave) {
        let end = (first + wave).min(t);
        let runs: Vec<Range<usize>> = (first..end)
            .step_by(CHUNK_FRAMES)
            .map(|a| a..(a + CHUNK_FRAMES).min(end))
            .collect();
        let done: Vec<_> = runs
            .into_par_iter()
            .map(|run| {
                let clock = Instant::now();
                let mut blur = FrameBlur::new(&op);
                let mut state = start(run.clone());
                let mut run_moments = Vec::with_capacity(run.len());
                for f in run {
                    run_moments.push(blur.next(tared.index_axis(Axis(0), f)));
                    visit(&mut state, f, blur.frame.view());
                }
                (state, run_moments, clock.elapsed())
            })
            .collect();
        for (state, run_moments, took) in done {
            moments.extend(run_moments);
            merge(state, took);
        }
    }
    Ok(BlurStats::of(&moments, dim, sampling))
}

/// One blurred frame at a time: the operator, the frame and the scratch it reuses.
struct FrameBlur<'a> {
    op: &'a BlurOperator,
    frame: Array2<f64>,
    scratch: Vec<f64>,
}

impl<'a> FrameBlur<'a> {
    fn new(op: &'a BlurOperator) -> Self {
        let frame = Array2::zeros(op.out_dim());
        FrameBlur {
            op,
            frame,
            scratch: Vec::new(),
        }
    }

    /// Blurs `src` into `self.frame` and returns the frame's mean and std.
    fn next(&mut self, src: ArrayView2<f64>) -> (f64, f64) {
        self.op
            .apply_into(src, self.frame.view_mut(), &mut self.scratch);
        match self.frame.as_slice() {
            Some(s) => mean_std(s),
            None => mean_std(&self.frame.iter().copied().collect::<Vec<_>>()),
        }
    }
}

impl BlurStats {
    /// The statistics of frames of shape `dim` with per-frame `moments` (mean, std).
    fn of(moments: &[(f64, f64)], dim: (usize, usize), sampling: &Sampling) -> Self {
        let (mean, std) = combine(moments, dim.0 * dim.1);
        BlurStats {
            mean,
            std,
            pitch_mm: sampling.pixel_mm(),
            frame_dim: dim,
        }
    }
}

fn combine(stats: &[(f64, f64)], n: usize) -> (f64, f64) {
    if stats.is_empty() || n == 0 {
        return (0.0, 0.0);
    }
    let chunks = stats.len() as f64;
    let means: Vec<f64> = stats.iter().map(|s| s.0).collect();
    let mean = blocked_sum(&means, |v| v) / chunks;
    let big = stats
        .iter()
        .fold(0.0f64, |m, s| m.max(s.1).max((s.0 - mean).abs()));
    if big == 0.0 {
        return (mean, 0.0);
    }
    let scale = 2f64.powf(-big.log2().floor());
    let terms: Vec<f64> = stats
        .iter()
        .map(|&(m, s)| {
            let (a, b) = (s * scale, (m - mean) * scale);
            a * a + b * b
        })
        .collect();
    (mean, (blocked_sum(&terms, |v| v) / chunks).sqrt() / scale)
}

/// Sum of `f(v)` over `values`: plain sums in eight lanes over blocks of 1024 values
/// (vectorises), blocks combined with Neumaier compensation, so the mean of millions of
/// values keeps all its digits at a fraction of the cost of compensating every value.
#[inline(always)]
fn blocked_sum(values: &[f64], f: impl Fn(f64) -> f64) -> f64 {
    let (mut sum, mut comp) = (0.0f64, 0.0f64);
    for block in values.chunks(1024) {
        let mut lanes = [0.0f64; 8];
        let mut it = block.chunks_exact(8);
        for c in &mut it {
            for (l, &v) in lanes.iter_mut().zip(c) {
                *l += f(v);
            }
        }
        let tail: f64 = it.remainder().iter().map(|&v| f(v)).sum();
        let b = lanes.iter().sum::<f64>() + tail;
        let t = sum + b;
        comp += if sum.abs() >= b.abs() {
            (sum - t) + b
        } else {
            (b - t) + sum
        };
        sum = t;
    }
    sum + comp
}

touchc_wide::kernel! {
    /// Population mean and standard deviation (numpy's `mean`, `std` with `ddof = 0`),
    /// two-pass with compensated block sums.
    ///
    /// Values far from 1 are scaled by a power of two (exact) before squaring, so the sum
    /// of squares neither overflows for 1e30-psi data nor underflows for 1e-30-psi data.
    ///
    /// Compiled for AVX2 too, picked at run time: the same numbers either way.
    pub(crate) fn mean_std / mean_std_baseline / mean_std_avx2 (values: &[f64]) -> (f64, f64) {
        if values.is_empty() {
            return (0.0, 0.0);
        }
        // A comparison, not `f64::max`: the same maximum (a NaN is skipped either way, as
        // it never compares greater), in one instruction instead of a NaN-aware sequence.
        // Eight independent running maxima (vectorises; one chain of maxima does not).
        let larger = |m: f64, v: f64| if v > m { v } else { m };
        let mut lanes = [0.0f64; 8];
        let mut chunks = values.chunks_exact(8);
        for chunk in &mut chunks {
            for (l, v) in lanes.iter_mut().zip(chunk) {
                *l = larger(*l, v.abs());
            }
        }
        let max_abs = chunks
            .remainder()
            .iter()
            .map(|v| v.abs())
            .chain(lanes)
            .fold(0.0f64, larger);
        if max_abs == 0.0 {
            return (0.0, 0.0);
        }
        let scale = if (1e-100..1e100).contains(&max_abs) {
            1.0
        } else {
            2f64.powf(-max_abs.log2().floor())
        };
        let n = values.len() as f64;
        let mean_s = blocked_sum(values, |v| v * scale) / n;
        let var_s = blocked_sum(values, |v| {
            let d = v * scale - mean_s;
            d * d
        }) / n;
        (mean_s / scale, var_s.sqrt() / scale)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frames of random bumps over a few decades, some with exact plateaus.
    fn random_frames(seed: u64, count: usize, dim: (usize, usize)) -> Vec<Array2<f64>> {
        let mut rng = touchc_test_rng::Xorshift::new(seed);
        let mut next = move || rng.uniform();
        (0..count)
            .map(|i| {
                let scale = 10f64.powi(i as i32 % 7 - 3);
                Array2::from_shape_fn(dim, |_| {
                    let v = next();
                    if v < 0.2 {
                        0.0
                    } else {
                        scale * (v - 0.2).powi(3)
                    }
                })
            })
            .collect()
    }

    /// The AVX2 builds of the blur and of the mean and std give the baseline's numbers
    /// to the bit ([`touchc_wide`]); on a CPU without AVX2 there is one build only.
    #[test]
    fn the_avx2_builds_compute_the_baseline_numbers() {
        if !touchc_wide::avx2_or_skip(
            "preprocess::tests::the_avx2_builds_compute_the_baseline_numbers",
        ) {
            return;
        }
        let sampling = Sampling::PAPER;
        let op = BlurOperator::new(8, 21, &Blur::new(&PreprocessConfig::default(), &sampling))
            .expect("the paper's blur");
        let (mut a, mut b) = (Array2::zeros(op.out_dim()), Array2::zeros(op.out_dim()));
        let (mut sa, mut sb) = (Vec::new(), Vec::new());
        for frame in random_frames(7, 40, (8, 21)) {
            blur_into_baseline(&op, frame.view(), a.view_mut(), &mut sa);
            // SAFETY: the CPU runs AVX2 (checked above).
            unsafe { blur_into_avx2(&op, frame.view(), b.view_mut(), &mut sb) };
            assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
            let values = a.as_slice().expect("standard layout");
            let (m0, s0) = mean_std_baseline(values);
            // SAFETY: as above.
            let (m1, s1) = unsafe { mean_std_avx2(values) };
            assert_eq!((m0.to_bits(), s0.to_bits()), (m1.to_bits(), s1.to_bits()));
        }
        for values in [&[1e300, -1e300, 3.0][..], &[1e-300; 9], &[]] {
            // SAFETY: as above.
            let wide = unsafe { mean_std_avx2(values) };
            assert_eq!(
                format!("{:?}", mean_std_baseline(values)),
                format!("{wide:?}")
            );
        }
    }

    #[test]
    fn kernel_matches_scipy_radius_and_normalisation() {
        let k = gaussian_kernel(3.0, 4.0);
        assert_eq!(k.len(), 25);
        assert!((k.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert!(k[12] > k[11] && (k[0] - k[24]).abs() == 0.0);
    }

    #[test]
    fn reflect_is_half_sample_symmetric() {
        let idx: Vec<usize> = (-4..7).map(|i| reflect_index(i, 3)).collect();
        assert_eq!(idx, vec![2, 2, 1, 0, 0, 1, 2, 2, 1, 0, 0]);
    }

    /// A recording of `t` frames of 3 x 5 cells, a ramp with a bump that moves.
    fn moving(t: usize) -> Array3<f64> {
        Array3::from_shape_fn((t, 3, 5), |(f, r, c)| {
            0.001 * (f + r + c) as f64 + if (f / 7) % 5 == c { 0.8 } else { 0.0 }
        })
    }

    #[test]
    fn runs_on_any_number_of_threads_give_the_stream_bit_for_bit() {
        let tared = moving(300); // five runs of 64 frames, the last short
        let (cfg, sampling) = (PreprocessConfig::default(), Sampling::PAPER);
        let mut whole = Vec::new();
        let stream = blur_stream(tared.view(), &cfg, &sampling, |f, frame| {
            whole.push((f, frame.sum()));
        })
        .unwrap();
        for threads in [1, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut merged = Vec::new();
            let chunks = pool
                .install(|| {
                    blur_chunks(
                        tared.view(),
                        &cfg,
                        &sampling,
                        |_| Vec::new(),
                        |seen: &mut Vec<(usize, f64)>, f, frame| seen.push((f, frame.sum())),
                        |seen, _| merged.extend(seen),
                    )
                })
                .unwrap();
            assert_eq!(chunks, stream, "{threads} threads");
            assert_eq!(merged, whole, "{threads} threads");
        }
    }

    #[test]
    fn mean_std_matches_textbook_and_survives_extremes() {
        let v = [1.0, 2.0, 3.0, 4.0];
        let (m, s) = mean_std(&v);
        assert_eq!(m, 2.5);
        assert!((s - 1.25f64.sqrt()).abs() < 1e-15);
        let big: Vec<f64> = v.iter().map(|x| x * 1e300).collect();
        let (mb, sb) = mean_std(&big);
        assert!(
            (mb / 2.5e300 - 1.0).abs() < 1e-15
                && (sb / (1.25f64.sqrt() * 1e300) - 1.0).abs() < 1e-14
        );
    }
}
