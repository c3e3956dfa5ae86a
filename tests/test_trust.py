"""Trust on realistic data: the realistic simulator, verdicts instead of refusals, honest
uncertainty, the board-scale check, and the faults of issue 18 (wrong square size, swapped poses,
an image whose points are all rejected)."""

from __future__ import annotations

import csv
import re
import shutil
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

import handeye
import realdata
from handeye.cli import main
from handeye.estimation.diagnostics import board_scale
from handeye.estimation.refinement import refine_reprojection
from handeye.frames.metrics import rotation_error, translation_error
from handeye.geometry.se3 import invert, make_transform
from handeye.simulate import EXACT, REALISTIC, arm_forward_kinematics, random_scene, realistic_scene

SAMPLE = Path(handeye.__file__).parent / "data" / "sample_session"


# --- the realistic simulator ----------------------------------------------------------------

@pytest.mark.parametrize("setup", ["eye_in_hand", "eye_to_hand"])
def test_realistic_scene_without_errors_is_exact(setup):
    sc = realistic_scene(12, setup, 3, errors=EXACT)
    assert np.abs(sc.flange2base - sc.flange2base_true).max() < 1e-12
    assert np.abs(sc.target2cam - sc.target2cam_true).max() < 1e-12
    assert np.abs(arm_forward_kinematics(sc.joints) - sc.flange2base).max() < 1e-12
    cal = handeye.calibrate_poses(sc.flange2base, sc.target2cam, setup, refine="none")
    assert rotation_error(cal.X, sc.X) < 1e-9 and translation_error(cal.X, sc.X) < 1e-9


def test_realistic_errors_are_those_of_real_robots():
    """Kinematic errors that depend on the pose (not one constant offset), PnP errors larger along
    the optical axis than across it, and planar flips at about the stated rate."""
    kin = replace(EXACT, dh_length_mm=0.3, dh_angle_deg=0.02)
    sc = realistic_scene(15, "eye_in_hand", 5, errors=kin)
    D = invert(sc.flange2base_true) @ sc.flange2base  # the reported pose's error, in the flange frame
    err = 1e3 * np.linalg.norm(D[:, :3, 3], axis=1)
    assert 0.1 < np.median(err) < 3.0  # ~0.5-1 mm, as arms are
    assert np.std(D[:, :3, 3], axis=0).max() > 0.2 * np.abs(D[:, :3, 3]).mean()  # it varies with the pose
    cam = replace(EXACT, pixel_px=0.3)
    depth, lateral = [], []
    for seed in range(5):
        sc = realistic_scene(15, "eye_in_hand", seed, errors=cam)
        d = sc.target2cam[:, :3, 3] - sc.target2cam_true[:, :3, 3]
        ray = sc.target2cam_true[:, :3, 3] / np.linalg.norm(sc.target2cam_true[:, :3, 3], axis=1, keepdims=True)
        along = np.einsum("ni,ni->n", d, ray)
        depth.append(np.abs(along))
        lateral.append(np.linalg.norm(d - along[:, None] * ray, axis=1))
    assert np.median(np.concatenate(depth)) > 2 * np.median(np.concatenate(lateral))
    flips = replace(EXACT, pixel_px=0.3, flip_probability=0.2)
    n_flipped = sum(realistic_scene(15, "eye_in_hand", s, errors=flips).flipped.sum() for s in range(10))
    assert 10 <= n_flipped <= 50  # 150 poses at 0.2
    sc = realistic_scene(15, "eye_in_hand", 1, errors=replace(flips, flip_probability=0.5))
    err = rotation_error(sc.target2cam, sc.target2cam_true)
    assert np.median(err[sc.flipped]) > 10 * np.median(err[~sc.flipped])


