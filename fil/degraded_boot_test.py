#!/usr/bin/env python3
"""The shipped ELF on a degraded board: a crystal that never starts, and a part with too little
flash for the storage map. Both must boot, say what is wrong, and keep answering.

    python3 fil/degraded_boot_test.py ELF [--workdir DIR]

1. No crystal: the boot assist leaves `odocal_hse_ready` alone, so RCC_CR.HSERDY reads 0 (QEMU
   does not model the RCC) as on a board whose crystal never starts. The bounded wait must end,
   the board must run on the internal oscillator (HSI, PLL re-derived for 168 MHz) and say so
   right after the boot line (`event fault: no crystal: …`), then answer the console.
2. A 512 KiB part (STM32F407VE): the boot assist answers every flash-size read with 512. The
   board must refuse its storage cleanly — the boot line names the reason and the defaults are
   used, `save` answers with an error naming it, nothing panics.
"""

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from console import Console  # noqa: E402
from emulator import Emulator  # noqa: E402

NO_CRYSTAL_EVENT = ("event fault: no crystal: HSE did not start, running on the internal "
                    "oscillator (HSI, 168 MHz through the PLL; timing and baud rate within a few %)")
SMALL_BOOT = ("event boot: default parameters (no storage: this part has 512 KiB of flash, the "
              "storage map needs 1024 KiB), reset: unknown")
SMALL_SAVE = "err 19: flash error: no storage: this part's flash is smaller than the storage map"


def boot(elf, workdir, name, **kw):
    emu = Emulator(elf, workdir, assist=True, name=name, **kw)
    con = Console.unix(emu.u2)
    emu.start()
    return emu, con


def no_crystal(elf, workdir):
    emu, con = boot(elf, workdir, "no-crystal", crystal=False)
    try:
        line = con.wait_event("event boot", 60)
        fault = con.wait_event("event fault", 30)
        _, echo = con.command("echo off", 10)
        _, status = con.command("status", 10)
    finally:
        emu.stop()
    print(f"no crystal: `{line}`, then `{fault}`; `status` → `{status[:40]}…`")
    problems = []
    if not line.startswith("event boot: "):
        problems.append(f"boot line `{line}`")
    if fault != NO_CRYSTAL_EVENT:
        problems.append(f"fault event `{fault}`")
    if echo != "ok echo off" or not status.startswith("ok state=idle"):
        problems.append(f"console `{echo}` / `{status}`")
    return problems


def small_flash(elf, workdir):
    emu, con = boot(elf, workdir, "small-flash", flash_kib=512)
    try:
        line = con.wait_event("event boot", 60)
        con.command("echo off", 10)
        _, save = con.command("save", 10)
        _, status = con.command("status", 10)
        alive = emu.alive()
    finally:
        emu.stop()
    print(f"512 KiB part: `{line}`; `save` → `{save}`; `status` → `{status[:40]}…`")
    problems = []
    if line != SMALL_BOOT:
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
    args = ap.parse_args()
    os.makedirs(args.workdir, exist_ok=True)
    problems = no_crystal(args.elf, args.workdir) + small_flash(args.elf, args.workdir)
    for p in problems:
        print(f"FAILED: {p}")
    if problems:
        print("degraded boot test FAILED")
        return 1
    print("degraded boot: no crystal and a 512 KiB part both boot, report and answer")
    return 0


if __name__ == "__main__":
    sys.exit(main())
