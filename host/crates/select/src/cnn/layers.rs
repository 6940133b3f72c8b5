//! The network's layers on whole channels, forward and backward.
//!
//! A tensor is `[channels, frames, rows, cols]`, packed. A convolution here never
//! mixes channels' storage: output position `p` of a channel is the sum over taps of
//! a weight times the input at `p + tap`, so it is computed for every position below a
//! span at once, as long multiply-adds of shifted copies of the whole input channel
//! (loops of thousands of floats the compiler turns into SIMD). A (1, 2, 2) filter
//! has taps `0, 1, cols, cols + 1`; a (k, 1, 1) filter `0, rows * cols, ...`.
//! Positions at or past the span, and for (1, 2, 2) those in a frame's last row or
//! column, hold values nothing reads.

use std::cell::RefCell;

use serde::{Deserialize, Serialize};

thread_local! {
    /// Buffers this thread has finished with, for the next sample: a layer's output is
    /// megabytes, and a fresh allocation of that size is a fresh mapping whose every
    /// page the kernel faults in and clears (a quarter of the training time before).
    static SPARE: RefCell<Vec<Vec<f32>>> = const { RefCell::new(Vec::new()) };
}

/// `len` zeros, in a buffer this thread used before when it has one.
pub(super) fn zeros(len: usize) -> Vec<f32> {
    match SPARE.with(|s| s.borrow_mut().pop()) {
        Some(mut v) => {
            v.clear();
            v.resize(len, 0.0);
            v
        }
        None => vec![0.0; len],
    }
}

/// Gives `v` back for [`zeros`] to hand out again (a few per thread at most).
pub(super) fn recycle(v: Vec<f32>) {
    SPARE.with(|s| {
        let mut s = s.borrow_mut();
        if s.len() < 16 {
            s.push(v);
        }
    });
}

/// Sizes of a tensor `[channels, frames, rows, cols]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub(super) struct Dims {
    pub c: usize,
    pub t: usize,
    pub h: usize,
    pub w: usize,
}

impl Dims {
    pub fn len(self) -> usize {
        self.c * self.t * self.h * self.w
    }
    /// Floats of one channel.
    pub fn plane(self) -> usize {
        self.t * self.h * self.w
    }
    /// After (2, 2, 2) pooling (floor, as Keras's "valid") of the (1, 2, 2)
    /// convolution with `c` filters stored over `self`, whose last row and column are
    /// not outputs.
    pub fn conv_pool(self, c: usize) -> Dims {
        Dims {
            c,
            t: self.t / 2,
            h: self.h.saturating_sub(1) / 2,
            w: self.w.saturating_sub(1) / 2,
        }
    }
    /// The taps of a (1, 2, 2) filter over this storage, in weight order `(dy, dx)`.
    pub fn taps_122(self) -> [usize; 4] {
        [0, 1, self.w, self.w + 1]
    }
    /// Positions of a channel whose (1, 2, 2) window lies inside its storage.
    pub fn span_122(self) -> usize {
        self.plane().saturating_sub(self.w + 1)
    }
    /// The taps of a (k, 1, 1) filter over this storage.
    pub fn taps_k11(self, k: usize) -> Vec<usize> {
        (0..k).map(|dt| dt * self.h * self.w).collect()
    }
    /// Positions of a channel whose (k, 1, 1) window lies inside its storage: every
    /// frame that starts a full window, all its cells ("valid").
    pub fn span_k11(self, k: usize) -> usize {
        (self.t + 1).saturating_sub(k) * self.h * self.w
    }
}

/// Sum of `a[i] * b[i]` in eight lanes (a float sum in one lane cannot be vectorised:
/// its order is fixed), the lanes added last: the same order every run.
pub(super) fn dot(a: &[f32], b: &[f32]) -> f32 {
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

/// Sum of `a` in eight lanes, in the same order every run (as [`dot`]).
pub(super) fn sum(a: &[f32]) -> f32 {
    let mut lanes = [0.0f32; 8];
    let ca = a.chunks_exact(8);
    let tail: f32 = ca.remainder().iter().sum();
    for x in ca {
        for l in 0..8 {
            lanes[l] += x[l];
        }
    }
    lanes.iter().sum::<f32>() + tail
}

/// A convolution of `x` (`d.c` channels of `d.plane()`) by `w` `[cout][cin][taps]`
/// plus `b`, then ReLU: `cout` channels of `d.plane()`, computed below `span`.
pub(super) fn conv_fwd(
    x: &[f32],
    d: Dims,
    taps: &[usize],
    span: usize,
    w: &[f32],
    b: &[f32],
    cout: usize,
) -> Vec<f32> {
    let (n, m, k) = (d.plane(), span, taps.len());
    let mut y = zeros(cout * n);
    for (co, yc) in y.chunks_exact_mut(n).enumerate() {
        let yc = &mut yc[..m];
        yc.iter_mut().for_each(|v| *v = b[co]);
        for (ci, xc) in x.chunks_exact(n).enumerate() {
            for (j, &off) in taps.iter().enumerate() {
                let wk = w[(co * d.c + ci) * k + j];
                for (v, s) in yc.iter_mut().zip(&xc[off..off + m]) {
                    *v += wk * s;
                }
            }
        }
        yc.iter_mut().for_each(|v| *v = v.max(0.0));
    }
    y
}

/// What a convolution's backward pass reads: its input, shape, taps, span, weights.
pub(super) struct Conv<'a> {
    pub x: &'a [f32],
    pub d: Dims,
    pub taps: &'a [usize],
    pub span: usize,
    pub w: &'a [f32],
}

