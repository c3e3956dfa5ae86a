"""Robot kinematics in the loop: X from joint angles with the arm's table as unknowns, against the
black-box calibration on the nominal chain's flange poses (handeye's default and OpenCV's methods).

Each session is :func:`handeye.simulate.kinematic_scene`: a UR5 or a Franka Panda whose real DH /
MDH table differs from the nominal one (lengths 0.5 mm, angles 0.05 deg per entry: 1-3 mm of
absolute error at the flange), 2x the views asked for (half calibrate, half are held out), pixel
detections with 0.2 px of noise and PnP poses. Per arm, setup and number of views it prints:

* X's error (median, and the share within 0.3 mm / 0.05 deg) of handeye's default black-box
  calibration, of the best of OpenCV's 5 methods on the same poses, and of the kinematic
  calibration (:func:`handeye.calibrate_joints`);
* the share of sessions whose X lies within 3 of the kinematic calibration's reported std;
* the robot's absolute error seen from the camera on the held-out joint configurations (where the
  target's origin is predicted against where it is), before (black-box X, Z and the nominal chain)
  and after (the kinematic X, Z and the corrected chain), and the ratio.

With ``--compliance DEG_PER_M`` the simulated arm's joints also give way under the flange's load
(0.5-1.5x that per metre of moment arm), and a row "handeye kinematic+compliance" fits it
(``compliance=True``) beside the rigid kinematic fit.

With ``--planned N``, after the kinematic fit the N views
:func:`handeye.planning.joints.suggest_joint_views` proposes (for undetermined entries, or for X when
the joints moved too little) are captured by the true arm and X fitted again; beside it, N more
views of the same capture instead (the N next views drawn).

With ``--rendered`` the sessions are rendered (1280x1024 images of the chessboard, the controller's
joint angles in joints.csv), detected and fitted by :func:`handeye.pipelines.folders.calibrate_folder` (as
``handeye calibrate`` does): the kinematic rows only, X's error and its coverage by 3 std.

With ``--spread FACTOR`` the captures move each joint FACTOR times as far about the arm's home as
its table's ``spread_deg`` (views that do not show the whole target are still left out): how much
a wider capture determines.

Run from the repository root: ``python benchmarks/bench_kinematic.py [--sessions N] [--views 25,40]
[--arms ur5,panda] [--compliance 0.2] [--spread 2] [--planned 5] [--rendered]``.
"""

from __future__ import annotations

import argparse
import tempfile
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

import cv2
import numpy as np

import handeye
from handeye.frames.metrics import rotation_error, translation_error
from handeye.frames.setups import predicted_target2cam
from handeye.geometry.se3 import invert, make_transform
from handeye.pipelines.folders import calibrate_folder
from handeye.planning.joints import suggest_joint_views
from handeye.robot.kinematics import load_arm
from handeye.simulate import capture_joint_views, kinematic_scene, simulate_kinematic_session

OPENCV = ("TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS")


def _errors(X, X_true) -> tuple[float, float]:
    return float(np.degrees(rotation_error(X, X_true))), float(1e3 * translation_error(X, X_true))


def _opencv_best(flange2base, target2cam, setup, X_true) -> tuple[float, float]:
    g2b = flange2base if setup == "eye_in_hand" else invert(flange2base)
    errors = []
    for name in OPENCV:
        R, t = cv2.calibrateHandEye(list(g2b[:, :3, :3]), list(g2b[:, :3, 3]), list(target2cam[:, :3, :3]),
                                    list(target2cam[:, :3, 3]), method=getattr(cv2, f"CALIB_HAND_EYE_{name}"))
        errors.append(_errors(make_transform(R, t.ravel()), X_true))
    return min(errors, key=lambda e: e[1])


def _seen_error(X, Z, flange2base, setup, target2cam_true) -> float:
    """Median distance (mm) between where X, Z and the flange poses put the target's origin in the
    camera and where it is."""
    T = predicted_target2cam(X, Z, flange2base, setup)
    return float(1e3 * np.median(np.linalg.norm(T[:, :3, 3] - target2cam_true[:, :3, 3], axis=1)))


def _arm(name: str, spread: float):
    """The shipped arm ``name`` whose captures move the joints ``spread`` times its table's spread."""
    chain = load_arm(name)
    return replace(chain, spread=spread * chain.spread)


def _covered(e, std) -> bool:
    """Whether X's error ``e`` (deg, mm) is within 3 of its reported std (rotation deg, translation mm)."""
    return bool(e[0] <= 3 * np.linalg.norm(std[:3]) and e[1] <= 3 * np.linalg.norm(std[3:]))


