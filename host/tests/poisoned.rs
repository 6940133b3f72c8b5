//! The real binary against files built to hang, crash or exhaust the reader: each is
//! refused with its name and its problem, alone and in the middle of a batch, and the
//! rest of the batch still compiles.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

#[path = "common/poison.rs"]
mod poison;

fn touchc(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_touchc"))
        .args(args)
        .output()
        .unwrap()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn synth(dir: &Path, name: &str, gesture: &str) -> PathBuf {
    let path = dir.join(format!("{name}.npy"));
    let out = touchc(&["synth", gesture, "--quiet-frames", "25", "-o", s(&path)]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    path
}

#[test]
fn compile_refuses_each_poisoned_file_by_name() {
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes, phrase) in poison::poisoned() {
        let input = dir.path().join(name);
        std::fs::write(&input, bytes).unwrap();
        let out_file = dir.path().join("out.touch");
        let out = touchc(&["compile", s(&input), "-o", s(&out_file)]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name}: {stderr}");
        assert!(
            stderr.contains(s(&input)) && stderr.contains(phrase),
            "{name}: {stderr}"
        );
        assert!(!stderr.contains("panicked"), "{name}: {stderr}");
        assert!(!out_file.exists(), "{name}");
    }
}

#[test]
fn a_batch_survives_each_poisoned_file() {
    let dir = tempfile::tempdir().unwrap();
    let good = synth(dir.path(), "good", "tap");
    let good2 = synth(dir.path(), "good2", "stroke");
    for (name, bytes, phrase) in poison::poisoned() {
        let bad = dir.path().join(name);
        std::fs::write(&bad, bytes).unwrap();
        let out_dir = dir.path().join(format!("out_{name}"));
        let out = touchc(&[
            "compile",
            s(&good),
            s(&bad),
            s(&good2),
            "--out-dir",
            s(&out_dir),
        ]);
        let (stdout, stderr) = (
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr),
        );
        assert_eq!(out.status.code(), Some(1), "{name}: {stderr}");
        let row = |input: &Path| {
            stdout
                .lines()
                .find(|l| l.starts_with(s(input)))
                .unwrap_or_else(|| panic!("{name}: no summary row for {input:?}: {stdout}"))
                .to_owned()
        };
        assert!(row(&bad).contains("FAILED"), "{name}: {stdout}");
        assert!(row(&good).contains(" ok "), "{name}: {stdout}");
        assert!(row(&good2).contains(" ok "), "{name}: {stdout}");
        assert!(
            stderr.contains(s(&bad)) && stderr.contains(phrase),
            "{name}: {stderr}"
        );
        assert!(
            stderr.contains("1 of 3 recordings failed"),
            "{name}: {stderr}"
        );
        assert!(out_dir.join("good.touch").exists(), "{name}");
        assert!(out_dir.join("good2.touch").exists(), "{name}");
        let stem = Path::new(name).file_stem().unwrap().to_str().unwrap();
        assert!(!out_dir.join(format!("{stem}.touch")).exists(), "{name}");
    }
}
