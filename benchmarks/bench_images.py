"""Detection + PnP on rendered chessboard sessions, against plain OpenCV.

    python benchmarks/bench_images.py [--repeat 3] [--skip-large]

Two cases: 30 images of 1280x1024 (a 9x6 board), and a large one, 12 images of 4000x3000 (12 MP)
with a 28x17 board of 8 mm squares (timed once; the peak memory of a fresh process running each
side is printed too: neither holds more than the images in work).

Timings on the same images, best of ``--repeat``:

* ``opencv loop``: a plain sequential loop of OpenCV calls (imread, findChessboardCornersSB with
  EXHAUSTIVE | ACCURACY on the full image, solvePnP IPPE + solvePnPRefineLM), with OpenCV's
  default internal threading (which already spreads part of findChessboardCornersSB over the
  cores), and the same loop on one OpenCV thread;
* ``opencv loop, handeye's calls``: the same loop with the calls handeye makes for images of this
  size (findChessboardCornersSB on the half-size pyramid level to locate the board, then the same
  call as above on the board's region of the full image; see
  ``handeye.sensors.camera.targets.chessboard._chessboard_in_region``): the bare-OpenCV baseline for handeye's
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
import yaml

from _timing import best_time
from handeye.geometry.se3 import invert
from handeye.io.session import load_session
from handeye.sensors.camera import detect_images, solve_pnp, target_from_spec
from handeye.sensors.camera.detect import default_jobs
from handeye.sensors.camera.targets.chessboard import _chessboard_in_region
from handeye.simulate import simulate_session


def corner_rms(found: list, truth: list) -> float:
    """RMS distance (px) of detected corners from the true ones (either corner order of the board)."""
    err = [min(np.linalg.norm(f - t, axis=1), np.linalg.norm(f[::-1] - t, axis=1), key=np.mean) for f, t in zip(found, truth)]
    return float(np.sqrt(np.mean(np.square(np.concatenate(err)))))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--skip-large", action="store_true", help="only the 30-image 1280x1024 case")
    args = parser.parse_args()
    _case(30, (1280, 1024), "chessboard", args.repeat)
    if not args.skip_large:
        # high resolution and a large board: 12 MP, 28 x 17 inner corners of 8 mm squares
        _case(12, (4000, 3000), {"type": "chessboard", "cols": 28, "rows": 17, "square": 0.008}, 1)


_CHILD = """
import sys, json, cv2, numpy as np
from handeye.sensors.camera import detect_images, solve_pnp, target_from_spec
paths, spec, K, dist, which = json.loads(sys.stdin.read())
target, K, dist = target_from_spec(spec), np.array(K), np.array(dist)
if which == "handeye":
    for r in detect_images(paths, target, progress=False):
        solve_pnp(r.detection, K, dist)
else:
    objp = target.object_points().astype(np.float64)
    for p in paths:
        gray = cv2.imread(p, cv2.IMREAD_GRAYSCALE)
        _, c = cv2.findChessboardCornersSB(gray, (target.cols, target.rows), flags=cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY)
        img = c.reshape(-1, 2).astype(np.float64)
        _, rvec, tvec = cv2.solvePnP(objp, img, K, dist, flags=cv2.SOLVEPNP_IPPE)
        cv2.solvePnPRefineLM(objp, img, K, dist, rvec, tvec)
with open("/proc/self/status") as f:  # VmHWM: this process's peak resident memory (kB)
    print(next(int(line.split()[1]) for line in f if line.startswith("VmHWM")))
"""


def _child_peak_mib(which: str, paths: list[str], spec: dict, K, dist) -> float:
    """Peak resident memory (MiB) of a fresh process running handeye's detection + PnP on all
    cores (``which='handeye'``) or the plain sequential OpenCV loop on ``paths``; read by the
    child itself (a child's ``ru_maxrss`` starts from its parent's on Linux)."""
    import json
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", _CHILD], check=True, capture_output=True, text=True,
                         input=json.dumps([paths, spec, np.asarray(K).tolist(), np.asarray(dist).tolist(), which]))
    return int(out.stdout.split()[-1]) / 1024


def _case(n: int, size: tuple[int, int], target_spec, repeat: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "session"
        print(f"\nrendering {n} images {size[0]}x{size[1]} ...")
        simulate_session(folder, "eye_in_hand", n, target_spec, noise_px=0.2, seed=1, image_size=size)
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
        t_cv1 = best_time(opencv_loop(find_full), repeat, warmup=False)
        cv2.setNumThreads(saved)
        t_cv = best_time(opencv_loop(find_full), repeat, warmup=False)
        t_bare = best_time(opencv_loop(find_in_region), repeat, warmup=False)
        t_one = best_time(handeye_pipeline(1), repeat, warmup=False)
        t_par = best_time(handeye_pipeline(jobs), repeat, warmup=False)
        if min(size) > 2000:  # memory, each in a fresh process: the plain loop holds one image at a time
            mem_cv = _child_peak_mib("opencv", paths, session.target_spec, K, dist)
            mem_he = _child_peak_mib("handeye", paths, session.target_spec, K, dist)
            print(f"peak memory of a fresh process: opencv loop {mem_cv:.0f} MiB, handeye on {jobs} cores {mem_he:.0f} MiB "
                  f"(the {n} grey images alone: {n * size[0] * size[1] / 2**20:.0f} MiB)")
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
