//! The real `touchc` binary as a Unix tool: `-` for standard streams, pipes closed
//! early, full disks, symlinks, FIFOs, the umask, killed runs, exit codes, one message
//! per error, escaped names, and stimuli too long to hold in memory.

use crate::bin;
use crate::stimuli;

use std::io::Read;
use std::os::unix::fs::{FileTypeExt, PermissionsExt};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use bin::{command, fed, s, stderr, touchc};

/// A 1 s stimulus named `name` in `dir`.
fn short_stimulus(dir: &Path, name: &str) -> PathBuf {
    let path = dir.join(format!("{name}.touch"));
    let swell: stimuli::Shape = |x| 0.5 * (std::f64::consts::PI * x).sin();
    std::fs::write(
        &path,
        stimuli::stimulus(name, &stimuli::one_second(0.0, &[(2, swell)])),
    )
    .unwrap();
    path
}

/// A stimulus of `seconds` s in `dir` (a few dozen bytes, see [`stimuli::long`]).
fn long_stimulus(dir: &Path, seconds: u32) -> PathBuf {
    let path = dir.join(format!("long{seconds}.touch"));
    std::fs::write(&path, stimuli::long("long", seconds)).unwrap();
    path
}

/// Runs `touchc args` with its standard output a pipe whose reader is gone before the
/// first byte is written (`touchc ... | head -0`, deterministically).
fn with_closed_stdout(args: &[&str]) -> std::process::Output {
    let mut child = command()
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    child.wait_with_output().unwrap()
}

fn assert_quiet_success(out: &std::process::Output, what: &str) {
    let err = stderr(out);
    assert!(out.status.success(), "{what}: {:?}: {err}", out.status);
    assert!(
        !err.contains("panicked") && !err.contains("error"),
        "{what}: {err}"
    );
}

#[test]
fn a_closed_pipe_ends_quietly_with_status_0() {
    let dir = tempfile::tempdir().unwrap();
    let long = long_stimulus(dir.path(), 600);
    let out = with_closed_stdout(&["render", s(&long), "--csv"]);
    assert_quiet_success(&out, "render --csv");
    let out = with_closed_stdout(&["render", s(&long), "--wav", "-"]);
    assert_quiet_success(&out, "render --wav -");
    let out = with_closed_stdout(&["inspect", s(&long)]);
    assert_quiet_success(&out, "inspect");
    let out = with_closed_stdout(&["track", "../examples/stroke.npy"]);
    assert_quiet_success(&out, "track");
    let out = with_closed_stdout(&["completions", "bash"]);
    assert_quiet_success(&out, "completions");

    // `render | head -1`: the reader takes one line and leaves mid-stream.
    let mut child = command()
        .args(["render", s(&long), "--csv"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = [0u8; 64];
    child
        .stdout
        .as_mut()
        .unwrap()
        .read_exact(&mut first)
        .unwrap();
    assert!(first.starts_with(b"t_s,ch0"));
    drop(child.stdout.take());
    assert_quiet_success(&child.wait_with_output().unwrap(), "render | head");
}

#[test]
fn a_full_disk_is_an_error_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let file = short_stimulus(dir.path(), "love");
    let full = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .unwrap();
    let out = command()
        .args(["inspect", s(&file)])
        .stdout(full)
        .output()
        .unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("cannot write standard output") && err.contains("No space left"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn dash_is_standard_output_and_input() {
    let dir = tempfile::tempdir().unwrap();
    let file = short_stimulus(dir.path(), "love");
    let bytes = std::fs::read(&file).unwrap();
    let run = |args: &[&str], stdin: Option<&[u8]>| {
        let out = fed(
            command().args(args).current_dir(dir.path()),
            stdin.unwrap_or_default(),
        );
        assert!(out.status.success(), "{args:?}: {}", stderr(&out));
        out.stdout
    };
    let csv = run(&["render", s(&file), "--csv", "-o", "-"], None);
    assert!(csv.starts_with(b"t_s,ch0") && csv.len() > 1000);
    assert_eq!(run(&["render", "-", "--csv"], Some(&bytes)), csv);
    let wav = run(&["render", s(&file), "--wav", "-", "--rate", "1000"], None);
    assert!(wav.starts_with(b"RIFF") && wav.len() == 68 + 16 * (csv_rows(&csv)));
    let text = run(&["inspect", "-", "-o", "-"], Some(&bytes));
    assert!(String::from_utf8_lossy(&text).starts_with("love (stimulus v3)"));
    let npy = run(&["synth", "tap", "-o", "-"], None);
    assert!(npy.starts_with(b"\x93NUMPY"));
    let json = run(
        &[
            "track",
            concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/stroke.npy"),
            "--json",
            "-o",
            "-",
        ],
        None,
    );
    assert!(json.starts_with(b"{"));
    // None of these made a file named `-`.
    assert!(!dir.path().join("-").exists());
}

fn csv_rows(csv: &[u8]) -> usize {
    csv.iter().filter(|&&b| b == b'\n').count() - 1
}

fn is_symlink(path: &Path) -> bool {
    std::fs::symlink_metadata(path)
        .unwrap()
        .file_type()
        .is_symlink()
}

#[test]
fn outputs_through_symlinks_land_in_their_target() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("real.npy");
    let link = dir.path().join("link.npy");
    std::fs::write(&target, b"old").unwrap();
    std::os::unix::fs::symlink("real.npy", &link).unwrap();
    let out = touchc(&["synth", "tap", "-o", s(&link)]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(is_symlink(&link));
    assert!(std::fs::read(&target).unwrap().starts_with(b"\x93NUMPY"));

    // A dangling link: its target is created, the link kept.
    let dangling = dir.path().join("dangling.npy");
    std::os::unix::fs::symlink("sub/made.npy", &dangling).unwrap();
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    let out = touchc(&["synth", "tap", "-o", s(&dangling)]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(is_symlink(&dangling));
    assert!(dir.path().join("sub/made.npy").is_file());
}

#[test]
fn a_fifo_is_written_in_place_not_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let file = short_stimulus(dir.path(), "love");
    let fifo = dir.path().join("out.csv");
    let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(made.success());
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read(fifo).unwrap())
    };
    let out = touchc(&["render", s(&file), "--csv", "-o", s(&fifo)]);
    assert!(out.status.success(), "{}", stderr(&out));
    let got = reader.join().unwrap();
    assert!(got.starts_with(b"t_s,ch0") && csv_rows(&got) > 1000);
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

/// Runs `touchc args` from a shell that first runs `setup` (a `umask`, a `ulimit`).
fn after(setup: &str, args: &[&str]) -> std::process::Output {
    Command::new("sh")
        .arg("-c")
        .arg(format!("{setup}; exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_touchc"))
        .args(args)
        .output()
        .unwrap()
}

/// Runs `touchc args` under `umask`.
fn with_umask(umask: &str, args: &[&str]) -> std::process::Output {
    after(&format!("umask {umask}"), args)
}

fn mode(path: &Path) -> u32 {
    std::fs::metadata(path).unwrap().permissions().mode() & 0o7777
}

#[test]
fn new_outputs_follow_the_umask_and_overwrites_keep_the_mode() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rec.npy");
    for (umask, want) in [("022", 0o644), ("027", 0o640), ("002", 0o664)] {
        let _ = std::fs::remove_file(&out);
        let run = with_umask(umask, &["synth", "tap", "-o", s(&out)]);
        assert!(run.status.success(), "{}", stderr(&run));
        assert_eq!(mode(&out), want, "umask {umask}");
    }
    std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o604)).unwrap();
    let run = with_umask("077", &["synth", "pat", "-o", s(&out)]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert_eq!(mode(&out), 0o604, "an overwrite keeps the file's mode");
}

