#!/usr/bin/env bash
# Runs the maker's guide (firmware/README.md) as a maker would: every ```sh block, in
# a fresh clone of this checkout's committed HEAD, from the folder the block's first
# line names ("# in the workspace root" or "# in firmware/"; a block that names none
# fails the check). Up to the probe itself: a command that needs a probe on a board is
# not run and is named as skipped (probe-rs itself; `cargo run` in firmware/, whose
# runner is probe-rs, runs as the `cargo build` it starts with; installing probe-rs),
# and so is one that needs the USB-serial adapter (udevadm).
# A `touchc sleeve` line runs as written but on a port that does not exist (a sleeve
# on this machine's cable is never touched): it must read its files, then say in one
# line that no sleeve is attached and exit 1, with the `touchc` the guide installed.
# The twin runs `touchc sleeve` against the release firmware. Afterwards the clone's
# `git status` must be empty, and the installed touchc is measured against its size
# budget (scripts/installed-size.sh).
# `cargo install --path ...` installs into the clone's scratch folder, which is first
# on PATH for the blocks that follow; a `cargo install` of a tool already on PATH is
# skipped, said so.
#
# `bash firmware/ci.sh` (the Checks section) is not run again: scripts/check.sh runs it
# on this checkout just before.
#
#   bash firmware/guide-check.sh         # from anywhere; GUIDE_KEEP=1 keeps the clone
#
# The clone is made afresh each time; its builds (touchc in release, the firmware
# profile) go to a target directory kept between runs, target/guide-check/ of this
# checkout (GUIDE_TARGET_DIR to choose another, an empty one for a cold build), so only
# the first run compiles the dependencies: a few minutes on two cores, then about one.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
work="$(mktemp -d)"
cleanup() {
    if [ "${GUIDE_KEEP:-}" = 1 ]; then
        echo "clone kept in $work/clone"
    else
        rm -rf "$work"
    fi
}
trap cleanup EXIT
export CARGO_TARGET_DIR="${GUIDE_TARGET_DIR:-$root/target/guide-check}"
# Where the guide's `cargo install --path` puts its tools, ahead of any other on PATH.
installed="$work/cargo"
export PATH="$installed/bin:$PATH"

head_commit="$(git -C "$root" rev-parse HEAD)"
if [ -n "$(git -C "$root" status --porcelain -- firmware/README.md)" ]; then
    echo "note: firmware/README.md has uncommitted changes; the clone checks the committed one" >&2
fi
git clone --quiet --no-hardlinks "$root" "$work/clone"
git -C "$work/clone" checkout --quiet --detach "$head_commit"
clone="$work/clone"
guide="$clone/firmware/README.md"

