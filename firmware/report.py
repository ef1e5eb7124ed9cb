"""Size and stack report of the firmware image (docs/FIRMWARE.md).

    python firmware/report.py build/firmware/firmware/proxops_fw.elf [--json out.json]

Size: every symbol of the linked ELF (nm -S) goes to a component, by its
demangled name for the firmware's own objects and by its archive (from the
linker map) for the C library, libm and libgcc; .text here is code and
read-only data in flash, .data initialised RAM (also in flash), .bss
zeroed RAM. Bytes no symbol covers (alignment) are counted apart. The RAM
each flight object takes (its sizeof) comes from the fw_size_* symbols of
the unloaded .fw_sizes section.

Stack: the worst-case stack of a function is its own frame plus the worst
of its callees, over the call graph of the linked image: calls (bl, blx to
a label) and tail calls (b.w to another function) read from the
disassembly, which also covers library functions and calls the compiler
emits itself (memcpy, libgcc). Frames come from -fstack-usage (the .su
files beside the objects) where the compiler wrote one, else from the
function's prologue (push, vpush, sub sp). Indirect calls (blx register)
have no static target: --indirect NAME adds NAME as a callee of every
function that makes one (the self-test harness: its output sink and its
instruction counter); a step function that reaches an indirect call, a
recursion or a dynamic frame is flagged rather than given a number.
"""
from __future__ import annotations

import argparse
import glob
import json
import os
import re
import subprocess
import sys
from collections import defaultdict

PREFIX = os.environ.get("PROXOPS_ARM_PREFIX", "arm-none-eabi-")

# Components, first match wins (demangled names, return type included).
COMPONENTS = [
    ("flight app", r"fsw::FlightApp<"),
    ("modal estimator", r"fsw::(Modal|ModeUkf|PlateModes|plate_|reconstruct_shape|modal_)"),
    ("navigation UKF + CW", r"fsw::(NavUkf|NavState|NavConfig|CwPropagator|cw_|propagate_attitude|exp<|log<|"
                            r"boxplus|boxminus|normalized|quat|so3|skew|orbit_rate|nav_|StepRecord|cholesky|"
                            r"symmetri|covariance)"),
    ("thruster learner", r"fsw::(BayesLinReg|ValveFeatures|Blr)"),
    ("link: framing, deframing", r"fsw::(Deframer|Framer|Cobs|cobs_|crc16|kApid|apid_|to_string|LinkCounters|"
                                 r"build_packet|frame_bytes|encode|decode|pack_|unpack_|get_|put_|"
                                 r"packet_|data_length|kCrc|Rejec)"),
    ("Eigen kernels", r"Eigen::"),
    ("recorded self-test input", r"^fw_input_begin$"),
    ("self-test harness, startup", r"(fwtest::|semihosting::|Reset_Handler|Fault_Handler|g_vectors|main$|"
                                   r"fw_input|fw_eigen_alloca_forbidden|__stack|__data|__bss|fw_)"),
]
# Else by the object that defined it.
ORIGINS = [
    ("self-test harness, startup", r"/(target/[^/]*|selftest\.cpp)\.obj$"),
    ("link: framing, deframing", r"/deframer\.cpp\.obj$"),
    ("flight app", r"/instantiate_flight_app\.cpp\.obj$"),
    ("modal estimator", r"/instantiate_modal\.cpp\.obj$"),
    ("navigation UKF + CW", r"/instantiate_nav\.cpp\.obj$"),
    ("thruster learner", r"/instantiate_blr\.cpp\.obj$"),
]
LIBS = [("newlib libm", "libm.a"), ("newlib-nano libc", "libc_nano.a"), ("newlib-nano libc", "libg_nano.a"),
        ("libgcc", "libgcc.a"), ("libstdc++", "libstdc++"), ("libstdc++", "libsupc++")]

