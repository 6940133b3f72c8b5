//! Stage 6: conditioning, from per-actuator pressures (psi, frame rate) to the currents
//! the sleeve should output (amperes, 1 kHz). docs/algorithm.md section 6 is the contract.
//!
//! The steps, in order:
//!
//! 1. **Below-tare pressure is silence.** Negative samples (tare residue) become 0 psi:
//!    the coil renders pressure by pressing out from its rest, and "less than no touch"
//!    has no rendering; it would also make the filter ring above silence.
//! 2. **Spike removal** (`remove_spikes`), jointly over all channels.
//! 3. **Silence padding.** Frames of silence (0 psi) go after the recording, as many
//!    as the low-pass takes to settle (its impulse response falls below 1e-6 of its
//!    peak), so the filter rings out inside the stimulus instead of being cut off; as
//!    many go before it for the zero-phase pass, and one for the causal filter (from
//!    zero state, more silence in front would only come out as more silence). Zero padding (not scipy's odd extension) is the truth here: before and
//!    after the recording nothing touches the arm. With [`RingOut::Seconds`] the
//!    ring-out and the lead are times, not frames (the settling time of the filter at
//!    the 1 kHz output rate; 50 ms before, the paper's one frame at 20 Hz): the padding
//!    covers them and the 1 kHz signal starts and ends at those instants, so the same
//!    touch lasts as long at any frame rate.
//! 4. **Low-pass** (`design_lowpass`, [`lowpass`]): 5th-order 4 Hz Butterworth at the
//!    frame rate, as second-order sections, causal from zero state (the paper) or
//!    forward-backward (`zero_phase`).
//! 5. **Joint normalisation** to `[pre_dent, peak]`: `a = pre + (peak - pre) * clamp(p / P, 0, 1)`
//!    with `P` the largest filtered pressure over all channels. Silence (0 psi) is exactly
//!    the pre-dent; the filter's undershoot below silence is clamped to the pre-dent; the
//!    strongest filtered pressure of the scene (overshoot included, as in the published
//!    code, which normalises after filtering) is exactly `peak`. A scene without any
//!    positive pressure is all pre-dent, never a division by zero.
//! 6. **1 kHz reconstruction** by monotone piecewise-cubic Hermite interpolation
//!    (PCHIP, Fritsch-Carlson with harmonic-mean slopes) of the frame-rate currents.
//! 7. **Ramps**: raised-cosine ramps from 0 A to the first sample and from the last
//!    sample back to 0 A, `ramp_s` long each.
//!
//! Why filter at the frame rate and then interpolate, rather than upsample and filter at
//! 1 kHz: the contract (and the paper) specifies the Butterworth at the 20 Hz frame rate,
//! whose bilinear design has its own warped response; a 1 kHz design would be a different
//! filter. Why PCHIP rather than the published linear interpolation: linear interpolation
//! of 20 Hz frames puts a slope break every 50 ms, i.e. a 20 Hz harmonic series, and 20-40 Hz
//! is where the skin feels flutter; PCHIP is C1 (no slope breaks). Why not a band-limited
//! (sinc) or ordinary cubic spline: those overshoot between samples (most visibly where
//! the clamp at the pre-dent leaves a corner), which would push the output outside
//! `[pre_dent, peak]`. PCHIP never leaves the range of its two neighbouring samples, so the
//! 1 kHz signal keeps exactly the normalised range, and its slope is at most three times
//! the steepest frame-to-frame step.

use rayon::prelude::*;
use sci_rs::signal::filter::design::{
    butter_dyn, DigitalFilter, FilterBandType, FilterOutputType, Sos,
};
use sci_rs::signal::filter::sosfilt_dyn;
use thiserror::Error;

use crate::signals::CHANNELS;
use touchc_model::config::{RingOut, SignalConfig};

/// Update rate of the sleeve's outputs, Hz (docs/hardware.md): the rate of
/// [`Conditioned::output`] and the time step of [`check_limits`].
pub const OUTPUT_RATE_HZ: f64 = touch_protocol::stimulus::OUTPUT_RATE_HZ as f64;