# The blocks, one file each: the lines between "```sh" and "```". A ```text block that
# follows one directly (blank lines between at most) is its output as the guide shows
# it: NN.out, compared with what the block prints.
mkdir "$work/blocks"
awk -v dir="$work/blocks" '
    /^```sh[[:space:]]*$/ { n++; inside = 1; file = sprintf("%s/%02d", dir, n); printf "" > file; next }
    /^```text[[:space:]]*$/ && after { out = 1; file = sprintf("%s/%02d.out", dir, n); printf "" > file; next }
    /^```/ && (inside || out) { after = inside; inside = 0; out = 0; close(file); next }
    inside || out { print > file; next }
    /^[[:space:]]*$/ { next }
    { after = 0 }
' "$guide"
blocks=("$work"/blocks/[0-9][0-9])
if [ ! -e "${blocks[0]}" ]; then
    echo "no sh blocks in firmware/README.md" >&2
    exit 1
fi

skipped=0
# Writes, into the block's script, a line that names `line` as not run and why ($1).
skip() {
    printf 'echo %q\n' "SKIPPED ($1): $line"
    skipped=$((skipped + 1))
}

# `no_sleeve LINE COMMAND`, called by the blocks' scripts: runs the guide's `touchc
# sleeve` LINE as COMMAND (the same on a port that does not exist) and fails unless
# that ends in one line saying no sleeve is attached, status 1, and nothing on stdout.
no_sleeve() {
    local line=$1 cmd=$2 rc=0
    local out="$GUIDE_WORK/no-sleeve.out" err="$GUIDE_WORK/no-sleeve.err"
    if [ "$(command -v touchc)" != "$GUIDE_INSTALLED/bin/touchc" ]; then
        echo "firmware/README.md: '$line' runs a touchc that the guide did not install before it (cargo install --path host)" >&2
        return 1
    fi
    (eval "$cmd") >"$out" 2>"$err" || rc=$?
    if [ "$rc" != 1 ] || [ "$(wc -l <"$err")" != 1 ] || ! grep -q 'no sleeve' "$err" || [ -s "$out" ]; then
        echo "firmware/README.md: '$line' without a sleeve: expected one line saying so and exit 1, got exit $rc:" >&2
        cat "$out" "$err" >&2
        return 1
    fi
    echo "NO SLEEVE, as expected (exit 1, $(cat "$err")): $line"
}
export -f no_sleeve
export GUIDE_WORK="$work" GUIDE_INSTALLED="$installed"
nowhere="$work/no-sleeve-here"
no_sleeve_checked=0
for block in "${blocks[@]}"; do
    n="$(basename "$block")"
    where="$(head -n1 "$block")"
    case "$where" in
    "# in the workspace root") dir="$clone" ;;
    "# in firmware/") dir="$clone/firmware" ;;
    *)
        echo "firmware/README.md, sh block $n: its first line must say where it runs" \
            "('# in the workspace root' or '# in firmware/'), not: $where" >&2
        exit 1
        ;;
    esac
    # The block as a script, with the probe's commands replaced by a line saying so.
    script="$work/run-$n.sh"
    {
        echo "set -euo pipefail"
        while IFS= read -r line; do
            case "$line" in
            "probe-rs "*) skip "needs a probe on a board" ;;
            "bash firmware/ci.sh"*) skip "scripts/check.sh runs it on this checkout" ;;
            "sudo udevadm "*) skip "needs the USB-serial adapter plugged in" ;;
            "touchc sleeve "*)
                # The line's own --port goes: the port is one that does not exist.
                rest="${line#touchc sleeve }"
                if [[ $rest =~ ^(.*)--port[[:space:]]+[^[:space:]]+(.*)$ ]]; then
                    rest="${BASH_REMATCH[1]}${BASH_REMATCH[2]}"
                fi
                printf 'no_sleeve %q %q\n' "$line" "touchc sleeve --port $(printf %q "$nowhere") $rest"
                no_sleeve_checked=$((no_sleeve_checked + 1))
                ;;
            "cargo install probe-rs-tools"*) skip "probe-rs is for the board; CI does not need it" ;;
            "cargo install --path "*) echo "$line --root $(printf %q "$installed")" ;;
            "cargo install "*)
                tool="$(awk '{ print $3 }' <<<"$line")"
                if command -v "$tool" >/dev/null; then
                    skip "$tool is installed already"
                else
                    echo "$line"
                fi
                ;;
            *"cargo run "*)
                if [ "$dir" = "$clone/firmware" ]; then
                    skip "flashing needs a probe; building instead"
                    echo "${line/cargo run /cargo build }"
                else
                    echo "$line"
                fi
                ;;
            *) echo "$line" ;;
            esac
        done <"$block"
    } >"$script"
    printf '\n== guide block %s, %s\n' "$n" "${where#\# }"
    sed 's/^/   /' "$block"
    echo "--"
    if ! (cd "$dir" && bash "$script") | tee "$work/printed-$n"; then
        echo "firmware/README.md, sh block $n failed as written (run in ${dir#"$work"/})" >&2
        exit 1
    fi
    if [ -f "$block.out" ] && ! diff -u "$block.out" "$work/printed-$n"; then
        echo "firmware/README.md, sh block $n printed other figures than the guide shows (diff above)" >&2
        exit 1
    fi
done
# Following the guide leaves the checkout as it was: whatever its commands wrote there
# (stimuli, banks, erased.bin) is covered by .gitignore.
left="$(git -C "$clone" status --porcelain --untracked-files=all)"
if [ -n "$left" ]; then
    echo "firmware/README.md's commands left files in the checkout that .gitignore does not cover:" >&2
    echo "$left" >&2
    exit 1
fi
# The touchc the guide installed with `cargo install --path host`, against its budget.
bash "$root/scripts/installed-size.sh" "$installed/bin/touchc"
printf '\nguide check: %d blocks ran in a fresh clone; %d touchc sleeve commands ran without a sleeve; %d commands skipped (named above)\n' \
    "${#blocks[@]}" "$no_sleeve_checked" "$skipped"
