#!/usr/bin/env bash
# Regenerates the shipped example recordings (synthetic, seeded: the same bytes
# every time). Run from anywhere; needs only cargo.
set -euo pipefail
cd "$(dirname "$0")/.."
synth() { cargo run --quiet --release -p touchc -- synth "$@"; }
synth stroke --seed 7 -o examples/stroke.npy
synth tap pat --seed 11 -o examples/tap_pat.npy
synth squeeze --seed 3 -o examples/squeeze.npy
synth stroke tap squeeze shake pat --seed 5 --mask cells120 -o examples/combination.npy
