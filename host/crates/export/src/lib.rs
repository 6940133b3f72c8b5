//! Export: a stimulus as the sleeve plays it, written in the haptics world's formats.
//!
//! Every format starts from the player's output (the firmware's code, run here), not
//! from the keyframes in the file, so the limits, the ramps and the integer
//! interpolation are in what is exported. Each writer approximates each channel's
//! 1 kHz current with line segments (`fit_polyline`) at a tolerance the player itself
//! meets, then writes them as its format's own reader expects:
//!
//! | format | module | keeps |
//! |---|---|---|
//! | MPEG-I Haptics HJIF (ISO/IEC 23090-31) | [`hjif`] | signed current, 8 channels, their places on the forearm |
//! | Meta/Lofelt `.haptic` | [`haptic`] | one channel's (or the mix's) magnitude, 0..1 |
//! | Apple AHAP | [`ahap`] | one channel's (or the mix's) magnitude as Core Haptics intensity |
//! | bHaptics `.tact` | [`tact`] | magnitudes on the 6 motors of a forearm device, in 20 ms frames |
//!
//! `docs/export.md` says what each one loses. Every writer also reports how far what
//! its reader would reconstruct is from the player's output ([`Fidelity`]).

#![deny(missing_docs)]

pub mod ahap;
pub mod haptic;
pub mod hjif;
pub mod tact;

use touch_protocol::player::{code_to_amps, Fault};
use touch_protocol::{DeviceConfig, Player, Status, Stimulus, CHANNELS};
use touchc_model::layout::Layout;

/// Why a stimulus cannot be exported, or an exported file imported.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The stimulus was compiled for another actuator layout than the target's.
    #[error(
        "compiled for layout {file_layout:?} (geometry {file_hash:#010x}), not for {target:?} \
         (geometry {target_hash:#010x})"
    )]
    WrongLayout {
        /// The layout name the file carries.
        file_layout: String,
        /// The geometry hash the file carries.
        file_hash: u32,
        /// The target layout's name.
        target: String,
        /// The target layout's geometry hash.
        target_hash: u32,
    },
    /// The stimulus plays longer than an export holds (the whole output is kept in
    /// memory while it is fitted: 64 bytes per millisecond).
    #[error("plays {seconds:.0} s, longer than the {max_s} s an export holds")]
    TooLong {
        /// How long the stimulus plays, seconds.
        seconds: f64,
        /// `MAX_EXPORT_MS` in seconds.
        max_s: u32,
    },
    /// A channel number outside the sleeve's eight.
    #[error("channel {0} does not exist: the sleeve has channels 0 to 7")]
    NoSuchChannel(usize),
    /// A file to import is not what its format's reader accepts.
    #[error("not a valid {format} file: {reason}")]
    Invalid {
        /// The format's name.
        format: &'static str,
        /// What is wrong, in the reader's terms.
        reason: String,
    },
    /// A JSON document could not be parsed or written.
    #[error("JSON")]
    Json(#[from] serde_json::Error),
}

/// The formats `touchc export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// MPEG-I Haptics interchange format (JSON).
    Hjif,
    /// Meta/Lofelt `.haptic` (JSON).
    Haptic,
    /// Apple Haptic and Audio Pattern (JSON).
    Ahap,
    /// bHaptics `.tact` (JSON).
    Tact,
}

impl Format {
    /// The file name extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Hjif => "hjif",
            Format::Haptic => "haptic",
            Format::Ahap => "ahap",
            Format::Tact => "tact",
        }
    }

    /// Whether the format holds one signal per file (no spatial channels), so that a
    /// stimulus becomes one file per actuator unless one channel or the mix is chosen.
    pub fn single_signal(self) -> bool {
        matches!(self, Format::Haptic | Format::Ahap)
    }
}

/// Which of the eight signals a single-signal format carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pick {
    /// One actuator's channel.
    Channel(usize),
    /// At each tick, the most pressed of the eight channels (the largest current): a
    /// touch under one actuator is felt at its full strength, not diluted by seven at
    /// rest.
    Mix,
}

/// The sleeve's output for one stimulus, tick by tick, through the ramp down.
#[derive(Debug, Clone, PartialEq)]
pub struct Playback {
    /// Per channel, the current of each 1 kHz tick, amperes.
    pub amps: [Vec<f64>; CHANNELS],
    /// The device's full scale, amperes (codes 0 and 4095).
    pub full_scale_a: f64,
    /// The stimulus's name.
    pub name: String,
    /// The layout the stimulus was compiled for.
    pub layout: Layout,
    /// The first limit the player hit, and its tick, if any.
    pub fault: Option<(usize, Fault)>,
}

