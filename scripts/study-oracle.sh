#!/usr/bin/env bash
# `touchc study report` against scipy and scikit-learn: 24 generated response sets
# (degenerate ones included), every statistic within 1e-9 relative. Python runs here
# only, in a venv under target/ that this script makes when it is missing.
set -euo pipefail
cd "$(dirname "$0")/.."

venv=target/study-oracle-venv
if ! "$venv/bin/python" -c 'import numpy, scipy, sklearn' 2>/dev/null; then
    if ! python3 -c 'import ensurepip' 2>/dev/null; then
        sudo=""; [ "$(id -u)" = 0 ] || sudo=sudo
        $sudo apt-get update -q && $sudo apt-get install -y -q python3-venv
    fi
    rm -rf "$venv"
    python3 -m venv "$venv"
    "$venv/bin/pip" install -q --disable-pip-version-check numpy scipy scikit-learn
fi
cargo build --locked -q -p touchc --bin touchc
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$venv/bin/python" host/crates/study/oracle/oracle.py target/debug/touchc "$work"
