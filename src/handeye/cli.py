"""The ``handeye`` command."""

from __future__ import annotations

import argparse
import difflib
import math
import sys
import time
from dataclasses import replace
from importlib.resources import files
from pathlib import Path
from typing import Sequence

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from . import solvers
from ._shared.io import check_output_folder
from ._version import __version__
from .acquire import SimWorld, acquire, capture_views, make_camera, make_robot
from .calibration import calibrate, certify_calibration
from .checking import calibrate_folder, calibrate_pairs, check_folder
from .fleet import calibrate_many
from .errors import HandEyeError
from .geometry.se3 import make_transform
from .planning import (ROBOTS, candidate_views, easy_handeye_poses, fronto_parallel_start, plan_poses, predicted_cov, reprojection_information,
                       simulate_errors, visible_mask, write_plan)
from .poses import ANGLE_UNITS, LENGTH_UNITS, pose_columns
from .printing import PAPERS, write_target
from .report import EXPORTS, write_calibration, write_verification
from .options import PAIRS, REFINES, REFINES_POSES, ROBOT_ACCURACY, CalibrationOptions
from .importers import import_easy_handeye, import_industrial_calibration, import_rosbag, import_visp
from .result import Calibration
from .session import POSE_KINDS, TIME_UNITS, load_pose_pairs, load_pose_streams, load_yaml, read_intrinsics
from .setups import SETUPS, flange_poses, predicted_target2cam, setup_info
from .simulate import DEFAULT_TARGETS, MIN_IMAGE_SIDE, simulate_session
from .streams import KEYFRAMES
from .verdict import exit_status
from .study import headline, preset, study, write_study
from .verification import NOT_THIS, verify
from .vision.targets import target_from_spec, target_origin

EXAMPLE_POSEPAIRS = "example_posepairs"
SAMPLE_SESSION = "sample_session"


def _whole(lo: int):
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


def _number(lo: float, hi: float = math.inf, above: bool = False):
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


