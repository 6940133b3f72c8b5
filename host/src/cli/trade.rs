//! `touchc trade REC.npy... [--csv FILE] [--svg FILE]`: every preset on every recording, compared
//! with `exact` (see [`touchc_eval::trade`]).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::cli::output::write_atomic;
use anyhow::Context;
use touchc::viz::trade::plot_svg;
use touchc_eval::cases::{run_case, CaseRow};
use touchc_eval::trade::{trade, TradeRow};
use touchc_model::config::{Preset, ValidConfig};
use touchc_model::stage::Stage;
use touchc_pipeline::compile::CompileOptions;
use touchc_synth::cases::Bar;
use touchc_synth::Truth;

/// Arguments of `touchc trade`.
#[derive(Debug, clap::Args)]
#[command(mut_arg("preset", |a| a.help(
    "Compare only this preset with `exact` [default: every preset]"
)))]
pub struct Args {
    /// Recordings: `.npy` `[frames, rows, cols]` in psi, or `.npz` holding it as
    /// `pressure`; `-` is standard input.
    #[arg(required_unless_present = "cases")]
    recordings: Vec<PathBuf>,
    /// Instead of recordings: the synthetic cases of real touch (a flat hand with a
    /// weaker heel, rubs up to 1 m/s, 15 strokes, 2.5 m/s swipes; then the same touches
    /// and a tickle and a scratch read through a fabric grid) on both sensors at 20
    /// and 54 Hz, each measured
    /// against its truth (recall, merges, splits, false contacts, coverage) under every
    /// preset (`--preset P`: only P).
    #[arg(long, conflicts_with_all = ["recordings", "truth", "svg"])]
    cases: bool,
    /// With `--cases`: draw each case with seeds 1 to this [default: 1].
    #[arg(long)]
    seeds: Option<u64>,
    /// Compile each recording this many times per preset and keep the fastest run.
    #[arg(long, default_value_t = 3)]
    repeat: usize,
    /// Worker threads for the parallel stages (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Also write the table as CSV.
    #[arg(long)]
    csv: Option<PathBuf>,
    /// Also write the rows as JSON (every field, seconds per stage unrounded).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Also draw time against error as SVG.
    #[arg(long)]
    svg: Option<PathBuf>,
    /// Print the table as Markdown (for `docs/trade.md`).
    #[arg(long)]
    markdown: bool,
    /// Where each contact really was (`touchc synth --truth`), one file per recording in
    /// the same order: adds each preset's recall.
    #[arg(long)]
    truth: Vec<PathBuf>,
    /// Parameters laid over every preset (`--preset P`: compare only P with `exact`)
    /// and the recordings' sampling.
    #[command(flatten)]
    config: super::params::ConfigArgs,
}

/// The stages of the table, in pipeline order.
const STAGES: [Stage; 8] = [
    Stage::Preprocess,
    Stage::Detect,
    Stage::Track,
    Stage::Placement,
    Stage::Signals,
    Stage::Condition,
    Stage::Keyframes,
    Stage::Total,
];

pub fn run(args: &Args) -> anyhow::Result<()> {
    refuse_outputs_over_inputs(args)?;
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = args.threads {
        if n == 0 {
            return Err(super::report::usage("--threads must be at least 1"));
        }
        builder = builder.num_threads(n);
    }
    let pool = builder.build().context("cannot start the worker threads")?;
    if args.cases {
        return pool.install(|| run_cases(args));
    }
    // clap counts the unset `--cases` flag as given (its default), so `requires` on
    // `--seeds` would never refuse.
    if args.seeds.is_some() {
        return Err(super::report::usage(
            "--seeds draws the synthetic cases: use it with --cases",
        ));
    }
    let truths = truths(args)?;
    let configs = configs(args)?;
    let mut rows = Vec::new();
    let mut failed = 0;
    for (i, path) in args.recordings.iter().enumerate() {
        let rec = super::input::load_recording(path)?;
        let base = CompileOptions {
            metadata: args.config.overrides(),
            ..CompileOptions::default()
        };
        match pool.install(|| trade(&rec, &base, &configs, args.repeat, truths.get(i))) {
            Ok(r) => rows.extend(r),
            Err(e) => {
                failed += 1;
                super::report::print_error(&anyhow::Error::new(e).context(format!(
                    "{}: cannot compile",
                    super::input::input_name(path)
                )));
            }
        }
    }
    write_outputs(args, &rows)?;
    anyhow::ensure!(failed == 0, "{failed} recordings failed to compile");
    Ok(())
}

