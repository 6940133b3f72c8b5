//! Stimulus size of every recording the project ships or its tests compile: a table of
//! bytes per second under `touch` and `paper` with `--fit`, and the worst case (issue 16
//! asks for every one at <= 150 B/s at the unchanged fidelity bounds).
//!
//! ```text
//! cargo run --release -p touchc --example sizes                 # the table
//! cargo run --release -p touchc --example sizes -- --dump DIR   # and keep each signal
//! cargo run --release -p touchc --example sizes -- --encode DIR # re-encode kept signals
//! cargo run --release -p touchc --example sizes -- --input F.npy # F (repeatable) only
//! ```
//!
//! The recordings: the shipped examples (`examples/*.npy`, `examples/emoji/*.npy`), the
//! reference recordings (`tests/data/reference/*.npy`), the benches' synthetic scenes
//! (`moving_blobs(705, 4, 42)` of the track bench and `scale`, and the 698-frame
//! combination of the compile bench), every case of `host/tests/it/touch.rs` (both
//! sensors, both seeds), and the synthetic scenes `compile.rs`, `knobs.rs`,
//! `cli_sanity.rs` and `poisoned.rs` compile. Each compiles on one rayon thread.
//!
//! `--dump DIR` writes each case's 1 kHz signal (after the fit) to `DIR`; `--encode DIR`
//! then runs stage 7 alone on those signals, so a change to the encoder is measured in
//! seconds, and prints the CPU seconds stage 7 took in all (the compile's other stages
//! do not change the signal it is given).

use std::path::{Path, PathBuf};

use touchc_testkit as common;

use ndarray::Array3;
use touch_protocol::{Limits, CHANNELS};
use touchc_encoding::keyframes::{encode, HeaderFields, KeyframeOptions};
use touchc_input::recording::Recording;
use touchc_model::config::{Config, MetadataOverrides, Preset, ValidConfig};
use touchc_pipeline::compile::{compile, stimulus_name, CompileOptions};
use touchc_synth::{self as synth, Gesture, Sensor, SynthSpec};

/// One recording: its name, its frames and the sensor's rate and pitch when they are
/// not the paper's (a synthetic 10 x 10 grid).
struct Input {
    name: String,
    data: Array3<f64>,
    metadata: MetadataOverrides,
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir_after = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .map(PathBuf::from)
    };
    if let Some(dir) = dir_after("--encode") {
        return encode_kept(&dir);
    }
    let dump = dir_after("--dump");
    if let Some(d) = &dump {
        std::fs::create_dir_all(d)?;
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build_global()?;
    let mut index = String::new();
    let mut rows = Vec::new();
    println!("| recording | preset | s | bytes | B/s | period ms | shift | tolerance % FS | RMS % FS | max % FS |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    // `--input PATH` (repeatable): those recordings instead of the table's.
    let given: Vec<PathBuf> = args
        .windows(2)
        .filter(|w| w[0] == "--input")
        .map(|w| PathBuf::from(&w[1]))
        .collect();
    let inputs = if given.is_empty() {
        inputs()?
    } else {
        given
            .iter()
            .map(|p| load(p, &p.to_string_lossy()))
            .collect::<anyhow::Result<_>>()?
    };
    for (i, input) in inputs.into_iter().enumerate() {
        let rec = Recording::from_array(input.name.clone(), input.data.view())?;
        for preset in [Preset::Touch, Preset::Paper] {
            let opts = CompileOptions {
                config: ValidConfig::preset(preset),
                fit: true,
                metadata: input.metadata,
                ..CompileOptions::default()
            };
            let c = compile(&rec, &opts)?;
            let r = &c.report;
            println!(
                "| {} | `{}` | {:.1} | {} | {:.0} | {} | {} | {:.3} | {:.3} | {:.3} |",
                input.name,
                preset.name(),
                r.duration_s,
                r.bytes,
                r.bytes_per_second,
                r.keyframe_period_ms,
                r.quant_shift,
                100.0 * r.line_tolerance_fs,
                100.0 * r.rms_error_fs,
                100.0 * r.max_error_fs
            );
            rows.push((
                format!("{} `{}`", input.name, preset.name()),
                r.bytes_per_second,
            ));
            if let Some(d) = &dump {
                let file = format!("{i:03}-{}.f64", preset.name());
                let raw: Vec<u8> = c
                    .signal
                    .iter()
                    .flatten()
                    .flat_map(|v| v.to_le_bytes())
                    .collect();
                std::fs::write(d.join(&file), raw)?;
                index.push_str(&format!("{file}\t{}\t{}\n", input.name, preset.name()));
            }
        }
    }
    if let Some(d) = &dump {
        std::fs::write(d.join("index.tsv"), index)?;
    }
    summary(&rows);
    Ok(())
}

/// The worst case and the mean.
fn summary(rows: &[(String, f64)]) {
    let worst = rows.iter().max_by(|a, b| a.1.total_cmp(&b.1));
    let mean = rows.iter().map(|r| r.1).sum::<f64>() / rows.len().max(1) as f64;
    if let Some((what, bps)) = worst {
        println!(
            "\n{} stimuli; worst {bps:.1} B/s ({what}); mean {mean:.1} B/s",
            rows.len()
        );
    }
}

/// Stage 7 alone on the signals `--dump` kept: B/s of each and the CPU seconds in all.
fn encode_kept(dir: &Path) -> anyhow::Result<()> {
    let index = std::fs::read_to_string(dir.join("index.tsv"))?;
    let mut rows = Vec::new();
    let (mut cpu, mut total_bytes) = (0.0, 0usize);
    for line in index.lines() {
        let mut f = line.split('\t');
        let (Some(file), Some(name), Some(preset)) = (f.next(), f.next(), f.next()) else {
            continue;
        };
        let raw = std::fs::read(dir.join(file))?;
        let values: Vec<f64> = raw
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().unwrap_or([0; 8])))
            .collect();
        let signal: Vec<[f64; CHANNELS]> = values
            .chunks_exact(CHANNELS)
            .map(|c| std::array::from_fn(|i| c[i]))
            .collect();
        let config = Config::preset(if preset == "paper" {
            Preset::Paper
        } else {
            Preset::Touch
        });
        let fields = HeaderFields {
            name: stimulus_name("touch"),
            layout_hash: touch_protocol::layout::SLEEVE_HASH,
            layout: touch_protocol::layout::SLEEVE_NAME,
            limits: Limits::SLEEVE,
        };
        let start = common::cpu_seconds();
        let e = encode(&signal, fields, &KeyframeOptions::new(&config.keyframes))?;
        cpu += common::cpu_seconds() - start;
        let s = signal.len().saturating_sub(1) as f64 / 1000.0;
        let bps = if s > 0.0 {
            e.bytes.len() as f64 / s
        } else {
            0.0
        };
        total_bytes += e.bytes.len();
        println!(
            "| {name} | `{preset}` | {s:.1} | {} | {bps:.0} | {} | {} | {:.3} | {:.3} | {:.3} |",
            e.bytes.len(),
            e.period_ms,
            e.quant_shift,
            100.0 * e.tolerance_fs,
            100.0 * e.rms_error_fs,
            100.0 * e.max_error_fs
        );
        rows.push((format!("{name} `{preset}`"), bps));
    }
    summary(&rows);
    println!("{total_bytes} bytes in all; stage 7 {cpu:.3} CPU s in all");
    Ok(())
}