/// Highest Butterworth order accepted; far beyond anything a 20 Hz touch signal needs,
/// and a bound that keeps the design numerically tame.
const MAX_ORDER: usize = 16;

/// Longest accepted ramp, s.
const MAX_RAMP_S: f64 = 60.0;

/// Silence before the recording under [`RingOut::Seconds`] with the causal filter, s:
/// the paper's one frame at 20 Hz.
const LEAD_S: f64 = 0.05;

/// The impulse response counts as settled below this share of its peak.
const SETTLE_TOLERANCE: f64 = 1e-6;

/// Why conditioning refused its input; the variant names the parameter or sample at fault.
#[derive(Debug, Error, Clone, PartialEq)]
#[non_exhaustive]
pub enum ConditionError {
    /// The low-pass cannot be designed: order outside 1..=16, or a cut-off not strictly
    /// between 0 and the Nyquist frequency.
    #[error(
        "low-pass order {order} at {cutoff_hz} Hz is not realisable at {rate_hz} Hz \
         (order 1..=16, 0 < cut-off < rate / 2)"
    )]
    InvalidFilter {
        /// Requested order.
        order: usize,
        /// Requested cut-off, Hz.
        cutoff_hz: f64,
        /// Sampling rate, Hz.
        rate_hz: f64,
    },
    /// A scalar parameter is out of its domain (negative, NaN or infinite).
    #[error("signal parameter `{name}` = {} is out of range", touchc_model::display::Shortest(*.value))]
    InvalidParameter {
        /// Config field name.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// `pre_dent_a` must lie strictly below `peak_a`, both finite.
    #[error("pre-dent {pre_dent_a} A must be below the peak {peak_a} A")]
    InvalidRange {
        /// Resting current, A.
        pre_dent_a: f64,
        /// Peak current, A.
        peak_a: f64,
    },
    /// Channels must all have the same number of frames.
    #[error("channel {channel} has {len} frames, channel 0 has {expected}")]
    LengthMismatch {
        /// Offending channel.
        channel: usize,
        /// Its length.
        len: usize,
        /// Length of channel 0.
        expected: usize,
    },
    /// A pressure sample is NaN or infinite.
    #[error("pressure at channel {channel}, frame {frame} is not finite")]
    NotFinite {
        /// Channel of the sample.
        channel: usize,
        /// Frame of the sample.
        frame: usize,
    },
}

/// The conditioned stimulus: the frame-rate currents (what keyframes are cut from) and
/// the 1 kHz reference the device should output.
#[derive(Debug, Clone, PartialEq)]
pub struct Conditioned {
    /// Rate of `frames_a`, Hz (the recording's frame rate).
    pub frame_rate_hz: f64,
    /// Silent frames added before the recording: room for the backward pass of the
    /// zero-phase filter, one frame for the causal one; `frames_a[pad + t]` is
    /// recording frame `t`.
    pub pad_frames: usize,
    /// Silent frames added after the recording for the filter to ring out.
    pub tail_frames: usize,
    /// Position of `output`'s first sample after the ramp, in frames of `frames_a`: 0
    /// under [`RingOut::Frames`]; under [`RingOut::Seconds`] the instant the lead starts
    /// (`pad_frames - lead * rate`), between frames.
    pub start_frame: f64,
    /// Currents at the frame rate, amperes, after normalisation, before the ramps:
    /// `pad_frames + T + tail_frames` entries.
    pub frames_a: Vec<[f64; CHANNELS]>,
    /// Filtered pressure that maps to `peak_a`, psi (0 for a scene without pressure).
    pub full_scale_psi: f64,
    /// Samples in each ramp at the start and end of `output`.
    pub ramp_samples: usize,
    /// The 1 kHz reference, amperes: the ramp up, the PCHIP reconstruction of
    /// `frames_a` (its first sample is `frames_a[0]`), the ramp down. Starts and ends at 0 A.
    pub output: Vec<[f64; CHANNELS]>,
}

