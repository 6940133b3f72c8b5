#!/usr/bin/env bash
# `touchc study report` against scipy and scikit-learn: 24 generated response sets
# (degenerate ones included), every statistic within 1e-9 relative. Python runs here
# only, in the venv scripts/oracle-venv.sh makes under target/ when it is missing.
set -euo pipefail
cd "$(dirname "$0")/.."

source scripts/oracle-venv.sh
cargo build --locked -q -p touchc --bin touchc
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$venv/bin/python" host/crates/study/oracle/oracle.py target/debug/touchc "$work"
