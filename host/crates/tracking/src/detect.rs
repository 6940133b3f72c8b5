//! Stage 2: detections (local maxima of the blurred frames, a plateau counting once) and
//! their log-odds cost.
//!
//! Detections are enumerated frame by frame, each frame in row-major order (numpy's
//! `np.where` order in the published code). That order numbers the flow graph's nodes and
//! so decides every tie downstream.
//!
//! One deliberate difference from the published code: it also forbids maxima at pixels
//! with fewer than 5 in-frame neighbours (`findBadCells`, which after the blur only ever
//! hits the four frame corners). The contract (docs/algorithm.md section 2) has no such rule,
//! so corners may be detections here (the reference trajectories are unaffected).

use ndarray::ArrayView2;

use crate::preprocess::Blurred;
use touchc_model::config::{DetectConfig, Split};

mod lattice;
mod plateau;

pub(crate) use lattice::lattice_points_of_contacts;
#[cfg(test)]
use lattice::{lattice_points, with_lattice};

/// One local maximum of one blurred frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    /// Frame index (after tare/trim).
    pub frame: usize,
    /// Pixel row in the upsampled frame.
    pub row: usize,
    /// Pixel column in the upsampled frame.
    pub col: usize,
    /// Blurred pressure at the pixel, psi.
    pub value: f64,
    /// `ln((1 - P) / P)`, negative for strong detections.
    pub cost: f64,
    /// A lattice point of a flat contact ([`Split`]): a cell fixed on the sensor, which
    /// stands for the pressure there and does not move with its contact (the contact's
    /// local maximum does). Tracking links it only to the same cell.
    pub fixed: bool,
}

/// All detections of a movie, frame-major.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Detections {
    /// Every detection, sorted by frame, then row, then column.
    pub all: Vec<Detection>,
    /// `frame_start[t]..frame_start[t + 1]` indexes the detections of frame `t`.
    pub frame_start: Vec<usize>,
}

impl Detections {
    /// No detection in any of `frames` frames.
    pub fn empty(frames: usize) -> Self {
        Detections {
            all: Vec::new(),
            frame_start: vec![0; frames + 1],
        }
    }

    /// Detections of frame `t` (empty when `t` is out of range).
    pub fn in_frame(&self, t: usize) -> &[Detection] {
        match (self.frame_start.get(t), self.frame_start.get(t + 1)) {
            (Some(&a), Some(&b)) => &self.all[a..b],
            _ => &[],
        }
    }

    /// Number of frames covered.
    pub fn frames(&self) -> usize {
        self.frame_start.len().saturating_sub(1)
    }
}

/// What a candidate's detection cost is computed from: a blurred value, whose z-score
/// gives the cost, and a weight the cost is multiplied by.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Evidence {
    /// The value the z-score is taken of, psi.
    pub value: f64,
    /// Multiplies the cost: 1, or less for a lattice point below its contact's top.
    pub weight: f64,
    /// The point is a lattice cell ([`Detection::fixed`]).
    pub fixed: bool,
}

impl Evidence {
    /// A local maximum's own value, at full weight.
    pub fn own(value: f64) -> Self {
        Evidence {
            value,
            weight: 1.0,
            fixed: false,
        }
    }
}

/// Two blurred values that differ by at most this share of the larger one are level:
/// the same height, as far as the data can tell.
///
/// The blur's rounding leaves a flat input (a saturated sensor, a palm pressed evenly)
/// flat to about 1e-14 relative, in a pattern of ulps that would otherwise make a
/// maximum of every pixel on one level of the pattern; a float32 reading resolves 6e-8
/// relative, so no two readings the sensor told apart are this close. Real peaks fall
/// off by percents per pixel.
pub const LEVEL_TOLERANCE: f64 = 1e-9;

/// Whether `a` and `b` are level ([`LEVEL_TOLERANCE`]).
#[inline]
fn level(a: f64, b: f64) -> bool {
    (a - b).abs() <= LEVEL_TOLERANCE * a.abs().max(b.abs())
}

