"""The motor outputs' safe state, checked on the shipped ELF itself.

    python3 fil/safe_boot_test.py ELF [--workdir DIR] [--board NAME]

Written for the F407 (PE9, PE11 PWM, PE13 enable on GPIOE); `--board` (fil/boards.py) checks
another board's motor port and pins the same way (the NUCLEO-F446RE and the Black Pill F411CE:
PA8, PA9 PWM, PA10 enable on GPIOA).

1. Boot order (emulator run): QEMU logs every access to the peripherals it does not model, in
   order (`-d unimp`). The first GPIOE access must be the write that drives PE9, PE11 and PE13
   (both PWM pins and the H-bridge enable) low — BSRR = 0x2A000000 — followed by MODER making
   them outputs, and both must come before the first access to the flash interface ("Flash
   Int": the clock set-up's wait states, then the parameter load, which may erase a sector for
   seconds). Then every GPIOE write of the boot is listed in order. The port is never reset
   (RCC_AHB1RSTR.GPIOERST, which QEMU logs but does not model: it would float the motor pins and
   clear their pull-downs). No write may clear the motor pins' pull-downs or mode: a PUPDR write
   gives PE9/PE11/PE13 a pull-down or leaves them, a MODER write leaves them or makes PE13 an
   output and PE9/PE11 outputs or their PWM alternate function, and neither register is written
   as a whole with nothing set (QEMU reads these registers as 0, so a read-modify-write logs
   only the fields it sets: a zero field is not a change, a zero word is a clear; port E has no
   input pins). No write may drive PE13 (the H-bridge enable) high. On a board whose motor port
   also has a pin the boot makes an input (the Black Pill's PA15, a JTAG pin out of reset, before
   TIM2 takes it), each such pin is a MODER read-modify-write that QEMU logs as a zero word: up
   to that many zero MODER words are the inputs' (`port_inputs` in fil/boards.py), one more is a
   clear.
2. Fault path (emulator run): without the boot assist's flash-size answer, the HAL's read of the
   unmapped flash-size word HardFaults — a real fault in the shipped image. The HardFault
   handler must drive PE9, PE11 and PE13 low again (BSRR = 0x2A000000) and make them GPIO
   outputs (MODER), clear TIM1 BDTR.MOE (bit 15) and BDTR.AOE (bit 14, which would set MOE again
   at the next update), and reset the MCU (QEMU runs with -no-reboot, so the reset ends it; QMP's
   SHUTDOWN event must give the reason `guest-reset`, which a crash of QEMU does not).
3. Crash record (emulator run, QEMU rebooting on reset): the first flash-size read HardFaults
   as in step 2, the handler keeps the fault in the RAM the startup code leaves alone and
   resets; the boot assist answers the reads of the second boot, whose boot line must name the
   fault (`reset: hard fault at pc 0x…`), not RCC's `software`.
4. Panic path (disassembly): the panic handler's, the HardFault handler's and the NMI handler's
   (the clock security system's: the NUCLEO's external clock stopped) first call is
   `odocal_emergency_stop`, the function whose writes step 2 observed.
"""

import argparse
import json
import os
import re
import socket
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import console  # noqa: E402
import emulator  # noqa: E402
from boards import BOARDS, board as board_profile  # noqa: E402

# The board under test (main: --board): the motors' port, pins and enable pin, the control timer.
PROFILE = board_profile("f407")
PORT = PROFILE["motor_port"]


def set_board(name):
    global PROFILE, PORT, PE13, PORT_RESET_BIT
    PROFILE = board_profile(name)
    PORT = PROFILE["motor_port"]
    PE13 = PROFILE["enable_pin"]
    PORT_RESET_BIT = 1 << PROFILE["port_reset_bit"]


def pin_bits(shift, width):
    """The motor pins' field value `shift` in a register with `width`-bit fields, OR'ed."""
    out = 0
    for pin in PROFILE["motor_pins"]:
        out |= shift << (width * pin)
    return out

WRITE = re.compile(r"^(\S[^:]*): unimplemented device write \(size \d+, offset (0x[0-9a-f]+), value (0x[0-9a-f]+)\)")
ACCESS = re.compile(r"^(\S[^:]*): unimplemented device (read|write)")


def accesses(log_path):
    out = []
    with open(log_path) as f:
        for line in f:
            m = ACCESS.match(line)
            if not m:
                continue
            w = WRITE.match(line)
            out.append((m.group(1), m.group(2),
                        int(w.group(2), 16) if w else None, int(w.group(3), 16) if w else None))
    return out


def wait_for(log_path, pattern, seconds):
    deadline = time.time() + seconds
    while time.time() < deadline:
        if os.path.exists(log_path) and pattern in open(log_path).read():
            return True
        time.sleep(0.1)
    return False


