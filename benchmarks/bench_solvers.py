"""Solver speed against OpenCV's namesakes, measured in the same run on identical inputs.

    python benchmarks/bench_solvers.py [--repeat 30]

Both sides start from the same absolute poses. For the AX = XB methods both form every pose pair
(N(N-1)/2 motions, as cv2.calibrateHandEye does internally); the robot-world methods (shah, li)
work on the N poses directly, on both sides. Two handeye timings are printed:

* ``solve``: validation + all-pairs motions + solver (robot-world: validation + solver), the same
  work as OpenCV's call;
* ``core``: the same without handeye's input checks (finite, orthonormal, enough rotation about
  two axes), which OpenCV does not make: what the checks cost, shown apart;
* ``solve(A,B)``: the public ``handeye.solve`` on the motions as a user passes them (all pairs,
  made beforehand by ``handeye.relative_motions``), against OpenCV's call on the poses;
* ``calibrate_poses``: the user-facing call with ``refine='none'`` (validation, the check with its
  outlier search and leave-one-out, the solve, Z), against OpenCV's call plus the mean target pose
  (``Z``), which is what it returns.

Then ``solve(A,B)`` at 100 poses stage by stage (input checks, conversion to dual quaternions,
observability check + solver) beside the budget a 20x ratio leaves, and ``solve_batch`` on 200
runs x 15 poses (all 105 pairs each) against a loop of OpenCV calls.

Times are the best of ``--repeat`` runs (the least disturbed by the machine); ratio = OpenCV / ours.
"""

from __future__ import annotations

import argparse

import cv2
import numpy as np

import handeye
from _timing import best_time
from handeye.frames.motions import MotionSet, validate_poses
from handeye.frames.poses import validate_transform_pair
from handeye.frames.setups import constant_transforms, robot_world_inputs
from handeye.geometry.se3 import make_transform, mean_transform
from handeye.simulate import random_scene
from handeye.solvers import get, solve_motions, solve_robot_world
from handeye.solvers.observability import check_observability

CV_METHODS = {
    "tsai_lenz": ("hand_eye", "CALIB_HAND_EYE_TSAI"),
    "park_martin": ("hand_eye", "CALIB_HAND_EYE_PARK"),
    "horaud": ("hand_eye", "CALIB_HAND_EYE_HORAUD"),
    "andreff": ("hand_eye", "CALIB_HAND_EYE_ANDREFF"),
    "daniilidis": ("hand_eye", "CALIB_HAND_EYE_DANIILIDIS"),
    "shah": ("robot_world", "CALIB_ROBOT_WORLD_HAND_EYE_SHAH"),
    "li": ("robot_world", "CALIB_ROBOT_WORLD_HAND_EYE_LI"),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=30)
    args = parser.parse_args()
    print(f"handeye {handeye.__version__}, OpenCV {cv2.__version__}, numpy {np.__version__}")
    print(f"{'method':<12} {'poses':>5} {'motions':>7} {'opencv ms':>10} {'solve ms':>9} {'ratio':>7}"
          f" {'core ms':>8} {'ratio':>7} {'solve(A,B) ms':>13} {'ratio':>7} {'calibrate_poses ms':>19} {'ratio*':>7}")
    budgets = {}
    for method, (kind, cv_name) in CV_METHODS.items():
        cv_flag = getattr(cv2, cv_name)
        for n in (15, 100):
            scene = random_scene(n, "eye_in_hand", rng=n)
            f2b, t2c = scene.flange2base, scene.target2cam
            if kind == "hand_eye":
                args_cv = (list(f2b[:, :3, :3]), list(f2b[:, :3, 3]), list(t2c[:, :3, :3]), list(t2c[:, :3, 3]))

                def run_cv() -> None:
                    cv2.calibrateHandEye(*args_cv, method=cv_flag)

                def run_solve() -> None:
                    f, t = validate_poses(f2b, t2c)
                    solve_motions(MotionSet.from_poses(f, t, "eye_in_hand", "all"), method=method)

                def run_core() -> None:
                    get(method).func(MotionSet.from_poses(f2b, t2c, "eye_in_hand", "all"))

                A_rel, B_rel = handeye.relative_motions(f2b, t2c, "eye_in_hand", "all")

                def run_public() -> None:
                    handeye.solve(A_rel, B_rel, method=method)

                def run_cv_with_z() -> None:
                    R, t = cv2.calibrateHandEye(*args_cv, method=cv_flag)
                    X = make_transform(R, t.ravel())
                    mean_transform(constant_transforms(X, f2b, t2c, "eye_in_hand"))
            else:
                A, B = robot_world_inputs(f2b, t2c, "eye_in_hand")
                args_cv = (list(A[:, :3, :3]), list(A[:, :3, 3]), list(B[:, :3, :3]), list(B[:, :3, 3]))

                def run_cv() -> None:
                    cv2.calibrateRobotWorldHandEye(*args_cv, method=cv_flag)

                def run_solve() -> None:
                    solve_robot_world(A, B, method=method)

                def run_core() -> None:
                    get(method, kind="robot_world").func(A, B)

                run_public = run_solve

                def run_cv_with_z() -> None:
                    cv2.calibrateRobotWorldHandEye(*args_cv, method=cv_flag)  # returns X and Z

            def run_calibrate() -> None:
                handeye.calibrate_poses(f2b, t2c, setup="eye_in_hand", method=method, refine="none")

            t_cv = best_time(run_cv, args.repeat)
            t_solve = best_time(run_solve, args.repeat)
            t_core = best_time(run_core, args.repeat)
            t_cal = best_time(run_calibrate, args.repeat)
            t_public = best_time(run_public, args.repeat)
            t_cv_z = best_time(run_cv_with_z, args.repeat)
            motions = n * (n - 1) // 2 if kind == "hand_eye" else n
            if kind == "hand_eye" and n == 100:
                budgets[method] = t_cv / 20
            print(
                f"{method:<12} {n:>5} {motions:>7} {1e3 * t_cv:>10.2f} {1e3 * t_solve:>9.2f} "
                f"{t_cv / t_solve:>6.1f}x {1e3 * t_core:>8.2f} {t_cv / t_core:>6.1f}x "
                f"{1e3 * t_public:>13.2f} {t_cv / t_public:>6.1f}x "
                f"{1e3 * t_cal:>19.2f} {t_cv_z / t_cal:>6.1f}x"
            )
    print("* calibrate_poses against OpenCV's call plus the mean target pose Z (robot-world: its call, which gives Z);\n"
          "  issue 19's bar is the daniilidis row at 100 poses (no slower than OpenCV's Daniilidis + Z: ratio >= 1)")
    _breakdown(args.repeat, budgets)
    _batch(args.repeat)


