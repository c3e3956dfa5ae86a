"""X under real robots' errors (kinematic errors that depend on the pose, from a calibrated arm's
~0.2 mm to an uncalibrated one's ~3 mm): the simulator's sweep, rendered realistic sessions, and the
estimator choice that does not trust the pixel refinement's exact-robot model when the robot's
errors dominate its residuals. The full sweep against OpenCV is benchmarks/bench_robot_errors.py."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import yaml

import handeye
from handeye.errors import HandEyeError
from handeye.estimation.estimators import PIXEL, POSE, ROBOT_DOMINATES, choose, pixel_candidates, pose_candidates
from handeye.frames.metrics import rotation_error, translation_error
from handeye.io.session import load_session
from handeye.pipelines.calibration import calibrate_observed, observe
from handeye.simulate import EXACT, REALISTIC, realistic_scene, robot_accuracy_of, simulate_realistic_session


def test_the_sweep_spans_real_arms_accuracy():
    """scaled(0.25) is a calibrated arm (~0.2-0.4 mm), scaled(3) an uncalibrated one (~2-4 mm); the
    joint waves add a smooth error; scaled(0) leaves the timing and noise terms alone."""
    errs = replace(REALISTIC, joint_wave_deg=0.02)
    acc = {k: np.median([robot_accuracy_of(realistic_scene(12, "eye_in_hand", s, errors=errs.scaled(k)))[1]
                         for s in range(6)]) for k in (0.25, 1.0, 3.0)}
    assert 0.1 < acc[0.25] < 0.5 and 0.5 < acc[1.0] < 1.6 and 1.8 < acc[3.0] < 4.5, acc
    assert errs.scaled(0).dh_length_mm == 0 and errs.scaled(0).robot_mm == errs.robot_mm
    plain = realistic_scene(12, "eye_in_hand", 2, errors=replace(EXACT, dh_length_mm=0.3))
    waved = realistic_scene(12, "eye_in_hand", 2, errors=replace(EXACT, dh_length_mm=0.3, joint_wave_deg=0.05))
    assert np.allclose(plain.joints, waved.joints)  # the same commanded joints ...
    assert np.abs(plain.flange2base_true - waved.flange2base_true).max() > 1e-5  # ... the arm goes elsewhere
    with pytest.raises(HandEyeError, match="factor"):
        REALISTIC.scaled(-1)


@pytest.mark.slow
def test_a_rendered_realistic_session_calibrates_to_its_truth(tmp_path):
    sc = simulate_realistic_session(tmp_path / "s", 10, "eye_to_hand", 4)
    truth = yaml.safe_load((tmp_path / "s" / "ground_truth.yaml").read_text())
    assert np.allclose(truth["cam2base"], sc.X) and truth["robot_accuracy_deg_mm"][1] > 0
    cal = handeye.calibrate(tmp_path / "s", progress=False)
    assert 1e3 * translation_error(cal.X, sc.X) <= 3 * np.linalg.norm(cal.std[3:])
    assert np.degrees(rotation_error(cal.X, sc.X)) <= 3 * np.linalg.norm(cal.std[:3])
    with pytest.raises(HandEyeError, match="already holds a session"):
        simulate_realistic_session(tmp_path / "s", 10, "eye_to_hand", 4)


def _choice(folder):
    obs = observe(load_session(folder), jobs=1, progress=False)
    idx = np.asarray(handeye.calibrate_poses(obs.flange2base, obs.target2cam, obs.session.setup,
                                            refine="none", uncertainty=False).pose_indices)
    views = obs.views(idx)
    return obs, choose(views, pose_candidates("daniilidis", views) | pixel_candidates(views, "daniilidis"))


@pytest.mark.slow
def test_the_pixel_refinement_is_preferred_only_while_the_robot_is_exact(tmp_path):
    """An exact robot: the pixel fit's residual is the camera's (ratio ~1), the pixel refinement is
    preferred. An uncalibrated arm (~3 mm): the ratio is several, the pose refinement is preferred,
    and the default's X is closer to the truth than the pixel refinement's."""
    exact = replace(EXACT, pixel_px=0.1)
    simulate_realistic_session(tmp_path / "exact", 12, "eye_in_hand", 1, errors=exact)
    _, choice = _choice(tmp_path / "exact")
    assert choice.robot_error_ratio < ROBOT_DOMINATES and choice.prefer == PIXEL
    worse, better = [], []
    for seed in range(3):
        folder = tmp_path / f"arm{seed}"
        sc = simulate_realistic_session(folder, 12, "eye_in_hand", seed,
                                        errors=replace(REALISTIC, pixel_px=0.1).scaled(3))
        obs, choice = _choice(folder)
        assert choice.robot_error_ratio > 2 * ROBOT_DOMINATES and choice.prefer == POSE
        cal = calibrate_observed(obs)
        pixel = calibrate_observed(obs, refine="reprojection")
        better.append(translation_error(cal.X, sc.X))
        worse.append(translation_error(pixel.X, sc.X))
    assert np.median(better) < np.median(worse), (better, worse)


@pytest.mark.slow
def test_an_uncalibrated_arm_is_covered_once_its_accuracy_is_given(tmp_path):
    """The constant part of an uncalibrated arm's error (~3-4 mm here) moves X and no spread sees it:
    with the default robot_accuracy (a calibrated arm's 0.3 mm per axis) X was outside 3 std in 30%
    of such eye-to-hand sessions (bench_robot_errors.py), in none once the arm's accuracy is given.
    Seeds 3 and 8 are two of those sessions (3.7 and 6.4 std off with the default); the default's note
    names the assumption to change."""
    errors = replace(REALISTIC, pixel_px=0.1, joint_wave_deg=0.02).scaled(3)
    for seed in (3, 8):
        sc = simulate_realistic_session(tmp_path / f"s{seed}", 12, "eye_to_hand", seed, errors=errors)
        obs = observe(load_session(tmp_path / f"s{seed}"), jobs=1, progress=False)
        default = calibrate_observed(obs)
        assert any("--robot-accuracy" in note for note in default.notes)
        given = calibrate_observed(obs, robot_accuracy=tuple(np.asarray(robot_accuracy_of(sc)) / np.sqrt(3)))
        assert np.linalg.norm(given.std[3:]) > np.linalg.norm(default.std[3:])
        assert 1e3 * translation_error(given.X, sc.X) <= 3 * np.linalg.norm(given.std[3:])
        assert np.degrees(rotation_error(given.X, sc.X)) <= 3 * np.linalg.norm(given.std[:3])


def _pose_only(args):
    """X's error within 3 of the default's reported std on one pose-only session, the std's
    translation norm (mm) and whether the verdict names the robot's accuracy."""
    level, setup, seed = args
    sc = realistic_scene(12, setup, seed, errors=replace(REALISTIC, pixel_px=0.1, joint_wave_deg=0.02).scaled(level))
    cal = handeye.calibrate_poses(sc.flange2base, sc.target2cam, setup)
    covered = (np.degrees(rotation_error(cal.X, sc.X)) <= 3 * np.linalg.norm(cal.std[:3])
               and 1e3 * translation_error(cal.X, sc.X) <= 3 * np.linalg.norm(cal.std[3:]))
    named = any("the robot's accuracy alone" in a for a in cal.diagnostics.advice)
    return covered, float(np.linalg.norm(cal.std[3:])), cal.verdict, named


@pytest.mark.slow
def test_the_default_std_covers_an_uncalibrated_arm_and_says_why():
    """The sweep's coverage, pose pairs alone (the full sweep with images and OpenCV:
    bench_robot_errors.py). A calibrated arm (~0.3 mm): X within 3 std and the std not inflated
    (median under 1.5 mm). An uncalibrated one (~3 mm): the views show its pose-dependent error,
    X's std takes 3x that as the unseen constant part, and X is within 3 std in >= 95% of the
    sessions (with the calibrated-arm default alone, 51-85% of such sessions were); most verdicts
    are weak, saying the robot's accuracy is why."""
    import realdata

    tasks = [(level, setup, seed) for level in (0.25, 3.0) for setup in ("eye_in_hand", "eye_to_hand")
             for seed in range(100, 110)]
    with realdata.worker_pool() as pool:
        rows = list(pool.map(_pose_only, tasks, chunksize=5))
    calibrated, uncalibrated = rows[:20], rows[20:]
    print(f"~0.3 mm: covered {np.mean([r[0] for r in calibrated]):.0%}, median std {np.median([r[1] for r in calibrated]):.2f} mm; "
          f"~3 mm: covered {np.mean([r[0] for r in uncalibrated]):.0%}, median std {np.median([r[1] for r in uncalibrated]):.2f} "
          f"mm, weak for the robot {sum(r[3] for r in uncalibrated)} of 20")
    assert all(r[0] for r in calibrated) and np.median([r[1] for r in calibrated]) < 1.5
    assert np.mean([r[0] for r in uncalibrated]) >= 0.95
    assert sum(r[2] == "weak" and r[3] for r in uncalibrated) >= 10


@pytest.mark.slow
def test_the_robot_error_the_views_show(tmp_path):
    """robot_error_seen: what an exact robot's views show beyond the camera's noise is ~0; an
    uncalibrated arm's is several tenths of a millimetre per axis, and the default's std says so."""
    from handeye.estimation.validation import robot_error_seen

    simulate_realistic_session(tmp_path / "exact", 12, "eye_in_hand", 1, errors=replace(EXACT, pixel_px=0.1))
    sc = simulate_realistic_session(tmp_path / "arm", 12, "eye_in_hand", 1,
                                    errors=replace(REALISTIC, pixel_px=0.1, joint_wave_deg=0.02).scaled(3))
    seen = {}
    for name in ("exact", "arm"):
        obs = observe(load_session(tmp_path / name), jobs=1, progress=False)
        cal = calibrate_observed(obs)
        seen[name] = robot_error_seen(cal.X, cal.Z, obs.views(np.asarray(cal.pose_indices)))
    print(f"seen: exact robot {seen['exact']:.3f} mm, uncalibrated arm {seen['arm']:.3f} mm per axis")
    assert seen["exact"] < 0.03 and seen["arm"] > 0.15
    assert 1e3 * translation_error(cal.X, sc.X) <= 3 * np.linalg.norm(cal.std[3:])
    assert np.linalg.norm(cal.std_sources["robot_accuracy"][3:]) >= np.sqrt(3) * 3 * seen["arm"] - 1e-9
    assert any("the robot's poses miss what the camera saw" in n for n in cal.notes)
