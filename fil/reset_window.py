"""The motor pins' window after reset, measured on a shipped ELF: the instructions the core
executes from the reset vector to the first write to the motor port (the write that drives the
PWM and enable pins low), single-stepped under QEMU with gdb-multiarch.

    python3 fil/reset_window.py ELF [--board NAME] [--max N] [--limit N]

Until that write the pins are what the reset left them: floating inputs (docs/hardware.md,
"Until the first instruction"). The count is the window in instructions; at the 16 MHz the core
runs on out of reset, with the flash's reset wait states, it is at most a few cycles each.
Prints `reset → first <port> write: N instructions (pc 0x…: <instruction>)`; with `--max N`,
fails (exit status 1) when the window is longer (the shipped boards' `__pre_init` makes it 9).
"""

import argparse
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from boards import board as board_profile  # noqa: E402
from emulator import free_port  # noqa: E402

# The GPIO ports' register blocks: port A at 0x40020000, 0x400 apart (RM0090, RM0383, RM0390).
GPIO_BASE, GPIO_STRIDE = 0x40020000, 0x400

GDB_PY = r'''
import gdb, re
port_lo, port_hi, limit = {lo}, {hi}, {limit}
gdb.execute("set pagination off")
gdb.execute("target remote 127.0.0.1:{port}")
frame = gdb.selected_frame()
arch = frame.architecture()
steps = 0
regs = lambda name: int(gdb.parse_and_eval("$" + name)) & 0xffffffff
alias = {{"sb": "r9", "sl": "r10", "fp": "r11", "ip": "r12"}}
while steps < limit:
    pc = regs("pc")
    insn = arch.disassemble(pc)[0]["asm"]
    steps += 1
    m = re.match(r"\s*str\w*(?:\.w)?\s+\w+,\s*\[(\w+)(?:,\s*#(-?\d+))?\]", insn)
    if m:
        base = regs(alias.get(m.group(1), m.group(1)))
        addr = (base + int(m.group(2) or 0)) & 0xffffffff
        if port_lo <= addr < port_hi:
            print("RESULT %d 0x%x %s" % (steps, pc, insn.strip()))
            break
    gdb.execute("stepi", to_string=True)
else:
    print("RESULT none after %d instructions" % steps)
gdb.execute("kill")
'''


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("elf")
    ap.add_argument("--board", default="f407")
    ap.add_argument("--max", type=int, default=None, help="fail above this many instructions")
    ap.add_argument("--limit", type=int, default=2_000_000, help="give up after this many")
    args = ap.parse_args()
    profile = board_profile(args.board)
    index = ord(profile["motor_port"][-1]) - ord("A")
    lo = GPIO_BASE + index * GPIO_STRIDE
    port = free_port()
    qemu = subprocess.Popen(["qemu-system-arm", "-M", "netduinoplus2", "-display", "none",
                             "-serial", "null", "-monitor", "none", "-kernel", args.elf,
                             "-gdb", f"tcp:127.0.0.1:{port}", "-S"],
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        with tempfile.NamedTemporaryFile("w", suffix=".py", delete=False) as f:
            f.write(GDB_PY.format(lo=lo, hi=lo + GPIO_STRIDE, limit=args.limit, port=port))
            script = f.name
        out = subprocess.run(["gdb-multiarch", "-q", "-nx", "-batch", "-x", script, args.elf],
                             capture_output=True, text=True, timeout=3600).stdout
    finally:
        qemu.terminate()
        qemu.wait()
    result = [line for line in out.splitlines() if line.startswith("RESULT")]
    if not result or "none" in result[0]:
        raise SystemExit(f"reset window: no {profile['motor_port']} write found: {out[-400:]}")
    _, n, pc, insn = result[0].split(" ", 3)
    print(f"{os.path.basename(args.elf)} ({args.board}): reset → first {profile['motor_port']} "
          f"write: {n} instructions (pc {pc}: {insn})")
    if args.max is not None and int(n) > args.max:
        raise SystemExit(f"reset window: {n} instructions, more than {args.max}: the motor pins "
                         "float longer than `__pre_init` allows")


if __name__ == "__main__":
    main()
