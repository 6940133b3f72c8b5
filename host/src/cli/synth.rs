//! `touchc synth KIND... -o rec.npy [--truth truth.json]`: a seeded synthetic recording,
//! and where its contacts really were.

use std::path::PathBuf;

use super::help::PlainEnum;
use crate::cli::output::write_atomic;
use anyhow::Context;
use touchc_model::display::Shortest;
use touchc_synth::{self as synth, Fabric, Gesture, Mask, Sensor, SynthSpec, Tuning};

/// Most noise-only frames before and after the gestures: about 1.4 h at 20 Hz, a
/// recording of 130 MB. More would ask for memory no test recording needs.
const MAX_QUIET_FRAMES: usize = 100_000;

/// Arguments of `touchc synth`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Gestures, played one after another (several make a combination; `rest` is two
    /// seconds of sensor noise alone).
    #[arg(required = true, value_parser = PlainEnum::<Gesture>::new())]
    gestures: Vec<Gesture>,
    /// Seed of the random generator: the same arguments give the same file.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// The sensor imitated: `sleeve` (8 x 21 cells, 20 Hz) or `grid10` (10 x 10 cells,
    /// 54 Hz), one-inch cells both.
    #[arg(long, value_parser = PlainEnum::<Sensor>::new(), default_value = "sleeve")]
    sensor: Sensor,
    /// Sleeve outline (NaN outside it; the sleeve only).
    #[arg(long, value_parser = PlainEnum::<Mask>::new(), default_value = "cells142")]
    mask: Mask,
    /// Sensor noise, psi (standard deviation).
    #[arg(long, default_value_t = 0.004)]
    noise: f64,
    /// Noise-only frames before and after the gestures.
    #[arg(long, default_value_t = 30)]
    quiet_frames: usize,
    /// Stroke speed along the arm, m/s (`stroke`, `strokes`).
    #[arg(long)]
    speed: Option<f64>,
    /// Length of each tap, ms (`tap`).
    #[arg(long)]
    tap_ms: Option<f64>,
    /// Shake frequency, Hz (`shake`).
    #[arg(long)]
    shake_hz: Option<f64>,
    /// Shake amplitude across the arm, mm either side (`shake`).
    #[arg(long)]
    shake_mm: Option<f64>,
    /// Time from lift-off to the next touch-down, ms (`strokes`).
    #[arg(long)]
    gap_ms: Option<f64>,
    /// Flicker: dropouts per second while a contact presses fully, each 19-37 ms long
    /// (one or two frames at 54 Hz) at 3% of the contact's pressure.
    #[arg(long, default_value_t = 0.0)]
    flicker: f64,
    /// Begin the recording in the middle of the first contact.
    #[arg(long)]
    begin_mid_touch: bool,
    /// End the recording in the middle of the last contact.
    #[arg(long)]
    end_mid_touch: bool,
    /// Read the touch as a fabric grid does: `bare` (cells of uneven, wandering
    /// sensitivity that each drop out for a frame or two now and then) or `fur` (the
    /// same through fur: spread over more cells, more dropouts).
    #[arg(long, value_parser = ["bare", "fur"])]
    fabric: Option<String>,
    /// Also write where each contact really was, frame by frame (JSON).
    #[arg(long)]
    truth: Option<PathBuf>,
    /// The file to write: a `.npz` (by its extension) carries the sensor's rate and
    /// pitch beside the array; anything else is a `.npy` (`-`: standard output).
    #[arg(short, long)]
    output: PathBuf,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    {
        use crate::cli::output::{named, refuse_overwrites};
        let mut outputs = vec![named("-o", &args.output)];
        outputs.extend(args.truth.as_deref().map(|p| named("--truth", p)));
        refuse_overwrites(&[], &outputs)?;
    }
    check(args)?;
    let spec = spec(args);
    let (recording, truth) = synth::generate_with_truth(&spec);
    let (rate_hz, pitch_mm) = (spec.sensor.rate_hz(), spec.sensor.pitch_mm());
    // A `.npz` carries the sensor's rate and pitch; a `.npy` holds the array alone.
    let npz = args
        .output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npz"));
    let bytes = if npz {
        synth::to_npz(&recording, rate_hz, pitch_mm).map_err(anyhow::Error::from)
    } else {
        synth::to_npy(&recording).map_err(anyhow::Error::from)
    }
    .with_context(|| format!("{}: cannot encode the recording", args.output.display()))?;
    // The truth first: if it cannot be written, no recording appears either.
    if let Some(path) = &args.truth {
        let json = serde_json::to_vec_pretty(&truth)
            .with_context(|| format!("{}: cannot encode the truth", path.display()))?;
        write_atomic(path, &json)?;
    }
    write_atomic(&args.output, &bytes)?;
    report(args, &recording, truth.contacts.len(), npz);
    Ok(())
}

