//! `touchc preview REC.npy -o out.gif|png`: the recording as the compiler sees it,
//! frame by frame: blurred pressure, trajectories, workspaces, actuator intensities.

use std::path::PathBuf;

use crate::cli::output::write_atomic;
use anyhow::Context;
use touchc::viz::preview;
use touchc_pipeline::compile::{compile, CompileOptions};

/// Arguments of `touchc preview`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Recording: `.npy` float32/float64 `[frames, rows, cols]` in psi (NaN = no cell), or
    /// `.npz` holding it as `pressure`; `-` is standard input.
    recording: PathBuf,
    /// `.gif` writes the animation; `.png` writes one frame (`--frame`).
    #[arg(short, long)]
    output: PathBuf,
    /// Animate every N-th frame only (smaller files for long recordings).
    #[arg(long, default_value_t = 1)]
    every: usize,
    /// The frame a `.png` shows (after the tare and trim).
    #[arg(long, default_value_t = 0)]
    frame: usize,
    /// Algorithm parameters (preset, config file, knobs) and the recording's sampling.
    #[command(flatten)]
    config: super::params::ConfigArgs,
    /// Actuator layout TOML (default: the paper's 2 x 4 sleeve).
    #[arg(long)]
    layout: Option<PathBuf>,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let ext = args
        .output
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let gif = match ext.as_deref() {
        Some("gif") => true,
        Some("png") => false,
        _ => {
            return Err(super::report::usage(format!(
                "{}: name the output .gif (animation) or .png (one frame)",
                args.output.display()
            )))
        }
    };
    {
        use crate::cli::output::{named, refuse_overwrites};
        let mut inputs = vec![named("the recording", args.recording.as_path())];
        inputs.extend(args.config.config.as_deref().map(|p| named("--config", p)));
        inputs.extend(args.layout.as_deref().map(|p| named("--layout", p)));
        refuse_overwrites(&inputs, &[named("-o", &args.output)])?;
    }
    if args.every == 0 {
        return Err(super::report::usage("--every must be at least 1"));
    }
    let config = args.config.resolve()?;
    let layout = super::input::layout(args.layout.as_deref())?;
    // Whole frames (no crop) so every frame has its blurred map, streamed as the
    // compile does (the preview blurs each frame again as it draws it: an hour's movie
    // is 4.7 GB); scaled to the limits rather than refused, since a preview shows the
    // scene, not the stimulus.
    let opts = CompileOptions {
        config,
        layout,
        fit: true,
        crop: false,
        keep_scene: false,
        metadata: args.config.overrides(),
        ..CompileOptions::default()
    };
    let name = super::input::input_name(&args.recording);
    let recording = super::input::load_recording(&args.recording)?;
    super::input::check_file_sampling(&recording, &opts.config, &opts.metadata)?;
    let compiled = compile(&recording, &opts).with_context(|| format!("{name}: cannot compile"))?;
    let rate = compiled.report.metadata.rate_hz.value;
    for w in &compiled.report.warnings {
        super::report::warn(&args.recording, &super::warning::describe(w));
    }
    let image = if gif {
        preview::gif(&compiled, &recording, args.every, rate)
    } else {
        preview::png_frame(&compiled, &recording, args.frame, rate)
    }
    .with_context(|| format!("{name}: cannot preview"))?;
    write_atomic(&args.output, &image)?;
    Ok(())
}
