"""``handeye calibrate`` end to end on 30 images of 1280x1024 with a 28x17 board, against a plain
sequential OpenCV loop doing the same work (goal: <= 0.6x its time on 2 cores).

    python benchmarks/bench_end_to_end.py [--repeat 2] [--images 30]

The session has no intrinsics in session.yaml, so both sides calibrate the camera from the images.
OpenCV loop: imread, findChessboardCornersSB (EXHAUSTIVE | ACCURACY) on every full image,
calibrateCamera, solvePnP per image, calibrateHandEye (Daniilidis): X and nothing else. handeye:
``handeye calibrate SESSION --out DIR`` in this process: detection in parallel, intrinsics, PnP, the
check, the estimator chosen by cross-validation, the uncertainty, the result files and the report.
The error of X against the renderer's truth is printed for both.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import shutil
import tempfile
from pathlib import Path

import cv2
import numpy as np
import yaml

from _timing import best_time
from handeye.cli import main as cli
from handeye.frames.metrics import rotation_error, translation_error
from handeye.geometry.se3 import make_transform
from handeye.io.session import load_session
from handeye.sensors.camera import target_from_spec
from handeye.simulate import simulate_session

GOAL = 0.6
BOARD = {"type": "chessboard", "cols": 28, "rows": 17, "square": 0.012}


def opencv_loop(session_dir: Path) -> np.ndarray:
    session = load_session(session_dir)
    size = (BOARD["cols"], BOARD["rows"])
    obj = target_from_spec(BOARD).object_points().astype(np.float32)
    flags = cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
    found, keep = [], []
    for k, path in enumerate(session.image_paths):
        gray = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        ok, corners = cv2.findChessboardCornersSB(gray, size, flags=flags)
        if ok:
            found.append(corners.reshape(-1, 1, 2))
            keep.append(k)
    image_size = gray.shape[::-1]
    _, K, dist, _, _ = cv2.calibrateCamera([obj] * len(found), found, image_size, None, None)
    R_t2c, t_t2c = [], []
    for corners in found:
        _, rvec, tvec = cv2.solvePnP(obj, corners, K, dist)
        R_t2c.append(cv2.Rodrigues(rvec)[0])
        t_t2c.append(tvec)
    F = session.flange2base[keep]
    R, t = cv2.calibrateHandEye(list(F[:, :3, :3]), list(F[:, :3, 3]), R_t2c, t_t2c,
                                method=cv2.CALIB_HAND_EYE_DANIILIDIS)
    return make_transform(R, t.ravel())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--images", type=int, default=30)
    args = parser.parse_args()
    root = Path(tempfile.mkdtemp(prefix="handeye-bench-e2e-"))
    try:
        session = root / "session"
        print(f"rendering {args.images} images 1280x1024 of a {BOARD['cols']}x{BOARD['rows']} board ...")
        simulate_session(session, n_poses=args.images, target=BOARD, image_size=(1280, 1024), seed=4,
                         write_intrinsics=False, noise_px=0.2, robot_noise=(0.02, 0.1))
        truth = np.array(yaml.safe_load((session / "ground_truth.yaml").read_text())["cam2flange"])
        X_cv = opencv_loop(session)
        t_cv = best_time(lambda: opencv_loop(session), args.repeat, warmup=False)

        def handeye_run():
            shutil.rmtree(root / "out", ignore_errors=True)
            with contextlib.redirect_stdout(io.StringIO()):
                # --no-cache: each run detects (the cache would skip detection after the first)
                return cli(["calibrate", str(session), "--no-progress", "--no-cache", "--out", str(root / "out")])

        status = handeye_run()
        t_he = best_time(handeye_run, args.repeat, warmup=False)
        X_he = np.array(yaml.safe_load((root / "out" / "result.yaml").read_text())["X"]["matrix"])
    finally:
        shutil.rmtree(root, ignore_errors=True)
    ratio = t_he / t_cv
    print(f"cv2 {cv2.__version__}; best of {args.repeat}")
    print(f"  plain OpenCV loop (detect, calibrateCamera, solvePnP, calibrateHandEye): {t_cv:6.2f} s, "
          f"X off by {np.degrees(rotation_error(X_cv, truth)):.4f} deg / {1e3 * translation_error(X_cv, truth):.3f} mm")
    print(f"  handeye calibrate --out (and check, CV, uncertainty, report), exit {status}:  {t_he:6.2f} s, "
          f"X off by {np.degrees(rotation_error(X_he, truth)):.4f} deg / {1e3 * translation_error(X_he, truth):.3f} mm")
    print(f"  ratio handeye / OpenCV: {ratio:.2f} (goal <= {GOAL}: {'met' if ratio <= GOAL else 'NOT met'})")


if __name__ == "__main__":
    main()
