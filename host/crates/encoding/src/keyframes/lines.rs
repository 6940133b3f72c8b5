//! Keyframes on lines: the tolerance search of the tube, on the whole signal or on
//! windows of a long one.

use touch_protocol::{stimulus, Stimulus, CHANNELS};

use super::allocate::allocate;
use super::measure::measure;
use super::tube::tube_keyframes;
use super::{builder, interpolation_error, Encoded, HeaderFields, KeyframeError, KeyframeOptions};

/// The longest period of `opts` whose plain interpolation (keyframes exact, in f64)
/// meets both bounds, and the next shorter one: the periods the line encoding tries.
fn faithful_periods(signal: &[[f64; CHANNELS]], opts: &KeyframeOptions) -> Vec<u16> {
    let fs_a = f64::from(opts.full_scale_ma) / 1000.0;
    let mut periods = opts.encoding.periods_ms.clone();
    periods.sort_unstable_by(|a, b| b.cmp(a));
    periods.dedup();
    let max_a = opts.encoding.max_abs_error_fs * fs_a;
    let first = periods.iter().position(|&period| {
        interpolation_error(signal, usize::from(period.max(1)), max_a)
            .is_some_and(|(rms, _)| rms / fs_a <= opts.encoding.max_rms_error_fs)
    });
    first.map_or_else(Vec::new, |i| periods[i..].iter().take(2).copied().collect())
}

/// Quantisation shifts the line encoding tries: 2^5 and 2^6 Q15 units per step
/// (0.1% and 0.2% of full scale). Finer costs residual bits; coarser leaves too few
/// slopes for a line to follow a slow signal for long (a slope is a whole number of
/// steps per keyframe). Measured on the shipped, reference and synthetic recordings
/// under `touch` and `paper` (40 stimuli), {5, 6} gives 4-9% fewer bytes in all than
/// {4, 6} or {5, 7}, and 3.5% fewer than 6 or 5 alone (for one tube pass more).
pub(super) const LINE_SHIFTS: [u8; 2] = [6, 5];

/// At most this many tolerances are tried for the first shift, and for the second
/// (which starts from the first's answer).
const TOLERANCE_STEPS: usize = 3;
const TOLERANCE_STEPS_AFTER: usize = 1;

/// The tolerance search stops when the largest passing tolerance is within this
/// factor of the smallest failing one.
const TOLERANCE_RESOLUTION: f64 = 1.1;

/// The smallest line encoding found: its file, keyframe period (ms), quantisation
/// shift and tolerance (fraction of full scale).
struct Lines {
    bytes: Vec<u8>,
    period: u16,
    shift: u8,
    tol: f64,
}

/// Keyframes on lines through a tolerance tube (see [`tube_keyframes`]), the largest
/// tolerance whose modelled error meets the bounds, played once to confirm. `None`
/// when no such encoding exists or the player does not confirm it: the caller then
/// rounds every keyframe.
pub(super) fn encode_lines(
    signal: &[[f64; CHANNELS]],
    fields: HeaderFields<'_>,
    opts: &KeyframeOptions,
) -> Result<Option<Encoded>, KeyframeError> {
    let Some(model) = model_bounds(opts) else {
        return Ok(None);
    };
    // The longest period first; the next shorter one only when no tolerance passes
    // there (its plain interpolation is so near the max bound that a keyframe no line
    // reaches, rounded to the step, lands over it).
    let mut best = None;
    for period in faithful_periods(signal, opts) {
        best = search_period(signal, fields, opts, period, model)?;
        if best.is_some() {
            break;
        }
    }
    let Some(Lines {
        mut bytes,
        period,
        shift,
        mut tol,
    }) = best
    else {
        return Ok(None);
    };
    let fs_a = f64::from(opts.full_scale_ma) / 1000.0;
    let p = usize::from(period.max(1));
    if windows_sampled(signal, p) {
        // The tolerance was found on samples of a long signal: the whole signal's
        // lines, a little tighter while their modelled error misses the bounds.
        let whole = whole_signal(signal, fields, opts, period, shift, tol, model)?;
        let Some((whole_bytes, whole_tol)) = whole else {
            return Ok(None);
        };
        (bytes, tol) = (whole_bytes, whole_tol);
    } else {
        // Bytes per second of the 1 kHz signal.
        let density = bytes.len() as f64 * 1000.0 / signal.len() as f64;
        if density > opts.encoding.allocate_above_bytes_per_s {
            // A tolerance per second and channel instead of one for all, where that is
            // smaller.
            let builder = |shift| builder(fields, opts, period, shift);
            if let Some(b) = allocate(signal, fs_a, p, shift, tol, model, &builder)? {
                if b.len() < bytes.len() {
                    bytes = b;
                }
            }
        }
    }
    let Some((rms, max)) = confirmed(signal, &bytes, fields, opts)? else {
        return Ok(None);
    };
    Ok(Some(Encoded {
        bytes,
        period_ms: period,
        quant_shift: shift,
        tolerance_fs: tol,
        rms_error_fs: rms,
        max_error_fs: max,
        candidates_tried: 1,
    }))
}

