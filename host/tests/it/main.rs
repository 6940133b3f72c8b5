//! The host's integration tests, one binary: a change to the library relinks one test
//! executable, not one per file. Each module is a group of tests that used to be a file
//! of its own; `common` and its siblings are the fixtures (`common/mod.rs` is shared with
//! the benches and examples, `common/poison.rs` with the fuzz targets, so they stay
//! beside this folder). proptest keeps its regression seeds in `../proptest-regressions/`.

#[path = "../common/bin.rs"]
mod bin;
#[path = "../common/mod.rs"]
mod common;
#[path = "../common/fuzz_input.rs"]
mod fuzz_input;
#[path = "../common/poison.rs"]
mod poison;
#[path = "../common/stimuli.rs"]
mod stimuli;

mod blur;
mod bnb_oracle;
mod bounded;
mod cli;
mod cli_files;
mod cli_help;
mod cli_messages;
mod cli_outputs;
mod cli_sanity;
mod cli_sleeve;
mod cli_trade;
mod cli_unix;
mod cli_viz;
mod compile;
mod detect;
mod emoji_bank;
mod export;
mod extremes;
mod flow;
mod knobs;
mod layout_guess;
mod placement_oracle;
mod pictures;
mod playback;
mod placement_reference;
mod plot_png;
mod poisoned;
mod recording;
mod reference;
mod repository;
mod synth_files;
mod tare;
mod touch;
