//! `--help` as a person reads it, and the pipes it promises.

use crate::bin;

use std::process::Stdio;

use bin::{command, fed, s, stderr, touchc};

const SUBCOMMANDS: [&str; 10] = [
    "compile",
    "track",
    "inspect",
    "render",
    "plot",
    "preview",
    "bank",
    "synth",
    "trade",
    "completions",
];

fn help(args: &[&str]) -> String {
    let out = touchc(args);
    assert!(out.status.success(), "{args:?}: {}", stderr(&out));
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn no_help_shows_rustdoc_syntax() {
    for flag in ["-h", "--help"] {
        let top = help(&[flag]);
        assert!(!top.contains("[`"), "touchc {flag}: {top}");
        for sub in SUBCOMMANDS {
            let text = help(&[sub, flag]);
            assert!(!text.contains("[`"), "touchc {sub} {flag}: {text}");
            assert!(!text.contains("Tuning::"), "touchc {sub} {flag}: {text}");
        }
    }
    // The links became the flags they stand for.
    let synth = help(&["synth", "--help"]);
    assert!(synth.contains("(`--speed` sets its speed)"), "{synth}");
}

#[test]
fn compile_help_is_grouped_with_examples() {
    let text = help(&["compile", "--help"]);
    assert!(text.contains(".npz"), "{text}");
    let at = |what: &str| {
        text.find(what)
            .unwrap_or_else(|| panic!("no {what:?} in {text}"))
    };
    // Each flag under its heading, the headings in order.
    let (input, knobs, output, examples) = (
        at("\nInput and sensor:"),
        at("\nPreset and knobs:"),
        at("\nOutput:"),
        at("\nExamples:"),
    );
    assert!(
        input < knobs && knobs < output && output < examples,
        "{text}"
    );
    for flag in ["--rate <HZ>", "--pitch-mm <MM>"] {
        assert!((input..knobs).contains(&at(flag)), "{flag}: {text}");
    }
    for flag in [
        "--preset <PRESET>",
        "--set <",
        "--upsample <K>",
        "--lowpass-hz",
    ] {
        assert!((knobs..output).contains(&at(flag)), "{flag}: {text}");
    }
    for flag in ["--output <OUTPUT>", "--out-dir <", "--report <"] {
        assert!((output..examples).contains(&at(flag)), "{flag}: {text}");
    }
    assert!(
        text.contains("touchc synth stroke -o - | touchc compile -"),
        "{text}"
    );
    // Why a stimulus outlasts its recording, where its duration is explained.
    assert!(
        text.contains("longer than its recording") && text.contains("rings out"),
        "{text}"
    );
}

#[test]
fn synth_pipes_into_compile() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tap.touch");
    let mut synth = command()
        .args(["synth", "tap", "-o", "-"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let compiled = command()
        .args(["compile", "-", "-o", s(&out)])
        .stdin(synth.stdout.take().unwrap())
        .output()
        .unwrap();
    assert!(synth.wait().unwrap().success());
    let err = stderr(&compiled);
    assert!(compiled.status.success(), "{err}");
    assert!(err.contains("standard input -> "), "{err}");
    let shown = touchc(&["inspect", s(&out)]);
    let text = String::from_utf8(shown.stdout).unwrap();
    assert!(text.starts_with("stdin (stimulus"), "{text}");

    // And a stimulus to standard output, read back from standard input.
    let rec = std::fs::read("../examples/stroke.npy").unwrap();
    let compiled = fed(command().args(["compile", "-", "-o", "-"]), &rec);
    assert!(compiled.status.success(), "{}", stderr(&compiled));
    assert!(compiled.stdout.starts_with(b"TCHS"));
    // Standard input with no -o: there is no name to derive the output from.
    let out = command()
        .args(["compile", "-"])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}

/// Every command that reads a recording takes `-` for standard input, as `--help` says
/// `compile` does: `track`, `preview` and `trade` read the same bytes as from the file.
#[test]
fn recording_readers_take_standard_input() {
    let dir = tempfile::tempdir().unwrap();
    let rec = std::fs::read("../examples/tap_pat.npy").unwrap();
    let piped = |args: &[&str]| fed(command().args(args), &rec);
    let from_stdin = piped(&["track", "-", "--json"]);
    assert!(from_stdin.status.success(), "{}", stderr(&from_stdin));
    let from_file = touchc(&["track", "../examples/tap_pat.npy", "--json"]);
    assert_eq!(from_stdin.stdout, from_file.stdout);

    let gif = dir.path().join("p.gif");
    let previewed = piped(&["preview", "-", "--every", "20", "-o", s(&gif)]);
    assert!(previewed.status.success(), "{}", stderr(&previewed));
    assert!(std::fs::read(&gif).unwrap().starts_with(b"GIF8"));

    let traded = piped(&["trade", "-", "--preset", "paper", "--repeat", "1"]);
    assert!(traded.status.success(), "{}", stderr(&traded));
    assert!(!traded.stdout.is_empty());
}
