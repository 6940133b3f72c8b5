//! Keyframes rounded one by one: the fallback when no lines are confirmed.

use touch_protocol::{Stimulus, CHANNELS};
use touchc_model::config::KeyframeConfig;

use super::measure::measure;
use super::{builder, interpolation_error, Encoded, HeaderFields, KeyframeError, KeyframeOptions};

/// What the search of rounded keyframes has seen so far.
struct Tried {
    /// Candidates encoded and played.
    count: usize,
    /// The smallest RMS error seen and its max error, fractions of full scale.
    closest: (f64, f64),
    /// A peak or slew limit the player hit on a candidate.
    limit_hit: Option<&'static str>,
}

/// Keyframes rounded one by one: the longest period, then the coarsest resolution,
/// whose played output meets the bounds.
pub(super) fn encode_rounded(
    signal: &[[f64; CHANNELS]],
    fields: HeaderFields<'_>,
    opts: &KeyframeOptions,
) -> Result<Encoded, KeyframeError> {
    let fs_a = f64::from(opts.full_scale_ma) / 1000.0;
    let mut tried = Tried {
        count: 0,
        closest: (f64::INFINITY, f64::INFINITY),
        limit_hit: None,
    };
    let mut periods = opts.encoding.periods_ms.clone();
    periods.sort_unstable_by(|a, b| b.cmp(a));
    let max_a = opts.encoding.max_abs_error_fs * fs_a;
    for &period in &periods {
        // Interpolation error alone, in f64: a period that misses the bounds before
        // quantisation cannot meet them after it.
        let Some((rms, max)) = interpolation_error(signal, usize::from(period.max(1)), max_a)
        else {
            continue;
        };
        if rms / fs_a > opts.encoding.max_rms_error_fs {
            tried.closest = min_pair(tried.closest, (rms / fs_a, max / fs_a));
            continue;
        }
        // The longest passing period wins: a shorter one only adds keyframes.
        let interpolated = (rms / fs_a, max / fs_a);
        if let Some(mut b) = coarsest_shift(signal, fields, opts, period, interpolated, &mut tried)?
        {
            b.candidates_tried = tried.count;
            return Ok(b);
        }
    }
    // When the player refused a candidate and none passed, report the limit: it is
    // the obstacle a smaller signal (`--fit`) removes, where finer keyframes do not.
    match tried.limit_hit {
        Some(kind) => Err(KeyframeError::LimitHit(kind)),
        None => {
            let finest = periods.last().map_or(1, |&p| p.max(1));
            Err(unfaithful(signal, fields, opts, finest, &tried))
        }
    }
}

/// The coarsest resolution at `period` whose played output meets the bounds, given
/// the interpolation error `(rms, max)` (fractions of full scale) of the period. The
/// error grows with the shift, so the walk starts from the shift the error budget
/// predicts (see [`predicted_shift`]): up while candidates pass, down while they
/// fail. Usually two plays.
fn coarsest_shift(
    signal: &[[f64; CHANNELS]],
    fields: HeaderFields<'_>,
    opts: &KeyframeOptions,
    period: u16,
    (rms, max): (f64, f64),
    tried: &mut Tried,
) -> Result<Option<Encoded>, KeyframeError> {
    let max_shift = opts.encoding.max_quant_shift.min(15);
    let mut shift = predicted_shift(rms, max, &opts.encoding).min(max_shift);
    let mut passing: Option<Encoded> = None;
    loop {
        tried.count += 1;
        let bounds = (
            opts.encoding.max_rms_error_fs,
            opts.encoding.max_abs_error_fs,
        );
        let candidate = match try_encoding(signal, fields, opts, period, shift, Some(bounds)) {
            Ok(c) => c,
            // The coil's heat is the signal's energy: neither a finer resolution
            // nor more keyframes change it beyond rounding, so stop at once (with
            // `--fit` the compile scales the signal down and comes back).
            Err(KeyframeError::LimitHit(kind @ "thermal")) => {
                return Err(KeyframeError::LimitHit(kind))
            }
            // A peak or slew hit can be rounding's overshoot, which finer
            // encodings may not have: this one just fails.
            Err(KeyframeError::LimitHit(kind)) => {
                tried.limit_hit = Some(kind);
                Encoded::empty()
            }
            Err(e) => return Err(e),
        };
        tried.closest = min_pair(
            tried.closest,
            (candidate.rms_error_fs, candidate.max_error_fs),
        );
        let passes = candidate.rms_error_fs <= opts.encoding.max_rms_error_fs
            && candidate.max_error_fs <= opts.encoding.max_abs_error_fs;
        if passes {
            passing = Some(candidate);
            if shift == max_shift {
                break;
            }
            shift += 1;
        } else if passing.is_some() || shift == 0 {
            break;
        } else {
            shift -= 1;
        }
    }
    Ok(passing)
}

