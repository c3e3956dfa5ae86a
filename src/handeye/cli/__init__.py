"""The ``handeye`` command: one module per command (its parser, handler and printing), the
shared option groups in :mod:`._common`."""

from __future__ import annotations

import argparse
import contextlib
import difflib
import os
import sys
from typing import Sequence

from .._version import __version__
from ..errors import HandEyeError
from ..sensors.camera.detect import CACHE_ENV, default_cache_dir
from . import (
    acquire,
    calibrate,
    calibrate_poses,
    calibrate_streams,
    check,
    import_,
    live,
    plan,
    simulate,
    study,
    target,
    verify,
)
from ._common import EXAMPLE_POSEPAIRS, SAMPLE_SESSION
from ._printing import print_calibration
from .target import TARGET_KINDS

__all__ = ["main", "build_parser", "print_calibration", "SAMPLE_SESSION", "EXAMPLE_POSEPAIRS", "TARGET_KINDS"]

#: The commands in the order ``handeye --help`` lists them; each module's ``register`` adds its parser.
COMMANDS = (calibrate_poses, calibrate_streams, calibrate, check, verify, acquire, live, import_, target, simulate, plan, study)


class _Parser(argparse.ArgumentParser):
    """argparse, with its errors on one line (the fault and where to read more) instead of the usage,
    and no abbreviations: ``--square 0.04`` is an error, not ``--square-mm 0.04`` (the subcommands'
    parsers are of this class too)."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    """The ``handeye`` parser with every command of :data:`COMMANDS`."""
    parser = _Parser(
        prog="handeye",
        description="Hand-eye calibration of a camera against a robot arm.",
    )
    parser.add_argument("--version", action="version", version=f"handeye {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for command in COMMANDS:
        command.register(sub)
    return parser


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The commands of ``parser`` by name (none for a parser without commands)."""
    action = next((a for a in parser._actions if isinstance(a, argparse._SubParsersAction)), None)  # noqa: SLF001
    return {} if action is None else dict(action.choices)


def _unknown_options(parser: argparse.ArgumentParser, argv: list[str], extras: list[str]) -> str:
    """One line for arguments no option takes: the sub-command's own usage, and for a mistyped option
    the nearest ones it has ("did you mean")."""
    target = parser
    while (subs := _subparsers(target)):  # down to the innermost command named (import visp)
        command = next((a for a in argv if a in subs), None)
        if command is None:
            break
        target = subs[command]
    options = [o for a in target._actions for o in a.option_strings if o.startswith("--")]  # noqa: SLF001
    hints = []
    for extra in extras:
        if extra.startswith("-"):
            near = difflib.get_close_matches(extra.split("=")[0], options, n=1, cutoff=0.6)
            hints.append(f"{extra}" + (f" (did you mean {' or '.join(near)}?)" if near else ""))
        else:
            hints.append(repr(extra))
    usage = " ".join(target.format_usage().split())
    return f"{target.prog}: error: unrecognized argument(s) {', '.join(hints)}; {usage[0].lower() + usage[1:]}"


@contextlib.contextmanager
def _detection_cache(args: argparse.Namespace):
    """While a command runs: detections cached in the user's cache folder (unless
    ``$HANDEYE_CACHE_DIR`` says where, or is empty: no cache), or nowhere with ``--no-cache``. Set
    in the environment, so that the processes a fleet starts cache alike; restored afterwards."""
    before = os.environ.get(CACHE_ENV)
    if getattr(args, "no_cache", False):
        os.environ[CACHE_ENV] = ""
    elif before is None:
        os.environ[CACHE_ENV] = str(default_cache_dir())
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(CACHE_ENV, None)
        else:
            os.environ[CACHE_ENV] = before


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``handeye`` console script; returns the exit status."""
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    subs = _subparsers(parser)
    first = next((a for a in argv if not a.startswith("-")), None)
    if first is not None and first not in subs:
        near = difflib.get_close_matches(first, list(subs), n=1, cutoff=0.5)
        if near:
            print(f"handeye: error: unknown command {first!r}; did you mean {near[0]!r}? (see 'handeye --help')",
                  file=sys.stderr)
            return 2
    try:
        args, extras = parser.parse_known_args(argv)
    except SystemExit as exc:  # a bad option (status 2, the error printed), --help or --version (0)
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    if extras:
        print(_unknown_options(parser, argv, extras), file=sys.stderr)
        return 2
    try:
        with _detection_cache(args):
            return args.func(args)
    except HandEyeError as exc:
        print(f"handeye: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # unwritable output folder, unreadable file
        print(f"handeye: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("handeye: interrupted", file=sys.stderr)
        return 130
