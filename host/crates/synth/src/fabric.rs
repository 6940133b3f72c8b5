//! A fabric pressure grid as real captures show it (`REAL-TOUCH`-style recordings):
//! not a smooth blob per hand, but cells of uneven sensitivity that wander as the cloth
//! creases, each dropping out for a frame or two now and then, and, through fur or foam,
//! a touch spread over more cells and weakened.
//!
//! [`Fabric::apply`] works on the touch alone (before the sensor noise), in continuous
//! time: the same touch sampled at 20 and at 54 Hz sees the same cells, the same gains
//! and the same dropouts (a 20 Hz frame falls in fewer of them).

use ndarray::Array3;

use crate::contacts::Rng;

/// How a fabric sensor distorts the touch it reads ([`crate::SynthSpec::fabric`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fabric {
    /// Spread of each cell's sensitivity: a cell reads its pressure times
    /// `1 + spread x (a fixed draw in [-1, 1] + half a slow wander)` (at least a fifth),
    /// so one hand shows several local maxima that shift as it moves.
    pub gain_spread: f64,
    /// Dropouts per second of each cell: for [`DROPOUT_S`] it reads [`DROPOUT_FACTOR`]
    /// of its pressure (per-cell flicker).
    pub dropouts_hz: f64,
    /// Read through a layer (fur, foam): the touch is spread by a Gaussian of this many
    /// cells (0: bare skin on the sensor).
    pub layer_cells: f64,
    /// The share of the pressure the layer passes on (1: bare).
    pub layer_share: f64,
}

/// Shortest and longest dropout of a cell, seconds (one or two frames at 54 Hz).
pub const DROPOUT_S: (f64, f64) = (0.012, 0.04);
/// What a cell reads of its pressure during a dropout.
pub const DROPOUT_FACTOR: f64 = 0.05;
/// Slowest and fastest wander of a cell's sensitivity, Hz.
const WANDER_HZ: (f64, f64) = (0.3, 1.5);

impl Fabric {
    /// A bare fabric grid: sensitivity spread 0.8, 12 dropouts per second per cell.
    pub const BARE: Fabric = Fabric {
        gain_spread: 0.8,
        dropouts_hz: 12.0,
        layer_cells: 0.0,
        layer_share: 1.0,
    };

    /// The same grid read through fur: the touch spread over a cell and a third of it
    /// passed on, more dropouts.
    pub const FUR: Fabric = Fabric {
        gain_spread: 0.8,
        dropouts_hz: 20.0,
        layer_cells: 0.8,
        layer_share: 0.35,
    };

    /// Applies the fabric to `touch` (`[T, rows, cols]` psi, sampled at `rate_hz`),
    /// drawing from its own stream of `seed`.
    pub fn apply(&self, touch: &mut Array3<f64>, rate_hz: f64, seed: u64) {
        let (frames, rows, cols) = touch.dim();
        if self.layer_cells > 0.0 {
            for mut frame in touch.outer_iter_mut() {
                let spread = spread(&frame.to_owned(), self.layer_cells);
                frame.assign(&(spread * self.layer_share));
            }
        }
        let end_s = frames as f64 / rate_hz;
        for r in 0..rows {
            for c in 0..cols {
                // A stream per cell: how many dropouts one cell draws (which depends
                // on the recording's length in frames) never shifts another's.
                let cell = (r * 4096 + c) as u64;
                let mut rng =
                    Rng(seed ^ 0xFAB1_C0DE_5EED_0001 ^ cell.wrapping_mul(0x9E37_79B9_7F4A_7C15));
                let fixed = rng.range(-1.0, 1.0);
                let hz = rng.range(WANDER_HZ.0, WANDER_HZ.1);
                let phase = rng.range(0.0, std::f64::consts::TAU);
                let out = self.dropouts(&mut rng, end_s);
                for f in 0..frames {
                    let t = f as f64 / rate_hz;
                    let wander = 0.5 * (std::f64::consts::TAU * hz * t + phase).sin();
                    let mut gain = (1.0 + self.gain_spread * (fixed + wander)).max(0.2);
                    if out.iter().any(|&(a, b)| t >= a && t <= b) {
                        gain *= DROPOUT_FACTOR;
                    }
                    touch[[f, r, c]] *= gain;
                }
            }
        }
    }

    /// One cell's dropouts over `[0, end_s]`, as `(from, to)` seconds.
    fn dropouts(&self, rng: &mut Rng, end_s: f64) -> Vec<(f64, f64)> {
        let mut out = Vec::new();
        if self.dropouts_hz.is_nan() || self.dropouts_hz <= 0.0 {
            return out;
        }
        let mut t = 0.0;
        loop {
            t += -(1.0 - rng.uniform()).ln() / self.dropouts_hz;
            let d = rng.range(DROPOUT_S.0, DROPOUT_S.1);
            if t > end_s {
                return out;
            }
            out.push((t, t + d));
            t += d;
        }
    }
}

/// `frame` blurred by a Gaussian of `sigma` cells (zero outside), keeping its sum
/// inside the frame no larger: pressure through a layer spreads, it does not grow.
fn spread(frame: &ndarray::Array2<f64>, sigma: f64) -> ndarray::Array2<f64> {
    let (rows, cols) = frame.dim();
    let reach = (3.0 * sigma).ceil() as i64;
    let kernel: Vec<f64> = (-reach..=reach)
        .map(|d| (-0.5 * (d as f64 / sigma).powi(2)).exp())
        .collect();
    let norm: f64 = kernel.iter().sum();
    let pass = |get: &dyn Fn(i64) -> f64, n: i64, i: i64| -> f64 {
        (-reach..=reach)
            .filter(|d| (0..n).contains(&(i + d)))
            .map(|d| kernel[(d + reach) as usize] * get(i + d))
            .sum::<f64>()
            / norm
    };
    let along = ndarray::Array2::from_shape_fn((rows, cols), |(r, c)| {
        pass(&|j| frame[[r, j as usize]], cols as i64, c as i64)
    });
    ndarray::Array2::from_shape_fn((rows, cols), |(r, c)| {
        pass(&|i| along[[i as usize, c]], rows as i64, r as i64)
    })
}
