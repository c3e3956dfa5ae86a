"""``handeye calibrate-streams``: two time-stamped pose streams on two clocks."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

from ..errors import HandEyeError
from ..frames.setups import SETUPS
from ..io.session import POSE_KINDS, TIME_UNITS, load_camera_stream, load_joint_stream, load_pose_streams
from ..options import REFINES_POSES
from ..pipelines.folders import calibrate_pairs
from ..pipelines.streams import calibrate_joint_streams
from ._common import add_calibrate_options, add_out_options, calibrate_options, finish_poses, out_folder, units_arg


def _cmd_calibrate_streams(args: argparse.Namespace) -> int:
    robot, camera = Path(args.robot), Path(args.camera)
    if (args.arm is None) == (args.robot_format is None):
        raise HandEyeError("give --robot-format (the robot file holds poses) or --arm (it holds joint angles), one of them")
    if args.compliance and args.arm is None:
        raise HandEyeError("--compliance fits the joints' compliance: the robot file must hold joint angles (--arm)")
    if args.pendant_joints and args.arm is None:
        raise HandEyeError("--pendant-joints describes joint angles: the robot file must hold them (--arm)")
    if args.arm is not None and args.robot_pose != "flange2base":
        raise HandEyeError(f"--robot-pose {args.robot_pose} describes pose rows; with --arm the robot file holds joint "
                           "angles: leave --robot-pose out")
    out_folder(args.out, [robot.parent, camera.parent])
    rl, ra = units_arg(args.robot_units, "--robot-units")
    cl, ca = units_arg(args.camera_units, "--camera-units")
    if args.arm is not None:
        return _joint_streams(args, robot, camera, ra, cl, ca)
    pairs = load_pose_streams(
        {"file": str(robot), "format": args.robot_format, "length_unit": rl, "angle_unit": ra, "pose": args.robot_pose,
         "time_unit": args.time_unit},
        {"file": str(camera), "format": args.camera_format, "length_unit": cl, "angle_unit": ca,
         "pose": args.camera_pose, "time_unit": args.time_unit}, args.setup)
    return finish_poses(calibrate_pairs(pairs, calibrate_options(args)), args)


def _joint_streams(args: argparse.Namespace, robot: Path, camera: Path, joint_unit: str, cl: str, ca: str) -> int:
    """The robot file holds joint angles: X, Z and the arm's table from the two streams."""
    t_robot, joints, chain, joint_notes = load_joint_stream(robot, args.arm, joint_unit, args.time_unit,
                                                            args.pendant_joints)
    spec = {"file": str(camera), "format": args.camera_format, "length_unit": cl, "angle_unit": ca,
            "pose": args.camera_pose, "time_unit": args.time_unit}
    t_cam, target2cam, camera_notes = load_camera_stream(spec)
    cal = calibrate_joint_streams(t_robot, joints, t_cam, target2cam, args.setup, chain,
                                  calibrate_options(args).replace(arm=None))
    return finish_poses(replace(cal, notes=joint_notes + camera_notes + list(cal.notes), input_folder=robot.parent), args)


def register(sub) -> None:
    """Add the ``calibrate-streams`` command's parser to the sub-parsers ``sub``."""
    p = sub.add_parser(
        "calibrate-streams",
        help="calibrate from a robot pose stream and a camera pose stream with separate clocks",
        description="Pair two time-stamped pose recordings by time: estimate the clock offset (camera minus robot) "
        "from the motion, interpolate the robot at the camera's times, choose well-spread keyframes and calibrate. "
        "Each file: a header 'time' (or t, stamp, timestamp) then the pose columns of its format, or no header "
        "with the columns in that order (e.g. ETH/TUM trajectories: t x y z qx qy qz qw = quat_xyzw).",
    )
    p.add_argument("robot", help="CSV of robot poses with times (flange2base unless --robot-pose base2flange)")
    p.add_argument("camera", help="CSV of camera poses with times (target2cam unless --camera-pose cam2target)")
    p.add_argument("--setup", default="eye_in_hand", choices=list(SETUPS), help="default: eye_in_hand")
    p.add_argument("--robot-format", metavar="FORMAT",
                   help="pose columns of the robot file: matrix, quat_wxyz, quat_xyzw, rotvec or euler:SEQ")
    p.add_argument("--arm", metavar="NAME|TABLE.yaml|ROBOT.urdf",
                   help="instead of --robot-format: the robot file holds joint angles (a time column, then one per "
                   "joint, in the unit of --robot-units' angle), read with this arm's kinematics; X, Z and the arm's "
                   "table are fitted together")
    p.add_argument("--compliance", action="store_true", help="with --arm: fit each joint's compliance too")
    p.add_argument("--pendant-joints", action="store_true",
                   help="with --arm: the joint angles are as the teach pendant shows them (FANUC: J3 against the "
                   "horizon), converted with the arm's pendant_coupling")
    p.add_argument("--camera-format", required=True, metavar="FORMAT", help="pose columns of the camera file (as --robot-format)")
    p.add_argument("--robot-units", default="m,rad", metavar="LENGTH,ANGLE", help="units of the robot file (default m,rad)")
    p.add_argument("--camera-units", default="m,rad", metavar="LENGTH,ANGLE", help="units of the camera file (default m,rad)")
    p.add_argument("--robot-pose", default="flange2base", choices=list(POSE_KINDS["robot_poses"]),
                   help="what the robot rows are (default flange2base)")
    p.add_argument("--camera-pose", default="target2cam", choices=list(POSE_KINDS["camera_poses"]),
                   help="what the camera rows are (default target2cam, solvePnP's; cam2target for a camera pose in "
                   "the target frame)")
    p.add_argument("--time-unit", default="s", choices=list(TIME_UNITS), help="unit of both time columns (default s)")
    add_out_options(p)
    add_calibrate_options(p, REFINES_POSES)
    p.set_defaults(func=_cmd_calibrate_streams)
