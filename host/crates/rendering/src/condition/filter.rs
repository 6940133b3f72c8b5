//! The low-pass of step 4: its design as second-order sections, the run over a
//! channel, and how long its impulse response takes to settle.

use sci_rs::signal::filter::design::{
    butter_dyn, DigitalFilter, FilterBandType, FilterOutputType, Sos,
};
use sci_rs::signal::filter::sosfilt_dyn;

use super::ConditionError;

/// Highest Butterworth order accepted; far beyond anything a 20 Hz touch signal needs,
/// and a bound that keeps the design numerically tame.
const MAX_ORDER: usize = 16;

/// The impulse response counts as settled below this share of its peak.
pub(super) const SETTLE_TOLERANCE: f64 = 1e-6;

/// Designs the Butterworth low-pass as second-order sections (scipy's
/// `butter(order, cutoff_hz, fs=rate_hz, output='sos')`, via sci-rs).
///
/// SOS only: at 1 kHz the 4 Hz poles sit so close to z = 1 that the single (b, a)
/// polynomial loses them to rounding (in f32 a pole lands outside the unit circle).
pub(super) fn design_lowpass(
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
pub(super) fn lowpass(x: &[f64], sos: &[Sos<f64>], zero_phase: bool) -> Vec<f64> {
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
pub(super) fn settle_frames(sos: &[Sos<f64>]) -> usize {
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
