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
from ..planning.joints import suggest_joint_views
from ..planning.laser import NARROW_DEG, assumed_shape, plan_laser
from ..planning.linescan import NARROW_DEG as LINESCAN_NARROW_DEG
from ..planning.linescan import plan_linescan
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
from ..planning.rig import RigPlanCamera, plan_rig
from ..sensors.camera.targets import target_from_spec
from ..simulate import DEFAULT_TARGETS
from ..simulate.laser import TARGETS as LASER_TARGETS
from ._common import (
    accuracy_arg,
    add_placements,
    floats_arg,
    load_camera,
    number_arg,
    out_folder,
    placements,
    pose_arg,
    sensor_target,
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


def _plan_laser(args: argparse.Namespace) -> int:
    """--sensor laser_line: flange poses around a ball (over a plate, across an edge or a step, around a
    fixture's balls) for a laser profiler, and the std they would give, beside the same number of
    profiles turned at most NARROW_DEG."""
    given = [name for name, value in (("--intrinsics", args.intrinsics), ("--standoff", args.standoff),
                                      ("--target-spec", args.target_spec), ("--session", args.session)) if value]
    if given:
        raise HandEyeError(f"{', '.join(given)}: a camera's; plan --sensor laser_line takes the profiler's placement "
                           f"(--cam-in-flange or --camera-in-base), the target's and --target {'|'.join(LASER_TARGETS)}")
    target = sensor_target(args.sensor, args.target, "chessboard")
    if target != "sphere" and args.diameter is not None:
        raise HandEyeError(f"--diameter is a ball's; --target {target} has none"
                           + (" (the plan's fixture is the simulator's: see its output)" if target == "spheres" else "")
                           + ": leave it out")
    diameter = 0.04 if args.diameter is None else args.diameter
    _check_pose_format(args)
    if setup_info(args.setup).camera_on_flange and not args.camera_in_base and not args.target_in_flange:
        # the target's +z is the side the profiler looks from: a ball on a table is seen from above
        X = pose_arg(args.cam_in_flange, "--cam-in-flange")
        Z = pose_arg(args.target_in_base, "--target-in-base", (0.0, 0.0, 0.0), required=True)
    else:
        X, Z = placements(args)
    out = _new_file(args.out)
    out_folder(str(out.parent))
    plan = plan_laser(args.setup, X, Z, n_poses=args.poses or 20, target=target, radius=diameter / 2,
                      robot_accuracy=accuracy_arg(args.robot_accuracy), rng=args.seed)
    names = [f"p{k + 1:02d}.csv" for k in range(len(plan.flange2base))]
    write_pose_table(out, names, plan.flange2base, args.format, args.length_unit, args.angle_unit, id_column="profile")
    axis = "its faces' bisector" if target == "edge" else "the target frame's +z"
    print(f"{len(plan.flange2base)} profiles of {assumed_shape(target)}, the profiler within {plan.cone_deg:g} deg of "
          f"{axis}, turned about its view direction, in path order:")
    _print_plan("profile", names, plan.flange2base, plan, "which no capture removes", "profiles",
                f"the same number of profiles with the flange turned at most {NARROW_DEG:g} deg",
                "X is not determined (profiles at nearly one orientation only slide along a plate, an edge or a step)",
                " (turns between profiles place X's translation; " + _LEVER[target] + ")")
    print(f"\nwrote {out} ({args.format}, {args.length_unit}, {args.angle_unit}): flange2base per profile; it is the "
          "poses.csv of the laser session to capture (replace each row by the pose the robot reports)")
    return 0


def _plan_linescan(args: argparse.Namespace) -> int:
    """--sensor line_scan: straight scans across a chessboard for a line-scan camera, and the std they
    would give, beside the same number of scans at one distance turned at most LINESCAN_NARROW_DEG."""
    given = [name for name, value in (("--intrinsics", args.intrinsics), ("--session", args.session),
                                      ("--rig-camera", args.rig_camera), ("--diameter", args.diameter),
                                      ("--reach-box", args.reach_box), ("--z-range", args.z_range)) if value]
    if given or args.robot != "arm":
        raise HandEyeError(f"{', '.join(given) or '--robot ' + args.robot}: not for a line-scan plan; it takes the camera "
                           "(--line-camera WIDTH,FOCAL), its placement (--cam-in-flange or --camera-in-base), the target's, "
                           "--target or --target-spec, --standoff and --speed")
    spec = target_spec_arg(args.target_spec)
    points = None
    if spec is not None or args.target is not None:  # else the simulator's chessboard
        points = target_from_spec(spec or DEFAULT_TARGETS[sensor_target("camera", args.target, "chessboard")]).object_points()
    camera = floats_arg(args.line_camera, "--line-camera", (2,))
    width, focal = (None, None) if camera is None else (int(camera[0]), float(camera[1]))
    _check_pose_format(args)
    X, Z = placements(args)
    out = _new_file(args.out)
    out_folder(str(out.parent))
    plan = plan_linescan(args.setup, X, Z, n_scans=args.poses or 12, points=points, focal=focal, width=width,
                         distance=args.standoff or 0.4, speed=args.speed, noise_px=args.noise_px,
                         robot_accuracy=accuracy_arg(args.robot_accuracy), rng=args.seed)
    names = [f"s{k + 1:02d}.{end}" for k in range(len(plan.moves)) for end in ("start", "end")]
    write_pose_table(out, names, plan.moves.reshape(-1, 4, 4), args.format, args.length_unit, args.angle_unit,
                     id_column="scan")
    print(f"{len(plan.moves)} straight scans across the board at {plan.speed:g} m/s, forth and back in turn, the camera "
          f"within {plan.cone_deg:g} deg of the board's normal at {0.75 * plan.distance:.2f}-{1.25 * plan.distance:.2f} m "
          f"(line rate {plan.line_rate:.0f} rows/s for square pixels); each scan's start and end:")
    _print_plan("scan", names, plan.moves.reshape(-1, 4, 4), plan, "each scan's pose error fitted with it", "scans",
                f"the same number of scans at one distance, turned at most {LINESCAN_NARROW_DEG:g} deg",
                "X is not determined", " (turns between scans place X; distances tell the focal length from the distance)")
    print(f"\nwrote {out} ({args.format}, {args.length_unit}, {args.angle_unit}): per scan the flange's pose where its "
          "straight move starts and where it ends; record the robot's trajectory (with times) and each scan's start time "
          "for the line-scan session (docs/guide.md, 'Line-scan cameras')")
    return 0


def _print_plan(label: str, names: list[str], flange2base: np.ndarray, plan, accuracy_words: str, per: str, narrow: str,
                undetermined: str, why: str) -> None:
    """A sensor plan's flange poses by name, then X's predicted std as calibrate would report it (the
    robot's accuracy in it: ``accuracy_words``), from the ``per`` alone, and for the ``narrow`` capture
    (``undetermined`` when it cannot determine X; ``why``: what the plan's spread buys)."""
    print(f"  {label:10s}   flange x, y, z (mm)            flange rotation vector (deg)")
    for name, F in zip(names, flange2base):
        print(f"  {name:10s}   {fmt_vec(1e3 * F[:3, 3], 1):30s} {fmt_vec(Rotation.from_matrix(F[:3, :3]).as_rotvec(degrees=True), 1)}")
    s, d, n = plan.std_X, plan.std_data, plan.std_narrow
    acc = plan.robot_accuracy
    print(f"\npredicted std of X as calibrate would report it: rotation {fmt_vec(s[:3], 4)} deg, translation "
          f"{fmt_vec(s[3:], 3)} mm" + (f" (the robot's absolute accuracy {acc[0]:g} deg / {acc[1]:g} mm per axis in it, "
                                       f"{accuracy_words})" if acc is not None else ""))
    print(f"  from the {per} alone: rotation {fmt_vec(d[:3], 5)} deg, translation {fmt_vec(d[3:], 4)} mm")
    print(f"  {narrow}: " + (f"rotation {fmt_vec(n[:3], 5)} deg, translation {fmt_vec(n[3:], 4)} mm"
                             if np.all(np.isfinite(n)) else undetermined) + why)


#: What places X's rotation, per laser target (the plan's last line).
_LEVER = {"sphere": "the ball's centre across the laser plane, its rotation",
          "spheres": "the balls' centres across the laser plane, its rotation",
          "plane": "the plate's tilt in each profile, its rotation",
          "edge": "the faces' tilts and the edge's crossing point in each profile, its rotation",
          "step": "the levels' tilt and the riser's crossing point in each profile, its rotation"}


def _rig_cameras(args: argparse.Namespace, K: np.ndarray, dist: np.ndarray, size: tuple[int, int]) -> list[RigPlanCamera]:
    """The first camera (--intrinsics) and each --rig-camera NAME,INTRINSICS,X,Y,Z[,RX,RY,RZ] (its pose
    in the first camera's frame: metres and a rotation vector in degrees)."""
    cameras = [RigPlanCamera("cam0", np.eye(4), K, size, dist)]
    for text in args.rig_camera:
        parts = text.split(",")
        if len(parts) not in (5, 8) or not parts[0] or not parts[1]:
            raise HandEyeError(f"--rig-camera {text!r}: give NAME,INTRINSICS,X,Y,Z[,RX,RY,RZ]: the camera's name, its "
                               "intrinsics YAML and its pose in the first camera's frame (m; rotation vector, deg)")
        if parts[0] in [c.name for c in cameras]:
            raise HandEyeError(f"--rig-camera {text!r}: the name {parts[0]!r} is taken (the first camera is cam0): each "
                               "camera needs its own name")
        K_k, dist_k, size_k = load_camera(parts[1])
        cameras.append(RigPlanCamera(parts[0], pose_arg(",".join(parts[2:]), f"--rig-camera {parts[0]}"), K_k, size_k,
                                     dist_k))
    return cameras


def _plan_rig(args: argparse.Namespace, obj: np.ndarray, K: np.ndarray, dist: np.ndarray, size: tuple[int, int]) -> int:
    """--rig-camera: poses in which every camera of the rig sees the whole target, and each one's std."""
    if args.robot != "arm" or args.reach_box or args.z_range or args.check_runs:
        raise HandEyeError("--rig-camera plans a 6-axis arm's poses for a rig; leave --robot, --reach-box, --z-range and "
                           "--check-runs out")
    X, Z = placements(args)
    out = _new_file(args.out)
    out_folder(str(out.parent))
    plan = plan_rig(args.setup, X, Z, obj, _rig_cameras(args, K, dist, size), n_poses=args.poses or 15,
                    standoff=args.standoff, tilt_max_deg=args.tilt_max, margin_px=args.margin_px, noise_px=args.noise_px,
                    robot_accuracy=accuracy_arg(args.robot_accuracy))
    names = [f"v{k + 1:02d}" for k in range(len(plan.flange2base))]
    write_pose_table(out, names, plan.flange2base, args.format, args.length_unit, args.angle_unit, id_column="view",
                     protect=[p for p in [args.intrinsics, args.target_spec] + [t.split(",")[1] for t in args.rig_camera] if p])
    print(f"{len(names)} poses chosen from {plan.n_candidates} in which every camera ({', '.join(plan.names)}) keeps the "
          f"whole target {args.margin_px:g} px inside its image; in path order:")
    print("  view   flange x, y, z (mm)            flange rotation vector (deg)")
    for name, F in zip(names, plan.flange2base):
        print(f"  {name:5s}  {fmt_vec(1e3 * F[:3, 3], 1):30s} {fmt_vec(Rotation.from_matrix(F[:3, :3]).as_rotvec(degrees=True), 1)}")
    acc = plan.robot_accuracy
    print(f"\npredicted std of each camera's X as the rig's calibration would report it ({plan.noise_px:g} px of corner "
          "noise" + (f", the robot's absolute accuracy {acc[0]:g} deg / {acc[1]:g} mm per axis in it" if acc else "")
          + "):")
    for name, s in plan.std_per_camera.items():
        print(f"  {name:8s} rotation {fmt_vec(s[:3], 4)} deg, translation {fmt_vec(s[3:], 3)} mm")
    print(f"\nwrote {out} ({args.format}, {args.length_unit}, {args.angle_unit}): flange2base per view; it is the "
          "poses.csv of the rig session to capture (first column view; replace each row by the pose the robot reports)")
    return 0


def _cmd_plan(args: argparse.Namespace) -> int:
    if args.sensor == "line_scan":
        return _plan_linescan(args)
    if args.line_camera is not None:
        raise HandEyeError("--line-camera is a line-scan camera's: add --sensor line_scan, or leave it out")
    if args.sensor == "laser_line":
        if args.rig_camera:
            raise HandEyeError("--rig-camera plans for a rig of cameras; leave it out with --sensor laser_line")
        return _plan_laser(args)
    if args.diameter is not None:
        raise HandEyeError("--diameter is a laser target's (a ball's): add --sensor laser_line, or leave it out")
    if args.session:
        return _plan_next_views(args)
    args.target = sensor_target(args.sensor, args.target, "chessboard")
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
    if args.rig_camera:
        return _plan_rig(args, obj, K, dist, size)
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
    p.add_argument("--sensor", default="camera", choices=["camera", "laser_line", "line_scan"],
                   help="camera (default): views of a board; laser_line: a laser line profiler's profiles of a ball "
                   "(--diameter), a plate, a block's edge, a step or a fixture of balls (--target); --target-in-base "
                   "is then the ball's centre (a point of the plate, of the edge's line, the first ball's centre), its "
                   "rotation by default 0,0,0: the profiler looks from above; line_scan: a line-scan camera's straight "
                   "scans across a chessboard (--line-camera, --standoff, --speed)")
    p.add_argument("--line-camera", metavar="WIDTH,FOCAL",
                   help="--sensor line_scan: pixels along the line and the focal length in pixels (default 2048,2400)")
    p.add_argument("--speed", type=number_arg(0.0, above=True), default=0.2,
                   help="--sensor line_scan: the scans' speed (m/s, default 0.2)")
    p.add_argument("--target", default=None, choices=list(DEFAULT_TARGETS) + list(LASER_TARGETS),
                   help="built-in target (the one 'handeye simulate' renders; default chessboard); see --target-spec; "
                   "with --sensor laser_line: sphere (default), plane, edge, step or spheres")
    p.add_argument("--diameter", type=number_arg(0.0, 1.0, above=True), default=None,
                   help="--sensor laser_line: the ball's diameter (m, default 0.04)")
    p.add_argument("--target-spec", help="YAML with a target: mapping as in session.yaml (e.g. your session.yaml)")
    add_placements(p)
    p.add_argument("--standoff", type=number_arg(0.0, above=True),
                   help="camera-to-target distance (m) of the middle views; the plan spreads them over 0.8-1.25x it "
                   "(--sensor line_scan: 0.75-1.25x, default 0.4)")
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
    p.add_argument("--rig-camera", action="append", default=[], metavar="NAME,INTRINSICS,X,Y,Z[,RX,RY,RZ]",
                   help="plan for a rig: another camera, its intrinsics YAML and its rough pose in the first camera's "
                   "(--intrinsics, named cam0) frame (m; rotation vector, deg); repeat for each; the poses are those "
                   "every camera can use (written with a first column view, as a rig session's poses.csv)")
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
