"""``handeye import``: other tools' captures as handeye sessions."""

from __future__ import annotations

import argparse
from pathlib import Path

from .._shared.io import atomic_write
from ..errors import HandEyeError
from ..estimation.diagnostics import diagnose
from ..frames.setups import SETUPS
from ..io.importers import import_easy_handeye, import_industrial_calibration, import_rosbag, import_visp
from ..io.session import load_session
from ..pipelines.calibration import observe
from ..pipelines.kinds import importer_of
from ._common import target_spec_arg, whole_arg


def _cmd_import(args: argparse.Namespace) -> int:
    if args.kind == "easy-handeye":
        summary = import_easy_handeye(args.source, args.out, setup=args.setup)
    elif args.kind == "visp":
        summary = import_visp(args.source, args.out, setup=args.setup or "eye_in_hand",
                              target=target_spec_arg(args.target_spec))
    elif args.kind == "industrial-calibration":
        summary = import_industrial_calibration(args.source, args.out)
    elif importer_of(args.kind) is not None:  # another kind's session (a laser's, a silhouette's): its registration's
        summary = importer_of(args.kind)(args.source, args.out, **({"arm": args.arm} if hasattr(args, "arm") else {}))
    else:
        frames = None
        if args.robot_topic is None and args.joint_topic is None:
            base, sep, tool = args.robot_frames.partition(",")
            if not sep or not base.strip() or not tool.strip():
                raise HandEyeError(f"--robot-frames {args.robot_frames!r}: give BASE,TOOL, e.g. base_link,tool0")
            frames = (base.strip(), tool.strip())
        summary = import_rosbag(args.source, args.out, setup=args.setup or "eye_in_hand", robot_frames=frames,
                                robot_topic=args.robot_topic, image_topic=args.image_topic,
                                camera_pose_topic=args.camera_pose_topic, camera_pose=args.camera_pose,
                                camera_info_topic=args.camera_info_topic, target=target_spec_arg(args.target_spec),
                                every=args.every, joint_topic=args.joint_topic, arm=args.arm)
    what = {"session": "a session", "posepairs": "a pose-pair folder",
            "stream session": "a session (a robot stream, images with their times)",
            "stream posepairs": "a pose-pair folder of two streams",
            "joint streams": "two streams for calibrate-streams --arm (joints.csv, camera.csv)",
            "laser session": "a laser profiler's session (profiles/, poses.csv)",
            "silhouette session": "a markerless colour session (masks/, images/, joints.csv)"}[summary.kind]
    print(f"wrote {what} to {summary.folder}: {summary.robot_samples} robot and {summary.camera_samples} camera samples")
    for note in summary.notes:
        print(f"note: {note}")
    if getattr(args, "setup", None) is None and args.kind in ("visp", "rosbag"):
        # these sources do not record the setup: ViSP's small folders are checked, else say what was assumed
        found = _setup_from_data(summary.folder) if args.kind == "visp" and summary.kind == "session" else None
        if found is None:
            print("setup: eye_in_hand assumed (the source does not say); for a camera fixed beside the robot, import "
                  "again with --setup eye_to_hand")
        else:
            print(f"setup: {found[0]}, from the data (the source does not say; the check of its images: {found[1]}); "
                  "--setup eye_in_hand to keep the other")
    command = "calibrate" if summary.kind.endswith("session") else "calibrate-poses"
    print(f"next: handeye {command} {summary.folder} --out RESULTS")
    return 0


def _setup_from_data(folder: Path) -> tuple[str, str] | None:
    """The setup an imported session's own data take, when the pose check finds them consistent only
    in the other one (its convention hint ``setup:...``): ``(setup, the check's sentence)``, with
    session.yaml rewritten to it; None when the setup assumed fits, or the check cannot tell (no
    target found, too few views). The detections stay in the cache for the calibration."""
    try:
        session = load_session(folder)
        obs = observe(session, progress=False)
        diag = diagnose(obs.flange2base, obs.target2cam, session.setup, camera_from_images=True)
    except HandEyeError:
        return None
    hint = diag.convention_hint or ""
    if not hint.startswith("setup:"):
        return None
    setup = hint.partition(":")[2]
    path = Path(folder) / "session.yaml"
    text = path.read_text(encoding="utf-8")
    atomic_write(path, text.replace(f"\nsetup: {session.setup}\n", f"\nsetup: {setup}\n", 1))
    if load_session(folder).setup != setup:
        raise HandEyeError(f"{path}: could not set the setup to {setup}")
    return setup, next((a for a in diag.advice if "setup" in a), hint)


