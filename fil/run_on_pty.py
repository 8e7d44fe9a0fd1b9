"""The firmware image in QEMU with its console on a pseudo-terminal, for a person at a terminal
program.

    python3 fil/run_on_pty.py [ELF] [--workdir DIR]

ELF defaults to the shipped image (`cargo fw`: target/thumbv7em-none-eabihf/release/firmware).
Prints `pty /dev/pts/N`; connect with `picocom -b 115200 /dev/pts/N` (or screen, minicom, or
`cargo console --port /dev/pts/N`). Ctrl-C here stops QEMU.

What QEMU (netduinoplus2) lacks, so what the shipped image cannot do here: no TIM7 (the control
period never runs: runs are refused with `encoders not read yet`, saves with `motors running`),
no encoder or motor timers, no RCC (the boot assist of `fil/emulator.py` answers its ready bits).
The console itself, `help`, `params`, `set`, `status` and the line handling are the board's. For a
board with a simulated robot that drives, calibrates and saves, build the emulator image
(`cargo build --release --target thumbv7em-none-eabihf --bin firmware --features emulator`) and
give its ELF.
"""

import argparse
import os
import signal
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import emulator  # noqa: E402
from console_in_the_loop import bridge  # noqa: E402

SHIPPED = "target/thumbv7em-none-eabihf/release/firmware"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("elf", nargs="?", default=SHIPPED)
    ap.add_argument("--workdir", default=None, help="QEMU's logs and sockets (default: a temporary folder)")
    args = ap.parse_args()
    if not os.path.exists(args.elf):
        sys.exit(f"{args.elf} does not exist: build it with `cargo fw`")
    workdir = args.workdir or tempfile.mkdtemp(prefix="odocal-qemu-")
    e = emulator.Emulator(args.elf, workdir, name="pty")
    path, _slave = bridge(e.u2)
    e.start()
    print(f"pty {path}", flush=True)
    print(f"(QEMU logs in {workdir}; Ctrl-C stops)", flush=True)
    try:
        signal.sigwait({signal.SIGINT, signal.SIGTERM})
    except KeyboardInterrupt:
        pass
    finally:
        e.stop()


if __name__ == "__main__":
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    main()
