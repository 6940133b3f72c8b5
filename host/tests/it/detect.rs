//! Local maxima against a naive 3 x 3 scan of a zero-padded frame.

use ndarray::Array2;
use proptest::prelude::*;
use touchc::tracking::detect::local_maxima;

fn naive(f: &Array2<f64>, min_value: f64) -> Vec<(usize, usize, f64)> {
    let (h, w) = f.dim();
    let fmin = f.iter().cloned().fold(f64::INFINITY, f64::min);
    let padded = Array2::from_shape_fn((h + 2, w + 2), |(i, j)| {
        if i == 0 || j == 0 || i > h || j > w {
            0.0
        } else {
            f[[i - 1, j - 1]]
        }
    });
    let mut out = Vec::new();
    for r in 0..h {
        for c in 0..w {
            let v = f[[r, c]];
            let m = padded
                .slice(ndarray::s![r..r + 3, c..c + 3])
                .iter()
                .cloned()
                .fold(f64::NEG_INFINITY, f64::max);
            if v == m && v > fmin && v > min_value {
                out.push((r, c, v));
            }
        }
    }
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