/// The local maxima of one frame, as `(row, col, value)` in row-major order, above
/// `min_value`.
///
/// A local maximum is a plateau: a connected group (8-neighbours) of pixels, each at
/// least level with the largest pixel of its 3 x 3 neighbourhood (outside the frame
/// counts as 0), above `min_value`, and not level with the frame's minimum (a constant
/// frame has none). A plateau is one maximum, reported at its pixel nearest to its
/// centroid (ties: the higher value, then the first in row-major order) with that
/// pixel's value. A single-pixel peak is that pixel, so detections on real touch are
/// the strict 3 x 3 maxima; a flat contact gives one detection, not one per pixel
/// (which made a saturated sensor a detection at every pixel of every frame).
/// NaN-free input is assumed (the tare turned NaN into 0).
pub fn local_maxima(frame: ArrayView2<f64>, min_value: f64) -> Vec<(usize, usize, f64)> {
    plateau::plateaus(frame, near_maxima(frame, min_value))
}

/// Minimum of a frame (NaN-free), whatever its layout.
fn frame_min_of(frame: ArrayView2<f64>) -> f64 {
    match frame.as_slice() {
        Some(s) => frame_min(s),
        None => frame_min(&frame.iter().copied().collect::<Vec<_>>()),
    }
}

touchc_wide::kernel! {
    /// The candidates of [`local_maxima`]: pixels `(row, col, value)` at least level
    /// with the maximum of their 3 x 3 neighbourhood (outside the frame counts as 0) and
    /// above `min_value`, in row-major order.
    ///
    /// Separable, and branch-free where the work is: each row's maxima of three
    /// neighbours (0 outside), then per pixel the larger of those of the rows above, at
    /// and below, so a pixel is a candidate when it is at least that, less the level
    /// tolerance. Only the few pixels that pass are looked at one by one.
    ///
    /// Compiled for AVX2 too, picked at run time: the same numbers either way.
    pub(crate) fn near_maxima / near_maxima_baseline / near_maxima_avx2 (
        frame: ArrayView2<f64>,
        min_value: f64,
    ) -> Vec<(usize, usize, f64)> {
        let (h, w) = frame.dim();
        if h == 0 || w == 0 {
            return Vec::new();
        }
        let buf: Vec<f64>;
        let f: &[f64] = match frame.as_slice() {
            Some(s) => s,
            None => {
                buf = frame.iter().copied().collect();
                &buf
            }
        };
        let row = |r: usize| &f[r * w..(r + 1) * w];
        // Row maxima of three for the rows above, at and below the current one (a row
        // outside the frame is 0), rolled down the frame.
        let zeros = vec![0.0; w];
        let (mut above, mut at, mut below) = (zeros.clone(), vec![0.0; w], vec![0.0; w]);
        max_of_three(row(0), &mut at);
        if h > 1 {
            max_of_three(row(1), &mut below);
        }
        let mut is_max = vec![0u8; w];
        let mut out = Vec::new();
        for r in 0..h {
            if r + 1 >= h {
                below.copy_from_slice(&zeros);
            }
            for ((((m, &v), &a), &t), &b) in is_max
                .iter_mut()
                .zip(row(r))
                .zip(&above)
                .zip(&at)
                .zip(&below)
            {
                let top = larger(larger(a, t), b);
                *m = ((v >= top - LEVEL_TOLERANCE * top.abs()) & (v > min_value)) as u8;
            }
            // Maxima are rare: skip eight flags at a time (one 64-bit word).
            for (k, chunk) in is_max.chunks(8).enumerate() {
                let none = match <[u8; 8]>::try_from(chunk) {
                    Ok(word) => u64::from_ne_bytes(word) == 0,
                    Err(_) => chunk.iter().all(|&m| m == 0),
                };
                if none {
                    continue;
                }
                for c in (k * 8..k * 8 + chunk.len()).filter(|&c| is_max[c] != 0) {
                    out.push((r, c, row(r)[c]));
                }
            }
            // Roll the row maxima down by one row.
            std::mem::swap(&mut above, &mut at);
            std::mem::swap(&mut at, &mut below);
            if r + 2 < h {
                max_of_three(row(r + 2), &mut below);
            }
        }
        out
    }
}

