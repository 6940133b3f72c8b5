#!/usr/bin/env bash
# The firmware twin: boots the release ELF on emulated STM32F405 peripherals and
# checks what it writes (see README.md). Re-runnable; needs python3 with venv and
# network access to PyPI on the first run only.
#
#   bash firmware/twin/run.sh                    # builds the release ELF if missing
#   TWIN_ELF=path/to/elf bash firmware/twin/run.sh [unittest args, e.g. test_twin.Fault]
#   bash firmware/twin/run.sh serve [--bank B]   # the twin on a pseudo-terminal that
#                                                # `touchc sleeve ...` finds by itself (--link PATH: elsewhere)
#   bash firmware/twin/run.sh serve-usb --link /tmp/sleeve [--bank B]   # the same over its USB port
#   bash firmware/twin/run.sh figures            # the USB figures of docs/hardware.md
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
venv="$root/target/twin-venv"

if ! "$venv/bin/python" -c 'import unicorn, sys; sys.exit(unicorn.__version__ != "2.1.3")' 2>/dev/null; then
    rm -rf "$venv"
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check -r "$here/requirements.txt"
fi

elf="${TWIN_ELF:-$root/target/thumbv7em-none-eabihf/firmware/sleeve-firmware}"
if [ ! -f "$elf" ]; then
    (cd "$root/firmware" && cargo build --profile firmware --locked)
fi
if [ "${1:-}" = serve ]; then
    shift
    exec "$venv/bin/python" "$here/twin.py" "$elf" "$@"
fi
if [ "${1:-}" = serve-usb ]; then
    shift
    exec "$venv/bin/python" "$here/usb_host.py" "$elf" "$@"
fi
cd "$here"
# The host player's codes, from the protocol crate built for this machine; touchc for
# the README's study script.
(cd "$root" && cargo build --quiet --locked -p sleeve-firmware --example twin_codes &&
    cargo build --quiet --locked -p touchc --bin touchc)

if [ "${1:-}" = figures ]; then
    TWIN_ELF="$elf" TWIN_CODES="$root/target/debug/examples/twin_codes" exec "$venv/bin/python" usb_figures.py
fi
# By default the twin's own tests, the study's, then the real `touchc sleeve` against
# it (test_cli).
[ $# -gt 0 ] || set -- test_twin test_study test_cli
TWIN_ELF="$elf" TWIN_CODES="$root/target/debug/examples/twin_codes" \
    "$venv/bin/python" -W error::ResourceWarning -m unittest "$@"