fn temporaries(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.path())
        .filter(|p| {
            let n = p.file_name().unwrap().to_string_lossy();
            n.starts_with(".touchc-") && n.ends_with(".tmp")
        })
        .collect()
}

#[test]
fn a_killed_runs_temporary_is_removed_by_the_next_run() {
    let dir = tempfile::tempdir().unwrap();
    let long = long_stimulus(dir.path(), 4 * 3600);
    let csv = dir.path().join("out.csv");
    let mut child = command()
        .args(["render", s(&long), "--csv", "-o", s(&csv)])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Wait until it is well into writing, then SIGKILL it: no destructor runs.
    let deadline = Instant::now() + Duration::from_secs(60);
    let partial = loop {
        let tmps = temporaries(dir.path());
        if let Some(t) = tmps.first() {
            if std::fs::metadata(t).map(|m| m.len()).unwrap_or(0) > 1 << 20 {
                break t.clone();
            }
        }
        assert!(Instant::now() < deadline, "no temporary file appeared");
        std::thread::sleep(Duration::from_millis(20));
    };
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(partial.exists(), "the killed run left its temporary");
    assert!(!csv.exists(), "and no output");
    // The next run writing into the directory cleans up after it, once the temporary
    // is older than the 2 s margin that protects a sibling's not-yet-locked one.
    std::thread::sleep(Duration::from_millis(2500));
    let out = touchc(&["synth", "tap", "-o", s(&dir.path().join("rec.npy"))]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(temporaries(dir.path()), Vec::<PathBuf>::new());
}

#[test]
fn exit_codes_say_usage_or_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let file = short_stimulus(dir.path(), "love");
    let help = touchc(&["--help"]);
    let help = String::from_utf8_lossy(&help.stdout);
    assert!(
        help.contains("Exit status: 0 success") && help.contains("2 usage"),
        "{help}"
    );
    for args in [
        vec!["render", s(&file)],
        vec!["render", s(&file), "-o", "x.csv"],
        vec!["plot", s(&file), "-o", "x.txt"],
        vec!["compile", "a.npy", "b.npy"],
        vec!["inspect"],
        vec!["no-such-command"],
    ] {
        let out = touchc(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
    }
    let junk = dir.path().join("junk.touch");
    std::fs::write(&junk, b"not a stimulus").unwrap();
    for args in [
        vec!["inspect", s(&junk)],
        vec!["render", s(&junk), "--csv"],
        vec!["compile", "no-such-file.npy"],
    ] {
        let out = touchc(&args);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {}", stderr(&out));
    }
}

#[test]
fn each_error_is_said_once_without_temporary_paths() {
    let dir = tempfile::tempdir().unwrap();
    let out = touchc(&[
        "compile",
        "../examples/stroke.npy",
        "--upsample",
        "1000",
        "-o",
        s(&dir.path().join("x.touch")),
    ]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    // A knob out of range names the knob, its value and its range, once.
    assert_eq!(err.matches("1000").count(), 1, "{err}");
    assert!(err.contains("upsample") && err.contains("32"), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");

    let missing = dir.path().join("no/such/dir/rec.npy");
    let out = touchc(&["synth", "tap", "-o", s(&missing)]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("rec.npy") && !err.contains(".touchc-"),
        "{err}"
    );
    assert_eq!(err.matches("No such file").count(), 1, "{err}");
}

#[test]
fn the_thermal_limit_is_reported_once() {
    let dir = tempfile::tempdir().unwrap();
    // A firm press held for 90 s: past the coil's I^2 t budget (under `paper`, whose
    // output is pinned; the default plays this press on more actuators, and within it).
    let (frames, rows, cols) = (1840, 8, 21);
    let rec = ndarray::Array3::from_shape_fn((frames, rows, cols), |(t, r, c)| {
        let d2 = (r as f64 - 3.5).powi(2) + (c as f64 - 10.0).powi(2);
        let on = if (40..frames - 40).contains(&t) {
            1.0
        } else {
            0.0
        };
        on * 2.0 * (-d2 / 4.0).exp()
    });
    let npy = dir.path().join("hold.npy");
    std::fs::write(&npy, touchc_synth::to_npy(&rec).unwrap()).unwrap();
    let out = touchc(&[
        "compile",
        s(&npy),
        "-o",
        s(&dir.path().join("hold.touch")),
        "--preset",
        "paper",
    ]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("thermal load"), "{err}");
    assert_eq!(err.matches("thermal load").count(), 1, "{err}");
    // The command line, not the library, names the flag that puts it right.
    assert!(
        err.trim_end().ends_with("(use --fit to scale it down)"),
        "{err}"
    );
    assert!(!dir.path().join("hold.touch").exists());
}

#[test]
fn names_with_control_codes_are_escaped_on_the_terminal() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("evil.touch");
    std::fs::write(
        &path,
        stimuli::stimulus("evil\x1b[2J\x1b]0;pwned\x07", &[[0.0; 8], [0.1; 8]]),
    )
    .unwrap();
    let out = touchc(&["inspect", s(&path)]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(!text.contains('\x1b') && !text.contains('\x07'), "{text:?}");
    assert!(
        text.starts_with("evil\\u{1b}[2J\\u{1b}]0;pwned\\u{7} (stimulus"),
        "{text}"
    );
    // JSON carries the name exactly, escaped by JSON's own rules.
    let out = touchc(&["inspect", s(&path), "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["name"], "evil\x1b[2J\x1b]0;pwned\x07");
    // An error message quoting a path with control codes is escaped too.
    let out = touchc(&["inspect", "no\x1b[31mfile.touch"]);
    assert!(!stderr(&out).contains('\x1b'), "{}", stderr(&out));
}

/// Runs `touchc args` with at most `mb` MB of data memory (RLIMIT_DATA covers the heap,
/// including large allocations made with mmap).
fn with_memory_limit(mb: u32, args: &[&str]) -> std::process::Output {
    after(&format!("ulimit -d {}", mb * 1024), args)
}

#[test]
fn long_stimuli_render_and_plot_in_constant_memory() {
    let dir = tempfile::tempdir().unwrap();
    // 3 hours: 10.8 M ticks, 173 MB of codes held in memory by a non-streaming player.
    let long = long_stimulus(dir.path(), 3 * 3600);
    assert!(std::fs::metadata(&long).unwrap().len() < 100);
    let png = dir.path().join("long.png");
    let out = with_memory_limit(64, &["plot", s(&long), "-o", s(&png)]);
    assert!(out.status.success(), "plot: {}", stderr(&out));
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    let wav = dir.path().join("long.wav");
    let out = with_memory_limit(
        64,
        &["render", s(&long), "--wav", s(&wav), "--rate", "1000"],
    );
    assert!(out.status.success(), "wav: {}", stderr(&out));
    let ticks = 3 * 3600 * 1000 + 1 + 10;
    assert_eq!(std::fs::metadata(&wav).unwrap().len(), 68 + 16 * ticks);
}

#[test]
fn completions_for_three_shells() {
    for shell in ["bash", "zsh", "fish"] {
        let out = touchc(&["completions", shell]);
        assert!(out.status.success(), "{shell}: {}", stderr(&out));
        let script = String::from_utf8(out.stdout).unwrap();
        for word in ["touchc", "compile", "render", "inspect", "preset"] {
            assert!(script.contains(word), "{shell} lacks {word}");
        }
    }
    let out = touchc(&["completions", "tcsh-or-so"]);
    assert_eq!(out.status.code(), Some(2));
}
