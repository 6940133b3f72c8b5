#!/usr/bin/env bash
# The features scorer's regression (touchc-select's `Logistic`, smartcore's L-BFGS) against
# scikit-learn's LogisticRegression on seven generated tables: every class probability
# within 1e-4. Python runs here only, in the venv scripts/oracle-venv.sh makes.
set -euo pipefail
cd "$(dirname "$0")/.."

source scripts/oracle-venv.sh
cargo build --locked -q --release -p touchc-select --example fit_logistic
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$venv/bin/python" host/crates/select/oracle/logistic.py target/release/examples/fit_logistic "$work"
