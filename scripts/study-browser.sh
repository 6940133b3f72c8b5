#!/usr/bin/env bash
# The study page in headless Chromium: a scripted participant runs a whole
# `touchc study run` session against the in-memory sleeve, killed mid-round and
# resumed (tests/browser/study_page.py). Installs Debian's chromium and
# chromium-driver, and selenium into the test venv under target/, when missing.
# `bash scripts/study-browser.sh docs/study` also saves the docs' screenshots.
set -euo pipefail
cd "$(dirname "$0")/.."

if ! command -v chromium >/dev/null || ! command -v chromedriver >/dev/null; then
    sudo=""; [ "$(id -u)" = 0 ] || sudo=sudo
    $sudo apt-get update -q && $sudo apt-get install -y -q chromium chromium-driver
fi
venv=target/study-oracle-venv
if ! "$venv/bin/python" -c 'import selenium' 2>/dev/null; then
    [ -x "$venv/bin/python" ] || python3 -m venv "$venv"
    "$venv/bin/pip" install -q --disable-pip-version-check selenium
fi
cargo build --locked -q -p touchc --bin touchc
cargo build --locked -q -p touch-e2e --example pty_sleeve
"$venv/bin/python" tests/browser/study_page.py target/debug/touchc target/debug/examples/pty_sleeve "$@"

# With a directory: the report's figures on a simulated paper-sized study (30
# participants, three rounds and the manikin round), as Chromium draws them.
if [ $# -gt 0 ]; then
    sim=$(mktemp -d)
    trap 'rm -rf "$sim"' EXIT
    "$venv/bin/python" host/crates/study/oracle/oracle.py --example "$sim/simulated.csv"
    target/debug/touchc study report "$sim/simulated.csv" -o "$sim/report"
    for fig in confusion cutoff clusters sam; do
        size=$(sed -n 's/.*<svg[^>]* width="\([0-9.]*\)" height="\([0-9.]*\)".*/\1,\2/p' "$sim/report/$fig.svg" | head -1 | sed 's/\.[0-9]*//g')
        chromium --headless=new --no-sandbox --disable-gpu --hide-scrollbars --window-size="$size" \
            --screenshot="$1/report-$fig.png" "file://$sim/report/$fig.svg" 2>/dev/null
    done
fi
