"""The progress bar (bench/runner/progress.py): drawn on a terminal, silent in
a file unless PROXOPS_PROGRESS=1 asks for it, and then in whole lines."""

import io

import pytest

from bench.runner.progress import ENV, ProgressBar


class Terminal(io.StringIO):
    def isatty(self):
        return True


def _run(stream, **kw):
    bar = ProgressBar("draw", 4, stored=1, stream=stream, **kw)
    bar.update()
    bar.update(failed=True)
    bar.total += 2  # a stage that finds more work while it runs
    bar(3)
    bar.close()
    return bar


def test_drawn_in_place_on_a_terminal(monkeypatch):
    monkeypatch.delenv(ENV, raising=False)
    out = Terminal()
    bar = _run(out)
    text = out.getvalue()
    assert "\r" in text and "draw" in text and "6/6" in text and "1 stored, 1 failed" in text
    assert (bar.done, bar.failed, bar.total) == (5, 1, 6)


def test_silent_in_a_file_unless_asked(monkeypatch):
    monkeypatch.delenv(ENV, raising=False)
    out = io.StringIO()
    bar = _run(out)
    assert out.getvalue() == "" and (bar.done, bar.failed) == (5, 1)
    monkeypatch.setenv(ENV, "1")
    out = io.StringIO()
    _run(out)
    lines = out.getvalue().splitlines()
    assert "\r" not in out.getvalue() and lines and all(line.startswith("draw:") for line in lines)
    assert "6/6" in lines[-1]


@pytest.mark.parametrize("enabled, env", [(False, None), (True, "0")])
def test_off_when_the_caller_or_the_environment_says_so(monkeypatch, enabled, env):
    if env is None:
        monkeypatch.delenv(ENV, raising=False)
    else:
        monkeypatch.setenv(ENV, env)
    out = Terminal()
    _run(out, enabled=enabled)
    assert out.getvalue() == ""
