//! The paper's 3D convolutional network, on the CPU: two blocks of a 3D convolution
//! with filter (1, 2, 2), stride 1 and ReLU, then 3D max pooling (2, 2, 2) stride 2;
//! flattened into a dense layer of one output per class; softmax and categorical
//! cross-entropy; Adam with learning rate 0.001 and Keras's other defaults
//! (beta 0.9 / 0.999, epsilon 1e-7), batches of 32, Glorot-uniform initial weights.
//!
//! The paper gives neither depth nor widths: [`C1`] and [`C2`] filters, chosen so the
//! 5-fold run on 700 recordings of 705 x 8 x 21 fits in minutes on two cores
//! (`docs/select.md`). Recordings are zero-padded in front to the longest of the
//! training set, as the paper did (a longer recording scored later keeps its last
//! frames), and scaled by the training set's RMS pressure.
//!
//! A (1, 2, 2) filter never mixes frames, so each convolution is a 2D convolution of
//! every frame; the layers are written out here, with their gradients. A channel's
//! frames lie one after another, so a convolution's output is computed at every position
//! of its input's storage as one long sum of four shifted copies of it (the positions in
//! a frame's last row or column, which the filter would read past, hold values nothing
//! reads): loops of tens of thousands of floats that the compiler turns into SIMD,
//! where a loop per row would run over 20. Each sample's gradient is computed in
//! parallel and the batch's are summed in sample order, so training gives the same
//! weights for a seed whatever the number of threads.

use std::sync::atomic::Ordering;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::dataset::Sample;
use crate::rng::Rng;
use crate::select::{Control, Progress};
use crate::SelectError;

/// Filters of the first convolution.
pub const C1: usize = 4;
/// Filters of the second convolution.
pub const C2: usize = 8;
/// Samples per Adam step (Keras's default).
const BATCH: usize = 32;
const LR: f32 = 1e-3;
const BETA1: f32 = 0.9;
const BETA2: f32 = 0.999;
const EPS: f32 = 1e-7;

/// Sizes of a tensor `[channels, frames, rows, cols]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
struct Dims {
    c: usize,
    t: usize,
    h: usize,
    w: usize,
}

impl Dims {
    fn len(self) -> usize {
        self.c * self.t * self.h * self.w
    }
    /// Floats of one channel.
    fn plane(self) -> usize {
        self.t * self.h * self.w
    }
    /// A (1, 2, 2) convolution's output as stored: `c` channels over this storage (see
    /// [`conv_fwd`]).
    fn conv(self, c: usize) -> Dims {
        Dims { c, ..self }
    }
    /// After (2, 2, 2) pooling (floor, as Keras's "valid") of the (1, 2, 2)
    /// convolution stored in `self`, whose last row and column are not outputs.
    fn conv_pool(self) -> Dims {
        Dims {
            c: self.c,
            t: self.t / 2,
            h: self.h.saturating_sub(1) / 2,
            w: self.w.saturating_sub(1) / 2,
        }
    }
}

/// The network's weights and the shape it reads.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Net {
    input: Dims,
    classes: usize,
    /// Multiplies the pressure (1 / the training set's RMS).
    scale: f32,
    /// Every weight: conv 1 `[C1][1][2][2]` and its biases, conv 2 `[C2][C1][2][2]` and
    /// its biases, the dense layer `[classes][flat]` and its biases.
    params: Vec<f32>,
}

/// Where each layer's weights start in [`Net::params`].
struct Offsets {
    b1: usize,
    w2: usize,
    b2: usize,
    wd: usize,
    bd: usize,
    len: usize,
}

fn offsets(input: Dims, classes: usize) -> Offsets {
    let flat = shapes(input).p2.len();
    let b1 = C1 * input.c * 4;
    let w2 = b1 + C1;
    let b2 = w2 + C2 * C1 * 4;
    let wd = b2 + C2;
    let bd = wd + classes * flat;
    Offsets {
        b1,
        w2,
        b2,
        wd,
        bd,
        len: bd + classes,
    }
}

/// The layer sizes of a network reading `input`: the convolutions' outputs as stored
/// (`a1`, `a2`), the poolings' outputs (`p1`, `p2`, packed).
struct Shapes {
    a1: Dims,
    p1: Dims,
    a2: Dims,
    p2: Dims,
}