impl Conditioned {
    /// Index into `output` of the sample at frame-rate frame `k` of `frames_a` (rounded
    /// down when the rates are not multiples), so plots and keyframes line up.
    #[cfg(test)]
    pub(crate) fn output_index_of_frame(&self, k: usize) -> usize {
        let from_start = (k as f64 - self.start_frame).max(0.0);
        self.ramp_samples + (from_start * OUTPUT_RATE_HZ / self.frame_rate_hz).floor() as usize
    }
}

/// Designs the Butterworth low-pass as second-order sections (scipy's
/// `butter(order, cutoff_hz, fs=rate_hz, output='sos')`, via sci-rs).
///
/// SOS only: at 1 kHz the 4 Hz poles sit so close to z = 1 that the single (b, a)
/// polynomial loses them to rounding (in f32 a pole lands outside the unit circle).
pub(crate) fn design_lowpass(
    order: usize,
    cutoff_hz: f64,
    rate_hz: f64,
) -> Result<Vec<Sos<f64>>, ConditionError> {
    let invalid = ConditionError::InvalidFilter {
        order,
        cutoff_hz,
        rate_hz,
    };
    let realisable = (1..=MAX_ORDER).contains(&order)
        && rate_hz.is_finite()
        && rate_hz > 0.0
        && cutoff_hz > 0.0
        && cutoff_hz < rate_hz / 2.0;
    if !realisable {
        return Err(invalid);
    }
    let filter = butter_dyn(
        order,
        vec![cutoff_hz],
        Some(FilterBandType::Lowpass),
        Some(false),
        Some(FilterOutputType::Sos),
        Some(rate_hz),
    );
    match filter {
        DigitalFilter::Sos(sos) => Ok(sos
            .sos
            .iter()
            // Fresh sections with zero state: the design's state fields are not ours.
            .map(|s| Sos::new(s.b, s.a))
            .collect()),
        _ => Err(invalid),
    }
}

/// Runs the sections over `x` from zero state; `zero_phase` adds a second pass over the
/// time-reversed output (also from zero state), which squares the magnitude response and
/// cancels the phase. Zero state, not scipy's `sosfiltfilt` edge handling: callers pad
/// with the true signal outside `x` (silence) instead of an odd reflection.
pub fn lowpass(x: &[f64], sos: &[Sos<f64>], zero_phase: bool) -> Vec<f64> {
    let run = |input: &mut dyn Iterator<Item = f64>| -> Vec<f64> {
        let mut sections: Vec<Sos<f64>> = sos.iter().map(|s| Sos::new(s.b, s.a)).collect();
        sosfilt_dyn(input, &mut sections)
    };
    let forward = run(&mut x.iter().copied());
    if !zero_phase {
        return forward;
    }
    let mut backward = run(&mut forward.iter().rev().copied());
    backward.reverse();
    backward
}

/// Frames after which the impulse response of `sos` stays below [`SETTLE_TOLERANCE`] of
/// its peak (at least 1): the silence padded around a recording.
///
/// The response is filtered in blocks, and the filtering stops once every section's
/// state is below [`QUIET`] of the peak: with no input left, the later response is the
/// state carried through a stable filter, which cannot grow it by the 1e144 it would
/// take to reach the tolerance again. Filtering on to the horizon only made numbers
/// too small to matter, and subnormal ones, about a hundred times slower each (most of
/// a short compile's conditioning time).
fn settle_frames(sos: &[Sos<f64>]) -> usize {
    const HORIZON: usize = 1 << 16;
    const BLOCK: usize = 1 << 10;
    let mut sections: Vec<Sos<f64>> = sos.iter().map(|s| Sos::new(s.b, s.a)).collect();
    let mut h: Vec<f64> = Vec::new();
    let mut peak = 0.0_f64;
    for start in (0..HORIZON).step_by(BLOCK) {
        let impulse = (start..start + BLOCK).map(|i| if i == 0 { 1.0 } else { 0.0 });
        // Sections keep their state between calls: one run over the blocks in turn.
        let block = sosfilt_dyn(impulse, &mut sections);
        peak = block.iter().fold(peak, |m, v| m.max(v.abs()));
        h.extend(block);
        let state = sections
            .iter()
            .fold(0.0_f64, |m, s| m.max(s.zi0.abs()).max(s.zi1.abs()));
        if peak > 0.0 && state <= QUIET * peak {
            break;
        }
    }
    let last = h
        .iter()
        .rposition(|v| v.abs() > SETTLE_TOLERANCE * peak)
        .unwrap_or(0);
    last + 1
}

