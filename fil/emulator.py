"""QEMU (netduinoplus2, STM32F405) around an odocal firmware ELF: launch, boot assist, console
socket, RAM dump and the defmt log from the RTT buffer.

What the emulator needs from outside the image, and why (QEMU 7.2 as shipped by Debian):

- RCC is not modelled (every register reads 0), so `Rcc::freeze` would wait for ever for the
  HSE and PLL ready bits, and on a part run above 168 MHz (the STM32F446 at 180 MHz) for the
  power controller's over-drive ready bits (PWR_CSR.ODRDY, ODSWRDY: PWR is not modelled either).
  The boot assist (a gdb-multiarch script generated from the ELF's disassembly by
  `boot_assist_script`) puts a breakpoint on the branch of each of those polling loops and
  continues after it, as if the bit had been set. The clock tree is not
  modelled either: SysTick runs at 168 MHz whatever RCC says, which is the shipped
  configuration's core clock.
- The flash-size word at 0x1FFF7A22 (system memory) is not mapped: reading it HardFaults, and the
  HAL reads it before every flash access, the board once at boot to check that the storage map
  fits. The boot assist breaks on each `ldrh` from that address and supplies the part's size
  (KiB: 1024 for the STM32F407VG, 512 for the STM32F446RE and STM32F411CE) in the destination
  register — or another size, to boot the image as on a
  smaller part (`flash_kib`).
- The board waits a bounded time for the crystal (`odocal_hse_ready`, RCC_CR.HSERDY) and falls
  back to the internal oscillator without it. The boot assist returns true from that function
  (a crystal that starts at once); with `crystal=False` it leaves it alone, RCC reads 0, and the
  image boots as on a board whose crystal never starts.
- The board then measures the crystal against the internal oscillator (`odocal_hse_count`:
  TIM11 capturing HSE_RTC, neither modelled). The boot assist returns the count the board's
  first documented crystal gives (`crystal_hz` in fil/boards.py; `crystal=<Hz>` another
  frequency's, e.g. one the board does not document: it then boots on the internal
  oscillator and its boot line says what was measured), computed as src/board/crystal.rs
  counts (`hse_count`).
- The Black Pill's regulator scale (`odocal_vos_ready`, PWR_CSR.VOSRDY; PWR is not modelled):
  the boot assist returns true (the regulator reached scale 1).
- The storage sectors of a freshly flashed board are erased (0xFF); QEMU's flash is ROM filled
  with zeros where the ELF has nothing. QEMU's generic loader puts 0xFF (or a given storage
  image) into the parameter sectors 1-2 (32 KiB at 0x08004000, between the vector table and
  `.text`) and the run sectors (256 KiB: sectors 10-11 at 0x080C0000 on the F407, 6-7 at
  0x08040000 on the 512 KiB parts; `fil/boards.py`).

Everything else runs as built: the vector table, RTIC's dispatchers, SysTick, USART2's RX/TX
interrupts (USART2 is the second `-serial`).
"""

import os
import re
import shutil
import socket
import struct
import subprocess
import time

from boards import board as board_profile

# The storage regions of the default board (src/board/f407/flash.rs, memory.x); other boards'
# in fil/boards.py.
PARAM_REGION_ADDR = 0x08004000
PARAM_REGION_LEN = 32 * 1024
RUN_REGION_ADDR = 0x080C0000
RUN_REGION_LEN = 256 * 1024
# A storage image (the emulator board's host file, `flash_image`): the parameter region, then
# the run region.
PARAMS_LEN = PARAM_REGION_LEN + RUN_REGION_LEN
RAM_ADDR = 0x20000000
RAM_LEN = 128 * 1024
RCC_BASE = 0x40023800
# The registers whose ready bits the clock set-up polls: RCC_CR (HSERDY bit 17, PLLRDY bit 25)
# and PWR_CSR (ODRDY bit 16, ODSWRDY bit 17), with the `lsls` shift that moves the bit to the
# sign: 31 - bit.
READY_LOOPS = {RCC_BASE: (14, 6), 0x40007004: (15, 14)}
FLASH_SIZE_ADDR = 0x1FFF7A22
# objdump's names of r9..r12 as gdb names them.
GDB_REGISTER = {"sb": "r9", "sl": "r10", "fp": "r11", "ip": "r12"}
FLASH_SIZE_KIB = 1024
# The crystal measurement (src/board/crystal.rs): HSI ticks (16 MHz) in RTC_DIVIDER (31) x
# EDGES_PER_CAPTURE (8) x CAPTURES (8) periods of the external clock.
HSI_HZ = 16_000_000
HSE_PERIODS = 31 * 8 * 8


