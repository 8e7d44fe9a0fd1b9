#!/usr/bin/env python3
"""Stage 1 of the firmware-in-the-loop test: the shipped ELF in QEMU.

Boots the exact image `cargo fw` builds (with the boot assist of `emulator.py`), waits for the
`event boot` line on USART2, sends the console script below (every command family, error cases,
an over-long line, CR endings, garbage bytes, Ctrl-C, escape sequences) and compares each reply with
`fil/golden/console.txt`; pastes a block of 31 lines with echo on and checks that each is echoed
right before its reply, in order; pastes 95 lines, more than the input queue holds, and checks
that each is answered in order or counted as lost in one notice after the last reply (how many
are lost depends on the host's speed: none is a pass too); types `status` key by key with the
pose stream on and checks that no stream line lands between its keys; then decodes the defmt
boot log from the RTT buffer of a RAM dump. Every check waits for what the console sends (a
reply, a marker command's reply, stream lines), never for a time to pass; the timeouts only
bound a hang.

    python3 fil/boot_test.py ELF [--regen] [--workdir DIR] [--board NAME]

`--board` (fil/boards.py, default `f407`): the board the ELF is built for. Its storage regions
and flash size go to the emulator; the golden file is the F407's, and a board's boot line differs
from it only in the clock it names (the board's `clock_note`), which is swapped in.

Prints `shipped ELF <sha256 prefix>: <N> console lines answered as expected` and exits 0 when
every reply matches; `--regen` rewrites the golden file from this run instead.
"""

import argparse
import hashlib
import os
import re
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from console import Console, ConsoleError  # noqa: E402
from boards import BOARDS, board as board_profile, boot_tail  # noqa: E402
from emulator import Emulator, defmt_log, rtt_up_bytes, watchdog_feeds  # noqa: E402

GOLDEN = os.path.join(os.path.dirname(os.path.abspath(__file__)), "golden", "console.txt")

# (bytes sent, whether a final reply is expected). Lines end with CR LF unless written out.
SCRIPT = [
    (b"echo off\r\n", True),
    (b"help\r\n", True),
    (b"?\r\n", True),
    (b"status\r\n", True),
    (b"params\r\n", True),
    (b"set square_side 0.5\r\n", True),
    (b"SET Runs_Per_Direction 1\r\n", True),
    (b"set bogus 1\r\n", True),
    (b"set d_right abc\r\n", True),
    (b"set wheelbase 0,385\r\n", True),
    (b"set wheelbase 385mm\r\n", True),
    (b"set d_right nan\r\n", True),
    (b"set wheelbase 99\r\n", True),
    (b"set max_speed\r\n", True),
    (b"frobnicate\r\n", True),
    (b"pose\r\n", True),
    (b"odom reset\r\n", True),
    (b"runs\r\n", True),
    (b"drop 1\r\n", True),
    (b"measure\r\n", True),
    (b"measure 0.1m 0.2m 3deg\r\n", True),
    (b"calibrate\r\n", True),
    (b"calibrate exakt\r\n", True),
    (b"apply exact\r\n", True),
    (b"stream on 5\r\n", True),
    (b"stream off\r\n", True),
    (b"clear\r\n", True),
    (b"\r\n", False),
    (b"x" * 100 + b"\r\n", True),
    (b"status \xff\xfe\r\n", True),
    (b"\x00\x01\x02garbage\x7f\x7f\x7f\x7f\x7f\x7f\x7fstatus\r\n", True),
    (b"pose\r", True),
    (b"params\r", True),
    (b"half a line\x03status\r", True),
    (b"\x1b[A\x1b[B\x1bOPstop\r\n", True),
    (b"run cw 0.5\r\n", True),
    (b"status\r\n", True),
    (b"save\r\n", True),
    (b"stop\r\n", True),
    (b"drive 0.1 0\r\n", True),
    (b"stop\r\n", True),
    (b"line 0.3\r\n", True),
    (b"stop\r\n", True),
    (b"circle ccw 0.2\r\n", True),
    (b"stop\r\n", True),
    (b"next\r\n", True),
    (b"stop\r\n", True),
    (b"runs\r\n", True),
    (b"status\r\n", True),
]

