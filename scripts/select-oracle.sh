#!/usr/bin/env bash
# `touchc select`'s features scorer against a linear model of about a hundred simple
# features fitted by scikit-learn, on the same grouped folds of the seven-gesture
# synthetic set (10 x 10 grid at 54 Hz, 833 recordings, ten people): prints both
# accuracies and fails when touchc is more than 3 points below. About a minute of CPU
# after the release builds; not part of check.sh (docs/select.md has the table).
# Python runs here only, in the venv scripts/oracle-venv.sh makes (shared with
# scripts/study-oracle.sh).
set -euo pipefail
cd "$(dirname "$0")/.."

source scripts/oracle-venv.sh
cargo build --locked -q --release -p touchc --bin touchc
cargo build --locked -q --release -p touchc-select --example labelled_set
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
target/release/examples/labelled_set "$work/data" 119 540 7 10 gestures
target/release/touchc select "$work/data/manifest.csv" --model features --rate 54 -o "$work/out" >/dev/null
"$venv/bin/python" host/crates/select/oracle/linear.py "$work/out" "$work/data" 54
