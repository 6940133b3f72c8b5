//! Multinomial logistic regression on standardised features: the features scorer's
//! model. Fitted by `linfa-logistic` (L-BFGS with a More-Thuente line search, from
//! `argmin`); the fitted weights are kept here, so a saved model reads back without
//! the crate's types and scores with a few lines. Convex and deterministic: every fit of
//! the same data reaches the same optimum.

use linfa::prelude::Fit;
use linfa_logistic::MultiLogisticRegression;
use serde::{Deserialize, Serialize};

use crate::SelectError;
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

/// The L2 penalty on the summed cross-entropy (biases not penalised): scikit-learn's
/// default `C = 1` for its `LogisticRegression`.
const ALPHA: f64 = 1.0;
/// Iterations at most; the fits here converge in a few hundred.
const MAX_ITER: u64 = 1000;
/// The gradient's norm at which a fit has converged (the loss is summed over the
/// recordings, so this is tight for hundreds of them).
const GRAD_TOL: f64 = 1e-5;
/// The bias of a class the training set lacks: its probability about e^-50, never chosen.
const ABSENT_BIAS: f64 = -50.0;

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
    /// Fits rows `x` (each of the same length) with classes `y` (`< classes`); at least
    /// two classes must be present.
    pub fn fit(x: &[Vec<f64>], y: &[usize], classes: usize) -> Result<Self, SelectError> {
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
        let z = ndarray_linfa::Array2::from_shape_fn((x.len(), d), |(i, j)| {
            (x[i][j] - model.mean[j]) / model.scale[j]
        });
        let targets = ndarray_linfa::Array1::from_vec(y.to_vec());
        let fitted = MultiLogisticRegression::default()
            .alpha(ALPHA)
            .max_iterations(MAX_ITER)
            .gradient_tolerance(GRAD_TOL)
            .fit(&linfa::Dataset::new(z, targets))
            .map_err(|e| SelectError::Fit(e.to_string()))?;
        // linfa's columns are the classes present, in order; a class the training set
        // lacks keeps zero weights and a bias that rules it out.
        let (params, intercept) = (fitted.params(), fitted.intercept());
        let d1 = d + 1;
        for k in 0..classes {
            model.weights[k * d1 + d] = ABSENT_BIAS;
        }
        for (col, &k) in fitted.classes().iter().enumerate() {
            for j in 0..d {
                model.weights[k * d1 + j] = params[[j, col]];
            }
            model.weights[k * d1 + d] = intercept[col];
        }
        Ok(model)
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
        let m = Logistic::fit(&x, &y, 3).unwrap();
        let right = x.iter().zip(&y).filter(|(r, &c)| {
            let p = m.predict(r);
            (0..3).all(|k| p[c] >= p[k])
        });
        assert_eq!(right.count(), 150);
        let p = m.predict(&x[0]);
        assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-9);
    }
}

#[cfg(test)]
mod absent {
    use super::*;

    /// A class missing from the training set is never predicted, and the others keep
    /// their places.
    #[test]
    fn a_class_the_training_set_lacks_is_never_chosen() {
        let x: Vec<Vec<f64>> = (0..40)
            .map(|i| vec![(i % 2) as f64 * 4.0 + (i as f64) * 0.01])
            .collect();
        let y: Vec<usize> = (0..40).map(|i| if i % 2 == 0 { 0 } else { 2 }).collect();
        let m = Logistic::fit(&x, &y, 3).unwrap();
        for (r, &c) in x.iter().zip(&y) {
            let p = m.predict(r);
            assert!(p[1] < 1e-9, "{p:?}");
            assert!(p[c] > 0.5, "{p:?}");
        }
    }
}
