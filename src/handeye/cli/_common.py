"""Arguments, option groups and output steps shared by the commands."""

from __future__ import annotations

import argparse
import math
from importlib.resources import files
from pathlib import Path
from typing import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from .. import solvers
from .._shared.io import check_output_folder
from .._shared.lazy import lazy_module
from ..errors import HandEyeError, InputMismatchError
from ..estimation.verdict import exit_status
from ..frames.poses import ANGLE_UNITS, LENGTH_UNITS
from ..frames.setups import setup_info
from ..geometry.se3 import make_transform
from ..io.session import load_yaml, read_intrinsics
from ..options import KEYFRAMES, PAIRS, REFINES, ROBOT_ACCURACY, CalibrationOptions
from ..pipelines.calibration import certify_calibration
from ..pipelines.kinds import SensorKind, kinds_of_target, sensor_kinds
from ..result import Calibration
from ..robot.kinematics import arm_names
from ..sensors.camera.targets import target_from_spec
from ._printing import print_calibration

# Loaded when a command uses them, not when it parses: ``calibrate`` without --out writes no report,
# and only ``simulate`` and ``plan`` ask the simulator about targets and image sizes.
_report = lazy_module("handeye.report")
_report_files = lazy_module("handeye.report.files")
_simulate = lazy_module("handeye.simulate")

EXAMPLE_POSEPAIRS = "example_posepairs"


SAMPLE_SESSION = "sample_session"


