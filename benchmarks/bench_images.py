"""Detection + PnP on a rendered 30-image 1280x1024 chessboard session, against plain OpenCV.

    python benchmarks/bench_images.py [--repeat 3]

Timings on the same images, best of ``--repeat``:

* ``opencv loop``: a plain sequential loop of OpenCV calls (imread, findChessboardCornersSB with
  EXHAUSTIVE | ACCURACY on the full image, solvePnP IPPE + solvePnPRefineLM), with OpenCV's
  default internal threading (which already spreads part of findChessboardCornersSB over the
  cores), and the same loop on one OpenCV thread;
* ``opencv loop, handeye's calls``: the same loop with the calls handeye makes for images of this
  size (findChessboardCornersSB on the half-size pyramid level to locate the board, then the same
  call as above on the board's region of the full image; see
  ``handeye.vision.targets._chessboard_in_region``): the bare-OpenCV baseline for handeye's
  overhead;
* ``handeye jobs=1``: handeye's pipeline in one worker (goal: < 10% over the bare calls);
* ``handeye jobs=N``: all cores (goal: >= 1.8x the plain loop on 2 cores).

The speed-up over the plain loop comes from searching only the board's region and from running
images in parallel; the corner error against the renderer's true corners is printed for both, so the speed
is not bought with accuracy unseen.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import cv2
import numpy as np
from _timing import best_time

import yaml

from handeye.geometry.se3 import invert
from handeye.session import load_session
from handeye.simulate import simulate_session
from handeye.vision import detect_images, solve_pnp, target_from_spec
from handeye.vision.detect import default_jobs
from handeye.vision.targets import _chessboard_in_region


def corner_rms(found: list, truth: list) -> float:
    """RMS distance (px) of detected corners from the true ones (either corner order of the board)."""
    err = [min(np.linalg.norm(f - t, axis=1), np.linalg.norm(f[::-1] - t, axis=1), key=np.mean) for f, t in zip(found, truth)]
    return float(np.sqrt(np.mean(np.square(np.concatenate(err)))))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "session"
        print("rendering 30 images 1280x1024 ...")
        simulate_session(folder, "eye_in_hand", 30, "chessboard", noise_px=0.2, seed=1, image_size=(1280, 1024))
        session = load_session(folder)
        target = target_from_spec(session.target_spec)
        K, dist = session.camera_matrix, session.dist_coeffs
        paths = [str(p) for p in session.image_paths]
        objp = target.object_points().astype(np.float64)

        def find_full(gray):
            _, corners = cv2.findChessboardCornersSB(gray, (target.cols, target.rows),
                                                     flags=cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY)
            return corners

        def find_in_region(gray):
            return _chessboard_in_region(gray, (target.cols, target.rows))

        def opencv_loop(find, out=None):
            def run() -> None:
                for p in paths:
                    gray = cv2.imread(p, cv2.IMREAD_GRAYSCALE)
                    img = find(gray).reshape(-1, 2).astype(np.float64)
                    _, rvec, tvec = cv2.solvePnP(objp, img, K, dist, flags=cv2.SOLVEPNP_IPPE)
                    cv2.solvePnPRefineLM(objp, img, K, dist, rvec, tvec)
                    if out is not None:
                        out.append(img)
            return run

        def handeye_pipeline(jobs: int, out=None):
            def run() -> None:
                for r in detect_images(paths, target, jobs=jobs, progress=False):
                    solve_pnp(r.detection, K, dist)
                    if out is not None:
                        out.append(r.detection.image_points)
            return run

        # the true corners, from the renderer's ground truth (eye-in-hand: target2cam = X^-1 F^-1 Z)
        gt = yaml.safe_load((folder / "ground_truth.yaml").read_text())
        target2cam = invert(np.array(gt["cam2flange"])) @ invert(session.flange2base) @ np.array(gt["target2base"])
        truth = []
        for T in target2cam:
            rvec, _ = cv2.Rodrigues(T[:3, :3])
            truth.append(cv2.projectPoints(objp, rvec, T[:3, 3], K, dist)[0].reshape(-1, 2))
        found_cv, found_he = [], []
        opencv_loop(find_full, found_cv)()
        handeye_pipeline(1, found_he)()

        jobs = default_jobs()
        saved = cv2.getNumThreads()
        cv2.setNumThreads(1)
        t_cv1 = best_time(opencv_loop(find_full), args.repeat, warmup=False)
        cv2.setNumThreads(saved)
        t_cv = best_time(opencv_loop(find_full), args.repeat, warmup=False)
        t_bare = best_time(opencv_loop(find_in_region), args.repeat, warmup=False)
        t_one = best_time(handeye_pipeline(1), args.repeat, warmup=False)
        t_par = best_time(handeye_pipeline(jobs), args.repeat, warmup=False)
        print(f"cv2 {cv2.__version__}, {jobs} cores, images rendered with 0.2 px noise")
        print(f"opencv loop                   {t_cv:7.3f} s   (one OpenCV thread: {t_cv1:.3f} s); "
              f"corner RMS from truth {corner_rms(found_cv, truth):.4f} px")
        print(f"opencv loop, handeye's calls  {t_bare:7.3f} s")
        print(f"handeye jobs=1                {t_one:7.3f} s   overhead over the same bare calls {100 * (t_one / t_bare - 1):+.1f}%; "
              f"corner RMS from truth {corner_rms(found_he, truth):.4f} px")
        print(f"handeye jobs={jobs}                {t_par:7.3f} s   speed-up {t_cv / t_par:.2f}x over the opencv loop "
              f"({t_cv1 / t_par:.2f}x over it on one OpenCV thread); {t_one / t_par:.2f}x over jobs=1")


if __name__ == "__main__":
    main()
