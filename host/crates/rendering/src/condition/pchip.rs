//! Step 6's 1 kHz reconstruction: the monotone cubic interpolant through the
//! frame-rate currents, and where the output samples fall between the frames.

use crate::signals::CHANNELS;

/// Monotone cubic Hermite interpolant (PCHIP) through samples at unit spacing.
///
/// Slopes: harmonic mean of the neighbouring secants where they agree in sign, 0 at
/// local extrema and flat spots, the secant at both ends. These satisfy the
/// Fritsch-Carlson conditions, so every piece stays within its two samples; evaluation
/// also clamps to that interval so rounding cannot step outside it by an ulp.
pub(super) struct Pchip<'a> {
    pub(super) y: &'a [f64],
    secant: Vec<f64>,
    slope: Vec<f64>,
}

impl<'a> Pchip<'a> {
    /// Needs at least two samples.
    pub(super) fn new(y: &'a [f64]) -> Option<Self> {
        let n = y.len();
        if n < 2 {
            return None;
        }
        let secant: Vec<f64> = y.windows(2).map(|w| w[1] - w[0]).collect();
        let mut slope = vec![0.0; n];
        slope[0] = secant[0];
        slope[n - 1] = secant[n - 2];
        for k in 1..n - 1 {
            let (a, b) = (secant[k - 1], secant[k]);
            if a * b > 0.0 {
                slope[k] = 2.0 * a * b / (a + b);
            }
        }
        Some(Self { y, secant, slope })
    }

    /// Value at position `u` (in samples from the first), `0 <= u <= n - 1` (the
    /// compile evaluates all eight channels at once: [`eval_channels`]).
    #[cfg(test)]
    pub(super) fn eval(&self, u: f64) -> f64 {
        let (k, h) = hermite(u, self.y.len());
        self.piece(k, h)
    }

    /// Value on piece `k` with the Hermite weights `h` of [`hermite`].
    #[inline(always)]
    fn piece(&self, k: usize, (h01, h10, h11): (f64, f64, f64)) -> f64 {
        let (a, b) = (self.y[k], self.y[k + 1]);
        // Written around y[k] so that a flat piece returns y[k] exactly.
        let v = a + self.secant[k] * h01 + self.slope[k] * h10 + self.slope[k + 1] * h11;
        v.clamp(a.min(b), a.max(b))
    }
}

/// The piece `k` of `n >= 2` unit-spaced samples that position `u` falls in, and the
/// cubic Hermite weights `(h01, h10, h11)` at its offset in that piece.
#[inline(always)]
pub(super) fn hermite(u: f64, n: usize) -> (usize, (f64, f64, f64)) {
    let k = (u.max(0.0).floor() as usize).min(n - 2);
    let s = u - k as f64;
    let (s2, s3) = (s * s, s * s * s);
    (k, (3.0 * s2 - 2.0 * s3, s3 - 2.0 * s2 + s, s3 - s2))
}

/// The value of every channel's [`Pchip`] at `u`: the curves share their samples'
/// positions, so the piece and its weights are found once for all eight.
pub(super) fn eval_channels(curves: &[Pchip; CHANNELS], u: f64) -> [f64; CHANNELS] {
    let (k, h) = hermite(u, curves[0].y.len());
    std::array::from_fn(|ch| curves[ch].piece(k, h))
}

/// Number of `out_hz` samples from the first to the last of `n` samples at `rate_hz`.
pub(super) fn resampled_len(n: usize, rate_hz: f64, out_hz: f64) -> usize {
    match n {
        0 => 0,
        _ => ((n - 1) as f64 * out_hz / rate_hz + 1e-9).floor() as usize + 1,
    }
}

/// Position, in input samples, of output sample `j`. Multiplying before dividing keeps
/// it exact where the rates are multiples (j = 50 k lands exactly on frame k at 20 Hz),
/// so the 1 kHz signal passes through the frame-rate samples bit for bit.
pub(super) fn resampled_position(j: usize, rate_hz: f64, out_hz: f64) -> f64 {
    j as f64 * rate_hz / out_hz
}
