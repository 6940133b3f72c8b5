//! Linker setup for the target build: `memory.x` from the workspace root, then
//! cortex-m-rt's `link.x` and defmt's `defmt.x`. Host builds (tests) need none of it.
use std::env;
use std::path::PathBuf;

fn main() {
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let root = manifest.parent().expect("firmware/ lives in the workspace");
    println!("cargo:rerun-if-changed={}", root.join("memory.x").display());
    println!("cargo:rerun-if-env-changed=SLEEVE_DEFAULT_BANK");
    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    println!("cargo:rustc-link-search={}", root.display());
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    if env::var_os("CARGO_FEATURE_DEFAULT_BANK").is_some() {
        let bank = env::var("SLEEVE_DEFAULT_BANK")
            .expect("feature default-bank needs SLEEVE_DEFAULT_BANK=path/to/sleeve.bank");
        let bank = std::fs::canonicalize(&bank).expect("SLEEVE_DEFAULT_BANK names a readable file");
        println!("cargo:rerun-if-changed={}", bank.display());
        println!(
            "cargo:rustc-env=SLEEVE_DEFAULT_BANK_PATH={}",
            bank.display()
        );
    }
}
