//! The paper's 3D convolutional network, on the CPU, made to read what a touch is
//! rather than where and when it happened: two blocks of a 3D convolution with filter
//! (1, 2, 2), stride 1 and ReLU, then 3D max pooling (2, 2, 2) stride 2, as the paper
//! describes; then a convolution along time only, (K3, 1, 1) with ReLU, and global
//! average and max pooling of each of its channels over every frame and cell, into a
//! dense layer of one output per class; softmax and categorical cross-entropy; Adam
//! with learning rate 0.003 (the paper's 0.001 trained too slowly here) and Keras's other defaults (beta 0.9 / 0.999, epsilon
//! 1e-7), batches of 32, Glorot-uniform initial weights.
//!
//! The paper gives neither depth nor widths ([`Arch`]: chosen and measured,
//! `docs/select.md`). The paper's network flattened its last map into the dense layer,
//! which then weighs every place and moment on its own: on 560 recordings it learns
//! where along the arm and when each training person touched, not what they did. The
//! global pooling makes the scores the same wherever and whenever a touch happens (to
//! the pooling's stride of 4 frames and 4 cells), and the time convolution gives the
//! pooled features a view of 4 x K3 frames, long enough for a tap's rhythm or a
//! stroke's sweep, which a (1, 2, 2) filter alone never sees. Recordings are
//! zero-padded in front to the longest of the training set, as the paper did (a longer
//! recording scored later keeps its last frames), and each is divided by its own RMS
//! pressure: a person who presses twice as hard makes the same input (0.695 to 0.717
//! on the seven-gesture set, 0.689 to 0.667 on the benchmark: `docs/select.md`). The
//! trained weights are the mean of the second half's epochs', and a model
//! is [`NETWORKS`] such networks whose probabilities are averaged ([`train_ensemble`]).
//!
//! The layers are written out here with their gradients (`cnn/layers.rs`). Each sample's
//! gradient is computed in parallel and the batch's are summed in sample order, so
//! training gives the same weights for a seed whatever the number of threads.

use std::sync::atomic::Ordering;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::dataset::Sample;
use crate::model::Settings;
use crate::rng::Rng;
use crate::select::{Control, Progress};
use crate::SelectError;

mod layers;
use layers::{
    conv_bwd, conv_fwd, dot, global_bwd, global_fwd, pool_bwd, pool_fwd, recycle, zeros, Conv, Dims,
};

/// Samples per Adam step (Keras's default).
const BATCH: usize = 32;
/// Three times the paper's 0.001: with the global pooling, 30 epochs at 0.001 left
/// the training loss near 0.75 and 0.613 on unseen people, 0.003 reached 0.46 and
/// 0.689 (`docs/select.md`).
const LR: f32 = 3e-3;
const BETA1: f32 = 0.9;
const BETA2: f32 = 0.999;
const EPS: f32 = 1e-7;

/// The network's widths: filters of each convolution and the time convolution's
/// length in pooled frames (4 input frames each).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Arch {
    /// Filters of the first (1, 2, 2) convolution.
    pub c1: usize,
    /// Filters of the second (1, 2, 2) convolution.
    pub c2: usize,
    /// Filters of the (K3, 1, 1) time convolution.
    pub c3: usize,
    /// Its length K3, in frames after the two poolings.
    pub k3: usize,
}

impl Arch {
    /// The widths `touchc select` trains (`docs/select.md` has the measurements).
    pub const DEFAULT: Arch = Arch {
        c1: 4,
        c2: 8,
        c3: 16,
        k3: 9,
    };
}

/// The network's weights and the shape it reads.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Net {
    input: Dims,
    classes: usize,
    arch: Arch,
    /// Every weight: conv 1 `[c1][1][2][2]` and its biases, conv 2 `[c2][c1][2][2]`
    /// and its biases, conv 3 `[c3][c2][k3]` and its biases, the dense layer
    /// `[classes][2 c3]` and its biases.
    params: Vec<f32>,
}

