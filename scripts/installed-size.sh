#!/usr/bin/env bash
# The installed `touchc` as a user gets it, measured: `cargo install --path host --locked`
# into a scratch root (or a binary given, which firmware/guide-check.sh installed that way),
# its size against the budget, and the panic locations and symbols that must stay in it.
#
#   bash scripts/installed-size.sh           # installs into a scratch root, then measures
#   bash scripts/installed-size.sh TOUCHC    # measures an installed binary
#
# Prints one line with the figures (docs/performance.md, "Builds and tests"); exits 1 when
# the binary is 15 MB or more, or has lost its source locations or its symbol table.
set -euo pipefail
cd "$(dirname "$0")/.."
budget=15000000

if [ $# -gt 1 ]; then
    echo "usage: $0 [TOUCHC]" >&2
    exit 2
fi
if [ $# -eq 1 ]; then
    bin="$1"
else
    root="$(mktemp -d)"
    trap 'rm -rf "$root"' EXIT
    cargo install --path host --locked --root "$root" --quiet
    bin="$root/bin/touchc"
fi

size=$(stat -c %s "$bin")
# A panic's message names its file and line from data the compiler keeps whatever the
# debug info: the workspace's source paths in the binary are those locations.
locations=$(grep -aoE '(host|protocol)/[A-Za-z0-9_/-]+\.rs' "$bin" | sort -u | wc -l)
# A backtrace names its functions from the symbol table.
symbols=$(nm "$bin" 2>/dev/null | wc -l)
debug=$(readelf -S -W "$bin" | grep -c '\.debug_' || true)
awk -v size="$size" -v budget="$budget" -v debug="$debug" -v loc="$locations" -v sym="$symbols" 'BEGIN {
    printf "installed touchc: %d B (%.1f MB, budget %.0f MB), %d debug sections, %d source files named for panic locations, %d symbols\n", size, size / 1e6, budget / 1e6, debug, loc, sym
}'
fail=0
if [ "$size" -ge "$budget" ]; then
    echo "the installed touchc is over its budget of $budget B" >&2
    fail=1
fi
if [ "$locations" -lt 50 ]; then
    echo "the installed touchc names only $locations source files: panics would not say where" >&2
    fail=1
fi
if [ "$symbols" -lt 1000 ]; then
    echo "the installed touchc has lost its symbol table ($symbols symbols): backtraces would not name functions" >&2
    fail=1
fi
exit "$fail"