def check_boot_order(elf, workdir):
    e = emulator.Emulator(elf, workdir, name="safe-boot", board=PROFILE["name"])
    try:
        e.start()
        if not wait_for(e.log, "Flash Int", 60):
            return "no flash interface access within 60 s"
        # The control timer (TIM7) is set up after every GPIO port: the whole pin set-up is in
        # the log once it appears.
        if not wait_for(e.log, PROFILE["control_timer"], 60):
            return f"no control-timer ({PROFILE['timer_name']}) access within 60 s"
    finally:
        e.stop()
    acc = accesses(e.log)
    gpioe = [i for i, a in enumerate(acc) if a[0] == PORT]
    flash = [i for i, a in enumerate(acc) if a[0] == "Flash Int"]
    if not gpioe or not flash:
        return f"{PORT} accesses {len(gpioe)}, flash accesses {len(flash)}"
    first = acc[gpioe[0]]
    low = pin_bits(1 << 16, 1)
    if first[1:] != ("write", 0x18, low):
        return f"first {PORT} access is {first}, not BSRR = 0x{low:08X}"
    moder = [acc[i] for i in gpioe if acc[i][1] == "write" and acc[i][2] == 0x00]
    mask = pin_bits(3, 2)
    want = pin_bits(1, 2)
    if not moder or moder[0][3] & mask != want:
        return f"MODER does not make the motor pins outputs first: {moder[:1]}"
    moder_at = next(i for i in gpioe if acc[i][1] == "write" and acc[i][2] == 0x00)
    if not (gpioe[0] < moder_at < flash[0]):
        return f"order: BSRR at {gpioe[0]}, MODER at {moder_at}, first flash access at {flash[0]}"
    print(f"boot order ({PROFILE['name']}): {PORT} pins {PROFILE['motor_pins']} driven low "
          f"(access {gpioe[0]}) and made outputs "
          f"(access {moder_at}) before the first flash-interface access (access {flash[0]})")
    return check_every_gpioe_write(acc)


# RCC_AHB1RSTR and the motor port's bit (GPIOE's on the F407); MODER, PUPDR, ODR, BSRR offsets.
AHB1RSTR, PORT_RESET_BIT = 0x10, 1 << PROFILE["port_reset_bit"]
MODER, PUPDR, ODR, BSRR = 0x00, 0x0C, 0x14, 0x18
# The bridge enable pin (PE13 on the F407).
PE13 = PROFILE["enable_pin"]


def field(value, pin):
    return (value >> (2 * pin)) & 0b11


def pin_name(pin):
    """`PE13`, `PA10`: the port letter and pin number."""
    return f"P{PORT[-1]}{pin}"


def check_every_gpioe_write(acc):
    """Lists every write to the motor port in order and checks each against the rules in the
    module docs; returns the first violation, or None."""
    names = {MODER: "MODER", PUPDR: "PUPDR", ODR: "ODR", BSRR: "BSRR", 0x04: "OTYPER",
             0x08: "OSPEEDR", 0x20: "AFRL", 0x24: "AFRH"}
    motor_pins = PROFILE["motor_pins"]
    # The port's pins the boot makes inputs: each is a MODER read-modify-write that QEMU logs as
    # a zero word (its field 00, the others read as 0).
    inputs = PROFILE["port_inputs"]
    print(f"{PORT} writes during boot, in order:")
    writes = 0
    zero_moder = 0
    for i, (dev, kind, off, val) in enumerate(acc):
        if kind != "write":
            continue
        if dev == "RCC" and off == AHB1RSTR and val & PORT_RESET_BIT:
            print(f"  access {i}: RCC_AHB1RSTR: {PORT} reset")
            return (f"access {i}: {PORT} reset (the motor pins float, their pull-downs "
                    f"cleared)")
        if dev != PORT:
            continue
        writes += 1
        name = names.get(off, f"offset 0x{off:02x}")
        print(f"  access {i}: {PORT} {name} = 0x{val:08x}")
        if off == BSRR and val & (1 << PE13):
            return f"access {i}: BSRR drives {pin_name(PE13)} (H-bridge enable) high during boot"
        if off == ODR and val & (1 << PE13):
            return f"access {i}: ODR drives {pin_name(PE13)} (H-bridge enable) high during boot"
        if off == PUPDR and val == 0:
            return f"access {i}: {PORT} PUPDR written as a whole with nothing set: a clear"
        if off == MODER and val == 0:
            zero_moder += 1
            if zero_moder > len(inputs):
                return (f"access {i}: {PORT} MODER written as a whole with nothing set: a clear "
                        f"(zero word {zero_moder}; the boot makes {len(inputs)} pin(s) of the "
                        f"port inputs: {[pin_name(p) for p in inputs]})")
        if off == PUPDR:
            for pin in motor_pins:
                if field(val, pin) not in (0b00, 0b10):
                    return (f"access {i}: PUPDR gives {pin_name(pin)} pull "
                            f"{field(val, pin):02b}, not its pull-down")
        if off == MODER:
            for pin in motor_pins:
                allowed = (0b00, 0b01) if pin == PE13 else (0b00, 0b01, 0b10)
                if field(val, pin) not in allowed:
                    return f"access {i}: MODER makes {pin_name(pin)} mode {field(val, pin):02b}"
    inputs_said = (f", {zero_moder} MODER word(s) making the port's input pins "
                   f"{[pin_name(p) for p in inputs]} inputs" if inputs else "")
    print(f"every {PORT} write ({writes}): no port reset, the motor pins' pull-downs and modes "
          f"never cleared, {pin_name(PE13)} never high{inputs_said}")
    return None


