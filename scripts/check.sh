#!/usr/bin/env bash
# Everything CI does, runnable by anyone on a fresh Debian machine with rustup:
# installs what it needs, then formats, lints, tests the host crates, checks the
# protocol crate for the MCU, builds and tests the firmware (QEMU included), and runs
# the firmware guide's commands in a fresh clone.
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

# The AVX2 comparisons (host/crates/wide/src/lib.rs) can only run on a CPU that has AVX2: there a
# skip is a failure; elsewhere each skip prints a SKIPPED line, and this says why.
if grep -qw avx2 /proc/cpuinfo 2>/dev/null; then
    export TOUCHC_REQUIRE_AVX2=1
else
    echo "NOTE: this CPU does not run AVX2: the AVX2 builds are not compared with the baseline (SKIPPED lines below)"
fi

# Each crate alone, so that none passes only on features another member turns on
# (the firmware logic's own run is in firmware/ci.sh: cargo test -p sleeve-firmware).
step "tests: protocol alone"
cargo test --locked -p touch-protocol
step "tests: the host's layer crates (host/crates/)"
cargo test --locked -p touchc-model -p touchc-wide -p touchc-test-rng -p touchc-input -p touchc-synth \
    -p touchc-tracking -p touchc-placement -p touchc-rendering -p touchc-encoding \
    -p touchc-pipeline -p touchc-eval -p touchc-export -p touchc-link -p touchc-study -p touchc-select \
    -p touchc-testkit
step "build: each layer crate alone, with only its own features"
# Tested together above, Cargo unifies their dependencies' features, which hides a crate
# that builds only beside another (touchc-synth once lacked zip's deflate backend).
for crate in touchc-model touchc-wide touchc-test-rng touchc-input touchc-synth \
    touchc-tracking touchc-placement touchc-rendering touchc-encoding touchc-pipeline \
    touchc-eval touchc-export touchc-link touchc-study touchc-select touchc-testkit; do
    cargo check --locked -q -p "$crate" --all-targets
done
step "MSRV: the workspace's rust-version (1.89) builds the host, the protocol and the firmware"
# Cargo.toml's rust-version is a promise to whoever builds with an older toolchain; a
# check build on exactly that toolchain keeps it (own target dir: other rustc, other
# artefacts).
msrv=$(sed -n 's/^rust-version = "\(.*\)"/\1/p' Cargo.toml)
rustup toolchain list | grep -q "^$msrv-" || rustup toolchain install "$msrv" --profile minimal
rustup target list --toolchain "$msrv" --installed | grep -qx thumbv7em-none-eabihf \
    || rustup target add --toolchain "$msrv" thumbv7em-none-eabihf
CARGO_TARGET_DIR=target/msrv cargo "+$msrv" check --locked -q --workspace --exclude sleeve-firmware
(cd firmware && CARGO_TARGET_DIR=../target/msrv cargo "+$msrv" check --locked -q)
step "tests: touchc alone"
cargo test --locked -p touchc
step "tests: end-to-end alone"
cargo test --locked -p touch-e2e

step "study statistics against scipy / scikit-learn (venv under target/)"
bash scripts/study-oracle.sh

step "features scorer's regression (smartcore) against scikit-learn (the same venv)"
bash scripts/logistic-oracle.sh

step "study page in headless Chromium against the in-memory sleeve (apt chromium when missing)"
bash scripts/study-browser.sh

step "API docs: every public item documented, every link resolved"
RUSTDOCFLAGS='-D warnings' cargo doc --no-deps --workspace --exclude sleeve-firmware --locked -q

step "pipeline library without the CLI and the pictures (no clap, plotters, gif, png, indicatif)"
cargo build -p touchc --lib --no-default-features --locked

step "no_std check of protocol for the MCU"
cargo build -p touch-protocol --target thumbv7em-none-eabihf --release --locked

step "firmware: host logic tests, release build, QEMU target test"
bash firmware/ci.sh

step "firmware/README.md's commands, as written, in a fresh clone (up to the probe)"
bash firmware/guide-check.sh

printf '\nall checks passed in %ss\n' "$(( $(date +%s) - start ))"