/// `out[c]` = the largest of `row[c - 1]`, `row[c]` and `row[c + 1]`, 0 outside the row.
#[inline(always)]
fn max_of_three(row: &[f64], out: &mut [f64]) {
    let w = row.len();
    if w == 1 {
        out[0] = larger(row[0], 0.0);
        return;
    }
    out[0] = larger(larger(row[0], row[1]), 0.0);
    out[w - 1] = larger(larger(row[w - 2], row[w - 1]), 0.0);
    let (left, mid, right) = (&row[..w - 2], &row[1..w - 1], &row[2..]);
    for (((o, &l), &m), &r) in out[1..w - 1].iter_mut().zip(left).zip(mid).zip(right) {
        *o = larger(larger(l, m), r);
    }
}

/// The larger of two numbers that are not NaN, by comparison (vectorises; `f64::max`
/// must special-case NaN).
#[inline(always)]
fn larger(a: f64, b: f64) -> f64 {
    if b > a {
        b
    } else {
        a
    }
}

/// Minimum of a NaN-free slice, in eight independent lanes (vectorises; `f64::min`
/// must special-case NaN and does not).
#[inline(always)]
fn frame_min(f: &[f64]) -> f64 {
    let mut lanes = [f64::INFINITY; 8];
    let mut chunks = f.chunks_exact(8);
    for c in &mut chunks {
        for (m, &v) in lanes.iter_mut().zip(c) {
            *m = if v < *m { v } else { *m };
        }
    }
    chunks
        .remainder()
        .iter()
        .chain(&lanes)
        .fold(f64::INFINITY, |m, &v| if v < m { v } else { m })
}

/// `ln Phi(x)`, the log of the standard normal CDF, finite for every finite `x`.
///
/// For `x < 0` it uses `Phi(x) = erfcx(t) exp(-t^2) / 2` with `t = -x / sqrt 2`, so the
/// Gaussian tail never underflows; for `x >= 0`, `log1p(-erfc(x / sqrt 2) / 2)`.
pub(crate) fn log_ndtr(x: f64) -> f64 {
    if x < 0.0 {
        let t = -x * std::f64::consts::FRAC_1_SQRT_2;
        (0.5 * puruspe::erfcx(t)).ln() - t * t
    } else {
        (-0.5 * puruspe::erfc(x * std::f64::consts::FRAC_1_SQRT_2)).ln_1p()
    }
}

/// `ln(exp(a) + exp(b))` without overflow; `-inf` terms drop out.
fn log_add_exp(a: f64, b: f64) -> f64 {
    let (hi, lo) = if a >= b { (a, b) } else { (b, a) };
    if lo == f64::NEG_INFINITY {
        return hi;
    }
    hi + (lo - hi).exp().ln_1p()
}

/// Detection cost `ln((1 - P) / P)` with `P = m Phi(z - sigma_k)`, in log space.
///
/// `1 - P = (1 - m) + m Phi(sigma_k - z)`, so both logs come from `log_ndtr` and the
/// cost is finite for any finite `z` (about `z^2 / 2` for very negative `z`, saturating
/// at `ln((1 - m) / m)` for large `z`).
pub fn detection_cost(z: f64, cfg: &DetectConfig) -> f64 {
    let m = cfg.max_probability;
    let x = z - cfg.sigma_k;
    let ln_p = m.ln() + log_ndtr(x);
    let ln_q = log_add_exp((1.0 - m).ln(), m.ln() + log_ndtr(-x));
    ln_q - ln_p
}

/// The detections of one blurred frame: its local maxima above `cfg.min_value_psi`,
/// and with `split` the lattice points of its flat contacts.
pub fn frame_points(
    frame: ArrayView2<f64>,
    cfg: &DetectConfig,
    split: Option<&Split>,
    upsample: usize,
) -> Vec<(usize, usize, f64)> {
    frame_candidates(frame, cfg, split, upsample)
        .into_iter()
        .map(|(p, _)| p)
        .collect()
}

