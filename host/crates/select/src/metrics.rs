//! How well cross-validated scores name the true class: the confusion matrix, accuracy
//! and macro-averaged F1, and the best-scoring recordings of each class.

use serde::Serialize;

/// The figures of one cross-validation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Metrics {
    /// Fraction of recordings whose highest score is their class.
    pub accuracy: f64,
    /// F1 averaged over the classes, each weighing the same.
    pub macro_f1: f64,
    /// `confusion[true][predicted]`: counts, rows and columns in class order.
    pub confusion: Vec<Vec<usize>>,
}

/// The class with the highest score (the first of equals).
pub fn argmax(scores: &[f64]) -> usize {
    let mut best = 0;
    for (k, s) in scores.iter().enumerate() {
        if *s > scores[best] {
            best = k;
        }
    }
    best
}

impl Metrics {
    /// The figures of `scores` (one row of class scores per recording) against `labels`.
    pub fn new(scores: &[Vec<f64>], labels: &[usize], classes: usize) -> Self {
        let mut confusion = vec![vec![0; classes]; classes];
        for (s, &l) in scores.iter().zip(labels) {
            confusion[l][argmax(s)] += 1;
        }
        let right: usize = (0..classes).map(|k| confusion[k][k]).sum();
        let f1 = (0..classes).map(|k| {
            let tp = confusion[k][k] as f64;
            let predicted: usize = (0..classes).map(|t| confusion[t][k]).sum();
            let actual: usize = confusion[k].iter().sum();
            if predicted + actual == 0 {
                0.0
            } else {
                2.0 * tp / (predicted + actual) as f64
            }
        });
        Metrics {
            accuracy: right as f64 / labels.len().max(1) as f64,
            macro_f1: f1.sum::<f64>() / classes.max(1) as f64,
            confusion,
        }
    }
}

/// For each class, the indices of the `n` recordings that score highest for it, best
/// first (ties by recording order).
pub fn top(scores: &[Vec<f64>], classes: usize, n: usize) -> Vec<Vec<usize>> {
    (0..classes)
        .map(|k| {
            let mut order: Vec<usize> = (0..scores.len()).collect();
            order.sort_by(|&a, &b| scores[b][k].total_cmp(&scores[a][k]).then(a.cmp(&b)));
            order.truncate(n);
            order
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn figures_of_a_known_confusion() {
        // Truth 0,0,1,1; predicted 0,1,1,1.
        let scores = vec![
            vec![0.9, 0.1],
            vec![0.4, 0.6],
            vec![0.2, 0.8],
            vec![0.3, 0.7],
        ];
        let m = Metrics::new(&scores, &[0, 0, 1, 1], 2);
        assert_eq!(m.confusion, vec![vec![1, 1], vec![0, 2]]);
        assert!((m.accuracy - 0.75).abs() < 1e-12);
        // F1: class 0 = 2/3, class 1 = 0.8.
        assert!((m.macro_f1 - (2.0 / 3.0 + 0.8) / 2.0).abs() < 1e-12);
        assert_eq!(top(&scores, 2, 2), vec![vec![0, 1], vec![2, 3]]);
    }
}
