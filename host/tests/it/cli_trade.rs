//! The real binary: `--preset` and the knobs, batch compiles, `touchc trade`.

use crate::bin;

use bin::{ok, refused, s, touchc};
use std::path::{Path, PathBuf};

fn synth(dir: &Path, name: &str, gesture: &str) -> PathBuf {
    let path = dir.join(format!("{name}.npy"));
    let out = touchc(&["synth", gesture, "--quiet-frames", "25", "-o", s(&path)]);
    ok(&out);
    path
}

fn report(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

#[test]
fn presets_and_knobs_reach_the_compile() {
    let dir = tempfile::tempdir().unwrap();
    let rec = synth(dir.path(), "stroke", "stroke");
    let out = dir.path().join("x.touch");
    let json = dir.path().join("r.json");
    let compile = |extra: &[&str]| {
        let mut a = vec!["compile", s(&rec), "-o", s(&out), "--report", s(&json)];
        a.extend_from_slice(extra);
        touchc(&a)
    };
    let ok = compile(&["--preset", "fast"]);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    assert!(report(&json)["transforms_evaluated"].as_u64().unwrap() < 4200);

    let ok = compile(&[
        "--preset",
        "exact",
        "--grid",
        "3,2",
        "--set",
        "detect.sigma_k=1.5",
    ]);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    assert_eq!(report(&json)["transforms"], 9);

    // A config file lays over the preset; unknown keys are refused by name.
    let toml = dir.path().join("c.toml");
    std::fs::write(&toml, "[placement]\ngrid_x = 2\n").unwrap();
    let ok = compile(&["--preset", "fast", "--config", s(&toml)]);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    assert_eq!(report(&json)["transforms"], 420);
    let bad = compile(&["--set", "placement.nope=1"]);
    assert!(refused(&bad).contains("nope"));
    let bad = compile(&["--upsample", "0"]);
    assert!(String::from_utf8_lossy(&bad.stderr).contains("preprocess.upsample = 0"));
}

#[test]
fn batch_compiles_the_good_files_and_reports_the_bad() {
    let dir = tempfile::tempdir().unwrap();
    let a = synth(dir.path(), "a", "stroke");
    let b = synth(dir.path(), "b", "tap");
    let bad = dir.path().join("bad.npy");
    std::fs::write(&bad, b"not numpy").unwrap();
    let out_dir = dir.path().join("out");
    let out = touchc(&[
        "compile",
        s(&a),
        s(&bad),
        s(&b),
        "--out-dir",
        s(&out_dir),
        "--report",
        "r.json",
    ]);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(!out.status.success());
    assert!(
        stdout.contains("FAILED") && stdout.contains("b.npy"),
        "{stdout}"
    );
    assert!(
        stderr.contains("bad.npy") && stderr.contains("1 of 3"),
        "{stderr}"
    );
    for f in ["a.touch", "b.touch", "a.json", "b.json"] {
        assert!(out_dir.join(f).exists(), "{f}");
    }
    assert!(!out_dir.join("bad.touch").exists());

    // Several recordings need --out-dir; one stem twice is refused before any work.
    let out = touchc(&["compile", s(&a), s(&b)]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("--out-dir"));
    let sub = dir.path().join("sub");
    std::fs::create_dir(&sub).unwrap();
    let a2 = synth(&sub, "a", "pat");
    let out = touchc(&["compile", s(&a), s(&a2), "--out-dir", s(&out_dir)]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("would both compile"));
}

/// The batch table shows, per recording, what the single compile line does about the
/// touch: the tracking coverage and the rendered coverage (`played`), each as its
/// report holds it.
#[test]
fn batch_table_shows_coverage_and_played_per_recording() {
    let dir = tempfile::tempdir().unwrap();
    let a = synth(dir.path(), "a", "stroke");
    let b = synth(dir.path(), "b", "pat");
    let out_dir = dir.path().join("out");
    let out = touchc(&[
        "compile",
        s(&a),
        s(&b),
        "--out-dir",
        s(&out_dir),
        "--report",
        "r.json",
    ]);
    ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let mut lines = stdout.lines();
    let header: Vec<&str> = lines.next().unwrap().split_whitespace().collect();
    let column = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .unwrap_or_else(|| panic!("no {name} column: {stdout}"))
    };
    // "rms % fs" is three words of the header and one cell of a row.
    let shift = 2;
    let (coverage, played) = (column("coverage") - shift, column("played") - shift);
    for (stem, rec) in [("a", &a), ("b", &b)] {
        let row: Vec<&str> = stdout
            .lines()
            .find(|l| l.starts_with(s(rec)))
            .unwrap_or_else(|| panic!("no row for {stem}: {stdout}"))
            .split_whitespace()
            .collect();
        let r = report(&out_dir.join(format!("{stem}.json")));
        let cell = |i: usize| row[i].parse::<f64>().unwrap();
        let rendered = r["rendered_coverage"].as_f64().unwrap();
        assert!(rendered > 0.0, "{stem}: nothing played");
        assert!((cell(coverage) - r["coverage"].as_f64().unwrap()).abs() <= 0.005);
        assert!((cell(played) - rendered).abs() <= 0.005, "{stem}: {stdout}");
    }
}

