#!/usr/bin/env bash
# Everything CI does, runnable by anyone on a fresh Debian machine with rustup:
# installs what it needs, then formats, lints, tests the host crates, checks the
# protocol crate for the MCU, and builds and tests the firmware (QEMU included).
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n==> %s\n' "$*"; }
start=$(date +%s)

step "toolchain: thumbv7em-none-eabihf target, rustfmt, clippy"
rustup target list --installed | grep -qx thumbv7em-none-eabihf || rustup target add thumbv7em-none-eabihf
rustup component list --installed | grep -q '^rustfmt' || rustup component add rustfmt
rustup component list --installed | grep -q '^clippy' || rustup component add clippy

step "format"
cargo fmt --all --check

step "clippy (host crates, all targets)"
cargo clippy --all-targets --locked -- -D warnings

step "clippy (protocol for the MCU, with defmt)"
cargo clippy -p touch-protocol --target thumbv7em-none-eabihf --features defmt --locked -- -D warnings

step "host tests (protocol, touchc, end-to-end)"
cargo test --locked

step "pipeline library without the CLI and the pictures (no clap, plotters, gif, png, indicatif)"
cargo build -p touchc --lib --no-default-features --locked

step "no_std check of protocol for the MCU"
cargo build -p touch-protocol --target thumbv7em-none-eabihf --release --locked

step "firmware: host logic tests, release build, QEMU target test"
bash firmware/ci.sh

printf '\nall checks passed in %ss\n' "$(( $(date +%s) - start ))"
