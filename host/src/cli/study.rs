//! `touchc study ...`: perception studies with the sleeve in the loop. `run` serves
//! the participant's page and plays a plan's trials; `report` analyses the logs
//! (or tidy CSVs collected with any other tool) as the paper did.

use std::path::{Path, PathBuf};

use anyhow::Context;
use touchc_study::{figures, log, markdown, tidy, Responses, Settings};

use crate::cli::output::{named, refuse_overwrites, write_atomic};

mod http;
mod plan;
mod session;

/// What `--help` says after the subcommands.
const AFTER_HELP: &str = "\
Inputs of `report`: session logs (JSON lines, as `run` writes them) or tidy CSVs
(participant, round, position, stimulus, p_<scenario>..., valence, arousal), in
any mix; all must name the same scenarios in the same order. See docs/study.md.

Exit status: 0 success, 1 bad input or no sleeve attached, 2 usage (a bad plan).";

/// Arguments of `touchc study`.
#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Debug, clap::Subcommand)]
enum Cmd {
    /// Run one participant's session: serve the page on 127.0.0.1, play each trial on
    /// the sleeve, log each answer (JSON lines, flushed per trial).
    Run(session::RunArgs),
    /// Analyse session logs or tidy CSVs: confusion, accuracy, binomial tests,
    /// cut-offs, Bhattacharyya, k-means, Kruskal-Wallis (Markdown on stdout, or
    /// report.json, report.md, CSVs and SVG figures in -o DIR).
    Report(ReportArgs),
}

#[derive(Debug, clap::Args)]
struct ReportArgs {
    /// Session logs (.jsonl) or tidy CSVs.
    #[arg(required = true, value_name = "LOG")]
    inputs: Vec<PathBuf>,
    /// Write the report's files into this directory (created if missing).
    #[arg(short, long, value_name = "DIR")]
    output: Option<PathBuf>,
    /// A reference confusion matrix (stimulus,<scenario>...) for the Bhattacharyya
    /// coefficients, e.g. a human-human study's.
    #[arg(long, value_name = "CSV")]
    reference: Option<PathBuf>,
    /// Seed of the k-means starts.
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

/// Runs `touchc study`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    match &args.command {
        Cmd::Run(a) => session::run(a),
        Cmd::Report(a) => report(a),
    }
}

fn read_text(path: &Path) -> anyhow::Result<String> {
    std::fs::read_to_string(path).with_context(|| path.display().to_string())
}

/// A log or a tidy CSV, told apart by their first character (a log's lines are JSON
/// objects).
pub(crate) fn read_responses(path: &Path) -> anyhow::Result<Responses> {
    let text = read_text(path)?;
    let r = if text.trim_start().starts_with('{') {
        log::read(&text)
    } else {
        tidy::read(&text)
    };
    r.with_context(|| path.display().to_string())
}

fn report(a: &ReportArgs) -> anyhow::Result<()> {
    let mut all = Responses::default();
    for p in &a.inputs {
        all.merge(read_responses(p)?)
            .with_context(|| p.display().to_string())?;
    }
    let reference = match &a.reference {
        Some(p) => {
            Some(tidy::read_reference(&read_text(p)?).with_context(|| p.display().to_string())?)
        }
        None => None,
    };
    let settings = Settings {
        seed: a.seed,
        ..Settings::default()
    };
    let r = touchc_study::analyse(&all, reference.as_ref(), &settings);
    let md = markdown::render(&r);
    let Some(dir) = &a.output else {
        return Ok(write_atomic(Path::new("-"), md.as_bytes())?);
    };
    let mut files: Vec<(String, Vec<u8>)> = vec![
        (
            "report.json".into(),
            (serde_json::to_string_pretty(&r)? + "\n").into_bytes(),
        ),
        ("report.md".into(), md.into_bytes()),
        ("trials.csv".into(), tidy::write(&all).into_bytes()),
        (
            "confusion.csv".into(),
            markdown::confusion_csv(&r).into_bytes(),
        ),
    ];
    files.extend(
        figures::all(&r, &all)
            .into_iter()
            .map(|(n, s)| (n.to_string(), s.into_bytes())),
    );
    let paths: Vec<PathBuf> = files.iter().map(|(n, _)| dir.join(n)).collect();
    let mut inputs: Vec<_> = a.inputs.iter().map(|p| named("an input", p)).collect();
    inputs.extend(a.reference.iter().map(|p| named("--reference", p)));
    let outputs: Vec<_> = paths.iter().map(|p| named("-o", p)).collect();
    refuse_overwrites(&inputs, &outputs)?;
    std::fs::create_dir_all(dir).with_context(|| dir.display().to_string())?;
    for (p, (_, bytes)) in paths.iter().zip(&files) {
        write_atomic(p, bytes)?;
    }
    Ok(())
}
