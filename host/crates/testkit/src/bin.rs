//! Running the real `touchc` binary, for the tests that drive it.

use std::path::Path;
use std::process::{Command, Output};

/// An executable under test: its path, as cargo gives it to an integration test or
/// bench of the package that builds it (`Bin(env!("CARGO_BIN_EXE_touchc"))`; the kit
/// cannot name it itself, being another package).
#[derive(Debug, Clone, Copy)]
pub struct Bin(pub &'static str);

impl Bin {
    /// A command running the executable, to add arguments, a working directory or
    /// standard input to.
    pub fn command(self) -> Command {
        Command::new(self.0)
    }

    /// Runs it with `args` to the end and returns its status and output.
    pub fn run(self, args: &[&str]) -> Output {
        self.command()
            .args(args)
            .output()
            .unwrap_or_else(|e| panic!("{}: {e}", self.0))
    }
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
