#!/usr/bin/env bash
# Records what a `touchc` binary makes of every example, reference and emoji-bank
# recording, under every preset, so that a change meant to keep behaviour can be shown
# to: the stimulus file of `touchc compile` and the output of `touchc track --json`.
#
#   bash scripts/same-outputs.sh path/to/touchc OUT            # record into OUT
#   bash scripts/same-outputs.sh path/to/touchc OUT BEFORE     # record, then compare with BEFORE
#
# The comparison is byte for byte (`cmp`); it ends with "identical" or lists what differs
# and exits 1. Timings are not compared (they are printed to standard error, not written).
set -euo pipefail
if [ $# -lt 2 ] || [ $# -gt 3 ]; then
    echo "usage: $0 TOUCHC OUT [BEFORE]" >&2
    exit 2
fi
touchc="$1"
out="$2"
before="${3:-}"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

recordings=(
    "$here"/examples/*.npy
    "$here"/examples/emoji/*.npy
    "$here"/tests/data/reference/*.npy
)
presets=(touch paper fast exact)

mkdir -p "$out"
for rec in "${recordings[@]}"; do
    # The folder keeps recordings apart that share a file name.
    rel="${rec#"$here"/}"
    name="${rel//\//_}"
    name="${name%.npy}"
    for preset in "${presets[@]}"; do
        "$touchc" compile "$rec" --preset "$preset" -o "$out/$name.$preset.touch" >/dev/null 2>&1
        "$touchc" track "$rec" --preset "$preset" --json -o "$out/$name.$preset.track.json" >/dev/null 2>&1
    done
done
echo "recorded $(find "$out" -type f | wc -l) files into $out"

if [ -n "$before" ]; then
    differ=0
    for f in "$before"/*; do
        g="$out/$(basename "$f")"
        if [ ! -f "$g" ]; then
            echo "missing: $g"
            differ=1
        elif ! cmp -s "$f" "$g"; then
            echo "differs: $(basename "$f")"
            differ=1
        fi
    done
    for g in "$out"/*; do
        [ -f "$before/$(basename "$g")" ] || { echo "new: $g"; differ=1; }
    done
    if [ "$differ" -ne 0 ]; then
        echo "NOT identical"
        exit 1
    fi
    echo "identical"
fi