/// Gradients of [`conv_fwd`]: `gy` (already through the ReLU, zero where nothing was
/// an output) into `gw`, `gb` and, when asked, the input's gradient.
pub(super) fn conv_bwd(
    c: &Conv,
    gy: &[f32],
    gw: &mut [f32],
    gb: &mut [f32],
    mut gx: Option<&mut [f32]>,
) {
    let (n, m, k) = (c.d.plane(), c.span, c.taps.len());
    for (co, gc) in gy.chunks_exact(n).enumerate() {
        let gc = &gc[..m];
        gb[co] += gc.iter().sum::<f32>();
        for (ci, xc) in c.x.chunks_exact(n).enumerate() {
            for (j, &off) in c.taps.iter().enumerate() {
                let widx = (co * c.d.c + ci) * k + j;
                gw[widx] += dot(gc, &xc[off..off + m]);
                if let Some(gx) = gx.as_deref_mut() {
                    let wk = c.w[widx];
                    for (v, a) in gx[ci * n + off..][..m].iter_mut().zip(gc) {
                        *v += wk * a;
                    }
                }
            }
        }
    }
}

/// (2, 2, 2) max pooling of the (1, 2, 2) convolution stored in `x` (`d`); the packed
/// output and the index in `x` of each maximum.
pub(super) fn pool_fwd(x: &[f32], d: Dims) -> (Vec<f32>, Vec<u32>) {
    let o = d.conv_pool(d.c);
    let mut y = zeros(o.len());
    let mut arg = vec![0u32; o.len()];
    const CUBE: [(usize, usize, usize); 8] = [
        (0, 0, 0),
        (0, 0, 1),
        (0, 1, 0),
        (0, 1, 1),
        (1, 0, 0),
        (1, 0, 1),
        (1, 1, 0),
        (1, 1, 1),
    ];
    for c in 0..o.c {
        for t in 0..o.t {
            for i in 0..o.h {
                for j in 0..o.w {
                    let (mut best, mut at) = (f32::NEG_INFINITY, 0usize);
                    for (dt, di, dj) in CUBE {
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

/// The gradient through a max pooling (to each maximum) and the ReLU before it (where
/// it passed): `gp` of the pooled values into the gradient of `a`'s storage.
pub(super) fn pool_bwd(gp: &[f32], arg: &[u32], a: &[f32]) -> Vec<f32> {
    let mut ga = zeros(a.len());
    for (gv, &at) in gp.iter().zip(arg) {
        if a[at as usize] > 0.0 {
            ga[at as usize] += gv;
        }
    }
    ga
}

/// Global average and max pooling of each channel of `x` (channels of `plane` floats,
/// outputs below `span`): the channels' means, then their maxima, and where each
/// maximum is.
pub(super) fn global_fwd(x: &[f32], plane: usize, span: usize) -> (Vec<f32>, Vec<u32>) {
    let chans = x.len() / plane.max(1);
    let mut y = vec![0.0f32; 2 * chans];
    let mut arg = vec![0u32; chans];
    for (c, xc) in x.chunks_exact(plane).enumerate() {
        let xc = &xc[..span];
        y[c] = sum(xc) / span as f32;
        let (mut best, mut at) = (f32::NEG_INFINITY, 0usize);
        for (i, &v) in xc.iter().enumerate() {
            if v > best {
                best = v;
                at = i;
            }
        }
        y[chans + c] = best;
        arg[c] = (c * plane + at) as u32;
    }
    (y, arg)
}

/// The gradient through [`global_fwd`] and the ReLU before it: `gy` of the means and
/// maxima into the gradient of `a`'s storage.
pub(super) fn global_bwd(
    gy: &[f32],
    arg: &[u32],
    a: &[f32],
    plane: usize,
    span: usize,
) -> Vec<f32> {
    let chans = arg.len();
    let mut ga = zeros(a.len());
    for c in 0..chans {
        let share = gy[c] / span as f32;
        let base = c * plane;
        for (g, &v) in ga[base..base + span].iter_mut().zip(&a[base..base + span]) {
            if v > 0.0 {
                *g = share;
            }
        }
        let at = arg[c] as usize;
        if a[at] > 0.0 {
            ga[at] += gy[chans + c];
        }
    }
    ga
}