/// [`frame_points`], each with the evidence its detection cost is computed from: its
/// own value for a local maximum, as [`lattice_points_of_contacts`] says for a lattice
/// point. A pixel that is both is a local maximum.
pub(crate) fn frame_candidates(
    frame: ArrayView2<f64>,
    cfg: &DetectConfig,
    split: Option<&Split>,
    upsample: usize,
) -> Vec<((usize, usize, f64), Evidence)> {
    let maxima = local_maxima(frame, cfg.min_value_psi);
    let own = |p: (usize, usize, f64)| (p, Evidence::own(p.2));
    let Some(s) = split else {
        return maxima.into_iter().map(own).collect();
    };
    let lattice = lattice_points_of_contacts(frame, upsample, s, cfg.min_value_psi);
    if lattice.is_empty() {
        return maxima.into_iter().map(own).collect();
    }
    // Maxima first, so that the stable sort and dedup keep a maximum's own evidence.
    let mut all: Vec<((usize, usize, f64), Evidence)> = maxima.into_iter().map(own).collect();
    all.extend(lattice);
    all.sort_by_key(|&((r, c, _), _)| (r, c));
    all.dedup_by_key(|p| (p.0 .0, p.0 .1));
    all
}

/// Finds and scores the detections of every frame.
///
/// A zero (or non-finite) standard deviation means a featureless recording: it has no
/// detections rather than NaN costs.
pub fn detect(blurred: &Blurred, cfg: &DetectConfig) -> Detections {
    let maxima = blurred
        .frames
        .outer_iter()
        .map(|f| local_maxima(f, cfg.min_value_psi))
        .collect();
    score(maxima, blurred.mean, blurred.std, cfg)
}

/// Scores per-frame local maxima (`maxima[t]` as returned by [`local_maxima`] for frame
/// `t`, e.g. found during the blur) against the global mean and std; same result as
/// [`detect`] on the same frames.
pub fn score(
    maxima: Vec<Vec<(usize, usize, f64)>>,
    mean: f64,
    std: f64,
    cfg: &DetectConfig,
) -> Detections {
    let mut candidates = Candidates::with_frames(maxima.len());
    for found in maxima {
        candidates.push_frame(found);
    }
    score_candidates(&candidates, mean, std, cfg)
}

/// Candidate points (row, column, blurred value) of every frame, frame after frame in
/// one buffer: an hour of frames is one allocation, not one per frame (which the
/// allocator keeps, fragmented, long after they are freed).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Candidates {
    points: Vec<(usize, usize, f64)>,
    /// Per point, what its detection cost is computed from (see [`frame_candidates`]).
    evidence: Vec<Evidence>,
    /// `starts[t]..starts[t + 1]` indexes frame `t`'s points.
    starts: Vec<usize>,
}

impl Candidates {
    /// No frame yet, room for `frames` frames' offsets.
    pub(crate) fn with_frames(frames: usize) -> Self {
        let mut starts = Vec::with_capacity(frames + 1);
        starts.push(0);
        Candidates {
            points: Vec::new(),
            evidence: Vec::new(),
            starts,
        }
    }

    /// Appends the next frame's points.
    pub(crate) fn push_frame(&mut self, found: impl IntoIterator<Item = (usize, usize, f64)>) {
        for p in found {
            self.points.push(p);
            self.evidence.push(Evidence::own(p.2));
        }
        self.starts.push(self.points.len());
    }

    /// Appends the next frame's points, each with what its cost is computed from.
    pub(crate) fn push_frame_with(
        &mut self,
        found: impl IntoIterator<Item = ((usize, usize, f64), Evidence)>,
    ) {
        for (p, e) in found {
            self.points.push(p);
            self.evidence.push(e);
        }
        self.starts.push(self.points.len());
    }

    /// Appends every frame of `other`, after this one's.
    pub fn append(&mut self, other: &Candidates) {
        let base = self.points.len();
        self.points.extend_from_slice(&other.points);
        self.evidence.extend_from_slice(&other.evidence);
        self.starts
            .extend(other.starts.iter().skip(1).map(|&s| base + s));
    }

    /// Frames pushed.
    pub fn frames(&self) -> usize {
        self.starts.len() - 1
    }

    /// Frame `t`'s points (empty when out of range).
    pub fn frame(&self, t: usize) -> &[(usize, usize, f64)] {
        match (self.starts.get(t), self.starts.get(t + 1)) {
            (Some(&a), Some(&b)) => &self.points[a..b],
            _ => &[],
        }
    }