def _one_session(args):
    """One realistic session: handeye's default against OpenCV's methods (translation errors, mm),
    and whether X's error is within 3 reported std."""
    seed, setup = args
    sc = realistic_scene(15, setup, seed, errors=REALISTIC)
    cal = handeye.calibrate_poses(sc.flange2base, sc.target2cam, setup)
    d_rot = np.degrees(Rotation.from_matrix(cal.X[:3, :3] @ sc.X[:3, :3].T).as_rotvec())
    d_t = 1e3 * (cal.X[:3, 3] - sc.X[:3, 3])
    covered = bool(np.linalg.norm(d_t) <= 3 * np.linalg.norm(cal.std[3:])
                   and np.linalg.norm(d_rot) <= 3 * np.linalg.norm(cal.std[:3]))
    g2b = sc.flange2base if setup == "eye_in_hand" else invert(sc.flange2base)
    opencv = {}
    for name in ("TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS"):
        R, t = cv2.calibrateHandEye(list(g2b[:, :3, :3]), list(g2b[:, :3, 3]), list(sc.target2cam[:, :3, :3]),
                                    list(sc.target2cam[:, :3, 3]), method=getattr(cv2, f"CALIB_HAND_EYE_{name}"))
        opencv[name] = 1e3 * translation_error(make_transform(R, t.ravel()), sc.X)
    return setup, cal.verdict, covered, 1e3 * translation_error(cal.X, sc.X), opencv, int(sc.flipped.sum()), cal.estimator


@pytest.fixture(scope="module")
def realistic_study():
    """200 realistic sessions (100 per setup, 15 poses each), on both cores."""
    tasks = [(seed, setup) for setup in ("eye_in_hand", "eye_to_hand") for seed in range(100)]
    with realdata.worker_pool() as pool:
        return list(pool.map(_one_session, tasks, chunksize=10))


@pytest.mark.slow
def test_realistic_sessions_are_answered_not_refused(realistic_study):
    """At most 2 of 200 solvable sessions called inconsistent (none raises)."""
    verdicts = [r[1] for r in realistic_study]
    print({v: verdicts.count(v) for v in set(verdicts)}, "flipped poses:", sum(r[5] for r in realistic_study))
    assert len(verdicts) == 200 and verdicts.count("inconsistent") <= 2


@pytest.mark.slow
def test_realistic_std_covers_the_error(realistic_study):
    """X's error within 3 reported std (translation and rotation, as norms) in >= 95% of sessions,
    for each setup."""
    for setup in ("eye_in_hand", "eye_to_hand"):
        covered = [r[2] for r in realistic_study if r[0] == setup]
        print(f"{setup}: within 3 std in {np.mean(covered):.1%}")
        assert np.mean(covered) >= 0.95


@pytest.mark.slow
def test_realistic_median_error_beats_every_opencv_method(realistic_study):
    for setup in ("eye_in_hand", "eye_to_hand"):
        rows = [r for r in realistic_study if r[0] == setup]
        ours = np.median([r[3] for r in rows])
        theirs = {m: np.median([r[4][m] for r in rows]) for m in rows[0][4]}
        estimators = [r[6] for r in rows]
        print(f"{setup}: median translation error handeye {ours:.3f} mm, OpenCV {theirs}; "
              f"estimators {({e: estimators.count(e) for e in set(estimators)})}")
        assert ours <= min(theirs.values())


# --- the board scale ------------------------------------------------------------------------

@pytest.mark.parametrize("setup", ["eye_in_hand", "eye_to_hand"])
def test_board_scale_finds_a_wrong_square_size(setup):
    """On the poses the check keeps (the scene has a flipped planar pose for eye-to-hand, which the
    check leaves out): the scale is 1 as given, 1.2 with the square given as 25 mm for 30."""
    sc = realistic_scene(15, setup, 7)
    d = handeye.diagnose(sc.flange2base, sc.target2cam, setup)
    assert abs(d.scale - 1) < 4 * d.scale_std + 0.01 and d.verdict != "inconsistent"
    keep = np.setdiff1d(np.arange(15), d.outliers)
    t2c = sc.target2cam.copy()
    t2c[:, :3, 3] *= 25 / 30  # the square given as 25 mm for 30
    s, sd = board_scale(sc.flange2base[keep], t2c[keep], setup)
    assert abs(s - 1.2) < 4 * sd + 0.005 and abs(s - 1) > 10 * sd
    cal = handeye.calibrate_poses(sc.flange2base, t2c, setup)
    factors = [float(m) for a in cal.diagnostics.advice for m in re.findall(r"multiply it by ([0-9.]+)", a)]
    assert cal.verdict == "inconsistent" and len(factors) == 1 and abs(factors[0] - 1.2) < 0.01
    # X from the camera's poses at the robot's scale, not as given: as close to the truth as from the right poses
    right = handeye.calibrate_poses(sc.flange2base, sc.target2cam, setup)
    assert cal.target_scale == pytest.approx(factors[0], abs=1e-4) and cal.std_sources["board_scale"] is not None
    assert 1e3 * translation_error(cal.X, sc.X) <= 3 * np.linalg.norm(cal.std[3:])
    assert translation_error(cal.X, sc.X) < 2 * translation_error(right.X, sc.X) + 5e-4
    assert "target_scale" in handeye.report.result_dict(cal) and "target_scale" not in handeye.report.result_dict(right)


