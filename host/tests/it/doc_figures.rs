//! The figures the user docs quote that a test can measure again in seconds are measured
//! again here and compared with the docs' text (issue 34, N6): the README's compile line,
//! the export guide's sizes, the stimulus figures of docs/performance.md and the twin's
//! test counts. A change that moves one fails here until the doc says the new figure.
//! (The firmware's flash and RAM figures are compared by `firmware/ci.sh`, which
//! measures them; figures that take minutes carry their command and date in the doc.)

use crate::bin::{command, stderr};

use std::path::Path;

fn doc(path: &str) -> String {
    std::fs::read_to_string(Path::new("..").join(path)).unwrap()
}

/// The first number in `text` after `before` (digits, `.`, `,` as thousands).
fn number_after(text: &str, before: &str) -> f64 {
    let at = text
        .find(before)
        .unwrap_or_else(|| panic!("no {before:?} in {text}"));
    let rest = &text[at + before.len()..];
    let digits: String = rest
        .trim_start()
        .chars()
        .take_while(|c| c.is_ascii_digit() || *c == '.' || *c == ',')
        .filter(|c| *c != ',')
        .collect();
    digits
        .trim_end_matches('.')
        .parse()
        .unwrap_or_else(|_| panic!("no number after {before:?} in {text}"))
}

/// `touchc ARGS` from the host folder; its summary line (standard error).
fn summary(args: &[&str]) -> String {
    let out = command().args(args).output().unwrap();
    let err = stderr(&out);
    assert!(out.status.success(), "{args:?}: {err}");
    err.lines()
        .find(|l| l.starts_with("touchc: "))
        .unwrap_or_else(|| panic!("{args:?} printed no summary: {err}"))
        .to_string()
}

/// A summary line without its run time (the part after the last comma) and with the
/// host folder's `../` gone, as the README shows it from the workspace root.
fn without_time(line: &str) -> String {
    let line = line.replace("../", "");
    line[..line.rfind(", ").unwrap()].to_string()
}

#[test]
fn the_readmes_compile_line_is_what_compile_prints() {
    let readme = doc("README.md");
    let shown = readme
        .lines()
        .find(|l| l.starts_with("touchc: examples/stroke.npy -> "))
        .expect("the README shows the example's compile line");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("stroke.touch");
    let line = summary(&[
        "compile",
        "../examples/stroke.npy",
        "-o",
        out.to_str().unwrap(),
    ]);
    let line = line.replace(out.to_str().unwrap(), "examples/stroke.touch");
    assert_eq!(without_time(&line), without_time(shown));
}

/// Every format's bytes (all its files) and the played seconds of `touch` exported.
fn exported(touch: &Path, dir: &Path) -> Vec<(f64, f64)> {
    ["hjif", "haptic", "ahap", "tact"]
        .iter()
        .map(|format| {
            let base = dir.join(format!("x.{format}"));
            let line = summary(&[
                "export",
                touch.to_str().unwrap(),
                "--to",
                format,
                "-o",
                base.to_str().unwrap(),
            ]);
            let bytes = number_after(&line, " s, ");
            (bytes / 1000.0, number_after(&line, "plays "))
        })
        .collect()
}