def qmp_connect(path, timeout=60.0):
    """A QMP session on QEMU's socket `path`, past the greeting and capabilities negotiation."""
    deadline = time.time() + timeout
    while True:
        s = socket.socket(socket.AF_UNIX)
        try:
            s.connect(path)
            break
        except OSError:
            s.close()
            if time.time() > deadline:
                raise
            time.sleep(0.02)
    s.settimeout(timeout)
    f = s.makefile("rb")
    json.loads(f.readline())
    s.sendall(b'{"execute": "qmp_capabilities"}\n')
    while "return" not in json.loads(f.readline()):
        pass
    return s, f


def qmp_shutdown(sock, f, timeout):
    """Reads QMP events until QEMU's SHUTDOWN event; returns its data (`reason`: `guest-reset`
    for a reset the guest asked for, with -no-reboot), or None if QEMU ended without one (a
    crash) or `timeout` wall seconds passed (a bound on a hang)."""
    deadline = time.time() + timeout
    sock.settimeout(timeout)
    while time.time() < deadline:
        try:
            line = f.readline()
        except OSError:
            return None
        if not line:
            return None
        msg = json.loads(line)
        if msg.get("event") == "SHUTDOWN":
            return msg.get("data", {})
    return None


def check_fault_path(elf, workdir):
    qmp = os.path.join(os.path.abspath(workdir), "safe-fault-qmp.sock")
    if os.path.exists(qmp):
        os.unlink(qmp)
    # With -no-reboot a reset the guest asks for (SYSRESETREQ) ends QEMU with a SHUTDOWN event
    # whose reason is `guest-reset`, and exit status 0; a crash of QEMU (e.g. a lockup: a fault
    # in the fault handler) sends no such event.
    e = emulator.Emulator(elf, workdir, name="safe-fault", board=PROFILE["name"],
                          extra=["-no-reboot", "-qmp", f"unix:{qmp},server=on,wait=off"])
    qmp_sock, qmp_in = qmp_connect(qmp)
    script, _ = emulator.boot_assist_script(elf, e.port, e.flash_kib, e.crystal)
    # Drop the flash-size answers: the read then HardFaults as it would on a part without the
    # word mapped.
    kept, skip = [], False
    for line in script.splitlines():
        if line.startswith("# flash-size read"):
            skip = True
            continue
        if skip:
            if line == "end":
                skip = False
            continue
        kept.append(line)
    path = os.path.join(workdir, "safe-fault.gdb")
    with open(path, "w") as f:
        f.write("\n".join(kept) + "\n")
    e.gdb = subprocess.Popen(["gdb-multiarch", "-q", "-nx", "-batch", "-x", path, elf],
                             stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL)
    shutdown = qmp_shutdown(qmp_sock, qmp_in, 60.0)
    try:
        status = e.qemu.wait(30)
    except subprocess.TimeoutExpired:
        status = None
    qmp_sock.close()
    e.stop()
    reset = shutdown == {"guest": True, "reason": "guest-reset"} and status == 0
    acc = accesses(e.log)
    low = ("write", 0x18, pin_bits(1 << 16, 1))
    boot = next((i for i, a in enumerate(acc) if a[0] == PORT and a[1:] == low), None)
    stop = next((i for i, a in enumerate(acc)
                 if boot is not None and i > boot and a[0] == PORT and a[1:] == low), None)
    if boot is None or stop is None:
        return f"no second motor-pins-low write after boot (boot {boot}, stop {stop})"
    mask = pin_bits(3, 2)
    want = pin_bits(1, 2)
    moder = [a for a in acc[stop:] if a[0] == PORT and a[1] == "write" and a[2] == 0x00]
    if not moder or moder[0][3] & mask != want:
        return f"the motor pins not made GPIO outputs after the fault: {moder[:1]}"
    # QEMU names the unmodelled TIM1 "timer[1]".
    tim1 = [a for a in acc[stop:] if a[0] in ("TIM1", "timer[1]") and a[1] == "write" and a[2] == 0x44]
    if not tim1 or tim1[0][3] & ((1 << 15) | (1 << 14)):
        return f"TIM1 BDTR.MOE/AOE not cleared after the fault: {tim1[:1]}"
    if not reset:
        return (f"the MCU did not reset after the fault: QEMU's shutdown event {shutdown}, exit "
                f"status {status} (a guest reset is `guest-reset`, status 0)")
    print(f"fault path: HardFault → {PORT} pins {PROFILE['motor_pins']} low GPIO outputs, "
          f"TIM1 BDTR = 0x{tim1[0][3]:08x} (MOE and AOE off), reset (QEMU: shutdown "
          f"`{shutdown['reason']}`, status {status})")
    return None