/// Where each layer's weights start in [`Net::params`].
struct Offsets {
    b1: usize,
    w2: usize,
    b2: usize,
    w3: usize,
    b3: usize,
    wd: usize,
    bd: usize,
    len: usize,
}

fn offsets(a: Arch, classes: usize) -> Offsets {
    let b1 = a.c1 * 4;
    let w2 = b1 + a.c1;
    let b2 = w2 + a.c2 * a.c1 * 4;
    let w3 = b2 + a.c2;
    let b3 = w3 + a.c3 * a.c2 * a.k3;
    let wd = b3 + a.c3;
    let bd = wd + classes * 2 * a.c3;
    Offsets {
        b1,
        w2,
        b2,
        w3,
        b3,
        wd,
        bd,
        len: bd + classes,
    }
}

/// The layer sizes of a network reading `input`: the convolutions' outputs as stored
/// (`a1`, `a2`, `a3`), the poolings' outputs (`p1`, `p2`, packed), the spans below
/// which each convolution computes.
struct Shapes {
    a1: Dims,
    p1: Dims,
    a2: Dims,
    p2: Dims,
    a3: Dims,
}

fn shapes(input: Dims, a: Arch) -> Shapes {
    let a1 = Dims { c: a.c1, ..input };
    let p1 = a1.conv_pool(a.c1);
    let a2 = Dims { c: a.c2, ..p1 };
    let p2 = a2.conv_pool(a.c2);
    let a3 = Dims { c: a.c3, ..p2 };
    Shapes { a1, p1, a2, p2, a3 }
}

/// What a forward pass keeps for the backward pass.
struct Trace {
    a1: Vec<f32>,
    p1: Vec<f32>,
    arg1: Vec<u32>,
    a2: Vec<f32>,
    p2: Vec<f32>,
    arg2: Vec<u32>,
    a3: Vec<f32>,
    g: Vec<f32>,
    argg: Vec<u32>,
    probs: Vec<f32>,
}

impl Trace {
    /// Gives the layers' buffers back for the next sample.
    fn recycle(self) {
        [self.a1, self.p1, self.a2, self.p2, self.a3]
            .into_iter()
            .for_each(recycle);
    }
}

fn softmax(z: &mut [f32]) {
    let m = z.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let mut s = 0.0;
    for v in z.iter_mut() {
        *v = (*v - m).exp();
        s += *v;
    }
    z.iter_mut().for_each(|v| *v /= s);
}

impl Net {
    /// A network of widths `arch` for recordings of `rows` x `cols` cells padded to
    /// `frames`, with Glorot-uniform weights from `seed` and zero biases (Keras's
    /// defaults).
    fn new(frames: usize, rows: usize, cols: usize, classes: usize, arch: Arch, seed: u64) -> Self {
        let input = Dims {
            c: 1,
            t: frames,
            h: rows,
            w: cols,
        };
        let (a, o) = (arch, offsets(arch, classes));
        let mut rng = Rng::new(seed);
        let mut params = vec![0.0f32; o.len];
        let mut glorot = |range: std::ops::Range<usize>, fan_in: usize, fan_out: usize| {
            let limit = (6.0 / (fan_in + fan_out) as f64).sqrt();
            for p in &mut params[range] {
                *p = ((2.0 * rng.uniform() - 1.0) * limit) as f32;
            }
        };
        glorot(0..o.b1, 4, a.c1 * 4);
        glorot(o.w2..o.b2, a.c1 * 4, a.c2 * 4);
        glorot(o.w3..o.b3, a.c2 * a.k3, a.c3 * a.k3);
        glorot(o.wd..o.bd, 2 * a.c3, classes);
        Net {
            input,
            classes,
            arch,
            params,
        }
    }

    /// The sensor shape `[rows, cols]` the network reads.
    pub fn shape(&self) -> [usize; 2] {
        [self.input.h, self.input.w]
    }

    /// True when the network can read its input: two poolings leave at least one cell
    /// and the time convolution at least one window.
    fn fits(input: Dims, a: Arch) -> bool {
        let p2 = shapes(input, a).p2;
        p2.h * p2.w > 0 && a.k3 > 0 && p2.span_k11(a.k3) > 0
    }

