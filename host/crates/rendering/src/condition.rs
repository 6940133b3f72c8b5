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
//!    after the recording nothing touches the arm. With [`RingOut::Seconds`](touchc_model::config::RingOut::Seconds) the
//!    ring-out and the lead are times, not frames (the settling time of the filter at
//!    the 1 kHz output rate; 50 ms before, the paper's one frame at 20 Hz): the padding
//!    covers them and the 1 kHz signal starts and ends at those instants, so the same
//!    touch lasts as long at any frame rate.
//! 4. **Low-pass** (`design_lowpass`, `lowpass`): 5th-order 4 Hz Butterworth at the
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
use sci_rs::signal::filter::design::Sos;

use crate::signals::CHANNELS;
use filter::{design_lowpass, lowpass};
use pchip::{eval_channels, resampled_position, Pchip};
use span::Span;
use touchc_model::config::SignalConfig;

mod errors;
mod filter;
mod limits;
mod pchip;
mod span;

pub use errors::ConditionError;
pub use limits::{check_limits, fit, fit_to, LimitViolation, Limits};

/// Update rate of the sleeve's outputs, Hz (docs/hardware.md): the rate of
/// [`Conditioned::output`] and the time step of [`check_limits`].
pub const OUTPUT_RATE_HZ: f64 = touch_protocol::stimulus::OUTPUT_RATE_HZ as f64;

/// Longest accepted ramp, s.
const MAX_RAMP_S: f64 = 60.0;

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
    /// under [`RingOut::Frames`](touchc_model::config::RingOut::Frames); under [`RingOut::Seconds`](touchc_model::config::RingOut::Seconds) the instant the lead starts
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
    let frames = checked_frames(psi)?;

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
    let filtered = padded_lowpass(work, &span, frames, unit, &sos, cfg.zero_phase);

    // 5. Joint normalisation.
    let top = filtered.iter().flatten().fold(0.0_f64, |m, &v| m.max(v));
    let frames_a = normalised(filtered, top, cfg);

    // 6-7. 1 kHz reconstruction framed by the ramps.
    let ramp = (cfg.ramp_s * OUTPUT_RATE_HZ).round() as usize;
    let output = reconstructed(&frames_a, &span, frame_rate_hz, ramp)?;

    Ok(Conditioned {
        frame_rate_hz,
        pad_frames: span.pad,
        tail_frames: span.tail,
        start_frame: span.start,
        frames_a,
        full_scale_psi: top * unit,
        ramp_samples: ramp,
        output,
    })
}

/// The number of frames every channel of `psi` has, or the first channel whose length
/// differs from channel 0's or whose samples are not all finite.
fn checked_frames(psi: &[Vec<f64>; CHANNELS]) -> Result<usize, ConditionError> {
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
    Ok(frames)
}

/// Steps 3-4: each channel of `work` (`frames` long) in units of `unit`, between the
/// silence `span` pads around it, through the low-pass.
fn padded_lowpass(
    work: [Vec<f64>; CHANNELS],
    span: &Span,
    frames: usize,
    unit: f64,
    sos: &[Sos<f64>],
    zero_phase: bool,
) -> Vec<Vec<f64>> {
    let (pad, tail) = (span.pad, span.tail);
    // What the 1 kHz signal is built beside is its peak of memory (an hour's is 230 MB):
    // each 20 Hz copy goes as soon as it is used (4.6 MB apiece at an hour), `work`
    // when this returns.
    work.iter()
        .map(|x| {
            let mut padded = vec![0.0; pad + frames + tail];
            for (p, &v) in padded[pad..pad + frames].iter_mut().zip(x) {
                *p = v / unit;
            }
            lowpass(&padded, sos, zero_phase)
        })
        .collect()
}

/// Step 5: the filtered channels, frame by frame, as currents in `[pre_dent, peak]`,
/// `top` (the largest filtered value) mapping to the peak.
fn normalised(filtered: Vec<Vec<f64>>, top: f64, cfg: &SignalConfig) -> Vec<[f64; CHANNELS]> {
    let len = filtered.first().map_or(0, Vec::len);
    (0..len)
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
        .collect()
}

/// Steps 6-7: the 1 kHz signal through `frames_a` over `span`, framed by raised-cosine
/// ramps of `ramp` samples.
fn reconstructed(
    frames_a: &[[f64; CHANNELS]],
    span: &Span,
    frame_rate_hz: f64,
    ramp: usize,
) -> Result<Vec<[f64; CHANNELS]>, ConditionError> {
    // `frames_a.len() >= 2` (pad >= 1), so every channel has an interpolant; the
    // fallback only keeps this free of panics.
    let columns: Vec<Vec<f64>> = (0..CHANNELS)
        .map(|ch| frames_a.iter().map(|f| f[ch]).collect())
        .collect();
    let curves: Vec<Pchip> = columns.iter().filter_map(|y| Pchip::new(y)).collect();
    let Ok(curves) = <[Pchip; CHANNELS]>::try_from(curves) else {
        return Err(ConditionError::InvalidParameter {
            name: "frames",
            value: frames_a.len() as f64,
        });
    };
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
    Ok(output)
}

/// Weight `j / n` of the way along a raised-cosine ramp: 0 at `j = 0`, 1 at `j = n`, with
/// zero slope at both ends so neither end of the ramp is a kink.
fn raised_cosine(j: usize, n: usize) -> f64 {
    if j >= n {
        return 1.0;
    }
    0.5 * (1.0 - (std::f64::consts::PI * j as f64 / n as f64).cos())
}

#[cfg(test)]
mod tests;