/// Refuses an output over an input (or over another output).
fn refuse_outputs_over_inputs(args: &Args) -> anyhow::Result<()> {
    use crate::cli::output::{named, refuse_overwrites};
    let mut inputs: Vec<_> = args
        .recordings
        .iter()
        .map(|p| named("the recording", p))
        .collect();
    inputs.extend(args.truth.iter().map(|p| named("--truth", p)));
    inputs.extend(args.config.config.as_deref().map(|p| named("--config", p)));
    let mut outputs = vec![named("the table", Path::new("-"))];
    outputs.extend(args.csv.as_deref().map(|p| named("--csv", p)));
    outputs.extend(args.json.as_deref().map(|p| named("--json", p)));
    outputs.extend(args.svg.as_deref().map(|p| named("--svg", p)));
    refuse_overwrites(&inputs, &outputs)
}

/// The truth files of `--truth`, one per recording (none without the flag).
fn truths(args: &Args) -> anyhow::Result<Vec<Truth>> {
    if !args.truth.is_empty() && args.truth.len() != args.recordings.len() {
        return Err(super::report::Usage(format!(
            "--truth needs one file per recording: {} recordings, {} truth files",
            args.recordings.len(),
            args.truth.len()
        ))
        .into());
    }
    args.truth
        .iter()
        .map(|p| {
            let text = super::input::read_text(p, super::input::MAX_TEXT_BYTES)
                .with_context(|| format!("{}: cannot read", p.display()))?;
            serde_json::from_str::<Truth>(&text).with_context(|| {
                format!(
                    "{}: not a truth file of `touchc synth --truth`",
                    p.display()
                )
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()
}

/// Each preset compared, with its config: `--preset` and `exact`, or every preset.
fn configs(args: &Args) -> anyhow::Result<Vec<(Preset, ValidConfig)>> {
    let presets: Vec<Preset> = match args.config.preset {
        Some(p) if p != Preset::Exact => vec![p, Preset::Exact],
        Some(p) => vec![p],
        None => Preset::ALL.to_vec(),
    };
    configs_of(args, presets)
}

/// `presets` with their configs. The preset asked for takes every knob; the others
/// (the `exact` reference among them) take those their tables have, and a note says
/// which they do not.
fn configs_of(args: &Args, presets: Vec<Preset>) -> anyhow::Result<Vec<(Preset, ValidConfig)>> {
    let (configs, skipped) = args.config.resolve_presets(&presets)?;
    for line in skipped {
        eprintln!("touchc: note: {line}");
    }
    Ok(configs)
}

/// The table on standard output, and the CSV, JSON and SVG files asked for.
fn write_outputs(args: &Args, rows: &[TradeRow]) -> anyhow::Result<()> {
    let table = if args.markdown {
        markdown(rows)
    } else {
        text(rows)
    };
    write_atomic(std::path::Path::new("-"), table.as_bytes())?;
    for line in far_from_exact(rows) {
        eprintln!("touchc: note: {line}");
    }
    if let Some(path) = &args.csv {
        write_atomic(path, csv(rows).as_bytes())?;
    }
    if let Some(path) = &args.json {
        write_atomic(path, &serde_json::to_vec_pretty(rows)?)?;
    }
    if let Some(path) = &args.svg {
        let svg = plot_svg(rows).with_context(|| format!("{}: cannot draw", path.display()))?;
        write_atomic(path, svg.as_bytes())?;
    }
    Ok(())
}

/// Why a row's signal or tracks are far from `exact`'s, once per kind: a difference
/// past full scale or no tracks in common reads as a fault, and is what a preset that
/// tracks or places otherwise gives.
fn far_from_exact(rows: &[TradeRow]) -> Vec<String> {
    let mut notes = Vec::new();
    // The rows a note is about, as `input under preset`.
    let named = |keep: &dyn Fn(&TradeRow) -> bool| -> Vec<String> {
        rows.iter()
            .filter(|r| keep(r))
            .map(|r| {
                format!(
                    "{} under {}",
                    super::report::escaped(&r.input),
                    r.preset.name()
                )
            })
            .collect()
    };
    let far = named(&|r| r.max_vs_exact_pct > 100.0);
    if !far.is_empty() {
        notes.push(format!(
            "max vs exact over 100% of full scale ({}): the signals are -0.9 A at rest and \
             up to +1 A, so where this preset drives an actuator that exact leaves at rest \
             (or the other way round) they differ by up to 190%",
            far.join(", ")
        ));
    }
    let apart =
        named(&|r| r.tracks_agree_pct == 0.0 && r.preset != touchc_model::config::Preset::Exact);
    if !apart.is_empty() {
        notes.push(format!(
            "tracks agree 0 ({}): no detection is tracked by both this preset and exact, \
             as when one splits a broad contact or links at another speed and the other \
             follows another point of the hand",
            apart.join(", ")
        ));
    }
    notes
}

/// `touchc trade --cases`: every synthetic case under the presets, one row each, and
/// how many rows of each preset pass the bar of [`CaseRow::passes`].
fn run_cases(args: &Args) -> anyhow::Result<()> {
    let seeds = args.seeds.unwrap_or(1);
    if seeds == 0 {
        return Err(super::report::usage("--seeds must be at least 1"));
    }
    let presets: Vec<Preset> = match args.config.preset {
        Some(p) => vec![p],
        None => Preset::ALL.to_vec(),
    };
    let configs = configs_of(args, presets)?;
    let base = CompileOptions::default();
    let mut rows: Vec<CaseRow> = Vec::new();
    for case in touchc_synth::cases::cases() {
        for seed in 1..=seeds {
            rows.extend(run_case(&case, seed, &base, &configs)?);
        }
    }
    let header = [
        "case",
        "sensor",
        "Hz",
        "seed",
        "preset",
        "contacts",
        "trajectories",
        "recall",
        "merges",
        "splits",
        "false",
        "coverage",
        "played",
        "B/s",
        "duration s",
        "ms",
        "passes",
    ]
    .map(String::from)
    .to_vec();
    let line = |r: &CaseRow| -> Vec<String> {
        vec![
            r.case.clone(),
            r.sensor.to_string(),
            format!("{}", r.rate_hz),
            r.seed.to_string(),
            r.preset.name().to_string(),
            r.contacts.to_string(),
            r.trajectories.to_string(),
            format!("{:.2}", r.recall),
            r.merges.to_string(),
            r.splits.to_string(),
            r.false_contacts.to_string(),
            format!("{:.2}", r.coverage),
            format!("{:.2}", r.rendered),
            format!("{:.0}", r.bytes_per_s),
            format!("{:.3}", r.duration_s),
            format!("{:.1}", 1e3 * r.seconds),
            if r.passes() { "yes" } else { "no" }.to_string(),
        ]
    };
    let table: Vec<Vec<String>> = std::iter::once(header.clone())
        .chain(rows.iter().map(line))
        .collect();
    let mut out = if args.markdown {
        let mut s = format!("| {} |\n|", header.join(" | "));
        s += &(0..header.len())
            .map(|i| if i < 5 { "---|" } else { "---:|" })
            .collect::<String>();
        s.push('\n');
        for l in &table[1..] {
            s += &format!("| {} |\n", l.join(" | "));
        }
        s
    } else {
        aligned(&table, 5)
    };
    summarise(&mut out, &rows, &configs);
    write_atomic(Path::new("-"), out.as_bytes())?;
    if let Some(path) = &args.csv {
        let csv: String = table
            .iter()
            .map(|l| l.iter().map(|f| csv_field(f)).collect::<Vec<_>>().join(",") + "\n")
            .collect();
        write_atomic(path, csv.as_bytes())?;
    }
    if let Some(path) = &args.json {
        write_atomic(path, &serde_json::to_vec_pretty(&rows)?)?;
    }
    Ok(())
}

/// One line per preset: how many smooth and how many real-like cases pass their bar.
fn summarise<C>(out: &mut String, rows: &[CaseRow], configs: &[(Preset, C)]) {
    for (preset, _) in configs {
        let of = |real: bool| -> Vec<&CaseRow> {
            rows.iter()
                .filter(|r| r.preset == *preset && matches!(r.bar, Bar::RealLike { .. }) == real)
                .collect()
        };
        let (smooth, real) = (of(false), of(true));
        let passed = |rows: &[&CaseRow]| rows.iter().filter(|r| r.passes()).count();
        let _ = writeln!(
            out,
            "\n{}: {} of {} smooth cases pass (recall >= 0.95, coverage >= 0.9, splits <= 10% of contacts, no merge, no false contact); {} of {} real-like (recall >= 0.95, coverage >= 0.9, trajectories <= 1.5 x contacts, B/s <= 150, scratch 200)",
            preset.name(),
            passed(&smooth),
            smooth.len(),
            passed(&real),
            real.len()
        );
    }
}

/// A table for a terminal: the first `left` columns left-aligned, the rest right.
fn aligned(table: &[Vec<String>], left: usize) -> String {
    let widths: Vec<usize> = (0..table.first().map_or(0, Vec::len))
        .map(|c| table.iter().map(|l| l[c].len()).max().unwrap_or(0))
        .collect();
    let mut s = String::new();
    for line in table {
        for (c, cell) in line.iter().enumerate() {
            let _ = if c < left {
                write!(s, "{cell:<w$}  ", w = widths[c])
            } else {
                write!(s, "{cell:>w$}  ", w = widths[c])
            };
        }
        s.truncate(s.trim_end().len());
        s.push('\n');
    }
    s
}

/// Milliseconds of `stage`; 0 for a stage that did not run (no touch: no placement).
fn ms(r: &TradeRow, stage: Stage) -> f64 {
    1e3 * r.seconds.get(stage).unwrap_or(0.0)
}

/// The numeric columns after the recording and preset, formatted; the transforms as
/// one `scored/total` cell, or two with `split` (CSV, where every cell is one number).
fn cells(r: &TradeRow, split: bool) -> Vec<String> {
    let mut out: Vec<String> = STAGES.iter().map(|s| format!("{:.1}", ms(r, *s))).collect();
    if split {
        out.push(r.transforms.0.to_string());
        out.push(r.transforms.1.to_string());
    } else {
        out.push(format!("{}/{}", r.transforms.0, r.transforms.1));
    }
    out.push(format!("{:.3}", r.score_gap_pct));
    out.push(format!("{:.3}", r.rms_vs_exact_pct));
    out.push(format!("{:.3}", r.max_vs_exact_pct));
    out.push(format!("{:.1}", r.tracks_agree_pct));
    out.push(r.bytes.to_string());
    out.push(format!("{:.2}", r.coverage));
    out.push(format!("{:.2}", r.rendered));
    out.push(
        r.recall
            .map_or_else(|| "-".to_string(), |v| format!("{v:.2}")),
    );
    out
}

/// The column names, matching [`cells`] with the same `split`.
fn headers(split: bool) -> Vec<String> {
    let mut h = vec!["recording".to_string(), "preset".to_string()];
    h.extend(STAGES.iter().map(|s| format!("{} ms", s.name())));
    h.push("transforms scored".into());
    if split {
        h.push("transforms".into());
    }
    h.extend(
        [
            "score gap %",
            "rms vs exact % fs",
            "max vs exact % fs",
            "tracks agree %",
            "bytes",
            "coverage",
            "played",
            "recall",
        ]
        .map(String::from),
    );
    h
}

/// One row per line in `[recording, preset, cells...]` form.
fn lines(rows: &[TradeRow], split: bool) -> impl Iterator<Item = Vec<String>> + '_ {
    rows.iter().map(move |r| {
        let mut line = vec![r.input.clone(), r.preset.name().to_string()];
        line.extend(cells(r, split));
        line
    })
}

/// A line for a terminal: the recording's name (from its path) escaped.
fn shown(mut line: Vec<String>) -> Vec<String> {
    if let Some(name) = line.first_mut() {
        *name = super::report::escaped(name);
    }
    line
}

fn text(rows: &[TradeRow]) -> String {
    let table: Vec<Vec<String>> = std::iter::once(headers(false))
        .chain(lines(rows, false).map(shown))
        .collect();
    aligned(&table, 2)
}

fn markdown(rows: &[TradeRow]) -> String {
    let h = headers(false);
    let mut s = format!("| {} |\n", h.join(" | "));
    s += &format!(
        "|{}\n",
        h.iter()
            .enumerate()
            .map(|(i, _)| if i < 2 { "---|" } else { "---:|" })
            .collect::<String>()
    );
    for line in lines(rows, false).map(shown) {
        s += &format!("| {} |\n", line.join(" | "));
    }
    s
}

/// RFC 4180 CSV: one field per value, a field quoted when it holds a comma, a quote or
/// a line break (a recording's name may).
fn csv(rows: &[TradeRow]) -> String {
    std::iter::once(headers(true))
        .chain(lines(rows, true))
        .map(|line| {
            line.iter()
                .map(|f| csv_field(f))
                .collect::<Vec<_>>()
                .join(",")
                + "\n"
        })
        .collect()
}

fn csv_field(field: &str) -> std::borrow::Cow<'_, str> {
    if field.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", field.replace('"', "\"\"")).into()
    } else {
        field.into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_fields_are_quoted_only_when_they_must_be() {
        assert_eq!(csv_field("tap"), "tap");
        assert_eq!(csv_field("a,b"), "\"a,b\"");
        assert_eq!(csv_field(r#"say "hi""#), r#""say ""hi""""#);
        assert_eq!(csv_field("two\nlines"), "\"two\nlines\"");
    }

    #[test]
    fn split_headers_match_split_cells() {
        assert_eq!(headers(true).len(), headers(false).len() + 1);
    }
}
