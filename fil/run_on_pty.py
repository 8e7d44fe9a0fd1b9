"""The firmware image in QEMU with its console on a pseudo-terminal, for a person at a terminal
program.

    python3 fil/run_on_pty.py [ELF] [--board NAME] [--storage IMAGE] [--workdir DIR]

ELF defaults to the shipped image (`cargo fw`: target/thumbv7em-none-eabihf/release/firmware).
Prints `pty /dev/pts/N`; connect with `picocom -b 115200 /dev/pts/N` (or screen, minicom, or
`cargo console --port /dev/pts/N`). Ctrl-C here stops QEMU.

`--board` (fil/boards.py: f407, nucleo-f446re, blackpill-f411ce; default f407) is the board the
ELF was built for (`cargo fw-<board>`): its storage regions are loaded at that board's addresses
(parameters in sectors 1-2, runs in sectors 10-11 on the F407 and 6-7 on the 512 KiB parts),
erased, or from `--storage IMAGE` (the parameter region, then the run region, as
`fil/emulator.py` describes), and the flash-size read answers with the board's part.

What QEMU (netduinoplus2) lacks, so what the shipped image cannot do here: no TIM7 (the control
period never runs: runs are refused with `encoders not read yet`, saves with `motors running`),
no encoder or motor timers (TIM11 on the Black Pill), no RCC (the boot assist of `fil/emulator.py` answers its ready bits).
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
from boards import BOARDS  # noqa: E402
from console_in_the_loop import bridge  # noqa: E402

SHIPPED = "target/thumbv7em-none-eabihf/release/firmware"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("elf", nargs="?", default=SHIPPED)
    ap.add_argument("--board", default="f407", choices=sorted(BOARDS),
                    help="the board the ELF is built for (default f407)")
    ap.add_argument("--storage", default=None,
                    help="a storage image to load at the board's storage addresses (default: erased)")
    ap.add_argument("--workdir", default=None, help="QEMU's logs and sockets (default: a temporary folder)")
    args = ap.parse_args()
    if not os.path.exists(args.elf):
        sys.exit(f"{args.elf} does not exist: build it with `cargo fw`")
    workdir = args.workdir or tempfile.mkdtemp(prefix="odocal-qemu-")
    e = emulator.Emulator(args.elf, workdir, name="pty", board=args.board,
                          flash_image=args.storage)
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
