//! Rank tests for ratings across groups: Kruskal-Wallis and Dunn's post-hoc test with
//! the Sidak correction (the paper's choice: the ratings are not normal nor of equal
//! variance, and the groups are independent).

use serde::Serialize;

use crate::special::{chi2_sf, normal_sf};

/// The result of a Kruskal-Wallis test.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct KruskalWallis {
    /// H, corrected for ties.
    pub statistic: f64,
    /// The chi-square tail of H.
    pub p: f64,
    /// Degrees of freedom: the non-empty groups less one.
    pub df: u32,
}

/// Average ranks (1-based, ties share their mean rank) of all values, and the tie
/// term `sum(t^3 - t)` over the groups of equal values.
fn ranks(values: &[f64]) -> (Vec<f64>, f64) {
    let mut idx: Vec<usize> = (0..values.len()).collect();
    idx.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
    let mut r = vec![0.0; values.len()];
    let mut ties = 0.0;
    let mut i = 0;
    while i < idx.len() {
        let mut j = i;
        while j + 1 < idx.len() && values[idx[j + 1]] == values[idx[i]] {
            j += 1;
        }
        let mean = (i + j) as f64 / 2.0 + 1.0;
        for &k in &idx[i..=j] {
            r[k] = mean;
        }
        let t = (j - i + 1) as f64;
        ties += t * t * t - t;
        i = j + 1;
    }
    (r, ties)
}

/// The groups' sizes and rank sums, and the total count and tie term.
struct Ranked {
    sizes: Vec<usize>,
    sums: Vec<f64>,
    n: f64,
    ties: f64,
}

fn rank_groups(groups: &[Vec<f64>]) -> Ranked {
    let all: Vec<f64> = groups.iter().flatten().copied().collect();
    let (r, ties) = ranks(&all);
    let mut sums = Vec::with_capacity(groups.len());
    let mut at = 0;
    for g in groups {
        sums.push(r[at..at + g.len()].iter().sum());
        at += g.len();
    }
    Ranked {
        sizes: groups.iter().map(Vec::len).collect(),
        sums,
        n: all.len() as f64,
        ties,
    }
}

/// The Kruskal-Wallis H test over the non-empty `groups` (as scipy's `kruskal`).
/// `None` with fewer than two non-empty groups or when every value is the same.
pub fn kruskal_wallis(groups: &[Vec<f64>]) -> Option<KruskalWallis> {
    let groups: Vec<Vec<f64>> = groups.iter().filter(|g| !g.is_empty()).cloned().collect();
    if groups.len() < 2 {
        return None;
    }
    let g = rank_groups(&groups);
    let correction = 1.0 - g.ties / (g.n * g.n * g.n - g.n);
    if correction <= 0.0 {
        return None;
    }
    let ssbn: f64 = g
        .sums
        .iter()
        .zip(&g.sizes)
        .map(|(s, m)| s * s / *m as f64)
        .sum();
    let h = (12.0 / (g.n * (g.n + 1.0)) * ssbn - 3.0 * (g.n + 1.0)) / correction;
    let df = groups.len() as u32 - 1;
    Some(KruskalWallis {
        statistic: h,
        p: chi2_sf(h, df),
        df,
    })
}

/// Dunn's test between every pair of non-empty groups, two-sided, the p-values Sidak
/// corrected for the number of pairs (`1 - (1 - p)^m`, computed without loss for
/// small p). The matrix is indexed by `groups`; `None` on the diagonal, for an empty
/// group, and everywhere when all values are the same.
pub fn dunn_sidak(groups: &[Vec<f64>]) -> Vec<Vec<Option<f64>>> {
    let k = groups.len();
    let mut out = vec![vec![None; k]; k];
    let live: Vec<usize> = (0..k).filter(|&i| !groups[i].is_empty()).collect();
    if live.len() < 2 {
        return out;
    }
    let g = rank_groups(groups);
    let n = g.n;
    let variance = n * (n + 1.0) / 12.0 - g.ties / (12.0 * (n - 1.0));
    if variance <= 0.0 {
        return out;
    }
    let pairs = (live.len() * (live.len() - 1) / 2) as f64;
    for (a, &i) in live.iter().enumerate() {
        for &j in &live[a + 1..] {
            let (ni, nj) = (g.sizes[i] as f64, g.sizes[j] as f64);
            let diff = g.sums[i] / ni - g.sums[j] / nj;
            let z = diff.abs() / (variance * (1.0 / ni + 1.0 / nj)).sqrt();
            let p = (2.0 * normal_sf(z)).min(1.0);
            let adjusted = -(pairs * (-p).ln_1p()).exp_m1();
            out[i][j] = Some(adjusted);
            out[j][i] = Some(adjusted);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranks_average_ties() {
        let (r, t) = ranks(&[3.0, 1.0, 3.0, 2.0]);
        assert_eq!(r, vec![3.5, 1.0, 3.5, 2.0]);
        assert_eq!(t, 6.0);
    }

    #[test]
    fn identical_values_have_no_test() {
        let g = vec![vec![5.0, 5.0], vec![5.0]];
        assert!(kruskal_wallis(&g).is_none());
        assert!(dunn_sidak(&g).iter().flatten().all(Option::is_none));
    }

    #[test]
    fn separated_groups_differ() {
        let g = vec![
            (0..10).map(f64::from).collect(),
            (20..30).map(f64::from).collect(),
        ];
        let kw = kruskal_wallis(&g).unwrap();
        assert_eq!(kw.df, 1);
        assert!(kw.p < 1e-3);
        assert!(dunn_sidak(&g)[0][1].unwrap() < 1e-3);
    }
}
