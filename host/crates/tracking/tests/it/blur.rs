//! The matrix-product blur against scipy's documented numbers and a direct 2-D oracle.

use touchc_testkit as common;

use ndarray::{Array2, ArrayView2};
use proptest::prelude::*;
use touchc_model::config::PreprocessConfig;
use touchc_model::config::Sampling;
use touchc_tracking::preprocess::{gaussian_kernel, Blur, BlurOperator};

/// scipy 'reflect', by bouncing off the ends until inside (independent of the crate's
/// modular formula).
fn mirror(mut i: i64, n: usize) -> usize {
    let n = n as i64;
    while i < 0 || i >= n {
        i = if i < 0 { -i - 1 } else { 2 * n - 1 - i };
    }
    i as usize
}

/// Explicit x k upsampling, then the full 2-D double sum of the outer-product kernel.
fn oracle(frame: ArrayView2<f64>, k: usize, sigma: f64, truncate: f64) -> Array2<f64> {
    let (r, c) = frame.dim();
    let (h, w) = (r * k, c * k);
    let up = Array2::from_shape_fn((h, w), |(i, j)| frame[[i / k, j / k]]);
    let kern = gaussian_kernel(sigma, truncate);
    let rad = (kern.len() / 2) as i64;
    Array2::from_shape_fn((h, w), |(i, j)| {
        let mut s = 0.0;
        for a in -rad..=rad {
            for b in -rad..=rad {
                let wgt = kern[(a + rad) as usize] * kern[(b + rad) as usize];
                s += wgt * up[[mirror(i as i64 + a, h), mirror(j as i64 + b, w)]];
            }
        }
        s
    })
}

#[test]
fn matches_scipy_gaussian_filter1d_doc_example() {
    // scipy docs: gaussian_filter1d([1, 2, 3, 4, 5], 1) and (..., 4).
    let cases = [
        (
            1.0,
            [1.427_040_95, 2.067_822_03, 3.0, 3.932_177_97, 4.572_959_05],
        ),
        (
            4.0,
            [2.919_483_43, 2.950_235_02, 3.0, 3.049_764_98, 3.080_516_57],
        ),
    ];
    for (sigma, want) in cases {
        let cfg = Blur {
            upsample: 1,
            sigma_px: sigma,
            truncate: 4.0,
        };
        let op = BlurOperator::new(1, 5, &cfg).unwrap();
        let f = Array2::from_shape_vec((1, 5), vec![1.0, 2.0, 3.0, 4.0, 5.0]).unwrap();
        let out = op.apply(f.view());
        for (g, w) in out.iter().zip(want) {
            assert!((g - w).abs() < 1e-8, "sigma {sigma}: {g} vs {w}");
        }
    }
}

#[test]
fn paper_shape_matches_oracle() {
    let rec = common::moving_blobs(60, 2, 7);
    let cfg = Blur::new(&PreprocessConfig::default(), &Sampling::PAPER);
    assert_eq!(cfg.sigma_px, 3.0);
    let op = BlurOperator::new(8, 21, &cfg).unwrap();
    let frame = rec
        .index_axis(ndarray::Axis(0), 30)
        .mapv(|v| if v.is_nan() { 0.0 } else { v });
    let got = op.apply(frame.view());
    let want = oracle(frame.view(), 7, 3.0, 4.0);
    let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (g, w) in got.iter().zip(want.iter()) {
        assert!((g - w).abs() <= 1e-13 * scale, "{g} vs {w}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// Any small shape (including ones narrower than the kernel, where reflection wraps
    /// more than once), any factor and sigma.
    #[test]
    fn any_shape_matches_oracle(
        r in 1usize..5, c in 1usize..5, k in 1usize..4, sigma in 0.0f64..3.0,
        seed in any::<u64>(),
    ) {
        let mut n = common::Xorshift::mixed(seed);
        let frame = Array2::from_shape_fn((r, c), |_| n.signed());
        let cfg = Blur { upsample: k, sigma_px: sigma, truncate: 4.0 };
        let got = BlurOperator::new(r, c, &cfg).unwrap().apply(frame.view());
        let want = oracle(frame.view(), k, sigma, 4.0);
        for (g, w) in got.iter().zip(want.iter()) {
            prop_assert!((g - w).abs() <= 1e-13, "{} vs {}", g, w);
        }
    }
}
