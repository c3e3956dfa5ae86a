"""The simulation study's speed: batched solvers against a loop of OpenCV calls, and the full preset.

    python benchmarks/bench_study.py [--runs 200] [--repeat 5] [--jobs 2] [--skip-preset]

1. Daniilidis calibrations per second on the same Monte-Carlo runs (15 poses each, noisy), in the
   same process: a Python loop of ``cv2.calibrateHandEye(..., CALIB_HAND_EYE_DANIILIDIS)`` (which
   forms all 105 pose pairs itself) against ``handeye.solve_batch`` on all runs at once, both with
   the same all-pairs motions (the same work) and with the 14 consecutive motions the study uses.
   Our timings include forming the motions from the poses.
2. The whole ``seed-chapter5`` preset (``handeye study``): wall time with ``--jobs`` workers, against
   the goal of 60 s, and beside it what OpenCV would need for just the closed-form calibrations
   that have a cv2 namesake (count x cv2's per-call time measured above).

Times are the best of ``--repeat``; ratio = OpenCV / ours.
"""

from __future__ import annotations

import argparse
import time

import cv2
import numpy as np

import handeye
from _timing import best_time
from handeye.simulate import Noise, add_noise, seed_scenes
from handeye.workflows.study import _motions, preset, study, write_study

CV_NAMESAKES = {"tsai_lenz", "park_martin", "horaud", "daniilidis", "andreff", "shah", "li"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--skip-preset", action="store_true")
    args = parser.parse_args()
    print(f"handeye {handeye.__version__}, OpenCV {cv2.__version__}, numpy {np.__version__}")

    rng = np.random.default_rng(0)
    sc = seed_scenes(args.runs, 15, "eye_in_hand", rng)
    f2b = add_noise(sc.flange2base, Noise(0.3, 0.3), rng)
    t2c = add_noise(sc.target2cam, Noise(0.3, 0.3), rng)
    cv_args = [(list(f2b[s, :, :3, :3]), list(f2b[s, :, :3, 3]), list(t2c[s, :, :3, :3]), list(t2c[s, :, :3, 3]))
               for s in range(args.runs)]

    def run_cv() -> None:
        for a in cv_args:
            cv2.calibrateHandEye(*a, method=cv2.CALIB_HAND_EYE_DANIILIDIS)

    def run_batch(pairs: str):
        def run() -> None:
            A, B = _motions(f2b, t2c, "eye_in_hand", pairs)
            handeye.solve_batch(A, B, "daniilidis")
        return run

    t_cv = best_time(run_cv, args.repeat)
    print(f"\nDaniilidis, {args.runs} runs x 15 poses")
    print(f"{'':<44} {'ms':>8} {'calib/s':>10} {'ratio':>7}")
    print(f"{'cv2.calibrateHandEye loop (all 105 pairs)':<44} {1e3 * t_cv:8.1f} {args.runs / t_cv:10.0f} {'1.0':>7}")
    for pairs, label in (("all", "handeye.solve_batch, all 105 pairs"), ("consecutive", "handeye.solve_batch, 14 consecutive")):
        t = best_time(run_batch(pairs), args.repeat)
        print(f"{label:<44} {1e3 * t:8.1f} {args.runs / t:10.0f} {t_cv / t:7.1f}")
    A, B = _motions(f2b, t2c, "eye_in_hand", "all")
    X_batch = handeye.solve_batch(A, B, "daniilidis")
    R_cv, t_cv_x = cv2.calibrateHandEye(*cv_args[0], method=cv2.CALIB_HAND_EYE_DANIILIDIS)
    dX = max(np.abs(X_batch[0, :3, :3] - R_cv).max(), np.abs(X_batch[0, :3, 3] - t_cv_x.ravel()).max())
    print(f"(same answer as OpenCV on run 0: max |dX| = {dX:.1e})")

    if args.skip_preset:
        return
    settings, figures = preset("seed-chapter5")
    t0 = time.perf_counter()
    res = study(settings, runs=args.runs, seed=0, jobs=args.jobs, progress=False, figures=figures,
                preset_name="seed-chapter5")
    t_sim = time.perf_counter() - t0
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        write_study(res, tmp)
        t_write = time.perf_counter() - t0
    n_cv = sum(args.runs * len(CV_NAMESAKES & set(s.methods)) for s in settings)
    per_call = t_cv / args.runs
    print(f"\nseed-chapter5 preset: {len(settings)} settings x {args.runs} runs, {args.jobs} workers")
    print(f"  simulate + solve: {t_sim:.1f} s, write CSV/MD/JSON + {len(figures)} figures: {t_write:.1f} s, "
          f"total {t_sim + t_write:.1f} s (goal < 60 s)")
    print(f"  OpenCV for its {n_cv} closed-form calibrations alone (one core, at {1e3 * per_call:.2f} ms each): "
          f"~{n_cv * per_call:.0f} s; ratio to our whole preset {n_cv * per_call / (t_sim + t_write):.1f}")


if __name__ == "__main__":
    main()
