//! Stage 2: detections (3 x 3 local maxima of the blurred frames) and their log-odds cost.
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

use crate::config::DetectConfig;
use crate::preprocess::Blurred;

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

/// Pixels `(row, col, value)` equal to the maximum of their 3 x 3 neighbourhood (outside
/// the frame counts as 0, plateaus count), strictly above the frame minimum and above
/// `min_value`, in row-major order.
///
/// Two-step, for speed: a branch-free pass marks the pixels that are maxima of their row
/// triple and above `min_value` (rare in a blurred frame), and only those are compared
/// with the rows above and below. The frame minimum is needed only for a candidate
/// whose in-frame neighbours all equal it (a plateau), so it is computed lazily.
/// NaN-free input is assumed (the tare turned NaN into 0).
pub fn local_maxima(frame: ArrayView2<f64>, min_value: f64) -> Vec<(usize, usize, f64)> {
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
    let mut fmin: Option<f64> = None;
    let mut cand = vec![0u8; w];
    let mut out = Vec::new();
    for r in 0..h {
        let row = &f[r * w..(r + 1) * w];
        // Row triples, 0 outside; `&` on bools keeps the loop free of branches.
        if w == 1 {
            cand[0] = ((row[0] >= 0.0) & (row[0] > min_value)) as u8;
        } else {
            cand[0] = ((row[0] >= 0.0) & (row[0] >= row[1]) & (row[0] > min_value)) as u8;
            let last = w - 1;
            cand[last] =
                ((row[last] >= row[last - 1]) & (row[last] >= 0.0) & (row[last] > min_value)) as u8;
            for (cd, t) in cand[1..last].iter_mut().zip(row.windows(3)) {
                *cd = ((t[1] >= t[0]) & (t[1] >= t[2]) & (t[1] > min_value)) as u8;
            }
        }
        // Candidates are rare: skip eight flags at a time.
        for (k, chunk) in cand.chunks(8).enumerate() {
            if chunk.iter().fold(0u8, |a, &b| a | b) == 0 {
                continue;
            }
            for c in (k * 8..k * 8 + chunk.len()).filter(|&c| cand[c] != 0) {
                let v = row[c];
                let mut all_equal = true;
                let mut is_max = true;
                for rr in [r.checked_sub(1), Some(r), Some(r + 1).filter(|&x| x < h)] {
                    let Some(rr) = rr else {
                        // A missing row is 0 outside the frame.
                        is_max &= v >= 0.0;
                        continue;
                    };
                    let nrow = &f[rr * w..(rr + 1) * w];
                    for &n in &nrow[c.saturating_sub(1)..(c + 2).min(w)] {
                        is_max &= v >= n;
                        all_equal &= n == v;
                    }
                }
                if !is_max {
                    continue;
                }
                // Some in-frame neighbour is lower, so v is above the frame minimum;
                // only a flat neighbourhood needs the (lazily computed) minimum.
                if all_equal {
                    let m = *fmin.get_or_insert_with(|| frame_min(f));
                    if v <= m {
                        continue;
                    }
                }
                out.push((r, c, v));
            }
        }
    }
    out
}

/// Minimum of a NaN-free slice, in eight independent lanes (vectorises; `f64::min`
/// must special-case NaN and does not).
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
pub fn log_ndtr(x: f64) -> f64 {
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
/// `1 - P = (1 - m) + m Phi(sigma_k - z)`, so both logs come from [`log_ndtr`] and the
/// cost is finite for any finite `z` (about `z^2 / 2` for very negative `z`, saturating
/// at `ln((1 - m) / m)` for large `z`).
pub fn detection_cost(z: f64, cfg: &DetectConfig) -> f64 {
    let m = cfg.max_probability;
    let x = z - cfg.sigma_k;
    let ln_p = m.ln() + log_ndtr(x);
    let ln_q = log_add_exp((1.0 - m).ln(), m.ln() + log_ndtr(-x));
    ln_q - ln_p
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
    let usable = std > 0.0 && std.is_finite() && mean.is_finite();
    let mut all = Vec::new();
    let mut frame_start = Vec::with_capacity(maxima.len() + 1);
    frame_start.push(0);
    for (frame, found) in maxima.into_iter().enumerate() {
        if usable {
            all.extend(found.into_iter().map(|(row, col, value)| {
                let cost = detection_cost((value - mean) / std, cfg);
                Detection {
                    frame,
                    row,
                    col,
                    value,
                    cost,
                }
            }));
        }
        frame_start.push(all.len());
    }
    Detections { all, frame_start }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::array;

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
        // The plateau counts twice; (2, 3) touches a higher pixel diagonally.
        assert_eq!(m, vec![(1, 1, 2.0), (1, 2, 2.0)]);
        let constant = ndarray::Array2::<f64>::from_elem((3, 3), 5.0);
        assert!(local_maxima(constant.view(), 1e-5).is_empty());
    }
}