def whole_arg(lo: int):
    """argparse type: a whole number >= ``lo``."""
    def whole(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if v < lo:
            raise argparse.ArgumentTypeError(f"{v} is too small: give a whole number >= {lo}")
        return v
    return whole


def number_arg(lo: float, hi: float = math.inf, above: bool = False):
    """argparse type: a finite number in ``[lo, hi]`` (``(lo, hi]`` when ``above``)."""
    def number(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not math.isfinite(v) or v < lo or (above and v == lo) or v > hi:
            bound = (f"> {lo:g}" if above else f">= {lo:g}") + (f" and <= {hi:g}" if math.isfinite(hi) else "")
            raise argparse.ArgumentTypeError(f"{text} is out of range: give a number {bound}")
        return v
    return number


def image_size_arg(text: str) -> tuple[int, int]:
    """argparse type: WIDTHxHEIGHT in pixels, each at least the simulator's MIN_IMAGE_SIDE."""
    parts = text.lower().replace(" ", "").split("x")
    try:
        w, h = (int(v) for v in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give WIDTHxHEIGHT in pixels, e.g. 640x480") from None
    if min(w, h) < _simulate.MIN_IMAGE_SIDE:
        raise argparse.ArgumentTypeError(f"{text}: each side must be at least {_simulate.MIN_IMAGE_SIDE} px")
    return w, h


def floats_arg(text: str | None, name: str, sizes: tuple[int, ...]) -> np.ndarray | None:
    if text is None:
        return None
    try:
        v = np.array([float(t) for t in text.replace(" ", "").split(",")])
    except ValueError:
        raise HandEyeError(f"{name} {text!r}: give comma-separated numbers") from None
    if v.size not in sizes or not np.all(np.isfinite(v)):
        raise HandEyeError(f"{name} {text!r}: give {' or '.join(str(n) for n in sizes)} finite comma-separated numbers")
    return v


def pose_arg(text: str | None, name: str, default_rot_deg=(0.0, 0.0, 0.0), required: bool = False) -> np.ndarray | None:
    """x,y,z[,rx,ry,rz]: metres and a rotation vector in degrees, as a 4x4."""
    v = floats_arg(text, name, (3, 6))
    if v is None:
        if required:
            raise HandEyeError(f"{name} is needed: x,y,z (m) and optionally rx,ry,rz (rotation vector, deg)")
        v = np.r_[0.0, 0.0, 0.0, default_rot_deg]
    rot = v[3:] if v.size == 6 else np.asarray(default_rot_deg, dtype=float)
    return make_transform(Rotation.from_rotvec(rot, degrees=True).as_matrix(), v[:3])


def load_camera(path: str) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """K, dist and image size of ``--intrinsics`` (see :func:`handeye.io.session.read_intrinsics`)."""
    try:
        return read_intrinsics(path)
    except HandEyeError as exc:
        raise HandEyeError(f"--intrinsics {exc}") from None


def placements(args: argparse.Namespace, target_rotation: Sequence[float] = (180.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Rough X and Z from --cam-in-flange / --target-in-base (eye-in-hand; ``target_rotation``: the
    target's rotation vector, deg, when --target-in-base gives none) or --camera-in-base /
    --target-in-flange (eye-to-hand)."""
    if setup_info(args.setup).camera_on_flange:
        if args.camera_in_base or args.target_in_flange:
            raise HandEyeError("--camera-in-base and --target-in-flange are for eye_to_hand; eye_in_hand takes "
                               "--target-in-base and --cam-in-flange")
        return (pose_arg(args.cam_in_flange, "--cam-in-flange"),
                pose_arg(args.target_in_base, "--target-in-base", tuple(target_rotation), required=True))
    if args.target_in_base or args.cam_in_flange:
        raise HandEyeError("--target-in-base and --cam-in-flange are for eye_in_hand; eye_to_hand takes "
                           "--camera-in-base and --target-in-flange")
    return (pose_arg(args.camera_in_base, "--camera-in-base", required=True),
            pose_arg(args.target_in_flange, "--target-in-flange", (180.0, 0.0, 0.0)))


def board_target(target: str | None, board: str) -> str:
    """--target for a camera: a board (default ``board``); another kind's target (a laser's plane) is a
    clear error that names the --sensor it needs (simulate and plan)."""
    target = target or board
    others = kinds_of_target(target)
    if others:
        raise InputMismatchError(f"--target {target} is a {' or a '.join(k.display for k in others)}'s target: add "
                                 f"{' or '.join('--sensor ' + k.cli for k in others)}, or give a board "
                                 f"({', '.join(_simulate.DEFAULT_TARGETS)})")
    return target


def target_choices(boards: Sequence[str], command: str) -> list[str]:
    """--target's choices: the boards, then every kind's own targets that ``command`` (``simulate``,
    ``plan``) takes for it."""
    return list(dict.fromkeys(list(boards) + [t for k in sensor_kinds() if getattr(k, command) for t in k.targets]))


def add_kind_options(p: argparse.ArgumentParser, command: str) -> None:
    """Every registered kind's own options of ``command`` (its registration's ``options``)."""
    for kind in sensor_kinds():
        for option in kind.options_of(command):
            settings: dict = {"help": f"--sensor {kind.cli}: {option.help}"}
            if option.type == "flag":
                settings["action"] = "store_true"
            elif option.type == "texts":  # given once per value
                settings.update(action="append", default=None)
            else:
                settings["default"] = None
                settings["type"] = {"number": number_arg(option.low, option.high, option.above), "whole": whole_arg(int(option.low)),
                                    "text": str}[option.type]
            if option.metavar:
                settings["metavar"] = option.metavar
            p.add_argument(option.flag, **settings)


def chosen_kind(args: argparse.Namespace, command: str) -> SensorKind | None:
    """The kind whose own option that ``chooses`` it (:class:`~handeye.pipelines.kinds.KindOption`) was
    given to ``command`` without ``--sensor`` (``plan --rig-camera``: a rig); None when none was."""
    return next((k for k in sensor_kinds() for o in k.options_of(command) if o.chooses and getattr(args, o.dest)), None)


def kind_options(args: argparse.Namespace, command: str, kind: SensorKind | None) -> dict:
    """The options of ``kind`` (None: the camera) given to ``command``, by name; another kind's option
    given is an error that names its --sensor."""
    for other in sensor_kinds():
        for option in other.options_of(command):
            if other is not kind and getattr(args, option.dest) not in (None, False):
                raise InputMismatchError(f"{option.flag} is a {other.display}'s: add --sensor {other.cli}, or leave it out")
    return {option.dest: getattr(args, option.dest) for option in (kind.options_of(command) if kind else ())}


def add_placements(p: argparse.ArgumentParser) -> None:
    p.add_argument("--target-in-base", metavar="X,Y,Z[,RX,RY,RZ]",
                   help="eye_in_hand: where the target lies (m); default rotation 180,0,0 = printed side up")
    p.add_argument("--cam-in-flange", metavar="X,Y,Z[,RX,RY,RZ]",
                   help="eye_in_hand: rough camera mounting (default: at the flange, looking along flange z)")
    p.add_argument("--camera-in-base", metavar="X,Y,Z,RX,RY,RZ", help="eye_to_hand: rough camera pose in the base frame")
    p.add_argument("--target-in-flange", metavar="X,Y,Z[,RX,RY,RZ]",
                   help="eye_to_hand: target on the flange (default 0,0,0 turned 180 deg about x: printed side outwards)")


def units_arg(text: str, name: str) -> tuple[str, str]:
    length, _, angle = text.partition(",")
    if length not in LENGTH_UNITS or angle not in ANGLE_UNITS:
        raise HandEyeError(f"{name} {text!r}: give LENGTH,ANGLE with LENGTH one of {', '.join(LENGTH_UNITS)} and ANGLE "
                           f"one of {', '.join(ANGLE_UNITS)}, e.g. m,rad or mm,deg")
    return length, angle


def known_arg(items: list[str]) -> dict[str, str]:
    """--known NAME=VALUE (repeatable) as the ``known=`` dict (calibrate_poses checks names and values)."""
    known = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name.strip() or not value.strip():
            raise HandEyeError(f"--known {item!r}: give TRANSFORM.AXIS=METRES, e.g. --known target2base.z=0.012")
        known[name.strip()] = value.strip()
    return known


def accuracy_arg(text: str | None):
    """--robot-accuracy DEG,MM (calibrate checks the values); absent: handeye's default."""
    v = floats_arg(text, "--robot-accuracy", (2,))
    return ROBOT_ACCURACY if v is None else tuple(v.tolist())


def target_spec_arg(path: str | None) -> dict | None:
    """--target-spec FILE: the target: mapping of a YAML file (a session.yaml, or the mapping alone)."""
    if path is None:
        return None
    data = load_yaml(Path(path))
    spec = data.get("target", data)
    if not isinstance(spec, dict) or "type" not in spec:
        raise HandEyeError(f"--target-spec {path}: no target mapping (type, cols, rows, square, ... as in session.yaml)")
    target_from_spec(spec, where=f"--target-spec {path}")
    return spec


def input_folder(given: str | None, bundled: bool, bundled_name: str, usage: str) -> Path:
    """The folder a command works on: the one given, or (flag set) the one bundled with handeye."""
    if bundled == (given is not None):
        raise HandEyeError(usage)
    if given is not None:
        return Path(given)
    folder = Path(str(files("handeye") / "data" / bundled_name))  # handeye installs as plain files
    print(f"bundled {bundled_name.replace('_', ' ')}: {folder}\n")
    return folder


def out_folder(out: str | None, inputs: Sequence[Path] = ()) -> Path | None:
    """The --out folder of a command, checked before any work (see
    :func:`handeye._shared.io.check_output_folder`)."""
    if out is None:
        return None
    try:
        return check_output_folder(out, inputs)
    except HandEyeError as exc:
        raise HandEyeError(f"--out: {exc}") from None


def export_arg(text: str) -> str:
    """argparse type: a name of the report's exports (``report.files.EXPORTS``) or 'all', checked when
    --export is given (parsing a command does not import the report)."""
    names = [*_report_files.EXPORTS, "all"]
    if text not in names:
        raise argparse.ArgumentTypeError(f"invalid choice: {text!r} (choose from {', '.join(names)})")
    return text


def add_out_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("-o", "--out", help="write result.json, result.yaml and report.html into this folder")
    p.add_argument("--parent-frame", help="ROS frame X is given in (default: tool0 for eye_in_hand, base_link for eye_to_hand)")
    own = "; ".join(f"a {k.display}'s: {k.frame}" for k in sensor_kinds() if k.frame)
    p.add_argument("--child-frame", help=f"ROS frame of the camera (default: camera_optical_frame; {own})")
    p.add_argument("--export", action="append", default=[], type=export_arg, metavar="NAME",
                   help="with --out, also write: ros2-launch (a ROS 2 launch file publishing X), ros1-launch (the "
                   "ROS 1 launch file MoveIt Calibration writes), easy-handeye (easy_handeye2's .calib); repeat or all")
    p.add_argument("--tool", metavar="X,Y,Z[,RX,RY,RZ]",
                   help="your robot's tool (TCP) frame in the flange frame (m; rotation vector in deg): the result "
                   "files also give the camera (eye-in-hand) or the target (eye-to-hand) relative to the tool")
    p.add_argument("--certify", action="store_true",
                   help="certify whether X is the global minimum of the stated motion cost (a semidefinite relaxation; "
                   "needs pip install 'handeye[certifiable]')")


#: --refine's help per choice (docs/guide.md's "auto" paragraph says how auto chooses)
REFINE_HELP = {
    "auto": "auto (default): the estimator that predicts held-out views best by cross-validation among the closed "
            "forms (all but horaud_nonlinear), pose and, with images, reprojection; preferred: the pixel refinement "
            "while its residual is at most 1.2x PnP's (the robot's errors do not dominate), else the pose refinement, "
            "replaced only by a candidate better by more than one standard error (docs/guide.md)",
    "reprojection": "reprojection: X and Z on the pixel errors of all target points, robot poses exact (or corrected "
                    "under the prior --robot-noise gives)",
    "pose": "pose: X and Z on the robot and camera poses, both noisy (their noise estimated from the data)",
    "none": "none: the --method closed form alone (its std: the jackknife and the robot's accuracy)",
}


def add_calibrate_options(p: argparse.ArgumentParser, refines: tuple[str, ...] = REFINES) -> None:
    """The options of a calibration (:class:`handeye.CalibrationOptions`), defined once for every command
    that calibrates or judges data."""
    g = p.add_argument_group("calibration (the same in calibrate, calibrate-poses, calibrate-streams and check)")
    g.add_argument("--method", default="daniilidis", choices=solvers.available(), help="solver (default: daniilidis)")
    g.add_argument("--refine", default="auto", choices=list(refines),
                   help="; ".join(REFINE_HELP[r] for r in refines))
    g.add_argument("--pairs", default="auto", choices=list(PAIRS),
                   help="which pose pairs form motions (auto: all up to 141 poses, else ~10,000 spread pairs)")
    g.add_argument("--folds", type=whole_arg(2), default=None,
                   help="cross-validation folds of --refine auto (default: one per view up to 10 views, else 5)")
    g.add_argument("--robot-accuracy", metavar="DEG,MM",
                   help=f"the robot's absolute accuracy per axis, added to the std of X (a constant robot error is "
                   f"invisible in the data; default {ROBOT_ACCURACY[0]:g},{ROBOT_ACCURACY[1]:g}; 0,0 for an exact robot)")
    if "reprojection" in refines:  # a session with images
        g.add_argument("--strict-images", action="store_true",
                       help="fail (exit 2) on a missing or unreadable image instead of skipping it with the reason")
        g.add_argument("--robot-noise", metavar="DEG,MM",
                       help="robot pose error per axis (e.g. 0.05,0.2): the pixel refinement then corrects each robot "
                       "pose within it instead of taking the poses as exact")
        g.add_argument("--arm", metavar="NAME|TABLE.yaml|ROBOT.urdf",
                       help="the arm's kinematics for the session's joint angles (its joints: table), instead of the "
                       f"arm session.yaml names: a shipped arm ({', '.join(arm_names())}), a DH table or a URDF")
        g.add_argument("--compliance", action="store_true",
                       help="with joint angles: fit each joint's compliance with the arm's table (how far it gives way "
                       "per metre of the moment arm of the flange's load; gravity along the base's -z)")
        g.add_argument("--urdf", metavar="ROBOT.urdf", help="the arm's URDF for the session's joint angles (the same as "
                       "--arm ROBOT.urdf; the chain from the URDF's root to its last joint's link, or the session's "
                       "base_link/tip_link)")
    if "reprojection" in refines:  # a session folder: sensors other than cameras have unknowns beside X
        g.add_argument("--hold", metavar="NAME[,NAME]", action="append", default=[],
                       help="a sensor's unknowns beside X to hold at their nominal or given value (depth_scale, depth_bias, "
                       "radius, focal, cx, k1): by default each is fitted where the capture determines it")
        g.add_argument("--free", metavar="NAME[,NAME]", action="append", default=[],
                       help="a sensor's unknowns beside X to fit whatever the capture (a given ball's radius, ...)")
    g.add_argument("--strict", action="store_true",
                   help="fail (exit 2) instead of answering when the check calls the data inconsistent")
    g.add_argument("--no-check", action="store_true",
                   help="calibrate the poses as they are: no check of the data, no outlier removal (the API's check=False)")
    g.add_argument("--known", action="append", metavar="TRANSFORM.AXIS=METRES[+-STD]", default=[],
                   help="what the data cannot determine, given (SCARA and Cartesian robots): e.g. "
                   "--known target2base.z=0.012 (the board's height), --known cam2flange.z=0.085+-0.001 (from the "
                   "drawing); repeat for more")
    add_stream_options(p)


def add_detection_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--jobs", type=whole_arg(1), default=None, help="parallel detection workers (default: all cores)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--no-cache", action="store_true",
                   help="detect the target in every image again: neither read nor keep detections in the cache "
                   "(by default they are kept in the user's cache folder, or $HANDEYE_CACHE_DIR, keyed by each image "
                   "file's bytes, the target and the detector, so that a second run on the same images skips detection)")


def add_stream_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("streams (files with a time column: two clocks, paired by time)")
    g.add_argument("--keyframes", type=whole_arg(3), default=KEYFRAMES,
                   help=f"camera samples to calibrate on, well spread where the robot moves slowly (default {KEYFRAMES})")
    g.add_argument("--offset-range", metavar="LO,HI",
                   help="clock offsets to search, seconds, camera clock minus robot clock (default -1,1; around the "
                   "difference of the streams' middles when their stamps do not overlap)")
    g.add_argument("--time-offset", type=number_arg(-math.inf), metavar="SECONDS",
                   help="the clock offset when known (camera minus robot): no estimate")


def calibrate_options(args: argparse.Namespace) -> CalibrationOptions:
    """The calibration options of a command's arguments, as one checked record."""
    robot_noise = floats_arg(getattr(args, "robot_noise", None), "--robot-noise", (2,))
    rng = floats_arg(args.offset_range, "--offset-range", (2,))
    return CalibrationOptions(
        method=args.method, refine=args.refine, pairs=args.pairs, folds=args.folds, strict=args.strict,
        check=not args.no_check, robot_accuracy=accuracy_arg(args.robot_accuracy), known=known_arg(args.known),
        robot_noise=None if robot_noise is None else tuple(robot_noise.tolist()), keyframes=args.keyframes,
        offset_range=None if rng is None else tuple(rng.tolist()), time_offset=args.time_offset,
        strict_images=getattr(args, "strict_images", False), arm=arm_arg(args),
        compliance=getattr(args, "compliance", False), hold=_names_arg(getattr(args, "hold", [])),
        free=_names_arg(getattr(args, "free", [])))


def _names_arg(values: list[str]) -> tuple[str, ...]:
    """Names given as repeated and comma-separated flags (``--hold a,b --hold c``)."""
    return tuple(n.strip() for v in values for n in v.split(",") if n.strip())


def arm_arg(args: argparse.Namespace) -> str | None:
    """The arm of ``--arm`` or ``--urdf`` (one of them; ``--urdf`` takes a .urdf file only)."""
    arm, urdf = getattr(args, "arm", None), getattr(args, "urdf", None)
    if urdf is None:
        return arm
    if arm is not None:
        raise HandEyeError(f"--arm {arm} and --urdf {urdf}: give the arm's kinematics once")
    if not urdf.lower().endswith(".urdf"):
        raise HandEyeError(f"--urdf {urdf}: not a .urdf file; a DH table (.yaml) or a shipped arm's name goes to --arm")
    return urdf


def write_options(args: argparse.Namespace) -> dict:
    """write_calibration's options from the command's arguments."""
    return dict(parent_frame=args.parent_frame, child_frame=args.child_frame, exports=args.export,
                tool2flange=pose_arg(args.tool, "--tool") if args.tool else None)


def write_outputs(cal: Calibration, args: argparse.Namespace) -> None:
    """Write the result files and the report (never into ``cal.input_folder``: write_calibration)."""
    if args.out:
        for path in _report.write_calibration(cal, args.out, **write_options(args)):
            print(f"wrote {path}")
    else:
        print("no --out: nothing written (--out FOLDER writes result.json, result.yaml and report.html)")


def finish_poses(cal: Calibration, args: argparse.Namespace) -> int:
    if args.certify:
        cal = certify_calibration(cal)
    print_calibration(cal)
    write_outputs(cal, args)
    return verdict_status(cal)


def verdict_status(cal: Calibration) -> int:
    """Exit status of a calibration that answered, as ``check`` gives it on the same data
    (:data:`handeye.estimation.verdict.EXIT_STATUS`: 0 good or not checked, 1 weak or partial, 2 inconsistent;
    the result is written all the same)."""
    return exit_status(cal.verdict)
