#!/usr/bin/env bash
# The firmware's checks, as CI runs them. Re-runnable; on a fresh Debian machine
# (as root) it installs what it needs first.
#
#   bash firmware/ci.sh            # from anywhere
#
# 1. tools: the thumbv7em target, flip-link, llvm-tools, qemu-system-arm (bookworm-backports
#    when available: QEMU 10; else the distribution's)
# 2. host: fmt check, clippy -D warnings, tests of the firmware logic
# 3. target: clippy -D warnings (all feature sets), release builds (default, with USB,
#    and UART only), flash/RAM use of each against the budgets
# 4. QEMU: the player on the F405 checked against the host, instructions per tick
# 5. twin: the release ELF (with a linked bank) booted on emulated peripherals
#    (unicorn from PyPI in a venv under target/, see twin/README.md); the UART-only
#    build's playback and link tests; the USB tests (twin/test_usb.py)
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
target=thumbv7em-none-eabihf
flash_budget=$((64 * 1024))
ram_budget=$((16 * 1024))

step() { printf '\n== %s\n' "$*"; }

install_tools() {
    if ! rustup target list --installed | grep -qx "$target"; then
        rustup target add "$target"
    fi
    # The firmware links through flip-link (stack overflow protection, .cargo/config.toml).
    if ! command -v flip-link >/dev/null; then
        cargo install flip-link --locked
    fi
    if ! rustup component list --installed | grep -q '^llvm-tools'; then
        rustup component add llvm-tools || echo "llvm-tools unavailable: sizes from readelf"
    fi
    if ! python3 -c 'import ensurepip, venv' 2>/dev/null; then
        if [ "$(id -u)" != 0 ]; then
            echo "python3 venv support missing and not root: install it (apt-get install python3-venv)" >&2
            exit 1
        fi
        DEBIAN_FRONTEND=noninteractive apt-get install -y python3-venv ||
            { apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y python3-venv; }
    fi
    if command -v qemu-system-arm >/dev/null; then
        return
    fi
    if [ "$(id -u)" != 0 ]; then
        echo "qemu-system-arm missing and not root: install it (apt-get install qemu-system-arm)" >&2
        exit 1
    fi
    export DEBIAN_FRONTEND=noninteractive
    # shellcheck disable=SC1091
    codename="$(. /etc/os-release && echo "${VERSION_CODENAME:-}")"
    src=/etc/apt/sources.list.d/debian.sources
    if [ -n "$codename" ] && [ -f "$src" ]; then
        # A private sources dir: the system's sources plus the same mirror's
        # backports suite (QEMU 10 emulates the F405 better than bookworm's 7.2).
        parts="$(mktemp -d)"
        cp "$src" "$parts/"
        awk -v suite="$codename-backports" 'BEGIN { RS = ""; ORS = "\n\n" }
            NR == 1 { sub(/Suites:[^\n]*/, "Suites: " suite); print }' "$src" >"$parts/backports.sources"
        if apt-get -o Dir::Etc::SourceParts="$parts" update &&
            apt-get -o Dir::Etc::SourceParts="$parts" install -y -t "$codename-backports" qemu-system-arm; then
            rm -rf "$parts"
            return
        fi
        rm -rf "$parts"
    fi
    apt-get update
    apt-get install -y qemu-system-arm
}

