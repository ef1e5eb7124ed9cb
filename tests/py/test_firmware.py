"""The Cortex-M7 firmware (firmware/, docs/FIRMWARE.md): what its linked
image contains, its stack, and its self-test under QEMU against the host
float build.

`make test` builds the image first and sets PROXOPS_FIRMWARE_BUILD; then a
missing image or tool fails these tests. Without it they look in
build/firmware and skip when nothing is there."""

import json
import os
import re
import subprocess
import sys

import pytest

from hil_sim import firmware as fw

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
FW_BUILD = os.environ.get("PROXOPS_FIRMWARE_BUILD")
ELF = os.path.join(FW_BUILD or os.path.join(ROOT, "build", "firmware"), "firmware", "proxops_fw.elf")
HOST_EXE = os.path.join(os.environ.get("PROXOPS_CPP_BUILD", os.path.join(ROOT, "build", "cpp")), "fw_selftest_host")
NM = "arm-none-eabi-nm"

sys.path.insert(0, os.path.join(ROOT, "firmware"))
import report  # noqa: E402  (firmware/report.py)


def _need(path):
    if not os.path.exists(path):
        if FW_BUILD:
            pytest.fail(f"{path} missing (make firmware builds it)")
        pytest.skip(f"{path} not built (make firmware)")


# Symbols that mean a heap, exceptions or stdio in the image.
FORBIDDEN = re.compile(
    r"^(malloc|free|calloc|realloc|memalign|aligned_alloc|posix_memalign|_malloc_r|_free_r|_calloc_r|_realloc_r|"
    r"_sbrk|_sbrk_r|sbrk|"
    r"_Zn[wa].*|_Zd[la].*|"  # operator new / delete, all forms
    r"__cxa_(throw|allocate_exception|begin_catch|end_catch|rethrow|guard_acquire|atexit)|"
    r"__gxx_personality_v0|_Unwind_.*|__aeabi_unwind_cpp_pr\d|"
    r"_?(v|f|s|sn|as|d|i|fi|si|sni)?printf(_r)?|_v?f?printf_r|_svfi?printf_r|_vfi?printf_r|"
    r"(f|)puts|putchar|fputc|putc|fwrite|fflush|fopen|fclose|_fwrite_r|_fputs_r|__sfvwrite_r|__swsetup_r|"
    r"__sinit|stdout|stderr|_write|_write_r|_read|_close|_lseek|_fstat|_isatty)$"
)
# (newlib's _impure_ptr, its per-thread state, is linked: the float
# functions set errno through it.)


def forbidden_symbols(nm_output: str) -> list:
    out = []
    for line in nm_output.splitlines():
        p = line.split()
        if p and FORBIDDEN.match(p[-1]):
            out.append(p[-1])
    return sorted(set(out))


def test_the_symbol_check_finds_what_it_forbids():
    # The pattern itself: the names newlib and libstdc++ give these functions.
    nm = "\n".join(
        f"00001000 T {n}"
        for n in (
            "malloc",
            "_Znwj",
            "_ZdlPvj",
            "__cxa_throw",
            "printf",
            "_printf_r",
            "iprintf",
            "puts",
            "fwrite",
            "_sbrk",
            "__gxx_personality_v0",
            "_Unwind_Resume",
            "__sinit",
        )
    )
    assert len(forbidden_symbols(nm)) == 13
    assert (
        forbidden_symbols(
            "00001000 T memcpy\n00001000 T sinf\n00001000 T _ZN3fsw8Deframer4feedEPKhjRNS_13DeframeResultE"
        )
        == []
    )


def test_image_links_no_heap_no_exceptions_no_stdio():
    _need(ELF)
    nm = subprocess.run([NM, ELF], check=True, capture_output=True, text=True).stdout
    assert len(nm.splitlines()) > 200  # the image's symbol table, not an empty one
    assert forbidden_symbols(nm) == []
    assert " U " not in nm  # nothing left undefined


def test_only_the_harness_reaches_the_semihosting_output():
    # The one output path is Arm semihosting (BKPT 0xAB), in semihosting::,
    # called by the self-test harness and the startup code only: no flight
    # core function calls it.
    _need(ELF)
    funcs = report.disassembly_graph(ELF)
    names = report.demangle(funcs)
    dis = subprocess.run(["arm-none-eabi-objdump", "-d", ELF], check=True, capture_output=True, text=True).stdout
    with_bkpt, cur = set(), None
    for line in dis.splitlines():
        m = re.match(r"^[0-9a-f]+ <(.+)>:$", line)
        if m:
            cur = m.group(1)
        elif re.search(r"\tbkpt\t0x00ab", line):
            with_bkpt.add(names.get(cur, cur))
    assert with_bkpt and all(n.startswith("semihosting::") for n in with_bkpt), with_bkpt
    semi = {m for m, d in names.items() if d.startswith("semihosting::")}
    callers = {names[m] for m, f in funcs.items() if f["callees"] & semi and m not in semi}
    assert callers and all(
        re.match(
            r"(fwtest::|\(anonymous namespace\)::|Reset_Handler|Fault_Handler|"
            r"fw_eigen_alloca_forbidden|main\b)",
            c,
        )
        for c in callers
    ), callers
    assert not any(c.startswith("fsw::") for c in callers)