    /// Keeps the points of frame `t` for which `keep(t, point)` holds, in order.
    pub fn retain(&mut self, mut keep: impl FnMut(usize, &(usize, usize, f64)) -> bool) {
        let mut kept = 0;
        for t in 0..self.frames() {
            let (a, b) = (self.starts[t], self.starts[t + 1]);
            self.starts[t] = kept;
            for i in a..b {
                if keep(t, &self.points[i]) {
                    self.points[kept] = self.points[i];
                    self.evidence[kept] = self.evidence[i];
                    kept += 1;
                }
            }
        }
        let last = self.starts.len() - 1;
        self.starts[last] = kept;
        self.points.truncate(kept);
        self.evidence.truncate(kept);
    }
}

/// [`score`] on candidates gathered frame by frame.
pub(crate) fn score_candidates(
    candidates: &Candidates,
    mean: f64,
    std: f64,
    cfg: &DetectConfig,
) -> Detections {
    use rayon::prelude::*;
    let usable = std > 0.0 && std.is_finite() && mean.is_finite();
    // Each cost on its own (an hour holds millions of candidates), so on every core.
    let costs: Vec<f64> = if usable {
        candidates
            .evidence
            .par_iter()
            .map(|e| e.weight * detection_cost((e.value - mean) / std, cfg))
            .collect()
    } else {
        Vec::new()
    };
    let mut all = Vec::with_capacity(costs.len());
    let mut frame_start = Vec::with_capacity(candidates.frames() + 1);
    frame_start.push(0);
    for frame in 0..candidates.frames() {
        if usable {
            let (a, b) = (candidates.starts[frame], candidates.starts[frame + 1]);
            all.extend(
                candidates.points[a..b]
                    .iter()
                    .zip(&costs[a..b])
                    .zip(&candidates.evidence[a..b])
                    .map(|((&(row, col, value), &cost), e)| Detection {
                        frame,
                        row,
                        col,
                        value,
                        cost,
                        fixed: e.fixed,
                    }),
            );
        }
        frame_start.push(all.len());
    }
    Detections { all, frame_start }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::array;

    /// The AVX2 build of the local maxima finds the baseline's, value for value
    /// ([`touchc_wide`]), on frames with peaks, plateaus and flat zeros.
    #[test]
    fn the_avx2_build_finds_the_baseline_maxima() {
        if !touchc_wide::avx2_or_skip("detect::tests::the_avx2_build_finds_the_baseline_maxima") {
            return;
        }
        let mut rng = touchc_test_rng::Xorshift::new(0x9e37_79b9_7f4a_7c15);
        let mut next = move || rng.uniform();
        for (i, dim) in [(56, 147), (3, 5), (1, 9), (7, 1), (17, 33)]
            .into_iter()
            .enumerate()
        {
            let frame = ndarray::Array2::from_shape_fn(dim, |_| {
                let v = next();
                // Quantised so that plateaus occur; a fifth exactly zero.
                if v < 0.2 {
                    0.0
                } else {
                    (v * 8.0).floor()
                }
            });
            for min_value in [-1.0, 0.0, 3.0] {
                let base = near_maxima_baseline(frame.view(), min_value);
                // SAFETY: the CPU runs AVX2 (checked above).
                let wide = unsafe { near_maxima_avx2(frame.view(), min_value) };
                assert_eq!(base, wide, "frame {i}, above {min_value}");
                assert!(i > 0 || min_value > 0.0 || !base.is_empty());
            }
        }
    }

    #[test]
    fn candidates_keep_frames_apart_and_order_within_them() {
        let frames = vec![
            vec![(1, 1, 0.5), (2, 7, 0.9), (3, 3, 0.1)],
            vec![],
            vec![(4, 4, 0.7), (5, 9, 0.2)],
        ];
        let mut c = Candidates::with_frames(3);
        for f in &frames {
            c.push_frame(f.iter().copied());
        }
        assert_eq!(c.frames(), 3);
        for (t, f) in frames.iter().enumerate() {
            assert_eq!(c.frame(t), &f[..]);
        }
        assert!(c.frame(3).is_empty());
        // Drop frame 0's middle point and all of frame 2 but its last.
        c.retain(|t, &(r, _, _)| (t == 0 && r != 2) || (t == 2 && r == 5));
        assert_eq!(c.frame(0), &[(1, 1, 0.5), (3, 3, 0.1)]);
        assert!(c.frame(1).is_empty());
        assert_eq!(c.frame(2), &[(5, 9, 0.2)]);
        // Scoring the flat buffer is scoring the frames.
        let cfg = DetectConfig::default();
        let kept = vec![vec![(1, 1, 0.5), (3, 3, 0.1)], vec![], vec![(5, 9, 0.2)]];
        assert_eq!(
            score_candidates(&c, 0.2, 0.1, &cfg),
            score(kept, 0.2, 0.1, &cfg)
        );
    }

    #[test]
    fn log_ndtr_matches_known_values() {
        // Phi(0) = 1/2, Phi(-1) = 0.15865525393145707, Phi(-40) from the asymptotic series.
        assert!((log_ndtr(0.0) - 0.5f64.ln()).abs() < 1e-16);
        assert!((log_ndtr(-1.0) - 0.158_655_253_931_457_07f64.ln()).abs() < 1e-15);
        assert!((log_ndtr(1.0) - 0.841_344_746_068_542_9f64.ln()).abs() < 1e-15);
        let x = -40.0f64;
        let asym = -0.5 * x * x - (-x).ln() - 0.5 * (2.0 * std::f64::consts::PI).ln()
            + (-1.0 / (x * x) + 3.0 / x.powi(4) - 15.0 / x.powi(6)).ln_1p();
        assert!(
            (log_ndtr(x) / asym - 1.0).abs() < 1e-12,
            "{} {}",
            log_ndtr(x),
            asym
        );
    }

    #[test]
    fn cost_matches_direct_formula_in_the_safe_range() {
        let cfg = DetectConfig::default();
        for i in -40..=80 {
            let z = i as f64 * 0.1;
            let phi = 0.5 * puruspe::erfc(-(z - 1.25) / std::f64::consts::SQRT_2);
            let p = 0.98 * phi;
            let direct = ((1.0 - p) / p).ln();
            assert!((detection_cost(z, &cfg) - direct).abs() < 1e-12 * direct.abs().max(1.0));
        }
    }

    #[test]
    fn costs_finite_from_minus_to_plus_a_million() {
        let cfg = DetectConfig::default();
        let sat = (0.02f64 / 0.98).ln();
        let mut prev = f64::INFINITY;
        for i in -1000..=1000 {
            let z = i as f64 * 1e3;
            let c = detection_cost(z, &cfg);
            assert!(c.is_finite(), "z = {z}");
            assert!(c <= prev, "cost must fall as z rises");
            prev = c;
        }
        assert!((detection_cost(1e6, &cfg) - sat).abs() < 1e-15);
        assert!(detection_cost(-1e6, &cfg) > 4.9e11);
    }

    #[test]
    fn plateaus_and_borders() {
        let f = array![
            [0.0, 0.0, 0.0, 0.0],
            [0.0, 2.0, 2.0, 0.0],
            [0.0, 0.0, 0.0, 1.0]
        ];
        let m = local_maxima(f.view(), 1e-5);
        // The plateau is one maximum (its two pixels are equally near its centroid: the
        // first); (2, 3) touches a higher pixel diagonally.
        assert_eq!(m, vec![(1, 1, 2.0)]);
        let constant = ndarray::Array2::<f64>::from_elem((3, 3), 5.0);
        assert!(local_maxima(constant.view(), 1e-5).is_empty());
    }

    #[test]
    fn the_lattice_reaches_a_weaker_shoulder_down_to_its_extent() {
        // 4 x 10 cells: a flat 4 x 4 top at 1 psi, beside it a 4 x 4 shoulder at 0.3.
        let mut f = ndarray::Array2::<f64>::zeros((4, 10));
        for r in 0..4 {
            for c in 0..8 {
                f[[r, c]] = if c < 4 { 1.0 } else { 0.3 };
            }
        }
        let mut split = Split {
            min_cells: 8,
            level: 0.5,
            spacing_cells: 2,
            extent: None,
        };
        let cols = |s: &Split| {
            let mut c: Vec<usize> = lattice_points(f.view(), 1, s, 0.05)
                .iter()
                .map(|p| p.1)
                .collect();
            c.dedup();
            c.sort_unstable();
            c.dedup();
            c
        };
        assert_eq!(cols(&split), vec![0, 2]);
        split.extent = Some(0.25);
        assert_eq!(cols(&split), vec![0, 2, 4, 6]);
        // Below the extent, nothing.
        split.extent = Some(0.35);
        assert_eq!(cols(&split), vec![0, 2]);
    }

    /// A point the extent adds is tracked on its contact's evidence, but weighs less
    /// than the top by the pressure it carries: its cost is negative, and above the
    /// top's (so the placement prefers circles where the contact presses).
    #[test]
    fn a_shoulder_point_costs_less_than_the_top_but_is_still_a_detection() {
        // 4 x 10 cells: a flat 4 x 4 top at 1 psi, beside it a 4 x 4 shoulder at 0.3.
        let mut f = ndarray::Array2::<f64>::zeros((4, 10));
        for r in 0..4 {
            for c in 0..8 {
                f[[r, c]] = if c < 4 { 1.0 } else { 0.3 };
            }
        }
        let split = Split {
            min_cells: 8,
            level: 0.5,
            spacing_cells: 2,
            extent: Some(0.25),
        };
        let cfg = DetectConfig::default();
        let mut c = Candidates::with_frames(1);
        c.push_frame_with(frame_candidates(f.view(), &cfg, Some(&split), 1));
        // A strong contact against a quiet recording: the top's cost saturates.
        let d = score_candidates(&c, 0.01, 0.05, &cfg);
        let cost_at = |col: usize| {
            d.all
                .iter()
                .find(|p| p.row == 2 && p.col == col)
                .map(|p| p.cost)
                .unwrap_or_else(|| panic!("no detection at column {col}: {d:?}"))
        };
        let (top, shoulder) = (cost_at(2), cost_at(6));
        assert!(shoulder < 0.0, "{shoulder}");
        assert!(top < shoulder, "top {top}, shoulder {shoulder}");
        // Weighted by its share of the top: 0.3 / 0.5.
        assert!((shoulder - 0.6 * top).abs() < 1e-12, "{top} {shoulder}");
    }

    #[test]
    fn a_flat_contact_gets_lattice_points_a_fingertip_none() {
        // 6 x 8 cells at upsampling 1: a flat 4 x 5 top and a one-cell fingertip.
        let mut f = ndarray::Array2::<f64>::zeros((6, 8));
        for r in 0..4 {
            for c in 0..5 {
                f[[r, c]] = 1.0;
            }
        }
        f[[5, 7]] = 2.0;
        let split = Split {
            min_cells: 8,
            level: 0.5,
            spacing_cells: 2,
            extent: None,
        };
        let pts = lattice_points(f.view(), 1, &split, 0.05);
        let cells: Vec<(usize, usize)> = pts.iter().map(|p| (p.0, p.1)).collect();
        assert_eq!(cells, vec![(0, 0), (0, 2), (0, 4), (2, 0), (2, 2), (2, 4)]);
        // Upsampled x3: the same cells, at their centre pixels.
        let up = ndarray::Array2::from_shape_fn((18, 24), |(r, c)| f[[r / 3, c / 3]]);
        let pts3 = lattice_points(up.view(), 3, &split, 0.05);
        assert_eq!(pts3[1], (1, 7, 1.0));
        // Merged with the maxima, each pixel once, row-major.
        let maxima = local_maxima(f.view(), 0.05);
        let all = with_lattice(maxima.clone(), pts);
        assert!(all.windows(2).all(|w| (w[0].0, w[0].1) < (w[1].0, w[1].1)));
        assert!(maxima.iter().all(|m| all.contains(m)));
        // A smaller top is not split.
        let few = Split {
            min_cells: 21,
            ..split
        };
        assert!(lattice_points(f.view(), 1, &few, 0.05).is_empty());
    }
}