impl Playback {
    /// Ticks (1 ms each).
    pub fn ticks(&self) -> usize {
        self.amps[0].len()
    }

    /// Seconds of output.
    pub fn seconds(&self) -> f64 {
        self.ticks() as f64 / 1000.0
    }

    /// The single signal `pick` chooses, amperes.
    pub fn signal(&self, pick: Pick) -> Result<Vec<f64>, ExportError> {
        match pick {
            Pick::Channel(c) if c < CHANNELS => Ok(self.amps[c].clone()),
            Pick::Channel(c) => Err(ExportError::NoSuchChannel(c)),
            Pick::Mix => Ok((0..self.ticks())
                .map(|t| {
                    self.amps
                        .iter()
                        .map(|a| a[t])
                        .fold(f64::NEG_INFINITY, f64::max)
                })
                .collect()),
        }
    }
}

/// The longest playback an export takes, ms: an hour, 230 MB of samples while it is
/// fitted; haptic clips in these formats last seconds.
pub(crate) const MAX_EXPORT_MS: u32 = 3_600_000;

/// Plays `stimulus` on the sleeve (the device's full scale and limits, a cold coil)
/// to the end, after checking that it was compiled for `layout` and is not longer
/// than `MAX_EXPORT_MS`.
pub fn play(stimulus: &Stimulus<'_>, layout: &Layout) -> Result<Playback, ExportError> {
    let header = stimulus.header();
    if header.playback_ms() > MAX_EXPORT_MS {
        return Err(ExportError::TooLong {
            seconds: f64::from(header.playback_ms()) / 1000.0,
            max_s: MAX_EXPORT_MS / 1000,
        });
    }
    if header.layout_hash != layout.geometry_hash() {
        return Err(ExportError::WrongLayout {
            file_layout: header.layout.to_string(),
            file_hash: header.layout_hash,
            target: layout.id().to_string(),
            target_hash: layout.geometry_hash(),
        });
    }
    let device = DeviceConfig::default();
    let mut player = Player::new(stimulus, &device);
    let ticks = header.playback_ms() as usize + 1;
    let mut amps: [Vec<f64>; CHANNELS] = std::array::from_fn(|_| Vec::with_capacity(ticks));
    let mut fault = None;
    let mut t = 0usize;
    loop {
        let tick = player.tick();
        if let Status::Fault(f) = tick.status {
            fault.get_or_insert((t, f));
        }
        for (c, code) in tick.codes.iter().enumerate() {
            amps[c].push(code_to_amps(*code, device.full_scale_ma));
        }
        t += 1;
        if tick.status == Status::Finished {
            break;
        }
    }
    Ok(Playback {
        amps,
        full_scale_a: f64::from(device.full_scale_ma) / 1000.0,
        name: stimulus.name().to_string(),
        layout: layout.clone(),
        fault,
    })
}

/// How far what a format's reader reconstructs is from the player's output, as
/// fractions of the full scale, over every channel and tick the file carries.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Fidelity {
    /// RMS error against the player's signed output.
    pub rms_fs: f64,
    /// Largest error against the player's signed output.
    pub max_fs: f64,
    /// RMS error against what the format can carry of it (for `.tact`, the motor mix;
    /// elsewhere the signal itself): the precision of the fit alone.
    pub fit_rms_fs: f64,
    /// Largest error against what the format can carry.
    pub fit_max_fs: f64,
}

/// Sums squared and largest errors, then gives [`Fidelity`]'s fractions.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct ErrorSum {
    sum_sq: f64,
    max: f64,
    n: usize,
}

impl ErrorSum {
    /// Adds one error (already a fraction of the full scale).
    pub(crate) fn add(&mut self, e: f64) {
        self.sum_sq += e * e;
        self.max = self.max.max(e.abs());
        self.n += 1;
    }

    /// RMS and max.
    pub(crate) fn figures(&self) -> (f64, f64) {
        if self.n == 0 {
            return (0.0, 0.0);
        }
        ((self.sum_sq / self.n as f64).sqrt(), self.max)
    }
}

/// A file an export writes: `suffix` goes between the output's stem and its extension
/// (`.ch3` for actuator 3 of a single-signal format), empty for the one file.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportFile {
    /// Inserted before the extension: `""` or `.chN`.
    pub suffix: String,
    /// The file's bytes.
    pub bytes: Vec<u8>,
}

