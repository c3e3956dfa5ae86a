"""``handeye plan``: robot poses to capture, with the std they would give."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from .._shared.io import atomic_write
from ..errors import HandEyeError
from ..frames.poses import pose_columns
from ..frames.setups import SETUPS, predicted_target2cam, setup_info
from ..io.session import SESSION_FILE, load_yaml, write_pose_table
from ..options import ROBOT_ACCURACY, CalibrationOptions
from ..pipelines.folders import calibrate_session
from ..pipelines.kinds import PlanRequest, SensorKind, kind_named, sensor_kinds
from ..planning.joints import suggest_joint_views
from ..planning.poses import (
    ROBOTS,
    easy_handeye_poses,
    fronto_parallel_start,
    plan_poses,
    predicted_cov,
    reprojection_information,
    simulate_errors,
    visible_mask,
    write_plan,
)
from ..sensors.camera.targets import target_from_spec
from ..simulate import DEFAULT_TARGETS
from ._common import (
    accuracy_arg,
    add_kind_options,
    add_placements,
    board_target,
    chosen_kind,
    floats_arg,
    kind_options,
    load_camera,
    number_arg,
    out_folder,
    placements,
    target_choices,
    target_spec_arg,
    whole_arg,
)
from ._printing import fmt_vec, print_next_views


def _plan_next_views(args: argparse.Namespace) -> int:
    """--session: the next joint configurations of a joint session, so that the entries of the arm's
    table its capture left undetermined become determined, or X's std shrinks when it is mostly the
    table's (calibrate prints the same after its fit)."""
    session = Path(args.session)
    given = [name for name, value in (("--intrinsics", args.intrinsics), ("--standoff", args.standoff),
                                      ("--target-spec", args.target_spec), ("--reach-box", args.reach_box)) if value]
    if given:
        raise HandEyeError(f"{', '.join(given)} plan a new capture; --session takes the camera, target and arm from "
                           "the session: leave them out")
    out = _new_file(args.out)
    out_folder(str(out.parent), [session])
    if not (session / SESSION_FILE).is_file() or load_yaml(session / SESSION_FILE).get("joints") is None:
        raise HandEyeError(f"{session}: plan --session proposes the next joint configurations of a session with joint "
                           "angles (a joints: table in session.yaml); this one has none (robot poses only?): plan a new "
                           "capture with --intrinsics and --standoff instead")
    cal = calibrate_session(session, CalibrationOptions(), progress=True)
    views = suggest_joint_views(cal, n_views=args.poses or 5, rng=args.seed)
    if not len(views.joints):
        print("next views: none to propose: " + ("the capture determines every entry of the arm's table that views can "
                                                 "determine, and X's std is not mostly the table's" if not views.needed
                                                 else "no candidate configuration sees the whole target"))
        return 0
    text = print_next_views(cal, views)
    atomic_write(out, text, list(cal.image_paths or []))
    print(f"wrote {out}: capture these joint configurations (degrees), add them to {session}, and calibrate again")
    return 0


def _new_file(path: str) -> Path:
    out = Path(path)
    if out.is_dir():
        raise HandEyeError(f"--out {out} is a folder; give the file to write, e.g. {out / 'poses.csv'}")
    if out.exists():
        raise HandEyeError(f"--out {out} exists (it may be a session's recorded poses); give a new file name")
    return out


def _check_pose_format(args: argparse.Namespace) -> None:
    """--format, --length-unit and --angle-unit of the poses.csv to write, checked before any work."""
    pose_columns(args.format)
    if args.length_unit not in ("m", "mm") or args.angle_unit not in ("deg", "rad"):
        raise HandEyeError("--length-unit must be m or mm, --angle-unit deg or rad")


#: The options of a camera's plan, by flag and name in the parsed arguments: another kind's plan takes
#: those its registration names (``plan_takes``), and refuses the others given.
_CAMERA_OPTIONS = (("--intrinsics", "intrinsics"), ("--target-spec", "target_spec"), ("--standoff", "standoff"),
                   ("--session", "session"), ("--reach-box", "reach_box"), ("--z-range", "z_range"),
                   ("--check-runs", "check_runs"))