# How long to wait for a reply (wall seconds): it bounds a hang, nothing waits for it to pass.
REPLY_TIMEOUT = 30.0
# How long to collect late lines (events) before the events are compared (wall seconds).
NO_REPLY_WAIT = 0.5
# A command with a one-line reply and no effect, sent after a line that expects no reply: what
# that line caused comes before the marker's reply, however long it takes.
MARKER = b"status\r\n"


def no_reply(con):
    """The reply lines that the line just sent caused (none expected), read up to the reply of
    MARKER; the marker's reply itself is not returned."""
    con.send_raw(MARKER)
    got = []
    while True:
        try:
            data, final = con.reply(REPLY_TIMEOUT)
        except ConsoleError:
            return got + ["(no reply to the marker)"]
        if final.startswith("ok state="):
            return got + data
        got += data + [final]


# A block pasted into a terminal with echo on: 30 `set` lines and `runs`, sent at once (656 bytes
# packed: it fits the 711-byte input queue however fast or slow the bytes arrive).
PASTE = [f"set square_side {1 + i / 100:.2f}" for i in range(30)] + ["runs"]
# More than the input queue holds if they all arrive before the console takes any (about 2 KB).
# Whether any are lost depends on how fast QEMU hands the bytes to the USART relative to the
# console task's one line per millisecond of (host-clocked) virtual time: on a slow host none are.
OVERFLOW = [f"set square_side {1 + i / 100:.2f}" for i in range(95)]
OVERFLOW_REPLY = re.compile(
    r"ok square_side = (\d+\.\d{3}) m( \(unchanged\)| \(not saved; save to keep\))"
)
OVERFLOW_NOTICE = re.compile(r"err 10: (\d+) line\(s\) dropped: input queue full")
# The longest the console may stay silent while it works through a paste (wall seconds): it
# bounds a hang, nothing waits for it to pass.
PASTE_TIMEOUT = 30.0


def overflow_check(con):
    """Pastes OVERFLOW (echo off); returns (problems, outcome). What holds at any relative speed
    of host and emulator: every line is answered `ok` in order or counted as lost; if some are
    lost, one `err 10: N line(s) dropped` notice follows the last reply and answered + N is the
    whole paste; if none are lost, there is no notice."""
    con.send_raw("\r".join(OVERFLOW).encode() + b"\r")
    replies = []
    answered = 0
    # Until the paste is accounted for: every line answered, or the notice (which comes only
    # once the lines kept have been answered).
    while answered < len(OVERFLOW) and not any(OVERFLOW_NOTICE.fullmatch(r) for r in replies):
        line = con.read_line(PASTE_TIMEOUT)
        if line is None:
            break
        if con._sort(line) == "reply":
            replies.append(line)
            answered += 1 if line.startswith("ok ") else 0
    # `status` as a marker: whatever the paste still causes (a late notice, a second one, a
    # reply after the notice) comes before its reply.
    con.send_raw(b"status\r\n")
    deadline = time.time() + PASTE_TIMEOUT
    marker = None
    while marker is None and time.time() < deadline:
        line = con.read_line(deadline - time.time())
        if line is None:
            break
        if con._sort(line) != "reply":
            continue
        if line.startswith("ok state="):
            marker = line
        else:
            replies.append(line)
    problems = []
    if marker is None:
        problems.append(f"no reply to `status` after the paste within {PASTE_TIMEOUT} s")
    taken = []
    notices = []
    for i, r in enumerate(replies):
        ok = OVERFLOW_REPLY.fullmatch(r)
        notice = OVERFLOW_NOTICE.fullmatch(r)
        if ok:
            taken.append(round((float(ok.group(1)) - 1) * 100))
        elif notice:
            notices.append((i, int(notice.group(1))))
        else:
            problems.append(f"reply {i + 1} `{r}` is neither a line's reply nor the notice")
    if taken != sorted(set(taken)) or any(not 0 <= t < len(OVERFLOW) for t in taken):
        problems.append(f"lines answered out of order or twice: {taken}")
    lost = sum(n for _, n in notices)
    if len(notices) > 1:
        problems.append(f"{len(notices)} notices for one paste: {[replies[i] for i, _ in notices]}")
    if notices and notices[-1][0] != len(replies) - 1:
        problems.append(f"the notice is not the last reply: {replies[notices[-1][0]:][:3]}")
    if len(taken) + lost != len(OVERFLOW):
        problems.append(f"{len(OVERFLOW)} lines pasted: {len(taken)} answered + {lost} reported "
                        f"lost (notices {[replies[i] for i, _ in notices]}, last reply "
                        f"`{replies[-1] if replies else None}`)")
    if notices:
        outcome = (f"{len(OVERFLOW)} lines pasted at once (more than the input queue holds): "
                   f"{len(taken)} answered in order, then `{replies[notices[0][0]]}` as the last "
                   "reply (the queue overflowed)")
    else:
        outcome = (f"{len(OVERFLOW)} lines pasted at once (more than the input queue holds): all "
                   f"{len(taken)} answered in order, no notice (the console kept up with the "
                   "bytes as QEMU delivered them)")
    return problems, outcome


