//! `touchc compile REC.npy [-o OUT.touch] [--report report.json]`: the whole chain.
//!
//! `touchc compile A.npy B.npy ... --out-dir DIR` compiles many recordings in parallel
//! into `DIR/<stem>.touch`, with a progress bar and a summary table; a file that fails is
//! reported and the others still compile, and the exit code says whether any failed.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use crate::cli::output::write_atomic;
use crate::cli::params::{OUTPUT, PRESET_AND_KNOBS};
use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use touchc_pipeline::compile::{compile_owned, CompileOptions, Report};

/// What `touchc compile --help` adds after the options.
const AFTER_HELP: &str = "\
Examples:
  touchc compile examples/stroke.npy               writes examples/stroke.touch
  touchc compile rec.npz --report rec.json         the .npz's rate_hz and pitch_mm apply
  touchc compile rec.npy --rate 54 --pitch-mm 25.4 a sensor other than the paper's sleeve
  touchc compile rec.npy --preset paper -o paper.touch
  touchc compile a.npy b.npy c.npz --out-dir stimuli/
  touchc synth stroke -o - | touchc compile - -o stroke.touch

A stimulus lasts longer than its recording (2.9 s longer with the default preset, at
any rate): the 4 Hz low-pass filter rings out after the last frame (1.9 s of it, after
a 50 ms lead) and the current ramps in and out over 0.5 s at each end.";

/// Arguments of `touchc compile`.
#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    /// Recordings: `.npy` float32/float64 `[frames, rows, cols]` in psi (NaN = no cell),
    /// or `.npz` holding such an array as `pressure` (with optional scalars `rate_hz`
    /// and `pitch_mm`); `-` is standard input. Several need `--out-dir`.
    #[arg(required = true)]
    recordings: Vec<PathBuf>,
    /// Algorithm parameters (preset, config file, knobs) and the recordings' sampling.
    #[command(flatten)]
    config: super::params::ConfigArgs,
    /// Stimulus file to write (default: the recording's name with `.touch`; `-`:
    /// standard output); one recording only.
    #[arg(short, long, conflicts_with = "out_dir", help_heading = OUTPUT)]
    output: Option<PathBuf>,
    /// Write `<stem>.touch` for every recording into this directory (created if needed),
    /// compiling them in parallel.
    #[arg(long, help_heading = OUTPUT)]
    out_dir: Option<PathBuf>,
    /// Also write the compile's figures as JSON (with `--out-dir`: `<stem>.json` in the
    /// directory, whatever the name given).
    #[arg(long, help_heading = OUTPUT)]
    report: Option<PathBuf>,
    /// Actuator layout TOML of the sleeve the stimulus is for (default: the paper's
    /// 2 x 4 sleeve).
    #[arg(long, help_heading = OUTPUT)]
    layout: Option<PathBuf>,
    /// Name written into the stimulus (default: the recording's file stem).
    #[arg(long, help_heading = OUTPUT)]
    name: Option<String>,
    /// Scale the signal down to pass the safety limits instead of refusing it.
    #[arg(long, help_heading = OUTPUT)]
    fit: bool,
    /// Run the heavy stages on the whole recording instead of the active scene.
    #[arg(long, help_heading = PRESET_AND_KNOBS)]
    no_crop: bool,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    check_outputs(args)?;
    let config = args.config.resolve()?;
    let layout = super::input::layout(args.layout.as_deref())?;
    let opts = CompileOptions {
        config,
        layout,
        fit: args.fit,
        crop: !args.no_crop,
        metadata: args.config.overrides(),
        // Only the stimulus and the report are written.
        keep_trajectories: false,
        ..CompileOptions::default()
    };
    match (&args.out_dir, args.recordings.as_slice()) {
        (None, [one]) => {
            let out = default_output(args, one)?;
            let r = compile_one(one, &out, args.report.as_deref(), args, &opts)?;
            for w in &r.warnings {
                super::report::warn(one, &super::warning::describe(w));
            }
            // Named as in every message (`-` is standard input or output).
            let (input, output) = (
                PathBuf::from(super::input::input_name(one)),
                PathBuf::from(crate::cli::output::shown(&out)),
            );
            eprintln!(
                "{}",
                super::report::escaped(&summary_line(&input, &output, &r))
            );
            Ok(())
        }
        (None, _) => Err(super::report::usage(format!(
            "{} recordings given: use --out-dir DIR to compile several",
            args.recordings.len()
        ))),
        (Some(dir), recordings) => batch(recordings, dir, args, &opts),
    }
}

