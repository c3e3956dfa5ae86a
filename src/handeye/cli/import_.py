"""``handeye import``: other tools' captures as handeye sessions."""

from __future__ import annotations

import argparse

from ..errors import HandEyeError
from ..importers import import_easy_handeye, import_industrial_calibration, import_rosbag, import_visp
from ..setups import SETUPS
from ._common import target_spec_arg, whole_arg


def _cmd_import(args: argparse.Namespace) -> int:
    if args.kind == "easy-handeye":
        summary = import_easy_handeye(args.source, args.out, setup=args.setup)
    elif args.kind == "visp":
        summary = import_visp(args.source, args.out, setup=args.setup or "eye_in_hand",
                              target=target_spec_arg(args.target_spec))
    elif args.kind == "industrial-calibration":
        summary = import_industrial_calibration(args.source, args.out)
    else:
        frames = None
        if args.robot_topic is None:
            base, sep, tool = args.robot_frames.partition(",")
            if not sep or not base.strip() or not tool.strip():
                raise HandEyeError(f"--robot-frames {args.robot_frames!r}: give BASE,TOOL, e.g. base_link,tool0")
            frames = (base.strip(), tool.strip())
        summary = import_rosbag(args.source, args.out, setup=args.setup or "eye_in_hand", robot_frames=frames,
                                robot_topic=args.robot_topic, image_topic=args.image_topic,
                                camera_pose_topic=args.camera_pose_topic, camera_pose=args.camera_pose,
                                camera_info_topic=args.camera_info_topic, target=target_spec_arg(args.target_spec),
                                every=args.every)
    what = {"session": "a session", "posepairs": "a pose-pair folder",
            "stream session": "a session (a robot stream, images with their times)",
            "stream posepairs": "a pose-pair folder of two streams"}[summary.kind]
    print(f"wrote {what} to {summary.folder}: {summary.robot_samples} robot and {summary.camera_samples} camera samples")
    if args.setup is None and args.kind in ("visp", "rosbag"):
        # these sources do not record the setup: say what was assumed, before a calibration says it is inconsistent
        print("setup: eye_in_hand assumed (the source does not say); for a camera fixed beside the robot, import "
              "again with --setup eye_to_hand")
    command = "calibrate" if summary.kind.endswith("session") else "calibrate-poses"
    print(f"next: handeye {command} {summary.folder} --out RESULTS")
    return 0


def register(sub) -> None:
    """Add the ``import`` command's parser to the sub-parsers ``sub``."""
    p = sub.add_parser(
        "import",
        help="turn a ROS bag, easy_handeye samples, a ViSP or an industrial_calibration dataset into a handeye folder",
        description="rosbag: the robot from /tf (BASE,TOOL frames) or a pose topic, the camera from an image topic "
        "(a session; --target-spec needed) or a pose topic (two pose streams); header stamps are kept, so handeye "
        "estimates the clock offset. easy-handeye: easy_handeye2's .samples file as a pose-pair folder. visp: a "
        "folder of ViSP's hand-eye tutorial (rPe/fPe poses, images, camera.xml, chessboard-/apriltag-data.txt; or "
        "cPo poses). industrial-calibration: ROS-Industrial's cal_data.yaml (or its folder).",
    )
    p.add_argument("kind", choices=["rosbag", "easy-handeye", "visp", "industrial-calibration"])
    p.add_argument("source", help="the bag (ROS 2 folder, .db3/.mcap, or ROS 1 .bag), the .samples file, the ViSP "
                   "folder, or cal_data.yaml")
    p.add_argument("-o", "--out", required=True, help="folder to write (new or empty)")
    p.add_argument("--setup", choices=list(SETUPS),
                   help="default eye_in_hand (rosbag); easy-handeye reads it from the file's calibration_type")
    p.add_argument("--robot-frames", default="base_link,tool0", metavar="BASE,TOOL",
                   help="tf frames of the robot's base and flange (default base_link,tool0)")
    p.add_argument("--robot-topic", help="instead of tf: a PoseStamped/TransformStamped/Odometry topic of the flange")
    p.add_argument("--image-topic", help="an Image or CompressedImage topic")
    p.add_argument("--camera-pose-topic", help="instead of images: a pose topic of the target in the camera")
    p.add_argument("--camera-pose", default="target2cam", choices=["target2cam", "cam2target"],
                   help="what --camera-pose-topic holds (default target2cam)")
    p.add_argument("--camera-info-topic", help="a CameraInfo topic: the intrinsics (else estimated from the images)")
    p.add_argument("--target-spec", help="YAML with a target: mapping as in session.yaml (needed with --image-topic; "
                   "for ViSP folders without chessboard-/apriltag-data.txt)")
    p.add_argument("--every", type=whole_arg(1), default=1, help="keep every n-th image (default 1)")
    p.set_defaults(func=_cmd_import)