def paste_check(con):
    """Pastes PASTE with echo on, then OVERFLOW with echo off; returns the problems found (none:
    every PASTE line answered, in order, each echoed right before its reply; OVERFLOW as
    `overflow_check`) and the lines seen, the OVERFLOW outcome last."""
    con.ok("echo on")
    # The echo of `echo on`'s own line ends before its reply; nothing else is pending.
    con.send_raw("\r".join(PASTE).encode() + b"\r")
    got = []
    while len(got) < 2 * len(PASTE):
        line = con.read_line(REPLY_TIMEOUT)
        if line is None:
            break
        if con._sort(line) == "reply":
            got.append(line)
    con.ok("echo off")
    problems = []
    for i, cmd in enumerate(PASTE):
        pair = got[2 * i:2 * i + 2]
        if len(pair) < 2 or pair[0] != cmd or not pair[1].startswith("ok"):
            problems.append(f"line {i + 1} `{cmd}`: got {pair}")
    overflow_problems, outcome = overflow_check(con)
    got.append(outcome)
    return problems + overflow_problems, got


# A line typed key by key while the pose stream runs (echo on): one key per TYPING_GAP seconds
# (how many stream lines fall into a gap depends on the host; the stream must hold whatever it
# is). STREAM_AROUND whole stream lines are awaited before the first key and after the reply,
# for at most TYPING_TIMEOUT wall seconds (a bound on a hang only).
TYPED = b"status\r"
TYPING_GAP = 0.1
STREAM_AROUND = 5
TYPING_TIMEOUT = 30.0
STREAM = re.compile(r"stream -?\d+\.\d{6}( [+-]\d+\.\d+){5}")


def typing_check(con):
    """Types `status` key by key with echo on and the pose stream at 20 Hz; returns the
    problems found (none: the echo reads `status` whole, right before its reply, every other
    line is a whole stream line, and the stream resumes after the reply) and the lines seen."""
    con.ok("echo on")
    con.ok("stream on 20")
    problems = []
    # The stream runs before the first key.
    before = 0
    deadline = time.time() + TYPING_TIMEOUT
    while before < STREAM_AROUND:
        line = con.read_line(max(0.0, deadline - time.time()))
        if line is None:
            problems.append(f"the stream did not start: {before} lines in {TYPING_TIMEOUT} s")
            break
        con._sort(line)
        before += 1 if STREAM.fullmatch(line) else 0
    for key in TYPED:
        con.send_raw(bytes([key]))
        time.sleep(TYPING_GAP)
    # Everything up to STREAM_AROUND stream lines after the reply.
    lines = []
    after = None
    deadline = time.time() + TYPING_TIMEOUT
    while after is None or after < STREAM_AROUND:
        line = con.read_line(max(0.0, deadline - time.time()))
        if line is None:
            break
        lines.append(line)
        if line.startswith("ok state="):
            after = 0
        elif after is not None and STREAM.fullmatch(line):
            after += 1
    con.ok("stream off")
    con.ok("echo off")
    typed = TYPED.decode().strip()
    if typed not in lines:
        problems.append(f"no `{typed}` line (the echo was cut): {lines[:8]}")
    else:
        at = lines.index(typed)
        if at + 1 >= len(lines) or not lines[at + 1].startswith("ok state="):
            problems.append(f"`{typed}` not followed by its reply: {lines[at:at + 3]}")
        others = [l for i, l in enumerate(lines) if i not in (at, at + 1)]
        cut = [l for l in others if not STREAM.fullmatch(l)]
        if cut:
            problems.append(f"lines that are not whole stream lines: {cut[:4]}")
        if (after or 0) < STREAM_AROUND:
            problems.append(f"the stream did not resume after the line within {TYPING_TIMEOUT} "
                            f"s: {lines}")
    return problems, lines