def _breakdown(repeat: int, budgets: dict[str, float], n: int = 100) -> None:
    """Where the time of ``handeye.solve(A, B)`` goes on all pairs of ``n`` poses, stage by stage
    (each stage timed on its own, on fresh objects), beside the budget of a 20x ratio."""
    scene = random_scene(n, "eye_in_hand", rng=n)
    A, B = handeye.relative_motions(scene.flange2base, scene.target2cam, "eye_in_hand", "all")
    names = ("A (robot motions)", "B (camera motions)"), ("robot motions A", "camera motions B")
    T = validate_transform_pair(A, B, *names)
    motions = MotionSet.from_matrices(T[0], T[1])
    t_val = best_time(lambda: validate_transform_pair(A, B, *names), repeat)
    t_conv = best_time(lambda: MotionSet.from_matrices(T[0], T[1]), repeat)
    print(f"\nsolve(A, B) stage by stage on {len(A)} motions (ms): the input checks (finite, 4x4 rigid: {2 * len(A)} "
          f"matrices), the conversion to dual quaternions (scipy's from_matrix, assume_valid), the observability check "
          f"and the solver; budget = OpenCV's time / 20")
    print(f"{'method':<12} {'checks':>7} {'convert':>8} {'observe+solve':>14} {'total':>7} {'budget':>7}")
    for method, budget in budgets.items():
        def run() -> None:
            fresh = MotionSet(motions.dq_a, motions.dq_b, _AB=motions._AB)  # no cached sums
            check_observability(fresh)
            get(method).func(fresh)
        t_solve = best_time(run, repeat)
        print(f"{method:<12} {1e3 * t_val:>7.2f} {1e3 * t_conv:>8.2f} {1e3 * t_solve:>14.2f} "
              f"{1e3 * (t_val + t_conv + t_solve):>7.2f} {1e3 * budget:>7.2f}")


def _batch(repeat: int, runs: int = 200, n: int = 15) -> None:
    """solve_batch on ``runs`` x ``n`` poses (all pairs) against a loop of OpenCV calls."""
    scenes = [random_scene(n, "eye_in_hand", rng=1000 + k) for k in range(runs)]
    motions = [handeye.relative_motions(sc.flange2base, sc.target2cam, "eye_in_hand", "all") for sc in scenes]
    A = np.stack([m[0] for m in motions])
    B = np.stack([m[1] for m in motions])
    args_cv = [(list(sc.flange2base[:, :3, :3]), list(sc.flange2base[:, :3, 3]), list(sc.target2cam[:, :3, :3]),
                list(sc.target2cam[:, :3, 3])) for sc in scenes]
    print(f"\nsolve_batch: {runs} runs x {n} poses ({A.shape[1]} motions each), best of {repeat}")
    print(f"{'method':<12} {'opencv loop ms':>15} {'solve_batch ms':>15} {'ratio':>7}")
    for method in ("tsai_lenz", "park_martin", "horaud", "andreff", "daniilidis"):
        cv_flag = getattr(cv2, CV_METHODS[method][1])
        t_cv = best_time(lambda: [cv2.calibrateHandEye(*a, method=cv_flag) for a in args_cv], max(3, repeat // 5))
        t_he = best_time(lambda: handeye.solve_batch(A, B, method=method), max(3, repeat // 5))
        print(f"{method:<12} {1e3 * t_cv:>15.1f} {1e3 * t_he:>15.1f} {t_cv / t_he:>6.1f}x")


if __name__ == "__main__":
    main()
