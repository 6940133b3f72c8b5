//! Multinomial logistic regression on standardised features: the features scorer's
//! model, fitted by smartcore's `LogisticRegression` (L-BFGS). Small (classes x features
//! weights), deterministic, and convex, so every fit of the same data reaches the same
//! optimum.

use serde::{Deserialize, Serialize};
use smartcore::linalg::basic::arrays::Array;
use smartcore::linalg::basic::matrix::DenseMatrix;
use smartcore::linear::logistic_regression::{
    LogisticRegression, LogisticRegressionParameters, LogisticRegressionSolverName,
};

/// A fitted model: the standardisation and the weights.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Logistic {
    /// Each feature's mean over the training set.
    pub mean: Vec<f64>,
    /// Each feature's standard deviation (1 where it is constant).
    pub scale: Vec<f64>,
    /// Weights, one row of `features + 1` per class (the bias last).
    pub weights: Vec<f64>,
    /// Number of classes.
    pub classes: usize,
}

/// The L2 penalty on the summed cross-entropy: scikit-learn's default (`C = 1`) for its
/// `LogisticRegression`, and smartcore's `alpha` (both leave the biases unpenalised).
const L2: f64 = 1.0;
/// The bias given a class the training set has no recording of: its probability is then
/// zero to f64 precision (`exp(-1000)` underflows), as the likelihood's optimum has it.
const ABSENT_BIAS: f64 = -1000.0;

fn softmax(z: &mut [f64]) {
    let m = z.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let mut s = 0.0;
    for v in z.iter_mut() {
        *v = (*v - m).exp();
        s += *v;
    }
    for v in z.iter_mut() {
        *v /= s;
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

impl Logistic {
    /// Fits rows `x` (each of the same length) with classes `y` (`< classes`).
    pub fn fit(x: &[Vec<f64>], y: &[usize], classes: usize) -> Self {
        let d = x.first().map_or(0, Vec::len);
        let n = x.len().max(1) as f64;
        let mean: Vec<f64> = (0..d)
            .map(|j| x.iter().map(|r| r[j]).sum::<f64>() / n)
            .collect();
        let scale: Vec<f64> = (0..d)
            .map(|j| {
                let v = x.iter().map(|r| (r[j] - mean[j]).powi(2)).sum::<f64>() / n;
                if v > 1e-24 {
                    v.sqrt()
                } else {
                    1.0
                }
            })
            .collect();
        let mut model = Logistic {
            mean,
            scale,
            weights: vec![0.0; classes * (d + 1)],
            classes,
        };
        model.weights = fit_weights(&model, x, y, classes, d);
        model
    }

    fn standardised(&self, row: &[f64]) -> Vec<f64> {
        let mut z: Vec<f64> = row
            .iter()
            .zip(self.mean.iter().zip(&self.scale))
            .map(|(v, (m, s))| (v - m) / s)
            .collect();
        z.push(1.0);
        z
    }

    /// The probability of each class for one row of features.
    pub fn predict(&self, row: &[f64]) -> Vec<f64> {
        let z = self.standardised(row);
        let d1 = z.len();
        let mut p: Vec<f64> = (0..self.classes)
            .map(|k| dot(&self.weights[k * d1..(k + 1) * d1], &z))
            .collect();
        softmax(&mut p);
        p
    }
}

/// The weights, one row of `d + 1` per class (bias last), of smartcore's multinomial
/// logistic regression (L-BFGS) on the standardised rows. smartcore fits the classes the
/// training set holds; a class it lacks keeps zero weights and [`ABSENT_BIAS`].
fn fit_weights(
    model: &Logistic,
    x: &[Vec<f64>],
    y: &[usize],
    classes: usize,
    d: usize,
) -> Vec<f64> {
    let d1 = d + 1;
    let mut weights = vec![0.0; classes * d1];
    let mut present: Vec<usize> = y.iter().copied().filter(|&c| c < classes).collect();
    present.sort_unstable();
    present.dedup();
    for c in (0..classes).filter(|c| present.binary_search(c).is_err()) {
        weights[c * d1 + d] = ABSENT_BIAS;
    }
    if present.len() < 2 || d == 0 {
        // One class seen (or nothing to read): it is the only answer, at probability 1.
        return weights;
    }
    let values: Vec<f64> = x
        .iter()
        .flat_map(|r| model.standardised(r).into_iter().take(d))
        .collect();
    // Labels as indices into `present`, which smartcore's sorted `unique` reproduces.
    let labels: Vec<u32> = y
        .iter()
        .map(|c| present.binary_search(c).map_or(0, |i| i as u32))
        .collect();
    let fitted = DenseMatrix::new(x.len(), d, values, false).and_then(|m| {
        LogisticRegression::fit(
            &m,
            &labels,
            LogisticRegressionParameters::default()
                .with_solver(LogisticRegressionSolverName::LBFGS)
                .with_alpha(L2),
        )
    });
    let Ok(fitted) = fitted else {
        // Only a shape mismatch fails, and the rows were built to the shape above.
        return weights;
    };
    let (coefficients, intercept) = (fitted.coefficients(), fitted.intercept());
    if present.len() == 2 {
        // One logit, the second class's against the first's (held at 0).
        let c = present[1];
        for j in 0..d {
            weights[c * d1 + j] = *coefficients.get((0, j));
        }
        weights[c * d1 + d] = *intercept.get((0, 0));
    } else {
        for (k, &c) in present.iter().enumerate() {
            for j in 0..d {
                weights[c * d1 + j] = *coefficients.get((k, j));
            }
            weights[c * d1 + d] = *intercept.get((k, 0));
        }
    }
    weights
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn separates_three_gaussian_clouds() {
        let mut x = Vec::new();
        let mut y = Vec::new();
        for i in 0..150 {
            let c = i % 3;
            let jitter = ((i * 37) % 17) as f64 / 17.0 - 0.5;
            x.push(vec![
                c as f64 * 3.0 + jitter,
                -(c as f64) + 0.3 * jitter,
                jitter,
            ]);
            y.push(c);
        }
        let m = Logistic::fit(&x, &y, 3);
        let right = x.iter().zip(&y).filter(|(r, &c)| {
            let p = m.predict(r);
            (0..3).all(|k| p[c] >= p[k])
        });
        assert_eq!(right.count(), 150);
        let p = m.predict(&x[0]);
        assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-9);
    }

    #[test]
    fn classes_a_training_set_lacks_get_no_probability() {
        // Four classes, the rows only of classes 1 and 3 (smartcore's two-class path).
        let x: Vec<Vec<f64>> = (0..40)
            .map(|i| vec![(i % 2) as f64 * 4.0 + (i % 7) as f64 * 0.1])
            .collect();
        let y: Vec<usize> = (0..40).map(|i| if i % 2 == 0 { 1 } else { 3 }).collect();
        let m = Logistic::fit(&x, &y, 4);
        for (row, &c) in x.iter().zip(&y) {
            let p = m.predict(row);
            assert_eq!((p[0], p[2]), (0.0, 0.0));
            assert!(p[c] > 0.9, "{p:?} for class {c}");
            assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        }
        // A model of one class answers it; the weights stay finite, so a model file
        // (JSON) holds them.
        let one = Logistic::fit(&x[..3], &[2, 2, 2], 3);
        assert_eq!(one.predict(&x[0]), vec![0.0, 0.0, 1.0]);
        assert!(one.weights.iter().all(|w| w.is_finite()));
    }
}
