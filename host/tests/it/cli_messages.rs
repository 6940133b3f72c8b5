//! What a person reads from the real `touchc` binary: errors that name the file they
//! are about, exit status 2 for every usage error, values in their shortest form, user
//! text clipped and escaped, each message a line or two, and `--help` without rustdoc.

use crate::bin;
use crate::stimuli;

use std::path::{Path, PathBuf};
use std::process::Command;

use bin::{s, stderr, touchc};

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

/// `rec.npy`, a short recording, in `dir`.
fn recording(dir: &Path) -> PathBuf {
    let rec = dir.join("rec.npy");
    std::fs::copy("../examples/stroke.npy", &rec).unwrap();
    rec
}

/// Runs `touchc args` and returns its standard error after checking that it exited
/// with `code` and said one line.
fn said_once(args: &[&str], code: i32) -> String {
    let out = touchc(args);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(code), "{args:?}: {err}");
    assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
    assert!(!err.contains("\\n"), "{args:?}: a literal \\n: {err}");
    err
}

#[test]
fn every_usage_error_exits_2() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rec = recording(d);
    let stim = stimulus(d, "s", 1);
    let out = d.join("x.touch");
    let many: Vec<&str> = std::iter::repeat_n(s(&stim), 33).collect();
    let mut bank = vec!["bank"];
    bank.extend(many);
    bank.extend(["-o", "b.bank"]);
    let wav = d.join("x.wav");
    for args in [
        vec!["compile", s(&rec), "-o", s(&out), "--upsample", "0"],
        vec![
            "compile",
            s(&rec),
            "-o",
            s(&out),
            "--set",
            "track.max_speed=5",
        ],
        vec!["compile", s(&rec), "-o", s(&out), "--set", "no-equals-sign"],
        vec!["compile", s(&rec), "-o", s(&out), "--rate", "2000"],
        vec!["compile", s(&rec), "-o", s(&out), "--pitch-mm", "1e308"],
        vec![
            "compile",
            s(&rec),
            "-o",
            s(&out),
            "--config",
            "missing.toml",
        ],
        vec![
            "compile",
            s(&rec),
            "-o",
            s(&out),
            "--layout",
            "missing.toml",
        ],
        vec![
            "compile",
            s(&rec),
            "-o",
            s(&out),
            "--set",
            "signal.lowpass_hz=400",
        ],
        vec!["track", s(&rec), "--set", "detect.sigma_k=1e308"],
        vec!["synth", "tap", "--noise=-1", "-o", "t.npy"],
        vec!["synth", "tap", "--flicker=-1e308", "-o", "t.npy"],
        vec![
            "synth",
            "tap",
            "--quiet-frames",
            "100000000000",
            "-o",
            "t.npy",
        ],
        vec!["plot", s(&stim), "-o", "p.svg", "--width", "0"],
        vec!["render", s(&stim), "--wav", s(&wav), "--rate", "500"],
        vec!["trade", s(&rec), "--threads", "0"],
        bank,
    ] {
        let err = said_once(&args, 2);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    assert!(!out.exists() && !wav.exists());
}

#[test]
fn messages_say_what_is_wrong_in_a_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rec = recording(d);
    let out = d.join("x.touch");
    let compile = |extra: &[&str]| {
        let mut args = vec!["compile", s(&rec), "-o", s(&out)];
        args.extend(extra);
        said_once(&args, 2)
    };
    let err = compile(&["--set", "track.max_speed=5"]);
    assert!(
        err.contains("unknown field `max_speed`") && err.contains("max_speed_mm_s"),
        "{err}"
    );
    // The rate is checked as an input, against the range any recording may have,
    // not in the signal stage against one of its internal knobs.
    let err = compile(&["--rate", "2000"]);
    assert!(
        err.contains("--rate 2000") && err.contains("1 to 1000 Hz"),
        "{err}"
    );
    assert!(!err.contains("frame_rate_hz"), "{err}");
    // Shortest form: 1e308, not 309 digits.
    let err = said_once(&["synth", "tap", "--flicker=-1e308", "-o", "t.npy"], 2);
    assert!(err.contains("-1e308") && err.len() < 200, "{err}");
    let err = compile(&["--pitch-mm", "1e308"]);
    assert!(err.contains("1e308") && err.len() < 200, "{err}");
}