def hse_count(hz):
    """The count `odocal_hse_count` returns for an external clock of `hz` at the nominal HSI
    (src/board/crystal.rs, `expected_count`)."""
    return (HSI_HZ * HSE_PERIODS + hz // 2) // hz


def disassemble(elf):
    """(address, mnemonic, operands) of every instruction in the ELF's code."""
    out = subprocess.run(
        ["arm-none-eabi-objdump", "-d", "--no-show-raw-insn", elf],
        check=True, capture_output=True, text=True).stdout
    insns = []
    for line in out.splitlines():
        m = re.match(r"^\s*([0-9a-f]+):\s+(\S+)\s*(.*)$", line)
        if m:
            insns.append((int(m.group(1), 16), m.group(2), m.group(3)))
    return insns


def boot_assist_points(elf):
    """The ELF's RCC ready-bit polling loops and flash-size reads, found in its disassembly.

    Returns a list of (kind, breakpoint address, resume address, register) tuples:
    - `("rcc-ready", branch, next, (base_register, offset, n))`: the loop `ldr rA, [rB, #off];
      lsls rA, rA, #n; bpl <ldr>` with n = 14 (RCC_CR.HSERDY, bit 17) or n = 6 (RCC_CR.PLLRDY,
      bit 25), or n = 15 / 14 on PWR_CSR (ODRDY, ODSWRDY; READY_LOOPS);
    - `("flash-size", ldrh, next, destination)`: the address into rX, by `movw rX, #0x7a22;
      movt rX, #0x1fff` or (size-optimised code) by `ldr rX, [pc, #n]` from a literal word
      0x1fff7a22, followed by `ldrh rD, [rX, #0]`.
    """
    insns = disassemble(elf)
    points = []
    reg = r"(r\d+|sb|sl|fp|ip)"
    for i in range(len(insns) - 3):
        (a0, op0, arg0), (_, op1, arg1), (a2, op2, arg2), (a3, _, _) = insns[i:i + 4]
        m0 = re.match(reg + r", \[" + reg + r"(?:, #(\d+))?\]$", arg0)
        m1 = re.match(reg + ", " + reg + r", #(\d+)", arg1)
        if (op0 in ("ldr", "ldr.w") and op1 == "lsls" and op2.startswith("bpl") and m0 and m1
                and m1.group(1) == m1.group(2) == m0.group(1)
                and int(m1.group(3)) in (6, 14, 15)
                and arg2.startswith(f"{a0:x} ")):
            base = GDB_REGISTER.get(m0.group(2), m0.group(2))
            points.append(("rcc-ready", a2, a3,
                           (base, int(m0.group(3) or 0), int(m1.group(3)))))
    def flash_size_read(reg, start):
        for k in range(start, min(start + 3, len(insns) - 1)):
            ak, opk, argk = insns[k]
            mk = re.match(r"(r\d+), \[" + reg + r", #0\]", argk)
            if opk == "ldrh" and mk:
                points.append(("flash-size", ak, insns[k + 1][0], mk.group(1)))
                return

    literals = {a for a, op, arg in insns
                if op == ".word" and arg.lower() == f"0x{FLASH_SIZE_ADDR:08x}"}
    for i, (a, op, arg) in enumerate(insns):
        m = re.match(r"(r\d+), \[pc, #\d+\]\s+@ \(([0-9a-f]+)", arg)
        if op in ("ldr", "ldr.w") and m and int(m.group(2), 16) in literals:
            flash_size_read(m.group(1), i + 1)
            continue
        m = re.match(r"(r\d+), #31266\b", arg)
        if op != "movw" or not m:
            continue
        reg = m.group(1)
        for j in range(i + 1, min(i + 6, len(insns) - 1)):
            aj, opj, argj = insns[j]
            if opj == "movt" and argj.startswith(f"{reg}, #8191"):
                flash_size_read(reg, j + 1)
                break
    return points


def boot_assist_script(elf, port, flash_kib=FLASH_SIZE_KIB, crystal=8_000_000):
    """The gdb-multiarch script that lets the ELF boot in QEMU (see the module docs).
    `crystal`: the external clock's frequency (Hz) the measurement finds, or False for none."""
    points = boot_assist_points(elf)
    hse_ready = optional_symbol_address(elf, "odocal_hse_ready")
    answers = [(name, value) for name, value in
               (("odocal_hse_count", hse_count(crystal) if crystal else None),
                ("odocal_vos_ready", 1))
               if value is not None and optional_symbol_address(elf, name) is not None]
    rcc = [p for p in points if p[0] == "rcc-ready"]
    size = [p for p in points if p[0] == "flash-size"]
    # The flash-size read is in every build that touches the flash; the ready loops may be
    # bounded (a clock fallback after a timeout), and then need no help.
    if not size:
        raise SystemExit(
            f"boot assist: no flash-size read found in {elf} (found {len(rcc)} RCC ready "
            "loops): the HAL's code changed, update fil/emulator.py")
    lines = [
        "# Generated by fil/emulator.py from " + os.path.basename(elf) + ": see its docs.",
        "set pagination off",
        "set confirm off",
        f"target remote 127.0.0.1:{port}",
    ]
    if hse_ready is not None and crystal:
        lines += [
            "# odocal_hse_ready (RCC is not modelled): the crystal is ready",
            f"break *0x{hse_ready & ~1:x}",
            "commands",
            "silent",
            "set $r0 = 1",
            "set $pc = $lr & 0xfffffffe",
            "continue",
            "end",
        ]
    for name, value in answers:
        lines += [
            f"# {name} (not modelled): returns {value}",
            f"break *0x{optional_symbol_address(elf, name) & ~1:x}",
            "commands",
            "silent",
            f"set $r0 = {value}",
            "set $pc = $lr & 0xfffffffe",
            "continue",
            "end",
        ]
    for kind, bp, resume, reg in points:
        if kind == "rcc-ready":
            base, offset, shift = reg
            # The register polled must be one whose bit `shift` selects is a ready flag.
            allowed = " || ".join(f"${base} + {offset} == 0x{addr:x}"
                                  for addr, shifts in READY_LOOPS.items() if shift in shifts)
            lines += [
                f"# ready-bit loop ({base} + {offset}, lsls #{shift}: RCC_CR or PWR_CSR): leave "
                "it as if the bit were set",
                f"break *0x{bp:x}",
                "commands",
                "silent",
                f"if !({allowed})",
                f'  echo boot assist: loop at 0x{bp:x} does not poll a clock ready bit\\n',
                "  kill",
                "  quit 1",
                "end",
                f"set $pc = 0x{resume:x}",
                "continue",
                "end",
            ]
        else:
            lines += [
                f"# flash-size read (0x{FLASH_SIZE_ADDR:X} is not mapped): {flash_kib} KiB",
                f"break *0x{bp:x}",
                "commands",
                "silent",
                f"set ${reg} = {flash_kib}",
                f"set $pc = 0x{resume:x}",
                "continue",
                "end",
            ]
    lines.append("continue")
    return "\n".join(lines) + "\n", points


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Emulator:
    """One QEMU run of `elf` with USART2 on a unix socket and the HMP monitor on another.

    `assist`: attach the boot assist (gdb) — needed by the shipped image. `flash_image`: a
    storage image (PARAMS_LEN bytes: parameter region, then run region) loaded into the storage
    sectors (default: erased; False: none). `extra`: more QEMU
    arguments (e.g. `-icount`, `-semihosting-config`).
    """

    def __init__(self, elf, workdir, assist=True, flash_image=None, extra=(), name="qemu",
                 flash_kib=None, crystal=True, board="f407"):
        profile = board_profile(board)
        self.flash_kib = profile["flash_kib"] if flash_kib is None else flash_kib
        # The external clock's frequency the boot assist reports (False: none starts).
        self.crystal = profile["crystal_hz"] if crystal is True else crystal
        self.elf = elf
        self.workdir = workdir
        os.makedirs(workdir, exist_ok=True)
        workdir = os.path.abspath(workdir)
        self.workdir = workdir
        self.u2 = os.path.join(workdir, f"{name}-usart2.sock")
        self.mon = os.path.join(workdir, f"{name}-monitor.sock")
        self.log = os.path.join(workdir, f"{name}.log")
        for p in (self.u2, self.mon):
            if os.path.exists(p):
                os.unlink(p)
        elf = os.path.abspath(elf)
        self.elf = elf
        if flash_image is None:
            flash_image = os.path.join(workdir, "erased-storage.bin")
            with open(flash_image, "wb") as f:
                f.write(b"\xff" * PARAMS_LEN)
        regions = []
        if flash_image:
            with open(flash_image, "rb") as f:
                image = f.read()
            if len(image) != PARAMS_LEN:
                raise SystemExit(f"{flash_image}: a storage image is {PARAMS_LEN} bytes")
            for part, addr, data in (("params", profile["param_addr"], image[:PARAM_REGION_LEN]),
                                     ("runs", profile["run_addr"], image[PARAM_REGION_LEN:])):
                path = os.path.join(workdir, f"{name}-{part}.bin")
                with open(path, "wb") as f:
                    f.write(data)
                regions.append((path, addr))
        self.gdb = None
        self.port = free_port() if assist else None
        cmd = ["qemu-system-arm", "-M", "netduinoplus2", "-display", "none",
               "-serial", "null",
               "-chardev", f"socket,id=u2,path={self.u2},server=on,wait=off",
               "-serial", "chardev:u2",
               "-monitor", f"unix:{self.mon},server=on,wait=off",
               "-d", "unimp,guest_errors", "-D", self.log,
               "-kernel", elf]
        for path, addr in regions:
            cmd += ["-device", f"loader,file={path},addr=0x{addr:08x},force-raw=on"]
        if assist:
            cmd += ["-gdb", f"tcp:127.0.0.1:{self.port}"]
        # Halted until `start`, so a client can connect to USART2 before the boot line.
        cmd += ["-S"] + list(extra)
        self.qemu = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, cwd=workdir,
                                     stdout=open(os.path.join(workdir, f"{name}.out"), "wb"),
                                     stderr=subprocess.STDOUT)
        self.points = []
        self.name = name
        # A bound on a hung start only (wall seconds).
        deadline = time.time() + 60
        while not (os.path.exists(self.u2) and os.path.exists(self.mon)):
            if self.qemu.poll() is not None or time.time() > deadline:
                raise SystemExit(f"qemu did not start (see {workdir}/{name}.out)")
            time.sleep(0.02)

    def start(self):
        """Lets the CPU run (through the boot assist if there is one)."""
        if self.port is None:
            self.monitor("cont")
            return
        script, self.points = boot_assist_script(self.elf, self.port, self.flash_kib,
                                                 self.crystal)
        path = os.path.join(self.workdir, f"{self.name}-boot-assist.gdb")
        with open(path, "w") as f:
            f.write(script)
        self.gdb = subprocess.Popen(["gdb-multiarch", "-q", "-nx", "-batch", "-x", path, self.elf],
                                    stdin=subprocess.DEVNULL,
                                    stdout=open(os.path.join(self.workdir, f"{self.name}-gdb.out"), "wb"),
                                    stderr=subprocess.STDOUT)

    def monitor(self, command, wait=30.0):
        """One HMP monitor command; returns its output (up to the next prompt). `wait` bounds
        a hung monitor (wall seconds); the output is complete when the prompt comes back,
        however long that takes."""
        with socket.socket(socket.AF_UNIX) as s:
            s.connect(self.mon)
            s.settimeout(wait)

            def until_prompt(out):
                try:
                    while b"(qemu)" not in out:
                        chunk = s.recv(4096)
                        if not chunk:
                            return out, "the monitor closed the connection"
                        out += chunk
                except socket.timeout:
                    return out, f"no monitor prompt within {wait} s"
                return out, None

            _, problem = until_prompt(b"")
            if problem is None:
                s.sendall(command.encode() + b"\n")
                out, problem = until_prompt(b"")
            if problem is not None:
                raise SystemExit(f"monitor `{command}`: {problem} (QEMU "
                                 f"{'running' if self.alive() else 'exited'})")
            return out.decode(errors="replace")

    def dump_ram(self, path):
        path = os.path.abspath(path)
        if os.path.exists(path):
            os.unlink(path)
        self.monitor(f'pmemsave 0x{RAM_ADDR:x} {RAM_LEN} "{path}"')
        # pmemsave writes the file before the monitor prompts again; the wait bounds a slow disk.
        deadline = time.time() + 30
        while not (os.path.exists(path) and os.path.getsize(path) == RAM_LEN):
            if time.time() > deadline:
                raise SystemExit("RAM dump failed")
            time.sleep(0.05)
        with open(path, "rb") as f:
            return f.read()

    def read_words(self, address, count):
        """`count` 32-bit words of guest memory at `address` (monitor `xp`)."""
        out = self.monitor(f"xp /{count}wx 0x{address:x}")
        words = []
        for line in out.splitlines():
            if ":" in line and line.split(":")[0].strip().startswith("0000"):
                words += [int(w, 16) for w in line.split(":", 1)[1].split()]
        if len(words) != count:
            raise SystemExit(f"monitor xp returned {len(words)} words, wanted {count}: {out!r}")
        return words

    def alive(self):
        return self.qemu.poll() is None

    def stop(self):
        for p in (self.gdb, self.qemu):
            if p is not None and p.poll() is None:
                p.terminate()
                try:
                    p.wait(5)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()


