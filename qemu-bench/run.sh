#!/usr/bin/env bash
# Builds the QEMU benchmark, runs it on the netduinoplus2 model (STM32F405, Cortex-M4F) with the
# instruction-counting plugin, runs the same workloads on the host, and
#   - fails if any `result` line (raw bits of final poses / calibration results) differs,
#   - fails if the host's odometry misses the accuracy budget (0.1 mm after 1 km),
#   - fails if the SysTick cross-check disagrees with the plugin,
#   - fails if an odometry step needs more than ODOMETRY_GOAL instructions,
#   - prints a table of instruction counts, CPU load, the share of float-library and libm
#     instructions, and stack.
# Needs: qemu-system-arm, binutils-arm-none-eabi (nm), gcc, flip-link, the thumbv7em-none-eabihf
# target.
# Method and limits: docs/performance.md.
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/.." && pwd)"
# Share the repository's target directory: the bench's thumb dependencies are the firmware's.
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
OUT="$CARGO_TARGET_DIR/qemu-bench"
mkdir -p "$OUT"
ODOMETRY_GOAL="${ODOMETRY_GOAL:-500}"
TARGET=thumbv7em-none-eabihf
ELF="$CARGO_TARGET_DIR/$TARGET/release/qemu-bench"
HOST_BIN="$CARGO_TARGET_DIR/release/qemu-bench"

for tool in qemu-system-arm arm-none-eabi-nm gcc cargo flip-link; do
    command -v "$tool" >/dev/null || {
        echo "qemu-bench: $tool not found (apt-get install -y qemu-system-arm binutils-arm-none-eabi gcc; cargo install flip-link)" >&2
        exit 1
    }
done

cd "$HERE"

# 1. The plugin.
gcc -shared -fPIC -O2 -Wall -Werror -fvisibility=hidden -o "$OUT/libinsnwin.so" plugin/insnwin.c

# Lints and unit tests of the bench crate itself (it is not a workspace member, so the
# repository-wide fmt, clippy and test steps do not see it). QEMU_BENCH_LINT=0 skips them.
SEP=$'\x1f'
# The same tokens as the repository's config (not merely the same flags), so that the bench's
# dependencies are the firmware's compiled ones rather than a second copy.
TARGET_RUSTFLAGS="-C${SEP}link-arg=-Tlink.x${SEP}-C${SEP}link-arg=-Tdefmt.x${SEP}-C${SEP}link-arg=--nmagic"
TARGET_RUSTFLAGS="$TARGET_RUSTFLAGS${SEP}-C${SEP}opt-level=z"
if [ "${QEMU_BENCH_LINT:-1}" != 0 ]; then
    cargo fmt -- --check
    cargo clippy --quiet --all-targets -- -D warnings
    cargo test --quiet
    CARGO_ENCODED_RUSTFLAGS="$TARGET_RUSTFLAGS" \
        cargo clippy --quiet --release --target "$TARGET" -- -D warnings
fi

# 2. The target binary. The flags are pinned here rather than inherited from the repository's
#    .cargo/config.toml (which cargo merges with qemu-bench/.cargo/config.toml): cortex-m-rt's
#    link.x, defmt's section script, --nmagic, and the firmware's size-optimised code generation
#    (opt-level z with its machine outliner, so the counts are the firmware's). The linker (flip-link, as for the firmware)
#    comes from qemu-bench/.cargo/config.toml. With the same linker and the same flag tokens the
#    thumb dependencies are the ones `cargo fw` compiled (a different linker or a different
#    spelling of the flags would give every dependency a second, rebuilt copy).
CARGO_ENCODED_RUSTFLAGS="$TARGET_RUSTFLAGS" \
    cargo build --quiet --release --target "$TARGET" --bin qemu-bench

# 3. The host reference (std build of the same crate).
cargo build --quiet --release
host_status=0
"$HOST_BIN" >"$OUT/host.out" || host_status=$?

# 4. QEMU with the plugin (exact counts) and -icount shift=0 (for the SysTick cross-check).
addr() {
    local a
    a="$(arm-none-eabi-nm "$ELF" | awk -v s="$1" '$3 == s { print "0x" $1 }')"
    [ -n "$a" ] || { echo "qemu-bench: symbol $1 not found in $ELF" >&2; exit 1; }
    echo "$a"
}
PLUGIN_ARGS="start=$(addr bench_start),end=$(addr bench_end)"
for sel in $(arm-none-eabi-nm "$ELF" | awk '$3 ~ /^bench_select_/ { sub("bench_select_", "", $3); print $3 }'); do
    PLUGIN_ARGS="$PLUGIN_ARGS,sel=$sel@$(addr "bench_select_$sel")"
done
# Instruction groups: the float support library (f64 arithmetic in software — the M4F's FPU is
# single precision — and 64-bit integer <-> float conversions) and libm.
while read -r lo size group; do
    PLUGIN_ARGS="$PLUGIN_ARGS,grp=$group@0x$lo-$(printf '0x%x' $((0x$lo + 0x$size)))"