def check_crash_record(elf, workdir):
    e = emulator.Emulator(elf, workdir, name="safe-crash", board=PROFILE["name"])
    script, _ = emulator.boot_assist_script(elf, e.port, e.flash_kib, e.crystal)
    # The first flash-size read is left unanswered (it HardFaults); the later ones are answered.
    lines, in_size_block = [], False
    for line in script.splitlines():
        lines.append(line)
        if line.startswith("target remote"):
            lines.append("set $odocal_faulted = 0")
        if line.startswith("# flash-size read"):
            in_size_block = True
        if in_size_block and line == "silent":
            lines += ["if $odocal_faulted == 0", "  set $odocal_faulted = 1", "  continue", "end"]
            in_size_block = False
    path = os.path.join(workdir, "safe-crash.gdb")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    try:
        c = console.Console.unix(e.u2)
        e.gdb = subprocess.Popen(["gdb-multiarch", "-q", "-nx", "-batch", "-x", path, elf],
                                 stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                 stderr=subprocess.DEVNULL)
        boot = c.wait_event("event boot", 60)
        _, status = c.command("status", timeout=30)
        _, cleared = c.command("clear", timeout=30)
        _, after = c.command("status", timeout=30)
    finally:
        e.stop()
    # (the board's clock note follows the reset cause after `; `)
    if not re.search(r"reset: hard fault at pc 0x[0-9a-f]{8}(; |$)", boot or ""):
        return f"the boot after a HardFault does not name it: {boot!r}"
    if not re.search(r' reset="hard fault at pc 0x[0-9a-f]{8}"$', status or ""):
        return f"status after the HardFault does not name it: {status!r}"
    if cleared != "ok reset cause cleared" or "reset=" in (after or ""):
        return f"clear did not acknowledge the reset cause: {cleared!r}, then {after!r}"
    said = re.search(r"reset: hard fault at pc 0x[0-9a-f]{8}", boot).group(0)
    print(f"crash record: the boot after the HardFault says `{said}`, status "
          f"shows it until clear")
    return None


def check_handlers(elf):
    dis = subprocess.run(["arm-none-eabi-objdump", "-d", "--no-show-raw-insn", elf], check=True,
                         capture_output=True, text=True).stdout
    found = {}
    for name, pattern in (("panic", "rust_begin_unwind>:"), ("HardFault", "__cortex_m_rt_HardFault"),
                          ("NMI", "__cortex_m_rt_NonMaskableInt")):
        m = re.search(r"^[0-9a-f]+ <[^>]*" + re.escape(pattern.rstrip(">:")) + r"[^>]*>:\n(.*?)\n\n",
                      dis, re.S | re.M)
        if not m:
            return f"{name} handler not found in the disassembly"
        calls = re.findall(r"\bbl\s+[0-9a-f]+ <([^>]+)>", m.group(1))
        if not calls or calls[0] != "odocal_emergency_stop":
            return f"{name} handler's first call is {calls[:1]}, not odocal_emergency_stop"
        found[name] = calls[0]
    print("handlers: panic, HardFault and NMI (the clock security system's) call "
          "odocal_emergency_stop first")
    return None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("elf")
    ap.add_argument("--workdir", default="target/fil")
    ap.add_argument("--board", default="f407", choices=sorted(BOARDS))
    args = ap.parse_args()
    set_board(args.board)
    os.makedirs(args.workdir, exist_ok=True)
    failures = [f for f in (check_handlers(args.elf), check_boot_order(args.elf, args.workdir),
                            check_fault_path(args.elf, args.workdir),
                            check_crash_record(args.elf, args.workdir)) if f]
    for f in failures:
        print("FAILED:", f)
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
