//! k-means (Lloyd's algorithm from k-means++ starts) and the two criteria that choose
//! the number of clusters: Calinski-Harabasz and the mean silhouette.

use crate::order::SplitMix64;

/// Lloyd iterations at most (scikit-learn's default).
const MAX_ITER: usize = 300;

/// One k-means result.
#[derive(Debug, Clone, PartialEq)]
pub struct KMeansRun {
    /// The number of clusters.
    pub k: usize,
    /// The start the result came from (k-means++ on the seed), one row per cluster.
    pub init: Vec<Vec<f64>>,
    /// The cluster means.
    pub centers: Vec<Vec<f64>>,
    /// Each point's cluster.
    pub labels: Vec<usize>,
    /// The sum of squared distances of the points to their centers.
    pub inertia: f64,
    /// Lloyd iterations run.
    pub iterations: usize,
}

fn sq_dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

fn nearest(x: &[f64], centers: &[Vec<f64>]) -> usize {
    let mut best = (0, f64::INFINITY);
    for (j, c) in centers.iter().enumerate() {
        let d = sq_dist(x, c);
        if d < best.1 {
            best = (j, d);
        }
    }
    best.0
}

/// The means of the clusters; `None` if one is empty.
fn means(points: &[Vec<f64>], labels: &[usize], k: usize) -> Option<Vec<Vec<f64>>> {
    let dim = points[0].len();
    let mut sums = vec![vec![0.0; dim]; k];
    let mut counts = vec![0usize; k];
    for (x, &l) in points.iter().zip(labels) {
        counts[l] += 1;
        for (s, v) in sums[l].iter_mut().zip(x) {
            *s += v;
        }
    }
    if counts.contains(&0) {
        return None;
    }
    for (s, c) in sums.iter_mut().zip(&counts) {
        s.iter_mut().for_each(|v| *v /= *c as f64);
    }
    Some(sums)
}

/// k-means++ seeding: the first center uniformly, each next one with probability
/// proportional to the squared distance to the nearest chosen. `None` when fewer than
/// `k` distinct points exist.
fn plus_plus(points: &[Vec<f64>], k: usize, rng: &mut SplitMix64) -> Option<Vec<Vec<f64>>> {
    let mut centers = vec![points[rng.below(points.len() as u64) as usize].clone()];
    let mut d2: Vec<f64> = points.iter().map(|x| sq_dist(x, &centers[0])).collect();
    while centers.len() < k {
        let total: f64 = d2.iter().sum();
        if total <= 0.0 {
            return None;
        }
        let mut r = rng.next_f64() * total;
        let mut pick = d2.iter().rposition(|d| *d > 0.0)?;
        for (i, d) in d2.iter().enumerate() {
            if r < *d {
                pick = i;
                break;
            }
            r -= d;
        }
        let c = points[pick].clone();
        for (d, x) in d2.iter_mut().zip(points) {
            *d = d.min(sq_dist(x, &c));
        }
        centers.push(c);
    }
    Some(centers)
}

/// Lloyd's algorithm from `init` until no label changes, as scikit-learn's `lloyd`
/// with `tol=0`. `None` if a cluster empties (scikit-learn would move a far point into
/// it; this start is dropped instead, so that every kept run is plain Lloyd).
fn lloyd(points: &[Vec<f64>], init: Vec<Vec<f64>>) -> Option<KMeansRun> {
    let k = init.len();
    let mut centers = init.clone();
    let mut labels: Vec<usize> = Vec::new();
    let mut iterations = 0;
    let mut converged = false;
    while iterations < MAX_ITER {
        iterations += 1;
        let next: Vec<usize> = points.iter().map(|x| nearest(x, &centers)).collect();
        if next == labels {
            converged = true;
            break;
        }
        centers = means(points, &next, k)?;
        labels = next;
    }
    if !converged {
        labels = points.iter().map(|x| nearest(x, &centers)).collect();
    }
    let inertia = points
        .iter()
        .zip(&labels)
        .map(|(x, &l)| sq_dist(x, &centers[l]))
        .sum();
    Some(KMeansRun {
        k,
        init,
        centers,
        labels,
        inertia,
        iterations,
    })
}

