//! The `touchc` command line: parses arguments, runs one subcommand, and turns any error
//! into a message and a non-zero exit code, in this one place.

mod cli;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Compiles recorded social touch into stimuli for an 8-actuator haptic sleeve.
#[derive(Debug, Parser)]
#[command(name = "touchc", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// One variant per pipeline entry point; each body lives in `cli/<name>.rs`.
#[derive(Debug, Subcommand)]
enum Command {
    /// Track contacts in a recording (stages 0-3) and print the trajectories.
    Track(cli::track::TrackArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Track(args) => cli::track::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("touchc: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