def _image_size(text: str) -> tuple[int, int]:
    """argparse type: WIDTHxHEIGHT in pixels, each at least MIN_IMAGE_SIDE."""
    parts = text.lower().replace(" ", "").split("x")
    try:
        w, h = (int(v) for v in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give WIDTHxHEIGHT in pixels, e.g. 640x480") from None
    if min(w, h) < MIN_IMAGE_SIDE:
        raise argparse.ArgumentTypeError(f"{text}: each side must be at least {MIN_IMAGE_SIDE} px")
    return w, h


def _fmt_vec(v: np.ndarray, digits: int = 6) -> str:
    return "[" + ", ".join(f"{x: .{digits}f}" for x in v) + "]"


def _std_label(cal: Calibration) -> str:
    """What the std of X comes from, in words: the estimator and the parts it adds up."""
    who = cal.estimator or cal.method
    who = f"{who} refinement" if who in ("pose", "reprojection") else who
    parts = [k.replace("_", " ") for k, v in (cal.std_sources or {}).items() if v is not None]
    return who + (f": {' + '.join(parts)}" if parts else "")


def print_calibration(cal: Calibration, out=None) -> None:
    """Print X in the forms people paste into robot programs, and the residual summary."""
    info = setup_info(cal.setup)
    x_name, z_name = info.x_name, info.z_name
    rot = Rotation.from_matrix(cal.X[:3, :3])
    w = (out or sys.stdout).write
    d = cal.diagnostics
    if d is not None and d.verdict == "inconsistent":  # the fix first: X below is not a result to use
        w(f"INCONSISTENT DATA: {d.advice[0] if d.advice else 'the poses do not agree on one X'}\n"
          + "".join(f"  also: {a}\n" for a in d.advice[1:])
          + "X below is what the data give as declared, to compare after the fix; do not use it.\n\n")
    w(f"{cal.setup}: X = {x_name} (maps camera coordinates into the {info.x_parent} frame), method {cal.method}, "
      f"{len(cal.flange2base)} poses, {len(cal.pairs)} motions\n\n")
    with np.printoptions(precision=6, suppress=True, floatmode="fixed", sign=" "):
        w(f"{x_name} (4x4, metres):\n{cal.X}\n\n")
    w(f"translation      m : {_fmt_vec(cal.X[:3, 3])}\n")
    w(f"translation     mm : {_fmt_vec(1e3 * cal.X[:3, 3], 3)}\n")
    w(f"quaternion    wxyz : {_fmt_vec(rot.as_quat(canonical=True, scalar_first=True))}\n")
    w(f"rotation vec   rad : {_fmt_vec(rot.as_rotvec())}\n")
    w(f"rotation vec   deg : {_fmt_vec(rot.as_rotvec(degrees=True), 4)}\n\n")
    w(f"{z_name} translation mm : {_fmt_vec(1e3 * cal.Z[:3, 3], 3)}\n")
    if cal.std_Z is not None:
        w(f"std of {z_name}: rotation {_fmt_vec(cal.std_Z[:3], 4)} deg, translation {_fmt_vec(cal.std_Z[3:], 3)} mm\n")
    mres, pres = cal.motion_residuals, cal.pose_residuals
    share = 100 * cal.motion_pitch_share
    w(f"screw congruence per motion (|angle_A - angle_B|; |pitch_A - pitch_B| as a share of the motion's "
      f"translation; both 0 for consistent data): median {np.median(mres[:, 0]):.3f} deg / {np.median(share):.2f}%, "
      f"worst {mres[:, 0].max():.3f} deg / {share.max():.1f}%\n")
    worst = int(np.argmax(pres[:, 1]))
    w(f"{z_name} consistency per pose: median {np.median(pres[:, 0]):.3f} deg / {np.median(pres[:, 1]):.3f} mm, "
      f"worst {cal.pose_name(worst)}: {pres[worst, 0]:.3f} deg / {pres[worst, 1]:.3f} mm\n")
    if cal.std is not None:
        w(f"std of X ({_std_label(cal)}): rotation {_fmt_vec(cal.std[:3], 4)} deg, "
          f"translation {_fmt_vec(cal.std[3:], 3)} mm" + (" (inf: not determined by the data)"
                                                        if np.isinf(cal.std).any() else "") + "\n")
    else:  # a closed form alone (--refine none) has no noise model: say so rather than print nothing
        w(f"std of X: not computed ({cal.method} closed form alone; --refine auto or pose gives it)\n")
    for u in cal.unobservable:
        w(f"NOT DETERMINED: {u.parameter}; set to {u.choice}. {u.coupled[:1].upper() + u.coupled[1:]}. To fix: {u.fix}\n")
    for name, k in cal.known.items():
        w(f"known {name} = {k['value_m']:.5f} +- {k['std_m']:.5f} m: "
          + ("used (the data cannot determine it)\n" if k["used"] else f"not used (the data give {k['data_m']:.5f} m)\n"))
    if cal.time_offset is not None:
        w(f"clock offset (camera minus robot): {1e3 * cal.time_offset:.2f} +- {1e3 * cal.time_offset_std:.2f} ms "
          f"({len(cal.streams['keyframe_camera_times_s'])} keyframes of {cal.streams['camera_samples']} camera and "
          f"{cal.streams['robot_samples']} robot samples)\n")
    if cal.pose_noise is not None:
        nz = cal.pose_noise
        w(f"pose noise estimated from the data (per axis): robot rotation {nz['robot_rotation_deg']:.4f} deg, "
          f"camera rotation {nz['camera_rotation_deg']:.4f} deg, translation {nz['translation_mm']:.3f} mm\n")
    if cal.prediction_error is not None:
        pe = cal.prediction_error
        w(f"held-out prediction error ({cal.estimator}, cross-validated): "
          + (f"{pe['px']:.3f} px, " if pe.get("px") is not None else "") + f"{pe['mm']:.3f} mm at the target\n")
    if cal.diagnostics is not None:
        left, _ = cal.outliers_split()  # images: listed as skipped, and those put back in a note
        d = cal.diagnostics
        w(f"check: {d.verdict}" + (f"; left out as outliers: {d.pose_names(left)}" if left and not cal.image_names
                                   else "") + "\n")
    for note in cal.notes:
        w(f"note: {note}\n")


def _input_folder(given: str | None, bundled: bool, bundled_name: str, usage: str) -> Path:
    """The folder a command works on: the one given, or (flag set) the one bundled with handeye."""
    if bundled == (given is not None):
        raise HandEyeError(usage)
    if given is not None:
        return Path(given)
    folder = Path(str(files("handeye") / "data" / bundled_name))  # handeye installs as plain files
    print(f"bundled {bundled_name.replace('_', ' ')}: {folder}\n")
    return folder


def _out_folder(out: str | None, inputs: Sequence[Path] = ()) -> Path | None:
    """The --out folder of a command, checked before any work (see
    :func:`handeye._shared.io.check_output_folder`)."""
    if out is None:
        return None
    try:
        return check_output_folder(out, inputs)
    except HandEyeError as exc:
        raise HandEyeError(f"--out: {exc}") from None


def _write_outputs(cal: Calibration, args: argparse.Namespace) -> None:
    """Write the result files and the report (never into ``cal.input_folder``: write_calibration)."""
    if args.out:
        for path in write_calibration(cal, args.out, **_write_options(args)):
            print(f"wrote {path}")
    else:
        print("no --out: nothing written (--out FOLDER writes result.json, result.yaml and report.html)")


def _finish_poses(cal: Calibration, args: argparse.Namespace) -> int:
    if args.certify:
        cal = certify_calibration(cal)
    print_calibration(cal)
    _write_outputs(cal, args)
    return _verdict_status(cal)


def _cmd_calibrate_streams(args: argparse.Namespace) -> int:
    robot, camera = Path(args.robot), Path(args.camera)
    _out_folder(args.out, [robot.parent, camera.parent])
    rl, ra = _units_arg(args.robot_units, "--robot-units")
    cl, ca = _units_arg(args.camera_units, "--camera-units")
    pairs = load_pose_streams(
        {"file": str(robot), "format": args.robot_format, "length_unit": rl, "angle_unit": ra, "pose": args.robot_pose,
         "time_unit": args.time_unit},
        {"file": str(camera), "format": args.camera_format, "length_unit": cl, "angle_unit": ca,
         "pose": args.camera_pose, "time_unit": args.time_unit}, args.setup)
    return _finish_poses(calibrate_pairs(pairs, _calibrate_options(args)), args)


def _units_arg(text: str, name: str) -> tuple[str, str]:
    length, _, angle = text.partition(",")
    if length not in LENGTH_UNITS or angle not in ANGLE_UNITS:
        raise HandEyeError(f"{name} {text!r}: give LENGTH,ANGLE with LENGTH one of {', '.join(LENGTH_UNITS)} and ANGLE "
                           f"one of {', '.join(ANGLE_UNITS)}, e.g. m,rad or mm,deg")
    return length, angle


def _cmd_calibrate_poses(args: argparse.Namespace) -> int:
    folder = _input_folder(args.folder, args.example, EXAMPLE_POSEPAIRS,
                           "give a pose-pair folder, or --example for the bundled one (not both)")
    _out_folder(args.out, [folder])
    load_pose_pairs(folder)  # a folder without posepairs.yaml: its own error, not a session's
    return _finish_poses(calibrate_folder(folder, _calibrate_options(args), progress=not args.no_progress), args)


def _print_image_summary(cal: Calibration) -> None:
    n_used, n_skip = len(cal.image_names or []), len(cal.skipped)
    print(f"images: {n_used} used, {n_skip} skipped")
    for name, reason in cal.skipped:
        print(f"  skipped {name}: {reason}")
    if cal.intrinsics_source.startswith("estimated"):
        print(f"intrinsics: {cal.intrinsics_source} (camera calibration RMS {cal.intrinsics_rms:.3f} px)")
    else:
        print("intrinsics: from session.yaml")
    rms = cal.reprojection_rms
    worst = int(np.argmax(rms))
    print(f"PnP reprojection RMS per image: median {np.median(rms):.3f} px, worst {cal.image_names[worst]} {rms[worst]:.3f} px")
    if cal.refinement == "reprojection":
        print(f"refined X and Z on the pixel errors of all target points: RMS {cal.refined_rms:.3f} px")
    print()


def _calibrate_options(args: argparse.Namespace) -> CalibrationOptions:
    """The calibration options of a command's arguments, as one checked record."""
    robot_noise = _floats(getattr(args, "robot_noise", None), "--robot-noise", (2,))
    rng = _floats(args.offset_range, "--offset-range", (2,))
    return CalibrationOptions(
        method=args.method, refine=args.refine, pairs=args.pairs, folds=args.folds, strict=args.strict,
        check=not args.no_check, robot_accuracy=_accuracy_arg(args.robot_accuracy), known=_known_arg(args.known),
        robot_noise=None if robot_noise is None else tuple(robot_noise.tolist()), keyframes=args.keyframes,
        offset_range=None if rng is None else tuple(rng.tolist()), time_offset=args.time_offset,
        strict_images=getattr(args, "strict_images", False))


def _write_options(args: argparse.Namespace) -> dict:
    """write_calibration's options from the command's arguments."""
    return dict(parent_frame=args.parent_frame, child_frame=args.child_frame, exports=args.export,
                tool2flange=_pose_arg(args.tool, "--tool") if args.tool else None)


def _cmd_calibrate_many(args: argparse.Namespace) -> int:
    """calibrate with several session folders: each into --out/<name>/, on local processes or Dask."""
    if not args.out:
        raise HandEyeError("several sessions need --out: each session's files go into a folder of its own there")
    items = calibrate_many(args.session, args.out, scheduler=args.scheduler, jobs=args.jobs,
                           progress=not args.no_progress, certify=args.certify, write_options=_write_options(args),
                           options=_calibrate_options(args))
    status = 0
    print(f"{'session':<32} {'verdict':<13} {'X translation (mm)':<30} std (mm)")
    for it in items:
        if it.error is not None:
            print(f"{it.session:<32.32} {'FAILED':<13} {it.error}")
            status = 2
            continue
        std = "—" if it.std_mm is None else _fmt_vec(np.array(it.std_mm), 3)
        print(f"{it.session:<32.32} {it.verdict:<13} {_fmt_vec(np.array(it.translation_mm), 2):<30} {std}")
        status = max(status, exit_status(it.verdict))
    print(f"wrote {Path(args.out) / 'fleet.json'} and a folder per session")
    return status


def _cmd_calibrate(args: argparse.Namespace) -> int:
    if len(args.session) > 1:
        if args.sample:
            raise HandEyeError("give session folders or --sample, not both")
        return _cmd_calibrate_many(args)
    if args.scheduler:
        raise HandEyeError("--scheduler runs several sessions at once: give more than one session folder")
    session = _input_folder(args.session[0] if args.session else None, args.sample, SAMPLE_SESSION,
                            "give a session folder, or --sample for the bundled sample session (not both)")
    _out_folder(args.out, [session])
    cal = calibrate(session, _calibrate_options(args), jobs=args.jobs, progress=not args.no_progress)
    if args.certify:
        cal = certify_calibration(cal)
    _print_image_summary(cal)
    print_calibration(cal)
    _write_outputs(cal, args)
    return _verdict_status(cal)


def _verdict_status(cal: Calibration) -> int:
    """Exit status of a calibration that answered, as ``check`` gives it on the same data
    (:data:`handeye.verdict.EXIT_STATUS`: 0 good or not checked, 1 weak or partial, 2 inconsistent;
    the result is written all the same)."""
    return exit_status(cal.verdict)


def _cmd_check(args: argparse.Namespace) -> int:
    folder = _input_folder(args.folder, args.sample, SAMPLE_SESSION,
                           "give a session or pose-pair folder, or --sample (not both)")
    found = check_folder(folder, _calibrate_options(args), jobs=args.jobs, progress=not args.no_progress)
    for note in found.notes:
        print(f"note: {note}")
    for name, reason in found.skipped:
        print(f"skipped {name}: {reason}")
    print(found.diagnostics.pose_table())
    print()
    print(found.cross_validation_table())
    print()
    print(found.diagnostics.summary())
    if found.calibration is not None and found.calibration.std is not None:
        std = found.calibration.std
        print(f"std of X ({found.calibration.estimator}): {np.linalg.norm(std[:3]):.3f} deg / "
              f"{np.linalg.norm(std[3:]):.2f} mm (as calibrate reports it)")
    return found.exit_status


def _cmd_simulate(args: argparse.Namespace) -> int:
    _out_folder(args.out)
    simulate_session(args.out, setup=args.setup, n_poses=args.poses, target=args.target, noise_px=args.noise_px,
                     seed=args.seed, image_size=args.image_size, write_intrinsics=not args.no_intrinsics, robot=args.robot)
    print(f"wrote session {args.out} ({args.poses} {args.target} images, {args.setup}, {args.robot}); ground truth in "
          f"{Path(args.out) / 'ground_truth.yaml'}")
    return 0


def _cmd_study(args: argparse.Namespace) -> int:
    settings, figures = preset(args.preset, setup=args.setup)
    if args.figures:
        unknown = sorted(set(args.figures) - set(figures))
        if unknown:
            raise HandEyeError(f"unknown figure(s) {', '.join(unknown)} in preset {args.preset}; "
                               f"available: {', '.join(figures)}")
        wanted = set(args.figures)
        # a histogram figure needs the curve figure its data come from
        wanted |= {figures[f].source_figure for f in args.figures if figures[f].source_figure}
        settings = [s for s in settings if s.figure in wanted]
        figures = {k: v for k, v in figures.items() if k in wanted}
    out = _out_folder(args.out)
    start = time.perf_counter()
    result = study(settings, runs=args.runs, seed=args.seed, jobs=args.jobs, progress=not args.no_progress,
                   figures=figures, preset_name=args.preset, scheduler=args.scheduler)
    elapsed = time.perf_counter() - start
    print(headline(result))
    print()
    for path in write_study(result, out):
        print(f"wrote {path}")
    print(f"{len(settings)} settings x {args.runs} runs ({args.setup}, seed {args.seed}) in {elapsed:.1f} s")
    return 0


def _floats(text: str | None, name: str, sizes: tuple[int, ...]) -> np.ndarray | None:
    if text is None:
        return None
    try:
        v = np.array([float(t) for t in text.replace(" ", "").split(",")])
    except ValueError:
        raise HandEyeError(f"{name} {text!r}: give comma-separated numbers") from None
    if v.size not in sizes or not np.all(np.isfinite(v)):
        raise HandEyeError(f"{name} {text!r}: give {' or '.join(str(n) for n in sizes)} finite comma-separated numbers")
    return v


def _pose_arg(text: str | None, name: str, default_rot_deg=(0.0, 0.0, 0.0), required: bool = False) -> np.ndarray | None:
    """x,y,z[,rx,ry,rz]: metres and a rotation vector in degrees, as a 4x4."""
    v = _floats(text, name, (3, 6))
    if v is None:
        if required:
            raise HandEyeError(f"{name} is needed: x,y,z (m) and optionally rx,ry,rz (rotation vector, deg)")
        v = np.r_[0.0, 0.0, 0.0, default_rot_deg]
    rot = v[3:] if v.size == 6 else np.asarray(default_rot_deg, dtype=float)
    return make_transform(Rotation.from_rotvec(rot, degrees=True).as_matrix(), v[:3])


def _load_camera(path: str) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
    """K, dist and image size of ``--intrinsics`` (see :func:`handeye.session.read_intrinsics`)."""
    try:
        return read_intrinsics(path)
    except HandEyeError as exc:
        raise HandEyeError(f"--intrinsics {exc}") from None


def _placements(args: argparse.Namespace) -> tuple[np.ndarray, np.ndarray]:
    """Rough X and Z from --cam-in-flange / --target-in-base (eye-in-hand) or --camera-in-base /
    --target-in-flange (eye-to-hand)."""
    if setup_info(args.setup).camera_on_flange:
        if args.camera_in_base or args.target_in_flange:
            raise HandEyeError("--camera-in-base and --target-in-flange are for eye_to_hand; eye_in_hand takes "
                               "--target-in-base and --cam-in-flange")
        return (_pose_arg(args.cam_in_flange, "--cam-in-flange"),
                _pose_arg(args.target_in_base, "--target-in-base", (180.0, 0.0, 0.0), required=True))
    if args.target_in_base or args.cam_in_flange:
        raise HandEyeError("--target-in-base and --cam-in-flange are for eye_in_hand; eye_to_hand takes "
                           "--camera-in-base and --target-in-flange")
    return (_pose_arg(args.camera_in_base, "--camera-in-base", required=True),
            _pose_arg(args.target_in_flange, "--target-in-flange", (180.0, 0.0, 0.0)))


def _add_placements(p: argparse.ArgumentParser) -> None:
    p.add_argument("--target-in-base", metavar="X,Y,Z[,RX,RY,RZ]",
                   help="eye_in_hand: where the target lies (m); default rotation 180,0,0 = printed side up")
    p.add_argument("--cam-in-flange", metavar="X,Y,Z[,RX,RY,RZ]",
                   help="eye_in_hand: rough camera mounting (default: at the flange, looking along flange z)")
    p.add_argument("--camera-in-base", metavar="X,Y,Z,RX,RY,RZ", help="eye_to_hand: rough camera pose in the base frame")
    p.add_argument("--target-in-flange", metavar="X,Y,Z[,RX,RY,RZ]",
                   help="eye_to_hand: target on the flange (default 0,0,0 turned 180 deg about x: printed side outwards)")


def _cmd_acquire(args: argparse.Namespace) -> int:
    out = Path(args.out)
    results = Path(args.results) if args.results else out.with_name(out.name + "-results")
    _out_folder(str(results), [out])
    target_std = _floats(args.target_std, "--target-std", (2,))
    if args.robot == "sim":
        if args.camera != "sim":
            raise HandEyeError("--robot sim goes with --camera sim (the simulated cell)")
        world = SimWorld.default(args.setup, seed=args.seed)
        rough = make_transform(Rotation.from_rotvec(np.radians([1.5, -1.0, 1.0])).as_matrix(), [0.01, -0.008, 0.005])
        X0, Z0 = rough @ world.X, rough @ world.Z  # as from a drawing: ~1 cm and 2 deg off
        spec, (K, dist, size) = world.target_spec, (world.K, world.dist, world.image_size)
    else:
        world = None
        if not args.intrinsics:
            raise HandEyeError("--intrinsics is needed with a real camera (a YAML with K, dist, image_size)")
        K, dist, size = _load_camera(args.intrinsics)
        spec = _target_spec_arg(args.target_spec)
        if spec is None:
            raise HandEyeError("--target-spec is needed with a real camera (your session.yaml or a target: mapping)")
        X0, Z0 = _placements(args)
    rl, ra = _units_arg(args.robot_units, "--robot-units")
    robot = make_robot(args.robot, world, args.robot_format, rl, ra, speed=args.speed, yes=args.yes, dry_run=args.dry_run)
    camera = make_camera(args.camera, world, robot)
    acq = acquire(robot, camera, out, args.setup, spec, K, dist, size, X0, Z0,
                  target_std=tuple(target_std.tolist()) if target_std is not None else (0.05, 0.5),
                  max_poses=args.max_poses, min_poses=args.min_poses, standoff=args.standoff,
                  robot_accuracy=_accuracy_arg(args.robot_accuracy), settle_s=args.settle, progress=not args.no_progress)
    if acq.resumed_from:
        print(f"resumed a capture of {acq.resumed_from} views")
    print(f"{acq.n_views} views in {acq.folder}; stopped: {acq.stopped}")
    for s in acq.skipped:
        print(f"  skipped {s}")
    if acq.stopped == "interrupted" or acq.calibration is None:
        print(f"run the same command again to resume, or: handeye calibrate {acq.folder} --out RESULTS")
        return 1
    cal = replace(acq.calibration, notes=[f"captured by handeye acquire: {acq.n_views} views, stopped: {acq.stopped}"]
                  + list(acq.calibration.notes))
    print_calibration(cal)
    for path in write_calibration(cal, results):
        print(f"wrote {path}")
    status = _verdict_status(cal)
    if args.verify:
        status = max(status, _acquire_verify(args, robot, camera, out, results, spec, K, dist, size, cal))
    return status


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


def _cmd_plan(args: argparse.Namespace) -> int:
    pose_columns(args.format)  # a clear error for an unknown format before any work
    if args.length_unit not in ("m", "mm") or args.angle_unit not in ("deg", "rad"):
        raise HandEyeError("--length-unit must be m or mm, --angle-unit deg or rad")
    K, dist, size = _load_camera(args.intrinsics)
    if args.target_spec:
        p = Path(args.target_spec)
        spec = load_yaml(p).get("target")
        if not isinstance(spec, dict):
            raise HandEyeError(f"--target-spec {p}: no 'target:' mapping (as in session.yaml)")
    else:
        spec = DEFAULT_TARGETS[args.target]
    obj = target_from_spec(spec).object_points()
    X, Z = _placements(args)
    box = _floats(args.reach_box, "--reach-box", (6,))
    out = Path(args.out)
    if out.is_dir():
        raise HandEyeError(f"--out {out} is a folder; give the file to write, e.g. {out / 'poses.csv'}")
    if out.exists():
        raise HandEyeError(f"--out {out} exists (it may be a session's recorded poses); give a new file name")
    _out_folder(str(out.parent))  # a folder that can take the file, before the planning
    z_range = _floats(args.z_range, "--z-range", (2,))
    plan = plan_poses(args.setup, X, Z, obj, K, size, dist, n_poses=args.poses, standoff=args.standoff,
                      tilt_max_deg=args.tilt_max, margin_px=args.margin_px, reach_box=box, noise_px=args.noise_px,
                      robot=args.robot, z_range=None if z_range is None else tuple(z_range.tolist()),
                      robot_accuracy=_accuracy_arg(args.robot_accuracy))
    write_plan(plan, out, args.format, args.length_unit, args.angle_unit,
               protect=[p for p in (args.intrinsics, args.target_spec) if p])
    t2c = plan.target2cam
    print(f"{len(plan.flange2base)} poses chosen from {plan.n_candidates} views that keep the target "
          f"{args.margin_px:g} px inside the image; in path order:")
    print("  pose   flange x, y, z (mm)            flange rotation vector (deg)   view tilt (deg)  distance (mm)")
    centre = 0.5 * (obj.min(axis=0) + obj.max(axis=0))
    for k, (F, T) in enumerate(zip(plan.flange2base, t2c)):
        tilt = np.degrees(np.arccos(np.clip(T[2, 2], -1, 1)))  # optical axis vs the target normal
        rv = Rotation.from_matrix(F[:3, :3]).as_rotvec(degrees=True)
        print(f"  {k:3d}   {_fmt_vec(1e3 * F[:3, 3], 1):30s} {_fmt_vec(rv, 1):30s} {tilt:8.1f}        "
              f"{1e3 * np.linalg.norm(T[:3, :3] @ centre + T[:3, 3]):8.1f}")
    print(f"  (distance: camera to target centre; the views are spread over 0.8, 1 and 1.25 x --standoff "
          f"{1e3 * args.standoff:.0f} mm, as distance varies the depth the views see)")
    s, r = plan.std_X, plan.std_reported
    acc = plan.robot_accuracy
    print(f"\npredicted std of X as calibrate would report it: rotation {_fmt_vec(r[:3], 4)} deg, translation "
          f"{_fmt_vec(r[3:], 3)} mm")
    print(f"  from {plan.noise_px:g} px pixel noise (reprojection refinement): rotation {_fmt_vec(s[:3], 4)} deg, "
          f"translation {_fmt_vec(s[3:], 3)} mm"
          + (f"; plus the robot's absolute accuracy {acc[0]:g} deg / {acc[1]:g} mm per axis (--robot-accuracy), "
             "which no capture removes" if acc is not None else "; the robot taken as exact (--robot-accuracy 0,0)"))
    if plan.unobservable:
        info = setup_info(args.setup)
        print(f"warning: a {args.robot} robot cannot determine the {'; the '.join(plan.unobservable)} (std inf): "
              f"measure it, or {info.z_name}'s matching component (e.g. the target's height), and give it to the "
              f"calibration (--known {info.x_name}.z=METRES or --known {info.z_name}.z=METRES)"
              + ("; --check-runs is not simulated for it" if args.check_runs else ""))
    else:  # the comparison and the simulation are for arms that determine all of X
        _plan_comparison(plan, X, Z, obj, K, dist, size, args)
    print(f"\nwrote {out} ({args.format}, {args.length_unit}, {args.angle_unit}): flange2base per image; "
          "it is the poses.csv of the session to capture (replace each row by the pose the robot reports)")
    return 0


def _plan_comparison(plan, X, Z, obj, K, dist, size, args: argparse.Namespace) -> None:
    """easy_handeye's pattern at the same standoff for comparison and (``--check-runs``) simulated
    calibrations of the plan."""
    s = plan.std_X
    start = fronto_parallel_start(X, Z, obj, args.standoff, args.setup)
    eh = easy_handeye_poses(start)
    seen = visible_mask(predicted_target2cam(X, Z, eh, args.setup), obj, K, dist, size, 0.0)
    if seen.sum() >= 3:
        try:
            c = predicted_cov(reprojection_information(eh[seen], X, Z, args.setup, obj, K).sum(axis=0), plan.noise_px)
            print(f"for comparison, easy_handeye's 17-pose pattern from a straight-on view at the same standoff: "
                  f"{int(seen.sum())} of 17 poses see the whole target, translation std "
                  f"{_fmt_vec(1e3 * np.sqrt(np.diag(c)[3:]), 3)} mm")
        except np.linalg.LinAlgError:
            print(f"for comparison, easy_handeye's 17-pose pattern: only {int(seen.sum())} of 17 poses see the target "
                  "and they cannot determine X")
    else:
        print(f"for comparison, easy_handeye's 17-pose pattern: only {int(seen.sum())} of 17 poses see the whole target")
    if args.check_runs:
        err, _ = simulate_errors(plan.flange2base, X, Z, args.setup, obj, K, dist, size, plan.noise_px,
                                 args.check_runs, args.seed)
        rms = np.sqrt(np.mean(err**2, axis=0))
        print(f"simulated ({args.check_runs} runs: pixel noise, PnP, daniilidis, reprojection refinement): RMS error "
              f"of X {rms[0]:.4f} deg / {rms[1]:.3f} mm (predicted {np.linalg.norm(s[:3]):.4f} deg / "
              f"{np.linalg.norm(s[3:]):.3f} mm)")


def _known_arg(items: list[str]) -> dict[str, str]:
    """--known NAME=VALUE (repeatable) as the ``known=`` dict (calibrate_poses checks names and values)."""
    known = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name.strip() or not value.strip():
            raise HandEyeError(f"--known {item!r}: give TRANSFORM.AXIS=METRES, e.g. --known target2base.z=0.012")
        known[name.strip()] = value.strip()
    return known


def _accuracy_arg(text: str | None):
    """--robot-accuracy DEG,MM (calibrate checks the values); absent: handeye's default."""
    v = _floats(text, "--robot-accuracy", (2,))
    return ROBOT_ACCURACY if v is None else tuple(v.tolist())


def _add_out_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("-o", "--out", help="write result.json, result.yaml and report.html into this folder")
    p.add_argument("--parent-frame", help="ROS frame X is given in (default: tool0 for eye_in_hand, base_link for eye_to_hand)")
    p.add_argument("--child-frame", help="ROS frame of the camera (default: camera_optical_frame)")
    p.add_argument("--export", action="append", default=[], choices=list(EXPORTS) + ["all"],
                   help="with --out, also write: ros2-launch (a ROS 2 launch file publishing X), ros1-launch (the "
                   "ROS 1 launch file MoveIt Calibration writes), easy-handeye (easy_handeye2's .calib); repeat or all")
    p.add_argument("--tool", metavar="X,Y,Z[,RX,RY,RZ]",
                   help="your robot's tool (TCP) frame in the flange frame (m; rotation vector in deg): the result "
                   "files also give the camera (eye-in-hand) or the target (eye-to-hand) relative to the tool")
    p.add_argument("--certify", action="store_true",
                   help="certify whether X is the global minimum of the stated motion cost (a semidefinite relaxation; "
                   "needs pip install 'handeye[certifiable]')")


#: --refine's help per choice (the README's "auto" paragraph says how auto chooses)
_REFINE_HELP = {
    "auto": "auto (default): the estimator that predicts held-out views best (the pixel refinement while the robot's "
            "errors do not dominate its residuals, else the pose refinement, replaced only by a candidate better by "
            "more than one standard error)",
    "reprojection": "reprojection: X and Z on the pixel errors of all target points, robot poses exact",
    "pose": "pose: X and Z on the robot and camera poses, both noisy",
    "none": "none: the --method closed form alone (no std)",
}


def _add_calibrate_options(p: argparse.ArgumentParser, refines: tuple[str, ...] = REFINES) -> None:
    """The options of a calibration (:class:`handeye.CalibrationOptions`), defined once for every command
    that calibrates or judges data."""
    g = p.add_argument_group("calibration (the same in calibrate, calibrate-poses, calibrate-streams and check)")
    g.add_argument("--method", default="daniilidis", choices=solvers.available(), help="solver (default: daniilidis)")
    g.add_argument("--refine", default="auto", choices=list(refines),
                   help="; ".join(_REFINE_HELP[r] for r in refines))
    g.add_argument("--pairs", default="auto", choices=list(PAIRS),
                   help="which pose pairs form motions (auto: all up to 141 poses, else ~10,000 spread pairs)")
    g.add_argument("--folds", type=_whole(2), default=None,
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
    g.add_argument("--strict", action="store_true",
                   help="fail (exit 2) instead of answering when the check calls the data inconsistent")
    g.add_argument("--no-check", action="store_true",
                   help="calibrate the poses as they are: no check of the data, no outlier removal (the API's check=False)")
    g.add_argument("--known", action="append", metavar="TRANSFORM.AXIS=METRES[+-STD]", default=[],
                   help="what the data cannot determine, given (SCARA and Cartesian robots): e.g. "
                   "--known target2base.z=0.012 (the board's height), --known cam2flange.z=0.085+-0.001 (from the "
                   "drawing); repeat for more")
    _add_stream_options(p)


def _add_detection_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--jobs", type=_whole(1), default=None, help="parallel detection workers (default: all cores)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def _add_calibrate_poses(sub) -> None:
    p = sub.add_parser(
        "calibrate-poses",
        help="calibrate from robot poses and camera-to-target poses (a pose-pair folder)",
        description="Solve the hand-eye transform from a folder holding posepairs.yaml, the robot poses "
        "(flange2base) and the camera poses (target2cam).",
    )
    p.add_argument("folder", nargs="?", help="folder with posepairs.yaml")
    p.add_argument("--example", action="store_true", help="run on the bundled example folder")
    _add_out_options(p)
    _add_calibrate_options(p, REFINES_POSES)
    p.add_argument("--no-progress", action="store_true", help="no progress bar (shown from 200 poses)")
    p.set_defaults(func=_cmd_calibrate_poses)


def _add_stream_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("streams (files with a time column: two clocks, paired by time)")
    g.add_argument("--keyframes", type=_whole(3), default=KEYFRAMES,
                   help=f"camera samples to calibrate on, well spread where the robot moves slowly (default {KEYFRAMES})")
    g.add_argument("--offset-range", metavar="LO,HI",
                   help="clock offsets to search, seconds, camera clock minus robot clock (default -1,1; around the "
                   "difference of the streams' middles when their stamps do not overlap)")
    g.add_argument("--time-offset", type=_number(-math.inf), metavar="SECONDS",
                   help="the clock offset when known (camera minus robot): no estimate")


def _target_spec_arg(path: str | None) -> dict | None:
    """--target-spec FILE: the target: mapping of a YAML file (a session.yaml, or the mapping alone)."""
    if path is None:
        return None
    data = load_yaml(Path(path))
    spec = data.get("target", data)
    if not isinstance(spec, dict) or "type" not in spec:
        raise HandEyeError(f"--target-spec {path}: no target mapping (type, cols, rows, square, ... as in session.yaml)")
    target_from_spec(spec, where=f"--target-spec {path}")
    return spec


def _cmd_import(args: argparse.Namespace) -> int:
    if args.kind == "easy-handeye":
        summary = import_easy_handeye(args.source, args.out, setup=args.setup)
    elif args.kind == "visp":
        summary = import_visp(args.source, args.out, setup=args.setup or "eye_in_hand",
                              target=_target_spec_arg(args.target_spec))
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
                                camera_info_topic=args.camera_info_topic, target=_target_spec_arg(args.target_spec),
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


def _add_import(sub) -> None:
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
    p.add_argument("--every", type=_whole(1), default=1, help="keep every n-th image (default 1)")
    p.set_defaults(func=_cmd_import)


#: handeye target: per printable kind, the session.yaml type and the defaults (mm, counts, dictionary).
TARGET_KINDS = {
    "chessboard": ("chessboard", dict(cols=9, rows=6, square=20.0)),
    "charuco": ("charuco", dict(cols=7, rows=5, square=25.0, marker=18.0, dictionary="DICT_5X5_100")),
    "circles": ("circles", dict(cols=7, rows=6, square=20.0)),
    "asymmetric-circles": ("asymmetric_circles", dict(cols=4, rows=11, square=20.0)),
    "aruco-grid": ("aruco_grid", dict(cols=5, rows=7, square=25.0, separation=5.0, dictionary="DICT_5X5_100")),
    "apriltag-grid": ("aruco_grid", dict(cols=4, rows=5, square=35.0, separation=7.0, dictionary="DICT_APRILTAG_36h11")),
    "apriltag": ("apriltag", dict(square=100.0, dictionary="DICT_APRILTAG_36h11", id=0)),
}


def _cmd_target(args: argparse.Namespace) -> int:
    kind, defaults = TARGET_KINDS[args.type]
    given = {"cols": args.cols, "rows": args.rows, "square": args.square_mm, "marker": args.marker_mm,
             "separation": args.separation_mm, "dictionary": args.dictionary, "id": args.id}
    values = {k: given[k] if given[k] is not None else v for k, v in defaults.items()}
    unused = [f"--{k.replace('_', '-')}" + ("-mm" if k in ("square", "marker", "separation") else "")
              for k, v in given.items() if v is not None and k not in defaults]
    if unused:
        raise HandEyeError(f"{args.type} takes no {', '.join(unused)}")
    small = [(k, given[k]) for k in ("square", "marker") if given[k] is not None and given[k] < 1.0]
    if small:  # a side under 1 mm cannot be printed: metres given where millimetres are asked
        k, v = small[0]
        raise HandEyeError(f"--{k}-mm {v:g} looks like metres: the sizes are in millimetres here (--{k}-mm "
                           f"{v * 1e3:g} for {v:g} m)")
    spec = {"type": kind}
    for k, v in values.items():
        spec[k] = round(v / 1e3, 9) if k in ("square", "marker", "separation") else v
    if args.origin == "centre":
        spec["origin"] = "centre"
    path = write_target(spec, args.out, args.paper)
    print(f"wrote {path}: print it at 100% (no 'fit to page') and check the ruler measures 100 mm")
    print("for session.yaml:")
    print("  " + yaml.safe_dump({"target": spec}, sort_keys=False).replace("\n", "\n  ").rstrip())
    frame = target_from_spec(spec).frame
    if args.origin == "centre":
        centre = 1e3 * target_origin(spec)
        frame = (f"origin at the centre of the board, ({centre[0]:g}, {centre[1]:g}) mm in handeye's corner frame, whose "
                 f"axes it keeps ({frame})")
    print(f"target frame (Z and the target poses are given in it): {frame}")
    return 0


def _add_target(sub) -> None:
    p = sub.add_parser(
        "target",
        help="write a printable calibration target (PDF or SVG, true to scale) and its session.yaml block",
        description="A board to print, drawn as vector shapes at its true size (ChArUco and marker grids from "
        "OpenCV's own layout), with a 100 mm ruler to check the print and the target: block for session.yaml. "
        "Sizes in millimetres. cols/rows count: chessboard inner corners; charuco squares; circle grids circles "
        "(asymmetric: circles per row, rows); grids markers. Symmetric boards (chessboard, circles) can be read "
        "from either end: handeye resolves that from the robot motion, but a ChArUco board, a marker grid or an "
        "asymmetric circle grid removes the doubt.",
    )
    p.add_argument("--type", required=True, choices=list(TARGET_KINDS))
    p.add_argument("-o", "--out", required=True, help="board.pdf or board.svg")
    p.add_argument("--cols", type=_whole(1), help="see above (default per type: chessboard 9, charuco 7, ...)")
    p.add_argument("--rows", type=_whole(1), help="see above (default per type: chessboard 6, charuco 5, ...)")
    p.add_argument("--square-mm", type=_number(0.0, above=True),
                   help="square side (chessboard, charuco), circle spacing, marker side (grids) or tag side, mm")
    p.add_argument("--marker-mm", type=_number(0.0, above=True), help="charuco: marker side, mm")
    p.add_argument("--origin", choices=["corner", "centre"], default="corner",
                   help="where the target frame's origin is: corner (default: each type's first feature, see the README) "
                   "or centre (the board's centre, as ViSP and the AprilTag library put it); written to the target: block")
    p.add_argument("--separation-mm", type=_number(0.0, above=True), help="marker grids: gap between markers, mm")
    p.add_argument("--dictionary", help="charuco and marker grids: an OpenCV aruco dictionary (e.g. DICT_5X5_100)")
    p.add_argument("--id", type=_whole(0), help="apriltag: the tag id (default 0)")
    p.add_argument("--paper", default="A4", help=f"{', '.join(PAPERS)} or WIDTHxHEIGHT in mm (default A4; landscape "
                   "when the board needs it)")
    p.set_defaults(func=_cmd_target)


def _cmd_verify(args: argparse.Namespace) -> int:
    session = Path(args.session)
    _out_folder(args.out, [session])
    v = verify(args.result, session, jobs=args.jobs, progress=not args.no_progress)
    for name, reason in v.skipped:
        print(f"skipped {name}: {reason}")
    print(v.table())
    print()
    print(v.summary())
    if args.out:
        for path in write_verification(v, args.out):
            print(f"wrote {path}")
    return {"worse than promised": 1, NOT_THIS: 2}.get(v.verdict, 0)


def _add_verify(sub) -> None:
    p = sub.add_parser(
        "verify",
        help="check a calibration on a second capture: each view predicted from its robot pose",
        description="Predict where the target appears in every image of SESSION from its robot pose through the "
        "calibration in RESULT (a result folder, result.json or result.yaml), and compare with the detections: "
        "per view the RMS pixel error and the error in millimetres at the target. Exit 0 when the errors stay "
        "within 2x of what the calibration's own cross-validation promised, 1 when they do not, 2 when the views "
        "do not belong to this calibration or are its own images.",
    )
    p.add_argument("result", help="result folder, result.json or result.yaml written by handeye calibrate --out")
    p.add_argument("session", help="a session folder (images + robot poses) the calibration has not seen")
    p.add_argument("-o", "--out", help="write verify.json and verify.html into this folder")
    _add_detection_options(p)
    p.set_defaults(func=_cmd_verify)


def _add_acquire(sub) -> None:
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
    p.add_argument("--max-poses", type=_whole(3), default=20, help="at most this many views (default 20)")
    p.add_argument("--min-poses", type=_whole(3), default=6, help="at least this many views (default 6)")
    p.add_argument("--standoff", type=_number(0.0, above=True), default=0.5, help="camera-to-target distance (m, default 0.5)")
    p.add_argument("--settle", type=_number(0.0), default=0.0, help="seconds to wait after each move before the grab")
    p.add_argument("--verify", type=_whole(0), default=0, metavar="N",
                   help="then capture N more views at other poses and check the calibration on them (handeye verify)")
    p.add_argument("--intrinsics", help="real cameras: YAML with K, dist and image_size (a session.yaml will do)")
    p.add_argument("--target-spec", help="real cameras: YAML with the target: mapping")
    _add_placements(p)
    p.add_argument("--robot-format", default="euler:ZYX", help="manual: the format the robot reports its pose in")
    p.add_argument("--robot-units", default="mm,deg", metavar="LENGTH,ANGLE", help="manual: its units (default mm,deg)")
    p.add_argument("--robot-accuracy", metavar="DEG,MM", help="the robot's absolute accuracy (as calibrate)")
    p.add_argument("--speed", type=_number(0.0, above=True), default=0.1, help="ur: linear speed, m/s (capped at 0.25)")
    p.add_argument("--yes", action="store_true", help="ur: move without asking before each move")
    p.add_argument("--dry-run", action="store_true", help="ur: print the moves, do not make them")
    p.add_argument("--seed", type=_whole(0), default=0, help="sim: the simulated cell and its noise")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_acquire)


def _add_calibrate_streams(sub) -> None:
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
    p.add_argument("--robot-format", required=True, metavar="FORMAT",
                   help="pose columns of the robot file: matrix, quat_wxyz, quat_xyzw, rotvec or euler:SEQ")
    p.add_argument("--camera-format", required=True, metavar="FORMAT", help="pose columns of the camera file (as --robot-format)")
    p.add_argument("--robot-units", default="m,rad", metavar="LENGTH,ANGLE", help="units of the robot file (default m,rad)")
    p.add_argument("--camera-units", default="m,rad", metavar="LENGTH,ANGLE", help="units of the camera file (default m,rad)")
    p.add_argument("--robot-pose", default="flange2base", choices=list(POSE_KINDS["robot_poses"]),
                   help="what the robot rows are (default flange2base)")
    p.add_argument("--camera-pose", default="target2cam", choices=list(POSE_KINDS["camera_poses"]),
                   help="what the camera rows are (default target2cam, solvePnP's; cam2target for a camera pose in "
                   "the target frame)")
    p.add_argument("--time-unit", default="s", choices=list(TIME_UNITS), help="unit of both time columns (default s)")
    _add_out_options(p)
    _add_calibrate_options(p, REFINES_POSES)
    p.set_defaults(func=_cmd_calibrate_streams)


def _add_calibrate(sub) -> None:
    p = sub.add_parser(
        "calibrate",
        help="calibrate from a capture session (images + robot poses)",
        description="Detect the target in every image, estimate the camera poses and solve the hand-eye "
        "transform. SESSION holds session.yaml, poses.csv and images/ (see the README).",
    )
    p.add_argument("session", nargs="*", help="session folder; several calibrate each into --out/<name>/ (a fleet)")
    p.add_argument("--sample", action="store_true", help="run on the bundled sample session")
    p.add_argument("--scheduler", help="several sessions on Dask: 'local' (a LocalCluster of --jobs workers) or a "
                   "scheduler's address (pip install 'handeye[cluster]'); default local processes")
    _add_out_options(p)
    _add_calibrate_options(p)
    _add_detection_options(p)
    p.set_defaults(func=_cmd_calibrate)


def _add_check(sub) -> None:
    p = sub.add_parser(
        "check",
        help="check whether the data can give a good calibration (exit 0 good, 1 weak, 2 degenerate/inconsistent)",
        description="Observability, pose-convention mix-ups, outlier poses and leave-one-out stability of a "
        "capture session or a pose-pair folder, with advice. Exit status: 0 good, 1 weak, 2 degenerate or "
        "inconsistent (or bad input).",
    )
    p.add_argument("folder", nargs="?", help="session folder (session.yaml) or pose-pair folder (posepairs.yaml)")
    p.add_argument("--sample", action="store_true", help="check the bundled sample session")
    _add_detection_options(p)
    _add_calibrate_options(p)
    p.set_defaults(func=_cmd_check)


def _add_simulate(sub) -> None:
    p = sub.add_parser(
        "simulate",
        help="render a synthetic capture session with ground truth",
        description="Render target images seen from simulated robot poses and write a complete session "
        "with ground_truth.yaml (X, Z, K, dist).",
    )
    p.add_argument("-o", "--out", required=True, help="new session folder")
    p.add_argument("--setup", default="eye_in_hand", choices=list(SETUPS))
    p.add_argument("--poses", type=_whole(1), default=15, help="number of images (default 15)")
    p.add_argument("--target", default="charuco", choices=["chessboard", "charuco", "circles", "asymmetric_circles", "apriltag"],
                   help="the board rendered (default charuco: it cannot be read from the wrong end, as handeye's advice "
                   "recommends; chessboard for the thesis's set-up)")
    p.add_argument("--noise-px", type=_number(0.0), default=0.2, help="feature position noise in pixels (default 0.2)")
    p.add_argument("--seed", type=_whole(0), default=None)
    p.add_argument("--image-size", type=_image_size, default=(640, 480), help="WIDTHxHEIGHT (default 640x480)")
    p.add_argument("--no-intrinsics", action="store_true", help="leave K and dist out of session.yaml")
    p.add_argument("--robot", default="arm", choices=ROBOTS,
                   help="arm (default): views all around; scara: the flange turns about the vertical only; "
                   "cartesian: it only translates (both determine only part of X: see --known of calibrate)")
    p.set_defaults(func=_cmd_simulate)


def _add_plan(sub) -> None:
    p = sub.add_parser(
        "plan",
        help="plan robot poses for a good calibration and predict its accuracy",
        description="Choose N robot poses that keep the whole target in the image, minimise the predicted "
        "error of X (large rotations about spread axes) and make a short path; write them as a session "
        "poses.csv in your robot's pose format; print the predicted std of X. Lengths in metres, "
        "rotations as rotation vectors in degrees.",
    )
    p.add_argument("--setup", default="eye_in_hand", choices=list(SETUPS))
    p.add_argument("--intrinsics", required=True,
                   help="YAML with K, dist (optional) and image_size [width, height], top level or under camera:")
    p.add_argument("--target", default="chessboard", choices=["chessboard", "charuco", "circles", "asymmetric_circles", "apriltag"],
                   help="built-in target (the one 'handeye simulate' renders); see --target-spec")
    p.add_argument("--target-spec", help="YAML with a target: mapping as in session.yaml (e.g. your session.yaml)")
    _add_placements(p)
    p.add_argument("--standoff", type=_number(0.0, above=True), required=True,
                   help="camera-to-target distance (m) of the middle views; the plan spreads them over 0.8-1.25x it")
    p.add_argument("--tilt-max", type=_number(0.0, 89.0), default=45.0, help="largest view angle from the target normal (deg, default 45)")
    p.add_argument("--margin-px", type=_number(0.0), default=20.0, help="keep every target point this far inside the image")
    p.add_argument("--reach-box", metavar="XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX", help="where the flange may go (m, base frame)")
    p.add_argument("--robot", default="arm", choices=ROBOTS,
                   help="arm (default): views all around; scara: the flange points down and turns about the vertical "
                   "only; cartesian: it only translates (both leave part of X to --known at calibration)")
    p.add_argument("--z-range", metavar="ZMIN,ZMAX", help="heights the flange can reach (m, base frame; a SCARA's stroke)")
    p.add_argument("--poses", type=_whole(3), default=12, help="number of poses (default 12)")
    p.add_argument("--noise-px", type=_number(0.0, above=True), default=0.3, help="pixel noise for the predicted std (default 0.3)")
    p.add_argument("--robot-accuracy", metavar="DEG,MM",
                   help=f"the robot's absolute accuracy per axis, added to the predicted std as calibrate adds it "
                   f"(default {ROBOT_ACCURACY[0]:g},{ROBOT_ACCURACY[1]:g}; 0,0 for an exact robot)")
    p.add_argument("--check-runs", type=_whole(0), default=0, help="also simulate this many calibrations to check the prediction")
    p.add_argument("--seed", type=_whole(0), default=0)
    p.add_argument("-o", "--out", required=True, help="poses.csv to write")
    p.add_argument("--format", default="quat_wxyz", help="pose format: matrix, quat_wxyz, quat_xyzw, rotvec, euler:SEQ")
    p.add_argument("--length-unit", default="m", help="m or mm (default m)")
    p.add_argument("--angle-unit", default="deg", help="deg or rad for rotvec and euler (default deg)")
    p.set_defaults(func=_cmd_plan)


def _add_study(sub) -> None:
    p = sub.add_parser(
        "study",
        help="the Monte-Carlo study of the thesis's chapter 5 (every solver, any noise)",
        description="Simulate hand-eye captures with known X under a grid of noise levels and motion counts, "
        "run every solver on the same data and write study.csv, study.md, study.json and one PNG per figure.",
    )
    p.add_argument("--preset", default="seed-chapter5", help="study grid (default: seed-chapter5)")
    p.add_argument("-o", "--out", required=True, help="output folder (created; other files in it are left alone)")
    p.add_argument("--runs", type=_whole(1), default=200, help="simulations per setting (default 200, as the thesis)")
    p.add_argument("--seed", type=_whole(0), default=0, help="random seed: same seed, same numbers (default 0)")
    p.add_argument("--setup", default="eye_in_hand", choices=list(SETUPS))
    p.add_argument("--figures", nargs="+", metavar="ID", help="only these figures of the preset (e.g. 5.1 5.4)")
    p.add_argument("--jobs", type=_whole(1), default=None, help="worker processes (default: all cores)")
    p.add_argument("--scheduler", metavar="ADDRESS|local",
                   help="run on Dask distributed (pip install 'handeye[cluster]'): a scheduler's address, or 'local' "
                   "for a LocalCluster of --jobs workers; same seed, same numbers as without")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_study)


