"""Every real capture in ../shared/data/real (ViSP 2025 / 2022 / 2018, ROS-Industrial's ChArUco and
10x10 circle grid, Tabb's dataset 1, ETH's streams paired by time): no traceback, handeye's
held-out prediction error no worse than the best of OpenCV's calibrateHandEye methods on the same
folds, and the reported std within a factor 2 of the jackknife spread.

The held-out error (handeye.validation): 5-fold cross-validation over the views; each view is
predicted from its robot pose by X and Z fitted on the other folds, and compared with what the
camera saw (pixels for image sets, millimetres at the target's distance for pose pairs). handeye's
row is its whole default pipeline run on each training part (check, estimator chosen by an inner
cross-validation of that part alone), as a user would run it on those views.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest

import handeye
import realdata
from handeye.calibration import calibrate_observed
from handeye.validation import cross_validate, fold_indices

SETS = ["visp_eye_in_hand_2025", "visp_eye_to_hand_2025", "visp_eye_in_hand_2022", "visp_posepairs_2018",
        "industrial_charuco", "industrial_10x10", "tabb_ds1", "eth_robot_arm"]


def _evaluate(name: str) -> dict:
    with tempfile.TemporaryDirectory() as scratch:
        rs = realdata.load_all(Path(scratch), [name])[0]
        views = rs.views
        folds = fold_indices(len(views), 5)
        opencv = {m: cross_validate(realdata.opencv_fit(m), views, folds, m).score for m in realdata.OPENCV_METHODS}
        ours = cross_validate(realdata.handeye_fit(rs), views, folds, "handeye").score
        if rs.observations is not None:
            cal = calibrate_observed(rs.observations)
        else:
            cal = handeye.calibrate_poses(views.flange2base, views.target2cam, views.setup)
        return {"n": len(views), "pixels": views.has_pixels, "opencv": opencv, "handeye": ours, "std": cal.std,
                "jackknife": cal.std_sources["jackknife"], "estimator": cal.estimator, "verdict": cal.verdict}


@pytest.fixture(scope="module")
def real_results():
    if not realdata.REAL_DATA.is_dir():
        pytest.skip(f"real data not available at {realdata.REAL_DATA}")
    with realdata.worker_pool() as pool:
        return dict(zip(SETS, pool.map(_evaluate, SETS)))


@pytest.mark.parametrize("name", SETS)
def test_held_out_error_no_worse_than_opencv(real_results, name):
    r = real_results[name]
    best = min(r["opencv"], key=r["opencv"].get)
    unit = "px" if r["pixels"] else "mm"
    print(f"{name} ({r['n']} views): handeye {r['handeye']:.3f} {unit}, best OpenCV {best} {r['opencv'][best]:.3f} "
          f"(ratio {r['handeye'] / r['opencv'][best]:.3f}); all OpenCV {({k: round(v, 3) for k, v in r['opencv'].items()})}; "
          f"full-data estimator {r['estimator']}, verdict {r['verdict']}")
    assert np.isfinite(r["handeye"]) and r["handeye"] <= r["opencv"][best]


@pytest.mark.parametrize("name", SETS)
def test_reported_std_within_factor_2_of_the_jackknife(real_results, name):
    r = real_results[name]
    for part, sl in (("rotation", slice(0, 3)), ("translation", slice(3, 6))):
        ratio = np.linalg.norm(r["std"][sl]) / np.linalg.norm(r["jackknife"][sl])
        print(f"{name}: {part} std / jackknife {ratio:.2f}")
        assert 0.5 <= ratio <= 2.0