    /// True when the weights fit the shapes (a model file read back).
    pub fn consistent(&self, classes: usize) -> bool {
        let a = self.arch;
        self.classes == classes
            && self.input.c == 1
            && a.c1 > 0
            && a.c2 > 0
            && a.c3 > 0
            && Self::fits(self.input, a)
            && self.params.len() == offsets(a, classes).len
            && self.params.iter().all(|p| p.is_finite())
    }

    /// A sample as the network reads it: padded in front with zeros to the network's
    /// length (or its last frames kept), divided by its own RMS pressure.
    fn input_of(&self, s: &Sample) -> Vec<f32> {
        let d = self.input;
        let (t, _, _) = s.frames.dim();
        let mut x = vec![0.0f32; d.len()];
        let keep = t.min(d.t);
        let plane = d.h * d.w;
        let n = s.frames.len().max(1) as f64;
        let rms = (s.frames.iter().map(|v| f64::from(*v).powi(2)).sum::<f64>() / n).sqrt();
        let scale = if rms > 0.0 { (1.0 / rms) as f32 } else { 1.0 };
        for (k, frame) in s.frames.outer_iter().skip(t - keep).enumerate() {
            let dst = &mut x[(d.t - keep + k) * plane..][..plane];
            for (v, p) in dst.iter_mut().zip(frame.iter()) {
                *v = p * scale;
            }
        }
        x
    }

    fn forward(&self, x: &[f32]) -> Trace {
        let (a, s) = (self.arch, shapes(self.input, self.arch));
        let o = offsets(a, self.classes);
        let p = &self.params;
        let d0 = self.input;
        let a1 = conv_fwd(
            x,
            d0,
            &d0.taps_122(),
            d0.span_122(),
            &p[..o.b1],
            &p[o.b1..o.w2],
            a.c1,
        );
        let (p1, arg1) = pool_fwd(&a1, s.a1);
        let d1 = s.p1;
        let a2 = conv_fwd(
            &p1,
            d1,
            &d1.taps_122(),
            d1.span_122(),
            &p[o.w2..o.b2],
            &p[o.b2..o.w3],
            a.c2,
        );
        let (p2, arg2) = pool_fwd(&a2, s.a2);
        let d2 = s.p2;
        let span3 = d2.span_k11(a.k3);
        let a3 = conv_fwd(
            &p2,
            d2,
            &d2.taps_k11(a.k3),
            span3,
            &p[o.w3..o.b3],
            &p[o.b3..o.wd],
            a.c3,
        );
        let (g, argg) = global_fwd(&a3, s.a3.plane(), span3);
        let mut probs: Vec<f32> = (0..self.classes)
            .map(|k| p[o.bd + k] + dot(&p[o.wd + k * g.len()..][..g.len()], &g))
            .collect();
        softmax(&mut probs);
        Trace {
            a1,
            p1,
            arg1,
            a2,
            p2,
            arg2,
            a3,
            g,
            argg,
            probs,
        }
    }