#[test]
fn trade_prints_every_preset_against_exact() {
    let dir = tempfile::tempdir().unwrap();
    let rec = synth(dir.path(), "tap", "tap");
    let csv = dir.path().join("t.csv");
    let svg = dir.path().join("t.svg");
    let json = dir.path().join("t.json");
    let out = touchc(&[
        "trade",
        s(&rec),
        "--repeat",
        "1",
        "--threads",
        "1",
        "--csv",
        s(&csv),
        "--svg",
        s(&svg),
        "--json",
        s(&json),
    ]);
    ok(&out);
    let text = std::fs::read_to_string(&csv).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 5, "{text}");
    let exact: Vec<&str> = lines[4].split(',').collect();
    assert_eq!(exact[1], "exact");
    // Exact against itself: no gap, no difference, full agreement.
    assert_eq!(&exact[12..16], &["0.000", "0.000", "0.000", "100.0"]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("fast"));
    // The JSON holds the same rows as the CSV, typed.
    let rows = report(&json);
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), 4);
    assert_eq!(rows[3]["preset"], "exact");
    assert_eq!(rows[3]["rms_vs_exact_pct"], 0.0);
    assert_eq!(
        rows[3]["transforms"][1].as_u64().unwrap().to_string(),
        exact[11]
    );
    let svg = std::fs::read_to_string(&svg).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("exact"));
}

#[test]
fn trade_measures_recall_against_a_synthetic_truth() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("fast.npy");
    let truth = dir.path().join("fast.truth.json");
    // A 1 m/s stroke at 20 Hz: twice the paper's link gate, well inside touch's.
    let out = touchc(&[
        "synth",
        "stroke",
        "--speed",
        "1.0",
        "--seed",
        "3",
        "--truth",
        s(&truth),
        "-o",
        s(&rec),
    ]);
    ok(&out);
    let csv = dir.path().join("t.csv");
    let args = ["trade", s(&rec), "--repeat", "1", "--threads", "1"];
    let out = touchc(&[&args[..], &["--truth", s(&truth), "--csv", s(&csv)]].concat());
    ok(&out);
    let text = std::fs::read_to_string(&csv).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let col = header
        .iter()
        .position(|h| *h == "recall")
        .expect("a recall column");
    let recall = |preset: &str| -> f64 {
        let line = text
            .lines()
            .find(|l| l.split(',').nth(1) == Some(preset))
            .unwrap();
        line.split(',').nth(col).unwrap().parse().unwrap()
    };
    assert_eq!(recall("touch"), 1.0, "{text}");
    assert!(recall("paper") < 1.0, "{text}");

    // One truth file per recording, or a usage error naming both counts.
    let out = touchc(&[&args[..], &[s(&rec), "--truth", s(&truth)]].concat());
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("2 recordings, 1 truth files"));
}

#[test]
fn trade_cases_takes_no_recordings_and_seeds_only_with_cases() {
    let dir = tempfile::tempdir().unwrap();
    let rec = synth(dir.path(), "stroke", "stroke");
    for args in [
        vec!["trade", "--cases", s(&rec)],
        vec!["trade", "--seeds", "2", s(&rec)],
        vec!["trade", "--cases", "--seeds", "0"],
        vec!["trade"],
    ] {
        let out = touchc(&args);
        let err = refused(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains("--cases") || err.contains("--seeds") || err.contains("RECORDINGS"),
            "{args:?}: {err}"
        );
    }
}

/// A knob of a table only the chosen preset has (`detect.split`) reaches that preset;
/// the `exact` reference, which has no such table, runs without it and says so, where
/// the whole trade used to be refused.
#[test]
fn trade_applies_a_knob_to_the_presets_whose_table_has_it() {
    let dir = tempfile::tempdir().unwrap();
    // A pat: a flat hand, whose rim the footprint threshold reaches.
    let rec = synth(dir.path(), "pat", "pat");
    let json = dir.path().join("t.json");
    let trade = |set: &str| {
        touchc(&[
            "trade",
            s(&rec),
            "--preset",
            "touch",
            "--set",
            set,
            "--repeat",
            "1",
            "--json",
            s(&json),
        ])
    };
    let out = trade("track.regions.footprint_psi=0.06");
    ok(&out);
    let err = bin::stderr(&out);
    assert!(
        err.contains("--set track.regions.footprint_psi=0.06 is not applied to --preset exact")
            && err.contains("`track.regions` is off"),
        "{err}"
    );
    let with = report(&json);
    let narrow = with.as_array().unwrap()[0]["bytes"].clone();
    ok(&trade("track.regions.footprint_psi=0.03"));
    let default = report(&json).as_array().unwrap()[0]["bytes"].clone();
    // The knob reached `touch`: a narrower footprint is another stimulus.
    assert_ne!(narrow, default);
    // A knob the chosen preset cannot take is still refused.
    let out = touchc(&[
        "trade",
        s(&rec),
        "--preset",
        "paper",
        "--set",
        "track.regions.footprint_psi=0.06",
    ]);
    assert!(refused(&out).contains("off under --preset paper"));
}
