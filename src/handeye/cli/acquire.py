"""``handeye acquire``: capture views until X is known well enough."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import HandEyeError
from ..estimation.verdict import headline
from ..frames.setups import SETUPS, flange_poses
from ..geometry.se3 import make_transform
from ..pipelines.verify import verify
from ..planning.poses import candidate_views
from ..report import write_calibration, write_verification
from ..sensors.camera.targets import target_from_spec
from ..workflows.acquire import SimWorld, acquire, capture_views, make_camera, make_robot
from ._common import (
    accuracy_arg,
    add_placements,
    floats_arg,
    load_camera,
    number_arg,
    out_folder,
    placements,
    target_spec_arg,
    units_arg,
    verdict_status,
    whole_arg,
)
from ._printing import print_calibration


def _cmd_acquire(args: argparse.Namespace) -> int:
    out = Path(args.out)
    results = Path(args.results) if args.results else out.with_name(out.name + "-results")
    out_folder(str(results), [out])
    target_std = floats_arg(args.target_std, "--target-std", (2,))
    if args.robot == "sim":
        if args.camera != "sim":
            raise HandEyeError("--robot sim goes with --camera sim (the simulated cell)")
        # the simulated cell renders the board the user printed (step 1 of the tutorial), when given
        world = SimWorld.default(args.setup, seed=args.seed, target=target_spec_arg(args.target_spec))
        rough = make_transform(Rotation.from_rotvec(np.radians([1.5, -1.0, 1.0])).as_matrix(), [0.01, -0.008, 0.005])
        X0, Z0 = rough @ world.X, rough @ world.Z  # as from a drawing: ~1 cm and 2 deg off
        spec, (K, dist, size) = world.target_spec, (world.K, world.dist, world.image_size)
    else:
        world = None
        if not args.intrinsics:
            raise HandEyeError("--intrinsics is needed with a real camera (a YAML with K, dist, image_size)")
        K, dist, size = load_camera(args.intrinsics)
        spec = target_spec_arg(args.target_spec)
        if spec is None:
            raise HandEyeError("--target-spec is needed with a real camera (your session.yaml or a target: mapping)")
        X0, Z0 = placements(args)
    rl, ra = units_arg(args.robot_units, "--robot-units")
    robot = make_robot(args.robot, world, args.robot_format, rl, ra, speed=args.speed, yes=args.yes, dry_run=args.dry_run)
    camera = make_camera(args.camera, world, robot)
    acq = acquire(robot, camera, out, args.setup, spec, K, dist, size, X0, Z0,
                  target_std=tuple(target_std.tolist()) if target_std is not None else DEFAULT_TARGET_STD,
                  max_poses=args.max_poses, min_poses=args.min_poses, standoff=args.standoff,
                  robot_accuracy=accuracy_arg(args.robot_accuracy), settle_s=args.settle, progress=not args.no_progress)
    if acq.resumed_from:
        print(f"resumed a capture of {acq.resumed_from} views")
    print(f"{acq.n_views} views in {acq.folder}; stopped: {acq.stopped}")
    if acq.stopped == "robot accuracy":
        print("  the robot's error the views show keeps X's std above the target whatever more views add (the notes "
              "below say how much): ask for less (--target-std DEG,MM), or give the arm's accuracy if it is better "
              "(--robot-accuracy DEG,MM)")
    for s in acq.skipped:
        print(f"  skipped {s}")
    if acq.stopped == "interrupted" or acq.calibration is None:
        print(f"run the same command again to resume, or: handeye calibrate {acq.folder} --out RESULTS")
        return 1
    cal = replace(acq.calibration, notes=[f"captured by handeye acquire: {acq.n_views} views, stopped: {acq.stopped}"]
                  + list(acq.calibration.notes))
    print_calibration(cal)
    print(_why_stopped(acq, cal, target_std))
    for path in write_calibration(cal, results):
        print(f"wrote {path}")
    status = verdict_status(cal)
    if args.verify:
        status = max(status, _acquire_verify(args, robot, camera, out, results, spec, K, dist, size, cal))
    return status


#: --target-std's default: X's std per axis (deg, mm) at which a capture stops.
DEFAULT_TARGET_STD = (0.05, 0.5)
#: Why a capture stopped, in words (``Acquisition.stopped``).
STOP_REASONS = {"target std reached": "X's std reached the target (--target-std)",
                "robot accuracy": "the robot's error the views show keeps X's std above the target whatever more views add",
                "max poses": "it took --max-poses views",
                "no candidate left": "no view the planner can still propose would narrow X's std"}


def _why_stopped(acq, cal, target_std) -> str:
    """One sentence: why the capture stopped, and whether X is good (the verdict in words, its std per
    axis against the target asked for)."""
    target = DEFAULT_TARGET_STD if target_std is None else tuple(target_std.tolist())
    std = "" if cal.std is None else (f", std up to {np.max(cal.std[:3]):.3f} deg / {np.max(cal.std[3:]):.2f} mm per axis "
                                      f"against the {target[0]:g} deg / {target[1]:g} mm asked for")
    return (f"stopped after {acq.n_views} views because {STOP_REASONS.get(acq.stopped, acq.stopped)}; X is "
            f"{cal.verdict} ({headline(cal)}{std})")


def _acquire_verify(args, robot, camera, out: Path, results: Path, spec, K, dist, size, cal) -> int:
    """--verify N: N more views at candidate poses the calibration did not use, then handeye verify."""
    obj = target_from_spec(spec).object_points()
    cam2target = candidate_views(obj, K, size, dist, args.standoff)
    rng = np.random.default_rng(args.seed + 1000)
    pick = rng.choice(len(cam2target), size=min(args.verify, len(cam2target)), replace=False)
    folder = capture_views(robot, camera, out.with_name(out.name + "-verify"), args.setup, spec, K, dist,
                           flange_poses(cam2target[pick], cal.X, cal.Z, args.setup))
    v = verify(results, folder, progress=False)
    print(v.summary())
    for path in write_verification(v, results):
        print(f"wrote {path}")
    return 1 if v.verdict == "worse than promised" else 0


def register(sub) -> None:
    """Add the ``acquire`` command's parser to the sub-parsers ``sub``."""
    p = sub.add_parser(
        "acquire",
        help="capture a session: the robot moves, the camera shoots, handeye chooses each next pose and stops "
        "when X is known well enough",
        description="Move the robot to the view that reduces the predicted error of X most (X, Z and the pixel "
        "noise learnt from the views so far), grab, detect the target at once (retake, then skip), record the pose "
        "the robot reports; stop when the std calibrate reports reaches --target-std, or at --max-poses. The session "
        "is written after every view: Ctrl-C keeps it, the same command resumes. Then it is calibrated (results in "
        "--results, default OUT-results). Backends: --robot sim|manual[:POSE_FILE]|ur:HOST, --camera "
        "sim|opencv:INDEX|URL|FILE|genicam:PRODUCER.cti|folder:PATH. Only sim, manual and folder are exercised by "
        "handeye's tests; ur and genicam against stand-ins of their libraries, never on hardware.",
    )
    p.add_argument("--robot", required=True, metavar="BACKEND", help="sim, manual[:POSE_FILE] or ur:HOST")
    p.add_argument("--camera", required=True, metavar="BACKEND", help="sim, opencv:INDEX|URL|FILE, genicam:CTI, folder:PATH")
    p.add_argument("-o", "--out", required=True, help="the session folder to write (new, or a stopped capture to resume)")
    p.add_argument("--results", help="where the calibration goes (default: OUT-results beside OUT)")
    p.add_argument("--setup", default="eye_in_hand", choices=list(SETUPS))
    p.add_argument("--target-std", metavar="DEG,MM", help="stop when the std of X per axis is within these "
                   "(default 0.05,0.5; the robot's accuracy sets a floor, checked first)")
    p.add_argument("--max-poses", type=whole_arg(3), default=20, help="at most this many views (default 20)")
    p.add_argument("--min-poses", type=whole_arg(3), default=6, help="at least this many views (default 6)")
    p.add_argument("--standoff", type=number_arg(0.0, above=True), default=0.5, help="camera-to-target distance (m, default 0.5)")
    p.add_argument("--settle", type=number_arg(0.0), default=0.0, help="seconds to wait after each move before the grab")
    p.add_argument("--verify", type=whole_arg(0), default=0, metavar="N",
                   help="then capture N more views at other poses and check the calibration on them (handeye verify)")
    p.add_argument("--intrinsics", help="real cameras: YAML with K, dist and image_size (a session.yaml will do)")
    p.add_argument("--target-spec", help="real cameras: YAML with the target: mapping")
    add_placements(p)
    p.add_argument("--robot-format", default="euler:ZYX", help="manual: the format the robot reports its pose in")
    p.add_argument("--robot-units", default="mm,deg", metavar="LENGTH,ANGLE", help="manual: its units (default mm,deg)")
    p.add_argument("--robot-accuracy", metavar="DEG,MM", help="the robot's absolute accuracy (as calibrate)")
    p.add_argument("--speed", type=number_arg(0.0, above=True), default=0.1, help="ur: linear speed, m/s (capped at 0.25)")
    p.add_argument("--yes", action="store_true", help="ur: move without asking before each move")
    p.add_argument("--dry-run", action="store_true", help="ur: print the moves, do not make them (needs neither ur_rtde nor "
                   "the controller)")
    p.add_argument("--seed", type=whole_arg(0), default=0, help="sim: the simulated cell and its noise")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_acquire)