/// The bounds the modelled lines must meet, `(rms, max)` as fractions of full scale:
/// the player's output differs from the modelled line by its integer interpolation
/// (under a Q15 unit) and its 12-bit output code (half a code, 1/4096 of full
/// scale), so the model must stay that far inside the bounds. `None` when the bounds
/// leave no room for that.
fn model_bounds(opts: &KeyframeOptions) -> Option<(f64, f64)> {
    let bounds = &opts.encoding;
    let margin = 1.0 / 4096.0 + 2.0 / 32768.0;
    let max_model = bounds.max_abs_error_fs - margin;
    let rms_model = bounds.max_rms_error_fs * 0.97 - margin / 4.0;
    if max_model <= 0.0 || rms_model <= 0.0 {
        return None;
    }
    Some((rms_model, max_model))
}

/// The smallest encoding at `period` whose modelled error meets `model` (see
/// [`model_bounds`]), over the shifts of [`LINE_SHIFTS`], each at the largest
/// tolerance that passes.
fn search_period(
    signal: &[[f64; CHANNELS]],
    fields: HeaderFields<'_>,
    opts: &KeyframeOptions,
    period: u16,
    model: (f64, f64),
) -> Result<Option<Lines>, KeyframeError> {
    let max_shift = opts.encoding.max_quant_shift.min(15);
    let windows = search_windows(signal, usize::from(period.max(1)));
    let mut best: Option<Lines> = None;
    // The second shift starts from the first's answer.
    let mut start = model.1;
    for shift in LINE_SHIFTS.map(|s| s.min(max_shift)) {
        if best.as_ref().is_some_and(|b| b.shift == shift) {
            continue;
        }
        let steps = if best.is_some() {
            TOLERANCE_STEPS_AFTER
        } else {
            TOLERANCE_STEPS
        };
        let at = Candidates {
            windows: &windows,
            fields,
            opts,
            period,
            shift,
        };
        search_tolerance(&at, start, steps, model, &mut best)?;
        if let Some(b) = &best {
            start = b.tol;
        }
    }
    Ok(best)
}

/// Where a tolerance search runs: the search windows, at one period and shift.
struct Candidates<'w, 's, 'f> {
    windows: &'w [&'s [[f64; CHANNELS]]],
    fields: HeaderFields<'f>,
    opts: &'w KeyframeOptions,
    period: u16,
    shift: u8,
}

/// Up to `steps` tube passes from tolerance `start`, keeping in `best` the smallest
/// file whose modelled error meets `model`. The RMS error grows about in proportion
/// to the tolerance, so each guess interpolates the RMS between the passing and
/// failing tolerances tried (regula falsi, aiming just under the bound). Usually
/// three tube passes for the first shift, one for the second.
fn search_tolerance(
    at: &Candidates<'_, '_, '_>,
    start: f64,
    steps: usize,
    (rms_model, max_model): (f64, f64),
    best: &mut Option<Lines>,
) -> Result<(), KeyframeError> {
    let fs_a = f64::from(at.opts.full_scale_ma) / 1000.0;
    let p = usize::from(at.period.max(1));
    let builder = |shift| builder(at.fields, at.opts, at.period, shift);
    // (tolerance, RMS) of the largest passing and the smallest failing tried.
    let mut passing: Option<(f64, f64)> = None;
    let mut failing: Option<(f64, f64)> = None;
    let mut tol = start;
    for _ in 0..steps {
        let (bytes, rms, max) = tube_bytes(at.windows, fs_a, p, at.shift, tol, &builder)?;
        if rms <= rms_model && max <= max_model {
            if best.as_ref().is_none_or(|b| bytes.len() < b.bytes.len()) {
                *best = Some(Lines {
                    bytes,
                    period: at.period,
                    shift: at.shift,
                    tol,
                });
            }
            passing = Some((tol, rms));
        } else if rms <= rms_model {
            // A keyframe no line reaches: a smaller tolerance does not mend it.
            break;
        } else {
            failing = Some((tol, rms));
        }
        let aim = 0.99 * rms_model;
        tol = match (passing, failing) {
            (Some(p), Some(f)) => {
                if f.0 < p.0 * TOLERANCE_RESOLUTION {
                    break;
                }
                let guess = p.0 + (aim - p.1) * (f.0 - p.0) / (f.1 - p.1).max(f64::MIN_POSITIVE);
                let margin = 0.1 * (f.0 - p.0);
                guess.clamp(p.0 + margin, f.0 - margin)
            }
            (None, Some(f)) => f.0 * (aim / f.1).clamp(0.3, 0.9),
            (Some(p), None) if p.0 < max_model => {
                (p.0 * (aim / p.1.max(f64::MIN_POSITIVE)).clamp(1.1, 3.0)).min(max_model)
            }
            _ => break,
        };
    }
    Ok(())
}

