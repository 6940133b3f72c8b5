//! Following the docs leaves no untracked files in the checkout (issue 34, N5). Every
//! command line of the user docs' `sh` blocks is either run as written, with this
//! build's `touchc`, in a fresh copy of the tracked files, or named in [`NOT_RUN`] with
//! the reason; afterwards `git status` of the copy must be empty: whatever the commands
//! wrote is outside the checkout or covered by `.gitignore`. A block starts in the
//! workspace root, or in the folder its first line names (`# in examples/emoji/`), as
//! in the maker's guide, whose blocks `firmware/guide-check.sh` runs the same way and
//! holds to the same empty status.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The user docs whose blocks are run here (the maker's guide is guide-check's).
const DOCS: &[&str] = &[
    "README.md",
    "docs/algorithm.md",
    "docs/architecture.md",
    "docs/export.md",
    "docs/fuzzing.md",
    "docs/hardware.md",
    "docs/performance.md",
    "docs/select.md",
    "docs/study.md",
    "docs/trade.md",
    "firmware/twin/README.md",
    "examples/emoji/README.md",
    "tests/data/reference/README.md",
    "protocol/SPEC.md",
];

/// Lines not run here, by how they begin, and why.
const NOT_RUN: &[(&str, &str)] = &[
    ("bash scripts/check.sh", "CI itself (.ci/run)"),
    (
        "cargo install",
        "installs into ~/.cargo, outside the checkout",
    ),
    ("rustup ", "installs a toolchain, outside the checkout"),
    (
        "cargo build --release",
        "builds into target/, which is ignored",
    ),
    (
        "cargo +nightly fuzz",
        "30 minutes a target; the corpus folders are ignored",
    ),
    ("nice -n 15 cargo +nightly fuzz", "as cargo +nightly fuzz"),
    (
        "touchc sleeve",
        "needs a sleeve: firmware/twin/test_cli.py runs it on the twin",
    ),
    (
        "bash firmware/twin/run.sh",
        "the twin's own checks, which firmware/ci.sh runs",
    ),
    ("touchc trade", "minutes a run; writes into /tmp as written"),
    ("touchc synth $G", "writes into /tmp"),
    ("cp examples/*.npy /tmp", "writes into /tmp"),
    (
        "touchc select",
        "needs a labelled data set of one's own (data/); tests/it/cli_select.rs runs it",
    ),
    (
        "bash examples/emoji/build.sh",
        "rebuilds the tracked emoji; tests/it/emoji_bank.rs holds that they reproduce",
    ),
    ("OUT=/tmp/", "writes into /tmp"),
    (
        "RAYON_NUM_THREADS=2 nice timeout 2400 target/release/examples/trade",
        "the selection's benchmark, minutes; it writes nothing",
    ),
    (
        "bash scripts/select-oracle.sh",
        "the features scorer against scikit-learn: release builds and a venv, minutes",
    ),
];

/// The workspace root (the clone).
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

fn git(dir: &Path, args: &[&str]) -> String {
    let out = Command::new("git")
        .args(["-c", "user.name=docs", "-c", "user.email=docs@localhost"])
        .args(args)
        .current_dir(dir)
        .output()
        .expect("git runs");
    assert!(out.status.success(), "git {args:?}: {out:?}");
    String::from_utf8(out.stdout).unwrap()
}

/// A fresh copy of the tracked files (as the working tree has them), committed.
fn fresh_copy(into: &Path) -> PathBuf {
    let from = root();
    let copy = into.join("touchc");
    for file in git(&from, &["ls-files", "-z"]).split('\0') {
        let src = from.join(file);
        // A tracked file deleted in the working tree is not part of what is tested.
        if file.is_empty() || !src.is_file() {
            continue;
        }
        let dst = copy.join(file);
        std::fs::create_dir_all(dst.parent().unwrap()).unwrap();
        std::fs::copy(&src, &dst).unwrap();
    }
    git(&copy, &["init", "-q"]);
    git(&copy, &["add", "-A"]);
    git(&copy, &["commit", "-q", "-m", "copy"]);
    copy
}

/// A doc's `sh` blocks: (the folder the block starts in, its command lines, with
/// continuation lines joined).
fn blocks(doc: &str, text: &str) -> Vec<(String, Vec<String>)> {
    let mut found = Vec::new();
    let mut lines = text.lines();
    while let Some(line) = lines.next() {
        if line.trim_end() != "```sh" {
            continue;
        }
        let mut dir = String::new();
        let mut commands: Vec<String> = Vec::new();
        let mut continued = false;
        for (i, line) in lines
            .by_ref()
            .take_while(|l| !l.starts_with("```"))
            .enumerate()
        {
            if i == 0 {
                if let Some(named) = line.strip_prefix("# in ") {
                    if named != "the workspace root" {
                        assert!(named.ends_with('/'), "{doc}: a block's folder: {line}");
                        dir = named.to_string();
                    }
                    continue;
                }
            }
            let trimmed = line.trim();
            if continued {
                commands.last_mut().unwrap().push_str(trimmed);
            } else if !trimmed.is_empty() && !trimmed.starts_with('#') {
                commands.push(trimmed.to_string());
            }
            continued = trimmed.ends_with('\\');
            if continued {
                let last = commands.last_mut().unwrap();
                last.pop();
            }
        }
        found.push((dir, commands));
    }
    found
}

/// The line with the workspace's `cargo run ... -p touchc --` spelled as `touchc`.
fn as_installed(line: &str) -> String {
    let mut line = line.to_string();
    for run in [
        "cargo run --release -p touchc -- ",
        "cargo run --quiet --release -p touchc -- ",
    ] {
        line = line.replace(run, "touchc ");
    }
    line
}

#[test]
fn following_the_docs_leaves_no_untracked_files() {
    let scratch = tempfile::tempdir().unwrap();
    let copy = fresh_copy(scratch.path());
    let home = scratch.path().join("home");
    std::fs::create_dir(&home).unwrap();
    let bin_dir = Path::new(env!("CARGO_BIN_EXE_touchc")).parent().unwrap();
    let path = format!("{}:{}", bin_dir.display(), std::env::var("PATH").unwrap());
    let (mut ran, mut not_run) = (0, 0);
    for doc in DOCS {
        let text = std::fs::read_to_string(copy.join(doc)).unwrap();
        for (dir, commands) in blocks(doc, &text) {
            let mut cwd = copy.join(&dir);
            for command in commands {
                let line = as_installed(&command);
                if NOT_RUN.iter().any(|(start, _)| line.starts_with(start)) {
                    not_run += 1;
                    continue;
                }
                if let Some(to) = line.strip_prefix("cd ") {
                    cwd = cwd.join(to.trim());
                    assert!(cwd.starts_with(&copy), "{doc}: {line} leaves the checkout");
                    continue;
                }
                let out = Command::new("bash")
                    .args(["-euo", "pipefail", "-c", &line])
                    .current_dir(&cwd)
                    .env("PATH", &path)
                    .env("HOME", &home)
                    .output()
                    .unwrap();
                assert!(
                    out.status.success(),
                    "{doc}: `{line}` in {} failed: {}",
                    cwd.display(),
                    String::from_utf8_lossy(&out.stderr)
                );
                ran += 1;
            }
        }
    }
    // The README's compile and completions and the export guide's lines at least.
    assert!(ran >= 12, "only {ran} doc commands ran ({not_run} not run)");
    let status = git(&copy, &["status", "--porcelain", "--untracked-files=all"]);
    assert!(
        status.is_empty(),
        "following the docs left files in the checkout (neither ignored nor tracked):\n{status}"
    );
}