    /// The cross-entropy of `tr` (the forward pass of `x`) against `label`, and its
    /// gradient for every weight.
    fn backward(&self, x: &[f32], tr: &Trace, label: usize) -> (f32, Vec<f32>) {
        let (a, s) = (self.arch, shapes(self.input, self.arch));
        let o = offsets(a, self.classes);
        let p = &self.params;
        let mut g = vec![0.0f32; o.len];
        let flat = tr.g.len();
        let mut gg = vec![0.0f32; flat];
        for k in 0..self.classes {
            let e = tr.probs[k] - f32::from(u8::from(k == label));
            g[o.bd + k] = e;
            let row = &p[o.wd + k * flat..][..flat];
            for ((gw, gx), (w, x)) in g[o.wd + k * flat..][..flat]
                .iter_mut()
                .zip(gg.iter_mut())
                .zip(row.iter().zip(&tr.g))
            {
                *gw = e * x;
                *gx += e * w;
            }
        }
        let (d0, d1, d2) = (self.input, s.p1, s.p2);
        let span3 = d2.span_k11(a.k3);
        let ga3 = global_bwd(&gg, &tr.argg, &tr.a3, s.a3.plane(), span3);
        let mut gp2 = zeros(tr.p2.len());
        let (head, tail) = g.split_at_mut(o.b3);
        let taps3 = d2.taps_k11(a.k3);
        let conv3 = Conv {
            x: &tr.p2,
            d: d2,
            taps: &taps3,
            span: span3,
            w: &p[o.w3..o.b3],
        };
        conv_bwd(
            &conv3,
            &ga3,
            &mut head[o.w3..],
            &mut tail[..a.c3],
            Some(&mut gp2),
        );
        recycle(ga3);
        let ga2 = pool_bwd(&gp2, &tr.arg2, &tr.a2);
        recycle(gp2);
        let mut gp1 = zeros(tr.p1.len());
        let (head, tail) = g.split_at_mut(o.b2);
        let taps2 = d1.taps_122();
        let conv2 = Conv {
            x: &tr.p1,
            d: d1,
            taps: &taps2,
            span: d1.span_122(),
            w: &p[o.w2..o.b2],
        };
        conv_bwd(
            &conv2,
            &ga2,
            &mut head[o.w2..],
            &mut tail[..a.c2],
            Some(&mut gp1),
        );
        recycle(ga2);
        let ga1 = pool_bwd(&gp1, &tr.arg1, &tr.a1);
        recycle(gp1);
        let (head, tail) = g.split_at_mut(o.b1);
        let taps1 = d0.taps_122();
        let conv1 = Conv {
            x,
            d: d0,
            taps: &taps1,
            span: d0.span_122(),
            w: &p[..o.b1],
        };
        conv_bwd(&conv1, &ga1, head, &mut tail[..a.c1], None);
        recycle(ga1);
        (-tr.probs[label].max(1e-30).ln(), g)
    }

    /// Each class's probability for `sample`.
    pub fn predict(&self, sample: &Sample) -> Vec<f64> {
        let tr = self.forward(&self.input_of(sample));
        let probs = tr.probs.iter().map(|&v| f64::from(v)).collect();
        tr.recycle();
        probs
    }
}

/// Networks a model trains and averages, each from its own initial weights and order
/// of batches: one network's accuracy on people it has not seen varies with its seed
/// by several points (0.701 to 0.725 on the seven-gesture set for seeds 1-3); the mean
/// of three networks' probabilities is both higher and steadier (0.720 to 0.748;
/// 0.676 to 0.703 on the benchmark, `docs/select.md`).
pub const NETWORKS: usize = 3;