@pytest.mark.parametrize("setup, factor", [("eye_to_hand", 0.9893), ("eye_in_hand", 0.9893)])
def test_a_board_scale_call_that_turns_on_which_poses_are_in_is_said_not_acted_on(setup, factor):
    """Issue 60 item 14: a board 1% off, at the edge of what the check calls a wrong size, is called
    wrong by some subsets of the poses (each without a fifth) and not by others: the check says so
    (weak, the size may be wrong, how many subsets say it) and X is estimated with the size as given,
    where it used to rescale the board or not depending on a fifth of the views. A size 3% off is
    called by every subset: named and acted on as before."""
    seed = 0 if setup == "eye_to_hand" else 1
    sc = realistic_scene(20, setup, seed)
    t2c = sc.target2cam.copy()
    t2c[:, :3, 3] *= factor
    d = handeye.diagnose(sc.flange2base, t2c, setup)
    said = [a for a in d.advice if "the target's size may be wrong" in a]
    assert d.verdict == "weak" and len(said) == 1
    held = int(re.search(r"in: (\d) of 5 subsets", said[0]).group(1))
    assert 0 < held < 5
    cal = handeye.calibrate_poses(sc.flange2base, t2c, setup)
    assert cal.target_scale == 1.0 and cal.verdict != "good"
    t2c[:, :3, 3] *= 0.97 / factor
    d = handeye.diagnose(sc.flange2base, t2c, setup)
    assert d.verdict == "inconsistent" and any("multiply it by 1.03" in a for a in d.advice)


@pytest.mark.slow
def test_a_wrong_square_size_is_not_trusted_as_declared(tmp_path):
    """Images of a 30 mm board declared as 25 mm: the verdict is inconsistent and names the factor,
    and X is not the one the declared size gives: it is estimated with the board at the scale the
    robot's motions give (target_scale 1.2), lands within 3 std of the truth (the std holds the
    scale's error), as close as with the right size declared, and predicts held-out views better
    than X on the declared size; result.json and verify carry the scale."""
    folder = tmp_path / "s"
    sc = handeye.simulate.simulate_realistic_session(folder, 12, "eye_in_hand", 3)
    right = handeye.calibrate(folder, progress=False)
    spec = yaml.safe_load((folder / "session.yaml").read_text())
    spec["target"]["square"] = 0.025
    (folder / "session.yaml").write_text(yaml.safe_dump(spec))
    cal = handeye.calibrate(folder, progress=False)
    declared = handeye.calibrate(folder, progress=False, check=False)
    err = np.degrees(rotation_error(cal.X, sc.X)), 1e3 * translation_error(cal.X, sc.X)
    print(f"scale {cal.target_scale:.4f}; X {err[0]:.3f} deg / {err[1]:.2f} mm from the truth (right size "
          f"{1e3 * translation_error(right.X, sc.X):.2f} mm, declared size {1e3 * translation_error(declared.X, sc.X):.2f} mm); "
          f"held-out {cal.prediction_error['px']:.3f} px against {declared.prediction_error['px']:.3f} px")
    assert cal.verdict == "inconsistent" and abs(cal.target_scale - 1.2) < 0.02
    factors = [float(m) for a in cal.diagnostics.advice for m in re.findall(r"multiply it by ([0-9.]+)", a)]
    assert factors == [pytest.approx(cal.target_scale, abs=1e-4)]
    assert err[0] <= 3 * np.linalg.norm(cal.std[:3]) and err[1] <= 3 * np.linalg.norm(cal.std[3:])
    assert 1e3 * translation_error(cal.X, right.X) < 0.5 < 1e3 * translation_error(declared.X, sc.X)
    assert cal.prediction_error["px"] < declared.prediction_error["px"]
    assert cal.std_sources["board_scale"] is not None
    assert not any("focal length" in a for a in cal.diagnostics.advice)  # K given: the size it is
    handeye.write_calibration(cal, tmp_path / "out")
    assert handeye.load_result(tmp_path / "out").target_scale == pytest.approx(cal.target_scale)


