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
import queue
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
# Bounds on a hung tool (wall seconds), generous for a loaded machine: the longest the guided
# tool may stay silent (a run and its settling take a few seconds), and the longest the tool
# may take to exit after its last line or to recalibrate the log offline.
TOOL_SILENCE = 300.0
TOOL_EXIT = 60.0


def lines_of(stream):
    """A queue that receives the lines of `stream` (without their newline), then None at its
    end, read by a thread so that the reader can wait for a line with a timeout."""
    q = queue.Queue()

    def pump():
        for line in stream:
            q.put(line.rstrip("\n"))
        q.put(None)

    threading.Thread(target=pump, daemon=True).start()
    return q


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
    lines = lines_of(tool.stdout)
    try:
        while True:
            try:
                line = lines.get(timeout=TOOL_SILENCE)
            except queue.Empty:
                raise SystemExit(f"console-in-the-loop: FAILED: the tool printed nothing for "
                                 f"{TOOL_SILENCE:.0f} s (hung?); its last lines: {transcript[-3:]}")
            if line is None:
                break
            transcript.append(line)
            print(line, flush=True)
            answer = None
            if line.startswith("? Square side L"):
                answer = f"{SIDE_M}m"
            elif line.startswith("? Runs per direction"):
                answer = str(RUNS_PER_DIRECTION)
            elif line.startswith("? Enter starts the run"):
                start = truth.settle()
                answer = ""
            elif line.startswith("? Measured end pose"):
                end = truth.settle()
                answer = measure_line(start, end).removeprefix("measure ")
                measured += 1
            elif line.rstrip().endswith("(y/n):"):
                # Apply and save need a typed yes.
                answer = "y"
            elif line.startswith("? Nominal geometry"):
                answer = "k"
            elif line.startswith("? Bring-up check") or line.startswith("? Motor identification"):
                # The emulated robot is wired right and its motors are the plant's: skip both.
                answer = "s"
            elif line.startswith("? Check square"):
                # Skipped, so exactly the plan's runs are measured.
                answer = "s"
            elif line.startswith("? "):
                answer = ""
            if answer is not None:
                tool.stdin.write(answer + "\n")
                tool.stdin.flush()
        try:
            code = tool.wait(TOOL_EXIT)
        except subprocess.TimeoutExpired:
            raise SystemExit(f"console-in-the-loop: FAILED: the tool did not exit within "
                             f"{TOOL_EXIT:.0f} s after its last line `{transcript[-1:]}`")
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
    try:
        out = subprocess.run([args.console, "recalibrate", log], capture_output=True, text=True,
                             check=True, timeout=TOOL_EXIT).stdout
    except subprocess.TimeoutExpired:
        raise SystemExit(f"console-in-the-loop: FAILED: `odocal-console recalibrate` did not "
                         f"finish within {TOOL_EXIT:.0f} s")
    except subprocess.CalledProcessError as e:
        raise SystemExit(f"console-in-the-loop: FAILED: `odocal-console recalibrate` exited "
                         f"with {e.returncode}: {e.stderr.strip()[-500:]}")
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