def test_stack_report_bounds_every_step_within_the_reserved_stack(tmp_path):
    _need(ELF)
    out = tmp_path / "report.json"
    report.main(
        [
            ELF,
            "--indirect",
            "(anonymous namespace)::SemihostingOutput::write",
            "--indirect",
            "(anonymous namespace)::instructions",
            "--json",
            str(out),
        ]
    )
    r = json.loads(out.read_text())
    steps = {s["step"]: s for s in r["stack"]}
    reserved = r["sections"][".stack"]
    for name in (
        "NavUkf<float>::predict",
        "NavUkf<float>::update_pose",
        "Deframer::feed",
        "BayesLinReg::add",
        "BayesLinReg::remove_oldest",
        "ModalTracker::add (segment, image step)",
        "FlightApp<float>::on_bytes (whole app step)",
        "FlightApp<float>::on_plan (cmd_plan: load, start, abort)",
        "FlightApp<float>::plan_tick (a plan's valve command)",
        "Reset_Handler (whole program)",
    ):
        s = steps[name]
        assert s["bytes"] is not None and s["flags"] == [], (name, s)
    whole = steps["Reset_Handler (whole program)"]["bytes"]
    assert steps["FlightApp<float>::on_bytes (whole app step)"]["bytes"] < whole <= reserved
    # A quarter of the reserved stack is margin (docs/FIRMWARE.md).
    assert whole <= 0.75 * reserved, (whole, reserved)
    # Most frames come from the compiler's own -fstack-usage figures.
    assert r["stack_graph"]["frames_from_su"] > r["stack_graph"]["functions"] // 2
    # The flight objects fit the 512 KB RAM budget with the stack.
    assert r["flight_objects"]["flight_app"] + reserved < 512 * 1024


@pytest.fixture(scope="module")
def runs():
    _need(ELF)
    if not os.path.exists(HOST_EXE):
        pytest.fail(f"{HOST_EXE} missing (the host build's test targets)")
    tgt = fw.run_qemu(ELF)
    assert tgt.returncode == 0, tgt.stdout[-1000:] + tgt.stderr[-1000:]
    host = fw.run_host(HOST_EXE, os.path.join(ROOT, fw.DEFAULT_INPUT))
    assert host.returncode == 0, host.stderr
    return fw.parse(tgt.stdout), fw.parse(host.stdout)


def test_instruction_counter_is_exact_on_a_loop_of_known_length(runs):
    tgt, host = runs
    assert tgt.counter_check is not None and tgt.counter_check[0] == tgt.counter_check[1]
    assert all(n == -1 for _, _, n in host.frames)  # the host has no counter


def test_firmware_self_test_matches_the_host_float_build(runs):
    tgt, host = runs
    assert tgt.status == 0 and host.status == 0
    # The recording exercises every step: poses fused, learner samples,
    # every image fused and the frequency acquisition done once, a valve
    # plan refused, loaded, flown to its end (60 intervals), started again
    # and aborted after 4.
    a = tgt.app_counters
    assert a["imu_steps"] == 666 and a["pose_fused"] == 66 and a["learner_samples"] > 100
    assert a["images_fused"] == 84 and a["acquisitions"] == 1 and a["rejected_total"] == 0
    assert (a["plans_loaded"], a["plan_commands_refused"], a["plans_finished"], a["plan_aborts"]) == (1, 1, 1, 1)
    assert a["plan_valve_commands"] == 60 + 4
    c = fw.compare(tgt, host)
    assert c.failures == []
    assert c.packets > 2000 and c.values > 30000
    # The two builds are not bit-identical (else the tolerances would be
    # untested): the navigation estimate differs in rounding.
    assert c.worst["tm_estimate[0:3]"][1] > 0


def test_comparison_catches_a_changed_value(runs):
    tgt, host = runs
    # One tm_estimate position off by 0.1 mm in the host's telemetry.
    import copy

    from hil_sim import packets as pk

    bad = copy.deepcopy(host)
    i = next(k for k, (_, a, _) in enumerate(bad.frames) if a == 0x010)
    frames = bad.telemetry[i].split(b"\x00")
    for j, f in enumerate(frames):
        p = pk.parse_frame(f + b"\x00", pk.FROM_FLIGHT) if f else None
        if isinstance(p, pk.Packet) and p.apid == 0x040:
            v = list(p.values())
            v[0] += 1e-4
            frames[j] = pk.build_frame(0x040, p.header.seq_count, p.t_s, pk.pack_payload(0x040, *v))[:-1]
            break
    bad.telemetry[i] = b"\x00".join(frames)
    c = fw.compare(tgt, bad)
    assert len(c.failures) == 1 and "tm_estimate field 0" in c.failures[0]