# Step functions whose worst-case stack is reported (demangled name regex).
STEPS = [
    ("FlightApp<float>::on_bytes (whole app step)", r"^fsw::FlightApp<float>::on_bytes\("),
    ("FlightApp<float>::on_imu (imu_sample)", r"^fsw::FlightApp<float>::on_imu\("),
    ("FlightApp<float>::on_pose (led_pose)", r"^fsw::FlightApp<float>::on_pose\("),
    ("FlightApp<float>::on_plan (cmd_plan: load, start, abort)", r"^fsw::FlightApp<float>::on_plan\("),
    ("FlightApp<float>::plan_tick (a plan's valve command)", r"^fsw::FlightApp<float>::plan_tick\("),
    ("NavUkf<float>::predict", r"fsw::NavUkf<float, false, \d+>::predict\("),
    ("NavUkf<float>::update_pose", r"fsw::NavUkf<float, false, \d+>::update_pose\("),
    ("NavUkf<float>::reacquire", r"fsw::NavUkf<float, false, \d+>::reacquire\("),
    ("NavUkf<float>::init", r"fsw::NavUkf<float, false, \d+>::init\("),
    ("Deframer::feed", r"^fsw::Deframer::feed\("),
    ("Framer::frame (one telemetry packet)", r"^fsw::Framer::frame\("),
    ("BayesLinReg::add", r"fsw::BayesLinReg<float, 9, 6, 30>::add\("),
    ("BayesLinReg::remove_oldest", r"fsw::BayesLinReg<float, 9, 6, 30>::remove_oldest\("),
    ("BayesLinReg::predict", r"fsw::BayesLinReg<float, 9, 6, 30>::predict\("),
    ("ModalTracker::add (segment, image step)", r"fsw::ModalTracker<float, 10, [^>]*>, 256>::add\("),
    ("ModalTracker::close_other", r"fsw::ModalTracker<float, 10, [^>]*>, 256>::close_other\("),
    ("self-test run (all of the above)", r"^fwtest::run\("),
    ("Reset_Handler (whole program)", r"^Reset_Handler$"),
]


def tool(name, *args) -> str:
    return subprocess.run([PREFIX + name, *args], check=True, capture_output=True, text=True).stdout


def demangle(names):
    names = list(names)
    if not names:
        return {}
    out = subprocess.run([PREFIX + "c++filt"], input="\n".join(names), check=True, capture_output=True,
                         text=True).stdout.splitlines()
    return dict(zip(names, out))


def map_origins(map_path):
    """[(start, size, origin path)] of the input sections placed in the image."""
    out = []
    pending = None
    rx = re.compile(r"^\s+(0x[0-9a-f]+)\s+(0x[0-9a-f]+)\s+(\S.*)$")
    rx_one = re.compile(r"^ (\.\S+)\s+(0x[0-9a-f]+)\s+(0x[0-9a-f]+)\s+(\S.*)$")
    with open(map_path) as f:
        for line in f:
            m = rx_one.match(line)
            if m:
                out.append((int(m.group(2), 16), int(m.group(3), 16), m.group(4).strip()))
                pending = None
                continue
            if re.match(r"^ \.\S+$", line.rstrip("\n")):
                pending = line.strip()
                continue
            if pending:
                m = rx.match(line)
                if m:
                    out.append((int(m.group(1), 16), int(m.group(2), 16), m.group(3).strip()))
                pending = None
    return sorted(o for o in out if o[1] > 0 and o[0] > 0 or o[0] == 0 and o[1] > 0)


def origin_of(addr, origins):
    lo, hi = 0, len(origins)
    while lo < hi:
        mid = (lo + hi) // 2
        if origins[mid][0] <= addr:
            lo = mid + 1
        else:
            hi = mid
    if lo and origins[lo - 1][0] <= addr < origins[lo - 1][0] + origins[lo - 1][1]:
        return origins[lo - 1][2]
    return ""