fn shapes(input: Dims) -> Shapes {
    let a1 = input.conv(C1);
    let p1 = a1.conv_pool();
    let a2 = p1.conv(C2);
    let p2 = a2.conv_pool();
    Shapes { a1, p1, a2, p2 }
}

/// Sum of `a[i] * b[i]` in eight lanes (a float sum in one lane cannot be vectorised:
/// its order is fixed), the lanes added last: the same order every run.
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut lanes = [0.0f32; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f32 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for l in 0..8 {
            lanes[l] += x[l] * y[l];
        }
    }
    lanes.iter().sum::<f32>() + tail
}

/// Positions of a channel of `d` whose (1, 2, 2) window lies inside its storage: every
/// output position is below it.
fn span(d: Dims) -> usize {
    d.plane().saturating_sub(d.w + 1)
}

/// (1, 2, 2) convolution of `x` (`d`, packed) by `w` `[cout][cin][2][2]` plus `b`, then
/// ReLU, stored over `d.conv(cout)`: output `(t, i, j)` at `x`'s index of `(t, i, j)`,
/// for `i < d.h - 1`, `j < d.w - 1`.
fn conv_fwd(x: &[f32], d: Dims, w: &[f32], b: &[f32], cout: usize) -> Vec<f32> {
    let (n, m) = (d.plane(), span(d));
    let mut y = vec![0.0f32; cout * n];
    for (co, yc) in y.chunks_exact_mut(n).enumerate() {
        let yc = &mut yc[..m];
        yc.iter_mut().for_each(|v| *v = b[co]);
        for (ci, xc) in x.chunks_exact(n).enumerate() {
            for (dy, dx) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                let k = w[((co * d.c + ci) * 2 + dy) * 2 + dx];
                let off = dy * d.w + dx;
                for (v, s) in yc.iter_mut().zip(&xc[off..off + m]) {
                    *v += k * s;
                }
            }
        }
        yc.iter_mut().for_each(|v| *v = v.max(0.0));
    }
    y
}

/// Gradients of [`conv_fwd`]: `gy` (already through the ReLU, zero where nothing was
/// an output) into `gw`, `gb` and, when asked, the input's gradient.
#[allow(clippy::too_many_arguments)]
fn conv_bwd(
    x: &[f32],
    d: Dims,
    w: &[f32],
    gy: &[f32],
    cout: usize,
    gw: &mut [f32],
    gb: &mut [f32],
    gx: Option<&mut [f32]>,
) {
    let (n, m) = (d.plane(), span(d));
    let mut gx = gx;
    for (co, gc) in gy.chunks_exact(n).enumerate().take(cout) {
        let gc = &gc[..m];
        gb[co] += gc.iter().sum::<f32>();
        for (ci, xc) in x.chunks_exact(n).enumerate() {
            for (dy, dx) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                let widx = ((co * d.c + ci) * 2 + dy) * 2 + dx;
                let off = dy * d.w + dx;
                gw[widx] += dot(gc, &xc[off..off + m]);
                if let Some(gx) = gx.as_deref_mut() {
                    let k = w[widx];
                    for (v, a) in gx[ci * n + off..][..m].iter_mut().zip(gc) {
                        *v += k * a;
                    }
                }
            }
        }
    }
}

/// (2, 2, 2) max pooling of the convolution stored in `x` (`d`); the packed output and
/// the index in `x` of each maximum.
fn pool_fwd(x: &[f32], d: Dims) -> (Vec<f32>, Vec<u32>) {
    let o = d.conv_pool();
    let mut y = vec![0.0f32; o.len()];
    let mut arg = vec![0u32; o.len()];
    for c in 0..o.c {
        for t in 0..o.t {
            for i in 0..o.h {
                for j in 0..o.w {
                    let (mut best, mut at) = (f32::NEG_INFINITY, 0usize);
                    for (dt, di, dj) in [
                        (0, 0, 0),
                        (0, 0, 1),
                        (0, 1, 0),
                        (0, 1, 1),
                        (1, 0, 0),
                        (1, 0, 1),
                        (1, 1, 0),
                        (1, 1, 1),
                    ] {
                        let idx = ((c * d.t + 2 * t + dt) * d.h + 2 * i + di) * d.w + 2 * j + dj;
                        if x[idx] > best {
                            best = x[idx];
                            at = idx;
                        }
                    }
                    let k = ((c * o.t + t) * o.h + i) * o.w + j;
                    y[k] = best;
                    arg[k] = at as u32;
                }
            }
        }
    }
    (y, arg)
}