/// Every recording of the table, in order.
fn inputs() -> anyhow::Result<Vec<Input>> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut out = Vec::new();
    for dir in ["examples", "examples/emoji", "tests/data/reference"] {
        let mut files: Vec<PathBuf> = std::fs::read_dir(root.join(dir))?
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "npy"))
            .collect();
        files.sort();
        for path in files {
            let file = path
                .file_name()
                .map_or(String::new(), |f| f.to_string_lossy().into_owned());
            out.push(load(&path, &format!("{dir}/{file}"))?);
        }
    }
    let paper = MetadataOverrides::default();
    let plain = |name: String, data| Input {
        name,
        data,
        metadata: paper,
    };
    out.push(plain(
        "bench: moving_blobs(705, 4, 42)".into(),
        common::moving_blobs(705, 4, 42),
    ));
    out.push(plain(
        "bench: combination 698".into(),
        common::combination_698(),
    ));
    // The synthetic scenes the integration tests compile (tracking-only tests aside).
    for (frames, blobs, seed, test) in [
        (100, 1, 6, "cli_sanity"),
        (100, 1, 5, "knobs"),
        (80, 1, 1, "poisoned"),
        (80, 1, 2, "poisoned"),
    ] {
        out.push(plain(
            format!("{test}: moving_blobs({frames}, {blobs}, {seed})"),
            common::moving_blobs(frames, blobs, seed),
        ));
    }
    use Gesture::*;
    let compile_rs: [(&[Gesture], u64); 9] = [
        (&[Stroke], 7),
        (&[Stroke], 8),
        (&[Stroke], 9),
        (&[Squeeze], 3),
        (&[Tap, Pat], 11),
        (&[Squeeze, Shake], 3),
        (&[Stroke, Pat, Squeeze], 9),
        (&[Stroke], 4),
        (&[], 1),
    ];
    for (gestures, seed) in compile_rs {
        let spec = SynthSpec {
            gestures: gestures.to_vec(),
            seed,
            ..SynthSpec::default()
        };
        out.push(plain(
            format!("compile: {gestures:?} seed {seed}"),
            synth::generate(&spec),
        ));
    }
    for sensor in [Sensor::Sleeve, Sensor::Grid10] {
        for (name, spec) in common::touch_cases(sensor) {
            for seed in [1, 2] {
                let (data, truth) = synth::generate_with_truth(&SynthSpec {
                    seed,
                    ..spec.clone()
                });
                out.push(Input {
                    name: format!("touch: {} {name} seed {seed}", sensor.name()),
                    data,
                    metadata: MetadataOverrides {
                        rate_hz: Some(truth.rate_hz),
                        pitch_mm: Some(truth.pitch_mm),
                    },
                });
            }
        }
    }
    Ok(out)
}

/// A recording file, at the paper's rate and pitch.
fn load(path: &Path, name: &str) -> anyhow::Result<Input> {
    Ok(Input {
        name: name.to_string(),
        data: Recording::load(path)?.data().to_owned(),
        metadata: MetadataOverrides::default(),
    })
}