/// k-means with `k` clusters: `starts` k-means++ starts from `seed`, the run of least
/// inertia kept (the first on a tie). `None` if no start gave `k` non-empty clusters
/// (fewer than `k` distinct points, or every start emptied one).
pub fn kmeans(points: &[Vec<f64>], k: usize, seed: u64, starts: usize) -> Option<KMeansRun> {
    if k == 0 || points.len() < k {
        return None;
    }
    let mut best: Option<KMeansRun> = None;
    for s in 0..starts {
        let mut rng = SplitMix64::new(seed ^ ((k as u64) << 32) ^ s as u64);
        let Some(run) = plus_plus(points, k, &mut rng).and_then(|init| lloyd(points, init)) else {
            continue;
        };
        if best.as_ref().is_none_or(|b| run.inertia < b.inertia) {
            best = Some(run);
        }
    }
    best
}

/// The Calinski-Harabasz index: between-cluster over within-cluster dispersion, each
/// per degree of freedom (1 when the clusters have no spread, as scikit-learn).
pub(crate) fn calinski_harabasz(points: &[Vec<f64>], labels: &[usize], k: usize) -> f64 {
    let n = points.len();
    let dim = points[0].len();
    let mean: Vec<f64> = (0..dim)
        .map(|d| points.iter().map(|x| x[d]).sum::<f64>() / n as f64)
        .collect();
    let (mut extra, mut intra) = (0.0, 0.0);
    for c in 0..k {
        let members: Vec<&Vec<f64>> = points
            .iter()
            .zip(labels)
            .filter(|(_, &l)| l == c)
            .map(|(x, _)| x)
            .collect();
        let m = members.len() as f64;
        let mk: Vec<f64> = (0..dim)
            .map(|d| members.iter().map(|x| x[d]).sum::<f64>() / m)
            .collect();
        extra += m * sq_dist(&mk, &mean);
        intra += members.iter().map(|x| sq_dist(x, &mk)).sum::<f64>();
    }
    if intra == 0.0 {
        1.0
    } else {
        extra * (n - k) as f64 / (intra * (k as f64 - 1.0))
    }
}

/// The mean silhouette over all points (Euclidean distance); a point alone in its
/// cluster scores 0.
pub(crate) fn silhouette(points: &[Vec<f64>], labels: &[usize], k: usize) -> f64 {
    let n = points.len();
    let sizes: Vec<usize> = (0..k)
        .map(|c| labels.iter().filter(|&&l| l == c).count())
        .collect();
    let mut total = 0.0;
    for i in 0..n {
        let mut sums = vec![0.0; k];
        for j in 0..n {
            sums[labels[j]] += sq_dist(&points[i], &points[j]).sqrt();
        }
        let own = labels[i];
        if sizes[own] <= 1 {
            continue;
        }
        let a = sums[own] / (sizes[own] - 1) as f64;
        let b = (0..k)
            .filter(|&c| c != own && sizes[c] > 0)
            .map(|c| sums[c] / sizes[c] as f64)
            .fold(f64::INFINITY, f64::min);
        let m = a.max(b);
        if m > 0.0 {
            total += (b - a) / m;
        }
    }
    total / n as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_blobs() -> Vec<Vec<f64>> {
        let mut p = Vec::new();
        for i in 0..10 {
            p.push(vec![0.0 + i as f64 * 0.01, 0.0]);
            p.push(vec![5.0 + i as f64 * 0.01, 5.0]);
        }
        p
    }

    #[test]
    fn two_blobs_split_in_two() {
        let p = two_blobs();
        let run = kmeans(&p, 2, 1, 5).unwrap();
        let l = &run.labels;
        // Even indices are the first blob, odd the second.
        assert!(l.iter().step_by(2).all(|&x| x == l[0]));
        assert!(l.iter().skip(1).step_by(2).all(|&x| x == l[1]));
        assert_ne!(l[0], l[1]);
        assert!(silhouette(&p, &run.labels, 2) > 0.9);
        assert!(calinski_harabasz(&p, &run.labels, 2) > 100.0);
    }

    #[test]
    fn too_few_distinct_points_give_none() {
        let p = vec![vec![1.0, 0.0]; 5];
        assert!(kmeans(&p, 2, 0, 3).is_none());
    }
}