/// An export's files and how faithful they are.
#[derive(Debug, Clone, PartialEq)]
pub struct Exported {
    /// The files, in channel order for single-signal formats.
    pub files: Vec<ExportFile>,
    /// Reconstruction against the player's output.
    pub fidelity: Fidelity,
}

impl Exported {
    /// Bytes in all files.
    pub fn bytes(&self) -> usize {
        self.files.iter().map(|f| f.bytes.len()).sum()
    }
}

/// Options every writer shares.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportOptions {
    /// For single-signal formats: one channel, the mix, or (`None`) every channel in a
    /// file of its own.
    pub pick: Option<Pick>,
    /// The creation date written where a format has one, ISO 8601 (`YYYY-MM-DD`).
    pub date: String,
    /// The actuator's mechanical resonance, Hz, where a format describes the device
    /// (HJIF's reference device). `None` leaves it out: no value is made up for a coil
    /// whose datasheet the project does not have.
    pub resonance_hz: Option<f64>,
}

/// A single-signal format's writer: one file of `points` (tick, 0..1 value), the
/// [`UnitScale::curve`] of the signal `pick` chose.
type Writer = fn(&Playback, Pick, &[(usize, f64)]) -> Result<Vec<u8>, ExportError>;

/// Writes `playback` as `format`.
pub fn export(
    playback: &Playback,
    format: Format,
    opts: &ExportOptions,
) -> Result<Exported, ExportError> {
    match format {
        Format::Hjif => hjif::export(playback, &opts.date, opts.resonance_hz),
        Format::Tact => tact::export(playback),
        Format::Haptic | Format::Ahap => {
            let picks: Vec<(String, Pick)> = match opts.pick {
                Some(p) => vec![(String::new(), p)],
                None => (0..CHANNELS)
                    .map(|c| (format!(".ch{c}"), Pick::Channel(c)))
                    .collect(),
            };
            let mut files = Vec::new();
            let mut err = ErrorSum::default();
            let mut fit = ErrorSum::default();
            let (scale, write): (UnitScale, Writer) = if format == Format::Haptic {
                (haptic::SCALE, haptic::write)
            } else {
                (ahap::SCALE, ahap::write)
            };
            for (suffix, pick) in picks {
                let signal = playback.signal(pick)?;
                let points = scale.curve(&signal, playback.full_scale_a, &mut err, &mut fit);
                let bytes = write(playback, pick, &points)?;
                files.push(ExportFile { suffix, bytes });
            }
            Ok(Exported {
                files,
                fidelity: fidelity(&err, &fit),
            })
        }
    }
}

pub(crate) fn fidelity(err: &ErrorSum, fit: &ErrorSum) -> Fidelity {
    let (rms_fs, max_fs) = err.figures();
    let (fit_rms_fs, fit_max_fs) = fit.figures();
    Fidelity {
        rms_fs,
        max_fs,
        fit_rms_fs,
        fit_max_fs,
    }
}

/// Line segments through `samples` (one per 1 ms tick) that stay within `tol` of every
/// sample: the breakpoints `(tick, value)`, the first at tick 0 and the last at the
/// last tick, times strictly increasing.
///
/// Greedy and linear in time: from each breakpoint, the segment grows while some
/// slope keeps every sample so far within `tol` (the cone of such slopes narrows with
/// each sample); when none does, the segment ends at the previous sample, at the
/// value of the allowed slope nearest the sample there, which starts the next one.
pub(crate) fn fit_polyline(samples: &[f64], tol: f64) -> Vec<(usize, f64)> {
    let Some(&first) = samples.first() else {
        return Vec::new();
    };
    let mut points = vec![(0usize, first)];
    let (mut t0, mut v0) = (0usize, first);
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    let end_at = |t0: usize, v0: f64, lo: f64, hi: f64, t: usize, s: f64| {
        let dt = (t - t0) as f64;
        let slope = ((s - v0) / dt).clamp(lo, hi);
        v0 + slope * dt
    };
    let mut i = 1;
    while i < samples.len() {
        let dt = (i - t0) as f64;
        let l = lo.max((samples[i] - tol - v0) / dt);
        let h = hi.min((samples[i] + tol - v0) / dt);
        if l > h {
            let end = i - 1;
            let v = end_at(t0, v0, lo, hi, end, samples[end]);
            points.push((end, v));
            (t0, v0) = (end, v);
            (lo, hi) = (f64::NEG_INFINITY, f64::INFINITY);
            continue;
        }
        (lo, hi) = (l, h);
        i += 1;
    }
    let last = samples.len() - 1;
    if last > t0 {
        points.push((last, end_at(t0, v0, lo, hi, last, samples[last])));
    }
    points
}

