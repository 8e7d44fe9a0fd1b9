#!/usr/bin/env python3
"""The shipped ELF on a degraded board: a crystal that never starts, and a part with too little
flash for the storage map. Both must boot, say what is wrong, and keep answering.

    python3 fil/degraded_boot_test.py ELF [--workdir DIR] [--board NAME]

1. No crystal (no external clock): the boot assist leaves `odocal_hse_ready` alone, so
   RCC_CR.HSERDY reads 0 (QEMU does not model the RCC) as on a board whose crystal (or clock
   input) never starts. The bounded wait must end, the board must run on the internal oscillator
   (HSI, PLL re-derived for the same core clock), name it at the end of the boot line and say why
   right after it (`event fault: no crystal: …`, the board's text), then answer the console.
2. An unknown crystal: the boot assist answers the crystal measurement (`odocal_hse_count`) with
   the count of a frequency none of the board's documented crystals is (`unknown_hz` in
   fil/boards.py, 12 MHz). The board must switch the crystal off and run on the internal
   oscillator, end the boot line with the internal oscillator's note and the frequency it
   measured (`; crystal measured at 12001 kHz, none of the board's: HSE off`, the count's
   rounding at the nominal HSI), say so in a fault event, and answer the console.
   A board with more than one documented crystal (the Black Pill: 25 or 8 MHz) boots with each
   and its boot line names the one measured (`more_crystals` in fil/boards.py).
3. A part with half the flash (STM32F407VE for the F407's 1024 KiB, a 256 KiB STM32F446RC or
   STM32F411CC for the 512 KiB boards): the boot assist answers every flash-size read with it.
   The board must refuse its storage cleanly — the boot line names the reason and the defaults
   are used, `save` answers with an error naming it, nothing panics.

`--board` (fil/boards.py, default `f407`): the board the ELF is built for.
"""

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from console import Console  # noqa: E402
from boards import BOARDS, board as board_profile, boot_tail  # noqa: E402
from emulator import Emulator, HSE_PERIODS, HSI_HZ, hse_count  # noqa: E402

# The board under test (main: --board).
PROFILE = board_profile("f407")
UNKNOWN_FAULT = ("unknown crystal (the boot line says what it measured): running on the internal "
                 "oscillator")
SMALL_SAVE = "err 19: flash error: no storage: this part's flash is smaller than the storage map"


def boot(elf, workdir, name, **kw):
    emu = Emulator(elf, workdir, assist=True, name=name, board=PROFILE["name"], **kw)
    con = Console.unix(emu.u2)
    emu.start()
    return emu, con


def boot_with_fault(elf, workdir, name, crystal, label, end, fault_text):
    """Boots with `crystal` (False: none, else its frequency): the boot line must end with
    `end`, the fault event must be `fault_text`, and the console must answer."""
    emu, con = boot(elf, workdir, name, crystal=crystal)
    try:
        line = con.wait_event("event boot", 60)
        fault = con.wait_event("event fault", 30)
        _, echo = con.command("echo off", 10)
        _, status = con.command("status", 10)
    finally:
        emu.stop()
    print(f"{label}: `{line}`, then `{fault}`; `status` → `{status[:40]}…`")
    problems = []
    if not line.startswith("event boot: ") or not line.endswith(end):
        problems.append(f"boot line `{line}` (should end with `{end}`)")
    if fault != "event fault: " + fault_text:
        problems.append(f"fault event `{fault}`")
    if echo != "ok echo off" or not status.startswith("ok state=idle"):
        problems.append(f"console `{echo}` / `{status}`")
    return problems


def no_crystal(elf, workdir):
    end = "; " + PROFILE["internal_note"] + boot_tail(PROFILE)
    return boot_with_fault(elf, workdir, "no-crystal", False, "no crystal", end,
                           PROFILE["no_clock_fault"])


def unknown_crystal(elf, workdir):
    hz = PROFILE["unknown_hz"]
    count = hse_count(hz)
    measured_khz = (HSI_HZ * HSE_PERIODS + count // 2) // count // 1000
    end = (f"; {PROFILE['internal_note']}; crystal measured at {measured_khz} kHz, none of the "
           f"board's: HSE off{boot_tail(PROFILE)}")
    return boot_with_fault(elf, workdir, "unknown-crystal", hz, f"unknown crystal ({hz} Hz)", end,
                           UNKNOWN_FAULT)


def other_crystals(elf, workdir):
    problems = []
    for hz, note in PROFILE.get("more_crystals", ()):
        emu, con = boot(elf, workdir, f"crystal-{hz}", crystal=hz)
        try:
            line = con.wait_event("event boot", 60)
        finally:
            emu.stop()
        print(f"{hz} Hz crystal: `{line}`")
        end = f"; {note}{boot_tail(PROFILE)}"
        if not line.startswith("event boot: ") or not line.endswith(end):
            problems.append(f"boot line `{line}` (should end with `{end}`)")
    return problems


def small_flash(elf, workdir):
    small, full = PROFILE["small_kib"], PROFILE["flash_kib"]
    emu, con = boot(elf, workdir, "small-flash", flash_kib=small)
    try:
        line = con.wait_event("event boot", 60)
        con.command("echo off", 10)
        _, save = con.command("save", 10)
        _, status = con.command("status", 10)
        alive = emu.alive()
    finally:
        emu.stop()
    print(f"{small} KiB part: `{line}`; `save` → `{save}`; `status` → `{status[:40]}…`")
    problems = []
    want = (f"event boot: default parameters (no storage: this part has {small} KiB of flash, "
            f"the storage map needs {full} KiB), reset: unknown; {PROFILE['clock_note']}"
            f"{boot_tail(PROFILE)}")
    if line != want:
        problems.append(f"boot line `{line}`")
    if save != SMALL_SAVE:
        problems.append(f"save `{save}`")
    if not status.startswith("ok state=idle") or not alive:
        problems.append(f"console `{status}`, alive {alive}")
    return problems


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("elf")
    ap.add_argument("--workdir", default="target/fil")
    ap.add_argument("--board", default="f407", choices=sorted(BOARDS))
    args = ap.parse_args()
    global PROFILE
    PROFILE = board_profile(args.board)
    os.makedirs(args.workdir, exist_ok=True)
    problems = (no_crystal(args.elf, args.workdir) + unknown_crystal(args.elf, args.workdir)
                + other_crystals(args.elf, args.workdir) + small_flash(args.elf, args.workdir))
    for p in problems:
        print(f"FAILED: {p}")
    if problems:
        print("degraded boot test FAILED")
        return 1
    others = "".join(f", a {hz // 1_000_000} MHz crystal" for hz, _ in
                     PROFILE.get("more_crystals", ()))
    print(f"degraded boot ({args.board}): no crystal, an unknown crystal{others} and a "
          f"{PROFILE['small_kib']} KiB part all boot, report and answer")
    return 0


if __name__ == "__main__":
    sys.exit(main())