/// What a forward pass keeps for the backward pass.
struct Trace {
    a1: Vec<f32>,
    p1: Vec<f32>,
    arg1: Vec<u32>,
    a2: Vec<f32>,
    p2: Vec<f32>,
    arg2: Vec<u32>,
    probs: Vec<f32>,
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
    /// A network for recordings of `rows` x `cols` cells padded to `frames`, with
    /// Glorot-uniform weights from `seed` and zero biases (Keras's defaults).
    fn new(frames: usize, rows: usize, cols: usize, classes: usize, scale: f32, seed: u64) -> Self {
        let input = Dims {
            c: 1,
            t: frames,
            h: rows,
            w: cols,
        };
        let o = offsets(input, classes);
        let flat = shapes(input).p2.len();
        let mut rng = Rng::new(seed);
        let mut params = vec![0.0f32; o.len];
        let mut glorot = |range: std::ops::Range<usize>, fan_in: usize, fan_out: usize| {
            let limit = (6.0 / (fan_in + fan_out) as f64).sqrt();
            for p in &mut params[range] {
                *p = ((2.0 * rng.uniform() - 1.0) * limit) as f32;
            }
        };
        glorot(0..o.b1, 4, C1 * 4);
        glorot(o.w2..o.b2, C1 * 4, C2 * 4);
        glorot(o.wd..o.bd, flat, classes);
        Net {
            input,
            classes,
            scale,
            params,
        }
    }

    /// The sensor shape `[rows, cols]` the network reads.
    pub fn shape(&self) -> [usize; 2] {
        [self.input.h, self.input.w]
    }

    /// True when the weights fit the shapes (a model file read back).
    pub fn consistent(&self, classes: usize) -> bool {
        let s = shapes(self.input);
        self.classes == classes
            && self.input.c == 1
            && s.p2.len() > 0
            && self.params.len() == offsets(self.input, classes).len
            && self.scale.is_finite()
            && self.params.iter().all(|p| p.is_finite())
    }

    /// A sample as the network reads it: padded in front with zeros to the network's
    /// length (or its last frames kept), scaled.
    fn input_of(&self, s: &Sample) -> Vec<f32> {
        let d = self.input;
        let (t, _, _) = s.frames.dim();
        let mut x = vec![0.0f32; d.len()];
        let keep = t.min(d.t);
        let plane = d.h * d.w;
        for (k, frame) in s.frames.outer_iter().skip(t - keep).enumerate() {
            let dst = &mut x[(d.t - keep + k) * plane..][..plane];
            for (v, p) in dst.iter_mut().zip(frame.iter()) {
                *v = p * self.scale;
            }
        }
        x
    }

    fn forward(&self, x: &[f32]) -> Trace {
        let s = shapes(self.input);
        let o = offsets(self.input, self.classes);
        let p = &self.params;
        let a1 = conv_fwd(x, self.input, &p[..o.b1], &p[o.b1..o.w2], C1);
        let (p1, arg1) = pool_fwd(&a1, s.a1);
        let a2 = conv_fwd(&p1, s.p1, &p[o.w2..o.b2], &p[o.b2..o.wd], C2);
        let (p2, arg2) = pool_fwd(&a2, s.a2);
        let flat = p2.len();
        let mut probs: Vec<f32> = (0..self.classes)
            .map(|k| {
                let row = &p[o.wd + k * flat..][..flat];
                p[o.bd + k] + dot(row, &p2)
            })
            .collect();
        softmax(&mut probs);
        Trace {
            a1,
            p1,
            arg1,
            a2,
            p2,
            arg2,
            probs,
        }
    }

