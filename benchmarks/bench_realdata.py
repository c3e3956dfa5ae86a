"""Held-out prediction error on every real capture in ../shared/data/real: handeye against OpenCV.

Per set, 5-fold cross-validation on the same folds for everyone: fit on 4/5 of the views, predict
where the target's points appear in the other 1/5 from the robot pose alone, and compare with what
the camera saw (pixels for image sets, millimetres at the target's distance for pose pairs; see
handeye.estimation.validation). Rows: every OpenCV calibrateHandEye method (on the same PnP poses), handeye's
default pipeline (which chooses its estimator by an inner cross-validation on the training part
only), and each handeye estimator on its own. The ratio is against the best OpenCV method of the
set, measured in the same run.

One split of 8 views into 5 folds is one draw: ``--seeds N`` repeats the cross-validation on N
random splits (fold seeds 0 to N-1; the default run is seed 0) and prints, per set and row, the
median ratio to the best OpenCV method of the same split and its range. Measured (10 seeds, ~2 min),
the default: ViSP eye-in-hand 2025 0.89x [0.75-0.91], eye-to-hand 2025 0.92x [0.67-1.30], 2022
0.22x [0.13-0.27], 2018 pose pairs 1.00x [0.93-1.06] (0.95x at seed 0; no handeye estimator has a
median below 0.95x there: li 0.953x, the pose refinement 0.996x), ROS-Industrial ChArUco 0.34x
[0.29-0.41], 10x10 0.32x [0.30-0.36], Tabb 0.92x [0.88-0.95], ETH 0.80x [0.78-0.82].

Run from the repository root: ``python benchmarks/bench_realdata.py [--seeds N] [SET ...]``.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import numpy as np  # noqa: E402

import realdata  # noqa: E402
from handeye.estimation.estimators import pixel_candidates, pose_candidates  # noqa: E402
from handeye.estimation.validation import cross_validate, fold_indices  # noqa: E402


def bench_set(rs: realdata.RealSet, seed: int = 0) -> list[tuple[str, float, float]]:
    views = rs.views
    folds = fold_indices(len(views), 5, seed)
    rows = []
    for name in realdata.OPENCV_METHODS:
        r = cross_validate(realdata.opencv_fit(name), views, folds, f"OpenCV {name}")
        rows.append((r.name, r.score, r.rms_mm))
    start = time.perf_counter()
    r = cross_validate(realdata.handeye_fit(rs), views, folds, "handeye default")
    rows.append((f"{r.name} ({time.perf_counter() - start:.1f} s)", r.score, r.rms_mm))
    candidates = pose_candidates("daniilidis")
    if views.has_pixels:
        candidates |= pixel_candidates(views, "daniilidis", rs.observations.intrinsics_source == "estimated")
    for name, fit in candidates.items():
        r = cross_validate(fit, views, folds, f"handeye {name}")
        rows.append((r.name, r.score, r.rms_mm))
    return rows


def main(names: list[str]) -> None:
    with tempfile.TemporaryDirectory() as scratch:
        sets = realdata.load_all(Path(scratch), names or None)
        print(f"{'set / estimator':<44} {'held-out':>10} {'mm':>9} {'ratio':>7}")
        for rs in sets:
            rows = bench_set(rs)
            best = min(score for name, score, _ in rows if name.startswith("OpenCV"))
            unit = "px" if rs.views.has_pixels else "mm"
            print(f"{rs.name} ({len(rs.views)} views, held-out error in {unit}; ratio to the best OpenCV method)")
            for name, score, mm in rows:
                ratio = score / best if np.isfinite(score) else np.inf
                print(f"  {name:<42} {score:10.3f} {mm:9.3f} {ratio:7.2f}")


def repeated(names: list[str], seeds: int) -> None:
    """The ratios over ``seeds`` random splits into 5 folds: median and range per set and row."""
    with tempfile.TemporaryDirectory() as scratch:
        sets = realdata.load_all(Path(scratch), names or None)
        print(f"ratio to the best OpenCV method of each split, over {seeds} splits into 5 folds: median [min-max]")
        for rs in sets:
            ratios: dict[str, list[float]] = {}
            for seed in range(seeds):
                rows = bench_set(rs, seed)
                best = min(score for name, score, _ in rows if name.startswith("OpenCV"))
                for name, score, _ in rows:
                    ratios.setdefault(name.split(" (")[0], []).append(score / best if np.isfinite(score) else np.inf)
            print(f"{rs.name} ({len(rs.views)} views)")
            for name, r in ratios.items():
                print(f"  {name:<42} {np.median(r):7.3f} [{np.min(r):.2f}-{np.max(r):.2f}]")


if __name__ == "__main__":
    args = sys.argv[1:]
    if "--seeds" in args:
        k = args.index("--seeds")
        repeated(args[:k] + args[k + 2:], int(args[k + 1]))
    else:
        main(args)
