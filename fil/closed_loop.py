#!/usr/bin/env python3
"""Stage 2 of the firmware-in-the-loop test: the whole RTIC app calibrates a simulated robot.

The firmware built with `--features emulator` (the same `src/main.rs`; the board is
`src/board/emulator/`: a plant with host-sim's motor, wheel and encoder model and true factors
E_b = 1.010, E_d = 0.995) runs in QEMU with deterministic virtual time (`-icount shift=3,
sleep=off`, WFI idle). Over USART2 the client runs an operator's session:

1. plan 3 CW + 3 CCW squares of 0.3 m; `next` each, then `measure` the plant's true end pose in
   the run's start frame (read from the plant's `EMULATOR_TRUTH` block through the monitor: the
   tape measure); `calibrate`, `apply exact`, `save`;
2. restart QEMU on the same flash image (a host file the emulator board reaches through
   semihosting): `params` must show the calibration, and the runs with their measurements must
   be restored (`event runs restored: 6 runs, 6 measured`, the same `runs` listing);
3. on the restarted board: the pose stream at 100 Hz, the `drive` deadman, `stop` mid-run, a
   motor identification (`identify floor`: the report arrives and finds the plant's motors),
   `set control_hz 10000` with a 0.2 m line at 10 kHz, and last a 64 KiB burst of random bytes
   into RX (the console still answers, no reset);
4. the same session on host-sim (`serial --fast --auto-measure --settle`, same robot): every
   `measure` line, the whole `calibrate` table and the `apply exact` line must be identical;
5. the applied E_b and E_d must be the plant's true factors (`TRUE_E_B`, `TRUE_E_D` of
   src/board/emulator/plant.rs) within FACTOR_TOLERANCE (about 10x the measured error): host-sim runs the same library, so
   step 4 alone would not see a calibration that is wrong the same way in both.

Every command is sent only once the plant's wheels are at rest for good (speed below the
smallest normal f64), as host-sim's `--settle` does, so the number of idle control periods between commands (which the
client's wall-clock timing decides) cannot change the counts a run sees.

    python3 fil/closed_loop.py ELF [--workdir DIR] [--host-sim CMD]
"""

import argparse
import math
import os
import random
import re
import shlex
import struct
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from console import Console, ConsoleError  # noqa: E402
from emulator import PARAMS_LEN, Emulator, symbol_address, watchdog_feeds  # noqa: E402

# The plant's true factors, as src/board/emulator/plant.rs defines them (the firmware never sees
# them; host-sim is given the same values).
PLANT_RS = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                        "src", "board", "emulator", "plant.rs")


def plant_constant(name):
    m = re.search(rf"^pub const {name}: f64 = ([0-9.]+);", open(PLANT_RS).read(), re.M)
    if not m:
        raise SystemExit(f"closed loop: `pub const {name}: f64` not found in {PLANT_RS}")
    return float(m.group(1))


TRUE_E_B = plant_constant("TRUE_E_B")
TRUE_E_D = plant_constant("TRUE_E_D")
SIDE_M = 0.3
RUNS_PER_DIRECTION = 3
# Virtual time runs from instruction counts: 8 ns per instruction (2^3), idle skipped.
QEMU_TIME = ["-icount", "shift=3,sleep=off", "-semihosting-config", "enable=on,target=native"]
# How far the applied E_b and E_d may be from the plant's true factors. The run is deterministic
# (virtual time, commands sent at rest) and measures 6.2e-7 (E_b) and 1.5e-7 (E_d): what the
# counts' quantisation and the `measure` lines' rounding leave (1 um, 1e-4 deg = 1.7e-6 rad per
# run; over a square's 2 pi of turning about 3e-7 of E_b). About 10x those: a change that moves
# the fitted factors by more than a few counts' worth fails, where host-sim's agreement alone
# would not see it.
FACTOR_TOLERANCE = {"E_b": 6e-6, "E_d": 1.5e-6}
# Control periods after a lone `drive` by which its 500 ms deadman has stopped the motors.
DEADMAN_PERIODS = 1000
# Control periods of `run ccw` before it is stopped mid-run (0.5 s of robot time: at speed on the
# first side).
STOP_AFTER = 500
# Wall seconds without a reply after which the burst's marker is taken as dropped and sent again.
MARKER_RESEND = 5.0
SETUP = ["echo off", f"set square_side {SIDE_M}", f"set runs_per_direction {RUNS_PER_DIRECTION}"]


