//! The real binary against files built to hang, crash or exhaust the reader: each is
//! refused with its name and its problem, alone and in the middle of a batch, and the
//! rest of the batch still compiles.

use std::path::{Path, PathBuf};

use ndarray_npy::WriteNpyExt;

use crate::bin::{self, s};
use crate::common;
use crate::poison;

/// Runs `touchc compile ARGS...`.
fn compile(args: &[&Path]) -> std::process::Output {
    bin::command().arg("compile").args(args).output().unwrap()
}

/// A valid recording with one moving contact.
fn good(dir: &Path, name: &str, seed: u64) -> PathBuf {
    let path = dir.join(name);
    common::moving_blobs(80, 1, seed)
        .write_npy(std::fs::File::create(&path).unwrap())
        .unwrap();
    path
}

#[test]
fn compile_refuses_each_poisoned_file_by_name() {
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes, phrase) in poison::poisoned() {
        let input = dir.path().join(name);
        std::fs::write(&input, bytes).unwrap();
        let out_file = dir.path().join("out.touch");
        let out = compile(&[&input, Path::new("-o"), &out_file]);
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
    let good = good(dir.path(), "good.npy", 1);
    let good2 = self::good(dir.path(), "good2.npy", 2);
    for (name, bytes, phrase) in poison::poisoned() {
        let bad = dir.path().join(name);
        std::fs::write(&bad, bytes).unwrap();
        let out_dir = dir.path().join(format!("out_{name}"));
        let out = compile(&[&good, &bad, &good2, Path::new("--out-dir"), &out_dir]);
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
