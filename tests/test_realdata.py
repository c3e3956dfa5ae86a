"""Every real capture in ../shared/data/real (ViSP 2025 / 2022 / 2018, ROS-Industrial's ChArUco and
10x10 circle grid, Tabb's dataset 1, ETH's streams paired by time): no traceback, handeye's
held-out prediction error no worse than the best of OpenCV's calibrateHandEye methods on the same
folds; the reported std never narrower than half the jackknife spread, and wider than twice it only
by the robot's accuracy (raised to what the views show of the robot's error) and the intrinsics'
error; and X within 3 std of the closed forms' medoid unless the verdict says the data are not good,
or says that X was kept although the closed forms land further.

The held-out error (handeye.estimation.validation): 5-fold cross-validation over the views; each view is
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
from handeye.estimation.diagnostics import closed_form
from handeye.estimation.validation import cross_validate, fold_indices
from handeye.frames.metrics import rotation_error, translation_error
from handeye.pipelines.calibration import calibrate_observed

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
        keep = np.asarray(cal.pose_indices)
        closed = [closed_form(views.flange2base[keep], views.target2cam[keep], views.setup, m)[0]
                  for m in handeye.solvers.available(closed_forms=True)]
        return {"n": len(views), "pixels": views.has_pixels, "opencv": opencv, "handeye": ours, "std": cal.std,
                "sources": cal.std_sources, "estimator": cal.estimator, "verdict": cal.verdict,
                "advice": list(cal.diagnostics.advice),
                "from_closed": _from_medoid(cal.X, closed)}


def _from_medoid(X, closed) -> tuple[float, float]:
    """How far X is (deg, mm) from the medoid of the closed forms' estimates (the one with the least
    summed distance to the others, rotation in degrees plus translation in millimetres)."""
    d = [[np.degrees(rotation_error(A, B)) + 1e3 * translation_error(A, B) for B in closed] for A in closed]
    medoid = closed[int(np.argmin(np.sum(d, axis=1)))]
    return float(np.degrees(rotation_error(X, medoid))), float(1e3 * translation_error(X, medoid))


@pytest.fixture(scope="module")
def real_results():
    if not realdata.REAL_DATA.is_dir():
        pytest.skip(f"real data not available at {realdata.REAL_DATA}")
    with realdata.worker_pool() as pool:
        return dict(zip(SETS, pool.map(_evaluate, SETS)))


@pytest.mark.slow
@pytest.mark.parametrize("name", SETS)
def test_held_out_error_no_worse_than_opencv(real_results, name):
    r = real_results[name]
    best = min(r["opencv"], key=r["opencv"].get)
    unit = "px" if r["pixels"] else "mm"
    print(f"{name} ({r['n']} views): handeye {r['handeye']:.3f} {unit}, best OpenCV {best} {r['opencv'][best]:.3f} "
          f"(ratio {r['handeye'] / r['opencv'][best]:.3f}); all OpenCV {({k: round(v, 3) for k, v in r['opencv'].items()})}; "
          f"full-data estimator {r['estimator']}, verdict {r['verdict']}")
    assert np.isfinite(r["handeye"]) and r["handeye"] <= r["opencv"][best]


@pytest.mark.slow
@pytest.mark.parametrize("name", SETS)
def test_reported_std_is_the_jackknife_and_the_errors_it_cannot_see(real_results, name):
    r = real_results[name]
    parts = [r["sources"][k] for k in ("jackknife", "robot_accuracy", "intrinsics") if r["sources"].get(k) is not None]
    for part, sl in (("rotation", slice(0, 3)), ("translation", slice(3, 6))):
        jack = np.linalg.norm(r["sources"]["jackknife"][sl])
        unseen = np.sqrt(sum(np.linalg.norm(p[sl]) ** 2 for p in parts))
        std = np.linalg.norm(r["std"][sl])
        print(f"{name}: {part} std / jackknife {std / jack:.2f}, std / (jackknife, robot accuracy, intrinsics) "
              f"{std / unseen:.2f}")
        assert 0.5 * jack <= std <= 2.0 * unseen


@pytest.mark.slow
@pytest.mark.parametrize("name", SETS)
def test_x_within_3_std_of_the_closed_forms_or_the_verdict_says_so(real_results, name):
    r = real_results[name]
    deg, mm = r["from_closed"]
    limit = 3 * np.linalg.norm(r["std"][:3]), 3 * np.linalg.norm(r["std"][3:])
    said = [a for a in r["advice"] if "closed-form solvers land" in a]
    print(f"{name}: X {deg:.3f} deg / {mm:.2f} mm from the closed forms' medoid, 3 std {limit[0]:.3f} deg / "
          f"{limit[1]:.2f} mm, verdict {r['verdict']}{': ' + said[0] if said else ''}")
    assert (deg <= limit[0] and mm <= limit[1]) or r["verdict"] != "good" or said