/// Filter state, as a share of the impulse response's peak, below which
/// [`settle_frames`] knows the response has settled for good (see there).
const QUIET: f64 = 1e-150;

/// Spike removal, in place, jointly over all channels.
///
/// The **total pressure range** is `max - min` over every sample of every channel (the
/// published `cutoffTops` uses the same joint range). A sample `x[i]` (not the first or
/// last of its channel) is a spike when it is a strict local maximum that *both* rises
/// from `x[i-1]` and drops to `x[i+1]` by more than `fraction * range`; then
/// `x[i-1], x[i], x[i+1]` all become `(x[i-1] + x[i+1]) / 2`. Channels are scanned from
/// the start, in place, as in the published code.
///
/// Differences from the published code, on purpose: it runs after the low-pass there,
/// where a 4 Hz signal can hardly jump 1/8 of its range between frames, so a glitch has
/// already been smeared into a ringing bump; here it runs before. And the published test
/// takes the larger of rise and drop, which before the filter would also flatten the
/// first frame of every sharp onset that then eases off a little (0, 1, 0.95); the
/// contract says "rises and then drops", so both must exceed the threshold.
pub(crate) fn remove_spikes(channels: &mut [Vec<f64>; CHANNELS], fraction: f64) {
    let (lo, hi) = channels
        .iter()
        .flatten()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    let range = hi - lo;
    if !(range > 0.0 && range.is_finite()) {
        return;
    }
    let threshold = fraction * range;
    for x in channels.iter_mut() {
        for i in 1..x.len().saturating_sub(1) {
            let (before, here, after) = (x[i - 1], x[i], x[i + 1]);
            if here - before > threshold && here - after > threshold {
                let mean = 0.5 * (before + after);
                x[i - 1] = mean;
                x[i] = mean;
                x[i + 1] = mean;
            }
        }
    }
}

/// Monotone cubic Hermite interpolant (PCHIP) through samples at unit spacing.
///
/// Slopes: harmonic mean of the neighbouring secants where they agree in sign, 0 at
/// local extrema and flat spots, the secant at both ends. These satisfy the
/// Fritsch-Carlson conditions, so every piece stays within its two samples; evaluation
/// also clamps to that interval so rounding cannot step outside it by an ulp.
struct Pchip<'a> {
    y: &'a [f64],
    secant: Vec<f64>,
    slope: Vec<f64>,
}