/// The seed of network `m` of the ensemble of `seed`: network 0 is `seed`'s own.
fn network_seed(seed: u64, m: usize) -> u64 {
    seed ^ (m as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
}

/// Trains [`NETWORKS`] networks on `samples` with classes `labels` (one after another,
/// each reporting its epochs as network `m + 1` of them, in fold `fold`); stops with
/// [`SelectError::Cancelled`] between batches. Each network keeps the mean of its
/// weights at the end of each epoch of the second half (stochastic weight averaging,
/// Izmailov et al. 2018: 0.717 to 0.737 on the seven-gesture set, 0.667 to 0.676 on
/// the benchmark, `docs/select.md`).
pub fn train_ensemble(
    samples: &[&Sample],
    labels: &[usize],
    classes: usize,
    settings: &Settings,
    fold: Option<usize>,
    control: &Control,
) -> Result<Vec<Net>, SelectError> {
    let average_from = settings.epochs / 2 + 1;
    (0..NETWORKS)
        .map(|m| {
            let progress = |p: Progress| {
                (control.progress)(Progress {
                    network: m + 1,
                    networks: NETWORKS,
                    ..p
                })
            };
            let member = Control {
                cancel: control.cancel,
                progress: &progress,
            };
            let schedule = (
                network_seed(settings.seed, m),
                settings.epochs,
                average_from,
            );
            train_averaged(samples, labels, classes, schedule, fold, &member)
        })
        .collect()
}

/// Each class's probability for `sample`: the mean of the networks' (an empty list
/// gives none).
pub fn predict_ensemble(nets: &[Net], sample: &Sample) -> Vec<f64> {
    let each: Vec<Vec<f64>> = nets.iter().map(|net| net.predict(sample)).collect();
    let classes = each.first().map_or(0, Vec::len);
    (0..classes)
        .map(|c| each.iter().map(|p| p[c]).sum::<f64>() / each.len() as f64)
        .collect()
}

/// One network of the ensemble, from `seed`, for `epochs`, its weights averaged over
/// the epochs from `average_from` on (one past `epochs` keeps the last epoch's).
fn train_averaged(
    samples: &[&Sample],
    labels: &[usize],
    classes: usize,
    (seed, epochs, average_from): (u64, usize, usize),
    fold: Option<usize>,
    control: &Control,
) -> Result<Net, SelectError> {
    let frames = samples.iter().map(|s| s.frames.dim().0).max().unwrap_or(0);
    let (_, rows, cols) = samples.first().map_or((0, 0, 0), |s| s.frames.dim());
    let input = Dims {
        c: 1,
        t: frames,
        h: rows,
        w: cols,
    };
    let arch = Arch::DEFAULT;
    if !Net::fits(input, arch) {
        return Err(SelectError::Setting(format!(
            "the network needs frames of at least 7 x 7 cells and {} frames; these are {rows} x {cols}, {frames} frames at most",
            4 * arch.k3
        )));
    }
    let mut net = Net::new(frames, rows, cols, classes, arch, seed);
    let inputs: Vec<Vec<f32>> = samples.par_iter().map(|s| net.input_of(s)).collect();
    let n = net.params.len();
    let (mut m, mut v) = (vec![0.0f32; n], vec![0.0f32; n]);
    let mut rng = Rng::new(seed ^ 0xba7c_4e55);
    let mut order: Vec<usize> = (0..samples.len()).collect();
    let mut step = 0i32;
    let mut sum = vec![0.0f64; n];
    let mut averaged = 0u32;
    for epoch in 1..=epochs {
        rng.shuffle(&mut order);
        let mut total = 0.0f64;
        for batch in order.chunks(BATCH) {
            if control.cancel.load(Ordering::Relaxed) {
                return Err(SelectError::Cancelled);
            }
            let grads: Vec<(f32, Vec<f32>)> = batch
                .par_iter()
                .map(|&i| {
                    let tr = net.forward(&inputs[i]);
                    let out = net.backward(&inputs[i], &tr, labels[i]);
                    tr.recycle();
                    out
                })
                .collect();
            let mut g = vec![0.0f32; n];
            for (loss, gi) in &grads {
                total += f64::from(*loss);
                g.iter_mut().zip(gi).for_each(|(a, b)| *a += b);
            }
            let inv = 1.0 / batch.len() as f32;
            step += 1;
            let (c1, c2) = (1.0 - BETA1.powi(step), 1.0 - BETA2.powi(step));
            for j in 0..n {
                let gj = g[j] * inv;
                m[j] = BETA1 * m[j] + (1.0 - BETA1) * gj;
                v[j] = BETA2 * v[j] + (1.0 - BETA2) * gj * gj;
                net.params[j] -= LR * (m[j] / c1) / ((v[j] / c2).sqrt() + EPS);
            }
        }
        (control.progress)(Progress {
            fold,
            network: 1,
            networks: 1,
            epoch,
            epochs,
            loss: total / samples.len().max(1) as f64,
        });
        if epoch >= average_from {
            averaged += 1;
            sum.iter_mut()
                .zip(&net.params)
                .for_each(|(a, p)| *a += f64::from(*p));
        }
    }
    if averaged > 0 {
        let inv = 1.0 / f64::from(averaged);
        net.params
            .iter_mut()
            .zip(&sum)
            .for_each(|(p, a)| *p = (a * inv) as f32);
    }
    Ok(net)
}

#[cfg(test)]
mod tests;