/// The value at `tick` of the line segments through `points` (sorted by tick); the
/// first and last values hold outside them.
pub(crate) fn polyline_at(points: &[(usize, f64)], tick: usize, hint: &mut usize) -> f64 {
    while *hint + 1 < points.len() && points[*hint + 1].0 <= tick {
        *hint += 1;
    }
    let (t0, v0) = points[*hint];
    match points.get(*hint + 1) {
        Some(&(t1, v1)) if tick > t0 => v0 + (v1 - v0) * (tick - t0) as f64 / (t1 - t0) as f64,
        _ => v0,
    }
}

/// How a format that has no sign maps the current onto its 0..1 values, and back.
#[derive(Debug, Clone, Copy)]
pub(crate) struct UnitScale {
    /// The fit's tolerance, in the format's 0..1 values.
    pub(crate) tol: f64,
    /// A current (amperes) and the full scale to the format's value.
    pub(crate) to: fn(f64, f64) -> f64,
    /// A format's value and the full scale to the current its reader rebuilds.
    pub(crate) from: fn(f64, f64) -> f64,
}

impl UnitScale {
    /// The curve of `signal` (amperes, 1 kHz) in this scale: fitted within
    /// [`UnitScale::tol`], each breakpoint clamped to 0..1 and rounded to 6 decimals; at
    /// least two breakpoints, because these formats' readers want a start and an end
    /// even for a constant. What the reader rebuilds is compared with `signal` at every
    /// tick, and the errors (fractions of the full scale) are added to `err` and `fit`.
    pub(crate) fn curve(
        &self,
        signal: &[f64],
        full_scale_a: f64,
        err: &mut ErrorSum,
        fit: &mut ErrorSum,
    ) -> Vec<(usize, f64)> {
        let scaled: Vec<f64> = signal.iter().map(|&a| (self.to)(a, full_scale_a)).collect();
        let mut points: Vec<(usize, f64)> = fit_polyline(&scaled, self.tol)
            .into_iter()
            .map(|(t, v)| (t, round_to(v.clamp(0.0, 1.0), 6)))
            .collect();
        if points.len() == 1 {
            points.push((points[0].0 + 1, points[0].1));
        }
        let mut hint = 0;
        for (t, s) in signal.iter().enumerate() {
            let v = polyline_at(&points, t, &mut hint);
            let e = ((self.from)(v, full_scale_a) - s) / full_scale_a;
            fit.add(e);
            err.add(e);
        }
        points
    }
}

/// Tolerance of the curves, fraction of the full scale: two output codes (1/1024),
/// well inside the bounds the compiler meets (0.5% RMS, 2% max), so that a re-import
/// still meets them after its own encoding.
pub(crate) const CURVE_TOLERANCE_FS: f64 = 1.0 / 1024.0;

/// A current as the 0..1 amplitude of the formats that have no sign: `(I / full
/// scale + 1) / 2`. 0 is the coil pulled fully back, 1/2 no current, 1 fully pressed;
/// the sleeve's pre-indented rest (-0.9 A of 1 A) is 0.05. Affine, so nothing of the
/// value is lost: [`from_unit`] gives the current back.
pub(crate) fn to_unit(amps: f64, full_scale_a: f64) -> f64 {
    ((amps / full_scale_a + 1.0) / 2.0).clamp(0.0, 1.0)
}

/// The current of a [`to_unit`] amplitude.
pub(crate) fn from_unit(unit: f64, full_scale_a: f64) -> f64 {
    (2.0 * unit - 1.0) * full_scale_a
}

/// Rounds `v` to `digits` decimals, for compact JSON numbers.
pub(crate) fn round_to(v: f64, digits: i32) -> f64 {
    let k = 10f64.powi(digits);
    (v * k).round() / k
}

#[cfg(test)]
mod tests {
    use super::*;
    use touch_protocol::stimulus;

