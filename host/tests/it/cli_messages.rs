//! What a person reads from the real `touchc` binary: errors that name the file they
//! are about, exit status 2 for every usage error, values in their shortest form, user
//! text clipped and escaped, each message a line or two, and `--help` without rustdoc.

use crate::bin;
use crate::stimuli;

use std::path::{Path, PathBuf};
use std::process::Command;

use bin::{s, stderr};

/// A stimulus of `seconds` s in `dir`, named `name` inside.
fn stimulus(dir: &Path, name: &str, seconds: u32) -> PathBuf {
    let path = dir.join("s.touch");
    std::fs::write(&path, stimuli::long(name, seconds)).unwrap();
    path
}

/// Runs `touchc args` in `dir` from a shell that first runs `setup`.
fn after(setup: &str, dir: &Path, args: &[&str]) -> std::process::Output {
    Command::new("sh")
        .arg("-c")
        .arg(format!("{setup}; exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_touchc"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

#[test]
fn a_write_that_fails_names_the_output_not_the_temporary() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let stim = stimulus(d, "long", 60);
    // A file-size limit of 1 KiB, its signal ignored: every write past it fails with
    // EFBIG, as a full disk fails with ENOSPC, in the middle of the output.
    let limit = "trap '' XFSZ; ulimit -f 1";
    for (args, output) in [
        (
            vec!["render", s(&stim), "--csv", "-o", "big.csv"],
            "big.csv",
        ),
        (vec!["render", s(&stim), "--wav", "big.wav"], "big.wav"),
        (
            vec!["synth", "stroke", "tap", "shake", "-o", "big.npy"],
            "big.npy",
        ),
    ] {
        let out = after(limit, d, &args);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains(&format!("cannot write {output}")) && err.contains("too large"),
            "{args:?}: {err}"
        );
        assert!(
            !err.contains(".touchc-") && !err.contains(" at path "),
            "{args:?}: names the temporary file: {err}"
        );
        assert!(!d.join(output).exists(), "{args:?}");
    }
    let leftovers: Vec<_> = std::fs::read_dir(d)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}
