//! The scorers' trade on a synthetic benchmark, printed as a table: k-fold
//! cross-validation of recordings of the paper's size, each scorer on the same folds.
//!
//! `cargo run --release -p touchc-select --example trade -- [RECORDINGS] [FRAMES]
//! [FOLDS] [EPOCHS] [SCORERS] [realistic|separable|gestures]`; the benchmark of
//! `docs/select.md` is `RAYON_NUM_THREADS=2 ... -- 700 705 5 30 features,cnn`.
//! `gestures` is the seven-gesture set on the 10 x 10 grid at 54 Hz (the sleeve
//! otherwise).

use std::sync::atomic::AtomicBool;
use std::time::Instant;

use touchc_select::model::Settings;
use touchc_select::synthetic::{dataset, Mix, SetSpec};
use touchc_select::{cross_validate, Control, Folds, ScorerKind};
use touchc_synth::Sensor;

/// This process's CPU seconds (user + system) from `/proc/self/stat`: a figure a
/// loaded machine does not inflate as it does the wall clock (NaN off Linux).
fn cpu_s() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return f64::NAN;
    };
    // Fields after the command's closing parenthesis; utime and stime are 14 and 15.
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<f64> = rest
        .split_whitespace()
        .filter_map(|v| v.parse().ok())
        .collect();
    // `rest` starts at field 3 (the state, not a number), so field n is f[n - 4].
    match (f.get(10), f.get(11)) {
        (Some(u), Some(s)) => (u + s) / 100.0,
        _ => f64::NAN,
    }
}

/// The machine's one-minute load average (`/proc/loadavg`; "?" off Linux): on a shared
/// machine it says how far the wall-clock columns are inflated.
fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|l| l.split_whitespace().next().map(str::to_string))
        .unwrap_or_else(|| "?".into())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let num = |i: usize, default: usize| -> Result<usize, Box<dyn std::error::Error>> {
        Ok(args
            .get(i)
            .map(|s| s.parse())
            .transpose()?
            .unwrap_or(default))
    };
    let (recordings, frames, k, epochs) = (num(0, 700)?, num(1, 705)?, num(2, 5)?, num(3, 30)?);
    let scorers = args.get(4).map_or("features,cnn", String::as_str);
    let mix = match args.get(5).map_or("realistic", String::as_str) {
        "realistic" => Mix::Realistic,
        "separable" => Mix::Separable,
        "gestures" => Mix::Gestures,
        other => {
            return Err(format!("unknown mix {other}: realistic, separable or gestures").into())
        }
    };
    let sensor = match mix {
        Mix::Gestures => Sensor::Grid10,
        Mix::Realistic | Mix::Separable => Sensor::Sleeve,
    };
    let classes = mix.classes().len();
    let t0 = Instant::now();
    let mut data = dataset(&SetSpec {
        classes,
        per_class: recordings.div_ceil(classes),
        people: 10,
        sensor,
        frames: Some(frames),
        mix,
        seed: 1,
    });
    data.samples.truncate(recordings);
    data.listing.items.truncate(recordings);
    let groups = data.groups();
    let folds = Folds::new(&data.labels(), groups.as_deref(), k, 1)?;
    println!(
        "{} recordings of {:?}, {} classes ({mix:?}), {k} folds keeping each of 10 people whole, {} threads (generated in {:.1} s, load average {})",
        data.samples.len(),
        data.samples[0].frames.dim(),
        data.listing.classes.len(),
        rayon::current_num_threads(),
        t0.elapsed().as_secs_f64(),
        load()
    );
    println!("| scorer | accuracy | macro-F1 | train s | score s | total s | CPU s |");
    println!("|---|---|---|---|---|---|---|");
    for name in scorers.split(',') {
        let kind = match name {
            "features" => ScorerKind::Features,
            "cnn" => ScorerKind::Cnn,
            other => return Err(format!("unknown scorer {other}").into()),
        };
        let cancel = AtomicBool::new(false);
        let progress = |p: touchc_select::Progress| {
            eprint!(
                "\r{name} fold {:?} network {}/{} epoch {}/{} loss {:.4}   ",
                p.fold, p.network, p.networks, p.epoch, p.epochs, p.loss
            )
        };
        let control = Control {
            cancel: &cancel,
            progress: &progress,
        };
        let (t, cpu) = (Instant::now(), cpu_s());
        let s = cross_validate(
            &data,
            &Settings {
                kind,
                seed: 1,
                epochs,
            },
            &folds,
            &control,
        )?;
        eprintln!();
        println!(
            "| {name} | {:.3} | {:.3} | {:.1} | {:.1} | {:.1} | {:.1} |",
            s.metrics.accuracy,
            s.metrics.macro_f1,
            s.train_s,
            s.score_s,
            t.elapsed().as_secs_f64(),
            cpu_s() - cpu
        );
    }
    println!("load average at the end: {}", load());
    Ok(())
}
