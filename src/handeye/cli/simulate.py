"""``handeye simulate``: a rendered session with its ground truth (a camera's here; every other kind
of sensor's by its registration's ``simulate`` hook, :mod:`handeye.pipelines.kinds`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import InputMismatchError
from ..frames.setups import SETUPS
from ..pipelines.kinds import SimulateRequest, kind_named, sensor_kinds
from ..planning.poses import ROBOTS
from ..robot.kinematics import arm_names
from ..simulate import DEFAULT_TARGETS, simulate_kinematic_session, simulate_session
from ._common import add_kind_options, board_target, image_size_arg, kind_options, number_arg, out_folder, target_choices, whole_arg


def _cmd_simulate(args: argparse.Namespace) -> int:
    out_folder(args.out)
    kind = None if args.sensor == "camera" else kind_named(args.sensor)
    options = kind_options(args, "simulate", kind)
    if kind is not None:
        if args.target is not None and args.target not in kind.targets:
            board_target(args.target, "charuco")  # another kind's target: named
        print(kind.hook("simulate")(SimulateRequest(args.out, args.setup, args.poses, args.seed, args.target, args.arm,
                                                    args.robot, args.image_size, args.noise_px, options)))
        return 0
    args.target = board_target(args.target, "charuco")
    if args.arm is not None:
        if args.robot != "arm":
            raise InputMismatchError("--arm simulates a serial arm's joints; it does not combine with --robot " + args.robot)
        sc = simulate_kinematic_session(args.out, args.poses, args.setup, args.seed, arm=args.arm, target=args.target,
                                        image_size=args.image_size, pixel_px=args.noise_px)
        print(f"wrote session {args.out} ({args.poses} {args.target} images, {args.setup}, {sc.chain.name}'s joint angles "
              f"in joints.csv and its controller's poses in poses.csv; the arm is off its nominal table); ground truth "
              f"in {Path(args.out) / 'ground_truth.yaml'}")
        return 0
    simulate_session(args.out, setup=args.setup, n_poses=args.poses, target=args.target, noise_px=args.noise_px,
                     seed=args.seed, image_size=args.image_size, write_intrinsics=not args.no_intrinsics, robot=args.robot)
    print(f"wrote session {args.out} ({args.poses} {args.target} images, {args.setup}, {args.robot}); ground truth in "
          f"{Path(args.out) / 'ground_truth.yaml'}")
    return 0


def register(sub) -> None:
    """Add the ``simulate`` command's parser to the sub-parsers ``sub``."""
    p = sub.add_parser(
        "simulate",
        help="render a synthetic capture session with ground truth",
        description="Render target images seen from simulated robot poses and write a complete session "
        "with ground_truth.yaml (X, Z, K, dist).",
    )
    p.add_argument("-o", "--out", required=True, help="new session folder")
    kinds = [k for k in sensor_kinds() if k.simulate]
    p.add_argument("--sensor", default="camera", choices=["camera"] + [k.cli for k in kinds],
                   help="camera (default): rendered images of a board; " + "; ".join(f"{k.cli}: {k.simulate_help}" for k in kinds))
    add_kind_options(p, "simulate")
    p.add_argument("--setup", default="eye_in_hand", choices=list(SETUPS))
    p.add_argument("--poses", type=whole_arg(1), default=15, help="number of images (default 15)")
    own = "; ".join(f"with --sensor {k.cli}: {', '.join(k.targets)} ({k.targets[0]} the default)" for k in kinds if k.targets)
    p.add_argument("--target", default=None, choices=target_choices(DEFAULT_TARGETS, "simulate"),
                   help="the board rendered (default charuco: it cannot be read from the wrong end, as handeye's advice "
                   f"recommends; chessboard for the thesis's set-up); {own}")
    p.add_argument("--noise-px", type=number_arg(0.0), default=0.2, help="feature position noise in pixels (default 0.2)")
    p.add_argument("--seed", type=whole_arg(0), default=None)
    p.add_argument("--image-size", type=image_size_arg, default=(640, 480), help="WIDTHxHEIGHT (default 640x480)")
    p.add_argument("--no-intrinsics", action="store_true", help="leave K and dist out of session.yaml")
    p.add_argument("--robot", default="arm", choices=ROBOTS,
                   help="arm (default): views all around; scara: the flange turns about the vertical only; "
                   "cartesian: it only translates (both determine only part of X: see --known of calibrate)")
    p.add_argument("--arm", type=str.lower, choices=arm_names(), default=None,
                   help="simulate this arm's joint angles (joints.csv) beside its controller's poses, the arm 1-3 mm off "
                   "its nominal table: calibrate then fits the table with X (K and dist always written)")
    p.set_defaults(func=_cmd_simulate)