/// The stimulus file of a single compile: `-o`, else the recording's name with `.touch`.
fn default_output(args: &Args, recording: &Path) -> anyhow::Result<PathBuf> {
    match &args.output {
        Some(out) => Ok(out.clone()),
        None if crate::cli::output::is_stdio(recording) => Err(super::report::usage(
            "reading the recording from standard input: give -o FILE (or -o - for standard output)",
        )),
        None => Ok(recording.with_extension("touch")),
    }
}

/// Refuses, before any work, outputs that would write over an input (the recordings,
/// the config, the layout) or over each other: `-o`, `--report`, and in a batch every
/// `DIR/<stem>.touch` and `DIR/<stem>.json`.
fn check_outputs(args: &Args) -> anyhow::Result<()> {
    use crate::cli::output::{named, refuse_overwrites};
    let mut inputs: Vec<_> = args
        .recordings
        .iter()
        .map(|r| named("the recording", r))
        .collect();
    inputs.extend(args.config.config.as_deref().map(|p| named("--config", p)));
    inputs.extend(args.layout.as_deref().map(|p| named("--layout", p)));
    match (&args.out_dir, args.recordings.as_slice()) {
        (None, [one]) => {
            let out = default_output(args, one)?;
            let label = if args.output.is_some() {
                "-o"
            } else {
                "the default output"
            };
            let mut outputs = vec![named(label, &out)];
            outputs.extend(args.report.as_deref().map(|p| named("--report", p)));
            refuse_overwrites(&inputs, &outputs)
        }
        (None, _) => Ok(()),
        (Some(dir), recordings) => {
            if recordings.iter().any(|r| crate::cli::output::is_stdio(r)) {
                return Err(super::report::usage(
                    "standard input (-) cannot be part of a batch: compile it alone with -o",
                ));
            }
            check_stems(recordings, dir)?;
            let files: Vec<PathBuf> = recordings
                .iter()
                .flat_map(|r| {
                    let name = stem(r);
                    let report = args
                        .report
                        .as_ref()
                        .map(|_| dir.join(format!("{name}.json")));
                    std::iter::once(dir.join(format!("{name}.touch"))).chain(report)
                })
                .collect();
            let outputs: Vec<_> = files.iter().map(|p| named("the batch output", p)).collect();
            refuse_overwrites(&inputs, &outputs)
        }
    }
}

/// Two inputs with one stem would overwrite each other's output: a usage error.
fn check_stems(recordings: &[PathBuf], dir: &Path) -> anyhow::Result<()> {
    let mut stems: BTreeMap<String, &Path> = BTreeMap::new();
    for r in recordings {
        if let Some(first) = stems.insert(stem(r), r) {
            return Err(super::report::usage(format!(
                "{} and {} would both compile to {}",
                first.display(),
                r.display(),
                dir.join(format!("{}.touch", stem(r))).display()
            )));
        }
    }
    Ok(())
}

/// Compiles `input` into `out` (and the report into `report`).
fn compile_one(
    input: &Path,
    out: &Path,
    report: Option<&Path>,
    args: &Args,
    opts: &CompileOptions,
) -> anyhow::Result<Report> {
    let opts = CompileOptions {
        name: args.name.clone().unwrap_or_else(|| stem(input)),
        ..opts.clone()
    };
    let recording = super::input::load_recording(input)?;
    super::input::check_file_sampling(&recording, &opts.config, &opts.metadata)?;
    let compiled = compile_owned(recording, &opts)
        .with_context(|| format!("{}: cannot compile", input.display()))?;
    // The report first: if it cannot be written, no stimulus appears either.
    if let Some(path) = report {
        let json = serde_json::to_vec_pretty(&super::report_json::ReportJson(&compiled.report))?;
        write_atomic(path, &json)?;
    }
    write_atomic(out, &compiled.stimulus)?;
    Ok(compiled.report)
}

