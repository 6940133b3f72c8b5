//! `touchc select DATA`: the paper's instance selection. Every recording of a labelled
//! data set scored for every class by the fold that held it out, the best of each class
//! listed (and compiled into a bank with `--compile`), the cross-validated figures
//! reported; `--trade` compares the scorers on the same folds; `--score` applies a
//! saved model to new recordings.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use touchc_select::dataset::{self, Dataset, Listing};
use touchc_select::model::Settings;
use touchc_select::{
    cross_validate, metrics, Control, Folds, Model, ScorerKind, SelectError, Selection,
};

use crate::cli::output::{named, refuse_overwrites, write_atomic, Output};
use crate::cli::params::OUTPUT;

mod report;

/// What `touchc select --help` adds after the options.
const AFTER_HELP: &str = "\
DATA is a folder with one subfolder of recordings (.npy, .npz) per class, or a CSV
manifest of `path,label[,group]` lines (paths relative to the manifest; the group is
the person who touched: folds then keep each person whole).

Examples:
  touchc select data/ --top 6 -o sel/          report.json, scores.csv, scores.json
  touchc select data.csv --model cnn --seed 2  the paper's network, grouped folds
  touchc select data/ --compile -o sel/        the best of each class into sel/bank.bin
  touchc select data/ --compile --compile-top 3 -o sel/   each class's best 3 in the bank
  touchc select data/ --trade                  both scorers on the same folds
  touchc select data/ --model-file m.json      also train on everything and save it
  touchc select --model-file m.json --score new1.npy new2.npy

Ctrl-C stops training and writes nothing.";

/// The scorer, on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Scorer {
    /// Logistic regression on duration, pressure, area, speed, location and rhythm.
    Features,
    /// The paper's 3D convolutional network, globally pooled so it reads what a touch is
    /// rather than where and when; three of them, their scores averaged.
    Cnn,
}

impl From<Scorer> for ScorerKind {
    fn from(s: Scorer) -> Self {
        match s {
            Scorer::Features => ScorerKind::Features,
            Scorer::Cnn => ScorerKind::Cnn,
        }
    }
}

/// Arguments of `touchc select`.
#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    /// The labelled data set: a folder of class subfolders, or a CSV manifest.
    #[arg(required_unless_present = "score")]
    data: Option<PathBuf>,
    /// Folds of the cross-validation.
    #[arg(long, default_value_t = 5)]
    folds: usize,
    /// Recordings listed (and the best compiled) per class.
    #[arg(long, default_value_t = 6)]
    top: usize,
    /// The scorer.
    #[arg(long, value_enum, default_value_t = Scorer::Features)]
    model: Scorer,
    /// Seed of the folds, shuffles and initial weights.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Passes over the training set (each of the network scorer's three networks).
    #[arg(long, default_value_t = 30)]
    epochs: usize,
    /// Compare the scorers on the same folds: accuracy, macro-F1, seconds to train and
    /// to score.
    #[arg(long, conflicts_with_all = ["score", "compile"])]
    trade: bool,
    /// Train on the whole data set and save the model to this file (or, with
    /// `--score`, the model to apply).
    #[arg(long)]
    model_file: Option<PathBuf>,
    /// Score these recordings with `--model-file` instead of cross-validating.
    #[arg(long, num_args = 1.., requires = "model_file", conflicts_with = "data")]
    score: Vec<PathBuf>,
    /// Directory for report.json, scores.csv and scores.json (created if needed).
    #[arg(short, long, help_heading = OUTPUT)]
    output: Option<PathBuf>,
    /// Compile the best recording of each class into `DIR/<class>.touch` and a bank
    /// `DIR/bank.bin` for `touchc sleeve upload` (needs `-o DIR`).
    #[arg(long, requires = "output", help_heading = OUTPUT)]
    compile: bool,
    /// With `--compile`: each class's best K (at most `--top`, and 32 in all, a bank's
    /// slots), the k-th best as `DIR/<class>_<k>.touch`; the bank holds them class by
    /// class, best first.
    #[arg(long, value_name = "K", requires = "compile", help_heading = OUTPUT)]
    compile_top: Option<usize>,
    /// Algorithm parameters of `--compile`, and the recordings' sampling.
    #[command(flatten)]
    config: super::params::ConfigArgs,
}