def component(name, origin):
    for comp, lib in LIBS:
        if lib in origin:
            return comp
    for comp, rx in COMPONENTS:
        if re.search(rx, name):
            return comp
    for comp, rx in ORIGINS:
        if re.search(rx, origin):
            return comp
    return "other"


def section_table(elf):
    """{name: (size, address)} of the ELF's sections."""
    out = {}
    for line in tool("size", "-A", elf).splitlines():
        p = line.split()
        if len(p) == 3 and p[0].startswith("."):
            out[p[0]] = (int(p[1]), int(p[2]))
    return out


def section_sizes(elf):
    return {k: v[0] for k, v in section_table(elf).items()}


def size_report(elf, map_path):
    origins = map_origins(map_path)
    rows = defaultdict(lambda: {"text": 0, "data": 0, "bss": 0})
    fw_sizes = {}
    syms = []
    for line in tool("nm", "-S", "--size-sort", elf).splitlines():
        p = line.split(maxsplit=3)
        if len(p) != 4:
            continue
        addr, size, typ, name = int(p[0], 16), int(p[1], 16), p[2], p[3]
        syms.append((addr, size, typ, name))
    names = demangle(n for _, _, _, n in syms)
    table = section_table(elf)
    ranges = [(kind, table[sec][1], table[sec][1] + table[sec][0]) for kind, sec in
              (("text", ".text"), ("text", ".ARM.exidx"), ("text", ".init_array"), ("data", ".data"), ("bss", ".bss"))
              if sec in table]
    seen = set()
    for addr, size, typ, name in syms:
        if (addr, size) in seen and not name.startswith("fw_size_"):
            continue  # an alias (e.g. memset and __aeabi_memset)
        seen.add((addr, size))
        if name.startswith("fw_size_"):
            fw_sizes[name[len("fw_size_"):]] = size
            continue
        if typ in "NnUuAa":
            continue
        kind = next((k for k, lo, hi in ranges if lo <= addr < hi), None)
        if kind is None:
            continue
        comp = component(names[name], origin_of(addr, origins))
        rows[comp][kind] += size
        if comp == "other" and os.environ.get("FW_REPORT_DEBUG"):
            print("other:", names[name], origin_of(addr, origins), file=sys.stderr)
    sec = section_sizes(elf)
    text_total = sec.get(".text", 0) + sec.get(".ARM.exidx", 0) + sec.get(".init_array", 0)
    covered = {k: sum(r[k] for r in rows.values()) for k in ("text", "data", "bss")}
    rows["(alignment, no symbol)"] = {"text": text_total - covered["text"], "data": sec.get(".data", 0) - covered["data"],
                                      "bss": sec.get(".bss", 0) - covered["bss"]}
    return dict(rows), sec, fw_sizes


# ----------------------------------------------------------------------------- stack

def su_frames(build_dir):
    """Stack frames from the .ci files (mangled name -> (bytes, qualifier))."""
    frames = {}
    node = re.compile(r'node: \{ title: "(?:[^":]*:)?([^"]+)" label: "(.*?)" \}')
    for path in glob.glob(os.path.join(build_dir, "**", "*.ci"), recursive=True):
        with open(path) as f:
            for m in node.finditer(f.read()):
                lab = m.group(2)
                s = re.search(r"\\n(\d+) bytes \(([^)]*)\)$", lab)
                if s:
                    frames[m.group(1)] = (int(s.group(1)), s.group(2))
    return frames


