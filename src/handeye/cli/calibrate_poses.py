"""``handeye calibrate-poses``: a folder of robot and camera poses."""

from __future__ import annotations

import argparse

from ..io.session import load_pose_pairs
from ..options import REFINES_POSES
from ..pipelines.folders import calibrate_folder
from ._common import (
    EXAMPLE_POSEPAIRS,
    add_calibrate_options,
    add_out_options,
    calibrate_options,
    finish_poses,
    input_folder,
    out_folder,
)


def _cmd_calibrate_poses(args: argparse.Namespace) -> int:
    folder = input_folder(args.folder, args.example, EXAMPLE_POSEPAIRS,
                           "give a pose-pair folder, or --example for the bundled one (not both)")
    out_folder(args.out, [folder])
    load_pose_pairs(folder)  # a folder without posepairs.yaml: its own error, not a session's
    return finish_poses(calibrate_folder(folder, calibrate_options(args), progress=not args.no_progress), args)


def register(sub) -> None:
    """Add the ``calibrate-poses`` command's parser to the sub-parsers ``sub``."""
    p = sub.add_parser(
        "calibrate-poses",
        help="calibrate from robot poses and camera-to-target poses (a pose-pair folder)",
        description="Solve the hand-eye transform from a folder holding posepairs.yaml, the robot poses "
        "(flange2base) and the camera poses (target2cam).",
    )
    p.add_argument("folder", nargs="?", help="folder with posepairs.yaml")
    p.add_argument("--example", action="store_true", help="run on the bundled example folder")
    add_out_options(p)
    add_calibrate_options(p, REFINES_POSES)
    p.add_argument("--no-progress", action="store_true", help="no progress bar (shown from 200 poses)")
    p.set_defaults(func=_cmd_calibrate_poses)
