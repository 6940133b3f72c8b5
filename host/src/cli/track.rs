//! `touchc track REC.npy [--json]`: stages 0-3 on one recording.

use std::io::Write;
use std::path::PathBuf;

use serde::Serialize;
use touchc_input::recording::Recording;
use touchc_model::trajectory::Columns;
use touchc_pipeline::track::track_streaming;
use touchc_tracking::track::TrackOutput;

/// Arguments of `touchc track`.
#[derive(Debug, clap::Args)]
pub struct TrackArgs {
    /// Recording: `.npy` float32/float64 `[frames, rows, cols]` in psi (NaN = no cell), or
    /// `.npz` holding it as `pressure`; `-` is standard input.
    pub recording: PathBuf,
    /// Print machine-readable JSON (the reference vectors' fields) instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Where to write (`-`: standard output).
    #[arg(short, long, default_value = "-")]
    pub output: PathBuf,
    /// Algorithm parameters (preset, config file, knobs) and the recording's sampling.
    #[command(flatten)]
    pub config: super::params::ConfigArgs,
}

/// The JSON document: global statistics and trajectories in report order.
#[derive(Debug, Serialize)]
struct Report {
    mean: f64,
    std: f64,
    trajectories: Vec<TrajectoryReport>,
}

/// A trajectory in the published code's JSON: parallel arrays and the total cost.
#[derive(Debug, Serialize)]
struct TrajectoryReport {
    frames: Vec<usize>,
    rows: Vec<usize>,
    cols: Vec<usize>,
    costs: Vec<f64>,
    total_cost: f64,
}

/// Runs the subcommand.
pub fn run(args: &TrackArgs) -> anyhow::Result<()> {
    {
        use crate::cli::output::{named, refuse_overwrites};
        let mut inputs = vec![named("the recording", args.recording.as_path())];
        inputs.extend(args.config.config.as_deref().map(|p| named("--config", p)));
        refuse_overwrites(&inputs, &[named("-o", &args.output)])?;
    }
    let cfg = args.config.resolve()?;
    let rec = super::input::load_recording(&args.recording)?;
    super::input::check_file_sampling(&rec, &cfg, &args.config.overrides())?;
    // Streaming, as the compile does: neither the blurred movie nor the detections are
    // printed, so neither is kept.
    let out = track_streaming(&rec, &cfg, &args.config.overrides())?;
    let mut w = crate::cli::output::Output::create(&args.output)?;
    if args.json {
        serde_json::to_writer(&mut w, &report(&out))?;
        writeln!(w)?;
    } else {
        write_table(&mut w, &rec, &out)?;
    }
    w.finish()?;
    Ok(())
}

fn report(out: &TrackOutput) -> Report {
    Report {
        mean: out.mean(),
        std: out.std(),
        trajectories: out
            .trajectories
            .iter()
            .map(|t| {
                let c = Columns::from(t);
                TrajectoryReport {
                    frames: c.frames,
                    rows: c.rows,
                    cols: c.cols,
                    costs: c.costs,
                    total_cost: t.total_cost(),
                }
            })
            .collect(),
    }
}

fn write_table(w: &mut impl Write, rec: &Recording, out: &TrackOutput) -> std::io::Result<()> {
    let (t, r, c) = rec.dim();
    writeln!(
        w,
        "{}: {t} frames of {r} x {c} cells",
        super::report::escaped(rec.name())
    )?;
    writeln!(
        w,
        "blurred mean {:.6} psi, std {:.6} psi, {} detections, {} trajectories",
        out.mean(),
        out.std(),
        out.detection_count,
        out.trajectories.len()
    )?;
    writeln!(
        w,
        "{:>3}  {:>11}  {:>4}  {:>12}  {:>12}  {:>10}",
        "#", "frames", "len", "start r,c px", "end r,c px", "cost"
    )?;
    for (i, tr) in out.trajectories.iter().enumerate() {
        let (Some(first), Some(last)) = (tr.points.first(), tr.points.last()) else {
            continue;
        };
        let (f0, f1) = (first.frame, last.frame);
        let start = format!("{},{}", first.row, first.col);
        let end = format!("{},{}", last.row, last.col);
        writeln!(
            w,
            "{i:>3}  {:>11}  {:>4}  {start:>12}  {end:>12}  {:>10.4}",
            format!("{f0}-{f1}"),
            tr.len(),
            tr.total_cost()
        )?;
    }
    Ok(())
}