    /// A 2 s stimulus: each channel a different slow wave, signed.
    fn waves(layout_hash: u32) -> Vec<u8> {
        let builder = stimulus::Builder::new("waves", 20)
            .quant_shift(4)
            .layout("paper-2x4", layout_hash);
        let kf: Vec<[i16; CHANNELS]> = (0..=100)
            .map(|k| {
                let x = k as f64 / 100.0;
                std::array::from_fn(|c| {
                    let a = 0.4 * (std::f64::consts::PI * x * (c + 1) as f64).sin() - 0.2 * x;
                    (a * 32768.0).round() as i16
                })
            })
            .collect();
        builder.encode(&kf).unwrap()
    }

    #[test]
    fn a_stimulus_for_another_layout_is_not_played() {
        let bytes = waves(0x1234_5678);
        let stim = Stimulus::decode(&bytes).unwrap();
        let err = play(&stim, &Layout::paper()).unwrap_err();
        assert!(matches!(
            err,
            ExportError::WrongLayout {
                file_hash: 0x1234_5678,
                ..
            }
        ));
    }

    #[test]
    fn hjif_reads_back_what_it_wrote_within_its_tolerance() {
        let bytes = waves(Layout::paper().geometry_hash());
        let stim = Stimulus::decode(&bytes).unwrap();
        let played = play(&stim, &Layout::paper()).unwrap();
        let out = hjif::export(&played, "2026-01-01", None).unwrap();
        assert!(
            out.fidelity.max_fs <= CURVE_TOLERANCE_FS + 1e-6,
            "{:?}",
            out.fidelity
        );
        let back = hjif::import(&out.files[0].bytes, played.full_scale_a).unwrap();
        assert_eq!(back.layout_hash, Layout::paper().geometry_hash());
        assert_eq!(back.signal.len(), played.ticks());
        for (t, row) in back.signal.iter().enumerate() {
            for (c, (v, amps)) in row.iter().zip(&played.amps).enumerate() {
                let e = (v - amps[t]).abs() / played.full_scale_a;
                assert!(e <= CURVE_TOLERANCE_FS + 1e-5, "tick {t} channel {c}: {e}");
            }
        }
    }

    #[test]
    fn every_format_meets_its_tolerance_on_a_signed_signal() {
        let bytes = waves(Layout::paper().geometry_hash());
        let stim = Stimulus::decode(&bytes).unwrap();
        let played = play(&stim, &Layout::paper()).unwrap();
        for format in [Format::Hjif, Format::Haptic, Format::Ahap] {
            let opts = ExportOptions {
                pick: None,
                date: "2026-01-01".into(),
                resonance_hz: None,
            };
            let out = export(&played, format, &opts).unwrap();
            let files = if format.single_signal() { CHANNELS } else { 1 };
            assert_eq!(out.files.len(), files, "{format:?}");
            assert!(
                out.fidelity.max_fs <= CURVE_TOLERANCE_FS + 1e-5,
                "{format:?}: {:?}",
                out.fidelity
            );
        }
        let tact = export(
            &played,
            Format::Tact,
            &ExportOptions {
                pick: None,
                date: String::new(),
                resonance_hz: None,
            },
        )
        .unwrap();
        // Eight places on six motors: a real loss, reported, and larger than the fit.
        assert!(tact.fidelity.rms_fs > tact.fidelity.fit_rms_fs);
        assert!(matches!(
            played.signal(Pick::Channel(8)),
            Err(ExportError::NoSuchChannel(8))
        ));
    }

    #[test]
    fn the_polyline_stays_within_its_tolerance_and_is_sparse_on_lines() {
        let samples: Vec<f64> = (0..5000)
            .map(|t| (t as f64 / 700.0).sin() * 0.8 + if t > 2500 { 0.1 } else { 0.0 })
            .collect();
        let tol = 0.001;
        let points = fit_polyline(&samples, tol);
        assert_eq!(points.first().map(|p| p.0), Some(0));
        assert_eq!(points.last().map(|p| p.0), Some(samples.len() - 1));
        assert!(points.windows(2).all(|w| w[0].0 < w[1].0));
        let mut hint = 0;
        for (t, s) in samples.iter().enumerate() {
            let v = polyline_at(&points, t, &mut hint);
            assert!((v - s).abs() <= tol * (1.0 + 1e-9), "tick {t}: {v} vs {s}");
        }
        assert!(points.len() < 200, "{} points", points.len());
        let line: Vec<f64> = (0..1000).map(|t| 0.001 * t as f64).collect();
        assert_eq!(fit_polyline(&line, tol).len(), 2);
        assert_eq!(fit_polyline(&[0.5], tol), vec![(0, 0.5)]);
    }
}
