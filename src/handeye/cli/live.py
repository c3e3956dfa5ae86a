"""``handeye live``: a capture driven from a page in the browser."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import HandEyeError
from ..frames.setups import SETUPS
from ..geometry.se3 import make_transform
from ..workflows.acquire import SimCamera, SimRobot, SimWorld, URRobot, make_camera
from ..workflows.live import LiveCapture, PoseFileRobot, StillSimCamera, is_loopback, serve
from ..workflows.live.server import require_web
from ._common import (
    accuracy_arg,
    add_placements,
    floats_arg,
    load_camera,
    number_arg,
    placements,
    target_spec_arg,
    units_arg,
    whole_arg,
)


def _robot(args: argparse.Namespace, world: SimWorld | None):
    """The robot backend, and whether the page may move it (a robot moved by hand reports its pose in a file)."""
    kind, _, arg = args.robot.partition(":")
    if kind == "sim":
        if world is None:
            raise HandEyeError("--robot sim goes with --camera sim (the simulated cell)")
        return SimRobot(world), True
    if kind == "ur":
        if not arg:
            raise HandEyeError("--robot ur:HOST: give the controller's address, e.g. ur:192.168.1.10")
        # the click on the page is the operator's confirmation of each move (speed capped as in acquire)
        return URRobot(arg, speed=args.speed, yes=True, dry_run=args.dry_run), True
    if kind == "manual":
        if not arg:
            raise HandEyeError("--robot manual:POSE_FILE: the page reads the robot's pose from a file its program "
                               "rewrites (the numbers of --robot-format in --robot-units)")
        length, angle = units_arg(args.robot_units, "--robot-units")
        return PoseFileRobot(arg, args.robot_format, length, angle), False
    raise HandEyeError(f"robot backend {args.robot!r}; use sim, manual:POSE_FILE or ur:HOST")


def _cell(args: argparse.Namespace):
    """The cell: the simulated one, or the camera's intrinsics, the target and rough X, Z from the options."""
    if args.camera == "sim":
        if args.robot != "sim":
            raise HandEyeError("--camera sim goes with --robot sim (the simulated cell)")
        world = SimWorld.default(args.setup, seed=args.seed, target=target_spec_arg(args.target_spec))
        rough = make_transform(Rotation.from_rotvec(np.radians([1.5, -1.0, 1.0])).as_matrix(), [0.01, -0.008, 0.005])
        return world, world.target_spec, (world.K, world.dist, world.image_size), rough @ world.X, rough @ world.Z
    if not args.intrinsics:
        raise HandEyeError("--intrinsics is needed with a real camera (a YAML with K, dist, image_size)")
    spec = target_spec_arg(args.target_spec)
    if spec is None:
        raise HandEyeError("--target-spec is needed with a real camera (your session.yaml or a target: mapping)")
    return None, spec, load_camera(args.intrinsics), *placements(args)


def _cmd_live(args: argparse.Namespace) -> int:
    require_web()  # before any device is opened: the extra is missing, say so
    if not is_loopback(args.host) and not args.allow_remote:
        raise HandEyeError(f"--host {args.host} serves the page (and the robot's moves) beyond this machine: add "
                           "--allow-remote to mean it (every request then needs the one-time token printed)")
    target_std = floats_arg(args.target_std, "--target-std", (2,))
    world, spec, (K, dist, size), X0, Z0 = _cell(args)
    robot, can_move = _robot(args, world)
    camera = StillSimCamera(SimCamera(world, robot)) if world is not None else make_camera(args.camera)
    folder = Path(args.session)
    live = LiveCapture(folder, robot, camera, args.setup, spec, K, dist, size, X0, Z0, results=args.results,
                       target_std=(0.05, 0.5) if target_std is None else tuple(target_std.tolist()),
                       min_views=args.min_poses, robot_accuracy=accuracy_arg(args.robot_accuracy),
                       standoff=args.standoff, can_move=can_move, fps=args.fps, log=lambda text: print(text, flush=True))

    def ready(url: str) -> None:
        print(f"handeye live: the capture into {folder} is at {url}" + ("" if is_loopback(args.host) else
              "\n  (the token in this address is required: give it only to whom may move the robot)"), flush=True)
        print("handeye live: Ctrl-C stops; every view is in the session folder as it is taken", flush=True)

    serve(live, args.host, args.port, open_browser=not args.no_browser, ready=ready, move_first=world is not None)
    done = live.finished
    print(f"{len(live.views)} views in {folder}" + (f"; the report: {Path(done['folder']) / 'report.html'}" if done else
                                                     f"; to calibrate them: handeye calibrate {folder} --out RESULTS"))
    return 0