/// The whole signal's lines at `tol` found on search windows, a little tighter while
/// their modelled error misses `model`: the file and the tolerance, or `None` when
/// a few tightenings do not meet it.
fn whole_signal(
    signal: &[[f64; CHANNELS]],
    fields: HeaderFields<'_>,
    opts: &KeyframeOptions,
    period: u16,
    shift: u8,
    mut tol: f64,
    (rms_model, max_model): (f64, f64),
) -> Result<Option<(Vec<u8>, f64)>, KeyframeError> {
    let fs_a = f64::from(opts.full_scale_ma) / 1000.0;
    let p = usize::from(period.max(1));
    for _ in 0..TOLERANCE_STEPS {
        let (keyframes, rms, max) = tube_keyframes(signal, fs_a, p, shift, tol * 32768.0);
        if rms / 32768.0 <= rms_model && max / 32768.0 <= max_model {
            let bytes = builder(fields, opts, period, shift).encode(&keyframes)?;
            return Ok(Some((bytes, tol)));
        }
        tol *= 0.9;
    }
    Ok(None)
}

/// The playback error `(rms, max)` of `bytes`, played by the protocol player, when it
/// meets the bounds; `None` when it misses them or the player stops at a peak or slew
/// limit (the caller then tries keyframes rounded one by one). A thermal limit is an
/// error: the coil's heat is the signal's energy, which no encoding changes.
fn confirmed(
    signal: &[[f64; CHANNELS]],
    bytes: &[u8],
    fields: HeaderFields<'_>,
    opts: &KeyframeOptions,
) -> Result<Option<(f64, f64)>, KeyframeError> {
    let bounds = &opts.encoding;
    let stim = Stimulus::decode(bytes)?;
    let played = measure(
        &stim,
        signal,
        opts.full_scale_ma,
        fields.limits,
        Some((bounds.max_rms_error_fs, bounds.max_abs_error_fs)),
    );
    let (rms, max) = match played {
        Ok(e) => e,
        Err(KeyframeError::LimitHit(kind @ "thermal")) => {
            return Err(KeyframeError::LimitHit(kind))
        }
        Err(KeyframeError::LimitHit(_)) => return Ok(None),
        Err(e) => return Err(e),
    };
    if !(rms <= bounds.max_rms_error_fs && max <= bounds.max_abs_error_fs) {
        return Ok(None);
    }
    Ok(Some((rms, max)))
}

/// A signal longer than this many search windows' worth is searched on windows.
pub(super) const SEARCH_WINDOWS: usize = 16;

/// Length of a search window, ms (rounded down to whole keyframe periods).
const SEARCH_WINDOW_MS: usize = 6_000;

/// Whether the tolerance search of `signal` at `period` runs on windows, not on the
/// whole signal: when the windows cover under an eighth of it (past about 13 minutes;
/// at 6 minutes, windows covering a quarter found a tolerance 15% smaller than the
/// whole signal's, for 28% more bytes under `paper`).
pub(super) fn windows_sampled(signal: &[[f64; CHANNELS]], period: usize) -> bool {
    let len = (SEARCH_WINDOW_MS / period).max(1) * period + 1;
    signal.len() > 8 * SEARCH_WINDOWS * len
}

/// Where the tolerance search looks: the whole signal, or for a long one (an hour of
/// touch is 3.6 M ticks, and each tolerance tried is a pass over them)
/// [`SEARCH_WINDOWS`] windows of about [`SEARCH_WINDOW_MS`], spread evenly. Each
/// window starts on a keyframe and ends on one, so its lines are the whole signal's
/// up to where they start. The chosen tolerance is then checked on the whole signal.
pub(super) fn search_windows(signal: &[[f64; CHANNELS]], period: usize) -> Vec<&[[f64; CHANNELS]]> {
    if !windows_sampled(signal, period) {
        return vec![signal];
    }
    let len = (SEARCH_WINDOW_MS / period).max(1) * period + 1;
    let room = signal.len() - len;
    (0..SEARCH_WINDOWS)
        .map(|i| {
            let start = i * room / (SEARCH_WINDOWS - 1) / period * period;
            &signal[start..start + len]
        })
        .collect()
}

/// The tube's keyframes on each of `windows` at `tol` (fraction of full scale),
/// encoded: the file (of the whole signal when `windows` is it; else the windows'
/// files back to back, a size to compare shifts by) and the modelled RMS and max
/// error over all windows, fractions of full scale.
fn tube_bytes<'a>(
    windows: &[&[[f64; CHANNELS]]],
    fs_a: f64,
    period: usize,
    shift: u8,
    tol: f64,
    builder: &impl Fn(u8) -> stimulus::Builder<'a>,
) -> Result<(Vec<u8>, f64, f64), KeyframeError> {
    let (mut bytes, mut sum2, mut max, mut ticks) = (Vec::new(), 0.0, 0.0f64, 0usize);
    for w in windows {
        let (keyframes, rms, worst) = tube_keyframes(w, fs_a, period, shift, tol * 32768.0);
        bytes.extend(builder(shift).encode(&keyframes)?);
        let n = w.len() * CHANNELS;
        sum2 += rms * rms * n as f64;
        ticks += n;
        max = max.max(worst);
    }
    Ok((bytes, (sum2 / ticks as f64).sqrt() / 32768.0, max / 32768.0))
}