/// A selection error as the command line words it: bad settings are usage errors.
fn select_error(e: SelectError) -> anyhow::Error {
    match e {
        SelectError::Setting(m) => super::report::usage(m),
        e => e.into(),
    }
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let cancel = Arc::new(AtomicBool::new(false));
    // A second Ctrl-C still ends the process at once.
    signal_hook::flag::register_conditional_shutdown(
        signal_hook::consts::SIGINT,
        130,
        cancel.clone(),
    )
    .and_then(|_| signal_hook::flag::register(signal_hook::consts::SIGINT, cancel.clone()))
    .context("cannot watch for Ctrl-C")?;
    if !args.score.is_empty() {
        return score_new(args);
    }
    let data_path = args.data.as_deref().context("no data set given")?;
    check_outputs(args, data_path)?;
    if args.folds < 2 {
        return Err(super::report::usage(format!(
            "--folds {}: cross-validation needs at least 2",
            args.folds
        )));
    }
    if args.top == 0 {
        return Err(super::report::usage(
            "--top 0: list at least one recording per class",
        ));
    }
    let listing = Listing::open(data_path)?;
    check_compile_top(args, listing.classes.len())?;
    let data = listing.load(&args.config.overrides())?;
    let groups = data.groups();
    let folds = Folds::new(&data.labels(), groups.as_deref(), args.folds, args.seed)
        .map_err(select_error)?;
    let (runs, model) = train(args, &data, &folds, &cancel)?;
    if args.trade {
        return report::trade(&runs, &data, args.output.as_deref());
    }
    let (sel, seconds) = &runs[0];
    let top = metrics::top(&sel.scores, data.listing.classes.len(), args.top);
    // Everything is computed before anything is written: an error leaves no output.
    let mut files: Vec<(PathBuf, Vec<u8>)> = Vec::new();
    if let Some(dir) = &args.output {
        files.extend(report::files(dir, sel, &data, &top, *seconds, args.seed)?);
        if args.compile {
            files.extend(compile_best(args, dir, &data, &top)?);
        }
    }
    if let (Some(path), Some(model)) = (&args.model_file, &model) {
        files.push((path.clone(), model.to_json()));
    }
    let mut out = Output::stdout();
    report::tables(&mut out, sel, &data, &top).map_err(|e| out.error(e))?;
    out.finish()?;
    if let Some(dir) = &args.output {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("{}: cannot create the output directory", dir.display()))?;
    }
    for (path, bytes) in &files {
        write_atomic(path, bytes)?;
    }
    Ok(())
}

/// Each scorer's cross-validation with its seconds, and the model of the whole data set.
type Trained = (Vec<(Selection, f64)>, Option<Model>);

/// The cross-validation of the scorer (both with `--trade`), each with its seconds, and
/// the model of the whole data set when `--model-file` asks for one.
fn train(
    args: &Args,
    data: &Dataset,
    folds: &Folds,
    cancel: &AtomicBool,
) -> anyhow::Result<Trained> {
    let kinds: Vec<ScorerKind> = if args.trade {
        vec![ScorerKind::Features, ScorerKind::Cnn]
    } else {
        vec![args.model.into()]
    };
    let bar = Bar::new(kinds.iter().map(|&k| steps(k, folds.k, args.epochs)).sum());
    let progress = |p: touchc_select::Progress| bar.tick(p, folds.k);
    let control = Control {
        cancel,
        progress: &progress,
    };
    let mut runs = Vec::new();
    for kind in kinds {
        let settings = Settings {
            kind,
            seed: args.seed,
            epochs: args.epochs,
        };
        let t0 = std::time::Instant::now();
        let sel = cross_validate(data, &settings, folds, &control).map_err(select_error)?;
        runs.push((sel, t0.elapsed().as_secs_f64()));
    }
    let model = match &args.model_file {
        Some(_) if !args.trade => {
            let settings = Settings {
                kind: args.model.into(),
                seed: args.seed,
                epochs: args.epochs,
            };
            let samples: Vec<_> = data.samples.iter().collect();
            Some(
                Model::train(
                    &samples,
                    &data.labels(),
                    &data.listing.classes,
                    &settings,
                    None,
                    &control,
                )
                .map_err(select_error)?,
            )
        }
        _ => None,
    };
    bar.0.finish_and_clear();
    Ok((runs, model))
}

/// Refuses outputs over the data set or the model to apply.
fn check_outputs(args: &Args, data: &Path) -> anyhow::Result<()> {
    let inputs = vec![named("the data set", data)];
    let mut outputs = Vec::new();
    outputs.extend(args.model_file.as_deref().map(|p| named("--model-file", p)));
    if let Some(dir) = &args.output {
        if dir == data {
            return Err(super::report::usage(format!(
                "-o {}: the output directory is the data set",
                dir.display()
            )));
        }
    }
    refuse_overwrites(&inputs, &outputs)
}

/// The progress bar: one step per epoch of every network of every fold.
struct Bar(ProgressBar);

impl Bar {
    fn new(len: usize) -> Self {
        let bar = ProgressBar::new(len as u64);
        if let Ok(style) =
            ProgressStyle::with_template("{bar:40} {pos}/{len} epochs, {elapsed} {wide_msg}")
        {
            bar.set_style(style);
        }
        Bar(bar)
    }

    fn tick(&self, p: touchc_select::Progress, folds: usize) {
        let fold = match p.fold {
            Some(f) => format!("fold {}/{folds}", f + 1),
            None => "all data".into(),
        };
        let loss = if p.loss.is_finite() {
            format!(", loss {:.4}", p.loss)
        } else {
            String::new()
        };
        let network = if p.networks > 1 {
            format!(", network {}/{}", p.network, p.networks)
        } else {
            String::new()
        };
        self.0.set_message(format!(
            "{fold}{network}, epoch {}/{}{loss}",
            p.epoch, p.epochs
        ));
        if p.fold.is_some() {
            self.0.inc(1);
        }
    }
}

