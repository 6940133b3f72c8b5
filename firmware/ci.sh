#!/usr/bin/env bash
# Firmware checks (replaced by the firmware issue's full version).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build -p sleeve-firmware --target thumbv7em-none-eabihf --release --locked
