"""The ``handeye`` command: one module per command (its parser, handler and printing), the
shared option groups in :mod:`._common`.

A command's module is imported when that command is called, not before: ``handeye calibrate``
loads neither the simulator, the planner nor the capture loop, and ``handeye --help`` lists the
commands from :data:`COMMANDS` alone."""

from __future__ import annotations

import argparse
import contextlib
import difflib
import gc
import importlib
import os
import sys
from types import ModuleType
from typing import Any, Sequence

from .._shared.lazy import lazy_module
from .._version import __version__
from ..errors import HandEyeError

_detect = lazy_module("handeye.sensors.camera.detect")  # the detection cache's folder, on dispatch

#: The commands in the order ``handeye --help`` lists them: each one's module in this package (its
#: ``register`` adds the parser, imported only when the command is called) and the line the list shows
#: (the same as the module's parser's help: tests/test_architecture.py checks it).
COMMANDS = {
    "calibrate-poses": ("calibrate_poses", "calibrate from robot poses and camera-to-target poses (a pose-pair folder)"),
    "calibrate-streams": ("calibrate_streams",
                          "calibrate from a robot pose stream and a camera pose stream with separate clocks"),
    "calibrate": ("calibrate", "calibrate from a capture session (images + robot poses)"),
    "check": ("check", "check whether the data can give a good calibration (exit 0 good, 1 weak, 2 degenerate/inconsistent)"),
    "verify": ("verify", "check a calibration on a second capture: each view predicted from its robot pose"),
    "acquire": ("acquire", "capture a session: the robot moves, the camera shoots, handeye chooses each next pose and stops "
                "when X is known well enough"),
    "live": ("live", "capture from a page in the browser: the live image with the target found, the views taken, the "
             "coverage, the planner's next pose and a calibration after every view"),
    "import": ("import_", "turn another tool's capture into a handeye folder: rosbag, easy-handeye, visp, "
               "industrial-calibration, robcalibrator, easyhec"),
    "target": ("target", "write a printable calibration target (PDF or SVG, true to scale) and its session.yaml block"),
    "simulate": ("simulate", "render a synthetic capture session with ground truth"),
    "plan": ("plan", "plan robot poses for a good calibration and predict its accuracy"),
    "study": ("study", "the Monte-Carlo study of the thesis's chapter 5 (every solver, any noise)"),
}

#: Names this package gives, from the module that holds each (loaded on first use, PEP 562).
_NAMES = {"print_calibration": "_printing", "SAMPLE_SESSION": "_common", "EXAMPLE_POSEPAIRS": "_common",
          "TARGET_KINDS": "target"}

__all__ = ["COMMANDS", "main", "build_parser", "command_module", "print_calibration", "SAMPLE_SESSION",
           "EXAMPLE_POSEPAIRS", "TARGET_KINDS"]


def __getattr__(name: str) -> Any:
    if name not in _NAMES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_NAMES[name]}"), name)
    globals()[name] = value
    return value


def command_module(command: str) -> ModuleType:
    """The module of ``command`` (a key of :data:`COMMANDS`), imported now."""
    return importlib.import_module(f"{__name__}.{COMMANDS[command][0]}")


class _Parser(argparse.ArgumentParser):
    """argparse, with its errors on one line (the fault and where to read more) instead of the usage,
    and no abbreviations: ``--square 0.04`` is an error, not ``--square-mm 0.04`` (the subcommands'
    parsers are of this class too)."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def build_parser(commands: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The ``handeye`` parser with every command of :data:`COMMANDS` (or, given ``commands``, those
    commands' parsers, whose modules are imported, and the others by name and help line only)."""
    parser = _Parser(
        prog="handeye",
        description="Hand-eye calibration of a camera against a robot arm.",
    )
    parser.add_argument("--version", action="version", version=f"handeye {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name, (_, line) in COMMANDS.items():
        if commands is None or name in commands:
            command_module(name).register(sub)
        else:
            sub.add_parser(name, help=line)
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
    env = _detect.CACHE_ENV
    before = os.environ.get(env)
    if getattr(args, "no_cache", False):
        os.environ[env] = ""
    elif before is None:
        os.environ[env] = str(_detect.default_cache_dir())
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(env, None)
        else:
            os.environ[env] = before


@contextlib.contextmanager
def _imports_frozen(own_process: bool):
    """While the command's modules are imported, no garbage collection, then what they made frozen
    (:func:`gc.freeze`: never scanned again): in a process of its own (``own_process``) the ~10^5
    objects of numpy, SciPy, OpenCV and handeye live until the process ends, and each full collection
    during the imports and the command would walk them all (~5% of ``handeye calibrate --sample``).
    Not when ``main`` is called in a longer-lived process (tests, a notebook): its garbage stays collectable."""
    if not own_process or not gc.isenabled():
        yield
        return
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        gc.enable()


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``handeye`` console script; returns the exit status."""
    with _imports_frozen(own_process=argv is None):
        args_or_status = _parsed(list(sys.argv[1:] if argv is None else argv))
    if isinstance(args_or_status, int):
        return args_or_status
    return _run(args_or_status)


def _parsed(argv: list[str]) -> argparse.Namespace | int:
    """The arguments of ``argv`` (the command's module imported), or the exit status when they are wrong."""
    first = next((a for a in argv if not a.startswith("-")), None)
    if first is not None and first not in COMMANDS:
        near = difflib.get_close_matches(first, list(COMMANDS), n=1, cutoff=0.5)
        if near:
            print(f"handeye: error: unknown command {first!r}; did you mean {near[0]!r}? (see 'handeye --help')",
                  file=sys.stderr)
            return 2
    parser = build_parser([first] if first in COMMANDS else [])  # only the command called is imported
    try:
        args, extras = parser.parse_known_args(argv)
    except SystemExit as exc:  # a bad option (status 2, the error printed), --help or --version (0)
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    if extras:
        print(_unknown_options(parser, argv, extras), file=sys.stderr)
        return 2
    return args


def _run(args: argparse.Namespace) -> int:
    """The command ``args`` names, run; its exit status (errors said in one line)."""
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