/// Refuses flags out of their range. Every check is on a flag, so every refusal is a
/// usage error (exit status 2).
fn check(args: &Args) -> anyhow::Result<()> {
    let ensure = |ok: bool, message: String| -> anyhow::Result<()> {
        if ok {
            Ok(())
        } else {
            Err(super::report::usage(message))
        }
    };
    ensure(
        args.noise.is_finite() && args.noise >= 0.0,
        format!(
            "--noise must be a finite, non-negative psi value, got {}",
            Shortest(args.noise)
        ),
    )?;
    ensure(
        args.flicker.is_finite() && args.flicker >= 0.0,
        format!(
            "--flicker must be a finite, non-negative rate per second, got {}",
            Shortest(args.flicker)
        ),
    )?;
    ensure(
        args.quiet_frames <= MAX_QUIET_FRAMES,
        format!(
            "--quiet-frames {} is out of range: must be 0 to {MAX_QUIET_FRAMES}",
            args.quiet_frames
        ),
    )?;
    let positive = |name: &str, v: Option<f64>| -> anyhow::Result<()> {
        match v {
            Some(v) => ensure(
                v.is_finite() && v > 0.0,
                format!(
                    "--{name} must be a finite, positive number, got {}",
                    Shortest(v)
                ),
            ),
            None => Ok(()),
        }
    };
    positive("speed", args.speed)?;
    positive("tap-ms", args.tap_ms)?;
    positive("shake-hz", args.shake_hz)?;
    positive("shake-mm", args.shake_mm)?;
    if let Some(g) = args.gap_ms {
        ensure(
            g.is_finite() && g >= 0.0,
            format!(
                "--gap-ms must be a finite, non-negative number, got {}",
                Shortest(g)
            ),
        )?;
    }
    Ok(())
}

/// What the flags ask of the generator.
fn spec(args: &Args) -> SynthSpec {
    SynthSpec {
        gestures: args.gestures.clone(),
        seed: args.seed,
        mask: args.mask,
        noise_psi: args.noise,
        quiet_frames: args.quiet_frames,
        sensor: args.sensor,
        tuning: Tuning {
            stroke_speed_mps: args.speed,
            tap_s: args.tap_ms.map(|ms| ms / 1000.0),
            shake_hz: args.shake_hz,
            shake_amplitude_mm: args.shake_mm,
            gap_s: args.gap_ms.map(|ms| ms / 1000.0),
            ..Tuning::default()
        },
        flicker: args.flicker,
        begin_mid_touch: args.begin_mid_touch,
        end_mid_touch: args.end_mid_touch,
        rate_hz: None,
        fabric: args.fabric.as_deref().map(|f| match f {
            "fur" => Fabric::FUR,
            _ => Fabric::BARE,
        }),
    }
}

/// Says what was written to `args.output`, and the flags a `.npy` of a sensor other than
/// the published sleeve needs to compile as it was made.
fn report(args: &Args, recording: &ndarray::Array3<f64>, contacts: usize, npz: bool) {
    let (rate_hz, pitch_mm) = (args.sensor.rate_hz(), args.sensor.pitch_mm());
    let (frames, rows, cols) = recording.dim();
    eprintln!(
        "touchc: wrote {} ({frames} frames of {rows}x{cols} at {rate_hz} Hz, {} contacts)",
        super::report::escaped(&crate::cli::output::shown(&args.output)),
        contacts
    );
    // What `compile` assumes of a file that does not say (the published sleeve's).
    let assumed = touchc_model::config::InputConfig::default();
    if !npz && (rate_hz != assumed.rate_hz || pitch_mm != assumed.pitch_mm) {
        eprintln!(
            "touchc: note: a .npy holds no rate: compile it with --rate {rate_hz} \
             --pitch-mm {pitch_mm} (or write a .npz, which carries both)"
        );
    }
}
