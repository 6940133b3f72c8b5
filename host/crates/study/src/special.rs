//! The distributions the tests need: binomial tails, the normal upper tail and the
//! chi-square upper tail, each to about 1e-13 relative.
//!
//! The binomial sums its probability mass function, built by a recurrence in log
//! space (no overflow for large `n`, no cancellation: every term is positive). The
//! chi-square tail uses the closed form of the regularised upper incomplete gamma
//! function at integer and half-integer orders (degrees of freedom are whole numbers
//! here), with `erfc` for the half-integer part.

/// The two-sided normal quantile at 97.5 %: `scipy.special.ndtri(0.975)` to the last bit.
pub const Z_975: f64 = 1.959_963_984_540_054;

/// `ln P(X = i)` for `i` in `0..=n`, X ~ Binomial(n, p), 0 < p < 1.
fn binomial_log_pmf(n: u64, p: f64) -> Vec<f64> {
    let mut out = Vec::with_capacity(n as usize + 1);
    let log_odds = p.ln() - (-p).ln_1p();
    let mut lp = n as f64 * (-p).ln_1p();
    out.push(lp);
    for i in 0..n {
        lp += ((n - i) as f64 / (i + 1) as f64).ln() + log_odds;
        out.push(lp);
    }
    out
}

/// The sum of `exp(lp[i])` over the indices `keep` selects.
fn sum_exp(lp: &[f64], keep: impl Fn(usize) -> bool) -> f64 {
    let top = (0..lp.len())
        .filter(|&i| keep(i))
        .map(|i| lp[i])
        .fold(f64::NEG_INFINITY, f64::max);
    if top == f64::NEG_INFINITY {
        return 0.0;
    }
    let s: f64 = (0..lp.len())
        .filter(|&i| keep(i))
        .map(|i| (lp[i] - top).exp())
        .sum();
    s * top.exp()
}

/// The exact binomial test of `k` successes in `n` trials against success probability
/// `p`, two-sided as scipy's `binomtest` does it: the probability of every outcome at
/// most as likely as `k` (with a relative slack of 1e-7 on the far side of the mode,
/// so that rounding does not split outcomes of equal probability). `None` when `n` is
/// 0 or `p` is not strictly between 0 and 1.
pub fn binomial_test(k: u64, n: u64, p: f64) -> Option<f64> {
    if n == 0 || k > n || p <= 0.0 || p >= 1.0 || p.is_nan() {
        return None;
    }
    let lp = binomial_log_pmf(n, p);
    let d = lp[k as usize];
    // The far side keeps outcomes with pmf <= d * (1 + 1e-7), as scipy does.
    let slack = d + 1e-7f64.ln_1p();
    let mean = p * n as f64;
    let pval = if k as f64 == mean {
        1.0
    } else if (k as f64) < mean {
        let lo = mean.ceil() as usize;
        sum_exp(&lp, |i| i <= k as usize || (i >= lo && lp[i] <= slack))
    } else {
        let hi = mean.floor() as usize;
        sum_exp(&lp, |i| i >= k as usize || (i <= hi && lp[i] <= slack))
    };
    Some(pval.min(1.0))
}

/// `P(Z > z)` for a standard normal Z.
pub fn normal_sf(z: f64) -> f64 {
    0.5 * puruspe::erfc(z / std::f64::consts::SQRT_2)
}

/// `P(X > x)` for X ~ chi-square with `df` >= 1 degrees of freedom.
pub fn chi2_sf(x: f64, df: u32) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if x <= 0.0 {
        return 1.0;
    }
    let h = x / 2.0;
    let ln_h = h.ln();
    // Q(a, h) with a = df / 2: a finite series of Poisson-like terms, in log space.
    let (mut lt, mut order, mut base): (f64, f64, f64) = if df.is_multiple_of(2) {
        (-h, 1.0, 0.0)
    } else {
        // erfc(sqrt h) carries the half-integer part; the terms start at k + 3/2.
        let lg = (std::f64::consts::PI.sqrt() / 2.0).ln();
        (-h + 0.5 * ln_h - lg, 1.5, puruspe::erfc(h.sqrt()))
    };
    // df = 2m or 2m + 1: m terms either way.
    for _ in 0..df / 2 {
        base += lt.exp();
        lt += ln_h - order.ln();
        order += 1.0;
    }
    base.min(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * b.abs().max(1e-300)
    }

    #[test]
    fn chi2_with_two_degrees_is_the_exponential() {
        for x in [0.1, 1.0, 5.0, 40.0] {
            assert!(close(chi2_sf(x, 2), (-x / 2.0).exp()), "{x}");
        }
    }

    #[test]
    fn chi2_with_one_degree_is_twice_the_normal_tail() {
        for z in [0.3, 1.0, 2.5, 6.0] {
            assert!(close(chi2_sf(z * z, 1), 2.0 * normal_sf(z)), "{z}");
        }
    }

    #[test]
    fn binomial_sums_to_one_and_is_symmetric_at_one_half() {
        assert_eq!(binomial_test(5, 10, 0.5), Some(1.0));
        let lo = binomial_test(2, 10, 0.5).unwrap();
        let hi = binomial_test(8, 10, 0.5).unwrap();
        // 2 * (1 + 10 + 45) / 1024
        assert!(close(lo, 112.0 / 1024.0), "{lo}");
        assert!(close(hi, lo));
        assert_eq!(binomial_test(0, 0, 0.5), None);
    }
}
