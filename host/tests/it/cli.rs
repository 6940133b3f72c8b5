//! The real `touchc` binary: `track --json` on a reference file, the table, bad files.

use crate::bin;
use crate::common;

use bin::{command as touchc, ok};

#[test]
fn track_json_reproduces_the_reference() {
    let dir = common::reference_dir();
    let out = touchc()
        .args(["track", "--preset", "paper", "--json"])
        .arg(dir.join("tap_pat_200.npy"))
        .output()
        .unwrap();
    ok(&out);
    let got: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let text = std::fs::read_to_string(dir.join("tap_pat_200.reference.json")).unwrap();
    let want: serde_json::Value = serde_json::from_str(&text).unwrap();
    let rel = |a: &serde_json::Value, b: &serde_json::Value| {
        let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
        (a - b).abs() / b.abs()
    };
    assert!(rel(&got["mean"], &want["whole_mean"]) < 1e-9);
    assert!(rel(&got["std"], &want["whole_std"]) < 1e-9);
    let (g, w) = (
        got["trajectories"].as_array().unwrap(),
        want["trajectories"].as_array().unwrap(),
    );
    assert_eq!(g.len(), w.len());
    for (g, w) in g.iter().zip(w) {
        assert_eq!(g["frames"], w["times"]);
        assert_eq!(g["rows"], w["rows"]);
        assert_eq!(g["cols"], w["cols"]);
        assert!(rel(&g["total_cost"], &w["total_cost"]) < 1e-9);
    }
}

#[test]
fn track_table_lists_every_trajectory() {
    let p = common::reference_dir().join("stroke_60.npy");
    let out = touchc()
        .args(["track", "--preset", "paper"])
        .arg(&p)
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("1 trajectories"), "{text}");
    assert!(text.contains("1-18") && text.contains("-68.6298"), "{text}");
}

#[test]
fn bad_files_exit_non_zero_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("garbage.npy");
    std::fs::write(&bad, b"not a numpy file").unwrap();
    let missing = dir.path().join("missing.npy");
    for p in [&bad, &missing] {
        let out = touchc()
            .args(["track", "--preset", "paper", "--json"])
            .arg(p)
            .output()
            .unwrap();
        assert!(!out.status.success());
        assert!(out.stdout.is_empty());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(&p.display().to_string()), "{err}");
    }
}

/// The line of `help` that documents `--flag`, with the help text on the next line.
fn help_of(help: &str, flag: &str) -> String {
    let lines: Vec<&str> = help.lines().collect();
    let at = lines
        .iter()
        .position(|l| l.trim_start().starts_with(&format!("--{flag} ")))
        .unwrap_or_else(|| panic!("no --{flag} in\n{help}"));
    format!("{} {}", lines[at], lines.get(at + 1).unwrap_or(&""))
}

#[test]
fn help_prints_the_defaults_of_config_default() {
    let out = touchc().args(["compile", "--help"]).output().unwrap();
    assert!(out.status.success());
    let help = String::from_utf8(out.stdout).unwrap();
    let d = touchc_model::config::Config::default();
    // The default preset (touch) differs from the paper in these two; the help must
    // show the default's values, read here from the library.
    assert_ne!(
        d.track.max_speed_mm_s,
        touchc_model::config::Config::preset(touchc_model::config::Preset::Paper)
            .track
            .max_speed_mm_s
    );
    for (flag, value) in [
        ("max-speed-mm-s", d.track.max_speed_mm_s.to_string()),
        ("entry-cost", d.track.entry_cost.to_string()),
        ("upsample", d.preprocess.upsample.to_string()),
        (
            "grid",
            format!("{},{}", d.placement.grid_x, d.placement.grid_y),
        ),
        ("rate", d.input.rate_hz.to_string()),
    ] {
        let line = help_of(&help, flag);
        assert!(
            line.contains(&format!("[default: {value}]")) || line.contains(&format!(", {value})")),
            "--{flag} should print {value}: {line}"
        );
    }
    assert!(help_of(&help, "preset").contains("[default: touch]"));
    // Every pipeline command takes the same parameter flags.
    for cmd in ["track", "preview", "trade"] {
        let out = touchc().args([cmd, "--help"]).output().unwrap();
        let text = String::from_utf8(out.stdout).unwrap();
        for flag in [
            "preset",
            "config",
            "set",
            "rate",
            "pitch-mm",
            "max-speed-mm-s",
        ] {
            help_of(&text, flag);
        }
    }
}

#[test]
fn preview_honours_the_preset() {
    let dir = tempfile::tempdir().unwrap();
    let rec = common::reference_dir().join("tap_pat_200.npy");
    let frame = |preset: &str| {
        let png = dir.path().join(format!("{preset}.png"));
        let (out_path, rec_path) = (png.to_str().unwrap(), rec.to_str().unwrap());
        let args = ["preview", "--frame", "30", "--preset", preset];
        let out = bin::touchc(&[&args[..], &["-o", out_path, rec_path]].concat());
        assert!(out.status.success(), "{}", bin::stderr(&out));
        std::fs::read(&png).unwrap()
    };
    let (paper, touch) = (frame("paper"), frame("touch"));
    assert_ne!(paper, touch, "paper and touch preview alike");
}