/// The error when no rounded encoding meets the bounds, with the closest figures
/// `tried` saw. When it saw none (every candidate played stopped at a bound, or every
/// period broke the max bound in interpolation alone), the figures of the `finest`
/// period in full: played when candidates were (interpolation at 1 ms is exact; what
/// the player misses, a ramp-in from 0 A say, shows only in playback), else
/// interpolated.
fn unfaithful(
    signal: &[[f64; CHANNELS]],
    fields: HeaderFields<'_>,
    opts: &KeyframeOptions,
    finest: u16,
    tried: &Tried,
) -> KeyframeError {
    let fs_a = f64::from(opts.full_scale_ma) / 1000.0;
    let mut closest = tried.closest;
    if !closest.0.is_finite() {
        let played = (tried.count > 0)
            .then(|| try_encoding(signal, fields, opts, finest, 0, None).ok())
            .flatten();
        if let Some(e) = played {
            closest = (e.rms_error_fs, e.max_error_fs);
        } else if let Some(e) = interpolation_error(signal, usize::from(finest), f64::INFINITY) {
            closest = (e.0 / fs_a, e.1 / fs_a);
        }
    }
    KeyframeError::Unfaithful {
        rms: closest.0,
        max: closest.1,
    }
}

/// The coarsest quantisation shift whose error, added to the interpolation error
/// (`rms`, `max`, fractions of full scale), stays within the bounds: rounding a Q15
/// keyframe to a multiple of 2^shift errs by up to half a step (uniform, so its RMS is
/// step / sqrt(12)), and the 12-bit output code by up to half a code. A starting point
/// for the search only: the player decides.
fn predicted_shift(rms: f64, max: f64, bounds: &KeyframeConfig) -> u8 {
    let code = 2.0 / 4096.0;
    (0..=15u8)
        .rev()
        .find(|&s| {
            let step = f64::from(1u32 << s) / 32768.0;
            let rms_q = (rms * rms + (step * step + code * code) / 12.0).sqrt();
            rms_q <= bounds.max_rms_error_fs && max + 0.5 * (step + code) <= bounds.max_abs_error_fs
        })
        .unwrap_or(0)
}

fn min_pair(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    if b.0 < a.0 {
        b
    } else {
        a
    }
}

/// Q15 of the full scale, rounded to nearest and saturated.
pub(super) fn to_q15(amps: f64, fs_a: f64) -> i16 {
    (amps / fs_a * 32768.0).round().clamp(-32768.0, 32767.0) as i16
}

/// Keyframes rounded one by one at `period` and `2^shift`, encoded, played and measured
/// against `signal` (giving up, with infinite figures, once `bounds` are sure to be
/// missed).
fn try_encoding(
    signal: &[[f64; CHANNELS]],
    fields: HeaderFields<'_>,
    opts: &KeyframeOptions,
    period: u16,
    shift: u8,
    bounds: Option<(f64, f64)>,
) -> Result<Encoded, KeyframeError> {
    let fs_a = f64::from(opts.full_scale_ma) / 1000.0;
    let p = usize::from(period);
    let count = (signal.len() - 1).div_ceil(p) + 1;
    let keyframes: Vec<[i16; CHANNELS]> = (0..count)
        .map(|k| signal[(k * p).min(signal.len() - 1)].map(|a| to_q15(a, fs_a)))
        .collect();
    let bytes = builder(fields, opts, period, shift).encode(&keyframes)?;
    let stim = Stimulus::decode(&bytes)?;
    let (rms, max) = measure(&stim, signal, opts.full_scale_ma, fields.limits, bounds)?;
    Ok(Encoded {
        bytes,
        period_ms: period,
        quant_shift: shift,
        tolerance_fs: 0.0,
        rms_error_fs: rms,
        max_error_fs: max,
        candidates_tried: 1,
    })
}
