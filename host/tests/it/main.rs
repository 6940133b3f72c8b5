//! The host's integration tests, one binary: a change to the library relinks one test
//! executable, not one per file. Each module is a group of tests that used to be a file
//! of its own; the fixtures are the test kit's (`touchc-testkit`, shared with the
//! benches, examples and fuzz targets), `common` its root. The layer crates' own tests
//! (oracles, reference placements) live in those crates: `cargo test -p touchc-<layer>`.

use touchc_testkit as common;
use touchc_testkit::{fuzz_input, poison, stimuli};

/// The kit's runs of `touchc`, on this package's binary.
mod bin {
    use std::process::{Command, Output};

    pub use touchc_testkit::bin::{fed, ok, refused, s, stderr};

    const TOUCHC: touchc_testkit::bin::Bin = touchc_testkit::bin::Bin(env!("CARGO_BIN_EXE_touchc"));

    /// A `touchc` command, to add arguments, a working directory or standard input to.
    pub fn command() -> Command {
        TOUCHC.command()
    }

    /// Runs `touchc ARGS...` to the end and returns its status and output.
    pub fn touchc(args: &[&str]) -> Output {
        TOUCHC.run(args)
    }
}

mod bounded;
mod cli;
mod cli_files;
mod cli_help;
mod cli_messages;
mod cli_newcomer;
mod cli_outputs;
mod cli_sanity;
mod cli_select;
mod cli_sleeve;
mod cli_study;
mod cli_trade;
mod cli_unix;
mod cli_viz;
mod compile;
mod doc_figures;
mod docs_commands;
mod emoji_bank;
mod export;
mod extremes;
mod hjif_schema;
mod knobs;
mod layout_guess;
mod library_words;
mod pictures;
mod playback;
mod plot_png;
mod poisoned;
mod recording;
mod reference;
mod repository;
mod synth_files;
mod tare;
mod touch;