def _within(e) -> float:
    """The share of X's errors ``e`` ((N, 2): deg, mm) within 0.05 deg and 0.3 mm."""
    e = np.asarray(e, dtype=float).reshape(-1, 2)
    return float(np.mean((e[:, 0] <= 0.05) & (e[:, 1] <= 0.3)))


def one_session(args) -> dict:
    arm, n, setup, seed, compliance, spread, planned = args
    sc = kinematic_scene(2 * n, setup, seed, arm=_arm(arm, spread), compliance_deg_per_m=compliance)
    fit, held = np.arange(n), np.arange(n, 2 * n)
    black = handeye.calibrate_poses(sc.flange2base[fit], sc.target2cam[fit], setup, progress=False)
    row = {"black": _errors(black.X, sc.X), "opencv": _opencv_best(sc.flange2base[fit], sc.target2cam[fit], setup, sc.X),
           "before": _seen_error(black.X, black.Z, sc.flange2base[held], setup, sc.target2cam_true[held])}
    for key, with_compliance in (("kinematic", False), ("compliance", True))[:2 if compliance > 0 else 1]:
        kin = _fit(sc, sc.joints[fit], sc.target2cam[fit], list(sc.image_points[fit]), compliance=with_compliance)
        e = _errors(kin.X, sc.X)
        row |= {key: e, f"{key}_covered": _covered(e, kin.std),
                f"{key}_after": _seen_error(kin.X, kin.Z, kin.kinematic.chain.forward(sc.joints[held]), setup,
                                            sc.target2cam_true[held])}
        if key == "kinematic" and planned:
            row |= _planned(sc, kin, n, planned, seed)
    return row


def _planned(sc, kin, n: int, count: int, seed: int) -> dict:
    """X's error with the ``count`` views suggest_joint_views proposes after the fit on the first
    ``n`` views (captured by the true arm), and with ``count`` more views of the capture instead."""
    views = suggest_joint_views(kin, n_views=count, image_size=sc.image_size)
    more = np.arange(n + count)  # the capture's next views (held out from the other rows' fit)
    fit = _fit(sc, sc.joints[more], sc.target2cam[more], list(sc.image_points[more]))
    out = {"more": _errors(fit.X, sc.X), "proposed": len(views.joints) > 0, "aim": views.aim}
    if not len(views.joints):
        return out | {"planned": _errors(kin.X, sc.X)}
    reported, t2c, pixels = capture_joint_views(sc, views.joints, 1000 + seed)
    fit = _fit(sc, np.vstack([sc.joints[:n], reported]), np.concatenate([sc.target2cam[:n], t2c]),
               list(sc.image_points[:n]) + list(pixels))
    return out | {"planned": _errors(fit.X, sc.X)}


def _fit(sc, joints, target2cam, image_points, **options):
    """The joint fit of these views of ``sc``'s capture (its detections, intrinsics and nominal arm)."""
    return handeye.calibrate_joints(joints, target2cam, sc.setup, sc.chain, object_points=[sc.object_points] * len(joints),
                                    image_points=image_points, K=sc.K, dist=sc.dist, **options)


def _print_planned(rows: list[dict], count: int) -> None:
    """The --planned lines: X with the proposed views against the same count of the capture's."""
    proposed = [r for r in rows if r["proposed"]]
    e = np.array([r["planned"] for r in rows])  # the fit's own X where nothing was proposed
    print(f"  {'kinematic, then the proposed views if any':<44} in all {len(rows)} sessions: X median {np.median(e[:, 0]):.4f} "
          f"deg / {np.median(e[:, 1]):.3f} mm, within 0.05 deg / 0.3 mm {_within(e):.0%}")
    for key, label in (("planned", f"kinematic + {count} proposed views"), ("more", f"kinematic + {count} more of the capture")):
        e = np.array([r[key] for r in proposed]) if proposed else np.zeros((0, 2))
        within = _within(e) if len(e) else float("nan")
        print(f"  {label:<44} in the {len(proposed)} sessions with views proposed "
              f"({', '.join(sorted({r['aim'] for r in proposed})) or '-'}): X median "
              + (f"{np.median(e[:, 0]):.4f} deg / {np.median(e[:, 1]):.3f} mm, within 0.05 deg / 0.3 mm {within:.0%}"
                 if len(e) else "-"))


