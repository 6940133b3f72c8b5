#!/usr/bin/env bash
# Rebuilds the default emoji bank from seeded synthetic gestures: the same bytes
# every time (a test compares the committed files with this script's output).
#
#   bash examples/emoji/build.sh            # writes into examples/emoji/
#   OUT=dir TOUCHC=path/to/touchc bash examples/emoji/build.sh
#
# Slot order is the bank's and the sleeve's: button presses select slots 0-5 in
# this order. Why each gesture: see README.md in this folder.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
out="${OUT:-$here}"
mkdir -p "$out"
if [ -n "${TOUCHC:-}" ]; then
    touchc() { "$TOUCHC" "$@"; }
else
    touchc() { cargo run --quiet --release --manifest-path "$here/../../Cargo.toml" -p touchc -- "$@"; }
fi

# slot name       gestures         seed
emoji=(
    "attention  tap pat            101"
    "gratitude  squeeze            102"
    "happiness  shake pat          103"
    "calming    stroke stroke      104"
    "love       stroke squeeze     105"
    "sadness    squeeze squeeze    106"
)

stimuli=()
for line in "${emoji[@]}"; do
    read -r name rest <<<"$line"
    seed="${rest##* }"
    gestures="${rest% *}"
    # shellcheck disable=SC2086 # the gestures are words on purpose
    touchc synth $gestures --seed "$seed" --mask cells142 --noise 0.004 --quiet-frames 30 \
        -o "$out/$name.npy"
    touchc compile "$out/$name.npy" --preset paper --name "$name" -o "$out/$name.touch" >/dev/null
    stimuli+=("$out/$name.touch")
done
touchc bank "${stimuli[@]}" -o "$out/emoji.bank" >/dev/null
# The firmware builds in its own copy (firmware/build.rs; tests/tests/copies.rs holds
# the two equal): rebuilding the bank here rebuilds that copy too.
if [ "$out" = "$here" ]; then
    cp "$out/emoji.bank" "$here/../../firmware/emoji.bank"
fi
