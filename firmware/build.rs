//! The target build's inputs: the workspace's `memory.x` (the memory map, at the root,
//! shared with the QEMU test) and this crate's `emoji.bank` (the built-in bank, included
//! by `src/hw/mod.rs`) are copied into `OUT_DIR`, which goes on the linker's search path, where cortex-m-rt's `link.x`
//! finds `memory.x`; then `link.x` and defmt's `defmt.x`. With the feature
//! `default-bank` the bank named by `SLEEVE_DEFAULT_BANK` is copied there too. Host
//! builds (the logic's tests) need none of it.
use std::env;
use std::fmt::Display;
use std::fs;
use std::path::{Path, PathBuf};

/// The files the target build takes (from this crate's folder) and their names in
/// `OUT_DIR`.
const INPUTS: [(&str, &str); 2] = [("../memory.x", "memory.x"), ("emoji.bank", "emoji.bank")];

fn main() {
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("set by cargo"));
    for (path, _) in INPUTS {
        println!("cargo:rerun-if-changed={path}");
    }
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=SLEEVE_DEFAULT_BANK");
    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    for (path, name) in INPUTS {
        copy(&manifest.join(path), &out.join(name));
    }
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    if env::var_os("CARGO_FEATURE_DEFAULT_BANK").is_some() {
        let Some(bank) = env::var_os("SLEEVE_DEFAULT_BANK") else {
            fail("the feature default-bank needs SLEEVE_DEFAULT_BANK=path/to/sleeve.bank");
        };
        // Cargo runs this script in the crate's folder: a relative path is from firmware/.
        let bank = PathBuf::from(bank);
        println!("cargo:rerun-if-changed={}", bank.display());
        if let Err(e) = fs::copy(&bank, out.join("default.bank")) {
            fail(format_args!(
                "SLEEVE_DEFAULT_BANK={}: cannot read it ({e}); a relative path is taken from firmware/",
                bank.display()
            ));
        }
    }
}

/// Copies one of the checkout's files; a missing one is a broken checkout.
fn copy(from: &Path, to: &Path) {
    if let Err(e) = fs::copy(from, to) {
        fail(format_args!(
            "{}: cannot copy it into OUT_DIR ({e})",
            from.display()
        ));
    }
}

/// Stops the build with one line that says why.
fn fail(why: impl Display) -> ! {
    eprintln!("error: {why}");
    std::process::exit(1)
}
