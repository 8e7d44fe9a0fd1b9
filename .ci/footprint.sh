#!/usr/bin/env bash
# Flash and static RAM of the release firmware, checked against the budget.
#
#   .ci/footprint.sh [ELF]     (default: $CARGO_TARGET_DIR or target/, .../release/firmware)
#
# Build it first with `cargo fw`. Note that the size depends on DEFMT_LOG: every enabled log call
# adds its format string index and encoding code, so measure the build that is flashed.
# flash      = text + data  (code, read-only data, vector table, .data's initial values)
# static RAM = data + bss   (includes the defmt-rtt buffer and RTIC's task state; the stack is
#                            the rest of RAM: a static estimate is printed here, measured
#                            high-water marks of the library workloads by qemu-bench/run.sh)
# The budget is 192 KiB of flash and 48 KiB of static RAM: a build over it fails (exit status 1).
# A change that adds more than 4 KiB says why in its commit.
# Needs binutils-arm-none-eabi (arm-none-eabi-size, arm-none-eabi-nm).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
ELF="${1:-${CARGO_TARGET_DIR:-$ROOT/target}/thumbv7em-none-eabihf/release/firmware}"
FLASH_BUDGET=$((192 * 1024))
RAM_BUDGET=$((48 * 1024))

if [ ! -f "$ELF" ]; then
    echo "footprint: $ELF not found (run \`cargo fw\` first)" >&2
    exit 1
fi
command -v arm-none-eabi-size >/dev/null || {
    echo "footprint: arm-none-eabi-size not found (apt-get install -y binutils-arm-none-eabi)" >&2
    exit 1
}

read -r text data bss _ < <(arm-none-eabi-size -B -d "$ELF" | awk 'NR == 2')
flash=$((text + data))
ram=$((data + bss))
echo "footprint: $ELF"
printf "  text %d  data %d  bss %d (bytes)\n" "$text" "$data" "$bss"
kib() { awk -v v="$1" 'BEGIN { printf "%.1f", v / 1024 }'; }
printf "  flash %d bytes = %s KiB (budget <= %d KiB)\n" "$flash" "$(kib "$flash")" $((FLASH_BUDGET / 1024))
printf "  static RAM %d bytes = %s KiB (budget <= %d KiB)\n" "$ram" "$(kib "$ram")" $((RAM_BUDGET / 1024))
echo "  largest symbols (bytes, type, name):"
# (awk reads all of nm's output: an early-closing `head` would kill nm with SIGPIPE under pipefail)
arm-none-eabi-nm --size-sort -S -C -t d --reverse-sort "$ELF" | awk '
    $3 ~ /^[tTrRdDbB]$/ && shown++ < 8 {
        printf "    %6d %s", $2, $3; for (i = 4; i <= NF; i++) printf " %s", $i; print ""
    }'

# Static worst-case stack (call graph of the disassembly; see the script for what it cannot see).
if command -v python3 >/dev/null; then
    echo "  stack (static estimate):"
    python3 "$ROOT/.ci/stack_estimate.py" "$ELF" | sed 's/^/    /'
fi

status=0
if [ "$flash" -gt "$FLASH_BUDGET" ]; then
    echo "footprint: flash $flash > $FLASH_BUDGET (over budget)" >&2
    status=1
fi
if [ "$ram" -gt "$RAM_BUDGET" ]; then
    echo "footprint: static RAM $ram > $RAM_BUDGET (over budget)" >&2
    status=1
fi
if [ "$status" -eq 0 ]; then
    echo "footprint: OK (within the budget)"
fi
exit "$status"