fn summary_line(input: &Path, out: &Path, r: &Report) -> String {
    format!(
        "touchc: {} -> {}: {} frames of {} x {}, {:.2} s of signal, {} bytes ({:.0} B/s), keyframes every {} ms, error {:.3}% RMS / {:.3}% max of full scale, {} of {} trajectories, coverage {:.2}, played {:.2}, {}, {:.1} ms",
        input.display(),
        out.display(),
        r.shape[0],
        r.shape[1],
        r.shape[2],
        r.duration_s,
        r.bytes,
        r.bytes_per_second,
        r.keyframe_period_ms,
        100.0 * r.rms_error_fs,
        100.0 * r.max_error_fs,
        r.selected.len(),
        r.trajectories,
        r.coverage,
        r.rendered_coverage,
        r.metadata.describe(),
        1e3 * r.seconds.total(),
    )
}

/// The batch form: every recording in parallel, one progress bar, one table.
fn batch(
    recordings: &[PathBuf],
    dir: &Path,
    args: &Args,
    opts: &CompileOptions,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("{}: cannot create the output directory", dir.display()))?;
    let bar = ProgressBar::new(recordings.len() as u64);
    if let Ok(style) =
        ProgressStyle::with_template("{bar:40} {pos}/{len} recordings, {elapsed} {wide_msg}")
    {
        bar.set_style(style);
    }
    let warnings = Mutex::new(Vec::new());
    let results: Vec<anyhow::Result<Report>> = recordings
        .par_iter()
        .map(|input| {
            bar.set_message(super::report::escaped(&input.display().to_string()));
            let name = stem(input);
            let out = dir.join(format!("{name}.touch"));
            let report = args
                .report
                .as_ref()
                .map(|_| dir.join(format!("{name}.json")));
            let r = compile_one(input, &out, report.as_deref(), args, opts);
            if let Ok(r) = &r {
                if let Ok(mut w) = warnings.lock() {
                    w.extend(
                        r.warnings
                            .iter()
                            .map(|m| (input.clone(), super::warning::describe(m))),
                    );
                }
            }
            bar.inc(1);
            r
        })
        .collect();
    bar.finish_and_clear();
    for (input, w) in warnings.into_inner().unwrap_or_default() {
        super::report::warn(&input, &w);
    }
    let mut w = crate::cli::output::Output::stdout();
    write_summary(&mut w, recordings, &results)?;
    w.finish()?;
    let failed = results.iter().filter(|r| r.is_err()).count();
    // Every error names its file (the recording, or the output that failed).
    for e in results.iter().filter_map(|r| r.as_ref().err()) {
        super::report::print_error(e);
    }
    anyhow::ensure!(
        failed == 0,
        "{failed} of {} recordings failed to compile",
        recordings.len()
    );
    Ok(())
}

fn write_summary(
    w: &mut impl Write,
    recordings: &[PathBuf],
    results: &[anyhow::Result<Report>],
) -> std::io::Result<()> {
    writeln!(
        w,
        "{:<32} {:>6} {:>8} {:>7} {:>9} {:>9} {:>8} {:>6} {:>9}",
        "recording", "status", "seconds", "bytes", "rms % fs", "tracks", "coverage", "played", "ms"
    )?;
    for (input, r) in recordings.iter().zip(results) {
        let name = super::report::escaped(&input.display().to_string());
        match r {
            Ok(r) => writeln!(
                w,
                "{name:<32} {:>6} {:>8.2} {:>7} {:>9.3} {:>9} {:>8.2} {:>6.2} {:>9.1}",
                "ok",
                r.duration_s,
                r.bytes,
                100.0 * r.rms_error_fs,
                format!("{}/{}", r.selected.len(), r.trajectories),
                r.coverage,
                r.rendered_coverage,
                1e3 * r.seconds.total()
            )?,
            Err(_) => writeln!(w, "{name:<32} {:>6}", "FAILED")?,
        }
    }
    Ok(())
}

/// The file stem as a name ("love.npy" -> "love"; standard input is "stdin").
fn stem(path: &Path) -> String {
    if crate::cli::output::is_stdio(path) {
        return "stdin".into();
    }
    path.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "touch".into())
}
