"""Solver speed against OpenCV's namesakes, measured in the same run on identical inputs.

    python benchmarks/bench_solvers.py [--repeat 30]

Both sides start from the same absolute poses and form every pose pair (N(N-1)/2 motions, as
cv2.calibrateHandEye does internally). Two handeye timings are printed:

* ``solve``: validation + all-pairs motions + solver, the same work as cv2.calibrateHandEye;
* ``calibrate_poses``: the user-facing call, which also estimates Z (the target pose).

Times are the best of ``--repeat`` runs (the least disturbed by the machine); ratio = OpenCV / ours.
"""

from __future__ import annotations

import argparse
import time

import cv2
import numpy as np

import handeye
from handeye.motions import MotionSet, validate_poses
from handeye.simulate import random_scene
from handeye.solvers import solve_motions

CV_METHODS = {"daniilidis": cv2.CALIB_HAND_EYE_DANIILIDIS}


def best_time(fn, repeat: int) -> float:
    fn()  # warm-up
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=30)
    args = parser.parse_args()
    print(f"handeye {handeye.__version__}, OpenCV {cv2.__version__}, numpy {np.__version__}")
    print(f"{'method':<12} {'poses':>5} {'motions':>7} {'opencv ms':>10} {'solve ms':>9} {'ratio':>7}"
          f" {'calibrate_poses ms':>19} {'ratio':>7}")
    for method, cv_flag in CV_METHODS.items():
        for n in (15, 100):
            scene = random_scene(n, "eye_in_hand", rng=n)
            f2b, t2c = scene.flange2base, scene.target2cam
            R_g, t_g = list(f2b[:, :3, :3]), list(f2b[:, :3, 3])
            R_c, t_c = list(t2c[:, :3, :3]), list(t2c[:, :3, 3])

            def run_cv() -> None:
                cv2.calibrateHandEye(R_g, t_g, R_c, t_c, method=cv_flag)

            def run_solve() -> None:
                f, t = validate_poses(f2b, t2c)
                solve_motions(MotionSet.from_poses(f, t, "eye_in_hand", "all"), method=method)

            def run_calibrate() -> None:
                handeye.calibrate_poses(f2b, t2c, setup="eye_in_hand", method=method)

            t_cv = best_time(run_cv, args.repeat)
            t_solve = best_time(run_solve, args.repeat)
            t_cal = best_time(run_calibrate, args.repeat)
            print(
                f"{method:<12} {n:>5} {n * (n - 1) // 2:>7} {1e3 * t_cv:>10.2f} {1e3 * t_solve:>9.2f} "
                f"{t_cv / t_solve:>6.1f}x {1e3 * t_cal:>19.2f} {t_cv / t_cal:>6.1f}x"
            )


if __name__ == "__main__":
    main()
