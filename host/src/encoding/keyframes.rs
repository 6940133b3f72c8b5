//! Stage 7: keyframes. Chooses the keyframe rate and resolution the band-limited
//! signal needs and encodes the stimulus file.
//!
//! After the 4 Hz low-pass the signal carries nothing a 1 kHz sample stream would
//! add, so the file holds keyframes that the player interpolates linearly. The
//! choice is measured, not guessed: every candidate is encoded, decoded and played
//! by the protocol crate's player (the firmware's code), and its 1 kHz output is
//! compared with the compiler's own f64 signal. The smallest file that meets the
//! fidelity bounds wins.

use crate::config::KeyframeConfig;
use touch_protocol::player::{code_to_amps, LimitKind};
use touch_protocol::{stimulus, DeviceConfig, Limits, Player, Status, Stimulus, CHANNELS};

/// Bounds and fixed fields of the encoding.
#[derive(Debug, Clone, PartialEq)]
pub struct KeyframeOptions {
    /// Current of Q15 full scale, mA (the amplifier's full scale: a device fact, not a
    /// knob).
    pub full_scale_ma: u16,
    /// The fidelity bounds, ramp and candidates (the config's `keyframes` section).
    pub encoding: KeyframeConfig,
}

impl KeyframeOptions {
    /// The options of `encoding` at the device's full scale.
    pub fn new(encoding: &KeyframeConfig) -> Self {
        KeyframeOptions {
            full_scale_ma: DeviceConfig::default().full_scale_ma,
            encoding: encoding.clone(),
        }
    }
}

impl Default for KeyframeOptions {
    fn default() -> Self {
        KeyframeOptions::new(&KeyframeConfig::default())
    }
}

/// The encoded stimulus and how faithful it is.
#[derive(Debug, Clone, PartialEq)]
pub struct Encoded {
    /// The stimulus file.
    pub bytes: Vec<u8>,
    /// Chosen keyframe period, ms.
    pub period_ms: u16,
    /// Chosen quantisation shift.
    pub quant_shift: u8,
    /// RMS error of the player's output against the f64 signal, fraction of full scale.
    pub rms_error_fs: f64,
    /// Largest error, fraction of full scale.
    pub max_error_fs: f64,
    /// Candidates encoded and played to choose this one.
    pub candidates_tried: usize,
}

impl Encoded {
    /// A placeholder for a candidate that was not produced.
    fn empty() -> Self {
        Encoded {
            bytes: Vec::new(),
            period_ms: 0,
            quant_shift: 0,
            rms_error_fs: f64::INFINITY,
            max_error_fs: f64::INFINITY,
            candidates_tried: 0,
        }
    }
}

