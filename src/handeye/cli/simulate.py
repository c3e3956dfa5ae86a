"""``handeye simulate``: a rendered session with its ground truth."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import InputMismatchError
from ..frames.setups import SETUPS, setup_info
from ..planning.poses import ROBOTS
from ..robot.kinematics import arm_names
from ..simulate import (
    DEFAULT_TARGETS,
    depth_scene,
    laser_scene,
    simulate_kinematic_session,
    simulate_session,
    sphere_scene,
    write_depth_session,
    write_laser_session,
)
from ..simulate.arm_depth import arm_depth_scene, write_arm_depth_session
from ..simulate.laser import TARGETS as LASER_TARGETS
from ..simulate.linescan import linescan_scene, write_linescan_session
from ..simulate.mesh import mesh_scene, write_mesh_session
from ..simulate.rig import (
    camera_depth_scene,
    camera_laser_scene,
    rig_joint_scene,
    rig_scene,
    write_camera_depth_session,
    write_camera_laser_session,
    write_rig_session,
)
from ..simulate.scene import scene_capture, write_scene_session
from ..simulate.silhouette import silhouette_scene, write_silhouette_session
from ._common import image_size_arg, number_arg, out_folder, sensor_target, whole_arg


def _cmd_simulate(args: argparse.Namespace) -> int:
    out_folder(args.out)
    if args.sensor == "rig":
        if args.robot != "arm" or args.target is not None:
            raise InputMismatchError("--sensor rig simulates a 6-axis arm (its controller's poses, or with --arm its joint "
                                     "angles) and a chessboard; leave --robot and --target out")
        on_flange = setup_info(args.setup).camera_on_flange
        cameras = args.cameras or (2 if on_flange else 3)
        if args.laser and args.depth:
            raise InputMismatchError("--laser and --depth each put one sensor beside the camera: give one of them")
        if args.depth or args.laser:  # a camera beside one other sensor: an RGB-D camera, or a profiler scanning a ball
            flag, other = ("--depth", "depth camera") if args.depth else ("--laser", "laser profiler")
            if args.arm is not None or args.cameras is not None:
                raise InputMismatchError(f"{flag} simulates one camera beside one {other} on controller poses; leave --arm "
                                         "and --cameras out")
            scene, write = (camera_depth_scene, write_camera_depth_session) if args.depth else \
                (camera_laser_scene, write_camera_laser_session)
            write(args.out, scene(args.poses, args.setup, args.seed, robot_error=(0.01, 0.05)), rng=args.seed,
                  noise_px=args.noise_px)
            seen = "a chessboard both see, the depth scale 0.2% off" if args.depth else "a small chessboard and a 40 mm ball"
            print(f"wrote rig session {args.out} ({args.poses} poses, a camera and a {other} "
                  f"{'on the flange' if on_flange else 'fixed side by side'}: {seen}; the robot 0.01 deg / 0.05 mm off); "
                  f"ground truth in {Path(args.out) / 'ground_truth.yaml'}")
            return 0
        if args.arm is not None:  # joint angles of an arm 1-3 mm off its nominal table, the cameras side by side
            sc = rig_joint_scene(args.poses, args.setup, args.seed, arm=args.arm, cameras=cameras)
            error = f"the {sc.chain.name}'s joint angles, its real table 1-3 mm off the nominal one"
        else:
            sc = rig_scene(args.poses, args.setup, args.seed, cameras=cameras, robot_error=(0.01, 0.05))
            error = "the robot 0.01 deg / 0.05 mm off"
        write_rig_session(args.out, sc, rng=args.seed, noise_px=args.noise_px)
        what = ("a stereo pair on the flange" if cameras == 2 else f"{cameras} cameras on the flange") if on_flange else \
            f"{cameras} cameras fixed {'side by side' if args.arm else 'around the cell'}"
        print(f"wrote rig session {args.out} ({args.poses} poses, {what}, a chessboard; {error}); "
              f"ground truth in {Path(args.out) / 'ground_truth.yaml'}")
        return 0
    if args.cameras is not None or args.laser or args.depth:
        flag = "--cameras" if args.cameras is not None else "--laser" if args.laser else "--depth"
        raise InputMismatchError(f"{flag} describes a rig: give it with --sensor rig")
    if args.sensor == "line_scan":
        if args.robot != "arm" or args.target is not None:
            raise InputMismatchError("--sensor line_scan simulates a 6-axis arm (its controller's poses, or with --arm its "
                                     "joint angles) and a chessboard; leave --robot and --target out")
        sc = linescan_scene(args.poses, args.setup, args.seed, arm=args.arm)
        write_linescan_session(args.out, sc, rng=args.seed)
        arm = f", {args.arm}'s joint angles along the trajectory in joints.csv (the arm 1-3 mm off its nominal table)" \
            if args.arm else ""
        print(f"wrote line-scan session {args.out} ({args.poses} scans of a {sc.board[0]} x {sc.board[1]} chessboard, "
              f"{args.setup}, {sc.width} px at {sc.line_rate:.0f} lines/s, the robot's clock {1e3 * sc.clock_offset:.0f} ms "
              f"after the camera's{arm}); ground truth in {Path(args.out) / 'ground_truth.yaml'}")
        return 0
    if args.sensor == "depth":
        return _simulate_depth(args)
    if args.sensor == "silhouette":
        return _simulate_silhouette(args)
    if args.sensor == "laser_line":
        if args.robot != "arm":
            raise InputMismatchError("--sensor laser_line simulates a 6-axis arm (its controller's poses, or with --arm its "
                                     "joint angles too); leave --robot out")
        target = sensor_target(args.sensor, args.target, "charuco")
        write_laser_session(args.out, laser_scene(args.poses, args.setup, args.seed, arm=args.arm, target=target))
        what = {"sphere": "a 40 mm ball", "plane": "a 200 mm plate", "edge": "a block's edge", "step": "a 10 mm step",
                "spheres": "a fixture of 3 balls"}[target]
        arm = f", {args.arm}'s joint angles in joints.csv (the arm 1-3 mm off its nominal table)" if args.arm else ""
        print(f"wrote laser session {args.out} ({args.poses} profiles of {what}, {args.setup}{arm}); ground truth in "
              f"{Path(args.out) / 'ground_truth.yaml'}")
        return 0
    args.target = sensor_target(args.sensor, args.target, "charuco")
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


def _simulate_arm_depth(args: argparse.Namespace) -> int:
    """A depth camera fixed in the cell and the arm itself as the target (markerless): always eye_to_hand."""
    if args.robot != "arm":
        raise InputMismatchError("--sensor depth --target arm simulates a meshed arm's joint angles; leave --robot out")
    arm = args.arm or "panda"
    sc = arm_depth_scene(args.poses, args.seed, arm=arm, image_size=args.image_size)
    write_arm_depth_session(args.out, sc)
    print(f"wrote depth session {args.out} ({args.poses} clouds of the {arm} itself, its joint angles in joints.csv, a "
          f"camera fixed {1e3 * float(sc.X[2, 3]):.0f} mm above its base, eye_to_hand; a table and a box as clutter); "
          f"ground truth in {Path(args.out) / 'ground_truth.yaml'}")
    return 0


def _simulate_silhouette(args: argparse.Namespace) -> int:
    if args.robot != "arm" or args.target is not None or args.arm not in (None, "panda"):
        raise InputMismatchError("--sensor silhouette simulates a Panda seen by a fixed camera (eye_to_hand), no target; "
                                 "leave --robot and --target out")
    sc = silhouette_scene(args.poses, args.seed, image_size=args.image_size)
    write_silhouette_session(args.out, sc)
    print(f"wrote silhouette session {args.out} ({args.poses} masks of a Panda, {args.image_size[0]}x{args.image_size[1]}, "
          f"eye_to_hand, the masks' boundary off by ~1 px with a few blobs); ground truth in "
          f"{Path(args.out) / 'ground_truth.yaml'}")
    return 0


def _simulate_depth(args: argparse.Namespace) -> int:
    """A depth camera's clouds: of a mesh (the default: a flange-sized disc on the flange, eye-to-hand),
    a ball, or a board."""
    target = args.target or "mesh"
    if target == "arm":  # markerless: a camera fixed in the cell sees the arm itself
        return _simulate_arm_depth(args)
    if target == "scene":  # no target: whatever object the camera sees
        if args.robot != "arm" or args.arm is not None:
            raise InputMismatchError("--target scene simulates a 6-axis arm's controller poses; leave --robot and --arm out")
        write_scene_session(args.out, scene_capture(args.poses, args.setup, args.seed, image_size=args.image_size))
        where = "on a plate, the camera on the flange" if setup_info(args.setup).camera_on_flange else \
            "on the flange, a camera fixed in the cell"
        print(f"wrote depth session {args.out} ({args.poses} clouds of an irregular object {where}, 0.3-0.5 m away, "
              f"target: {{type: scene}}: no target, no mesh); ground truth in {Path(args.out) / 'ground_truth.yaml'}")
        return 0
    if args.robot != "arm":
        raise InputMismatchError("--sensor depth simulates a 6-axis arm (its controller's poses, or with --arm its joint "
                                 "angles); leave --robot out")
    if target == "mesh":
        if args.arm is not None and setup_info(args.setup).camera_on_flange:
            raise InputMismatchError("--target mesh --arm simulates the shape on the arm's flange before a fixed camera: "
                                     "give --setup eye_to_hand")
        sc = mesh_scene(args.poses, args.setup, args.seed, image_size=args.image_size, arm=args.arm)
        write_mesh_session(args.out, sc)
        what = "a flange-sized disc (target.stl) with bolt holes and a locating pin"
    elif target == "sphere":
        write_depth_session(args.out, sphere_scene(args.poses, args.setup, args.seed, image_size=args.image_size, arm=args.arm))
        what = "a 50 mm ball"
    elif target in DEFAULT_TARGETS:
        write_depth_session(args.out, depth_scene(args.poses, args.setup, args.seed, target=target,
                                                  image_size=args.image_size, noise_px=args.noise_px, arm=args.arm))
        what = f"a {target} with its intensity images"
    else:
        raise InputMismatchError(f"--target {target}: a depth camera's simulated target is mesh (default), sphere, scene, "
                                 f"arm or a board ({', '.join(DEFAULT_TARGETS)})")
    arm = f", {args.arm}'s joint angles in joints.csv (the arm 1-3 mm off its nominal table)" if args.arm else ""
    print(f"wrote depth session {args.out} ({args.poses} clouds of {what}, {args.setup}{arm}); ground truth in "
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
    p.add_argument("--sensor", default="camera", choices=["camera", "depth", "laser_line", "line_scan", "rig", "silhouette"],
                   help="camera (default): rendered images of a board; depth: a depth camera's 640x480 clouds of a mesh "
                   "(--target mesh, the default: a flange-sized disc on the flange), a ball (sphere) or a board; laser_line: "
                   "a laser line profiler's profiles of a ball, a plate, a block's edge, a step or a fixture of balls "
                   "(--target; --poses of them; --arm for joint angles); line_scan: a line-scan camera's scans of a "
                   "chessboard swept by the robot (--poses of them); rig: a stereo pair on the flange (eye_in_hand) or "
                   "three fixed cameras (eye_to_hand); silhouette: a fixed colour camera's masks of a Panda (markerless, "
                   "its joint angles, eye_to_hand; --poses of them)")
    p.add_argument("--cameras", type=whole_arg(2), default=None,
                   help="with --sensor rig: the number of cameras (default 2 on the flange, 3 fixed around the cell)")
    p.add_argument("--laser", action="store_true",
                   help="with --sensor rig: a camera beside a laser profiler (a small board and a 40 mm ball) instead of cameras")
    p.add_argument("--depth", action="store_true",
                   help="with --sensor rig: a camera beside a depth camera (640x480 clouds and intensity images), both seeing "
                   "the board, instead of cameras")
    p.add_argument("--setup", default="eye_in_hand", choices=list(SETUPS))
    p.add_argument("--poses", type=whole_arg(1), default=15, help="number of images (default 15)")
    p.add_argument("--target", default=None, choices=list(DEFAULT_TARGETS) + list(LASER_TARGETS) + ["mesh", "arm", "scene"],
                   help="the board rendered (default charuco: it cannot be read from the wrong end, as handeye's advice "
                   f"recommends; chessboard for the thesis's set-up); with --sensor laser_line: {', '.join(LASER_TARGETS)} "
                   f"({LASER_TARGETS[0]} the default); "
                   "with --sensor depth: mesh (default), sphere, a board, arm (the arm itself, markerless, its joint angles; "
                   "always eye_to_hand; --arm panda, the arm with meshes) or scene (an irregular object, no target and no "
                   "mesh given: X from the clouds' agreement)")
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
