#!/usr/bin/env python3
"""The guided console (`cargo console`) against the emulated firmware: the guided_session test's
flow with the firmware image in QEMU instead of host-sim.

The firmware built with `--features emulator` (src/board/emulator/: a simulated robot behind
the board seam) runs in QEMU as in fil/closed_loop.py; its USART2 socket is bridged to a
pseudo-terminal, so `odocal-console --port /dev/pts/N` opens it as it opens a USB-UART. This
script is the operator: it answers the tool's questions on its stdin (plan 3 + 3 squares of
0.3 m; Enter for each run once the plant's wheels are at rest; the measured end pose from the
plant's `EMULATOR_TRUTH` block, read through the monitor, in the run's start frame; the
default method). Then the tool's log must recalibrate on the PC (`odocal-console recalibrate
LOG`) to the board's `calibrate` table line for line, and `params` must have been verified.

    python3 fil/console_in_the_loop.py ELF --console target/debug/odocal-console [--workdir DIR]
"""

import argparse
import json
import os
import pty
import socket
import subprocess
import sys
import threading
import time
import tty

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from closed_loop import QEMU_TIME, Truth, measure_line  # noqa: E402
from emulator import PARAMS_LEN, Emulator  # noqa: E402

SIDE_M = 0.3
RUNS_PER_DIRECTION = 3


def bridge(sock_path):
    """A pseudo-terminal whose other side is the USART2 socket; returns the pty's path."""
    master, slave = pty.openpty()
    tty.setraw(slave)
    s = socket.socket(socket.AF_UNIX)
    s.connect(sock_path)

    def to_pty():
        while True:
            data = s.recv(4096)
            if not data:
                return
            os.write(master, data)

    def to_socket():
        while True:
            try:
                data = os.read(master, 4096)
            except OSError:
                return
            if not data:
                return
            s.sendall(data)

    for f in (to_pty, to_socket):
        threading.Thread(target=f, daemon=True).start()
    return os.ttyname(slave), slave


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("elf")
    ap.add_argument("--console", required=True, help="the odocal-console binary")
    ap.add_argument("--workdir", default="target/fil")
    args = ap.parse_args()
    os.makedirs(args.workdir, exist_ok=True)
    # The emulator board's parameter flash: a host file, erased (as fil/closed_loop.py).
    with open(os.path.join(args.workdir, "odocal-params.img"), "wb") as f:
        f.write(b"\xff" * PARAMS_LEN)
    t0 = time.time()
    emu = Emulator(args.elf, args.workdir, assist=False, flash_image=False, extra=QEMU_TIME,
                   name="console")
    path, _slave = bridge(emu.u2)
    emu.start()
    truth = Truth(emu, args.elf)
    log = os.path.abspath(os.path.join(args.workdir, "console-session.jsonl"))
    if os.path.exists(log):
        os.unlink(log)
    tool = subprocess.Popen([args.console, "--port", path, "--log", log],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1)
    transcript = []
    start = None
    measured = 0
    try:
        for line in tool.stdout:
            line = line.rstrip("\n")
            transcript.append(line)
            print(line, flush=True)
            answer = None
            if line.startswith("? Square side L"):
                answer = str(SIDE_M)
            elif line.startswith("? Runs per direction"):
                answer = str(RUNS_PER_DIRECTION)
            elif line.startswith("? Enter starts the run"):
                start = truth.settle()
                answer = ""
            elif line.startswith("? Measured end pose"):
                end = truth.settle()
                answer = measure_line(start, end).removeprefix("measure ")
                measured += 1
            elif line.startswith("? "):
                answer = ""
            if answer is not None:
                tool.stdin.write(answer + "\n")
                tool.stdin.flush()
        code = tool.wait(60)
    finally:
        if tool.poll() is None:
            tool.kill()
        emu.stop()
    if code != 0:
        raise SystemExit(f"console-in-the-loop: FAILED: the tool exited with {code}")
    if measured != 2 * RUNS_PER_DIRECTION:
        raise SystemExit(f"console-in-the-loop: FAILED: {measured} runs measured")
    verified = [t for t in transcript if t.startswith("verified: params shows calibration exact")]
    if not verified:
        raise SystemExit("console-in-the-loop: FAILED: params not verified")
    board = [json.loads(l) for l in open(log) if '"kind":"calibrate"' in l][-1]
    if board["source"] != "board":
        raise SystemExit("console-in-the-loop: FAILED: the table was not the board's")
    out = subprocess.run([args.console, "recalibrate", log], capture_output=True, text=True,
                         check=True).stdout
    offline = [l[2:] if l.startswith("  ") else l for l in out.splitlines()[1:]]
    if offline != board["table"]:
        raise SystemExit("console-in-the-loop: FAILED: offline table differs:\n"
                         + "\n".join(offline) + "\n---\n" + "\n".join(board["table"]))
    exact = next(l for l in offline if l.split()[0] == "exact")
    print(f"console in the loop: {measured} runs measured, {verified[0]}")
    print(f"  board (emulated firmware) and offline (host library), exact row:\n  {exact}")
    print(f"  offline recalibration identical to the board's table ({len(offline)} lines); "
          f"wall time {time.time() - t0:.1f} s")


if __name__ == "__main__":
    main()
