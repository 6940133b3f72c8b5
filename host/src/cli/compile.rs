//! `touchc compile REC.npy [-o OUT.touch] [--report report.json]`: the whole chain.

use std::path::{Path, PathBuf};

use anyhow::Context;
use touchc::compile::{compile, CompileOptions};
use touchc::layout::Layout;
use touchc::output::write_atomic;
use touchc::recording::Recording;

/// Arguments of `touchc compile`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Recording, `.npy` float32/float64 `[frames, rows, cols]` in psi (NaN = no cell).
    recording: PathBuf,
    /// Stimulus file to write (default: the recording's name with `.touch`).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Also write the compile's figures as JSON.
    #[arg(long)]
    report: Option<PathBuf>,
    /// TOML file overriding the paper's algorithm parameters.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Actuator layout TOML (default: the paper's 2 x 4 sleeve).
    #[arg(long)]
    layout: Option<PathBuf>,
    /// Name written into the stimulus (default: the recording's file stem).
    #[arg(long)]
    name: Option<String>,
    /// Scale the signal down to pass the safety limits instead of refusing it.
    #[arg(long)]
    fit: bool,
    /// Run the heavy stages on the whole recording instead of the active scene.
    #[arg(long)]
    no_crop: bool,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let config = super::load_config(args.config.as_deref())?;
    let layout = match &args.layout {
        Some(path) => Layout::load(path)?,
        None => Layout::paper(),
    };
    let name = args.name.clone().unwrap_or_else(|| stem(&args.recording));
    let opts = CompileOptions {
        config,
        layout,
        fit: args.fit,
        crop: !args.no_crop,
        name,
        ..CompileOptions::default()
    };
    let recording = Recording::load(&args.recording)?;
    let compiled = compile(&recording, &opts)
        .with_context(|| format!("{}: cannot compile", args.recording.display()))?;
    let out = args
        .output
        .clone()
        .unwrap_or_else(|| args.recording.with_extension("touch"));
    let r = &compiled.report;
    // The report first: if it cannot be written, no stimulus appears either.
    if let Some(path) = &args.report {
        let json = serde_json::to_vec_pretty(r)?;
        write_atomic(path, &json)?;
    }
    write_atomic(&out, &compiled.stimulus)?;
    for w in &r.warnings {
        eprintln!("touchc: warning: {}: {w}", args.recording.display());
    }
    eprintln!(
        "touchc: {} -> {}: {:.2} s, {} bytes ({:.0} B/s), keyframes every {} ms, error {:.3}% RMS / {:.3}% max of full scale, {} of {} trajectories, {:.1} ms",
        args.recording.display(),
        out.display(),
        r.duration_s,
        r.bytes,
        r.bytes_per_second,
        r.keyframe_period_ms,
        100.0 * r.rms_error_fs,
        100.0 * r.max_error_fs,
        r.selected.len(),
        r.trajectories,
        1e3 * r.seconds.get("total").copied().unwrap_or(0.0),
    );
    Ok(())
}

/// The file stem as a name ("love.npy" -> "love").
fn stem(path: &Path) -> String {
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "touch".into())
}
