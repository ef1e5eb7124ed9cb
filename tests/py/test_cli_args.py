"""Out-of-range, non-finite and nonsensical numeric arguments of every
`proxops` command: one line on stderr naming the argument, exit code 2, and
the user's output file untouched."""

from __future__ import annotations

import pytest

from bench import cli

BAD = [
    ("hil", "--duration", "0"),
    ("hil", "--duration", "-10"),
    ("hil", "--duration", "nan"),
    ("hil", "--duration", "inf"),
    ("hil", "--drop-rate", "1"),
    ("hil", "--ber", "2"),
    ("hil", "--images", "0"),
    ("hil", "--seed", "-1"),
    ("hil", "--baud", "12345"),
    ("nav", "--pose-latency-s", "nan"),
    ("nav", "--pose-latency-s", "-5"),
    ("nav", "--runs", "0"),
    ("modal", "--trials", "-1"),
    ("modal", "--modes", "0"),
    ("modal", "--images", "1000000000"),
    ("modal", "--images", "0"),
    ("modal", "--dt", "0"),
    ("modal", "--dt", "-60"),
    ("modal", "--range-noise", "1"),
    ("thrusters", "--seeds", "0"),
    ("thrusters", "--samples", "five"),
    ("diagnose", "--null-runs", "3"),
    ("validate-gap", "--runs", "0"),
    ("validate-gap", "--workers", "-2"),
    ("validate-gap", "--duration", "nan"),
    ("pose", "--runs", "-1"),
    ("pose", "--duration", "0"),
    ("pose", "--duration", "5"),
    ("cw-check", "--separation-m", "-5"),
    ("cw-check", "--altitude-km", "inf"),
    ("run", "--duration", "-10"),
]


@pytest.mark.parametrize("cmd,arg,value", BAD)
def test_bad_value_gives_one_line_and_exit_2(tmp_path, capsys, cmd, arg, value):
    out = tmp_path / "out.json"
    out.write_text('{"earlier": true}\n')
    argv = [cmd, arg, value, "--json", str(out)]
    if cmd == "modal":
        argv += ["--scenario", "structure"]
    assert cli.main(argv) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith(f"proxops {cmd}: error: argument {arg}")
    assert value in lines[0]
    assert captured.out == ""
    assert out.read_text() == '{"earlier": true}\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json"]


def test_help_shows_defaults_and_ranges(capsys):
    assert cli.main(["hil", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "(default: 60.0)" in text and "(> 0, <= 1e6)" in text
    for cmd in ("diagnose", "validate-gap", "pose", "cw-check", "run"):
        assert cli.main([cmd, "--help"]) == 0
        assert "(default:" in capsys.readouterr().out, cmd
    # help speaks of the product, not of the papers it came from
    for cmd in (
        "run",
        "cw-check",
        "nav",
        "hil",
        "modal",
        "modal-timing",
        "thrusters",
        "pose",
        "diagnose",
        "validate-gap",
    ):
        assert cli.main([cmd, "--help"]) == 0
        text = capsys.readouterr().out.lower()
        assert "seed's" not in text and "seed 0" not in text and "issue " not in text, cmd


def test_ctrl_c_gives_one_line_and_exit_130(monkeypatch, capsys):
    from bench.commands import thrusters

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(thrusters, "main", interrupted)
    assert cli.main(["thrusters", "--seeds", "1"]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["proxops thrusters: interrupted"]


def test_strict_json_writes_null_with_the_reason(tmp_path):
    import json

    import numpy as np

    from bench.report import write_json

    out = tmp_path / "s.json"
    write_json(out, {"a": float("inf"), "b": [1.0, float("nan")], "c": np.float64(-np.inf), "d": {"e": 2}}, strict=True)

    def refuse(name):
        raise ValueError(f"bare {name} in strict JSON")

    d = json.loads(out.read_text(), parse_constant=refuse)
    assert d["a"] is None and d["b"] == [1.0, None] and d["c"] is None and d["d"] == {"e": 2}
    assert d["non_finite_as_null"] == {"a": "inf", "b.1": "nan", "c": "-inf"}


def test_hil_json_dash_writes_the_json_to_stdout(tmp_path, capsys, monkeypatch):
    import json

    monkeypatch.chdir(tmp_path)
    assert cli.main(["hil", "--duration", "2", "--json", "-"]) == 0
    captured = capsys.readouterr()
    s = json.loads(captured.out)
    assert s["scenario"] == "docking" and s["steps"] > 0
    assert "HIL docking" in captured.err
    assert list(tmp_path.iterdir()) == []  # no file named "-"


def test_modal_summary_reads_as_text(capsys):
    # 10 images: the frequencies never converge; the summary says so in words
    # (it printed "after None images" and raw dicts).
    assert cli.main(["modal", "--scenario", "structure", "--images", "10", "--modes", "3"]) == 0
    out = capsys.readouterr().out
    assert "all frequencies within 1 % never;" in out
    assert "None" not in out and "{" not in out and "np." not in out


def test_nav_summary_names_statuses_as_text(capsys):
    assert cli.main(["nav", "--runs", "1"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith("gated 0, statuses init 1, ok ")
    assert "np." not in last


def test_json_dash_sends_strict_json_alone_to_stdout(capsys):
    # The generic path (commands that do not stream it themselves): what the
    # command prints goes to stderr, the JSON alone to stdout.
    import json as _json

    from bench.cli import main

    assert main(["cw-check", "--json", "-"]) == 0
    cap = capsys.readouterr()
    _json.loads(cap.out, parse_constant=lambda c: (_ for _ in ()).throw(AssertionError(f"bare {c}")))
    assert cap.err.strip()  # the summary went to stderr


def test_strict_json_round_trips_its_non_finite_values():
    import json as _json
    import math

    from bench.report import json_text, restore_non_finite

    data = {"a": [1.0, float("nan"), {"b": float("inf")}], "c": -float("inf"), "d": "x"}
    text = json_text(data, strict=True)
    back = restore_non_finite(_json.loads(text, parse_constant=lambda c: (_ for _ in ()).throw(AssertionError(c))))
    assert back["a"][0] == 1.0 and math.isnan(back["a"][1]) and back["a"][2]["b"] == float("inf")
    assert back["c"] == -float("inf") and back["d"] == "x" and "non_finite_as_null" not in back
