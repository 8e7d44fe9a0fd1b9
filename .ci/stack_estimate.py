#!/usr/bin/env python3
"""Static worst-case stack estimate of a Cortex-M ELF (e.g. the release firmware).

    python3 .ci/stack_estimate.py target/thumbv7em-none-eabihf/release/firmware

Reads `arm-none-eabi-objdump -d`; for every function it adds up the prologue's stack use
(`push`/`stmdb sp!`, `vpush`, `sub sp`) and follows direct calls (`bl`, `blx <label>`) and tail
branches into other functions through the call graph. It prints the deepest path from the reset
handler and from every interrupt/exception handler, and a conservative total: the reset path plus
every handler nested once, each with a 104-byte exception frame (FP context). Indirect calls
(`blx rN`) and recursion cannot be followed; they are listed, and the estimate is a lower bound
for paths through them.
"""
import re
import subprocess
import sys
from functools import lru_cache

FRAME_FP = 104  # exception entry with FP context (26 words)

FUNC = re.compile(r"^([0-9a-f]+) <(.+)>:$")
INSN = re.compile(r"^\s*([0-9a-f]+):\s+(\S+)\s*(.*)$")
REGLIST = re.compile(r"\{([^}]*)\}")


def reg_count(lst):
    n = 0
    for part in lst.split(","):
        part = part.strip()
        if "-" in part:
            a, b = part.split("-")
            n += int(b[1:]) - int(a[1:]) + 1
        elif part:
            n += 1
    return n


def parse(elf):
    out = subprocess.run(
        ["arm-none-eabi-objdump", "-d", "--no-show-raw-insn", "-C", elf],
        check=True, capture_output=True, text=True).stdout
    funcs = {}  # name -> dict(frame, calls, indirect, dynamic)
    addr_to_name = {}
    cur = None
    for line in out.splitlines():
        m = FUNC.match(line)
        if m:
            cur = m.group(2)
            addr_to_name[int(m.group(1), 16)] = cur
            funcs[cur] = {"frame": 0, "calls": set(), "indirect": False, "dynamic": False}
            continue
        if cur is None:
            continue
        m = INSN.match(line)
        if not m:
            continue
        op, args = m.group(2), m.group(3)
        f = funcs[cur]
        base = op.split(".")[0]
        if base == "push" or (base == "stmdb" and args.startswith("sp!")):
            r = REGLIST.search(args)
            if r:
                f["frame"] += 4 * reg_count(r.group(1))
        elif base == "vpush":
            r = REGLIST.search(args)
            if r:
                size = 8 if r.group(1).strip().startswith("d") else 4
                f["frame"] += size * reg_count(r.group(1))
        elif base in ("sub", "subw") and re.match(r"sp,\s*(sp,\s*)?#", args):
            f["frame"] += int(re.search(r"#(\d+)", args).group(1))
        elif base in ("sub", "subw") and args.startswith("sp,"):
            f["dynamic"] = True
        elif base in ("bl", "blx"):
            t = re.search(r"<([^>+]+)>", args)
            if t:
                f["calls"].add(t.group(1))
            else:
                f["indirect"] = True
        elif re.fullmatch(r"b(eq|ne|cs|cc|mi|pl|vs|vc|hi|ls|ge|lt|gt|le|al)?(\.[nw])?", op):
            # A branch to the start of another function is a tail call.
            t = re.search(r"<([^>]+)>", args)
            if t and "+" not in t.group(1) and t.group(1) != cur:
                f["calls"].add(t.group(1))
    return funcs


def main():
    elf = sys.argv[1]
    funcs = parse(elf)
    notes = set()

    @lru_cache(maxsize=None)
    def depth(name, stack=()):
        f = funcs.get(name)
        if f is None:
            return 0, (name,)
        if name in stack:
            notes.add(f"recursion through {name}")
            return 0, (name,)
        if f["indirect"]:
            notes.add(f"indirect call in {name}")
        if f["dynamic"]:
            notes.add(f"dynamic stack adjustment in {name}")
        best, path = 0, ()
        for c in f["calls"]:
            d, p = depth(c, stack + (name,))
            if d > best:
                best, path = d, p
        return f["frame"] + best, (name,) + path

    syms = subprocess.run(["arm-none-eabi-nm", elf], check=True, capture_output=True,
                          text=True).stdout.split("\n")
    handlers = sorted({l.split()[2] for l in syms if len(l.split()) == 3 and l.split()[1] == "T"
                       and re.fullmatch(r"[A-Z][A-Z0-9_]+", l.split()[2])} - {"Reset"})
    main_depth, main_path = depth("Reset")
    print(f"reset path: {main_depth} B  ({' > '.join(main_path[:8])}{' ...' if len(main_path) > 8 else ''})")
    total = main_depth
    for h in handlers:
        d, p = depth(h)
        if d == 0 and not funcs.get(h, {}).get("calls"):
            continue
        print(f"handler {h}: {d} B  ({' > '.join(p[:6])}{' ...' if len(p) > 6 else ''})")
        total += d + FRAME_FP
    print(f"conservative total (reset path + every handler nested once, {FRAME_FP} B frames): {total} B")
    for n in sorted(notes):
        print(f"note: {n}")


if __name__ == "__main__":
    main()
