//! Subcommands. Each module turns arguments into calls to the `touchc` library
//! and the `touch-protocol` crate; errors carry the file they concern, and
//! [`report`] prints them, in one place.

mod bank;
mod compile;
mod inspect;
mod output;
mod params;
mod plot;
mod preview;
mod render;
mod sleeve;
mod synth;
mod track;
mod trade;

use std::io::Read;
use std::path::Path;
use std::process::ExitCode;

use anyhow::Context;
use clap::{CommandFactory, Parser, Subcommand};
use touch_protocol::{Bank, Stimulus};

/// What `--help` says about exit codes, `-` and errors.
const AFTER_HELP: &str = "\
Files: `-` is standard input for `inspect` and `render` (and `plot`), and standard
output wherever an output can be a stream (`render`, `inspect -o`, `track -o`,
`synth -o`). Outputs that are regular files appear whole or not at all; devices,
pipes and symlinks are written through to their target.

Exit status: 0 success (also when a reader such as `head` closes the pipe early),
1 bad input, a failed compile or an output that cannot be written, 2 usage error.";

/// Compiles recorded social touch into stimuli for an 8-actuator haptic sleeve.
#[derive(Debug, Parser)]
#[command(name = "touchc", version, about, after_help = AFTER_HELP)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Compile a recording into a stimulus file (tracking, placement, signals, keyframes).
    Compile(compile::Args),
    /// Track contacts in a recording (stages 0-3) and print the trajectories.
    Track(track::TrackArgs),
    /// Show a stimulus or bank file: header, duration, size, CRC status.
    Inspect(inspect::Args),
    /// Play a stimulus through the player (the firmware's code) and write its output
    /// as CSV or as an 8-channel WAV.
    Render(render::Args),
    /// Plot a stimulus's eight currents as the sleeve outputs them (SVG or PNG).
    Plot(plot::Args),
    /// Animate a recording's blurred frames with trajectories, workspaces and actuator
    /// intensities (GIF), or show one frame (PNG).
    Preview(preview::Args),
    /// Pack stimuli into a bank image, one per button slot, for the sleeve's flash.
    Bank(bank::Args),
    /// Write a seeded synthetic recording (.npy) of stroke, tap, pat, squeeze, shake.
    Synth(synth::Args),
    /// Compile recordings under every preset and compare time, placement, signal and
    /// tracks with `exact`.
    Trade(trade::Args),
    /// Talk to a sleeve on a cable: list, info, upload, play, stop, stream, status, events.
    Sleeve(sleeve::Args),
    /// Print a shell completion script: `touchc completions bash > /etc/bash_completion.d/touchc`.
    Completions {
        /// The shell to complete in.
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
}

/// Runs the chosen subcommand.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Compile(args) => compile::run(&args),
        Command::Track(args) => track::run(&args),
        Command::Inspect(args) => inspect::run(&args),
        Command::Render(args) => render::run(&args),
        Command::Plot(args) => plot::run(&args),
        Command::Preview(args) => preview::run(&args),
        Command::Bank(args) => bank::run(&args),
        Command::Synth(args) => synth::run(&args),
        Command::Trade(args) => trade::run(&args),
        Command::Sleeve(args) => sleeve::run(&args),
        Command::Completions { shell } => {
            // Generated into memory: clap_complete panics on a write error.
            let mut script = Vec::new();
            clap_complete::generate(shell, &mut Cli::command(), "touchc", &mut script);
            Ok(crate::cli::output::write_atomic(Path::new("-"), &script)?)
        }
    }
}

/// A mistake in how the command was called (exit status 2, like clap's own).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub(crate) struct Usage(pub String);

/// Returns a usage error (exit status 2).
/// The actuator layout of a `--layout FILE` option, or the paper's sleeve without one.
pub(crate) fn layout(path: Option<&Path>) -> anyhow::Result<touchc::placement::layout::Layout> {
    Ok(match path {
        Some(path) => touchc::placement::layout::Layout::load(path)?,
        None => touchc::placement::layout::Layout::paper(),
    })
}

pub(crate) fn usage(message: impl Into<String>) -> anyhow::Error {
    Usage(message.into()).into()
}

/// Prints `err` once on stderr and chooses the exit status: 2 for usage errors, 0 when
/// a reader closed our output pipe (the reader got what it wanted), 1 for the rest.
pub fn report(err: &anyhow::Error) -> ExitCode {
    let broken_pipe = err.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe)
            || cause
                .downcast_ref::<crate::cli::output::WriteError>()
                .is_some_and(crate::cli::output::WriteError::is_broken_pipe)
    });
    if broken_pipe {
        return ExitCode::SUCCESS;
    }
    print_error(err);
    if err.chain().any(|cause| cause.is::<Usage>()) {
        ExitCode::from(2)
    } else {
        ExitCode::FAILURE
    }
}

/// Prints `err` on stderr: its chain once, escaped.
pub(crate) fn print_error(err: &anyhow::Error) {
    eprintln!("touchc: error: {}", escaped(&message(err)));
}

/// The error's chain joined by ": ", leaving out every cause whose text an outer error
/// already quoted: library errors often include their source's text and name it as the
/// source too, and a message should say each thing once.
fn message(err: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in err.chain() {
        let text = cause.to_string();
        if text.is_empty() || out.contains(&text) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&text);
    }
    out
}

/// `text` with control characters shown as escapes (`\u{1b}`, `\n`, ...), so that a
/// name or path from a file cannot drive the terminal it is printed on.
pub(crate) fn escaped(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

/// Prints a warning about `file` on stderr, escaped like every other message.
pub(crate) fn warn(file: &Path, message: &str) {
    eprintln!(
        "touchc: warning: {}",
        escaped(&format!("{}: {message}", input_name(file)))
    );
}

/// How an input path is named in messages (`-` is standard input).
pub(crate) fn input_name(path: &Path) -> String {
    if crate::cli::output::is_stdio(path) {
        "standard input".into()
    } else {
        path.display().to_string()
    }
}

/// Reads a whole input file, `-` being standard input, naming it in the error.
pub(crate) fn read_input(path: &Path) -> anyhow::Result<Vec<u8>> {
    if crate::cli::output::is_stdio(path) {
        let mut bytes = Vec::new();
        std::io::stdin()
            .lock()
            .read_to_end(&mut bytes)
            .context("standard input: cannot read")?;
        return Ok(bytes);
    }
    std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))
}

/// The stimulus in `bytes`: the file itself, or slot `slot` when it is a bank.
pub(crate) fn stimulus_in<'a>(
    bytes: &'a [u8],
    path: &Path,
    slot: usize,
) -> anyhow::Result<Stimulus<'a>> {
    let name = input_name(path);
    if bytes.starts_with(&touch_protocol::bank::MAGIC) {
        let bank = Bank::decode(bytes).with_context(|| format!("{name}: not a valid bank"))?;
        bank.slot(slot)
            .with_context(|| format!("{name}: slot {slot}"))
    } else {
        Stimulus::decode(bytes).with_context(|| format!("{name}: not a valid stimulus"))
    }
}
