#!/usr/bin/env bash
# Firmware in the loop: the firmware image runs in QEMU (netduinoplus2, STM32F405) and is driven
# through its own serial port (USART2).
#   Stage 1: the exact ELF `cargo fw` builds (sha256 printed) boots with a boot assist generated
#            from the ELF (fil/emulator.py), answers a scripted console session compared with
#            fil/golden/console.txt, and its defmt boot log is decoded from RTT; the same ELF
#            boots without a crystal and as on a 512 KiB part (fil/degraded_boot_test.py). The same
#            for the NUCLEO-F446RE's and the Black Pill F411CE's shipped ELFs (`--board`).
#   Stage 2: the same app built with `--features emulator` (src/board/emulator/: a simulated robot
#            behind the board seam) runs a whole calibration session over USART2, keeps the
#            parameters across an emulator restart, survives a 64 KiB random burst, streams the
#            pose at 100 Hz, and must give host-sim's factors and the plant's true ones (within
#            about 10x the measured error) (fil/closed_loop.py). Every check waits for what the
#            emulator does (replies, the plant's periods), never for a time to pass: wall-clock
#            timeouts only bound a hang.
#   Stage 3: the guided console tool drives that app through a pty bridged to USART2 (3 + 3
#            squares, measured from the plant's truth, apply, save, verify); its session log must
#            recalibrate on the PC to the board's table line for line (fil/console_in_the_loop.py).
# Needs: qemu-system-arm, gdb-multiarch, binutils-arm-none-eabi, python3, defmt-print, flip-link,
# the thumbv7em-none-eabihf target. Method and limits: docs/performance.md (Fidelity).
set -euo pipefail
cd "$(dirname "$0")/.."

for tool in qemu-system-arm gdb-multiarch arm-none-eabi-objdump arm-none-eabi-nm python3; do
    command -v "$tool" >/dev/null || {
        echo "firmware-in-the-loop: $tool not found (apt-get install -y qemu-system-arm gdb-multiarch binutils-arm-none-eabi python3)" >&2
        exit 1
    }
done
command -v defmt-print >/dev/null || [ -x "$HOME/.cargo/bin/defmt-print" ] || {
    echo "firmware-in-the-loop: defmt-print not found (cargo install defmt-print --locked)" >&2
    exit 1
}

# Cargo's output folder (CARGO_TARGET_DIR when set).
TARGET=${CARGO_TARGET_DIR:-target}
OUT=$TARGET/fil
mkdir -p "$OUT"
ELF=$TARGET/thumbv7em-none-eabihf/release/firmware

echo "== stage 1: the shipped ELF"
t0=$(date +%s.%N)
cargo fw --quiet
# Cargo keeps the shipped and the emulator build side by side but links both to the same path:
# each stage runs a copy.
cp "$ELF" "$OUT/firmware-shipped"
sha256sum "$OUT/firmware-shipped"
if arm-none-eabi-nm "$OUT/firmware-shipped" | grep -q EMULATOR_TRUTH; then
    echo "firmware-in-the-loop: FAILED: the shipped ELF contains the emulator board" >&2
    exit 1
fi
python3 fil/boot_test.py "$OUT/firmware-shipped" --workdir "$OUT" | tee "$OUT/stage1.txt"
# The motor outputs' safe state on the same ELF: boot order, HardFault path, panic handler.
python3 fil/safe_boot_test.py "$OUT/firmware-shipped" --workdir "$OUT"
python3 fil/reset_window.py "$OUT/firmware-shipped" --max 16
# The same ELF on a board whose crystal never starts, and on a 512 KiB part.
python3 fil/degraded_boot_test.py "$OUT/firmware-shipped" --workdir "$OUT"
# The other boards' shipped ELFs, the same three checks (fil/boards.py: their storage regions,
# flash size, clock texts, motor port and pins, control timer). QEMU's STM32F405 runs their code
# unchanged: the same core, USART2, IWDG, SYSCFG/EXTI and flash-size addresses; the boot assist
# answers their clock set-up's ready loops (the NUCLEO's over-drive included).
for board in nucleo-f446re blackpill-f411ce; do
    echo "-- stage 1: $board"
    cargo "fw-$board" --quiet
    cp "$ELF" "$OUT/firmware-$board"
    sha256sum "$OUT/firmware-$board"
    python3 fil/boot_test.py "$OUT/firmware-$board" --workdir "$OUT/$board" --board "$board" \
        | tee "$OUT/stage1-$board.txt"
    python3 fil/safe_boot_test.py "$OUT/firmware-$board" --workdir "$OUT/$board" --board "$board"
    python3 fil/reset_window.py "$OUT/firmware-$board" --board "$board" --max 16
    python3 fil/degraded_boot_test.py "$OUT/firmware-$board" --workdir "$OUT/$board" --board "$board"
done
t1=$(date +%s.%N)
awk -v a="$t0" -v b="$t1" 'BEGIN { printf "stage 1 wall time: %.1f s\n", b - a }'

echo "== stage 2: the whole app in a closed loop (emulator board)"
cargo build --release --quiet --target thumbv7em-none-eabihf --bin firmware --features emulator
cp "$ELF" "$OUT/firmware-emulator"
cargo build --release --quiet -p host-sim
python3 fil/closed_loop.py "$OUT/firmware-emulator" --workdir "$OUT" \
    --host-sim "$TARGET/release/host-sim" | tee "$OUT/stage2.txt"
t2=$(date +%s.%N)
awk -v a="$t1" -v b="$t2" 'BEGIN { printf "stage 2 wall time: %.1f s\n", b - a }'

echo "== stage 3: the guided console (cargo console) against the emulated firmware"
cargo build --quiet -p odocal-console
python3 fil/console_in_the_loop.py "$OUT/firmware-emulator" --workdir "$OUT" \
    --console "$TARGET/debug/odocal-console" | tee "$OUT/stage3.txt"
# Leave the shipped ELF at cargo's path again (nothing is rebuilt).
cargo fw --quiet
t3=$(date +%s.%N)
awk -v a="$t2" -v b="$t3" 'BEGIN { printf "stage 3 wall time: %.1f s\n", b - a }'