# --- the bundled sample, as given and with the faults --------------------------------

def _truth():
    return np.array(yaml.safe_load((SAMPLE / "ground_truth.yaml").read_text())["cam2flange"])


def _within_3_std(cal, X):
    d = np.r_[np.degrees(Rotation.from_matrix(X[:3, :3] @ cal.X[:3, :3].T).as_rotvec()), 1e3 * (X[:3, 3] - cal.X[:3, 3])]
    print(f"error in std: {np.round(d / cal.std, 2)}")
    return bool(np.all(np.abs(d) < 3 * cal.std))


def test_sample_within_3_std_of_its_ground_truth():
    cal = handeye.calibrate(SAMPLE, progress=False)
    assert cal.verdict == "good" and _within_3_std(cal, _truth())
    assert cal.prediction_error is not None and cal.prediction_error["px"] < 1.0


def test_sample_with_a_wrong_square_size_is_not_good(tmp_path):
    folder = tmp_path / "s"
    shutil.copytree(SAMPLE, folder)
    spec = (folder / "session.yaml").read_text()
    assert "square: 0.03" in spec
    (folder / "session.yaml").write_text(spec.replace("square: 0.03", "square: 0.025"))
    cal = handeye.calibrate(folder, progress=False)
    assert cal.verdict == "inconsistent" and abs(cal.diagnostics.scale - 1.2) < 0.02
    assert any("target's size" in a for a in cal.diagnostics.advice)
    assert main(["calibrate", str(folder), "--no-progress"]) == 2  # answered, but inconsistent: check's status