def rendered_session(args) -> tuple[tuple[float, float], bool]:
    """X's error (deg, mm) and whether it is within 3 std, of a rendered joint session (images
    1280x1024, detected, the joint fit of `handeye calibrate`)."""
    arm, n, setup, seed, spread = args
    chain = _arm(arm, spread)
    with tempfile.TemporaryDirectory(prefix="handeye-bench-kinematic-") as folder:
        sc = simulate_kinematic_session(f"{folder}/s", n, setup, seed=seed, arm=chain, controller_poses=False)
        cal = calibrate_folder(f"{folder}/s", progress=False)
    e = _errors(cal.X, sc.X)
    return e, _covered(e, cal.std)


def rendered_rows(args, pool) -> None:
    """--rendered: the kinematic fit on rendered sessions, per arm, setup and number of views."""
    for arm in args.arms.split(","):
        for setup in args.setups.split(","):
            for n in (int(v) for v in args.views.split(",")):
                rows = list(pool.map(rendered_session, [(arm, n, setup, s, args.spread) for s in range(args.sessions)]))
                e = np.array([r[0] for r in rows])
                print(f"{arm} {setup}, {n} views, {len(rows)} rendered sessions"
                      + (f", joints moved {args.spread:g}x the table's spread" if args.spread != 1 else "")
                      + f": handeye kinematic X median {np.median(e[:, 0]):.4f} deg / {np.median(e[:, 1]):.3f} mm, "
                      f"within 0.05 deg / 0.3 mm {_within(e):.0%}, "
                      f"within 3 std {np.mean([r[1] for r in rows]):.0%}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sessions", type=int, default=20)
    ap.add_argument("--views", default="25,40")
    ap.add_argument("--arms", default="ur5,panda")
    ap.add_argument("--setups", default="eye_in_hand,eye_to_hand")
    ap.add_argument("--compliance", type=float, default=0.0, metavar="DEG_PER_M",
                    help="the simulated joints' compliance (deg per metre of the load's moment arm; default 0: rigid)")
    ap.add_argument("--spread", type=float, default=1.0, metavar="FACTOR",
                    help="the capture moves each joint FACTOR times as far about home as the arm's table says "
                    "(spread_deg; views that do not see the whole target are still left out; default 1)")
    ap.add_argument("--planned", type=int, default=0, metavar="N",
                    help="after the kinematic fit, capture the N views suggest_joint_views proposes (when it proposes "
                    "any: for undetermined entries, or for X when the joints moved too little) and fit again; beside "
                    "it, N more views of the same capture")
    ap.add_argument("--rendered", action="store_true",
                    help="render the sessions (1280x1024 images, detected) and fit them as `handeye calibrate` does; "
                    "the kinematic rows only")
    args = ap.parse_args()
    if args.rendered:
        with ProcessPoolExecutor(2) as pool:
            rendered_rows(args, pool)
        return
    fits = ("kinematic", "compliance") if args.compliance > 0 else ("kinematic",)
    labels = {"black": "handeye black-box", "opencv": "best OpenCV method", "kinematic": "handeye kinematic",
              "compliance": "handeye kinematic+compliance"}
    with ProcessPoolExecutor(2) as pool:
        for arm in args.arms.split(","):
            for setup in args.setups.split(","):
                for n in (int(v) for v in args.views.split(",")):
                    rows = list(pool.map(one_session, [(arm, n, setup, s, args.compliance, args.spread, args.planned)
                                                        for s in range(args.sessions)]))
                    keys = ("black", "opencv") + fits
                    within = {k: _within([r[k] for r in rows]) for k in keys}
                    med = {k: np.median([r[k] for r in rows], axis=0) for k in keys}
                    before = np.median([r["before"] for r in rows])
                    print(f"{arm} {setup}, {n} views, {len(rows)} sessions"
                          + (f", joints moved {args.spread:g}x the table's spread" if args.spread != 1 else "")
                          + (f", joints' compliance {args.compliance:g} deg/m:" if args.compliance > 0 else ":"))
                    for k in keys:
                        print(f"  {labels[k]:<29} X median {med[k][0]:.4f} deg / {med[k][1]:.3f} mm, within 0.05 deg / "
                              f"0.3 mm {within[k]:.0%}")
                    if args.planned:
                        _print_planned(rows, args.planned)
                    for k in fits:
                        after = np.median([r[f"{k}_after"] for r in rows])
                        print(f"  {labels[k]}: X within 3 std {np.mean([r[f'{k}_covered'] for r in rows]):.0%}; robot "
                              f"error seen from the camera on held-out joints: {before:.2f} mm before, {after:.3f} mm after "
                              f"({before / after:.1f}x)")


if __name__ == "__main__":
    main()