# Reload-key writes in the stage-1 run: 1 that starts the watchdog + 2 around the boot's flash
# access (see `main`).
WATCHDOG_FEEDS = 1 + 2


def shown(data):
    """Sent bytes as one printable line."""
    return "".join(chr(b) if 32 <= b < 127 and b != 92 else f"\\x{b:02x}" for b in data)


def run(elf, workdir, board="f407"):
    emu = Emulator(elf, workdir, assist=True, name="shipped", board=board)
    blocks = []
    try:
        con = Console.unix(emu.u2)
        emu.start()
        boot = con.wait_event("event boot", 60)
        blocks.append(("(reset)", [boot]))
        for data, expect_reply in SCRIPT:
            con.send_raw(data)
            if expect_reply:
                try:
                    lines, final = con.reply(REPLY_TIMEOUT)
                    got = lines + [final]
                except ConsoleError:
                    got = ["(no reply)"]
            else:
                got = no_reply(con) or ["(no reply)"]
            blocks.append((shown(data), got))
        con.quiet(NO_REPLY_WAIT)
        paste = paste_check(con)
        typing = typing_check(con)
        # Events (e.g. the stop a Ctrl-C causes) come when the console task gets to them, not
        # at a fixed place among the replies: they are compared as one set at the end.
        con.quiet(NO_REPLY_WAIT)
        blocks.append(("(events after the boot line)", sorted(con.events)))
        ram = emu.dump_ram(os.path.join(workdir, "shipped-ram.bin"))
        alive = emu.alive()
    finally:
        emu.stop()
    log = defmt_log(elf, rtt_up_bytes(elf, ram))
    return blocks, log, alive, emu.points, paste, typing


def collapse(lines):
    """Runs of identical lines as (line, count)."""
    out = []
    for line in lines:
        if out and out[-1][0] == line:
            out[-1][1] += 1
        else:
            out.append([line, 1])
    return out


def render(blocks):
    out = []
    for sent, got in blocks:
        out.append("> " + sent)
        out += ["< " + g for g in got]
    return "\n".join(out) + "\n"


