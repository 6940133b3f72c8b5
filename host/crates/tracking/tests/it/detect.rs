//! Local maxima against a naive 3 x 3 scan of a zero-padded frame.

use ndarray::Array2;
use proptest::prelude::*;
use touchc_tracking::detect::local_maxima;

/// The plateau rule of `local_maxima`, pixel by pixel: every pixel at least level with
/// its 3 x 3 neighbourhood's maximum (outside counts as 0) and above `min_value`; its
/// 8-connected groups by flood fill; a group counts when some in-frame neighbour of it
/// is lower beyond level, or else its top is above the frame minimum beyond level; it
/// is reported at its pixel nearest its centroid, then the higher, then the first.
fn naive(f: &Array2<f64>, min_value: f64) -> Vec<(usize, usize, f64)> {
    let tol = touchc_tracking::detect::LEVEL_TOLERANCE;
    let level = |a: f64, b: f64| (a - b).abs() <= tol * a.abs().max(b.abs());
    let (h, w) = f.dim();
    let fmin = f.iter().cloned().fold(f64::INFINITY, f64::min);
    let padded = Array2::from_shape_fn((h + 2, w + 2), |(i, j)| {
        if i == 0 || j == 0 || i > h || j > w {
            0.0
        } else {
            f[[i - 1, j - 1]]
        }
    });
    let candidate = Array2::from_shape_fn((h, w), |(r, c)| {
        let v = f[[r, c]];
        let m = padded
            .slice(ndarray::s![r..r + 3, c..c + 3])
            .iter()
            .cloned()
            .fold(f64::NEG_INFINITY, f64::max);
        (v >= m || level(v, m)) && v > min_value
    });
    let neighbours = |r: usize, c: usize| {
        let rows = r.saturating_sub(1)..(r + 2).min(h);
        rows.flat_map(move |rr| (c.saturating_sub(1)..(c + 2).min(w)).map(move |cc| (rr, cc)))
    };
    let mut seen = Array2::from_elem((h, w), false);
    let mut out = Vec::new();
    for r in 0..h {
        for c in 0..w {
            if !candidate[[r, c]] || seen[[r, c]] {
                continue;
            }
            let mut group = vec![(r, c)];
            seen[[r, c]] = true;
            let mut i = 0;
            while i < group.len() {
                let (a, b) = group[i];
                for (rr, cc) in neighbours(a, b) {
                    if candidate[[rr, cc]] && !seen[[rr, cc]] {
                        seen[[rr, cc]] = true;
                        group.push((rr, cc));
                    }
                }
                i += 1;
            }
            let top = group
                .iter()
                .map(|&p| f[p])
                .fold(f64::NEG_INFINITY, f64::max);
            let lower = group.iter().any(|&(a, b)| {
                neighbours(a, b).any(|n| f[n] < f[[a, b]] && !level(f[n], f[[a, b]]))
            });
            if !lower && (top <= fmin || level(top, fmin)) {
                continue;
            }
            let n = group.len() as f64;
            let cr = group.iter().map(|p| p.0 as f64).sum::<f64>() / n;
            let cc = group.iter().map(|p| p.1 as f64).sum::<f64>() / n;
            let d2 = |p: (usize, usize)| (p.0 as f64 - cr).powi(2) + (p.1 as f64 - cc).powi(2);
            group.sort();
            let mut best = group[0];
            for &p in &group[1..] {
                if d2(p) < d2(best) || (d2(p) == d2(best) && f[p] > f[best]) {
                    best = p;
                }
            }
            out.push((best.0, best.1, f[best]));
        }
    }
    out.sort_by_key(|p| (p.0, p.1));
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]
    /// Values from a small set make plateaus, ties and flat frames common; negative
    /// values and a negative threshold exercise the "outside is 0" border rule.
    #[test]
    fn matches_naive(h in 1usize..6, w in 1usize..6, vals in prop::collection::vec(-2i32..3, 36), neg in any::<bool>()) {
        let f = Array2::from_shape_fn((h, w), |(r, c)| vals[r * 6 + c] as f64 * 0.5);
        let min_value = if neg { -0.75 } else { 1e-5 };
        prop_assert_eq!(local_maxima(f.view(), min_value), naive(&f, min_value));
    }
}
