#!/usr/bin/env bash
# Sourced by the oracle scripts: makes the Python venv they share under target/ (numpy,
# scipy, scikit-learn) when it is missing or broken, and sets `venv` to its path.
# Python is a test oracle here only, never a run-time dependency of touchc.
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