def parse(text):
    blocks = []
    for line in text.splitlines():
        if line.startswith("> "):
            blocks.append((line[2:], []))
        elif line.startswith("< ") and blocks:
            blocks[-1][1].append(line[2:])
    return blocks


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("elf")
    ap.add_argument("--regen", action="store_true")
    ap.add_argument("--workdir", default="target/fil")
    ap.add_argument("--board", default="f407", choices=sorted(BOARDS))
    args = ap.parse_args()
    profile = board_profile(args.board)
    sha = hashlib.sha256(open(args.elf, "rb").read()).hexdigest()
    print(f"boot test: {args.elf} sha256 {sha}")
    blocks, log, alive, points, (paste_problems, paste_got), (typing_problems, typed) = run(
        args.elf, args.workdir, args.board)
    print("boot assist (generated from the ELF):")
    for kind, bp, resume, reg in points:
        where = reg if isinstance(reg, str) else f"{reg[0]} + {reg[1]}, lsls #{reg[2]}"
        print(f"  {kind:10} break 0x{bp:08x} resume 0x{resume:08x} ({where})")
    print("defmt log (RTT buffer of the RAM dump, decoded by defmt-print):")
    for line, n in collapse(log.splitlines()):
        print("  " + line + (f"   (x{n})" if n > 1 else ""))
    text = render(blocks)
    with open(os.path.join(args.workdir, "console.txt"), "w") as f:
        f.write(text)
    if args.regen and args.board != "f407":
        raise SystemExit("--regen: the golden file is the F407's (run it with --board f407)")
    if args.regen:
        os.makedirs(os.path.dirname(GOLDEN), exist_ok=True)
        with open(GOLDEN, "w") as f:
            f.write(text)
        print(f"golden file rewritten: {GOLDEN}")
    golden = parse(open(GOLDEN).read())
    # The board's boot line names its own clock and control timer.
    f407_end = "; " + BOARDS["f407"]["clock_note"] + boot_tail(BOARDS["f407"])
    board_end = "; " + profile["clock_note"] + boot_tail(profile)
    golden = [(sent, [g.replace(f407_end, board_end) if sent == "(reset)"
                      else g for g in want]) for sent, want in golden]
    fail = 0
    good = 0
    if len(golden) != len(blocks):
        print(f"FAILED: {len(blocks)} exchanges, golden file has {len(golden)}")
        fail = 1
    for (sent, got), (gsent, gwant) in zip(blocks, golden):
        if sent == gsent and got == gwant:
            good += 1 if not sent.startswith("(") else 0
        else:
            fail = 1
            print(f"MISMATCH after `{sent}`:\n  want {gwant}\n  got  {got}")
    if "odocal up" not in log:
        print("FAILED: the boot log has no `odocal up` line")
        fail = 1
    if not alive:
        print("FAILED: QEMU exited during the test")
        fail = 1
    if paste_problems:
        print(f"FAILED: a pasted block of {len(PASTE)} lines with echo on:")
        for p in paste_problems[:5]:
            print("  " + p)
        fail = 1
    else:
        print(f"paste: {len(PASTE)} lines pasted at once with echo on, each echoed right before "
              f"its reply, in order (`{paste_got[0]}` … `{paste_got[-2]}`)")
        print(f"paste: {paste_got[-1]}")
    if typing_problems:
        print("FAILED: `status` typed key by key with the pose stream on:")
        for p in typing_problems:
            print("  " + p)
        fail = 1
    else:
        streams = sum(1 for l in typed if l.startswith("stream "))
        print(f"typing: `status` typed key by key ({TYPING_GAP} s apart) with the pose stream at "
              f"20 Hz: echoed whole right before its reply, {streams} whole stream lines around "
              "it, none between its keys")
    # QEMU has no TIM7 (nor TIM11), so the control task never runs here. The feeds are exactly: the one of
    # `init` that starts the watchdog (`set_timeout`), and the two of the console task's one
    # flash access with the watchdog relaxed (restoring the stored runs at boot: 10 s and back to
    # 50 ms, one reload-key write after each change has crossed over; the script's `save` is
    # refused before the flash is touched, the encoders never having been read). Fewer: the
    # watchdog never started, or the boot's flash access ran under the 50 ms timeout (on the
    # board a repairing erase would reset it). More: something feeds it without a control task,
    # which would hide a stalled control task (on the board the watchdog resets it 50 ms later).
    feeds = watchdog_feeds(os.path.join(args.workdir, "shipped.log"))
    print(f"watchdog: {feeds} feeds (IWDG_KR = 0xAAAA) in the QEMU log, {WATCHDOG_FEEDS} expected "
          "(start, then relaxed and restored around the boot's flash access); the control task "
          f"never ran (no {profile['timer_name']} in QEMU): a stalled control task, seen as "
          "missing feeds")
    if feeds != WATCHDOG_FEEDS:
        print(f"FAILED: {feeds} watchdog feeds, not {WATCHDOG_FEEDS}")
        fail = 1
    if fail:
        print(f"boot test FAILED (transcript: {args.workdir}/console.txt)")
        return 1
    print(f"shipped ELF {sha[:12]} ({args.board}): {good} console lines answered as expected")
    return 0


if __name__ == "__main__":
    sys.exit(main())
