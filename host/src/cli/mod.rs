//! Subcommands. Each module turns arguments into calls to the `touchc` library
//! and the `touch-protocol` crate; errors carry the file they concern, and
//! [`report`] prints them, in one place.

mod bank;
mod compile;
mod export;
mod help;
mod import;
mod input;
mod inspect;
mod output;
mod params;
mod plot;
mod preview;
mod render;
mod report;
mod report_json;
mod select;
mod sleeve;
mod stdio;
mod study;
mod synth;
mod track;
mod trade;
mod warning;

use std::path::Path;

use clap::{CommandFactory, Parser, Subcommand};

pub use report::{parse_error, report};

/// What `--help` says about exit codes, `-` and errors.
const AFTER_HELP: &str = "\
Files: `-` is standard input for `compile`, `inspect`, `render`, `plot`, `export` and
`import`, and standard output wherever an output can be a stream (`compile -o`,
`render`, `inspect -o`, `track -o`, `synth -o`, `export -o` when it writes one file,
`import -o`). Outputs that are regular files appear whole or not at all; devices,
pipes and symlinks are written through to their target. No output may be one of the
command's inputs, or another of its outputs.

Exit status: 0 success (also when a reader such as `head` closes the pipe early),
1 bad input, a failed compile or an output that cannot be written, 2 usage error
(a flag or parameter file out of range, an output over an input).";

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
    /// Write a stimulus as the sleeve plays it in another haptics format: MPEG-I Haptics
    /// (.hjif), Meta/Lofelt .haptic, Apple AHAP or bHaptics .tact.
    Export(export::Args),
    /// Read an MPEG-I Haptics file written by `export` back into a stimulus.
    Import(import::Args),
    /// Pack stimuli into a bank image, one per button slot, for the sleeve's flash.
    Bank(bank::Args),
    /// Write a seeded synthetic recording (.npy) of stroke, tap, pat, squeeze, shake.
    Synth(synth::Args),
    /// Compile recordings under every preset and compare time, placement, signal and
    /// tracks with `exact`.
    Trade(trade::Args),
    /// Score every recording of a labelled data set for every class by cross-validation
    /// and list the best of each class (the paper's instance selection).
    Select(select::Args),
    /// Talk to a sleeve on a cable: list, info, upload, play, stop, stream, status, events.
    Sleeve(sleeve::Args),
    /// Perception studies with the sleeve: run a participant's session from a plan,
    /// report the classification experiment's analyses.
    Study(study::Args),
    /// Print a shell completion script (installing it: see the README's "Install").
    Completions {
        /// The shell to complete in.
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
}

/// The command line's definition, its help in plain words (see [`help`]).
pub fn command() -> clap::Command {
    help::plain_command(Cli::command())
}

/// Parses the process's arguments with [`command`].
pub fn parse() -> Result<Cli, clap::Error> {
    use clap::FromArgMatches;
    let matches = command().try_get_matches()?;
    Cli::from_arg_matches(&matches)
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
        Command::Export(args) => export::run(&args),
        Command::Import(args) => import::run(&args),
        Command::Bank(args) => bank::run(&args),
        Command::Synth(args) => synth::run(&args),
        Command::Trade(args) => trade::run(&args),
        Command::Select(args) => select::run(&args),
        Command::Sleeve(args) => sleeve::run(&args),
        Command::Study(args) => study::run(&args),
        Command::Completions { shell } => {
            // Generated into memory: clap_complete panics on a write error.
            let mut script = Vec::new();
            clap_complete::generate(shell, &mut command(), "touchc", &mut script);
            Ok(crate::cli::output::write_atomic(Path::new("-"), &script)?)
        }
    }
}
