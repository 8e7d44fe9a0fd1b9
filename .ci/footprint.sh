#!/usr/bin/env bash
# Prints the firmware's flash and static RAM use and checks them against the goals
# (flash ≤ 64 KiB, static RAM ≤ 32 KiB).
set -euo pipefail
elf=${1:-target/thumbv7em-none-eabihf/release/firmware}
read -r text data bss _ < <(arm-none-eabi-size "$elf" | tail -n 1)
flash=$((text + data))
ram=$((data + bss))
awk -v elf="$elf" -v t="$text" -v d="$data" -v b="$bss" -v f="$flash" -v r="$ram" 'BEGIN {
  printf "firmware %s\n  .text %d B  .data %d B  .bss %d B\n", elf, t, d, b
  printf "  flash %d B (%.1f KiB, goal <= 64 KiB)\n  static RAM %d B (%.1f KiB, goal <= 32 KiB)\n", f, f / 1024, r, r / 1024
}'
# The goals are reported, not enforced: a build over them is a finding, not a broken build.
if [ "$flash" -gt $((64 * 1024)) ] || [ "$ram" -gt $((32 * 1024)) ]; then
  echo "  NOTE: over the footprint goal"
fi
