//! `touchc`: the command line. Parses arguments, runs one subcommand, and turns
//! every error into a message on stderr and a non-zero exit, in one place.

mod cli;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("touchc: error: {err:#}");
            ExitCode::FAILURE
        }
    }
}