class Truth:
    """The plant's published state (see src/board/emulator/plant.rs)."""

    def __init__(self, emu, elf):
        self.emu = emu
        self.addr = symbol_address(elf, "EMULATOR_TRUTH")

    def read(self):
        w = self.emu.read_words(self.addr, 12)
        v = [w[2 * i] | (w[2 * i + 1] << 32) for i in range(6)]
        f = [struct.unpack("<d", struct.pack("<Q", x))[0] for x in v[:5]]
        return {"x": f[0], "y": f[1], "theta": f[2], "omega": (f[3], f[4]), "periods": v[5]}

    def periods_after(self, start, periods, timeout=120.0):
        """Waits until the plant has run `periods` control periods after the state `start`
        (robot time, whatever the host's speed; `timeout` wall seconds bound a hang)."""
        deadline = time.time() + timeout
        while self.read()["periods"] - start["periods"] < periods:
            if time.time() > deadline:
                raise ConsoleError(f"the plant did not run {periods} periods")
            time.sleep(0.002)

    def settle(self, max_periods=300_000, stall=120.0):
        """Waits until both wheels are at rest for good (speed below the smallest normal f64:
        the braked lag decays into subnormals, where no count or pose coordinate changes any
        more); returns the state. Bounded in robot time, whatever the host's speed: the decay
        takes ln(4 rad/s / 2.2e-308) · 25 ms ≈ 18 s of robot time, 178,000 periods at 10 kHz,
        so wheels still turning after `max_periods` periods are a failure; `stall` wall
        seconds without a single plant period bound a hang."""
        first = self.read()
        seen, seen_at = first["periods"], time.time()
        while True:
            t = self.read()
            if all(abs(w) < sys.float_info.min for w in t["omega"]):
                return t
            if t["periods"] - first["periods"] > max_periods:
                raise ConsoleError(
                    f"the wheels did not come to rest in {max_periods} control periods: {t}")
            if t["periods"] != seen:
                seen, seen_at = t["periods"], time.time()
            elif time.time() - seen_at > stall:
                raise ConsoleError(f"the plant ran no control period for {stall} s: {t}")
            time.sleep(0.1)


def wrap_angle(a):
    return math.atan2(math.sin(a), math.cos(a))


def measure_line(start, end):
    """`measure x y θ` of `end` in the frame of `start` (as host-sim's `measure_line`)."""
    s, c = math.sin(start["theta"]), math.cos(start["theta"])
    dx, dy = end["x"] - start["x"], end["y"] - start["y"]
    x, y = c * dx + s * dy, -s * dx + c * dy
    theta = end["theta"] - start["theta"]
    return f"measure {x:.6f}m {y:.6f}m {math.degrees(wrap_angle(theta)):.4f}deg"


def boot(elf, workdir, name, log):
    emu = Emulator(elf, workdir, assist=False, flash_image=False, extra=QEMU_TIME, name=name)
    con = Console.unix(emu.u2)
    emu.start()
    line = con.wait_event("event boot", 30)
    log.append(line)
    return emu, con, Truth(emu, elf)


def send(con, line, log, timeout=60.0):
    data, final = con.command(line, timeout)
    log.append("> " + line)
    log += data + [final]
    return data, final


