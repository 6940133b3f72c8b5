//! How compile cost grows with the recording: time, peak memory and stimulus size of
//! a whole compile, from a short recording to an hour of touch.
//!
//! ```text
//! cargo run --release -p touchc --example scale            # the table (about a minute)
//! cargo run --release -p touchc --example scale -- --quick # without the hour
//! ```
//!
//! Each case runs in its own process (this program, started again with `--case`), so
//! that its peak resident memory (Linux `VmHWM`) is its own. Long recordings are the
//! shipped `examples/combination.npy` (252 frames of 8 x 21 at 20 Hz, 12.6 s) repeated
//! end to end: 29 times is 6.1 minutes, 286 times an hour. Every case compiles with
//! `--fit` (an hour of dense touch exceeds the coil's thermal budget unscaled) on one
//! rayon thread; times are CPU seconds of the compile call (best of `repeat`), so a
//! machine shared with other work still gives comparable figures.

use std::path::{Path, PathBuf};
use std::process::Command;

use touchc_testkit as common;

use touchc_input::recording::Recording;
use touchc_model::config::{Preset, ValidConfig};
use touchc_pipeline::compile::{compile, compile_owned, CompileOptions};

/// One case: a recording (the shipped example repeated, or the bench's synthetic one)
/// under one preset.
struct Case {
    what: &'static str,
    repeat: usize,
    preset: Preset,
    runs: usize,
}

const CASES: [Case; 6] = [
    Case {
        what: "synthetic 705 frames (the criterion bench's)",
        repeat: 0,
        preset: Preset::Paper,
        runs: 5,
    },
    Case {
        what: "combination.npy, 252 frames",
        repeat: 1,
        preset: Preset::Touch,
        runs: 5,
    },
    Case {
        what: "combination x29, 7,308 frames (6.1 min)",
        repeat: 29,
        preset: Preset::Paper,
        runs: 1,
    },
    Case {
        what: "combination x29, 7,308 frames (6.1 min)",
        repeat: 29,
        preset: Preset::Touch,
        runs: 1,
    },
    Case {
        what: "combination x286, 72,072 frames (1 h)",
        repeat: 286,
        preset: Preset::Paper,
        runs: 1,
    },
    Case {
        what: "combination x286, 72,072 frames (1 h)",
        repeat: 286,
        preset: Preset::Touch,
        runs: 1,
    },
];

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let Some(i) = args.iter().position(|a| a == "--case") {
        let index: usize = args.get(i + 1).map_or(Ok(usize::MAX), |v| v.parse())?;
        let case = CASES
            .get(index)
            .ok_or_else(|| anyhow::anyhow!("no case {index}"))?;
        return run_case(case);
    }
    let quick = args.iter().any(|a| a == "--quick");
    println!(
        "| input | preset | CPU s | peak RSS MB | B/s | trajectories | coverage | fit scale |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let me = std::env::current_exe()?;
    for (i, case) in CASES.iter().enumerate() {
        if quick && case.repeat > 100 {
            continue;
        }
        let out = Command::new(&me)
            .args(["--case", &i.to_string()])
            .output()?;
        if !out.status.success() {
            anyhow::bail!(
                "case {i} ({} {}) failed: {}",
                case.what,
                case.preset.name(),
                String::from_utf8_lossy(&out.stderr)
            );
        }
        print!("{}", String::from_utf8_lossy(&out.stdout));
    }
    Ok(())
}

fn run_case(case: &Case) -> anyhow::Result<()> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global()?;
    let rec = recording(case.repeat)?;
    let opts = CompileOptions {
        config: ValidConfig::preset(case.preset),
        fit: true,
        ..CompileOptions::default()
    };
    let mut best = f64::INFINITY;
    for _ in 1..case.runs {
        let start = common::cpu_seconds();
        compile(&rec, &opts)?;
        best = best.min(common::cpu_seconds() - start);
    }
    // The last run as the CLI compiles: handing the recording over.
    let start = common::cpu_seconds();
    let last = compile_owned(rec, &opts)?;
    best = best.min(common::cpu_seconds() - start);
    let report = last.report;
    println!(
        "| {} | `{}` | {:.3} | {} | {:.0} | {} | {:.2} | {:.3} |",
        case.what,
        case.preset.name(),
        best,
        peak_rss_mb().map_or_else(|| "n/a".into(), |mb| format!("{mb:.0}")),
        report.bytes_per_second,
        report.trajectories,
        report.coverage,
        report.fit_scale,
    );
    Ok(())
}

/// The shipped combination example `repeat` times end to end; 0 for the criterion
/// bench's synthetic 705-frame recording.
fn recording(repeat: usize) -> anyhow::Result<Recording> {
    if repeat == 0 {
        return Ok(Recording::from_array(
            "synthetic 705",
            common::moving_blobs(705, 4, 42).view(),
        )?);
    }
    let path: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/combination.npy");
    let one = Recording::load(&path)?;
    let copies: Vec<_> = (0..repeat).map(|_| one.data()).collect();
    let long = ndarray::concatenate(ndarray::Axis(0), &copies)?;
    Ok(Recording::from_array(
        format!("combination x{repeat}"),
        long.view(),
    )?)
}

/// This process's peak resident memory, MB (Linux `VmHWM`).
fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}
