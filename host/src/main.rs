//! `touchc`: the command line. Parses arguments, runs one subcommand, and turns
//! every error into one message on stderr and an exit status (0 ok, 1 bad input or
//! failed compile, 2 usage), in one place: [`cli::report`].

mod cli;

use std::process::ExitCode;

fn main() -> ExitCode {
    touchc::memory::return_freed_memory();
    let args = match cli::parse() {
        Ok(args) => args,
        Err(err) => return cli::parse_error(&err),
    };
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => cli::report(&err),
    }
}
