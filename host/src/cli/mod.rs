//! Subcommands. Each module turns arguments into calls to the `touchc` library
//! and the `touch-protocol` crate; errors carry the file they concern.

mod bank;
mod inspect;
mod render;
mod synth;

use std::path::Path;

use anyhow::Context;
use clap::{Parser, Subcommand};

/// Compiles recorded social touch into stimuli for an 8-actuator haptic sleeve.
#[derive(Debug, Parser)]
#[command(name = "touchc", version, about)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Show a stimulus or bank file: header, duration, size, CRC status.
    Inspect(inspect::Args),
    /// Play a stimulus through the player (the firmware's code) and write its output.
    Render(render::Args),
    /// Pack stimuli into a bank image, one per button slot, for the sleeve's flash.
    Bank(bank::Args),
    /// Write a seeded synthetic recording (.npy) of stroke, tap, pat, squeeze, shake.
    Synth(synth::Args),
}

/// Runs the chosen subcommand.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Inspect(args) => inspect::run(&args),
        Command::Render(args) => render::run(&args),
        Command::Bank(args) => bank::run(&args),
        Command::Synth(args) => synth::run(&args),
    }
}

/// Reads a whole input file, naming it in the error.
pub(crate) fn read_input(path: &Path) -> anyhow::Result<Vec<u8>> {
    std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))
}