#[test]
fn the_export_guides_sizes_are_what_export_writes() {
    let text = doc("docs/export.md");
    let row = text
        .lines()
        .find(|l| l.starts_with("| size (`examples/stroke.npy` compiled"))
        .expect("docs/export.md's size row");
    let dir = tempfile::tempdir().unwrap();
    let stroke = dir.path().join("stroke.touch");
    summary(&[
        "compile",
        "../examples/stroke.npy",
        "-o",
        stroke.to_str().unwrap(),
    ]);
    let of_stroke = exported(&stroke, dir.path());
    let mut emoji: Vec<Vec<(f64, f64)>> = Vec::new();
    for entry in std::fs::read_dir("../examples/emoji").unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "touch") {
            emoji.push(exported(&path, dir.path()));
        }
    }
    assert_eq!(emoji.len(), 6, "the six committed emoji");
    let played = number_after(row, "compiled, ");
    assert_eq!(
        format!("{played:.2}"),
        format!("{:.2}", of_stroke[0].1),
        "{row}"
    );
    let cells: Vec<&str> = row.split('|').skip(2).take(4).collect();
    for (f, cell) in cells.iter().enumerate() {
        let shown = number_after(cell, "");
        let low = number_after(cell, "(");
        let high = number_after(cell, "-");
        let kb = |v: f64| format!("{v:.1}");
        let sizes = emoji.iter().map(|e| e[f].0);
        let (min, max) = sizes.fold((f64::MAX, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
        assert_eq!(kb(shown), kb(of_stroke[f].0), "format {f}: {row}");
        assert_eq!((kb(low), kb(high)), (kb(min), kb(max)), "format {f}: {row}");
    }
}

#[test]
fn the_shipped_examples_figures_in_performance_md_are_measured() {
    let text = doc("docs/performance.md");
    let row = text
        .lines()
        .find(|l| l.starts_with("| shipped examples, default `touch` |"))
        .expect("docs/performance.md's row of the shipped examples");
    let dir = tempfile::tempdir().unwrap();
    let (mut low, mut high, mut rms, mut max) = (f64::MAX, 0.0f64, 0.0f64, 0.0f64);
    for name in ["combination", "squeeze", "stroke", "tap_pat"] {
        let out = dir.path().join(format!("{name}.touch"));
        let rec = format!("../examples/{name}.npy");
        let line = summary(&["compile", &rec, "-o", out.to_str().unwrap()]);
        let rate = number_after(&line, " bytes (");
        (low, high) = (low.min(rate), high.max(rate));
        rms = rms.max(number_after(&line, "error "));
        max = max.max(number_after(&line, "% RMS / "));
    }
    let figure = row.rsplit('|').nth(1).unwrap();
    assert_eq!(
        (number_after(figure, ""), number_after(figure, "-")),
        (low.round(), high.round()),
        "B/s: {row}"
    );
    assert_eq!(
        (
            format!("{:.2}", number_after(figure, "within ")),
            format!("{:.2}", number_after(figure, "RMS / "))
        ),
        (format!("{rms:.2}"), format!("{max:.2}")),
        "errors: {row}"
    );
}

#[test]
fn the_twins_test_counts_are_its_files() {
    let text = doc("firmware/twin/README.md");
    let count = |file: &str| {
        doc(&format!("firmware/twin/{file}"))
            .lines()
            .filter(|l| l.trim_start().starts_with("def test_"))
            .count() as f64
    };
    assert_eq!(
        number_after(&text, "`test_twin.py` held "),
        count("test_twin.py")
    );
    assert_eq!(
        number_after(&text, "`test_study.py` held "),
        count("test_study.py")
    );
    assert_eq!(
        number_after(&text, "`test_cli.py` held "),
        count("test_cli.py")
    );
    assert_eq!(
        number_after(&text, "`test_link.py` held "),
        count("test_link.py")
    );
    assert_eq!(
        number_after(&text, "`test_usb.py` held "),
        count("test_usb.py")
    );
}

#[test]
fn the_emoji_tables_lengths_are_what_the_stimuli_play() {
    let text = doc("examples/emoji/README.md");
    let mut rows = 0;
    for row in text
        .lines()
        .filter(|l| l.starts_with("| ") && l.contains(" s | "))
    {
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        let (name, length) = (cells[2], cells[5]);
        let touch = format!("../examples/emoji/{name}.touch");
        let out = command()
            .args(["inspect", &touch, "--json"])
            .output()
            .unwrap();
        assert!(out.status.success(), "{name}: {}", stderr(&out));
        let info: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let played = info["duration_s"].as_f64().unwrap() + info["ramp_ms"].as_f64().unwrap() / 1e3;
        assert_eq!(length, format!("{played:.1} s"), "{row}");
        rows += 1;
    }
    assert_eq!(rows, 6, "the six emoji's rows");
}