class _Parser(argparse.ArgumentParser):
    """argparse, with its errors on one line (the fault and where to read more) instead of the usage,
    and no abbreviations: ``--square 0.04`` is an error, not ``--square-mm 0.04`` (the subcommands'
    parsers are of this class too)."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="handeye",
        description="Hand-eye calibration of a camera against a robot arm.",
    )
    parser.add_argument("--version", action="version", version=f"handeye {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    _add_calibrate_poses(sub)
    _add_calibrate_streams(sub)
    _add_calibrate(sub)
    _add_check(sub)
    _add_verify(sub)
    _add_acquire(sub)
    _add_import(sub)
    _add_target(sub)
    _add_simulate(sub)
    _add_plan(sub)
    _add_study(sub)
    return parser


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))  # noqa: SLF001
    return dict(action.choices)


def _unknown_options(parser: argparse.ArgumentParser, argv: list[str], extras: list[str]) -> str:
    """One line for arguments no option takes: the sub-command's own usage, and for a mistyped option
    the nearest ones it has ("did you mean")."""
    subs = _subparsers(parser)
    command = next((a for a in argv if a in subs), None)
    target = subs.get(command, parser)
    options = [o for a in target._actions for o in a.option_strings if o.startswith("--")]  # noqa: SLF001
    hints = []
    for extra in extras:
        if extra.startswith("-"):
            near = difflib.get_close_matches(extra.split("=")[0], options, n=1, cutoff=0.6)
            hints.append(f"{extra}" + (f" (did you mean {' or '.join(near)}?)" if near else ""))
        else:
            hints.append(repr(extra))
    usage = " ".join(target.format_usage().split())
    return f"{target.prog}: error: unrecognized argument(s) {', '.join(hints)}; {usage[0].lower() + usage[1:]}"


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``handeye`` console script; returns the exit status."""
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    subs = _subparsers(parser)
    first = next((a for a in argv if not a.startswith("-")), None)
    if first is not None and first not in subs:
        near = difflib.get_close_matches(first, list(subs), n=1, cutoff=0.5)
        if near:
            print(f"handeye: error: unknown command {first!r}; did you mean {near[0]!r}? (see 'handeye --help')",
                  file=sys.stderr)
            return 2
    try:
        args, extras = parser.parse_known_args(argv)
    except SystemExit as exc:  # a bad option (status 2, the error printed), --help or --version (0)
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    if extras:
        print(_unknown_options(parser, argv, extras), file=sys.stderr)
        return 2
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
