//! One rule for every command that writes: no output replaces one of the command's
//! inputs (by path, through a symlink or a hard link, or a batch's own inputs), and no
//! two outputs of one command are the same file. Each refusal is a usage error (exit
//! status 2) naming both files, made before any work, and leaves every file as it was.

use crate::bin;
use crate::stimuli;

use std::path::{Path, PathBuf};

use bin::{command, s, stderr};

/// `rec.npy`, a short recording, and `s.touch`, a 1 s stimulus, in `dir`.
fn files(dir: &Path) -> (PathBuf, PathBuf) {
    let rec = dir.join("rec.npy");
    std::fs::copy("../examples/stroke.npy", &rec).unwrap();
    let stim = dir.join("s.touch");
    let swell: stimuli::Shape = |x| 0.5 * (std::f64::consts::PI * x).sin();
    std::fs::write(
        &stim,
        stimuli::stimulus("s", &stimuli::one_second(0.0, &[(2, swell)])),
    )
    .unwrap();
    (rec, stim)
}

/// Every file under `dir` with its bytes (symlinks as their target's name).
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let meta = std::fs::symlink_metadata(&p).unwrap();
            if meta.is_dir() {
                stack.push(p);
            } else if meta.file_type().is_symlink() {
                let target = std::fs::read_link(&p).unwrap();
                out.push((p, target.to_string_lossy().into_owned().into_bytes()));
            } else {
                let bytes = std::fs::read(&p).unwrap();
                out.push((p, bytes));
            }
        }
    }
    out.sort();
    out
}

/// Runs `touchc args` in `dir` and checks the refusal: exit status 2, a message that
/// names every one of `names`, and every file in `dir` exactly as it was.
fn assert_refused(dir: &Path, args: &[&str], names: &[&str]) {
    let before = snapshot(dir);
    let out = command().args(args).current_dir(dir).output().unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
    for name in names {
        assert!(err.contains(name), "{args:?}: want {name:?} in {err}");
    }
    assert!(err.contains("same file"), "{args:?}: {err}");
    assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
    assert!(snapshot(dir) == before, "{args:?} changed a file: {err}");
}

#[test]
fn compile_never_writes_over_its_recording() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    files(d);
    assert_refused(d, &["compile", "rec.npy", "-o", "rec.npy"], &["rec.npy"]);
    assert_refused(d, &["compile", "./rec.npy", "-o", "rec.npy"], &["rec.npy"]);
    assert_refused(
        d,
        &["compile", "rec.npy", "--report", "rec.npy", "-o", "x.touch"],
        &["--report", "rec.npy"],
    );
    // A recording named .touch: the default output is the recording itself.
    std::fs::copy(d.join("rec.npy"), d.join("rec.touch")).unwrap();
    assert_refused(
        d,
        &["compile", "rec.touch"],
        &["rec.touch", "default output"],
    );
    std::fs::remove_file(d.join("rec.touch")).unwrap();
    // Through a symlink and through a hard link.
    std::os::unix::fs::symlink("rec.npy", d.join("link.touch")).unwrap();
    assert_refused(
        d,
        &["compile", "rec.npy", "-o", "link.touch"],
        &["link.touch", "rec.npy"],
    );
    std::fs::hard_link(d.join("rec.npy"), d.join("hard.touch")).unwrap();
    assert_refused(
        d,
        &["compile", "rec.npy", "-o", "hard.touch"],
        &["hard.touch", "rec.npy"],
    );
    // The parameter files are inputs too.
    std::fs::write(d.join("c.toml"), "[signal]\nlowpass_hz = 4.0\n").unwrap();
    assert_refused(
        d,
        &["compile", "rec.npy", "--config", "c.toml", "-o", "c.toml"],
        &["c.toml", "--config"],
    );
}

#[test]
fn a_batch_never_writes_over_its_own_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    files(d);
    std::fs::create_dir(d.join("out")).unwrap();
    std::fs::copy(d.join("rec.npy"), d.join("out/a.touch")).unwrap();
    assert_refused(
        d,
        &["compile", "rec.npy", "out/a.touch", "--out-dir", "out"],
        &["out/a.touch"],
    );
    // The batch's reports are outputs too.
    std::fs::rename(d.join("out/a.touch"), d.join("out/b.json")).unwrap();
    assert_refused(
        d,
        &[
            "compile",
            "out/b.json",
            "rec.npy",
            "--out-dir",
            "out",
            "--report",
            "r.json",
        ],
        &["out/b.json"],
    );
}

#[test]
fn stimulus_commands_never_write_over_their_stimulus() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    files(d);
    assert_refused(
        d,
        &["render", "s.touch", "--csv", "-o", "s.touch"],
        &["s.touch"],
    );
    assert_refused(d, &["render", "s.touch", "--wav", "s.touch"], &["--wav"]);
    assert_refused(d, &["inspect", "s.touch", "-o", "s.touch"], &["s.touch"]);
    assert_refused(d, &["bank", "s.touch", "-o", "s.touch"], &["s.touch"]);
    std::fs::copy(d.join("s.touch"), d.join("s.svg")).unwrap();
    assert_refused(d, &["plot", "s.svg", "-o", "s.svg"], &["s.svg"]);
    // Standard input that is the file itself.
    let before = snapshot(d);
    let out = command()
        .args(["inspect", "-", "-o", "s.touch"])
        .current_dir(d)
        .stdin(std::fs::File::open(d.join("s.touch")).unwrap())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(snapshot(d) == before);
}

#[test]
fn recording_commands_never_write_over_their_recording() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    files(d);
    assert_refused(d, &["track", "rec.npy", "-o", "rec.npy"], &["rec.npy"]);
    std::fs::copy(d.join("rec.npy"), d.join("rec.gif")).unwrap();
    assert_refused(d, &["preview", "rec.gif", "-o", "rec.gif"], &["rec.gif"]);
    assert_refused(
        d,
        &["trade", "rec.npy", "--repeat", "1", "--csv", "rec.npy"],
        &["--csv", "rec.npy"],
    );
}

#[test]
fn two_outputs_of_one_command_are_never_one_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    files(d);
    assert_refused(
        d,
        &["compile", "rec.npy", "--report", "x.json", "-o", "./x.json"],
        &["--report", "-o", "x.json"],
    );
    assert_refused(
        d,
        &["synth", "tap", "-o", "t.npy", "--truth", "t.npy"],
        &["--truth", "t.npy"],
    );
    assert_refused(
        d,
        &[
            "render", "s.touch", "--csv", "-o", "a.out", "--wav", "a.out",
        ],
        &["--wav", "a.out"],
    );
    std::fs::create_dir(d.join("sub")).unwrap();
    assert_refused(
        d,
        &[
            "trade",
            "rec.npy",
            "--csv",
            "t.csv",
            "--json",
            "sub/../t.csv",
        ],
        &["--csv", "--json"],
    );
}

#[test]
fn devices_are_streams_and_never_clash() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    files(d);
    let out = command()
        .args([
            "compile",
            "rec.npy",
            "-o",
            "/dev/null",
            "--report",
            "/dev/null",
        ])
        .current_dir(d)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let out = command()
        .args(["inspect", s(&d.join("s.touch")), "-o", "/dev/null"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
}
