//! Subcommands. Each module turns arguments into calls to the `touchc` library
//! and the `touch-protocol` crate; errors carry the file they concern.

mod bank;
mod compile;
mod inspect;
mod params;
mod plot;
mod preview;
mod render;
mod synth;
mod track;
mod trade;

use std::path::Path;

use anyhow::Context;
use clap::{Parser, Subcommand};
use touch_protocol::{Bank, Stimulus};

/// Compiles recorded social touch into stimuli for an 8-actuator haptic sleeve.
#[derive(Debug, Parser)]
#[command(name = "touchc", version, about)]
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
    }
}

/// Reads a whole input file, naming it in the error.
pub(crate) fn read_input(path: &Path) -> anyhow::Result<Vec<u8>> {
    std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))
}

/// The stimulus in `bytes`: the file itself, or slot `slot` when it is a bank.
pub(crate) fn stimulus_in<'a>(
    bytes: &'a [u8],
    path: &Path,
    slot: usize,
) -> anyhow::Result<Stimulus<'a>> {
    let name = path.display();
    if bytes.starts_with(&touch_protocol::bank::MAGIC) {
        let bank = Bank::decode(bytes).with_context(|| format!("{name}: not a valid bank"))?;
        bank.slot(slot)
            .with_context(|| format!("{name}: slot {slot}"))
    } else {
        Stimulus::decode(bytes).with_context(|| format!("{name}: not a valid stimulus"))
    }
}
