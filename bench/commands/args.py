"""Checked command-line values: every numeric argument has a stated range;
a value outside it, not finite, or not a number is refused with one line
that names the argument (`proxops CMD: error: argument --x: ...`, exit 2)
before anything runs or any file is touched."""

from __future__ import annotations

import argparse
import math
import sys


def _fmt(v) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def number(kind=float, lo=None, hi=None, lo_open=False, hi_open=False):
    """An argparse type: kind (int or float) within [lo, hi] (an open end
    when lo_open / hi_open; None = unbounded on that side), finite."""
    parts = []
    if lo is not None:
        parts.append(f"{'>' if lo_open else '>='} {_fmt(lo)}")
    if hi is not None:
        parts.append(f"{'<' if hi_open else '<='} {_fmt(hi)}")
    what = ("an integer" if kind is int else "a finite number") + (" " + " and ".join(parts) if parts else "")

    def parse(text: str):
        try:
            v = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}") from None
        ok = math.isfinite(v)
        if ok and lo is not None:
            ok = v > lo if lo_open else v >= lo
        if ok and hi is not None:
            ok = v < hi if hi_open else v <= hi
        if not ok:
            raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}")
        return v

    parse.__name__ = "int" if kind is int else "float"  # argparse names the type in some messages
    return parse


def seed(text: str) -> int:
    """An argparse type: a seed, any integer >= 0 (numpy's generators take
    any such integer; the bench draws every stream from one)."""
    try:
        v = int(text)
    except ValueError:
        v = -1
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {text!r}")
    return v


SEED_HELP = "seed of every random draw, any integer >= 0"


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Adds "(default: X)" only where it says something: not when the help
    states its default already, not for a required option, a flag, or an
    option whose absence means "not done"."""

    def _get_help_string(self, action):
        text = action.help or ""
        quiet = (
            "default" in text
            or action.required
            or action.default is None
            or action.default is argparse.SUPPRESS
            or action.default is False
            or action.default == []
            or not action.option_strings
        )
        return text if quiet else text + " (default: %(default)s)"


def one_line_errors(parser: argparse.ArgumentParser, prog: str) -> argparse.ArgumentParser:
    """Makes parser report a bad argument in one line on stderr and exit 2
    (argparse prints the whole usage first)."""

    def error(message: str):
        print(f"{prog}: error: {message} (see {prog} --help)", file=sys.stderr)
        sys.exit(2)

    parser.error = error
    return parser