def _plan_kind(args: argparse.Namespace, kind: SensorKind) -> int:
    """--sensor of another kind than the camera: its registration's ``plan`` hook, its poses written
    as the poses.csv to capture and X's predicted std printed."""
    given = [flag for flag, name in _CAMERA_OPTIONS if getattr(args, name) and flag not in kind.plan_takes]
    given += [f"--robot {args.robot}"] if args.robot != "arm" else []
    if given:
        raise HandEyeError(f"{', '.join(given)}: a camera's; plan --sensor {kind.cli} takes {kind.plan_usage}")
    options = kind_options(args, "plan", kind)
    if args.target is not None and args.target not in kind.targets:
        board_target(args.target, "chessboard")  # another kind's target: named
    _check_pose_format(args)
    X, Z = placements(args, kind.plan_target_rotation)
    out = _new_file(args.out)
    out_folder(str(out.parent))
    plan = kind.hook("plan")(PlanRequest(args.setup, X, Z, args.poses, args.seed, args.target, target_spec_arg(args.target_spec),
                                         args.standoff, args.noise_px, accuracy_arg(args.robot_accuracy), options,
                                         args.intrinsics, args.tilt_max, args.margin_px))
    write_pose_table(out, plan.names, plan.flange2base, args.format, args.length_unit, args.angle_unit, id_column=plan.id_column)
    print(plan.heading)
    if plan.lines:  # its own std (a rig's: each camera's)
        _print_poses(plan.label, plan.names, plan.flange2base)
        print("\n".join(plan.lines))
    else:
        _print_plan(plan.label, plan.names, plan.flange2base, plan.plan, plan.accuracy, plan.per, plan.narrow, plan.undetermined,
                    plan.why)
    print(f"\nwrote {out} ({args.format}, {args.length_unit}, {args.angle_unit}): {plan.written}")
    return 0


def _print_poses(label: str, names: list[str], flange2base: np.ndarray) -> None:
    """A plan's flange poses by name (``label``: the names' column)."""
    print(f"  {label:10s}   flange x, y, z (mm)            flange rotation vector (deg)")
    for name, F in zip(names, flange2base):
        print(f"  {name:10s}   {fmt_vec(1e3 * F[:3, 3], 1):30s} {fmt_vec(Rotation.from_matrix(F[:3, :3]).as_rotvec(degrees=True), 1)}")


def _print_plan(label: str, names: list[str], flange2base: np.ndarray, plan, accuracy_words: str, per: str, narrow: str,
                undetermined: str, why: str) -> None:
    """A sensor plan's flange poses by name, then X's predicted std as calibrate would report it (the
    robot's accuracy in it: ``accuracy_words``), from the ``per`` alone, and for the ``narrow`` capture
    (``undetermined`` when it cannot determine X; ``why``: what the plan's spread buys)."""
    _print_poses(label, names, flange2base)
    s, d, n = plan.std_X, plan.std_data, plan.std_narrow
    acc = plan.robot_accuracy
    print(f"\npredicted std of X as calibrate would report it: rotation {fmt_vec(s[:3], 4)} deg, translation "
          f"{fmt_vec(s[3:], 3)} mm" + (f" (the robot's absolute accuracy {acc[0]:g} deg / {acc[1]:g} mm per axis in it, "
                                       f"{accuracy_words})" if acc is not None else ""))
    print(f"  from the {per} alone: rotation {fmt_vec(d[:3], 5)} deg, translation {fmt_vec(d[3:], 4)} mm")
    print(f"  {narrow}: " + (f"rotation {fmt_vec(n[:3], 5)} deg, translation {fmt_vec(n[3:], 4)} mm"
                             if np.all(np.isfinite(n)) else undetermined) + why)


def _cmd_plan(args: argparse.Namespace) -> int:
    if args.sensor != "camera":
        return _plan_kind(args, kind_named(args.sensor))
    chosen = chosen_kind(args, "plan")  # plan --rig-camera: a rig's plan, as before --sensor rig
    if chosen is not None:
        return _plan_kind(args, chosen)
    kind_options(args, "plan", None)  # another kind's options: refused, naming its --sensor
    if args.session:
        return _plan_next_views(args)
    args.target = board_target(args.target, "chessboard")
    if args.intrinsics is None or args.standoff is None:
        raise HandEyeError("plan needs --intrinsics and --standoff for a new capture (or --session SESSION for the next "
                           "views of a joint session)")
    _check_pose_format(args)
    K, dist, size = load_camera(args.intrinsics)
    if args.target_spec:
        p = Path(args.target_spec)
        spec = load_yaml(p).get("target")
        if not isinstance(spec, dict):
            raise HandEyeError(f"--target-spec {p}: no 'target:' mapping (as in session.yaml)")
    else:
        spec = DEFAULT_TARGETS[args.target]
    obj = target_from_spec(spec).object_points()
    X, Z = placements(args)
    box = floats_arg(args.reach_box, "--reach-box", (6,))
    out = _new_file(args.out)
    out_folder(str(out.parent))  # a folder that can take the file, before the planning
    z_range = floats_arg(args.z_range, "--z-range", (2,))
    plan = plan_poses(args.setup, X, Z, obj, K, size, dist, n_poses=args.poses or 12, standoff=args.standoff,
                      tilt_max_deg=args.tilt_max, margin_px=args.margin_px, reach_box=box, noise_px=args.noise_px,
                      robot=args.robot, z_range=None if z_range is None else tuple(z_range.tolist()),
                      robot_accuracy=accuracy_arg(args.robot_accuracy))
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
        print(f"  {k:3d}   {fmt_vec(1e3 * F[:3, 3], 1):30s} {fmt_vec(rv, 1):30s} {tilt:8.1f}        "
              f"{1e3 * np.linalg.norm(T[:3, :3] @ centre + T[:3, 3]):8.1f}")
    print(f"  (distance: camera to target centre; the views are spread over 0.8, 1 and 1.25 x --standoff "
          f"{1e3 * args.standoff:.0f} mm, as distance varies the depth the views see)")
    s, r = plan.std_X, plan.std_reported
    acc = plan.robot_accuracy
    print(f"\npredicted std of X as calibrate would report it: rotation {fmt_vec(r[:3], 4)} deg, translation "
          f"{fmt_vec(r[3:], 3)} mm")
    print(f"  from {plan.noise_px:g} px pixel noise (reprojection refinement): rotation {fmt_vec(s[:3], 4)} deg, "
          f"translation {fmt_vec(s[3:], 3)} mm"
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
                  f"{fmt_vec(1e3 * np.sqrt(np.diag(c)[3:]), 3)} mm")
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