def disassembly_graph(elf):
    """Functions (mangled) -> (start, prologue frame, callees, has indirect call, dynamic sp)."""
    funcs = {}
    cur = None
    head = re.compile(r"^([0-9a-f]+) <(.+)>:$")
    ins = re.compile(r"^\s+([0-9a-f]+):\s+(?:[0-9a-f]{4}\s?){1,2}\s+(\S+)\s*(.*)$")
    for line in tool("objdump", "-d", "--no-show-raw-insn", elf).splitlines():
        m = head.match(line)
        if m:
            cur = m.group(2)
            funcs[cur] = {"start": int(m.group(1), 16), "frame": 0, "callees": set(), "indirect": False,
                          "dynamic": False, "n": 0}
            continue
        if cur is None:
            continue
        m = re.match(r"^\s+([0-9a-f]+):\s+(\S+)\s*(.*)$", line)
        if not m:
            continue
        op, args = m.group(2), m.group(3)
        f = funcs[cur]
        f["n"] += 1
        if f["n"] <= 8:  # prologue
            if op in ("push", "push.w", "stmdb") and "sp" in args.split(",")[0] or op in ("push", "push.w"):
                regs = re.search(r"\{([^}]*)\}", args)
                if regs:
                    f["frame"] += 4 * _count_regs(regs.group(1))
            elif op in ("vpush", "vpush.64", "vstmdb"):
                regs = re.search(r"\{([^}]*)\}", args)
                if regs:
                    f["frame"] += (8 if "d" in regs.group(1) else 4) * _count_regs(regs.group(1))
            elif op in ("sub", "sub.w", "subw") and args.startswith("sp, "):
                imm = re.search(r"#(\d+)", args)
                if imm:
                    f["frame"] += int(imm.group(1))
        t = re.search(r"<([^>+]+)(\+0x[0-9a-f]+)?>", args)
        if op in ("bl", "blx") and t and not t.group(2):
            f["callees"].add(t.group(1))
        elif op == "blx" and not t:
            f["indirect"] = True
        elif op in ("b.w", "b") and t and not t.group(2) and t.group(1) != cur:
            f["callees"].add(t.group(1))  # tail call
        if op in ("mov", "mov.w") and args.startswith("sp, ") or (op in ("sub", "sub.w") and args.startswith("sp, ")
                                                                  and "#" not in args):
            f["dynamic"] = True
    return funcs


def _count_regs(spec):
    n = 0
    for part in spec.split(","):
        part = part.strip()
        if "-" in part:
            a, b = part.split("-")
            n += int(re.sub(r"\D", "", b)) - int(re.sub(r"\D", "", a)) + 1
        elif part:
            n += 1
    return n


def stack_report(elf, build_dir, indirect_targets):
    funcs = disassembly_graph(elf)
    su = su_frames(build_dir)
    frames, source = {}, {}
    for name, f in funcs.items():
        if name in su:
            frames[name], source[name] = su[name][0], "su"
            if su[name][1] != "static":
                f["dynamic"] = True
        else:
            frames[name], source[name] = f["frame"], "prologue"
    memo, state = {}, {}

    def worst(name):
        """(bytes, path, flags)"""
        if name in memo:
            return memo[name]
        if state.get(name) == "open":
            return (0, [name], {"recursion"})
        state[name] = "open"
        f = funcs.get(name)
        if f is None:
            memo[name] = (0, [name], {"unknown:" + name})
            state[name] = "done"
            return memo[name]
        flags = set()
        if f["dynamic"]:
            flags.add("dynamic")
        callees = set(f["callees"])
        if f["indirect"]:
            if indirect_targets:
                callees |= set(indirect_targets)
            else:
                flags.add("indirect")
        best = (0, [], set())
        for c in sorted(callees):
            w = worst(c)
            flags |= w[2]
            if w[0] > best[0]:
                best = w
        memo[name] = (frames[name] + best[0], [name] + best[1], flags)
        state[name] = "done"
        return memo[name]

    names = demangle(funcs)
    mangled_of = {}
    for mangled, dem in names.items():
        mangled_of.setdefault(dem, mangled)
    rows = []
    for label, rx in STEPS:
        hits = [m for m, d in names.items() if re.search(rx, d)]
        if not hits:
            rows.append({"step": label, "bytes": None, "note": "inlined into its caller (no symbol)"})
            continue
        best = max(hits, key=lambda m: worst(m)[0])
        b, path, flags = worst(best)
        rows.append({"step": label, "bytes": b, "frame": frames[best], "flags": sorted(flags),
                     "deepest_path": [names.get(p, p) for p in path]})
    checked = sum(1 for n in funcs if source[n] == "su")
    mismatch = [n for n in funcs if n in su and su[n][1] == "static" and funcs[n]["frame"] != su[n][0]]
    return rows, {"functions": len(funcs), "frames_from_su": checked, "prologue_disagrees_with_su": len(mismatch)}


