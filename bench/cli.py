"""`proxops`: the bench's command line. Each sub-command lives in its own
module under bench/commands/ and registers itself through ``register``."""

from __future__ import annotations

import argparse
import importlib
import importlib.metadata
import sys

# Sub-command modules, in the order `proxops --help` lists them.
COMMAND_MODULES = [
    "bench.commands.run",
    "bench.commands.cw_check",
    "bench.commands.nav",
    "bench.commands.hil",
    "bench.commands.modal",
    "bench.commands.thrusters",
    "bench.commands.pose",
    "bench.commands.diagnose",
    "bench.commands.plan",
    "bench.commands.validate_gap",
    "bench.commands.simulate",
    "bench.commands.export",
]


def _version() -> str:
    try:
        return importlib.metadata.version("proxops")
    except importlib.metadata.PackageNotFoundError:
        return "(not installed)"


def _one_line_error(message: str):
    """A mistake in the arguments before the command: one line, exit 2
    (as each command's own, bench/commands/args.py)."""
    print(f"proxops: error: {message} (see proxops --help)", file=sys.stderr)
    sys.exit(2)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="proxops",
        description="Inspector proximity-operations flight software bench.",
    )
    parser.error = _one_line_error
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    # Not required: a missing command is told apart from an unknown option (_parse).
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    parser.commands = sub.choices  # name -> its parser, for its own error messages
    return parser


def _parse(parser: argparse.ArgumentParser, argv) -> argparse.Namespace:
    """The arguments; an unknown option is named by the command it was given
    to, and `proxops --bogus` is told the option is unknown, not that a
    command is missing."""
    args, extra = parser.parse_known_args(argv)
    if args.command is not None and extra:
        parser.commands[args.command].error(f"unrecognized arguments: {' '.join(extra)}")
    if extra:
        parser.error(f"unrecognized arguments: {' '.join(extra)}; a command comes first")
    if args.command is None:
        parser.error("give a command")
    return args


# Commands that write `--json -` to standard output themselves.
STREAMS_JSON_ITSELF = ("hil", "diagnose")


def _json_to_stdout(args) -> int:
    """`--json -`: the command writes its JSON to a temporary file while all
    it prints goes to standard error; the JSON then goes to standard output,
    alone."""
    import contextlib
    import os
    import tempfile

    fd, name = tempfile.mkstemp(prefix="proxops-", suffix=".json")
    os.close(fd)
    try:
        args.json = name
        real = sys.stdout
        with contextlib.redirect_stdout(sys.stderr):
            rc = int(args.func(args) or 0)
        import json

        from bench.report import json_text

        with open(name) as f:
            text = f.read()
        real.write(json_text(json.loads(text), strict=True) if text.strip() else "")
        real.flush()
        return rc
    finally:
        os.unlink(name)


def main(argv=None) -> int:
    parser = build_parser()
    try:
        args = _parse(parser, argv)
    except SystemExit as exc:  # --help, or a bad argument (reported already)
        return int(exc.code or 0)
    try:
        if getattr(args, "json", None) == "-" and args.command not in STREAMS_JSON_ITSELF:
            return _json_to_stdout(args)
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError) as exc:
        print(f"proxops {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"proxops {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