def register(sub) -> None:
    """Add the ``live`` command's parser to the sub-parsers ``sub``."""
    p = sub.add_parser(
        "live",
        help="capture from a page in the browser: the live image with the target found, the views taken, the "
        "coverage, the planner's next pose and a calibration after every view",
        description="Serve a page (http://127.0.0.1:PORT/) that shows the camera's image with the target's detection, "
        "the robot's pose, the views taken (each removable), the rotations' coverage, the planner's next pose (a "
        "button moves the robot there) and after every view the calibration of the views so far (X, std, verdict, "
        "held-out error), saying plainly when it is enough; Finish writes the report. Each view is written into "
        "SESSION as it is taken; the same command continues a stopped capture. Needs the live extra "
        "(pip install 'handeye[live]'). Backends as handeye acquire: --robot sim|manual:POSE_FILE|ur:HOST, --camera "
        "sim|opencv:INDEX|URL|FILE|genicam:PRODUCER.cti|folder:PATH.",
    )
    p.add_argument("session", help="the session folder (new, or a stopped capture to continue)")
    p.add_argument("--robot", required=True, metavar="BACKEND", help="sim, manual:POSE_FILE or ur:HOST")
    p.add_argument("--camera", required=True, metavar="BACKEND", help="sim, opencv:INDEX|URL|FILE, genicam:CTI, folder:PATH")
    p.add_argument("--results", help="where Finish writes the calibration (default: SESSION-results beside SESSION)")
    p.add_argument("--setup", default="eye_in_hand", choices=list(SETUPS))
    p.add_argument("--host", default="127.0.0.1", help="the address to serve on (default 127.0.0.1: this machine only)")
    p.add_argument("--allow-remote", action="store_true", help="with --host beyond loopback: serve there, every request "
                   "needing the one-time token printed at the start")
    p.add_argument("--port", type=whole_arg(0), default=8765, help="the port (default 8765; 0: any free one)")
    p.add_argument("--no-browser", action="store_true", help="do not open the page in a browser")
    p.add_argument("--fps", type=number_arg(0.0, above=True), default=8.0, help="frames a second on the page (default 8)")
    p.add_argument("--target-std", metavar="DEG,MM", help="'enough' when X's std per axis is within these (default 0.05,0.5)")
    p.add_argument("--min-poses", type=whole_arg(3), default=6, help="never 'enough' before this many views (default 6)")
    p.add_argument("--standoff", type=number_arg(0.0, above=True), default=0.5, help="the planner's camera-to-target "
                   "distance (m, default 0.5)")
    p.add_argument("--intrinsics", help="real cameras: YAML with K, dist and image_size (a session.yaml will do)")
    p.add_argument("--target-spec", help="real cameras (or the simulated cell's board): YAML with the target: mapping")
    add_placements(p)
    p.add_argument("--robot-format", default="euler:ZYX", help="manual: the format the robot's pose file is in")
    p.add_argument("--robot-units", default="mm,deg", metavar="LENGTH,ANGLE", help="manual: its units (default mm,deg)")
    p.add_argument("--robot-accuracy", metavar="DEG,MM", help="the robot's absolute accuracy (as calibrate)")
    p.add_argument("--speed", type=number_arg(0.0, above=True), default=0.1, help="ur: linear speed, m/s (capped at 0.25)")
    p.add_argument("--dry-run", action="store_true", help="ur: print the moves, do not make them")
    p.add_argument("--seed", type=whole_arg(0), default=0, help="sim: the simulated cell and its noise")
    p.set_defaults(func=_cmd_live)
