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