# Prints "flash ram" in bytes for an ELF: flash = vectors + code + rodata + data
# image; static RAM = data + bss + uninit (the stack comes on top).
elf_use() {
    local elf=$1 llvm_size
    llvm_size="$(find "$(rustc --print sysroot)/lib/rustlib" -name llvm-size -type f -print -quit 2>/dev/null)"
    if [ -n "$llvm_size" ]; then
        "$llvm_size" -A "$elf" | awk '{ s[$1] = $2 } END {
            print s[".vector_table"] + s[".text"] + s[".rodata"] + s[".data"],
                  s[".data"] + s[".bss"] + s[".uninit"] }'
    else
        local name size flash=0 ram=0
        while read -r name size; do
            case $name in
            .vector_table | .text | .rodata) flash=$((flash + 16#$size)) ;;
            .data) flash=$((flash + 16#$size)) ram=$((ram + 16#$size)) ;;
            .bss | .uninit) ram=$((ram + 16#$size)) ;;
            esac
        done < <(readelf -SW "$elf" | sed -n 's/^ *\[ *[0-9]*\] *//p' | awk '{ print $1, $5 }')
        echo "$flash $ram"
    fi
}

if [ "${SLEEVE_CI_NO_INSTALL:-}" != 1 ]; then
    step "tools"
    install_tools
fi

step "host: fmt, clippy, tests of the firmware logic"
cd "$root"
cargo fmt -p sleeve-firmware -- --check
(cd "$here/qemu-test" && cargo fmt -- --check)
cargo clippy -p sleeve-firmware --no-deps --all-targets --locked -- -D warnings
cargo test -p sleeve-firmware --locked

# The workspace's `firmware` profile: size and speed first (fat LTO, one codegen unit),
# while `release` is tuned for the host tools' build time.
profile=firmware

step "target: clippy, $profile build"
cd "$here"
# The default build has the USB socket; "--no-default-features --features hw" is the
# UART-only one.
uart_only=(--no-default-features --features hw)
for features in "" "dac-outputs" "button-per-slot" "dac-outputs,button-per-slot"; do
    cargo clippy --profile "$profile" --no-deps --locked --features "$features" -- -D warnings
done
cargo clippy --profile "$profile" --no-deps --locked "${uart_only[@]}" -- -D warnings
cargo clippy --profile "$profile" --no-deps --locked --no-default-features \
    --features hw,dac-outputs,button-per-slot -- -D warnings
elf="$root/target/$target/$profile/sleeve-firmware"
# The docs that quote the two builds' flash and static RAM, as "64,052 B".
quoting_docs=(README.md docs/performance.md docs/hardware.md firmware/README.md)
# Fails unless every doc that quotes the firmware's size quotes this build's figures
# (the docs' figures are the ones measured here, not an earlier build's).
docs_quote() {
    local name=$1 figure doc
    shift
    for figure in "$@"; do
        figure="$(printf '%d' "$figure" | sed -e ':a' -e 's/\B[0-9]\{3\}\b/,&/' -e 'ta') B"
        for doc in "${quoting_docs[@]}"; do
            if ! grep -q "$figure" "$root/$doc"; then
                echo "$doc does not quote the $name build's $figure, as measured above: update it" >&2
                exit 1
            fi
        done
    done
}
# Builds with the given cargo feature arguments; fails when the ELF is over either
# budget or its stack is not below its statics.
build_within_budget() {
    local name=$1 flash ram nm stack_start sdata
    shift
    cargo build --profile "$profile" --locked "$@"
    read -r flash ram < <(elf_use "$elf")
    echo "sleeve-firmware ($profile profile, $name): flash $flash B ($((flash / 1024)) KB, budget $((flash_budget / 1024)) KB), static RAM $ram B ($((ram / 1024)) KB, budget $((ram_budget / 1024)) KB)"
    if [ "$flash" -gt "$flash_budget" ] || [ "$ram" -gt "$ram_budget" ]; then
        echo "firmware ($name) over its flash or RAM budget" >&2
        exit 1
    fi
    docs_quote "$name" "$flash" "$ram"
    # flip-link: the stack must sit below the statics (it grows down into the RAM boundary).
    nm="$(find "$(rustc --print sysroot)/lib/rustlib" -name llvm-nm -type f -print -quit 2>/dev/null)"
    if [ -n "$nm" ]; then
        stack_start="$("$nm" "$elf" | awk '$3 == "_stack_start" { print $1 }')"
        sdata="$("$nm" "$elf" | awk '$3 == "__sdata" { print $1 }')"
        echo "stack from 0x$stack_start down, statics from 0x$sdata up"
        if [ -z "$stack_start" ] || [ -z "$sdata" ] || [ $((16#$stack_start)) -gt $((16#$sdata)) ]; then
            echo "the stack is not below the statics: is the firmware linked with flip-link?" >&2
            exit 1
        fi
    fi
}
# The UART-only build first: the default one stays in place for the steps below.
build_within_budget "UART only" "${uart_only[@]}"
build_within_budget "default: USART2 and USB"

step "QEMU: player on the STM32F405 vs the host"
cd "$here/qemu-test"
cargo clippy --release --no-deps --locked -- -D warnings
cargo build --release --locked
log="$(mktemp)"
status=0
timeout 120 qemu-system-arm -M netduinoplus2 -display none -icount shift=4,sleep=off \
    -semihosting-config enable=on,target=native \
    -kernel "target/$target/release/sleeve-qemu-test" | tee "$log" || status=$?
if [ "$status" != 0 ] || ! grep -q '^1 passed, 0 failed$' "$log"; then
    rm -f "$log"
    echo "QEMU test failed (exit $status)" >&2
    exit 1
fi
rm -f "$log"

step "default bank linked into the BANK region"
bank="$(realpath "$(ls -t target/$target/release/build/sleeve-qemu-test-*/out/bank.bin | head -n1)")"
cd "$here"
SLEEVE_DEFAULT_BANK="$bank" cargo build --profile "$profile" --locked --features default-bank
# The .bank section must sit at 0x080C0000 and hold the whole image.
read -r addr size < <(readelf -SW "$elf" | sed -n 's/^ *\[ *[0-9]*\] *//p' | awk '$1 == ".bank" { print $3, $5 }')
if [ "$addr" != 080c0000 ] || [ "$((16#$size))" != "$(stat -c %s "$bank")" ]; then
    echo "default bank not linked at 0x080C0000 (got ${addr:-none}, ${size:-0} bytes)" >&2
    exit 1
fi
echo "default bank: $((16#$size)) bytes at 0x$addr"

step "twin: the release ELF on emulated STM32F405 peripherals"
TWIN_ELF="$elf" TWIN_LINKED_BANK="$bank" bash "$here/twin/run.sh"

step "twin: the UART-only build's playback and its link on USART2"
cargo build --profile "$profile" --locked "${uart_only[@]}"
TWIN_ELF="$elf" bash "$here/twin/run.sh" test_twin.BootAndPlay test_twin.LinkTwin \
    test_twin.PlayLatency test_twin.LinkStream test_link

step "twin: the default build on USB (OTG FS model, scripted host, the link over USB)"
# Leaves the default build in place for `cargo run --profile firmware`.
cargo build --profile "$profile" --locked
TWIN_ELF="$elf" bash "$here/twin/run.sh" test_usb
echo "firmware checks passed"
