//! Running the real `touchc` binary, for the tests that drive it.

use std::path::Path;
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

/// Fails the test with `touchc`'s standard error unless the run succeeded.
pub fn ok(out: &Output) {
    assert!(out.status.success(), "{}", stderr(out));
}

/// Fails the test unless the run failed, and returns its standard error (which names
/// the problem) for the caller's assertions.
pub fn refused(out: &Output) -> String {
    assert!(!out.status.success(), "expected a refusal: {}", stderr(out));
    stderr(out)
}

/// A path as a command-line argument (the tests' temporary paths are UTF-8).
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}