def short(name, n=90):
    name = re.sub(r"\(.*", "(...)", name)
    return name if len(name) <= n else name[:n - 3] + "..."


def main(argv=None):
    ap = argparse.ArgumentParser(description="Firmware size and stack report.")
    ap.add_argument("elf")
    ap.add_argument("--map", help="linker map (default: the ELF's with .map)")
    ap.add_argument("--build-dir", help="where the .ci/.su files are (default: the ELF's folder)")
    ap.add_argument("--indirect", action="append", default=[], help="a target of the indirect calls (demangled name)")
    ap.add_argument("--json", help="write the figures here too")
    a = ap.parse_args(argv)
    elf = a.elf
    map_path = a.map or re.sub(r"\.elf$", "", elf) + ".map"
    build_dir = a.build_dir or os.path.dirname(os.path.abspath(elf))

    rows, sec, fw_sizes = size_report(elf, map_path)
    print(f"Firmware image {elf}")
    print(f"  sections: .text {sec.get('.text', 0)} B (code and read-only data, flash), "
          f".data {sec.get('.data', 0)} B (RAM, copied from flash), .bss {sec.get('.bss', 0)} B (RAM), "
          f"main stack {sec.get('.stack', 0)} B (RAM)")
    print(f"\n  {'component':34s} {'.text':>9s} {'.data':>7s} {'.bss':>9s}")
    order = [c for c, _ in COMPONENTS] + sorted({c for c, _ in LIBS}) + ["other", "(alignment, no symbol)"]
    for comp in order:
        if comp in rows:
            r = rows[comp]
            print(f"  {comp:34s} {r['text']:9d} {r['data']:7d} {r['bss']:9d}")
    print(f"  {'total':34s} {sum(r['text'] for r in rows.values()):9d} {sum(r['data'] for r in rows.values()):7d} "
          f"{sum(r['bss'] for r in rows.values()):9d}")
    print("\n  RAM of the flight objects (sizeof, float build; the self-test holds them in its arena, .bss):")
    for k, v in fw_sizes.items():
        print(f"    {k:24s} {v:8d} B")

    demangled_targets = a.indirect
    funcs_dem = None
    targets = []
    if demangled_targets:
        funcs = disassembly_graph(elf)
        funcs_dem = demangle(funcs)
        for t in demangled_targets:
            hit = [m for m, d in funcs_dem.items() if d.startswith(t)]
            if not hit:
                sys.exit(f"--indirect {t}: no such function in the image")
            targets += hit
    steps, meta = stack_report(elf, build_dir, targets)
    print(f"\n  Worst-case stack per step function (call graph of the image: {meta['functions']} functions, "
          f"{meta['frames_from_su']} frames from -fstack-usage, the rest from prologues):")
    for r in steps:
        if r["bytes"] is None:
            print(f"    {r['step']:44s}      -   {r['note']}")
        else:
            fl = (" [" + ", ".join(r["flags"]) + "]") if r["flags"] else ""
            print(f"    {r['step']:44s} {r['bytes']:6d} B{fl}")
            print(f"      deepest: {' -> '.join(short(p, 60) for p in r['deepest_path'][:6])}"
                  + (" -> ..." if len(r["deepest_path"]) > 6 else ""))
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"sections": sec, "components": rows, "flight_objects": fw_sizes, "stack": steps,
                       "stack_graph": meta}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
