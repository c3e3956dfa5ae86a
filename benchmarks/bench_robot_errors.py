"""X under real robots' errors: a sweep of the simulated arm's kinematic error, handeye against OpenCV.

Each session is rendered by :func:`handeye.simulate.simulate_realistic_session` (a 6-axis arm whose
true DH parameters and joint zeros differ from the nominal ones the controller reports, smooth
joint-dependent errors, Student-t pose noise, timing jitter; images of a 9x6 chessboard at 640x480,
K given). The sweep scales the kinematic error (``RealisticErrors.scaled``) from a calibrated arm
(~0.2 mm absolute error) to an uncalibrated one (~3 mm). Per level, setup and number of views it
prints the median error of X (deg / mm) of handeye's default, of each handeye estimator fitted on
its own, and of OpenCV's 5 calibrateHandEye methods on OpenCV's own detection and PnP
(findChessboardCorners, cornerSubPix, solvePnP), and the share of sessions whose X lies within 3
reported std (rotation and translation norms), with the default ``robot_accuracy`` and with the
arm's accuracy given as its user would state it (``robot_accuracy`` = the median error of the
simulated arm's poses, per axis): the default assumes a calibrated arm (0.03 deg / 0.3 mm per axis),
and the constant part of a worse arm's error is invisible in the data.

Run from the repository root: ``python benchmarks/bench_robot_errors.py [--sessions N] [--levels
0.25,1,3] [--views 8,12,20]``. The default (10 sessions per cell, 3 levels, 3 view counts, both
setups: 180 sessions) takes ~10 min on 2 cores (96 sessions took ~5 min).
"""

from __future__ import annotations

import argparse
import tempfile
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

import handeye
from handeye.calibration import calibrate_observed, observe
from handeye.estimators import pixel_candidates, pose_candidates
from handeye.geometry.se3 import invert, make_transform
from handeye.metrics import rotation_error, translation_error
from handeye.session import load_session
from handeye.simulate import REALISTIC, robot_accuracy_of, simulate_realistic_session

OPENCV = ("TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS")


def _errors(X, X_true) -> tuple[float, float]:
    return float(np.degrees(rotation_error(X, X_true))), float(1e3 * translation_error(X, X_true))


def _opencv_pipeline(session) -> dict[str, np.ndarray]:
    """OpenCV alone: chessboard corners, sub-pixel refinement, solvePnP, calibrateHandEye."""
    spec = session.target_spec
    obj = np.zeros((spec["rows"] * spec["cols"], 3))
    obj[:, :2] = np.mgrid[0:spec["cols"], 0:spec["rows"]].T.reshape(-1, 2) * spec["square"]
    poses, ok = [], []
    for path in session.image_paths:
        gray = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        found, corners = cv2.findChessboardCorners(gray, (spec["cols"], spec["rows"]))
        ok.append(bool(found))
        if not found:
            poses.append(np.eye(4))
            continue
        corners = cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1),
                                   (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 1e-3))
        _, rvec, tvec = cv2.solvePnP(obj, corners, session.camera_matrix, session.dist_coeffs)
        poses.append(make_transform(cv2.Rodrigues(rvec)[0], tvec.ravel()))
    ok = np.array(ok)
    t2c = np.array(poses)[ok]
    f2b = session.flange2base[ok]
    g2b = f2b if session.setup == "eye_in_hand" else invert(f2b)
    out = {}
    for name in OPENCV:
        R, t = cv2.calibrateHandEye(list(g2b[:, :3, :3]), list(g2b[:, :3, 3]), list(t2c[:, :3, :3]),
                                    list(t2c[:, :3, 3]), method=getattr(cv2, f"CALIB_HAND_EYE_{name}"))
        out[name] = make_transform(R, t.ravel())
    return out


def _covered(e: tuple[float, float], std: np.ndarray) -> bool:
    """X's rotation and translation errors both within 3 of their reported std (norms)."""
    return bool(e[0] <= 3 * np.linalg.norm(std[:3]) and e[1] <= 3 * np.linalg.norm(std[3:]))


def one_session(args) -> dict:
    level, n, setup, seed = args
    errors = replace(REALISTIC, pixel_px=0.1, joint_wave_deg=0.02).scaled(level)
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(scratch) / "session"
        sc = simulate_realistic_session(folder, n, setup, seed, errors=errors)
        session = load_session(folder)
        obs = observe(session, jobs=1, progress=False)
        cal = calibrate_observed(obs)
        e = _errors(cal.X, sc.X)
        # the arm's accuracy as its user would state it: the median error of its poses, per axis
        given = calibrate_observed(obs, robot_accuracy=tuple(np.asarray(robot_accuracy_of(sc)) / np.sqrt(3)))
        e_given = _errors(given.X, sc.X)
        out = {"accuracy_mm": robot_accuracy_of(sc)[1], "default": e, "estimator": cal.estimator,
               "verdict": cal.verdict, "covered": _covered(e, cal.std), "covered_given": _covered(e_given, given.std)}
        idx = np.asarray(handeye.calibrate_poses(obs.flange2base, obs.target2cam, setup, refine="none").pose_indices)
        views = obs.views(idx)
        for name, fit in (pose_candidates("daniilidis", views) | pixel_candidates(views, "daniilidis")).items():
            try:
                out[f"handeye {name}"] = _errors(fit(views.flange2base, views.target2cam, setup, np.arange(len(views)))[0], sc.X)
            except handeye.HandEyeError:
                out[f"handeye {name}"] = (np.nan, np.nan)
        for name, X in _opencv_pipeline(session).items():
            out[f"OpenCV {name}"] = _errors(X, sc.X)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sessions", type=int, default=10)
    ap.add_argument("--levels", default="0.25,1,3")
    ap.add_argument("--views", default="8,12,20")
    ap.add_argument("--setups", default="eye_in_hand,eye_to_hand")
    args = ap.parse_args()
    cells = [(float(lv), int(n), setup) for lv in args.levels.split(",") for setup in args.setups.split(",")
             for n in args.views.split(",")]
    with ProcessPoolExecutor(2) as pool:
        for level, n, setup in cells:
            rows = list(pool.map(one_session, [(level, n, setup, s) for s in range(args.sessions)]))
            acc = np.median([r["accuracy_mm"] for r in rows])
            print(f"\nlevel {level:g} ({acc:.2f} mm median robot error), {setup}, {n} views, {len(rows)} sessions: "
                  f"X within 3 std {np.mean([r['covered'] for r in rows]):.0%} (with the arm's accuracy given: "
                  f"{np.mean([r['covered_given'] for r in rows]):.0%}); default chose "
                  + ", ".join(f"{e} {[r['estimator'] for r in rows].count(e)}" for e in sorted({r['estimator'] for r in rows})))
            names = ["default"] + [k for k in rows[0] if k.startswith("handeye ")] + [k for k in rows[0] if k.startswith("OpenCV ")]
            best_cv = [min(np.nanmedian([r[k][j] for r in rows]) for k in rows[0] if k.startswith("OpenCV ")) for j in (0, 1)]
            for name in names:
                med = [float(np.nanmedian([r[name][j] for r in rows])) for j in (0, 1)]
                print(f"  {name:<32} {med[0]:7.3f} deg {med[1]:7.2f} mm   ratio to best OpenCV {med[0] / best_cv[0]:5.2f} "
                      f"/ {med[1] / best_cv[1]:5.2f}")


if __name__ == "__main__":
    main()
