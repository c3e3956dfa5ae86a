"""The ``handeye`` command."""

from __future__ import annotations

import argparse
import sys
from importlib.resources import as_file, files
from pathlib import Path
from typing import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from . import __version__, solvers
from .calibration import Calibration, calibrate_poses
from .errors import HandEyeError

EXAMPLE_POSEPAIRS = "example_posepairs"


def _fmt_vec(v: np.ndarray, digits: int = 6) -> str:
    return "[" + ", ".join(f"{x: .{digits}f}" for x in v) + "]"


def print_calibration(cal: Calibration, out=None) -> None:
    """Print X in the forms people paste into robot programs, and the residual summary."""
    x_name = "cam2flange" if cal.setup == "eye_in_hand" else "cam2base"
    z_name = "target2base" if cal.setup == "eye_in_hand" else "target2flange"
    rot = Rotation.from_matrix(cal.X[:3, :3])
    w = (out or sys.stdout).write
    w(f"{cal.setup}: X = {x_name} (maps camera coordinates into the "
      f"{'flange' if cal.setup == 'eye_in_hand' else 'robot base'} frame), method {cal.method}, "
      f"{len(cal.flange2base)} poses, {len(cal.pairs)} motions\n\n")
    with np.printoptions(precision=6, suppress=True, floatmode="fixed", sign=" "):
        w(f"{x_name} (4x4, metres):\n{cal.X}\n\n")
    w(f"translation      m : {_fmt_vec(cal.X[:3, 3])}\n")
    w(f"translation     mm : {_fmt_vec(1e3 * cal.X[:3, 3], 3)}\n")
    w(f"quaternion    wxyz : {_fmt_vec(rot.as_quat(canonical=True, scalar_first=True))}\n")
    w(f"rotation vec   rad : {_fmt_vec(rot.as_rotvec())}\n")
    w(f"rotation vec   deg : {_fmt_vec(rot.as_rotvec(degrees=True), 4)}\n\n")
    w(f"{z_name} translation mm : {_fmt_vec(1e3 * cal.Z[:3, 3], 3)}\n")
    mres, pres = cal.motion_residuals, cal.pose_residuals
    w(f"screw congruence per motion (|angle_A - angle_B|, |pitch_A - pitch_B|): median "
      f"{np.median(mres[:, 0]):.3f} deg / {np.median(mres[:, 1]):.3f} mm, max "
      f"{mres[:, 0].max():.3f} deg / {mres[:, 1].max():.3f} mm\n")
    worst = int(np.argmax(pres[:, 1]))
    w(f"{z_name} consistency per pose: median {np.median(pres[:, 0]):.3f} deg / {np.median(pres[:, 1]):.3f} mm, "
      f"worst pose {worst}: {pres[worst, 0]:.3f} deg / {pres[worst, 1]:.3f} mm\n")


def _cmd_calibrate_poses(args: argparse.Namespace) -> int:
    from .report import write_results
    from .session import load_pose_pairs

    if args.example == (args.folder is not None):
        raise HandEyeError("give a pose-pair folder, or --example for the bundled one (not both)")
    if args.example:
        with as_file(files("handeye") / "data" / EXAMPLE_POSEPAIRS) as folder:
            pairs = load_pose_pairs(folder)
        print(f"bundled example: {pairs.source}\n")
    else:
        pairs = load_pose_pairs(args.folder)
    cal = calibrate_poses(pairs.flange2base, pairs.target2cam, setup=pairs.setup, method=args.method, pairs=args.pairs)
    print_calibration(cal)
    if args.out:
        inputs = [p for p in Path(pairs.source).iterdir() if p.is_file()] if not args.example else []
        for path in write_results(cal, args.out, protect=inputs):
            print(f"wrote {path}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="handeye",
        description="Hand-eye calibration of a camera against a robot arm.",
    )
    parser.add_argument("--version", action="version", version=f"handeye {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser(
        "calibrate-poses",
        help="calibrate from robot poses and camera-to-target poses (a pose-pair folder)",
        description="Solve the hand-eye transform from a folder holding posepairs.yaml, the robot poses "
        "(flange2base) and the camera poses (target2cam).",
    )
    p.add_argument("folder", nargs="?", help="folder with posepairs.yaml")
    p.add_argument("--example", action="store_true", help="run on the bundled example folder")
    p.add_argument("--method", default="daniilidis", choices=solvers.available(), help="solver (default: daniilidis)")
    p.add_argument("--pairs", default="all", choices=["all", "consecutive"], help="which pose pairs form motions")
    p.add_argument("--out", help="write result.json and result.yaml into this folder")
    p.set_defaults(func=_cmd_calibrate_poses)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``handeye`` console script; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
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


if __name__ == "__main__":
    sys.exit(main())
