//! Step 3's silence padding: how many frames go before and after a recording, and
//! the stretch of 1 kHz output between.

use sci_rs::signal::filter::design::Sos;

use super::filter::{design_lowpass, settle_frames};
use super::pchip::resampled_len;
use super::{ConditionError, OUTPUT_RATE_HZ};
use touchc_model::config::{RingOut, SignalConfig};

/// Silence before the recording under [`RingOut::Seconds`] with the causal filter, s:
/// the paper's one frame at 20 Hz.
const LEAD_S: f64 = 0.05;

/// Where the stimulus starts and ends around a recording of `frames` frames: the
/// silence padded before (`pad`) and after it (`tail`), in frames, and the 1 kHz body
/// between: `body` samples from position `start` (in frames of the padded signal).
pub(super) struct Span {
    pub(super) pad: usize,
    pub(super) tail: usize,
    pub(super) start: f64,
    pub(super) body: usize,
}

impl Span {
    pub(super) fn new(
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
                let at_output = design_lowpass(cfg.lowpass_order, cfg.lowpass_hz, OUTPUT_RATE_HZ)?;
                let settle_ticks = settle_frames(&at_output);
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