    /// The cross-entropy of `tr` (the forward pass of `x`) against `label`, and its
    /// gradient for every weight.
    fn backward(&self, x: &[f32], tr: &Trace, label: usize) -> (f32, Vec<f32>) {
        let s = shapes(self.input);
        let o = offsets(self.input, self.classes);
        let p = &self.params;
        let mut g = vec![0.0f32; o.len];
        let flat = tr.p2.len();
        let mut gp2 = vec![0.0f32; flat];
        for k in 0..self.classes {
            let e = tr.probs[k] - f32::from(u8::from(k == label));
            g[o.bd + k] = e;
            let row = &p[o.wd + k * flat..][..flat];
            for ((gw, gx), (w, x)) in g[o.wd + k * flat..][..flat]
                .iter_mut()
                .zip(gp2.iter_mut())
                .zip(row.iter().zip(&tr.p2))
            {
                *gw = e * x;
                *gx += e * w;
            }
        }
        // Through the pooling (to each maximum) and the ReLU (where it passed).
        let mut ga2 = vec![0.0f32; tr.a2.len()];
        for (gv, &at) in gp2.iter().zip(&tr.arg2) {
            if tr.a2[at as usize] > 0.0 {
                ga2[at as usize] += gv;
            }
        }
        let mut gp1 = vec![0.0f32; tr.p1.len()];
        {
            let (head, tail) = g.split_at_mut(o.b2);
            conv_bwd(
                &tr.p1,
                s.p1,
                &p[o.w2..o.b2],
                &ga2,
                C2,
                &mut head[o.w2..],
                &mut tail[..C2],
                Some(&mut gp1),
            );
        }
        let mut ga1 = vec![0.0f32; tr.a1.len()];
        for (gv, &at) in gp1.iter().zip(&tr.arg1) {
            if tr.a1[at as usize] > 0.0 {
                ga1[at as usize] += gv;
            }
        }
        {
            let (head, tail) = g.split_at_mut(o.b1);
            conv_bwd(
                x,
                self.input,
                &p[..o.b1],
                &ga1,
                C1,
                head,
                &mut tail[..C1],
                None,
            );
        }
        (-tr.probs[label].max(1e-30).ln(), g)
    }

    /// Each class's probability for `sample`.
    pub fn predict(&self, sample: &Sample) -> Vec<f64> {
        self.forward(&self.input_of(sample))
            .probs
            .iter()
            .map(|&v| f64::from(v))
            .collect()
    }
}

/// Trains a network on `samples` with classes `labels` for `epochs`, reporting each
/// epoch as fold `fold`; stops with [`SelectError::Cancelled`] between batches.
pub fn train(
    samples: &[&Sample],
    labels: &[usize],
    classes: usize,
    seed: u64,
    epochs: usize,
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
    if shapes(input).p2.len() == 0 {
        return Err(SelectError::Setting(format!(
            "the network needs frames of at least 6 x 6 cells and 4 frames; these are {rows} x {cols}, {frames} frames at most"
        )));
    }
    let (sum2, count) = samples.iter().fold((0.0f64, 0usize), |(s, n), x| {
        (
            s + x.frames.iter().map(|v| f64::from(*v).powi(2)).sum::<f64>(),
            n + x.frames.len(),
        )
    });
    let rms = (sum2 / count.max(1) as f64).sqrt();
    let scale = if rms > 0.0 { (1.0 / rms) as f32 } else { 1.0 };
    let mut net = Net::new(frames, rows, cols, classes, scale, seed);
    let inputs: Vec<Vec<f32>> = samples.par_iter().map(|s| net.input_of(s)).collect();
    let n = net.params.len();
    let (mut m, mut v) = (vec![0.0f32; n], vec![0.0f32; n]);
    let mut rng = Rng::new(seed ^ 0xba7c_4e55);
    let mut order: Vec<usize> = (0..samples.len()).collect();
    let mut step = 0i32;
    for epoch in 1..=epochs {
        rng.shuffle(&mut order);
        let mut total = 0.0f64;
        for batch in order.chunks(BATCH) {
            if control.cancel.load(Ordering::Relaxed) {
                return Err(SelectError::Cancelled);
            }
            let grads: Vec<(f32, Vec<f32>)> = batch
                .par_iter()
                .map(|&i| net.backward(&inputs[i], &net.forward(&inputs[i]), labels[i]))
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
            epoch,
            epochs,
            loss: total / samples.len().max(1) as f64,
        });
    }
    Ok(net)
}

#[cfg(test)]
mod tests;