def calibration_session(elf, workdir):
    """Step 1: the session on the emulator. Returns (transcript, measure lines, calibrate
    table, apply line)."""
    log = []
    emu, con, truth = boot(elf, workdir, "closed-loop", log)
    measures = []
    try:
        for line in SETUP:
            send(con, line, log)
        for _ in range(2 * RUNS_PER_DIRECTION):
            start = truth.settle()
            _, final = send(con, "next", log)
            if not final.startswith("ok run"):
                raise ConsoleError(f"next: {final}")
            log.append(con.wait_event("event run", 120))
            end = truth.settle()
            m = measure_line(start, end)
            measures.append(m)
            send(con, m, log)
        truth.settle()
        data, final = send(con, "calibrate", log, timeout=120)
        table = data + [final]
        _, apply = send(con, "apply exact", log)
        _, saved = send(con, "save", log)
        if saved != "ok saved":
            raise ConsoleError(f"save: {saved}")
        data, final = send(con, "runs", log)
        runs = data + [final]
    finally:
        emu.stop()
    return log, measures, table, apply, runs


def restarted_board(elf, workdir, apply, runs_before):
    """Steps 2 and 3 on a fresh emulator over the same flash image."""
    log = []
    checks = []
    emu, con, truth = boot(elf, workdir, "restarted", log)
    try:
        # The boot line may end with the reset cause (", reset: …").
        if not log[-1].startswith("event boot: parameters loaded"):
            raise ConsoleError(f"restart: {log[-1]}")
        # The session's runs and measurements survived the restart.
        n = 2 * RUNS_PER_DIRECTION
        restored = con.wait_event("event runs restored", 30)
        log.append(restored)
        if restored != f"event runs restored: {n} runs, {n} measured":
            raise ConsoleError(f"restart: {restored}")
        send(con, "echo off", log)
        data, final = send(con, "runs", log)
        if data + [final] != runs_before:
            raise ConsoleError(f"runs after restart: {data + [final]} vs {runs_before}")
        checks.append(f"runs after restart: `{restored}`, `runs` identical ({final})")
        data, _ = send(con, "params", log)
        cal = [d for d in data if d.strip().startswith("calibration")]
        m = re.search(r"E_d=(\S+) E_b=(\S+)", apply)
        if not cal or not m or f"E_d={m.group(1)}" not in cal[0] or f"E_b={m.group(2)}" not in cal[0]:
            raise ConsoleError(f"params after restart: {cal} vs `{apply}`")
        checks.append(f"params after restart: {cal[0].strip()}")

        # The pose stream at 100 Hz while the robot drives a line.
        start = truth.settle()
        send(con, "stream on 100", log)
        send(con, "line 0.3", log)
        con.wait_event("event run", 120)
        send(con, "stream off", log)
        # A finished run is measured before the next one starts.
        _, final = send(con, measure_line(start, truth.settle()), log)
        if not final.startswith("ok run"):
            raise ConsoleError(f"measure of the line: {final}")
        stamps = [float(s.split()[1]) for s in con.streams]
        steps = sorted(round(b - a, 6) for a, b in zip(stamps, stamps[1:]))
        if len(stamps) < 50 or steps[len(steps) // 2] != 0.01 or steps[0] < 0.01 - 1e-9:
            raise ConsoleError(f"stream: {len(stamps)} lines, steps {steps[:3]}..{steps[-3:]}")
        checks.append(f"pose stream: {len(stamps)} lines, median spacing "
                      f"{steps[len(steps) // 2]:.3f} s (100 Hz), min {steps[0]:.3f} s")

        # Drive deadman: one `drive`, then nothing: the motors must stop by themselves.
        truth.settle()
        before = truth.read()
        send(con, "drive 0.2 0", log)
        # Past the 500 ms deadman (robot time), then at rest.
        truth.periods_after(before, DEADMAN_PERIODS)
        end = truth.settle()
        moved = math.hypot(end["x"] - before["x"], end["y"] - before["y"])
        data, status = send(con, "status", log)
        if moved < 0.01 or "state=idle" not in status:
            raise ConsoleError(f"deadman: moved {moved} m, {status}")
        checks.append(f"drive deadman: one `drive 0.2 0`, moved {moved:.3f} m and stopped "
                      f"without a further command ({status.split()[1]})")

        # Stop mid-run: once the plant has run STOP_AFTER periods of the run (counted by the
        # plant, not by the wall clock), the emulator is paused, the true state read (the robot
        # must still be moving), `stop` queued on USART2 and the emulator resumed: the stop lands
        # within a few periods of that state, however fast the host runs the emulator.
        start = truth.settle()
        send(con, "run ccw", log)
        truth.periods_after(start, STOP_AFTER)
        emu.monitor("stop")
        mid = truth.read()
        con.send_raw(b"stop\r\n")
        emu.monitor("cont")
        data, final = con.reply(60)
        log += ["> stop"] + data + [final]
        end = truth.settle()
        data, status = send(con, "status", log)
        if not final.startswith("ok") or "state=idle" not in status or all(abs(w) < sys.float_info.min for w in mid["omega"]):
            raise ConsoleError(f"stop mid-run: {final}, {status}, {mid}")
        checks.append(f"stop mid-run: `{final}` {mid['periods'] - start['periods']} periods into "
                      f"the run, wheels at rest {(end['periods'] - mid['periods']) / 1000.0:.1f} s "
                      f"later, {status.split()[1]}")

        # Motor identification on the floor: the control task only freezes its statistics in
        # the period that ends it; the console task fits them when it takes the report (between
        # two short locks of the controller) and reports as before. The plant's motors: 1 m/s
        # (left 0.98 m/s) at full duty, 50 ms lag, no dead-band.
        truth.settle()
        _, final = send(con, "identify floor", log)
        if not final.startswith("ok identify floor"):
            raise ConsoleError(f"identify floor: {final}")
        fits = {}
        while True:
            event = con.wait_event("event identify", 120)
            log.append(event)
            m = re.match(r"event identify (right|left): gain_fwd=(\S+) gain_back=(\S+) m/s per "
                         r"duty, tau=(\S+) s", event)
            if m:
                fits[m.group(1)] = [float(v) for v in m.group(2, 3, 4)]
            elif event.startswith("event identify done (floor)"):
                break
            else:
                raise ConsoleError(f"identify floor: {event}")
        for side, gain in (("right", 1.0), ("left", 0.98)):
            fwd, back, tau = fits.get(side, (0.0, 0.0, 0.0))
            if max(abs(fwd - gain), abs(back - gain)) > 0.02 * gain or abs(tau - 0.05) > 0.001:
                raise ConsoleError(f"identify floor: {side} {fits.get(side)}")
        checks.append(f"motor identification (`identify floor`): right gain/tau "
                      f"{fits['right'][0]:.4f}/{fits['right'][2]:.4f} s, left "
                      f"{fits['left'][0]:.4f}/{fits['left'][2]:.4f} s (true 1.0/0.98 m/s, 0.05 s); "
                      "tuning applied")

        # The control rate at run time: `set control_hz 10000`, then a 0.2 m line. The plant
        # advances 0.1 ms of robot time per period (paced one period per 1 ms tick of the
        # monotonic: slow motion), so the line takes ten times the periods it takes at 1 kHz
        # (at least 1.63 s of robot time: 0.2 m at 0.3 m/s^2 and 0.3 m/s) and ends 0.2 m on.
        truth.settle()
        _, final = send(con, "set control_hz 10000", log)
        if final != "ok control_hz = 10000 Hz (not saved; save to keep)":
            raise ConsoleError(f"set control_hz: {final}")
        start = truth.settle()
        # Events of the earlier runs (the stopped one) are not this line's.
        con.events = [e for e in con.events if not e.startswith("event run")]
        _, final = send(con, "line 0.2", log)
        if not final.startswith("ok"):
            raise ConsoleError(f"line 0.2 at 10 kHz: {final}")
        log.append(con.wait_event("event run", 300))
        end = truth.settle()
        moved = math.hypot(end["x"] - start["x"], end["y"] - start["y"])
        periods = end["periods"] - start["periods"]
        if abs(moved - 0.2) > 0.002 or periods < 16_300:
            raise ConsoleError(f"10 kHz line: moved {moved} m in {periods} periods")
        checks.append(f"control at 10 kHz (`set control_hz 10000`): `line 0.2` moved "
                      f"{moved:.4f} m; {periods} control periods until the wheels were at rest "
                      "for good")
        # 64 KiB of random bytes into RX: the console must still answer, without a reset. Last,
        # so that nothing the burst leaves behind (a late reply, a dropped-lines notice) can be
        # taken for a later command's reply.
        before = truth.read()
        rng = random.Random(14)
        burst = bytes(rng.getrandbits(8) for _ in range(64 * 1024))
        # `status` is the marker that the burst has been worked through: no line of the burst
        # can be answered like it.
        assert b"status" not in burst.lower()
        sent = time.time()
        got = con.send_burst(burst)
        burst_s = time.time() - sent
        # What follows the burst is sent as it is (from a second thread while this one reads):
        # the emulator may still be taking the burst, and it stops taking bytes while its replies
        # wait unread.
        got += con.send_burst(b"\x03\r\n")
        # Everything up to the marker's reply is the burst's. A marker that arrives while the
        # input queue is full is dropped (and counted in a notice): after MARKER_RESEND s without
        # a reply it is sent again; a second reply to it does no harm here.
        final = None
        deadline = time.time() + 300
        while final is None and time.time() < deadline:
            pending = con.send_burst(b"status\r\n")
            while final is None:
                if pending:
                    line = pending.pop(0)
                else:
                    line = con.read_line(MARKER_RESEND)
                    if line is None:
                        break
                    if con._sort(line) != "reply":
                        continue
                if line.startswith("ok state="):
                    final = line
                else:
                    got.append(line)
        log += ["> (64 KiB burst)", "> status", str(final)]
        after = truth.read()
        boots = [e for e in con.events if e.startswith("event boot")]
        if final is None or boots or after["periods"] <= before["periods"]:
            raise ConsoleError(f"burst: `{final}`, boots {boots}, periods "
                               f"{before['periods']} -> {after['periods']}")
        errs = sum(1 for g in got if g.startswith("err "))
        checks.append(f"64 KiB random burst ({burst_s:.1f} s wall to send): {errs} error replies, "
                      "console answers `status`, "
                      f"no reset (control periods {before['periods']} -> {after['periods']})")

        final_periods = truth.read()["periods"]
        emu.monitor("stop")
        stopped_periods = truth.read()["periods"]
    finally:
        emu.stop()
    # The control task feeds the watchdog once per period, and the plant advances once per
    # period after the first (which only reads the counters): QEMU's log must hold the one feed
    # that starts the watchdog, then one per control period = plant periods + 1, plus two for
    # each flash access with the watchdog relaxed (10 s and back to 50 ms, one reload-key write
    # after each change has crossed over): restoring the runs at boot, storing the two `line`
    # runs, and storing the first line's measurement (a run is measured before the next one
    # starts). The control task feeds before it reads the counters (which advances the plant),
    # so a stop that lands between the two leaves one feed more than plant periods.
    feeds = watchdog_feeds(emu.log) - 2 * 4
    if not final_periods <= feeds - 2 <= stopped_periods + 1:
        raise ConsoleError(f"watchdog feeds {feeds} vs control periods {final_periods}.."
                           f"{stopped_periods}")
    checks.append(f"watchdog: {feeds} feeds in QEMU's log for {stopped_periods} control periods "
                  "(1 starts the watchdog, then one per control period)")
    return log, checks


def host_sim_session(cmd):
    """The same session on host-sim: its `measure` lines, `calibrate` table and `apply` line."""
    script = "\n".join(SETUP + ["next"] * (2 * RUNS_PER_DIRECTION)
                       + ["calibrate", "apply exact"]) + "\n"
    args = shlex.split(cmd) + ["serial", "--fast", "--auto-measure", "--settle",
                               "--eb", str(TRUE_E_B), "--ed", str(TRUE_E_D)]
    out = subprocess.run(args, input=script, capture_output=True, text=True, timeout=300,
                         check=True).stdout
    lines = [l.rstrip("\r") for l in out.splitlines()]
    measures = [l[2:] for l in lines if l.startswith("> measure")]
    i = next(i for i, l in enumerate(lines) if l.startswith("  method"))
    j = next(j for j in range(i, len(lines)) if lines[j].startswith(("ok", "err")))
    apply = next(l for l in lines[j + 1:] if l.startswith(("ok applied", "err")))
    return measures, lines[i:j + 1], apply


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("elf")
    ap.add_argument("--workdir", default="target/fil")
    ap.add_argument("--host-sim", default="cargo run --release -q -p host-sim --")
    args = ap.parse_args()
    os.makedirs(args.workdir, exist_ok=True)
    image = os.path.join(args.workdir, "odocal-params.img")
    with open(image, "wb") as f:
        f.write(b"\xff" * PARAMS_LEN)

    t0 = time.time()
    log1, measures, table, apply, runs = calibration_session(args.elf, args.workdir)
    t1 = time.time()
    log2, checks = restarted_board(args.elf, args.workdir, apply, runs)
    t2 = time.time()
    with open(os.path.join(args.workdir, "closed-loop.txt"), "w") as f:
        f.write("\n".join(log1 + ["(restart)"] + log2) + "\n")
    print("emulator session (3 CW + 3 CCW squares of 0.3 m, measured by the plant's truth):")
    for line in table:
        print("  " + line)
    print("  " + apply)
    for c in checks:
        print("  " + c)
    print(f"  wall time: calibration session {t1 - t0:.1f} s, restarted board {t2 - t1:.1f} s")

    h_measures, h_table, h_apply = host_sim_session(args.host_sim)
    fail = 0
    for name, mine, theirs in (("measure lines", measures, h_measures),
                               ("calibrate table", table, h_table),
                               ("apply line", [apply], [h_apply])):
        if mine != theirs:
            fail = 1
            print(f"FAILED: {name} differ from host-sim's:")
            for a, b in zip(mine + [""] * len(theirs), theirs + [""] * len(mine)):
                if a != b:
                    print(f"  emulator: {a}\n  host-sim: {b}")
        else:
            print(f"host-sim agrees: {len(mine)} {name} identical")
    m = re.search(r"E_d=(\S+) E_b=(\S+)", apply)
    if not m:
        fail = 1
        print(f"FAILED: no E_d/E_b in `{apply}`")
    else:
        e_d, e_b = float(m.group(1)), float(m.group(2))
        for name, got, true in (("E_b", e_b, TRUE_E_B), ("E_d", e_d, TRUE_E_D)):
            err = abs(got - true)
            if not err <= FACTOR_TOLERANCE[name]:
                fail = 1
                print(f"FAILED: {name} {got:.9f} is {err:.2e} from the plant's true {true} "
                      f"(tolerance {FACTOR_TOLERANCE[name]:.1e})")
            else:
                print(f"plant's truth: {name} {got:.9f} vs true {true}, error {err:.2e} "
                      f"(tolerance {FACTOR_TOLERANCE[name]:.1e})")
    if fail:
        print(f"closed loop FAILED (transcript: {args.workdir}/closed-loop.txt)")
        return 1
    print(f"closed loop: E_b {m.group(2)} E_d {m.group(1)} (true {TRUE_E_B:.3f} {TRUE_E_D:.3f}), "
          "params kept across restart")
    return 0


if __name__ == "__main__":
    sys.exit(main())