impl<'a> Pchip<'a> {
    /// Needs at least two samples.
    fn new(y: &'a [f64]) -> Option<Self> {
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
    fn eval(&self, u: f64) -> f64 {
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
fn hermite(u: f64, n: usize) -> (usize, (f64, f64, f64)) {
    let k = (u.max(0.0).floor() as usize).min(n - 2);
    let s = u - k as f64;
    let (s2, s3) = (s * s, s * s * s);
    (k, (3.0 * s2 - 2.0 * s3, s3 - 2.0 * s2 + s, s3 - s2))
}

/// The value of every channel's [`Pchip`] at `u`: the curves share their samples'
/// positions, so the piece and its weights are found once for all eight.
fn eval_channels(curves: &[Pchip; CHANNELS], u: f64) -> [f64; CHANNELS] {
    let (k, h) = hermite(u, curves[0].y.len());
    std::array::from_fn(|ch| curves[ch].piece(k, h))
}

/// Number of `out_hz` samples from the first to the last of `n` samples at `rate_hz`.
fn resampled_len(n: usize, rate_hz: f64, out_hz: f64) -> usize {
    match n {
        0 => 0,
        _ => ((n - 1) as f64 * out_hz / rate_hz + 1e-9).floor() as usize + 1,
    }
}

/// Position, in input samples, of output sample `j`. Multiplying before dividing keeps
/// it exact where the rates are multiples (j = 50 k lands exactly on frame k at 20 Hz),
/// so the 1 kHz signal passes through the frame-rate samples bit for bit.
fn resampled_position(j: usize, rate_hz: f64, out_hz: f64) -> f64 {
    j as f64 * rate_hz / out_hz
}

/// Checks the config fields conditioning reads, so that later arithmetic cannot see a
/// NaN or an impossible range.
fn validate(cfg: &SignalConfig, frame_rate_hz: f64) -> Result<(), ConditionError> {
    let param = |name, value: f64, ok: bool| {
        if ok && value.is_finite() {
            Ok(())
        } else {
            Err(ConditionError::InvalidParameter { name, value })
        }
    };
    // Bounds that keep the 1 kHz output a sane size: a frame rate of at least 1 Hz (at
    // most 1,000 output samples per frame) and not above the output rate, ramps of at
    // most a minute.
    let rate_ok = (1.0..=OUTPUT_RATE_HZ).contains(&frame_rate_hz);
    param("frame_rate_hz", frame_rate_hz, rate_ok)?;
    param(
        "spike_fraction",
        cfg.spike_fraction,
        cfg.spike_fraction >= 0.0,
    )?;
    param(
        "ramp_s",
        cfg.ramp_s,
        (0.0..=MAX_RAMP_S).contains(&cfg.ramp_s),
    )?;
    let range_ok =
        cfg.pre_dent_a.is_finite() && cfg.peak_a.is_finite() && cfg.pre_dent_a < cfg.peak_a;
    if !range_ok {
        return Err(ConditionError::InvalidRange {
            pre_dent_a: cfg.pre_dent_a,
            peak_a: cfg.peak_a,
        });
    }
    Ok(())
}

/// Stage 6: turns per-actuator pressures (psi, one `Vec` per channel, at `frame_rate_hz`)
/// into the currents the sleeve should output; the steps and their reasons are in the
/// module documentation. A scene with no pressure at all is a valid, silent stimulus:
/// ramp to the pre-dent, hold, ramp back.
///
/// `frame_rate_hz` must lie in `[1, 1000]` and `ramp_s` in `[0, 60]` s (bounds that keep
/// the 1 kHz output a sane size); other config errors are typed, never panics. Call it as
/// `condition(&signals.psi, &config.signal, config.input.frame_rate_hz)`.
///
/// ```
/// use touchc_rendering::condition::condition;
/// use touchc_model::config::SignalConfig;
///
/// // One second of silence on all eight channels at 20 Hz.
/// let psi: [Vec<f64>; 8] = std::array::from_fn(|_| vec![0.0; 20]);
/// let c = condition(&psi, &SignalConfig::default(), 20.0)?;
/// assert_eq!(c.ramp_samples, 500); // 0.5 s at 1 kHz
/// assert_eq!(c.output[0], [0.0; 8]); // starts at rest...
/// assert_eq!(c.output[c.output.len() - 1], [0.0; 8]); // ...and ends there
/// assert_eq!(c.output[c.output.len() / 2], [-0.9; 8]); // silence is the pre-dent
/// assert_eq!(c.output.len(), 2 * 500 + (c.frames_a.len() - 1) * 50 + 1);
/// # Ok::<(), touchc_rendering::condition::ConditionError>(())
/// ```
pub fn condition(
    psi: &[Vec<f64>; CHANNELS],
    cfg: &SignalConfig,
    frame_rate_hz: f64,
) -> Result<Conditioned, ConditionError> {
    validate(cfg, frame_rate_hz)?;
    let sos = design_lowpass(cfg.lowpass_order, cfg.lowpass_hz, frame_rate_hz)?;
    let frames = psi[0].len();
    for (channel, x) in psi.iter().enumerate() {
        if x.len() != frames {
            return Err(ConditionError::LengthMismatch {
                channel,
                len: x.len(),
                expected: frames,
            });
        }
        if let Some(frame) = x.iter().position(|v| !v.is_finite()) {
            return Err(ConditionError::NotFinite { channel, frame });
        }
    }

    // 1-2. Silence below tare, spikes.
    let mut work: [Vec<f64>; CHANNELS] =
        std::array::from_fn(|ch| psi[ch].iter().map(|&v| v.max(0.0)).collect());
    remove_spikes(&mut work, cfg.spike_fraction);

    // Work in units of the strongest input sample so the filter never sees values near
    // the ends of the f64 range (1e300 psi would overflow inside the sections); the
    // normalisation below divides this scale out again.
    let input_max = work.iter().flatten().fold(0.0_f64, |m, &v| m.max(v));
    let unit = if input_max > 0.0 { input_max } else { 1.0 };

    // 3-4. Pad with silence, filter. The causal filter starts from zero state, so
    // silence before the recording would come out as exact silence: one frame of it
    // (or 50 ms) is enough, and the stimulus does not make the wearer wait for nothing.
    let span = Span::new(cfg, &sos, frame_rate_hz, frames)?;
    let (pad, tail) = (span.pad, span.tail);
    let filtered: Vec<Vec<f64>> = work
        .iter()
        .map(|x| {
            let mut padded = vec![0.0; pad + frames + tail];
            for (p, &v) in padded[pad..pad + frames].iter_mut().zip(x) {
                *p = v / unit;
            }
            lowpass(&padded, &sos, cfg.zero_phase)
        })
        .collect();
    // What the 1 kHz signal is built beside is its peak of memory (an hour's is 230 MB):
    // each 20 Hz copy goes as soon as it is used (4.6 MB apiece at an hour).
    drop(work);

    // 5. Joint normalisation.
    let top = filtered.iter().flatten().fold(0.0_f64, |m, &v| m.max(v));
    let len = pad + frames + tail;
    let frames_a: Vec<[f64; CHANNELS]> = (0..len)
        .map(|t| {
            std::array::from_fn(|ch| {
                let u = if top > 0.0 {
                    (filtered[ch][t] / top).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                // This form hits both ends exactly (pre + span * 1 = 0.9999999999999999).
                cfg.pre_dent_a * (1.0 - u) + cfg.peak_a * u
            })
        })
        .collect();
    drop(filtered);

    // 6-7. 1 kHz reconstruction framed by the ramps. `len >= 2` (pad >= 1), so every
    // channel has an interpolant; the fallback only keeps this free of panics.
    let columns: Vec<Vec<f64>> = (0..CHANNELS)
        .map(|ch| frames_a.iter().map(|f| f[ch]).collect())
        .collect();
    let curves: Vec<Pchip> = columns.iter().filter_map(|y| Pchip::new(y)).collect();
    let Ok(curves) = <[Pchip; CHANNELS]>::try_from(curves) else {
        return Err(ConditionError::InvalidParameter {
            name: "frames",
            value: len as f64,
        });
    };
    let ramp = (cfg.ramp_s * OUTPUT_RATE_HZ).round() as usize;
    let body = span.body;
    let start = span.start;
    let at = |j: usize| -> [f64; CHANNELS] {
        let u = start + resampled_position(j, frame_rate_hz, OUTPUT_RATE_HZ);
        eval_channels(&curves, u)
    };
    let (first, last) = (at(0), at(body.saturating_sub(1)));
    let mut output = Vec::with_capacity(ramp + body + ramp);
    output.extend((0..ramp).map(|j| first.map(|v| v * raised_cosine(j, ramp))));
    // Each sample on its own (an hour is 3.6 M of them, 230 MB), so on every core,
    // written once, straight into the reserved memory (zeroing it first on one thread
    // cost more than the samples).
    output.par_extend((0..body).into_par_iter().map(at));
    output.extend((1..=ramp).map(|j| last.map(|v| v * raised_cosine(ramp - j, ramp))));

    Ok(Conditioned {
        frame_rate_hz,
        pad_frames: pad,
        tail_frames: tail,
        start_frame: start,
        frames_a,
        full_scale_psi: top * unit,
        ramp_samples: ramp,
        output,
    })
}

/// Where the stimulus starts and ends around a recording of `frames` frames: the
/// silence padded before (`pad`) and after it (`tail`), in frames, and the 1 kHz body
/// between: `body` samples from position `start` (in frames of the padded signal).
struct Span {
    pad: usize,
    tail: usize,
    start: f64,
    body: usize,
}

impl Span {
    fn new(
        cfg: &SignalConfig,
        sos: &[Sos<f64>],
        rate_hz: f64,
        frames: usize,
    ) -> Result<Span, ConditionError> {
        match cfg.ring_out {
            RingOut::Frames => {
                let tail = settle_frames(sos);
                let pad = if cfg.zero_phase { tail } else { 1 };
                Ok(Span {
                    pad,
                    tail,
                    start: 0.0,
                    body: resampled_len(pad + frames + tail, rate_hz, OUTPUT_RATE_HZ),
                })
            }
            RingOut::Seconds => {
                // At 1 kHz the bilinear design is the analog filter to within its
                // warping of 4 Hz at 1 kHz (0.05 %): a time that is the filter's own.
                // The settling time is the filter's alone, and at 1 kHz finding it walks
                // tens of thousands of ticks (most of a short compile's conditioning):
                // found once per filter in a process.
                static SETTLE_TICKS: std::sync::Mutex<Vec<((usize, u64), usize)>> =
                    std::sync::Mutex::new(Vec::new());
                let key = (cfg.lowpass_order, cfg.lowpass_hz.to_bits());
                let known = SETTLE_TICKS
                    .lock()
                    .ok()
                    .and_then(|k| k.iter().find(|(f, _)| *f == key).map(|&(_, t)| t));
                let settle_ticks = match known {
                    Some(t) => t,
                    None => {
                        let at_output =
                            design_lowpass(cfg.lowpass_order, cfg.lowpass_hz, OUTPUT_RATE_HZ)?;
                        let t = settle_frames(&at_output);
                        if let Ok(mut k) = SETTLE_TICKS.lock() {
                            k.push((key, t));
                        }
                        t
                    }
                };
                let settle_s = settle_ticks as f64 / OUTPUT_RATE_HZ;
                let lead_s = if cfg.zero_phase { settle_s } else { LEAD_S };
                // Frames that cover a time; the tolerance keeps 1 s at 20 Hz 20 frames.
                let cover = |s: f64| (s * rate_hz - 1e-9).ceil().max(0.0) as usize;
                let pad = cover(lead_s).max(1);
                // One frame more than the ring-out, so that its end lies inside the
                // interpolated samples.
                let tail = cover(settle_s) + 1;
                let start = pad as f64 - lead_s * rate_hz;
                let lead_ticks = (lead_s * OUTPUT_RATE_HZ).round() as usize;
                // A frame stands for 1 / rate of time: T frames last T / rate (not
                // (T - 1) / rate, which would make the same touch shorter at 20 Hz).
                let recording_ticks = (frames as f64 * OUTPUT_RATE_HZ / rate_hz).round() as usize;
                Ok(Span {
                    pad,
                    tail,
                    start,
                    body: lead_ticks + recording_ticks + settle_ticks,
                })
            }
        }
    }
}

/// Weight `j / n` of the way along a raised-cosine ramp: 0 at `j = 0`, 1 at `j = n`, with
/// zero slope at both ends so neither end of the ramp is a kink.
fn raised_cosine(j: usize, n: usize) -> f64 {
    if j >= n {
        return 1.0;
    }
    0.5 * (1.0 - (std::f64::consts::PI * j as f64 / n as f64).cos())
}

mod limits;

pub use limits::{check_limits, fit, fit_to, LimitViolation, Limits};

#[cfg(test)]
mod tests;
