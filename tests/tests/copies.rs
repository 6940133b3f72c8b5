//! Files the workspace holds twice, byte for byte the same. The firmware builds only
//! from files inside its own crate (its build script copies them into `OUT_DIR`), while
//! the workspace keeps the same files where the rest of it looks for them.

use std::fs;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ sits in the workspace")
        .to_path_buf()
}

/// Asserts that `copy` holds the same bytes as `truth` (both from the workspace root).
fn same(truth: &str, copy: &str, how: &str) {
    let read = |p: &str| fs::read(root().join(p)).unwrap_or_else(|e| panic!("{p}: {e}"));
    assert!(
        read(truth) == read(copy),
        "{copy} differs from {truth}; {how}"
    );
}

/// The built-in bank: `examples/emoji/build.sh` makes it, the firmware carries a copy.
#[test]
fn firmware_emoji_bank_is_the_examples() {
    same(
        "examples/emoji/emoji.bank",
        "firmware/emoji.bank",
        "copy examples/emoji/emoji.bank (what examples/emoji/build.sh makes) to firmware/",
    );
}