def register(sub) -> None:
    """Add the ``plan`` command's parser to the sub-parsers ``sub``."""
    p = sub.add_parser(
        "plan",
        help="plan robot poses for a good calibration and predict its accuracy",
        description="Choose N robot poses that keep the whole target in the image, minimise the predicted "
        "error of X (large rotations about spread axes) and make a short path; write them as a session "
        "poses.csv in your robot's pose format; print the predicted std of X. Lengths in metres, "
        "rotations as rotation vectors in degrees.",
    )
    p.add_argument("--setup", default="eye_in_hand", choices=list(SETUPS))
    p.add_argument("--intrinsics",
                   help="YAML with K, dist (optional) and image_size [width, height], top level or under camera:")
    kinds = [k for k in sensor_kinds() if k.plan]
    p.add_argument("--sensor", default="camera", choices=["camera"] + [k.cli for k in kinds],
                   help="camera (default): views of a board; " + "; ".join(f"{k.cli}: {k.plan_help}" for k in kinds))
    add_kind_options(p, "plan")
    own = "; ".join(f"with --sensor {k.cli}: {', '.join(k.targets)} ({k.targets[0]} the default)" for k in kinds if k.targets)
    p.add_argument("--target", default=None, choices=target_choices(DEFAULT_TARGETS, "plan"),
                   help="built-in target (the one 'handeye simulate' renders; default chessboard); see --target-spec; "
                   + own)
    p.add_argument("--target-spec", help="YAML with a target: mapping as in session.yaml (e.g. your session.yaml)")
    add_placements(p)
    p.add_argument("--standoff", type=number_arg(0.0, above=True),
                   help="camera-to-target distance (m) of the middle views; the plan spreads them over 0.8-1.25x it "
                   "(another --sensor's plan says its own spread, if it takes it)")
    p.add_argument("--tilt-max", type=number_arg(0.0, 89.0), default=45.0,
                   help="largest view angle from the target normal (deg, default 45)")
    p.add_argument("--margin-px", type=number_arg(0.0), default=20.0, help="keep every target point this far inside the image")
    p.add_argument("--reach-box", metavar="XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX", help="where the flange may go (m, base frame)")
    p.add_argument("--robot", default="arm", choices=ROBOTS,
                   help="arm (default): views all around; scara: the flange points down and turns about the vertical "
                   "only; cartesian: it only translates (both leave part of X to --known at calibration)")
    p.add_argument("--z-range", metavar="ZMIN,ZMAX", help="heights the flange can reach (m, base frame; a SCARA's stroke)")
    p.add_argument("--poses", type=whole_arg(3), default=None,
                   help="number of poses (default 12; with --session, of next views: default 5)")
    p.add_argument("--session", help="a joint session already captured: propose the next joint configurations that "
                   "determine the entries of the arm's table it left undetermined (written to --out as CSV, degrees)")
    p.add_argument("--noise-px", type=number_arg(0.0, above=True), default=0.3, help="pixel noise for the predicted std (default 0.3)")
    p.add_argument("--robot-accuracy", metavar="DEG,MM",
                   help=f"the robot's absolute accuracy per axis, added to the predicted std as calibrate adds it "
                   f"(default {ROBOT_ACCURACY[0]:g},{ROBOT_ACCURACY[1]:g}; 0,0 for an exact robot)")
    p.add_argument("--check-runs", type=whole_arg(0), default=0, help="also simulate this many calibrations to check the prediction")
    p.add_argument("--seed", type=whole_arg(0), default=0)
    p.add_argument("-o", "--out", required=True, help="poses.csv to write")
    p.add_argument("--format", default="quat_wxyz", help="pose format: matrix, quat_wxyz, quat_xyzw, rotvec, euler:SEQ")
    p.add_argument("--length-unit", default="m", help="m or mm (default m)")
    p.add_argument("--angle-unit", default="deg", help="deg or rad for rotvec and euler (default deg)")
    p.set_defaults(func=_cmd_plan)
