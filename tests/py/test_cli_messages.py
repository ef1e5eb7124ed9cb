"""What `proxops` says: every option's help, each default said once and
only where it means something, seeds as numpy takes them, a mistyped
option named as such, and summaries without doubled or empty words."""

from __future__ import annotations

import re

import pytest

from bench import cli

COMMANDS = sorted(cli.build_parser().commands)
SEEDED = [c for c in COMMANDS if "--seed" in cli.build_parser().commands[c].format_help()]
REQUIRED = {
    "modal": ["--scenario", "structure"],
    "pose": ["--experiment", "images"],
    "simulate": ["--out", "x.h5"],
    "plan": ["log.h5", "--json", "plan.json"],
}


def _help(cmd: str) -> str:
    return cli.build_parser().commands[cmd].format_help()


@pytest.mark.parametrize("cmd", COMMANDS)
def test_every_option_says_what_it_does(cmd):
    parser = cli.build_parser().commands[cmd]
    silent = [a.option_strings or a.dest for a in parser._actions if not (a.help or "").strip()]
    assert silent == [], f"proxops {cmd}: options without help: {silent}"


@pytest.mark.parametrize("cmd", COMMANDS)
def test_defaults_said_once_and_only_where_they_mean_something(cmd):
    text = " ".join(_help(cmd).split())
    for empty in ("(default: None)", "(default: False)", "(default: [])"):
        assert empty not in text, f"proxops {cmd}: {empty}"
    # a help that states its default, followed by the formatter's own
    assert not re.search(r"default[^()]*\) \(default:", text), text


def test_a_required_option_shows_no_default():
    text = " ".join(_help("simulate").split())
    assert "--out OUT the flight log to write (HDF5) --key" in text


def test_defaults_still_shown_where_they_mean_something():
    text = " ".join(_help("hil").split())
    assert "(default: 60.0)" in text and "(default: 921600)" in text


@pytest.mark.parametrize("cmd", SEEDED)
def test_seed_takes_any_non_negative_integer(cmd):
    import numpy as np

    big = 2**80 + 7
    np.random.default_rng(big)  # numpy takes it
    args = cli.build_parser().parse_args([cmd, "--seed", str(big), *REQUIRED.get(cmd, [])])
    assert args.seed == big
    assert "any integer >= 0" in " ".join(_help(cmd).split())


@pytest.mark.parametrize("cmd", SEEDED)
def test_a_negative_seed_is_refused_in_one_line(cmd, capsys):
    assert cli.main([cmd, "--seed", "-1", *REQUIRED.get(cmd, [])]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"proxops {cmd}: error: argument --seed: must be an integer >= 0")


def test_pose_duration_help_states_the_range_it_checks(capsys):
    assert "10 to 86400" in " ".join(_help("pose").split())
    assert cli.main(["pose", "--experiment", "features", "--duration", "5"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("proxops pose: error: argument --duration: must be a finite number >= 10"), err


@pytest.mark.parametrize(
    "argv, line",
    [
        (["--bogus"], "proxops: error: unrecognized arguments: --bogus; a command comes first"),
        ([], "proxops: error: give a command"),
        (["hil", "--bogus"], "proxops hil: error: unrecognized arguments: --bogus"),
    ],
)
def test_a_mistyped_option_is_named(argv, line, capsys):
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(line), err
    assert "required" not in err[0]


def test_hil_summary_reads_as_text(capsys):
    assert cli.main(["hil", "--duration", "2", "--ber", "1e-3", "--seed", "3"]) == 0
    out = capsys.readouterr().out
    assert "fsw_node: fsw_node:" not in out and " ;" not in out and "{" not in out
    link = next(line for line in out.splitlines() if line.strip().startswith("link:"))
    # a rejection count with its reasons in words: "flight rejected 10 (cobs_error 3, bad_crc 7)"
    assert re.search(r"flight rejected \d+( \(\w+ \d+(, \w+ \d+)*\))?; bench rejected telemetry \d+", link), link


def test_validate_gap_scores_without_runs_say_so():
    from bench.commands.validate_gap import score_lines

    res = {
        "false_alarm_rate": None,
        "n_null": 0,
        "in_library_by_scale": {},
        "beyond_detection_limit": {"n": 0, "by_effect": {}},
        "shrink_heldout": {"true_effect_median": None, "n_true": 0, "wrong_effect_median": 0.5, "n_wrong": 2},
        "interval_coverage_95": {"fraction": None, "n_parameters": 0},
    }
    text = "\n".join(score_lines(res))
    assert "None" not in text
    assert "true effect fitted none measured (n = 0), wrong effect fitted 0.5000 (n = 2)" in text
    assert "false alarms on null runs: none measured (n = 0)" in text


def test_diagnose_progress_only_on_a_terminal(monkeypatch, tmp_path):
    import sys

    from bench.gap import bundled
    from bench.gap import diagnose as gap_diagnose

    asked = []

    def record(log, progress=False, **kw):
        asked.append(progress)
        raise KeyboardInterrupt  # stop before any work

    monkeypatch.setattr(gap_diagnose, "diagnose", record)
    argv = ["diagnose", str(bundled.LOG), "--json", str(tmp_path / "d.json")]
    assert cli.main(argv) == 130
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    assert cli.main(argv) == 130
    assert cli.main([*argv, "--quiet"]) == 130
    assert asked == [False, True, False]
