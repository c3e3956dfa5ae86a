"""Held-out prediction error on every real capture in ../shared/data/real: handeye against OpenCV.

Per set, 5-fold cross-validation on the same folds for everyone: fit on 4/5 of the views, predict
where the target's points appear in the other 1/5 from the robot pose alone, and compare with what
the camera saw (pixels for image sets, millimetres at the target's distance for pose pairs; see
handeye.validation). Rows: every OpenCV calibrateHandEye method (on the same PnP poses), handeye's
default pipeline (which chooses its estimator by an inner cross-validation on the training part
only), and each handeye estimator on its own. The ratio is against the best OpenCV method of the
set, measured in the same run.

Run from the repository root: ``python benchmarks/bench_realdata.py [SET ...]``.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import numpy as np  # noqa: E402

import realdata  # noqa: E402
from handeye.estimators import pixel_candidates, pose_candidates  # noqa: E402
from handeye.validation import cross_validate, fold_indices  # noqa: E402


def bench_set(rs: realdata.RealSet) -> list[tuple[str, float, float]]:
    views = rs.views
    folds = fold_indices(len(views), 5)
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


if __name__ == "__main__":
    main(sys.argv[1:])