def watchdog_feeds(log_path):
    """Writes of the reload key 0xAAAA to IWDG_KR in QEMU's `-d unimp` log. QEMU 7.2 logs the
    IWDG's slot (0x4000_3000) under the name `I2S2ext`; both names are accepted."""
    n = 0
    with open(log_path, errors="replace") as f:
        for line in f:
            if (line.startswith(("IWDG:", "I2S2ext:")) and "device write" in line
                    and "offset 0x000, value 0xaaaa" in line.lower()):
                n += 1
    return n


def optional_symbol_address(elf, name):
    """The address of symbol `name` in the ELF, or None."""
    out = subprocess.run(["arm-none-eabi-nm", elf], check=True, capture_output=True,
                         text=True).stdout
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[2] == name:
            return int(parts[0], 16)
    return None


def symbol_address(elf, name):
    address = optional_symbol_address(elf, name)
    if address is None:
        raise SystemExit(f"symbol {name} not in {elf}")
    return address


def rtt_up_bytes(elf, ram):
    """The bytes in RTT up-buffer 0 (defmt's) of a RAM dump: what nobody has read yet."""
    cb = symbol_address(elf, "_SEGGER_RTT") - RAM_ADDR
    if ram[cb:cb + 10] != b"SEGGER RTT":
        raise SystemExit("RTT control block not initialised in the RAM dump")
    _name, buf, size, write, read, _flags = struct.unpack_from("<6I", ram, cb + 24)
    base = buf - RAM_ADDR
    data = ram[base:base + size]
    if write >= read:
        return data[read:write]
    return data[read:] + data[:write]


def defmt_log(elf, raw):
    """`raw` defmt frames decoded by defmt-print (text)."""
    tool = shutil.which("defmt-print") or os.path.expanduser("~/.cargo/bin/defmt-print")
    res = subprocess.run([tool, "-e", elf, "stdin"], input=raw, capture_output=True, timeout=60)
    return res.stdout.decode(errors="replace") + res.stderr.decode(errors="replace")
