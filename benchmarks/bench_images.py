"""Detection + PnP on a rendered 30-image 1280x1024 chessboard session, against plain OpenCV.

    python benchmarks/bench_images.py [--repeat 3]

Three timings on the same images, best of ``--repeat``:

* ``opencv loop``: a plain sequential loop of the same OpenCV calls (imread, findChessboardCornersSB,
  solvePnP IPPE + solvePnPRefineLM), with OpenCV's default internal threading (which already
  spreads part of findChessboardCornersSB over the cores), and the same loop on one OpenCV thread;
* ``handeye jobs=1``: handeye's pipeline in one worker (overhead over bare OpenCV: goal < 10%);
* ``handeye jobs=N``: all cores (goal: >= 1.8x the plain loop on 2 cores).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import cv2
import numpy as np
from _timing import best_time

from handeye.session import load_session
from handeye.simulate import simulate_session
from handeye.vision import detect_images, solve_pnp, target_from_spec
from handeye.vision.detect import default_jobs


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

        def opencv_loop() -> None:
            for p in paths:
                gray = cv2.imread(p, cv2.IMREAD_GRAYSCALE)
                ok, corners = cv2.findChessboardCornersSB(gray, (target.cols, target.rows),
                                                          flags=cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY)
                img = corners.reshape(-1, 2).astype(np.float64)
                _, rvec, tvec = cv2.solvePnP(objp, img, K, dist, flags=cv2.SOLVEPNP_IPPE)
                cv2.solvePnPRefineLM(objp, img, K, dist, rvec, tvec)

        def handeye_pipeline(jobs: int):
            def run() -> None:
                for r in detect_images(paths, target, jobs=jobs, progress=False):
                    solve_pnp(r.detection, K, dist)
            return run

        jobs = default_jobs()
        saved = cv2.getNumThreads()
        cv2.setNumThreads(1)
        t_cv1 = best_time(opencv_loop, args.repeat, warmup=False)
        cv2.setNumThreads(saved)
        t_cv = best_time(opencv_loop, args.repeat, warmup=False)
        t_one = best_time(handeye_pipeline(1), args.repeat, warmup=False)
        t_par = best_time(handeye_pipeline(jobs), args.repeat, warmup=False)
        print(f"cv2 {cv2.__version__}, {jobs} cores")
        print(f"opencv loop        {t_cv:7.3f} s   (one OpenCV thread: {t_cv1:.3f} s)")
        print(f"handeye jobs=1     {t_one:7.3f} s   overhead {100 * (t_one / t_cv - 1):+.1f}%")
        print(f"handeye jobs={jobs}     {t_par:7.3f} s   speed-up {t_cv / t_par:.2f}x over the opencv loop, "
              f"{t_cv1 / t_par:.2f}x over it on one OpenCV thread")


if __name__ == "__main__":
    main()
