//! Multinomial logistic regression on standardised features, fitted by L-BFGS: the
//! features scorer's model. Small (classes x features weights), deterministic, and
//! convex, so every fit of the same data reaches the same optimum.

use serde::{Deserialize, Serialize};

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

/// The L2 penalty's strength times the number of training recordings: scikit-learn's
/// default (`C = 1`) for its `LogisticRegression`.
const L2_TIMES_N: f64 = 1.0;
/// L-BFGS memory.
const MEMORY: usize = 10;
/// Iterations at most; the fits here converge in a few hundred.
const MAX_ITER: usize = 1000;

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
        let z: Vec<Vec<f64>> = x.iter().map(|r| model.standardised(r)).collect();
        let l2 = L2_TIMES_N / n;
        let objective = |w: &[f64], g: &mut [f64]| loss(w, g, &z, y, classes, l2);
        model.weights = lbfgs(model.weights.clone(), objective);
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

/// Mean cross-entropy plus the L2 penalty (not on the biases); its gradient into `g`.
fn loss(w: &[f64], g: &mut [f64], z: &[Vec<f64>], y: &[usize], k: usize, l2: f64) -> f64 {
    let n = z.len().max(1) as f64;
    let d1 = z.first().map_or(1, Vec::len);
    g.iter_mut().for_each(|v| *v = 0.0);
    let mut f = 0.0;
    let mut p = vec![0.0; k];
    for (row, &label) in z.iter().zip(y) {
        for (c, pc) in p.iter_mut().enumerate() {
            *pc = dot(&w[c * d1..(c + 1) * d1], row);
        }
        softmax(&mut p);
        f -= p[label].max(1e-300).ln();
        for (c, pc) in p.iter().enumerate() {
            let e = pc - f64::from(u8::from(c == label));
            for (gj, zj) in g[c * d1..(c + 1) * d1].iter_mut().zip(row) {
                *gj += e * zj;
            }
        }
    }
    f /= n;
    for (j, gj) in g.iter_mut().enumerate() {
        *gj /= n;
        if j % d1 != d1 - 1 {
            *gj += l2 * w[j];
            f += 0.5 * l2 * w[j] * w[j];
        }
    }
    f
}

/// Minimises `f` (which writes its gradient) from `x` by L-BFGS with a backtracking
/// (Armijo) line search.
fn lbfgs(mut x: Vec<f64>, mut f: impl FnMut(&[f64], &mut [f64]) -> f64) -> Vec<f64> {
    let n = x.len();
    let mut g = vec![0.0; n];
    let mut fx = f(&x, &mut g);
    let (mut s_hist, mut y_hist): (Vec<Vec<f64>>, Vec<Vec<f64>>) = (Vec::new(), Vec::new());
    let mut g_new = vec![0.0; n];
    for _ in 0..MAX_ITER {
        if dot(&g, &g).sqrt() < 1e-7 {
            break;
        }
        // Two-loop recursion: d = -H g.
        let mut q = g.clone();
        let mut alpha = vec![0.0; s_hist.len()];
        for i in (0..s_hist.len()).rev() {
            let rho = 1.0 / dot(&y_hist[i], &s_hist[i]);
            alpha[i] = rho * dot(&s_hist[i], &q);
            q.iter_mut()
                .zip(&y_hist[i])
                .for_each(|(a, b)| *a -= alpha[i] * b);
        }
        if let (Some(s), Some(y)) = (s_hist.last(), y_hist.last()) {
            let gamma = dot(s, y) / dot(y, y);
            q.iter_mut().for_each(|v| *v *= gamma);
        }
        for i in 0..s_hist.len() {
            let rho = 1.0 / dot(&y_hist[i], &s_hist[i]);
            let beta = rho * dot(&y_hist[i], &q);
            q.iter_mut()
                .zip(&s_hist[i])
                .for_each(|(a, b)| *a += (alpha[i] - beta) * b);
        }
        let mut dir: Vec<f64> = q.iter().map(|v| -v).collect();
        let mut slope = dot(&dir, &g);
        if slope >= 0.0 {
            // Not a descent direction (curvature lost): steepest descent.
            dir = g.iter().map(|v| -v).collect();
            slope = dot(&dir, &g);
            s_hist.clear();
            y_hist.clear();
        }
        let mut step = if s_hist.is_empty() {
            1.0 / dot(&g, &g).sqrt().max(1.0)
        } else {
            1.0
        };
        let mut accepted = None;
        for _ in 0..40 {
            let trial: Vec<f64> = x.iter().zip(&dir).map(|(a, b)| a + step * b).collect();
            let ft = f(&trial, &mut g_new);
            if ft <= fx + 1e-4 * step * slope {
                accepted = Some((trial, ft));
                break;
            }
            step *= 0.5;
        }
        let Some((trial, ft)) = accepted else { break };
        let s: Vec<f64> = trial.iter().zip(&x).map(|(a, b)| a - b).collect();
        let y: Vec<f64> = g_new.iter().zip(&g).map(|(a, b)| a - b).collect();
        let converged = (fx - ft).abs() <= 1e-12 * fx.abs().max(1.0);
        x = trial;
        fx = ft;
        std::mem::swap(&mut g, &mut g_new);
        if dot(&s, &y) > 1e-12 {
            s_hist.push(s);
            y_hist.push(y);
            if s_hist.len() > MEMORY {
                s_hist.remove(0);
                y_hist.remove(0);
            }
        }
        if converged {
            break;
        }
    }
    x
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
}
