//! `touchc trade REC.npy... [--csv FILE] [--svg FILE]`: every preset on every recording, compared
//! with `exact` (see [`touchc::measure::trade`]).

use std::fmt::Write as _;
use std::path::PathBuf;

use crate::cli::output::write_atomic;
use anyhow::Context;
use touchc::compile::CompileOptions;
use touchc::input::recording::Recording;
use touchc::input::synth::Truth;
use touchc::measure::trade::{plot_svg, trade, TradeRow};

/// Arguments of `touchc trade`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Recordings, `.npy` `[frames, rows, cols]` in psi.
    #[arg(required = true)]
    recordings: Vec<PathBuf>,
    /// Compile each recording this many times per preset and keep the fastest run.
    #[arg(long, default_value_t = 3)]
    repeat: usize,
    /// Worker threads for the parallel stages (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Also write the table as CSV.
    #[arg(long)]
    csv: Option<PathBuf>,
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
    /// The recordings' rate and cell pitch.
    #[command(flatten)]
    metadata: super::params::MetadataArgs,
}

/// The stages of the table, in pipeline order.
const STAGES: [&str; 8] = [
    "preprocess",
    "detect",
    "track",
    "placement",
    "signals",
    "condition",
    "keyframes",
    "total",
];

pub fn run(args: &Args) -> anyhow::Result<()> {
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = args.threads {
        anyhow::ensure!(n >= 1, "--threads must be at least 1");
        builder = builder.num_threads(n);
    }
    let pool = builder.build().context("cannot start the worker threads")?;
    if !args.truth.is_empty() && args.truth.len() != args.recordings.len() {
        return Err(super::Usage(format!(
            "--truth needs one file per recording: {} recordings, {} truth files",
            args.recordings.len(),
            args.truth.len()
        ))
        .into());
    }
    let truths = args
        .truth
        .iter()
        .map(|p| {
            let text = std::fs::read(p).with_context(|| format!("{}: cannot read", p.display()))?;
            serde_json::from_slice::<Truth>(&text).with_context(|| {
                format!(
                    "{}: not a truth file of `touchc synth --truth`",
                    p.display()
                )
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut rows = Vec::new();
    let mut failed = 0;
    for (i, path) in args.recordings.iter().enumerate() {
        let rec = Recording::load(path)?;
        let base = CompileOptions {
            metadata: args.metadata.overrides(),
            ..CompileOptions::default()
        };
        match pool.install(|| trade(&rec, &base, args.repeat, truths.get(i))) {
            Ok(r) => rows.extend(r),
            Err(e) => {
                failed += 1;
                super::print_error(
                    &anyhow::Error::new(e).context(format!("{}: cannot compile", path.display())),
                );
            }
        }
    }
    let table = if args.markdown {
        markdown(&rows)
    } else {
        text(&rows)
    };
    write_atomic(std::path::Path::new("-"), table.as_bytes())?;
    if let Some(path) = &args.csv {
        write_atomic(path, csv(&rows).as_bytes())?;
    }
    if let Some(path) = &args.svg {
        let svg = plot_svg(&rows).with_context(|| format!("{}: cannot draw", path.display()))?;
        write_atomic(path, svg.as_bytes())?;
    }
    anyhow::ensure!(failed == 0, "{failed} recordings failed to compile");
    Ok(())
}

fn ms(r: &TradeRow, stage: &str) -> f64 {
    1e3 * r.seconds.get(stage).copied().unwrap_or(0.0)
}

/// The numeric columns after the recording and preset, formatted.
fn cells(r: &TradeRow) -> Vec<String> {
    let mut out: Vec<String> = STAGES.iter().map(|s| format!("{:.1}", ms(r, s))).collect();
    out.push(format!("{}/{}", r.transforms.0, r.transforms.1));
    out.push(format!("{:.3}", r.score_gap_pct));
    out.push(format!("{:.3}", r.rms_vs_exact_pct));
    out.push(format!("{:.3}", r.max_vs_exact_pct));
    out.push(format!("{:.1}", r.tracks_agree_pct));
    out.push(r.bytes.to_string());
    out.push(format!("{:.2}", r.coverage));
    out.push(
        r.recall
            .map_or_else(|| "-".to_string(), |v| format!("{v:.2}")),
    );
    out
}

fn headers() -> Vec<String> {
    let mut h = vec!["recording".to_string(), "preset".to_string()];
    h.extend(STAGES.iter().map(|s| format!("{s} ms")));
    h.extend(
        [
            "transforms scored",
            "score gap %",
            "rms vs exact % fs",
            "max vs exact % fs",
            "tracks agree %",
            "bytes",
            "coverage",
            "recall",
        ]
        .map(String::from),
    );
    h
}

fn text(rows: &[TradeRow]) -> String {
    let mut table = vec![headers()];
    for r in rows {
        let mut line = vec![r.input.clone(), r.preset.name().to_string()];
        line.extend(cells(r));
        table.push(line);
    }
    let widths: Vec<usize> = (0..table[0].len())
        .map(|c| table.iter().map(|l| l[c].len()).max().unwrap_or(0))
        .collect();
    let mut s = String::new();
    for line in &table {
        for (c, cell) in line.iter().enumerate() {
            let _ = if c < 2 {
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

fn markdown(rows: &[TradeRow]) -> String {
    let h = headers();
    let mut s = format!("| {} |\n", h.join(" | "));
    s += &format!(
        "|{}\n",
        h.iter()
            .enumerate()
            .map(|(i, _)| if i < 2 { "---|" } else { "---:|" })
            .collect::<String>()
    );
    for r in rows {
        s += &format!(
            "| {} | {} | {} |\n",
            r.input,
            r.preset.name(),
            cells(r).join(" | ")
        );
    }
    s
}

fn csv(rows: &[TradeRow]) -> String {
    let mut s = headers().join(",") + "\n";
    for r in rows {
        // Names are quoted: a file name may hold a comma.
        s += &format!(
            "\"{}\",{},{}\n",
            r.input.replace('"', "\"\""),
            r.preset.name(),
            cells(r).join(",").replace("/", ",")
        );
    }
    s.replacen("transforms scored", "transforms scored,transforms", 1)
}