#: Each source: its one-line help and its description (``handeye import KIND --help``).
SOURCES = {
    "rosbag": ("a ROS 1 or ROS 2 bag: the robot from /tf or a pose topic, the camera from images or a pose topic",
               "The robot from /tf (--robot-frames BASE,TOOL) or a pose topic (--robot-topic), the camera from an "
               "image topic (a session; --target-spec needed) or a pose topic (two pose streams). Header stamps are "
               "kept, so handeye estimates the clock offset between robot and camera."),
    "easy-handeye": ("easy_handeye2's .samples file", "easy_handeye2's .samples file as a pose-pair folder; the "
                     "setup is read from its calibration_type."),
    "visp": ("a folder of ViSP's hand-eye tutorial", "A folder of ViSP's hand-eye tutorial: rPe/fPe robot poses with "
             "images, camera.xml and chessboard-/apriltag-data.txt (a session), or cPo camera poses (a pose-pair "
             "folder)."),
    "industrial-calibration": ("ROS-Industrial's cal_data.yaml (or its folder)", "ROS-Industrial's "
                               "industrial_calibration data set: cal_data.yaml with its images and poses, as a session."),
    "robcalibrator": ("RobCalibrator's laser scans of a sphere (p1.yml ..., RobPoses.rob)", "RobCalibrator's folder of "
                      "laser profiles of a sphere (p1.yml ...: OpenCV YAML scan_line in mm), FANUC poses (RobPoses.rob: "
                      "x, y, z, w, p, r in mm and degrees) and calibration.sec (setup, radius), as a laser session."),
    "easyhec": ("EasyHeC's markerless capture (color/, mask/, qpos/, K.txt)", "EasyHeC's folder of colour images, masks "
                "of the robot and joint angles (qpos/: the arm's, then the fingers') with K.txt, as a silhouette session "
                "(the camera fixed, the robot's own silhouette the target)."),
}


def register(sub) -> None:
    """Add the ``import`` command's parser to the sub-parsers ``sub``: one parser per source, with its options."""
    p = sub.add_parser(
        "import",
        help=f"turn another tool's capture into a handeye folder: {', '.join(SOURCES)}",
        description="Turn another tool's capture into a handeye folder; 'handeye import KIND --help' for each.",
    )
    kinds = p.add_subparsers(dest="kind", metavar="KIND")
    kinds.required = True
    parsers = {}
    for kind, (short, long) in SOURCES.items():
        k = parsers[kind] = kinds.add_parser(kind, help=short, description=long)
        k.add_argument("-o", "--out", required=True, help="folder to write (new or empty)")
        k.set_defaults(func=_cmd_import)
    parsers["rosbag"].add_argument("source", help="the bag: a ROS 2 folder, .db3 or .mcap, or a ROS 1 .bag")
    parsers["easy-handeye"].add_argument("source", help="the .samples file")
    parsers["visp"].add_argument("source", help="the ViSP folder")
    parsers["industrial-calibration"].add_argument("source", help="cal_data.yaml or its folder")
    parsers["robcalibrator"].add_argument("source", help="the folder of p1.yml ..., RobPoses.rob")
    parsers["easyhec"].add_argument("source", help="the folder of color/, mask/, qpos/ and K.txt")
    parsers["easyhec"].add_argument("--arm", default="panda", help="the arm whose joint angles qpos/ holds (default panda)")
    parsers["rosbag"].add_argument("--setup", choices=list(SETUPS), help="default eye_in_hand (a bag does not say)")
    parsers["visp"].add_argument("--setup", choices=list(SETUPS),
                                 help="default: the folder does not say; eye_to_hand when the images' poses are "
                                      "consistent only so (the pose check), else eye_in_hand")
    parsers["easy-handeye"].add_argument("--setup", choices=list(SETUPS),
                                         help="default: the file's calibration_type")
    r = parsers["rosbag"]
    r.add_argument("--robot-frames", default="base_link,tool0", metavar="BASE,TOOL",
                   help="tf frames of the robot's base and flange (default base_link,tool0)")
    r.add_argument("--robot-topic", help="instead of tf: a PoseStamped/TransformStamped/Odometry topic of the flange")
    r.add_argument("--image-topic", help="an Image or CompressedImage topic")
    r.add_argument("--camera-pose-topic", help="instead of images: a pose topic of the target in the camera")
    r.add_argument("--camera-pose", default="target2cam", choices=["target2cam", "cam2target"],
                   help="what --camera-pose-topic holds (default target2cam)")
    r.add_argument("--camera-info-topic", help="a CameraInfo topic: the intrinsics (else estimated from the images)")
    r.add_argument("--every", type=whole_arg(1), default=1, help="keep every n-th image (default 1)")
    r.add_argument("--joint-topic", help="instead of the robot's poses: a JointState topic (/joint_states); with "
                   "--image-topic each image's joint angles interpolated at its stamp into joints.csv (calibrate then fits "
                   "the arm's table with X); with --camera-pose-topic the two streams calibrate-streams --arm takes")
    r.add_argument("--arm", help="with --joint-topic: the arm (a shipped one: handeye.robot.kinematics.arm_names()), "
                   "or a DH table (.yaml) or URDF file you put in the session folder")
    for kind, when in (("rosbag", "needed with --image-topic"),
                       ("visp", "for folders without chessboard-/apriltag-data.txt")):
        parsers[kind].add_argument("--target-spec", help=f"YAML with a target: mapping as in session.yaml ({when})")
