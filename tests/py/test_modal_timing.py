"""`proxops modal-timing`: the Table I grid command. Labelled builds are
parsed and checked, the fitted constants of t = c1 m n + c2 m^3 come back
from data made with them, and a small grid runs numpy and the flight code
(through the bindings) in one command."""

import json
import sys

import numpy as np
import pytest

from bench.commands import modal as cmd
from bench.perf import modal_timing


def test_fit_recovers_the_constants_of_the_cost_model():
    c1, c2 = 1.2e-8, 5e-9
    cells = [(m, n, c1 * m * n + c2 * m**3) for m in (10, 20, 30, 40, 50) for n in (100, 1000, 10000)]
    got = modal_timing.fit(cells)
    assert got == pytest.approx((c1, c2), rel=1e-9)


def test_labelled_executables_are_checked(tmp_path):
    exe = tmp_path / "bench_modal"
    exe.write_text("")
    assert cmd._labelled_exes([str(exe)]) == {"flight": str(exe)}
    assert cmd._labelled_exes([f"portable={exe}", f"v3={exe}"]) == {"portable": str(exe), "v3": str(exe)}
    with pytest.raises(SystemExit, match="label 'v3' given twice"):
        cmd._labelled_exes([f"v3={exe}", f"v3={exe}"])
    with pytest.raises(SystemExit, match="the label must be a word"):
        cmd._labelled_exes([f"x86-64={exe}"])
    with pytest.raises(SystemExit, match="no such file"):
        cmd._labelled_exes([f"v3={tmp_path / 'missing'}"])


def test_bench_output_is_read_as_medians_per_cell(tmp_path):
    # a stand-in for bench_modal printing Google Benchmark's JSON (mean and median aggregates)
    fake = tmp_path / "bench_modal"
    rows = [
        {"run_name": "BM_Joint<10>/1000", "aggregate_name": "median", "real_time": 63.5, "time_unit": "us"},
        {"run_name": "BM_Joint<10>/1000", "aggregate_name": "mean", "real_time": 99.0, "time_unit": "us"},
        {"run_name": "BM_Decoupled<50>/10000", "aggregate_name": "median", "real_time": 1.24, "time_unit": "ms"},
    ]
    fake.write_text(f"#!{sys.executable}\nimport json\nprint(json.dumps({{'benchmarks': {rows!r}}}))\n")
    fake.chmod(0o755)
    got = modal_timing.run_bench_exe(str(fake))
    assert got == {("joint", 10, 1000): pytest.approx(63.5e-6), ("decoupled", 50, 10000): pytest.approx(1.24e-3)}


def test_small_grid_times_numpy_and_the_flight_code(tmp_path, capsys):
    from bench import cli

    out = tmp_path / "t.json"
    assert cli.main(["modal-timing", "--max-points", "100", "--repeats", "1", "--json", str(out)]) == 0
    d = json.loads(out.read_text())
    assert [(r["modes"], r["points"]) for r in d["rows"]] == [(m, 100) for m in (10, 20, 30, 40, 50)]
    for r in d["rows"]:
        assert r["numpy_bank_s"] > 0 and r["numpy_joint_s"] > 0
        if r["modes"] in (10, 50):  # the sizes the bindings build
            assert r["flight_bank_bindings_s"] > 0 and r["flight_joint_bindings_s"] > 0
    assert np.isfinite(d["fit_numpy_joint"]["c2"])
    assert "fit numpy bank" in capsys.readouterr().out
