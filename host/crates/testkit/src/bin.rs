//! Running the real `touchc` binary, for the tests that drive it.

use std::io::Write;
use std::path::Path;
use std::process::{Command, Output, Stdio};

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

/// Runs `cmd` with `input` on its standard input (written from another thread, so a
/// large input cannot deadlock against a full output pipe) and returns its output.
pub fn fed(cmd: &mut Command, input: &[u8]) -> Output {
    let mut child = cmd
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let bytes = input.to_vec();
    // A command that stops reading early (an error) closes the pipe: its output says why.
    let writer = std::thread::spawn(move || drop(stdin.write_all(&bytes)));
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap();
    out
}

/// Standard error as text, for assertions and their messages.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Fails the test with `touchc`'s standard error unless the run succeeded.
pub fn ok(out: &Output) {
    assert!(out.status.success(), "{}: {}", out.status, stderr(out));
}

/// Fails the test unless the run failed, and returns its standard error (which names
/// the problem) for the caller's assertions.
pub fn refused(out: &Output) -> String {
    assert!(
        !out.status.success(),
        "expected a refusal, got {}: {}",
        out.status,
        stderr(out)
    );
    stderr(out)
}

/// A path as a command-line argument (the tests' temporary paths are UTF-8).
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}