/// Why no encoding was produced.
#[derive(Debug, thiserror::Error, PartialEq)]
#[non_exhaustive]
pub enum KeyframeError {
    /// The signal is empty or not finite.
    #[error("the signal is empty or has a non-finite sample")]
    BadSignal,
    /// Even the finest candidate misses the fidelity bounds.
    #[error("no keyframe rate meets the fidelity bounds (best: {rms:.4} RMS, {max:.4} max of full scale)")]
    Unfaithful {
        /// Best RMS error found.
        rms: f64,
        /// Best max error found.
        max: f64,
    },
    /// The player hit a safety limit while playing the encoding.
    #[error("the player hit its {0} limit playing the signal")]
    LimitHit(&'static str),
    /// The protocol crate refused the header (name too long, ...).
    #[error("cannot encode: {0}")]
    Protocol(#[from] touch_protocol::Error),
}

/// Fields of the header that the caller decides.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeaderFields<'a> {
    /// Stimulus name.
    pub name: &'a str,
    /// Actuator layout id.
    pub layout_id: u16,
    /// Limits the signal was checked against.
    pub limits: Limits,
}

/// Encodes `signal` (1 kHz, amperes) as the smallest stimulus that plays back within
/// the bounds of `opts`.
pub fn encode(
    signal: &[[f64; CHANNELS]],
    fields: HeaderFields<'_>,
    opts: &KeyframeOptions,
) -> Result<Encoded, KeyframeError> {
    if signal.is_empty() || signal.iter().flatten().any(|v| !v.is_finite()) {
        return Err(KeyframeError::BadSignal);
    }
    let fs_a = f64::from(opts.full_scale_ma) / 1000.0;
    let mut best: Option<Encoded> = None;
    let mut closest = (f64::INFINITY, f64::INFINITY);
    let mut tried = 0;
    let mut limit_hit = None;
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
            closest = min_pair(closest, (rms / fs_a, max / fs_a));
            continue;
        }
        // Coarsest passing resolution for this period. The error grows with the shift,
        // so walk from the shift the error budget predicts (see [`predicted_shift`]):
        // up while candidates pass, down while they fail. Usually two plays.
        let max_shift = opts.encoding.max_quant_shift.min(15);
        let mut shift = predicted_shift(rms / fs_a, max / fs_a, &opts.encoding).min(max_shift);
        let mut passing: Option<Encoded> = None;
        loop {
            tried += 1;
            let candidate = match try_encoding(signal, fields, opts, period, shift) {
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
                    limit_hit = Some(kind);
                    Encoded::empty()
                }
                Err(e) => return Err(e),
            };
            closest = min_pair(closest, (candidate.rms_error_fs, candidate.max_error_fs));
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
        // The longest passing period wins: a shorter one only adds keyframes.
        if passing.is_some() {
            best = passing;
            break;
        }
    }
    match best {
        Some(mut b) => {
            b.candidates_tried = tried;
            Ok(b)
        }
        // When the player refused a candidate and none passed, report the limit: it is
        // the obstacle a smaller signal (`--fit`) removes, where finer keyframes do not.
        None => match limit_hit {
            Some(kind) => Err(KeyframeError::LimitHit(kind)),
            None => {
                if !closest.0.is_finite() {
                    // Every period broke the max bound in interpolation alone, so no
                    // figure was taken: the finest period's, in full, for the message.
                    let finest = periods.last().map_or(1, |&p| usize::from(p.max(1)));
                    if let Some(e) = interpolation_error(signal, finest, f64::INFINITY) {
                        closest = (e.0 / fs_a, e.1 / fs_a);
                    }
                }
                Err(KeyframeError::Unfaithful {
                    rms: closest.0,
                    max: closest.1,
                })
            }
        },
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

/// RMS and max error of linear interpolation through every `period`-th sample; `None`
/// as soon as an error exceeds `max_bound` (most long periods fail early on a fast edge).
fn interpolation_error(
    signal: &[[f64; CHANNELS]],
    period: usize,
    max_bound: f64,
) -> Option<(f64, f64)> {
    let n = signal.len();
    let at = |i: usize| signal[i.min(n - 1)];
    let (mut sum2, mut max) = (0.0f64, 0.0f64);
    for (t, s) in signal.iter().enumerate() {
        let k = t / period;
        let (a, b) = (at(k * period), at((k + 1) * period));
        let w = (t - k * period) as f64 / period as f64;
        for c in 0..CHANNELS {
            let e = a[c] + (b[c] - a[c]) * w - s[c];
            sum2 += e * e;
            max = max.max(e.abs());
        }
        if max > max_bound {
            return None;
        }
    }
    Some(((sum2 / (n * CHANNELS) as f64).sqrt(), max))
}

/// Q15 of the full scale, rounded to nearest and saturated.
fn to_q15(amps: f64, fs_a: f64) -> i16 {
    (amps / fs_a * 32768.0).round().clamp(-32768.0, 32767.0) as i16
}

fn try_encoding(
    signal: &[[f64; CHANNELS]],
    fields: HeaderFields<'_>,
    opts: &KeyframeOptions,
    period: u16,
    shift: u8,
) -> Result<Encoded, KeyframeError> {
    let fs_a = f64::from(opts.full_scale_ma) / 1000.0;
    let p = usize::from(period);
    let count = (signal.len() - 1).div_ceil(p) + 1;
    let keyframes: Vec<[i16; CHANNELS]> = (0..count)
        .map(|k| signal[(k * p).min(signal.len() - 1)].map(|a| to_q15(a, fs_a)))
        .collect();
    let header = stimulus::Header {
        channels: CHANNELS as u8,
        output_rate_hz: stimulus::OUTPUT_RATE_HZ,
        keyframe_period_ms: period,
        keyframe_count: 0,
        duration_ms: 0,
        ramp_ms: opts.encoding.ramp_ms,
        full_scale_ma: opts.full_scale_ma,
        quant_shift: shift,
        layout_id: fields.layout_id,
        limits: fields.limits,
        name: fields.name,
    };
    let bytes = stimulus::encode(header, &keyframes)?;
    let stim = Stimulus::decode(&bytes)?;
    let bounds = (
        opts.encoding.max_rms_error_fs,
        opts.encoding.max_abs_error_fs,
    );
    let (rms, max) = measure(
        &stim,
        signal,
        opts.full_scale_ma,
        fields.limits,
        Some(bounds),
    )?;
    Ok(Encoded {
        bytes,
        period_ms: period,
        quant_shift: shift,
        rms_error_fs: rms,
        max_error_fs: max,
        candidates_tried: 1,
    })
}

/// Plays `bytes` through the protocol player and compares its output, code by code
/// converted back to amperes, with `signal`; both are 0 A outside their lengths.
/// Returns RMS and max error as fractions of the full scale.
pub fn playback_error(
    bytes: &[u8],
    signal: &[[f64; CHANNELS]],
    full_scale_ma: u16,
    limits: Limits,
) -> Result<(f64, f64), KeyframeError> {
    let stim = Stimulus::decode(bytes)?;
    measure(&stim, signal, full_scale_ma, limits, None)
}

/// [`playback_error`] on a decoded stimulus. With `bounds = (rms, max)`, gives up as
/// soon as the error is sure to exceed them, and reports `(INFINITY, INFINITY)`.
fn measure(
    stim: &Stimulus<'_>,
    signal: &[[f64; CHANNELS]],
    full_scale_ma: u16,
    limits: Limits,
    bounds: Option<(f64, f64)>,
) -> Result<(f64, f64), KeyframeError> {
    let device = DeviceConfig {
        full_scale_ma,
        limits,
    };
    let fs_a = f64::from(full_scale_ma) / 1000.0;
    let ticks = signal.len().max(stim.header().playback_ms() as usize + 1);
    // The RMS bound, as a budget for the running sum of squares over all ticks.
    let (sum2_budget, max_bound) = match bounds {
        Some((rms, max)) => (rms * rms * (ticks * CHANNELS) as f64, max),
        None => (f64::INFINITY, f64::INFINITY),
    };
    let mut player = Player::new(stim, &device);
    let (mut sum2, mut max, mut n) = (0.0f64, 0.0f64, 0usize);
    loop {
        let tick = player.tick();
        if let Status::Fault(f) = tick.status {
            return Err(KeyframeError::LimitHit(match f.kind {
                LimitKind::Peak => "peak",
                LimitKind::Slew => "slew",
                LimitKind::Thermal => "thermal",
            }));
        }
        let want = signal.get(n).copied().unwrap_or([0.0; CHANNELS]);
        for (c, &code) in tick.codes.iter().enumerate() {
            let e = (code_to_amps(code, full_scale_ma) - want[c]) / fs_a;
            sum2 += e * e;
            max = max.max(e.abs());
        }
        n += 1;
        if sum2 > sum2_budget || max > max_bound {
            return Ok((f64::INFINITY, f64::INFINITY));
        }
        if tick.status == Status::Finished && n >= signal.len() {
            break;
        }
    }
    Ok(((sum2 / (n * CHANNELS) as f64).sqrt(), max))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fields() -> HeaderFields<'static> {
        HeaderFields {
            name: "test",
            layout_id: 1,
            limits: Limits::SLEEVE,
        }
    }

    /// What the compiler produces for a stroke: raised-cosine ramps from 0 A to the
    /// -0.9 A pre-dent and back, and on each channel in turn a smooth press out to
    /// +1 A lasting about half a second (a 4 Hz-band bump).
    fn stroke(seconds: f64) -> Vec<[f64; CHANNELS]> {
        let n = (seconds * 1000.0) as usize;
        let ramp = |x: f64| {
            let u = (x / 0.5)
                .clamp(0.0, 1.0)
                .min(((seconds - x) / 0.5).clamp(0.0, 1.0));
            0.5 - 0.5 * (std::f64::consts::PI * u).cos()
        };
        (0..n)
            .map(|t| {
                let x = t as f64 / 1000.0;
                std::array::from_fn(|c| {
                    let centre = 1.0 + (seconds - 2.0) * c as f64 / 7.0;
                    let bump = (-0.5 * ((x - centre) / 0.12).powi(2)).exp();
                    ramp(x) * (-0.9 + 1.9 * bump)
                })
            })
            .collect()
    }

    #[test]
    fn smooth_signal_meets_the_bounds_in_few_bytes() {
        let signal = stroke(6.0);
        let e = encode(&signal, fields(), &KeyframeOptions::default()).unwrap();
        assert!(e.rms_error_fs <= 0.005 && e.max_error_fs <= 0.02, "{e:?}");
        let bytes_per_s = e.bytes.len() as f64 / 6.0;
        assert!(
            bytes_per_s < 200.0,
            "{bytes_per_s} B/s, period {} shift {}",
            e.period_ms,
            e.quant_shift
        );
        // Independent check of the reported figures.
        let (rms, max) = playback_error(&e.bytes, &signal, 1000, Limits::SLEEVE).unwrap();
        assert_eq!((rms, max), (e.rms_error_fs, e.max_error_fs));
    }

    #[test]
    fn tighter_bounds_cost_more_bytes() {
        let signal = stroke(3.0);
        let loose = encode(&signal, fields(), &KeyframeOptions::default()).unwrap();
        let tight = KeyframeOptions::new(&KeyframeConfig {
            max_rms_error_fs: 0.0005,
            max_abs_error_fs: 0.002,
            ..Default::default()
        });
        let tight = encode(&signal, fields(), &tight).unwrap();
        assert!(tight.rms_error_fs <= 0.0005);
        assert!(tight.bytes.len() > loose.bytes.len());
    }

    #[test]
    fn silence_is_tiny_and_exact() {
        let signal = vec![[0.0; CHANNELS]; 2000];
        let e = encode(&signal, fields(), &KeyframeOptions::default()).unwrap();
        assert_eq!(e.rms_error_fs, 0.0);
        assert!(e.bytes.len() < 60, "{}", e.bytes.len());
    }

    #[test]
    fn impossible_bounds_are_an_error() {
        let signal = stroke(1.0);
        let opts = KeyframeOptions::new(&KeyframeConfig {
            max_abs_error_fs: 1e-9,
            ..Default::default()
        });
        assert!(matches!(
            encode(&signal, fields(), &opts),
            Err(KeyframeError::Unfaithful { .. })
        ));
        // Without the exact 1 ms period every period fails in interpolation alone; the
        // error still gives the finest period's figures, not infinities.
        let coarse = KeyframeOptions::new(&KeyframeConfig {
            periods_ms: vec![250, 100],
            max_abs_error_fs: 1e-9,
            ..Default::default()
        });
        match encode(&signal, fields(), &coarse) {
            Err(KeyframeError::Unfaithful { rms, max }) => {
                assert!(
                    rms.is_finite() && max.is_finite() && max > 1e-9,
                    "{rms} {max}"
                )
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(encode(&[], fields(), &opts), Err(KeyframeError::BadSignal));
        let nan = vec![[f64::NAN; CHANNELS]; 3];
        assert_eq!(encode(&nan, fields(), &opts), Err(KeyframeError::BadSignal));
    }
}