@pytest.mark.slow
def test_sample_with_two_swapped_poses(tmp_path, capsys):
    """The robot poses of images 3 and 7 swapped: both named, no traceback, X within 3 std."""
    folder = tmp_path / "s"
    shutil.copytree(SAMPLE, folder)
    rows = list(csv.reader((folder / "poses.csv").open()))
    assert rows[4][0] == "003.jpg" and rows[8][0] == "007.jpg"
    rows[4][1:], rows[8][1:] = rows[8][1:], rows[4][1:]
    with (folder / "poses.csv").open("w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    cal = handeye.calibrate(folder, progress=False)
    assert cal.diagnostics.outliers == [3, 7]
    named = " ".join(cal.notes) + " ".join(f"{n} {r}" for n, r in cal.skipped)
    assert "003.jpg" in named and "007.jpg" in named
    assert _within_3_std(cal, _truth())
    code = main(["calibrate", str(folder), "--no-progress", "--out", str(tmp_path / "out")])
    captured = capsys.readouterr()
    assert code in (0, 1) and "Traceback" not in captured.err and (tmp_path / "out" / "report.html").is_file()


def test_an_image_whose_points_are_all_rejected_does_not_crash():
    """The crash of issue 18: a robust pixel fit that sets aside every point of one image (its robot
    pose belongs to another image) must not reach the projection with no points."""
    sc = realistic_scene(10, "eye_in_hand", 2, errors=replace(EXACT, pixel_px=0.2))
    f2b = sc.flange2base.copy()
    f2b[[3, 6]] = f2b[[6, 3]]
    obj = [sc.object_points] * len(f2b)
    img = list(sc.image_points)
    ref = refine_reprojection(sc.X, sc.Z, f2b, obj, img, sc.K, sc.dist, "eye_in_hand", robust=True)
    assert set(ref.rejected_images) == {3, 6} and np.isnan(ref.per_image_rms_px[[3, 6]]).all()
    assert translation_error(ref.X, sc.X) < 1e-3


# --- verdicts, not refusals -------------------------------------------------------------------

def test_inconsistent_data_are_answered_unless_strict():
    sc = realistic_scene(12, "eye_in_hand", 4)
    with pytest.raises(handeye.InputMismatchError, match="robot poses are inverted"):
        handeye.calibrate_poses(invert(sc.flange2base), sc.target2cam, strict=True)
    cal = handeye.calibrate_poses(invert(sc.flange2base), sc.target2cam)
    assert cal.verdict == "inconsistent" and cal.diagnostics.convention_hint == "invert_robot_poses"
    with pytest.raises(handeye.DegenerateMotionError):  # not even X's rotation determined: still an error
        f = make_transform(np.eye(3), np.c_[np.linspace(0, 0.1, 6), np.zeros(6), np.zeros(6)])
        handeye.calibrate_poses(f, invert(f))


def test_the_choice_predicts_no_worse_than_every_closed_form():
    """On the user's own data, by the cross-validation that made the choice, within the one-
    standard-error slack; and the result carries the table and the std of every source."""
    sc = realistic_scene(15, "eye_to_hand", 9)
    cal = handeye.calibrate_poses(sc.flange2base, sc.target2cam, "eye_to_hand")
    cv = cal.cross_validation
    closed = [v["mm"] for k, v in cv.items() if k in handeye.solvers.available()]
    assert cal.prediction_error["mm"] <= 1.1 * min(closed)
    assert set(cal.std_sources) == {"model", "jackknife", "robot_accuracy"}
    assert np.all(cal.std >= cal.std_sources["jackknife"] - 1e-9)
    exact = handeye.calibrate_poses(sc.flange2base, sc.target2cam, "eye_to_hand", robot_accuracy=None)
    assert np.all(exact.std <= cal.std + 1e-12) and exact.std_sources["robot_accuracy"] is None
    for refine in ("auto", "pose"):  # checked whatever the refinement, before any work
        with pytest.raises(handeye.InputMismatchError, match="robot_accuracy"):
            handeye.calibrate_poses(sc.flange2base, sc.target2cam, "eye_to_hand", refine=refine, robot_accuracy=(-1, 0.3))


def test_solvers_far_apart_in_std_make_the_verdict_weak():
    """The verdict looks at the spread between solvers: with the std the data support the realistic
    session stays good; had the std promised 100x less, the closed forms would sit far outside it."""
    from handeye.estimation.estimators import choose, pose_candidates
    from handeye.estimation.validation import Views
    from handeye.pipelines.calibration import _spread_judged

    sc = realistic_scene(15, "eye_in_hand", 11)
    cal = handeye.calibrate_poses(sc.flange2base, sc.target2cam, "eye_in_hand")
    assert cal.verdict == "good"
    views = Views(cal.flange2base, cal.target2cam, "eye_in_hand")
    choice = choose(views, pose_candidates("daniilidis", views))
    assert _spread_judged(cal, choice).verdict == "good"
    promised = _spread_judged(replace(cal, std=cal.std / 100), choice)
    assert promised.verdict == "weak" and any("closed-form solvers" in a for a in promised.diagnostics.advice)


def test_a_view_with_the_camera_at_the_target_origin_scores_a_number():
    """Pose pairs are scored on a virtual target whose first point is its origin; a camera pose at
    that origin (zero camera-to-target translation: a tracker's bad sample) divided 0 by 0 and
    warned (found by fuzzing calibrate_poses). The point at the camera centre adds no error; the
    others score as usual."""
    import warnings

    from handeye.estimation.validation import Views, view_errors

    sc = random_scene(6, "eye_in_hand", rng=3)
    t2c = sc.target2cam.copy()
    t2c[2, :3, 3] = 0.0
    views = Views(sc.flange2base, t2c, "eye_in_hand")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _, mm = view_errors(sc.X, sc.Z, views, np.arange(6))
    assert np.isfinite(mm).all() and mm[2] > 0 and np.allclose(np.delete(mm, 2), 0.0, atol=1e-9)


def test_a_wrong_scale_with_estimated_intrinsics_names_the_focal_length_too(tmp_path):
    """A board declared 25 mm for 30, the intrinsics estimated from the same images: the advice names
    the factor, and that a focal length off by it would look the same (with K given it does not)."""
    folder = tmp_path / "s"
    handeye.simulate.simulate_session(folder, "eye_in_hand", 10, "chessboard", noise_px=0.2, seed=2,
                                      write_intrinsics=False)
    spec = yaml.safe_load((folder / "session.yaml").read_text())
    spec["target"]["square"] *= 25 / 30
    (folder / "session.yaml").write_text(yaml.safe_dump(spec))
    cal = handeye.calibrate(folder, progress=False, refine="none")
    assert cal.verdict == "inconsistent" and cal.intrinsics_source == "estimated"
    assert any("multiply it by 1.2" in a for a in cal.diagnostics.advice)
    assert any("a focal length off by that factor" in a for a in cal.diagnostics.advice)