done < <(arm-none-eabi-nm -S -C --defined-only "$ELF" | awk '
    $3 ~ /^[tT]$/ {
        name = $4
        if (name ~ /^compiler_builtins::float::/ || name ~ /^__aeabi_(d|f2d|l2d|ul2d|i2d|ui2d|l2f|ul2f|f2lz|f2ulz)/) print $1, $2, "softfloat"
        else if (name ~ /^libm::/) print $1, $2, "libm"
    }')
# The counts are exact whatever the host's speed (instructions, and SysTick in virtual time from
# -icount); QEMU_BENCH_TIMEOUT (wall seconds) only bounds a hung run, generously for a loaded
# machine.
QEMU_BENCH_TIMEOUT="${QEMU_BENCH_TIMEOUT:-1200}"
qemu_status=0
timeout "$QEMU_BENCH_TIMEOUT" qemu-system-arm -M netduinoplus2 -nographic -icount shift=0 \
    -semihosting-config enable=on,target=native \
    -plugin "$OUT/libinsnwin.so,$PLUGIN_ARGS" \
    -kernel "$ELF" >"$OUT/qemu.out" 2>"$OUT/plugin.out" || qemu_status=$?

fail=0
fidelity=ok
if [ "$qemu_status" -eq 124 ]; then
    echo "qemu-bench: FAILED: the QEMU run did not finish within $QEMU_BENCH_TIMEOUT s (hung?)" >&2
    cat "$OUT/qemu.out" "$OUT/plugin.out" >&2
    exit 1
fi
if [ "$qemu_status" -ne 0 ] || ! grep -q '^info done' "$OUT/qemu.out"; then
    echo "qemu-bench: FAILED: the QEMU run did not finish (status $qemu_status)" >&2
    cat "$OUT/qemu.out" "$OUT/plugin.out" >&2
    exit 1
fi

# 5. Fidelity: every result line must be identical, and there must be some.
grep '^result ' "$OUT/host.out" >"$OUT/host.result" || true
grep '^result ' "$OUT/qemu.out" >"$OUT/qemu.result" || true
n_results=$(wc -l <"$OUT/host.result")
if [ "$n_results" -eq 0 ] || ! diff -u "$OUT/host.result" "$OUT/qemu.result" >"$OUT/result.diff"; then
    echo "qemu-bench: FAILED: host and QEMU results differ" >&2
    cat "$OUT/result.diff" >&2
    fidelity=DIFFER
    fail=1
fi
if [ "$host_status" -ne 0 ]; then
    echo "qemu-bench: FAILED: host reference run (accuracy budget) exited with $host_status" >&2
    fail=1
fi

# 6. The table.
awk -v goal="$ODOMETRY_GOAL" -v nres="$n_results" -v fail_in="$fail" -v fidelity="$fidelity" '
    FNR == 1 { file++ }
    file == 1 && $1 == "insnwin" && $2 != "total" {
        name = $2
        for (i = 3; i <= NF; i++) { split($i, kv, "="); w[name, kv[1]] = kv[2] }
        names[++nn] = name
    }
    file == 2 && $1 == "info" && $2 == "systick_block" {
        for (i = 3; i <= NF; i++) { split($i, kv, "="); sys[kv[1]] = kv[2] }
    }
    file == 2 && $1 == "info" && $2 == "stack" {
        for (i = 4; i <= NF; i++) { split($i, kv, "="); stack[$3, kv[1]] = kv[2] }
        stacks[++ns] = $3
    }
    file == 3 && $1 == "info" && $2 == "accuracy" {
        for (i = 3; i <= NF; i++) { split($i, kv, "="); acc[kv[1]] = kv[2] }
    }
    END {
        fail = fail_in
        empty = w["empty", "min"]
        if (empty == "" || w["empty", "max"] != empty) { print "qemu-bench: FAILED: no constant empty window"; fail = 1 }
        printf "\nqemu-bench: instructions per call (netduinoplus2, QEMU TCG plugin; marker overhead of %d subtracted)\n", empty
        printf "%-10s %8s %11s %11s %11s %11s %10s %10s %9s %6s\n", "window", "calls", "mean", "min", "max",
            "max_us", "load@1kHz", "load@10kHz", "softfloat", "libm"
        for (k = 1; k <= nn; k++) {
            name = names[k]
            if (name == "empty" || name == "block") continue
            n = w[name, "n"]
            if (n == 0) { printf "%-10s %8s\n", name, "not run"; continue }
            mean = w[name, "sum"] / n - empty
            mn = w[name, "min"] - empty; mx = w[name, "max"] - empty
            # Time and load at 168 MHz if every instruction took one cycle (a lower bound; see
            # docs/performance.md). Load only for the per-period workloads.
            periodic = (name == "odometry" || name == "midpoint" || name == "control" || name == "period" || name == "identify")
            printf "%-10s %8d %11.1f %11d %11d %11.2f %10s %10s %8.1f%% %5.1f%%\n", name, n, mean, mn, mx, mx / 168,
                periodic ? sprintf("%.3f%%", 100 * mx * 1000 / 168e6) : "-",
                periodic ? sprintf("%.3f%%", 100 * mx * 10000 / 168e6) : "-",
                100 * w[name, "softfloat"] / w[name, "sum"], 100 * w[name, "libm"] / w[name, "sum"]
            if (name == "odometry" && mx > goal) {
                printf "qemu-bench: FAILED: odometry step needs %d instructions (goal %d)\n", mx, goal
                fail = 1
            }
        }
        if (w["odometry", "n"] == 0) { print "qemu-bench: FAILED: no odometry windows counted"; fail = 1 }
        # The step of the controller in one line (Controller::step driving the 1 m square), and the
        # whole period of the control task as the app core runs it (app::control::period: the stop
        # request, the step, the hand-off of the motor command).
        if (w["control", "n"] > 0) {
            printf "control step: mean %d max %d instructions\n",
                int(w["control", "sum"] / w["control", "n"] - empty + 0.5), w["control", "max"] - empty
        } else { print "qemu-bench: FAILED: no control windows counted"; fail = 1 }
        if (w["period", "n"] > 0) {
            printf "control period: mean %d max %d instructions\n",
                int(w["period", "sum"] / w["period", "n"] - empty + 0.5), w["period", "max"] - empty
        } else { print "qemu-bench: FAILED: no control period windows counted"; fail = 1 }
        # The longest controller lock of the console task: the most a console command delays a
        # control period (the solve runs outside the lock).
        # Reads run at any time; settings changes only while the robot is idle.
        if (w["lock", "n"] > 0 && w["lock_idle", "n"] > 0) {
            printf "console lock: max %d instructions over %d holds (%.1f us at 168 MHz; reads, at any time)\n",
                w["lock", "max"] - empty, w["lock", "n"], (w["lock", "max"] - empty) / 168
            printf "console lock while idle: max %d instructions over %d holds (%.1f us; settings changes)\n",
                w["lock_idle", "max"] - empty, w["lock_idle", "n"], (w["lock_idle", "max"] - empty) / 168
            worst = w["lock", "max"] > w["lock_idle", "max"] ? w["lock", "max"] : w["lock_idle", "max"]
            if ((worst - empty) + (w["period", "max"] - empty) >= 16800) {
                print "qemu-bench: FAILED: a console lock and a control period exceed the 10 kHz period"; fail = 1
            }
        } else { print "qemu-bench: FAILED: no console lock windows counted"; fail = 1 }
        # The controller period during a motor identification (its maximum: the closing period),
        # and the console task polling for the report (its maximum: the poll that takes it).
        if (w["identify", "n"] > 0 && w["id_report", "n"] > 0) {
            printf "identify step: mean %d max %d instructions\n",
                int(w["identify", "sum"] / w["identify", "n"] - empty + 0.5), w["identify", "max"] - empty
            printf "identify report: max %d instructions (console task, taking the report)\n",
                w["id_report", "max"] - empty
        } else { print "qemu-bench: FAILED: no identify windows counted"; fail = 1 }
        # SysTick cross-check: 1 instruction = 1 ns under -icount shift=0; SysTick at 168 MHz.
        est = sys["ticks"] * 1e9 / 168e6
        diff = est - w["block", "sum"]
        printf "\ncross-check, %d steps incl. trace generation: plugin %d, SysTick %d ticks = %.0f instructions (diff %.0f)\n",
            sys["steps"], w["block", "sum"], sys["ticks"], est, diff
        # One SysTick tick is 5.95 instructions; the two windows differ by the SysTick reads.
        if (diff < -60 || diff > 60) { print "qemu-bench: FAILED: SysTick cross-check"; fail = 1 }
        for (k = 1; k <= ns; k++) {
            s = stacks[k]
            printf "stack high-water (%s): %d bytes from reset, %d bytes below the caller of the workload\n",
                s, stack[s, "high_water"], stack[s, "high_water"] - stack[s, "at_call"]
        }
        printf "odometry accuracy (host, %s steps, %s m): position %s m, heading %s rad (budget %s m)\n",
            acc["steps"], acc["path_m"], acc["position_error_m"], acc["heading_error_rad"], acc["budget_m"]
        printf "fidelity: %d result lines, host and QEMU %s\n", nres, (fidelity == "ok" ? "bit-identical" : "DIFFER")
        exit fail
    }
' "$OUT/plugin.out" "$OUT/qemu.out" "$OUT/host.out" || fail=1

# The static estimate of the same binary, for comparison with the measured high-water marks.
if command -v python3 >/dev/null; then
    estimate="$(python3 "$ROOT/.ci/stack_estimate.py" "$ELF")"
    echo "static stack estimate of the bench binary: ${estimate%%$'\n'*}"
fi

if [ "$fail" -ne 0 ]; then
    echo "qemu-bench: FAILED" >&2
    exit 1
fi
echo "qemu-bench: OK"
