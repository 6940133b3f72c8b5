//! The top-choice measures: confusion, accuracy and its interval, recall, precision,
//! accuracy under a probability cut-off, and the Bhattacharyya coefficient.

use crate::special::Z_975;

/// The scenario given the highest probability; on an exact tie the first in scenario
/// order (as numpy's `argmax`). The study page forbids ties for the largest value;
/// responses collected elsewhere may hold them, and the report counts them.
pub fn top_choice(p: &[f64]) -> usize {
    let mut best = 0;
    for (i, v) in p.iter().enumerate() {
        if *v > p[best] {
            best = i;
        }
    }
    best
}

/// True if the largest probability is shared.
pub(crate) fn top_tied(p: &[f64]) -> bool {
    let t = top_choice(p);
    p.iter().enumerate().any(|(i, v)| i != t && *v == p[t])
}

/// Counts: rows = the stimulus's scenario, columns = the top choice.
pub(crate) fn confusion<'a>(
    n: usize,
    trials: impl Iterator<Item = (usize, &'a [f64])>,
) -> Vec<Vec<u64>> {
    let mut m = vec![vec![0u64; n]; n];
    for (stimulus, p) in trials {
        m[stimulus][top_choice(p)] += 1;
    }
    m
}

/// Each row divided by its sum; `None` for a row with no trials.
pub(crate) fn row_normalised(m: &[Vec<u64>]) -> Vec<Option<Vec<f64>>> {
    m.iter()
        .map(|row| {
            let s: u64 = row.iter().sum();
            (s > 0).then(|| row.iter().map(|c| *c as f64 / s as f64).collect())
        })
        .collect()
}

/// The Wilson score interval at 95 % for `k` successes in `n` (as scipy's
/// `BinomTestResult.proportion_ci(method="wilson")`): closed form, good coverage for
/// small `n` and proportions near 0 or 1, unlike the normal approximation.
pub fn wilson_interval(k: u64, n: u64) -> Option<(f64, f64)> {
    if n == 0 {
        return None;
    }
    let (k, n) = (k as f64, n as f64);
    let z = Z_975;
    let p = k / n;
    let q = 1.0 - p;
    let denom = 2.0 * (n + z * z);
    let center = (2.0 * n * p + z * z) / denom;
    let d = z * (z * z + 4.0 * n * p * q).sqrt() / denom;
    let lo = if k == 0.0 { 0.0 } else { center - d };
    let hi = if k == n { 1.0 } else { center + d };
    Some((lo, hi))
}

/// Per scenario: recall (the diagonal over the row) and precision (over the column);
/// `None` where the row or column is empty.
pub(crate) fn recall_precision(m: &[Vec<u64>]) -> (Vec<Option<f64>>, Vec<Option<f64>>) {
    let n = m.len();
    let recall = (0..n)
        .map(|i| {
            let s: u64 = m[i].iter().sum();
            (s > 0).then(|| m[i][i] as f64 / s as f64)
        })
        .collect();
    let precision = (0..n)
        .map(|j| {
            let s: u64 = m.iter().map(|r| r[j]).sum();
            (s > 0).then(|| m[j][j] as f64 / s as f64)
        })
        .collect();
    (recall, precision)
}

/// The sum of the `n` largest probabilities, added largest first.
pub(crate) fn top_sum(p: &[f64], n: usize) -> f64 {
    let mut s = p.to_vec();
    s.sort_by(|a, b| b.total_cmp(a));
    s.iter().take(n).fold(0.0, |acc, v| acc + v)
}

/// The supplement's non-forced-choice simulation: the fraction of trials whose top
/// choice is right and whose `top`-largest probabilities sum to at least `cutoff`.
pub(crate) fn accuracy_at_cutoff(trials: &[(usize, &[f64])], top: usize, cutoff: f64) -> f64 {
    let hits = trials
        .iter()
        .filter(|(s, p)| top_choice(p) == *s && top_sum(p, top) >= cutoff)
        .count();
    hits as f64 / trials.len() as f64
}

/// The Bhattacharyya coefficient of two rows, each normalised to sum to 1 first:
/// `sum_i sqrt(p_i q_i)`, 1 for equal rows, 0 for rows with disjoint support. `None`
/// if either row sums to zero or the lengths differ.
pub fn bhattacharyya(p: &[f64], q: &[f64]) -> Option<f64> {
    let (sp, sq): (f64, f64) = (p.iter().sum(), q.iter().sum());
    if p.len() != q.len() || sp <= 0.0 || sq <= 0.0 {
        return None;
    }
    Some(
        p.iter()
            .zip(q)
            .map(|(a, b)| (a / sp * (b / sq)).sqrt())
            .sum(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ties_go_to_the_first_and_are_seen() {
        assert_eq!(top_choice(&[0.4, 0.4, 0.2]), 0);
        assert!(top_tied(&[0.4, 0.4, 0.2]));
        assert!(!top_tied(&[0.3, 0.5, 0.2]));
    }

    #[test]
    fn wilson_is_clamped_at_the_ends() {
        assert_eq!(wilson_interval(0, 10).unwrap().0, 0.0);
        assert_eq!(wilson_interval(10, 10).unwrap().1, 1.0);
        let (lo, hi) = wilson_interval(5, 10).unwrap();
        assert!(lo < 0.5 && hi > 0.5 && (lo + hi - 1.0).abs() < 1e-12);
    }

    #[test]
    fn bhattacharyya_of_equal_rows_is_one() {
        let b = bhattacharyya(&[1.0, 2.0, 3.0], &[2.0, 4.0, 6.0]).unwrap();
        assert!((b - 1.0).abs() < 1e-12);
        assert_eq!(bhattacharyya(&[1.0, 0.0], &[0.0, 1.0]), Some(0.0));
        assert_eq!(bhattacharyya(&[0.0, 0.0], &[0.0, 1.0]), None);
    }
}
