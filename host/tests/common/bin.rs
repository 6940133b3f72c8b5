//! Running the real `touchc` binary (`#[path]`-included by the tests that drive it).

// Each test crate uses a different part of this module.
#![allow(dead_code)]

use std::process::{Command, Output};

/// A `touchc` command, to add arguments, a working directory or standard input to.
pub fn command() -> Command {
    Command::new(env!("CARGO_BIN_EXE_touchc"))
}

/// Runs `touchc ARGS...` to the end and returns its status and output.
pub fn touchc(args: &[&str]) -> Output {
    command().args(args).output().unwrap()
}

/// Standard error as text, for assertions and their messages.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}
