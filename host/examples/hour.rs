//! An hour of real-like touch compiled under `paper` and `touch`: wall and CPU seconds,
//! peak memory, size and trajectories, and `touch`'s ratio to `paper`, in one run.
//!
//! ```text
//! cargo run --release -p touchc --example hour                # two threads, the hour
//! cargo run --release -p touchc --example hour -- --threads 1 --minutes 10
//! ```
//!
//! The hour is the real-like cases of `touchc trade --cases` on the paper's sleeve at
//! 20 Hz (`touchc_synth::cases::real_like_on`: a held hand, a rub, pats, strokes, 15
//! strokes, a tickle and a scratch through a fabric grid, and strokes through fur),
//! drawn with seed after seed and laid end to end until they last the hour: real
//! touch's flicker, several maxima per hand and contacts that come and go, where
//! `scale`'s hour repeats one smooth recording. Each preset compiles in its own process
//! (this program, started again with `--preset`), so that its peak resident memory
//! (Linux `VmHWM`) is its own; both compile with `--fit` (an hour of touch exceeds the
//! coil's thermal budget unscaled) on a rayon pool of `--threads` threads, and as
//! `touchc compile` compiles: the process's allocator setting (`touchc::memory`), the
//! recording handed over (freed once tared) and only the stimulus and the report kept.
//! The hour is drawn into one array and copied once into the recording (97 MB each,
//! both freed before the compile's peak, the 1 kHz signal); the compile's four slowest
//! stages follow.

use std::process::Command;
use std::time::Instant;

use touchc_input::recording::Recording;
use touchc_model::config::{Preset, ValidConfig};
use touchc_model::stage::Stage;
use touchc_pipeline::compile::{compile_owned, CompileOptions, Warning};
use touchc_synth::cases::real_like_on;
use touchc_synth::{generate_with_truth, Sensor, SynthSpec};
use touchc_testkit as common;

/// The rate of the hour, Hz: the paper's sleeve.
const RATE_HZ: f64 = 20.0;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str, default: usize| -> anyhow::Result<usize> {
        match args.iter().position(|a| a == flag) {
            Some(i) => Ok(args
                .get(i + 1)
                .ok_or_else(|| anyhow::anyhow!("{flag} needs a value"))?
                .parse()?),
            None => Ok(default),
        }
    };
    let threads = value("--threads", 2)?;
    let minutes = value("--minutes", 60)?;
    if let Some(i) = args.iter().position(|a| a == "--preset") {
        let preset = match args.get(i + 1).map(String::as_str) {
            Some("paper") => Preset::Paper,
            Some("touch") => Preset::Touch,
            other => anyhow::bail!("--preset paper or touch, not {other:?}"),
        };
        return run(preset, threads, minutes);
    }
    println!(
        "| preset | frames | wall s | CPU s | peak RSS MB | B/s | trajectories | coverage | played | fit (refits) | largest stages, wall s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    let me = std::env::current_exe()?;
    let mut walls = Vec::new();
    for preset in ["paper", "touch"] {
        let out = Command::new(&me)
            .args(["--preset", preset])
            .args(["--threads", &threads.to_string()])
            .args(["--minutes", &minutes.to_string()])
            .output()?;
        if !out.status.success() {
            anyhow::bail!("{preset}: {}", String::from_utf8_lossy(&out.stderr));
        }
        let line = String::from_utf8_lossy(&out.stdout).to_string();
        // The wall seconds are the row's third cell.
        let wall: f64 = line
            .split('|')
            .nth(3)
            .and_then(|c| c.trim().parse().ok())
            .unwrap_or(f64::NAN);
        walls.push(wall);
        print!("{line}");
    }
    println!(
        "\n`touch` takes {:.2} times `paper`'s wall time ({threads} threads, {minutes} min of touch).",
        walls[1] / walls[0]
    );
    Ok(())
}

/// Compiles the hour under `preset` on `threads` threads and prints its row.
fn run(preset: Preset, threads: usize, minutes: usize) -> anyhow::Result<()> {
    // As `touchc` does: freed large blocks go back to the system.
    touchc::memory::return_freed_memory();
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global()?;
    let rec = real_like(minutes)?;
    let frames = rec.data().dim().0;
    let opts = CompileOptions {
        config: ValidConfig::preset(preset),
        fit: true,
        // As `touchc compile`: the stimulus and the report, not the trajectories.
        keep_trajectories: false,
        metadata: touchc_model::config::MetadataOverrides {
            rate_hz: Some(RATE_HZ),
            pitch_mm: Some(25.4),
        },
        ..CompileOptions::default()
    };
    let (wall, cpu) = (Instant::now(), common::cpu_seconds());
    let compiled = compile_owned(rec, &opts)?;
    let (wall, cpu) = (wall.elapsed().as_secs_f64(), common::cpu_seconds() - cpu);
    let r = compiled.report;
    let mut stages: Vec<(Stage, f64)> = r
        .seconds
        .iter()
        .filter(|(s, _)| *s != Stage::Total)
        .collect();
    stages.sort_by(|a, b| b.1.total_cmp(&a.1));
    let stages: Vec<String> = stages
        .iter()
        .take(4)
        .map(|(s, t)| format!("{} {t:.2}", s.name()))
        .collect();
    // A fitted signal whose played codes still trip a limit is encoded again, 1%
    // quieter: each refit is a second stage 7.
    let refits = r
        .warnings
        .iter()
        .find_map(|w| match w {
            Warning::Fitted { refits, .. } => Some(*refits),
            _ => None,
        })
        .unwrap_or(0);
    println!(
        "| `{}` | {frames} | {wall:.2} | {cpu:.2} | {} | {:.0} | {} | {:.2} | {:.2} | {:.3} ({refits}) | {} |",
        preset.name(),
        peak_rss_mb().map_or_else(|| "n/a".into(), |mb| format!("{mb:.0}")),
        r.bytes_per_second,
        r.trajectories,
        r.coverage,
        r.rendered_coverage,
        r.fit_scale,
        stages.join(", "),
    );
    Ok(())
}

/// The real-like cases on the sleeve at 20 Hz, seed after seed, end to end until they
/// last `minutes`; written into one array as they are drawn, so that the peak memory
/// is the hour's and the compile's, not a second copy of it.
fn real_like(minutes: usize) -> anyhow::Result<Recording> {
    let want = (minutes as f64 * 60.0 * RATE_HZ) as usize;
    let cases = real_like_on(Sensor::Sleeve, RATE_HZ);
    let mut all: Option<ndarray::Array3<f64>> = None;
    let mut at = 0;
    for seed in 1.. {
        for case in &cases {
            if at == want {
                let all = all.ok_or_else(|| anyhow::anyhow!("no touch drawn"))?;
                let name = format!("real-like {minutes} min");
                return Ok(Recording::from_array(name, all.view())?);
            }
            let spec = SynthSpec {
                seed,
                ..case.spec.clone()
            };
            let (data, _) = generate_with_truth(&spec);
            let (_, rows, cols) = data.dim();
            let all = all.get_or_insert_with(|| ndarray::Array3::zeros((want, rows, cols)));
            let n = data.dim().0.min(want - at);
            all.slice_mut(ndarray::s![at..at + n, .., ..])
                .assign(&data.slice(ndarray::s![..n, .., ..]));
            at += n;
        }
    }
    unreachable!("the loop returns once the hour is drawn")
}

/// This process's peak resident memory, MB (Linux `VmHWM`).
fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}
