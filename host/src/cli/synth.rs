//! `touchc synth KIND... -o rec.npy`: a seeded synthetic recording.

use std::path::PathBuf;

use anyhow::Context;
use touchc::output::write_atomic;
use touchc::synth::{self, Gesture, Mask, SynthSpec};

/// Arguments of `touchc synth`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Gestures, played one after another (several make a combination).
    #[arg(required = true, value_enum)]
    gestures: Vec<Gesture>,
    /// Seed of the random generator: the same arguments give the same file.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Sleeve outline (NaN outside it).
    #[arg(long, value_enum, default_value = "cells142")]
    mask: Mask,
    /// Sensor noise, psi (standard deviation).
    #[arg(long, default_value_t = 0.004)]
    noise: f64,
    /// Noise-only frames before and after the gestures.
    #[arg(long, default_value_t = 30)]
    quiet_frames: usize,
    /// The `.npy` file to write (`-`: standard output).
    #[arg(short, long)]
    output: PathBuf,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.noise.is_finite() && args.noise >= 0.0,
        "--noise must be a finite, non-negative psi value"
    );
    let spec = SynthSpec {
        gestures: args.gestures.clone(),
        seed: args.seed,
        mask: args.mask,
        noise_psi: args.noise,
        quiet_frames: args.quiet_frames,
    };
    let recording = synth::generate(&spec);
    let bytes = synth::to_npy(&recording)
        .with_context(|| format!("{}: cannot encode the recording", args.output.display()))?;
    write_atomic(&args.output, &bytes)?;
    eprintln!(
        "touchc: wrote {} ({} frames of {}x{})",
        super::escaped(&touchc::output::shown(&args.output)),
        recording.shape()[0],
        synth::ROWS,
        synth::COLS
    );
    Ok(())
}