/// Progress steps of a cross-validation: one per epoch of every network of every fold.
fn steps(kind: ScorerKind, folds: usize, epochs: usize) -> usize {
    match kind {
        ScorerKind::Features => folds,
        ScorerKind::Cnn => folds * epochs * touchc_select::cnn::NETWORKS,
    }
    .max(folds * usize::from(epochs == 0))
}

/// Refuses a `--compile-top` of none, of more than `--top` lists, or of more stimuli than
/// a bank holds, before any training.
fn check_compile_top(args: &Args, classes: usize) -> anyhow::Result<()> {
    let Some(k) = args.compile_top else {
        return Ok(());
    };
    let slots = usize::from(touch_protocol::bank::MAX_SLOTS);
    if k == 0 {
        return Err(super::report::usage(
            "--compile-top 0: compile at least one recording per class",
        ));
    }
    if k > args.top {
        return Err(super::report::usage(format!(
            "--compile-top {k}: more than the {} listed per class (--top)",
            args.top
        )));
    }
    if k * classes > slots {
        return Err(super::report::usage(format!(
            "--compile-top {k}: {classes} classes x {k} = {} stimuli, a bank holds {slots}",
            k * classes
        )));
    }
    Ok(())
}

/// `DIR/<class>.touch` for the best recording of each class (and `DIR/<class>_<k>.touch`
/// for the k-th best, up to `--compile-top`), and `DIR/bank.bin` of them class by class,
/// best first.
fn compile_best(
    args: &Args,
    dir: &Path,
    data: &Dataset,
    top: &[Vec<usize>],
) -> anyhow::Result<Vec<(PathBuf, Vec<u8>)>> {
    use touchc_input::recording::Recording;
    use touchc_pipeline::compile::{compile_owned, CompileOptions};
    let opts = CompileOptions {
        config: args.config.resolve()?,
        metadata: args.config.overrides(),
        ..CompileOptions::default()
    };
    let mut files = Vec::new();
    let per_class = args.compile_top.unwrap_or(1);
    for (class, best) in data.listing.classes.iter().zip(top) {
        for (rank, &i) in best.iter().take(per_class).enumerate() {
            // The best keeps the class's name; the next ones are numbered from 2.
            let suffix = if rank == 0 {
                String::new()
            } else {
                format!("_{}", rank + 1)
            };
            let path = &data.listing.items[i].path;
            let recording = Recording::load(path)?;
            // A stimulus name holds 32 characters: the class is cut, the rank kept.
            let head: String = class.chars().take(32 - suffix.len()).collect();
            let opts = CompileOptions {
                name: format!("{head}{suffix}"),
                ..opts.clone()
            };
            let compiled = compile_owned(recording, &opts)
                .with_context(|| format!("{}: cannot compile", path.display()))?;
            files.push((
                dir.join(format!("{class}{suffix}.touch")),
                compiled.stimulus,
            ));
        }
    }
    let slices: Vec<&[u8]> = files.iter().map(|(_, b)| b.as_slice()).collect();
    let bank = touch_protocol::bank::encode(&slices)
        .with_context(|| format!("{}: cannot build the bank", dir.join("bank.bin").display()))?;
    files.push((dir.join("bank.bin"), bank));
    Ok(files)
}

/// `--score NEW...`: the saved model's scores for each recording, as CSV.
fn score_new(args: &Args) -> anyhow::Result<()> {
    let path = args
        .model_file
        .as_deref()
        .context("--score needs --model-file")?;
    let bytes = super::input::read_input(path)?;
    let model = Model::from_json(path, &bytes)?;
    let mut samples = Vec::new();
    for p in &args.score {
        let s = dataset::load_sample(p, &args.config.overrides())?;
        model.check_shape(&p.display().to_string(), &s)?;
        samples.push(s);
    }
    let cancel = AtomicBool::new(false);
    let control = Control {
        cancel: &cancel,
        progress: &|_| {},
    };
    let refs: Vec<_> = samples.iter().collect();
    let scores = model.score(&refs, &control).map_err(select_error)?;
    let mut text = Vec::new();
    writeln!(text, "path,best,{}", model.classes.join(","))?;
    for (p, s) in args.score.iter().zip(&scores) {
        let cells: Vec<String> = s.iter().map(|v| format!("{v:.6}")).collect();
        writeln!(
            text,
            "{},{},{}",
            report::csv_field(&p.display().to_string()),
            model.classes[metrics::argmax(s)],
            cells.join(",")
        )?;
    }
    match &args.output {
        Some(dir) => {
            std::fs::create_dir_all(dir).with_context(|| {
                format!("{}: cannot create the output directory", dir.display())
            })?;
            write_atomic(&dir.join("scores.csv"), &text)?;
        }
        None => write_atomic(Path::new("-"), &text)?,
    }
    Ok(())
}
