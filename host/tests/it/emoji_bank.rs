//! The default emoji bank in `examples/emoji/` is what its script makes: the script
//! runs with this build's `touchc` into a scratch directory and every committed file
//! (recordings, stimuli, bank) must come out byte for byte the same.

use std::path::Path;
use std::process::Command;

const FILES: [&str; 6] = [
    "attention",
    "gratitude",
    "happiness",
    "calming",
    "love",
    "sadness",
];

#[test]
fn committed_emoji_bank_is_what_the_script_builds() {
    let emoji = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/emoji");
    let out = tempfile::tempdir().unwrap();
    let status = Command::new("bash")
        .arg(emoji.join("build.sh"))
        .env("TOUCHC", env!("CARGO_BIN_EXE_touchc"))
        .env("OUT", out.path())
        .status()
        .unwrap();
    assert!(status.success(), "build.sh failed: {status}");
    let mut names: Vec<String> = FILES
        .iter()
        .flat_map(|n| [format!("{n}.npy"), format!("{n}.touch")])
        .collect();
    names.push("emoji.bank".into());
    for name in names {
        let committed = std::fs::read(emoji.join(&name)).unwrap();
        let built = std::fs::read(out.path().join(&name)).unwrap();
        assert!(
            committed == built,
            "examples/emoji/{name} differs from what build.sh makes: rerun `bash examples/emoji/build.sh`"
        );
    }
}