#[test]
fn user_text_is_clipped_and_escaped() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rec = recording(d);
    let out = d.join("x.touch");
    // A 5 MB string value and a 200 KB nested value in a config file.
    let big = d.join("big.toml");
    let long = "A".repeat(5_000_000);
    std::fs::write(&big, format!("[input]\nbaseline = \"{long}\"\n")).unwrap();
    let nested = d.join("nested.toml");
    let deep = format!("{}{}", "[".repeat(100_000), "]".repeat(100_000));
    std::fs::write(&nested, format!("[input]\nbaseline = {deep}\n")).unwrap();
    let set = format!("input.baseline=\"{}\"", "B".repeat(100_000));
    for args in [
        vec!["compile", s(&rec), "-o", s(&out), "--config", s(&big)],
        vec!["compile", s(&rec), "-o", s(&out), "--config", s(&nested)],
        vec!["compile", s(&rec), "-o", s(&out), "--set", &set],
    ] {
        let err = said_once(&args, 2);
        assert!(err.len() < 600, "{} bytes: {}", err.len(), &err[..600]);
        assert!(!err.contains(&"A".repeat(81)) && !err.contains(&"B".repeat(81)));
        assert!(!err.contains(&"[".repeat(81)), "{err}");
    }
    // clap's own errors echo the value too.
    let value = "C".repeat(100_000);
    let run = touchc(&["compile", s(&rec), "--upsample", &value]);
    let err = stderr(&run);
    assert_eq!(run.status.code(), Some(2));
    assert!(err.len() < 600 && !err.contains(&"C".repeat(81)), "{err}");

    // A bidi override in a stimulus name, then in a path: shown as an escape.
    let evil = "\u{202e}kcab\u{200b}";
    let ok = touchc(&["compile", s(&rec), "-o", s(&out), "--name", evil]);
    assert!(ok.status.success(), "{}", stderr(&ok));
    let shown = touchc(&["inspect", s(&out)]);
    let text = String::from_utf8(shown.stdout).unwrap();
    assert!(text.contains("\\u{202e}kcab\\u{200b}"), "{text}");
    assert!(
        !text.contains('\u{202e}') && !text.contains('\u{200b}'),
        "{text}"
    );
    let missing = d.join(format!("{evil}.touch"));
    let err = said_once(&["inspect", s(&missing)], 1);
    assert!(
        err.contains("\\u{202e}") && !err.contains('\u{202e}'),
        "{err}"
    );
}

#[test]
fn a_bank_index_entry_inside_the_index_is_not_called_outside_the_bank() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let stim = stimulus(d, "s", 1);
    let bank = d.join("b.bank");
    assert!(touchc(&["bank", s(&stim), s(&stim), "-o", s(&bank)])
        .status
        .success());
    let mut bytes = std::fs::read(&bank).unwrap();
    // Entry 0's offset: right after the prefix, the slot count and the layout hash, the
    // first index byte.
    let at = touch_protocol::container::PREFIX_LEN + 2 + 4;
    let inside_index = u32::try_from(at).unwrap();
    bytes[at..at + 4].copy_from_slice(&inside_index.to_le_bytes());
    let body = bytes.len() - touch_protocol::container::CRC_LEN;
    let crc = touch_protocol::container::crc32(&bytes[..body]);
    bytes[body..].copy_from_slice(&crc.to_le_bytes());
    std::fs::write(&bank, &bytes).unwrap();
    let err = said_once(&["inspect", s(&bank)], 1);
    assert!(err.contains("index entry 0"), "{err}");
    assert!(!err.contains("outside"), "{err}");
}

#[test]
fn a_wav_too_long_says_how_long_the_stimulus_is() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 600 s at 768 kHz: 460 M sample frames, past the 268 M a WAV's 32-bit sizes hold.
    let stim = stimulus(d, "long", 600);
    let wav = d.join("x.wav");
    let err = said_once(
        &["render", s(&stim), "--wav", s(&wav), "--rate", "768000"],
        1,
    );
    assert!(err.contains("x.wav"), "{err}");
    assert!(err.contains("600.0 s"), "the stimulus's length: {err}");
    assert!(err.contains("4608"), "the stimulus's frames: {err}");
    assert!(err.contains("26843"), "the limit: {err}");
    assert!(!wav.exists());
}

#[test]
fn names_from_paths_are_escaped_in_tables_and_notes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rec = recording(d);
    let evil = d.join("\u{202e}r.npy");
    std::fs::copy(&rec, &evil).unwrap();
    let out_dir = d.join("out");
    let out = touchc(&["compile", s(&evil), "--out-dir", s(&out_dir)]);
    assert!(out.status.success(), "{}", stderr(&out));
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(
        table.contains("\\u{202e}r.npy") && !table.contains('\u{202e}'),
        "{table}"
    );
    let stim = stimulus(d, "s", 1);
    let bank = d.join("\u{202e}b.bank");
    let out = touchc(&["bank", s(&stim), "-o", s(&bank)]);
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("\\u{202e}b.bank") && !err.contains('\u{202e}'),
        "{err}"
    );
}
