"""Calibrated uncertainty: the covariance of the refinements against Monte-Carlo truth, the std every estimator
reports (jackknife, robot accuracy, intrinsics estimated from the images) against the error it promises to cover."""

from __future__ import annotations

import tempfile
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import handeye
import realdata
from handeye.estimation.diagnostics import closed_form
from handeye.estimation.estimators import POSE, intrinsics_cov, pose_fit
from handeye.estimation.refinement import refine_pose, refine_reprojection
from handeye.frames.metrics import rotation_error, translation_error
from handeye.io.session import load_session
from handeye.pipelines.calibration import observe
from handeye.sensors.camera import Detection, solve_pnp, target_from_spec
from handeye.sensors.camera.pnp import intrinsics_covariance, refine_pnp
from handeye.sensors.camera.render import Renderer, target_texture
from handeye.simulate import (
    REALISTIC,
    default_camera,
    perturb_poses,
    random_scene,
    realistic_scene,
    scene_from_viewpoints,
    visible_viewpoints,
)


def _mc_camera():
    size = (640, 480)
    K, dist = default_camera(size)
    target = target_from_spec({"type": "chessboard", "cols": 9, "rows": 6, "square": 0.03})
    return size, K, dist, target


def _mc_run(args):
    """One run of :func:`_monte_carlo` on its drawn data: PnP, closed form, reprojection refinement."""
    flange2base, X, pixels, setup = args
    _, K, dist, target = _mc_camera()
    obj = target.object_points()
    dets = [Detection(np.arange(len(obj)), px, obj) for px in pixels]
    poses = [solve_pnp(det, K, dist)[0] for det in dets]
    cal = handeye.calibrate_poses(flange2base, np.array(poses), setup=setup, refine="none", uncertainty=False, check=False)
    ref = refine_reprojection(cal.X, cal.Z, flange2base, [d.object_points for d in dets],
                              [d.image_points for d in dets], K, dist, setup)
    # errors in the covariance's own parameterisation: left rotation increment, translation
    return (Rotation.from_matrix(ref.X[:3, :3] @ X[:3, :3].T).as_rotvec(), ref.X[:3, 3] - X[:3, 3],
            np.trace(ref.cov_X[:3, :3]), np.trace(ref.cov_X[3:, 3:]))


def _monte_carlo(runs: int, sigma_px: float, setup: str, seed: int):
    """The random draws in this process (the same numbers whatever the workers), the fits on both cores."""
    rng = np.random.default_rng(seed)
    size, K, dist, target = _mc_camera()
    renderer = Renderer(K, dist, size, supersample=1)
    outline = target_texture(target).outline()
    obj = target.object_points()
    tasks = []
    for _ in range(runs):
        scene = scene_from_viewpoints(visible_viewpoints(15, rng, renderer, outline), setup, rng)
        pixels = [renderer.project(obj, T) + rng.normal(0.0, sigma_px, (len(obj), 2)) for T in scene.target2cam]
        tasks.append((scene.flange2base, scene.X, pixels, setup))
    with realdata.worker_pool() as pool:
        err_rot, err_t, var_rot, var_t = zip(*pool.map(_mc_run, tasks, chunksize=10))
    rms = lambda e: float(np.sqrt(np.mean(np.sum(np.square(e), axis=1))))  # noqa: E731
    return rms(err_rot), float(np.sqrt(np.mean(var_rot))), rms(err_t), float(np.sqrt(np.mean(var_t)))


@pytest.mark.slow
@pytest.mark.parametrize("setup", ["eye_in_hand", "eye_to_hand"])
def test_predicted_std_matches_monte_carlo(setup):
    """0.3 px noise on projected points, 15 poses, 200 runs: RMS error within 15% of the mean
    predicted standard deviation, for rotation and for translation."""
    rms_rot, pred_rot, rms_t, pred_t = _monte_carlo(200, 0.3, setup, seed=11)
    print(f"{setup}: rotation RMS {np.degrees(rms_rot):.4f} deg vs predicted {np.degrees(pred_rot):.4f} deg; "
          f"translation RMS {1e3 * rms_t:.4f} mm vs predicted {1e3 * pred_t:.4f} mm")
    assert abs(rms_rot / pred_rot - 1) < 0.15
    assert abs(rms_t / pred_t - 1) < 0.15


def test_calibration_reports_std_and_predicts_point_error(tmp_path):
    scene = handeye.simulate.simulate_session(tmp_path / "s", "eye_in_hand", 12, "circles", noise_px=0.2, seed=3)
    cal = handeye.calibrate(tmp_path / "s", progress=False)
    assert cal.refinement == "reprojection" and cal.cov.shape == (6, 6) and cal.std.shape == (6,)
    assert np.allclose(cal.std[:3], np.degrees(np.sqrt(np.diag(cal.cov)[:3])))
    # (not monotonic in distance: points near the observed target, ~0.6-1 m in front of the
    # camera, are better determined than the camera's own origin)
    # the linear propagation against sampling X from its covariance
    rng = np.random.default_rng(0)
    d = rng.multivariate_normal(np.zeros(6), cal.cov, 20000)
    p = np.array([0.05, -0.1, 0.8])
    R = Rotation.from_rotvec(d[:, :3]).as_matrix() @ cal.X[:3, :3]
    mapped = R @ p + cal.X[:3, 3] + d[:, 3:]
    assert np.allclose(mapped.std(axis=0), cal.predict_error(p), rtol=0.03)
    assert np.allclose(cal.predict_error([0.0, 0.0, 0.0]), np.sqrt(np.diag(cal.cov)[3:]))
    none = handeye.calibrate_poses(scene.flange2base, scene.target2cam, refine="none", uncertainty=False)
    with pytest.raises(ValueError, match="no covariance"):
        none.predict_error([0, 0, 1])


def test_refinement_gain_and_robust_loss():
    """Pixel noise 0.3 px, 15 poses (40 runs): the refined X has a far lower RMS translation error
    than Daniilidis alone (bar: >= 30% lower); with 10% of the points moved by 20 px, the robust
    refinement stays within 1.5x of the clean-data error."""
    rng = np.random.default_rng(5)
    size = (640, 480)
    K, dist = default_camera(size)
    renderer = Renderer(K, dist, size, supersample=1)
    target = target_from_spec({"type": "chessboard", "cols": 9, "rows": 6, "square": 0.03})
    outline, obj = target_texture(target).outline(), target.object_points()
    closed, clean, outl = [], [], []
    for _ in range(40):
        sc = scene_from_viewpoints(visible_viewpoints(15, rng, renderer, outline), "eye_in_hand", rng)
        good = [renderer.project(obj, T) + rng.normal(0, 0.3, (len(obj), 2)) for T in sc.target2cam]
        bad = []
        for px in good:
            q = px.copy()
            idx = rng.choice(len(obj), len(obj) // 10, replace=False)
            ang = rng.uniform(0, 2 * np.pi, len(idx))
            q[idx] += 20.0 * np.c_[np.cos(ang), np.sin(ang)]
            bad.append(q)
        for pts, out in ((good, clean), (bad, outl)):
            poses = np.array([solve_pnp(Detection(np.arange(len(obj)), p, obj), K, dist)[0] for p in pts])
            cal = handeye.calibrate_poses(sc.flange2base, poses, refine="none", uncertainty=False, check=False)  # closed-form start only
            if pts is good:
                closed.append(cal.X[:3, 3] - sc.X[:3, 3])
            ref = refine_reprojection(cal.X, cal.Z, sc.flange2base, [obj] * len(pts), pts, K, dist, "eye_in_hand",
                                      robust=pts is bad)
            out.append(ref.X[:3, 3] - sc.X[:3, 3])
            if pts is bad:
                assert ref.n_rejected >= 0.9 * 15 * (len(obj) // 10)
    rms = lambda e: float(np.sqrt(np.mean(np.sum(np.square(e), axis=1))))  # noqa: E731
    print(f"translation RMS: Daniilidis {1e3 * rms(closed):.3f} mm, refined {1e3 * rms(clean):.3f} mm, "
          f"refined robust with outliers {1e3 * rms(outl):.3f} mm")
    assert rms(clean) <= 0.7 * rms(closed)
    assert rms(outl) <= 1.5 * rms(clean)


# --- pose refinement (Strobl-Hirzinger, seed §2.2.4) ------------------------------------------

POSE_NOISE = dict(robot_deg=0.05, robot_mm=0.2, cam_deg=0.1, cam_mm=0.5)  # the setting
CLOSED_FORMS = ["daniilidis", "tsai_lenz", "park_martin", "horaud", "horaud_nonlinear", "andreff", "shah", "li"]


@pytest.fixture(scope="module", params=["eye_in_hand", "eye_to_hand"])
def pose_monte_carlo(request):
    """200 seeded runs, 15 poses, noise on robot and camera poses: per run the errors of the pose
    refinement (as rotation vector and translation) and its predicted variances, and the error
    angles and distances of every closed-form solver on the same data."""
    setup = request.param
    rng = np.random.default_rng(21)
    tasks = []
    for _ in range(200):
        s = random_scene(15, setup, rng)
        f = perturb_poses(s.flange2base, np.radians(POSE_NOISE["robot_deg"]), 1e-3 * POSE_NOISE["robot_mm"], rng)
        t = perturb_poses(s.target2cam, np.radians(POSE_NOISE["cam_deg"]), 1e-3 * POSE_NOISE["cam_mm"], rng)
        tasks.append((s.X, f, t, setup))
    with realdata.worker_pool() as pool:
        runs = list(pool.map(_pose_run, tasks, chunksize=10))
    closed = {m: [r[0][m] for r in runs] for m in CLOSED_FORMS}
    err_rot, err_t, var_rot, var_t, noise = (np.array([r[k] for r in runs]) for k in range(1, 6))
    return setup, err_rot, err_t, var_rot, var_t, closed, noise


def _pose_run(args):
    """One run of the pose Monte Carlo: every closed form, and the pose refinement with its own model."""
    X, f, t, setup = args
    closed = {}
    for m in CLOSED_FORMS:
        c = handeye.calibrate_poses(f, t, setup=setup, method=m, refine="none", uncertainty=False, check=False)
        closed[m] = (rotation_error(c.X, X), translation_error(c.X, X))
    # check=False: the data are clean by construction, and what is measured is the refinement
    cal = handeye.calibrate_poses(f, t, setup=setup, check=False, refine="pose")
    assert cal.refinement == "pose"
    model = cal.std_sources["model"]  # the refinement's own model (the reported std also has the jackknife, the robot)
    assert np.all(cal.std >= model)
    return (closed, Rotation.from_matrix(cal.X[:3, :3] @ X[:3, :3].T).as_rotvec(), cal.X[:3, 3] - X[:3, 3],
            np.sum(np.radians(model[:3]) ** 2), np.sum((1e-3 * model[3:]) ** 2), list(cal.pose_noise.values()))


@pytest.mark.slow
def test_pose_refinement_predicted_std_matches_monte_carlo(pose_monte_carlo):
    """Robot 0.05 deg / 0.2 mm, camera 0.1 deg / 0.5 mm, 15 poses, 200 runs: the RMS error of X is
    within 15% of the mean predicted standard deviation, for rotation and for translation; the
    noise estimates find the simulated levels."""
    setup, err_rot, err_t, var_rot, var_t, _, noise = pose_monte_carlo
    rms_rot, pred_rot = np.sqrt(np.mean(np.sum(err_rot**2, axis=1))), np.sqrt(np.mean(var_rot))
    rms_t, pred_t = np.sqrt(np.mean(np.sum(err_t**2, axis=1))), np.sqrt(np.mean(var_t))
    med = np.median(noise, axis=0)
    print(f"{setup}: rotation RMS {np.degrees(rms_rot):.4f} deg vs predicted {np.degrees(pred_rot):.4f}; translation RMS "
          f"{1e3 * rms_t:.4f} mm vs predicted {1e3 * pred_t:.4f}; median noise estimates {np.round(med, 4)}")
    assert abs(rms_rot / pred_rot - 1) < 0.15
    assert abs(rms_t / pred_t - 1) < 0.15
    # translation noise: robot and camera together, sqrt(0.2^2 + 0.5^2) = 0.54 mm per axis
    assert abs(med[2] / np.hypot(POSE_NOISE["robot_mm"], POSE_NOISE["cam_mm"]) - 1) < 0.2
    assert abs(np.hypot(med[0], med[1]) / np.hypot(POSE_NOISE["robot_deg"], POSE_NOISE["cam_deg"]) - 1) < 0.2


@pytest.mark.slow
def test_pose_refinement_no_worse_than_best_closed_form(pose_monte_carlo):
    """On median error over the same 200 runs, the pose refinement against the best closed-form
    solver (the best of eight, chosen after the fact). Translation: at least 15% lower (measured
    21-34% over 1000 runs). Rotation: the closed forms are nearly efficient there (measured over
    1000 runs: refined 2-7% lower), a gap 200 runs cannot resolve, so the bar is "not higher by
    more than two bootstrap standard errors of the paired median difference"."""
    setup, err_rot, err_t, _, _, closed, _ = pose_monte_carlo
    ref = np.c_[np.linalg.norm(err_rot, axis=1), np.linalg.norm(err_t, axis=1)]
    cf = {m: np.array(v) for m, v in closed.items()}
    best_r = min(cf, key=lambda m: np.median(cf[m][:, 0]))
    best_t = min(cf, key=lambda m: np.median(cf[m][:, 1]))
    rng = np.random.default_rng(0)
    boot = rng.integers(0, len(ref), (2000, len(ref)))
    diff = np.median(ref[boot, 0], axis=1) - np.median(cf[best_r][boot, 0], axis=1)
    print(f"{setup}: median rotation refined {np.degrees(np.median(ref[:, 0])):.4f} deg vs {best_r} "
          f"{np.degrees(np.median(cf[best_r][:, 0])):.4f} (bootstrap SE {np.degrees(diff.std()):.4f}); median translation "
          f"refined {1e3 * np.median(ref[:, 1]):.4f} mm vs {best_t} {1e3 * np.median(cf[best_t][:, 1]):.4f}")
    assert np.median(ref[:, 1]) <= 0.85 * np.median(cf[best_t][:, 1])
    assert np.median(ref[:, 0]) <= np.median(cf[best_r][:, 0]) + 2 * diff.std()


@pytest.mark.parametrize("setup", ["eye_in_hand", "eye_to_hand"])
@pytest.mark.parametrize("n_poses", [3, 5, 40])
def test_pose_refinement_keeps_noise_free_data_exact(setup, n_poses):
    """Started off the truth (0.5 deg / 5 mm on X and Z), noise-free poses: back to < 1e-9."""
    s = random_scene(n_poses, setup, rng=n_poses)
    rng = np.random.default_rng(1)
    X0, Z0 = perturb_poses(s.X, np.radians(0.5), 5e-3, rng), perturb_poses(s.Z, np.radians(0.5), 5e-3, rng)
    ref = refine_pose(X0, Z0, s.flange2base, s.target2cam, setup)
    assert rotation_error(ref.X, s.X) < 1e-9 and translation_error(ref.X, s.X) < 1e-9
    assert rotation_error(ref.Z, s.Z) < 1e-9 and translation_error(ref.Z, s.Z) < 1e-9
    assert ref.success and np.sqrt(np.diag(ref.cov_X)).max() < 1e-9


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_pose_noise_variances_are_found_from_the_closed_forms_start(seed):
    """40 poses, 0.3 mm of translation noise on robot and camera, 0.1 deg of rotation noise on the
    robot only: the variances are maximum-likelihood from where the closed form starts them (half
    the rotation residual to the robot, half to the camera): the robot's rotation noise found
    within 15%, the camera's near none, translation sqrt(2) 0.3 mm within 15%. (The quasi-Newton
    search used before stopped at its start on these: 0.058 deg each.)"""
    rng = np.random.default_rng(seed)
    s = random_scene(40, "eye_in_hand", rng)  # 0.3 mm on both, rotation noise on the robot's poses only
    f = perturb_poses(s.flange2base, np.radians(0.1), 0.3e-3, rng)
    t = perturb_poses(s.target2cam, 0.0, 0.3e-3, rng)
    X0, Z0, _ = closed_form(f, t, "eye_in_hand", "daniilidis")
    noise = refine_pose(X0, Z0, f, t, "eye_in_hand").noise
    assert abs(np.degrees(noise["robot_rotation"]) / 0.1 - 1) < 0.15
    assert np.degrees(noise["camera_rotation"]) < 0.02
    assert abs(noise["translation"] / (np.sqrt(2) * 0.3e-3) - 1) < 0.15


@pytest.mark.parametrize("setup", ["eye_in_hand", "eye_to_hand"])
def test_pose_jacobian_matches_finite_differences(setup):
    from handeye.geometry.se3 import make_transform, so3_left_jacobian
    from handeye.sensors.camera.poses import pose_jacobian, pose_residuals

    rng = np.random.default_rng(0)
    s = random_scene(6, setup, rng)
    f, t = perturb_poses(s.flange2base, 0.05, 0.02, rng), perturb_poses(s.target2cam, 0.05, 0.02, rng)

    def unpack(x):
        return (make_transform(Rotation.from_rotvec(x[:3]).as_matrix() @ s.X[:3, :3], s.X[:3, 3] + x[3:6]),
                make_transform(Rotation.from_rotvec(x[6:9]).as_matrix() @ s.Z[:3, :3], s.Z[:3, 3] + x[9:12]))

    x = rng.normal(0, 0.3, 12)
    fun = lambda x: pose_residuals(*unpack(x), f, t, setup)[0].ravel()  # noqa: E731
    h = 1e-6
    J_num = np.stack([(fun(x + h * e) - fun(x - h * e)) / (2 * h) for e in np.eye(12)], axis=1)
    X, Z = unpack(x)
    J = pose_jacobian(X, Z, f, t, setup, pose_residuals(X, Z, f, t, setup)[0])
    J[..., 0:3] = J[..., 0:3] @ so3_left_jacobian(x[:3])
    J[..., 6:9] = J[..., 6:9] @ so3_left_jacobian(x[6:9])
    assert np.abs(J.reshape(-1, 12) - J_num).max() < 1e-7


@pytest.mark.slow
@pytest.mark.parametrize("setup", ["eye_in_hand", "eye_to_hand"])
@pytest.mark.parametrize("n_poses", [5, 15])
def test_the_pose_refinement_is_the_cores_fit_of_whole_poses(setup, n_poses):
    """refine_pose is the estimation core's fit of the camera's whole poses (PoseDifferences): the
    same X, Z and noise as the estimator choice's poses_fit, no engine of its own; over 20 simulated
    captures its X lies within 3 of its std of the truth (rotation and translation, per axis) on at
    least 95% of the axes, and with 5 poses the noise has no depth term."""
    from handeye.estimation.estimators import poses_fit
    from handeye.estimation.validation import Views
    from handeye.frames.metrics import std_deg_mm

    inside = []
    for seed in range(20):
        rng = np.random.default_rng(n_poses if seed == 0 else 100 * n_poses + seed)
        s = random_scene(n_poses, setup, rng)
        f = perturb_poses(s.flange2base, np.radians(0.05), 0.2e-3, rng)
        t = perturb_poses(s.target2cam, np.radians(0.02), 0.5e-3, rng)
        X0, Z0, _ = closed_form(f, t, setup, "daniilidis")
        ref = refine_pose(X0, Z0, f, t, setup)
        if seed == 0:
            core = poses_fit(Views(f, t, setup), X0, Z0)
            assert np.array_equal(core.X, ref.X) and np.array_equal(core.Z, ref.Z) and np.array_equal(core.cov_X, ref.cov_X)
            assert core.noise == ref.noise and (ref.noise["camera_depth"] == 0.0) == (n_poses < 6)
            # a subset refitted with the noise held moves X away from the whole's, towards the subset's own fit
            X_sub, _ = core.on(np.arange(1, n_poses))
            own = refine_pose(X0, Z0, f[1:], t[1:], setup).X
            assert 0 < translation_error(X_sub, core.X) and translation_error(X_sub, own) < 0.5 * translation_error(core.X, own)
        err = np.r_[Rotation.from_matrix(ref.X[:3, :3] @ s.X[:3, :3].T).as_rotvec(), ref.X[:3, 3] - s.X[:3, 3]]
        err = np.r_[np.degrees(err[:3]), 1e3 * err[3:]]
        inside.append(np.abs(err) <= 3 * std_deg_mm(ref.cov_X))
    assert np.mean(inside) >= 0.95


def test_pose_refinement_priors_fix_what_the_poses_cannot_see():
    """A SCARA-like capture (every rotation about base z) leaves X's height free: a prior on it
    (TranslationPriors, rows of the core's fit) puts it at its value within the prior's std, and the
    rest of X at the truth."""
    from handeye.solvers.refine import TranslationPriors

    rng = np.random.default_rng(3)
    s = random_scene(10, "eye_in_hand", rng)
    axis_turns = Rotation.from_rotvec(np.c_[np.zeros((10, 2)), rng.uniform(-1.5, 1.5, 10)]).as_matrix()
    f = s.flange2base.copy()
    f[:, :3, :3] = axis_turns
    f[:, :3, 3] = np.c_[rng.uniform(0.3, 0.5, (10, 2)), np.full(10, 0.4)]
    t = np.linalg.inv(s.X) @ np.linalg.inv(f) @ s.Z  # eye-in-hand: target2cam = X^-1 F^-1 Z
    X0, Z0 = s.X.copy(), s.Z.copy()
    X0[2, 3] += 0.05  # wrong height: the poses cannot tell
    Z0[2, 3] += 0.05
    priors = TranslationPriors(np.array([[0, 0, 1.0, 0, 0, 0]]), np.array([s.X[2, 3]]), np.array([1e-4]))
    ref = refine_pose(X0, Z0, f, t, "eye_in_hand", priors=priors)
    assert abs(ref.X[2, 3] - s.X[2, 3]) < 1e-6 and translation_error(ref.X, s.X) < 1e-6
    assert rotation_error(ref.X, s.X) < 1e-8


def test_a_fit_of_correlated_residuals_needs_the_sensors_derivatives():
    """A sensor with correlated residuals but no jacobian is refused by name, not fitted by finite
    differences under weights that never move; and estimate() refuses whole poses (their noise is
    fitted, not stated: on exact rotations it called the translation undetermined, on real pose pairs
    every fit inconsistent), naming calibrate_poses."""
    from handeye.estimation.core import Problem
    from handeye.estimation.core import fit as core_fit
    from handeye.robot.models import ControllerPoses
    from handeye.sensors.base import CorrelatedNoise, Differentiable
    from handeye.sensors.camera.poses import PoseDifferences

    class NoDerivatives(PoseDifferences):
        jacobian = None  # the capability withdrawn, as a protocol's member is (the core asks by isinstance)

    s = random_scene(8, "eye_in_hand", rng=1)
    model = NoDerivatives("eye_in_hand", [str(i) for i in range(8)], s.target2cam)
    assert isinstance(model, CorrelatedNoise) and not isinstance(model, Differentiable)
    problem = Problem(model, ControllerPoses(s.flange2base), *model.start(s.flange2base, s.X, s.Z))
    with pytest.raises(handeye.HandEyeError, match="correlated residuals needs the sensor's own derivatives"):
        core_fit(problem)
    # nor does estimate() judge whole poses against a stated noise they do not have: it says where to go
    from handeye.estimation.core import estimate
    whole = PoseDifferences("eye_in_hand", [str(i) for i in range(8)], s.target2cam)
    with pytest.raises(handeye.HandEyeError, match="calibrate_poses"):
        estimate(whole, ControllerPoses(s.flange2base))


def test_pose_refinement_bad_arguments():
    s = random_scene(5, "eye_in_hand", rng=0)
    for weighting in ("ml", "strobl"):
        with pytest.raises(ValueError, match="weighting"):
            refine_pose(s.X, s.Z, s.flange2base, s.target2cam, "eye_in_hand", weighting=weighting)
    with pytest.raises(ValueError, match="at least 3 poses"):
        refine_pose(s.X, s.Z, s.flange2base[:2], s.target2cam[:2], "eye_in_hand")
    with pytest.raises(handeye.InputMismatchError, match="use handeye.calibrate on a session"):
        handeye.calibrate_poses(s.flange2base, s.target2cam, refine="reprojection")


def _robot_noise_scene(rng, n_poses=15, robot=(0.05, 0.2), sigma_px=0.3, outline_cache={}):  # noqa: B006
    """Rendered-camera geometry, projected points with pixel noise, robot poses with errors."""
    size = (1280, 1024)
    K, dist = default_camera(size)
    target = target_from_spec({"type": "chessboard", "cols": 9, "rows": 6, "square": 0.03})
    obj = target.object_points()
    if "outline" not in outline_cache:  # renderer set-up and texture are slow; the same for every run
        outline_cache["outline"] = target_texture(target).outline()
        outline_cache["renderer"] = Renderer(K, dist, size, supersample=1)
    renderer = outline_cache["renderer"]
    scene = scene_from_viewpoints(visible_viewpoints(n_poses, rng, renderer, outline_cache["outline"]),
                                  "eye_in_hand", rng)
    img = [renderer.project(obj, T) + rng.normal(0.0, sigma_px, (len(obj), 2)) for T in scene.target2cam]
    f2b = perturb_poses(scene.flange2base, np.radians(robot[0]), 1e-3 * robot[1], rng)
    poses = np.array([solve_pnp(Detection(np.arange(len(obj)), p, obj), K, dist)[0] for p in img])
    cal = handeye.calibrate_poses(f2b, poses, refine="none", uncertainty=False, check=False)
    return scene, f2b, poses, cal, [obj] * n_poses, img, K, dist


def _robot_aware_run(args):
    scene, f2b, poses, cal, obj, img, K, dist = args
    plain = refine_reprojection(cal.X, cal.Z, f2b, obj, img, K, dist, "eye_in_hand")
    robot = refine_reprojection(cal.X, cal.Z, f2b, obj, img, K, dist, "eye_in_hand", robot_noise=(np.radians(0.05), 0.2e-3))
    pose = handeye.calibrate_poses(f2b, poses, check=False)
    errs = {key: 1e3 * translation_error(X, scene.X) for key, X in (("plain", plain.X), ("robot", robot.X), ("pose", pose.X))}
    return errs, 1e6 * np.trace(robot.cov_X[3:, 3:])


@pytest.mark.slow
def test_robot_aware_reprojection_refinement_removes_the_robot_bias():
    """Robot poses off by 0.05 deg / 0.2 mm per axis, 0.3 px, 15 poses, 40 runs. Taking the robot
    poses as exact, the pixel refinement pulls X by the robot errors and claims 5x too small a
    std; with robot_noise each pose gets a correction under that prior: X is >= 2x closer than the
    plain pixel fit, closer than the pose refinement, and its predicted std is honest (within 30%
    of the RMS error; 40 runs estimate an RMS to ~11%)."""
    rng = np.random.default_rng(21)
    with realdata.worker_pool() as pool:  # the scenes drawn here, the fits on both cores
        runs = list(pool.map(_robot_aware_run, [_robot_noise_scene(rng) for _ in range(40)], chunksize=5))
    errs = {key: [r[0][key] for r in runs] for key in ("plain", "robot", "pose")}
    pred = [r[1] for r in runs]
    rms = {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in errs.items()}
    pred_t = float(np.sqrt(np.mean(pred)))
    print(f"\nRMS translation error of X (mm): plain {rms['plain']:.3f}, robot-aware {rms['robot']:.3f} "
          f"(predicted {pred_t:.3f}), pose refinement {rms['pose']:.3f}")
    assert rms["robot"] <= 0.5 * rms["plain"]
    assert rms["robot"] < rms["pose"]
    assert abs(rms["robot"] / pred_t - 1) < 0.3


@pytest.mark.slow
def test_robot_aware_elimination_matches_the_joint_fit(monkeypatch):
    """Each pose's error eliminated (variable projection on X and the target; each view's 6 solved for
    given them, their derivatives by the chain rule through X's) reaches the optimum, covariance and
    corrected poses of the joint fit over every unknown; with a wrong detection, the robust fit sets
    the same point aside and lands at the same X."""
    from handeye.estimation import core as core_module

    scene, f2b, poses, cal, obj, img, K, dist = _robot_noise_scene(np.random.default_rng(5), n_poses=12)
    kw = dict(robot_noise=(np.radians(0.05), 0.2e-3))
    img_out = [im.copy() for im in img]
    img_out[2][4] += 30.0
    fits = {}
    for label, threshold in (("eliminated", 0), ("joint", 10**9)):
        monkeypatch.setattr(core_module, "ELIMINATE_OWN_FROM", threshold)
        monkeypatch.setattr(core_module, "ELIMINATE_FROM", threshold)
        fits[label] = (refine_reprojection(cal.X, cal.Z, f2b, obj, img, K, dist, "eye_in_hand", **kw),
                       refine_reprojection(cal.X, cal.Z, f2b, obj, img_out, K, dist, "eye_in_hand", robust=True, **kw))
    (sp, sp_robust), (de, de_robust) = fits["eliminated"], fits["joint"]
    assert translation_error(sp.X, de.X) < 1e-8 and rotation_error(sp.X, de.X) < 1e-8
    assert np.abs(sp.cov_X - de.cov_X).max() < 1e-4 * np.abs(de.cov_X).max()
    assert translation_error(sp.flange2base, de.flange2base).max() < 1e-8
    # the corrected robot poses moved towards the truth
    assert translation_error(sp.flange2base, scene.flange2base).mean() < translation_error(f2b, scene.flange2base).mean()
    assert sp_robust.n_rejected == de_robust.n_rejected == 1 and not sp_robust.kept[2][4]
    assert translation_error(sp_robust.X, de_robust.X) < 1e-8 and rotation_error(sp_robust.X, de_robust.X) < 1e-8
    with pytest.raises(ValueError, match="positive"):
        refine_reprojection(cal.X, cal.Z, f2b, obj, img, K, dist, "eye_in_hand", robot_noise=(0.0, 1e-3))


def test_soft_l1_round_reaches_scipys_robust_optimum():
    """The core's robust round, its soft-L1 cost written as plain least squares for MINPACK's
    Levenberg-Marquardt (issue 37), has scipy's own soft-L1 optimum (trf, the loss applied by
    least_squares), with and without the intrinsics, wrong detections included; and each pose's error
    eliminated, Newton's steps for the errors reach the same optimum as scipy's on the joint problem."""
    from scipy.optimize import least_squares

    from handeye.estimation import core as core_module
    from handeye.estimation.refinement import corners_problem

    scene, f2b, poses, cal, obj, img, K, dist = _robot_noise_scene(np.random.default_rng(7), n_poses=8)
    img = [im.copy() for im in img]
    img[1][3] += 25.0
    img[5][10] -= 18.0
    names = [str(i) for i in range(len(img))]
    for intrinsics, robot in ((False, None), (True, None), (False, (np.radians(0.05), 0.2e-3))):
        problem = corners_problem("eye_in_hand", names, f2b, obj, img, K, dist, cal.X, cal.Z, intrinsics, robot)
        rows = np.arange(len(problem.sensor.owner))
        sigma = np.array([1.5e-4])  # m at the target: ~0.3 px
        x0 = np.zeros(sum(problem.sizes))
        fun = core_module._function(problem, rows, sigma)
        jac = core_module._jacobian(problem, rows, sigma)
        cost = lambda x: float(np.sum(2.0 * (np.sqrt(1.0 + (fun(x) / 2.0) ** 2) - 1.0)))  # noqa: E731
        kw = dict(x_scale=problem.scale(), xtol=1e-12, ftol=1e-12, gtol=1e-12)
        lm = core_module._robust_least_squares(fun, jac, x0, problem.scale(), 1e-12, True)
        trf = least_squares(fun, x0, jac, method="trf", loss="soft_l1", f_scale=2.0, **kw)
        X_lm, X_trf = problem.unpack(lm.x)[0], problem.unpack(trf.x)[0]
        # scipy's trf stops ~1e-7 deg short of the optimum with the intrinsics (a higher cost); MINPACK's steps
        # get as close or closer
        assert translation_error(X_lm, X_trf) < 1e-7 and rotation_error(X_lm, X_trf) < 1e-6
        assert cost(lm.x) <= cost(trf.x) * (1.0 + 1e-11)  # the same minimum, to rounding
        assert np.array_equal(lm.fun, fun(lm.x))  # the residuals themselves, not their soft-L1 form
        if robot is not None:  # the errors eliminated: the robust round of the fit itself
            elim, _ = core_module._fit_eliminated(problem, rows, sigma, x0, 1e-12, "soft_l1")
            X_elim = problem.unpack(elim.x)[0]
            assert translation_error(X_elim, X_trf) < 1e-7 and rotation_error(X_elim, X_trf) < 1e-6


def test_robot_aware_robust_fit_drops_a_view_its_robot_pose_contradicts():
    """A whole view 40 px off (a wrong robot pose, a swapped image): the soft-L1 pass bends that
    pose far beyond its prior instead of giving up the points, and pulled X by millimetres; the
    view now goes whole, and X is what the other views give."""
    scene, f2b, poses, cal, obj, img, K, dist = _robot_noise_scene(np.random.default_rng(9), n_poses=10)
    kw = dict(robot_noise=(np.radians(0.05), 0.2e-3), robust=True)
    bad = [im.copy() for im in img]
    bad[6] += 40.0
    got = refine_reprojection(cal.X, cal.Z, f2b, obj, bad, K, dist, "eye_in_hand", **kw)
    keep = np.arange(10) != 6
    without = refine_reprojection(cal.X, cal.Z, f2b[keep], [o for o, k in zip(obj, keep) if k],
                                  [im for im, k in zip(img, keep) if k], K, dist, "eye_in_hand", **kw)
    assert got.rejected_images == (6,) and got.n_rejected == len(obj[6])
    # (the same up to the noise scale each estimates from its own rows in its rounds)
    assert translation_error(got.X, without.X) < 0.01 * translation_error(without.X, scene.X)
    assert rotation_error(got.X, without.X) < 0.01 * rotation_error(without.X, scene.X)
    clean = refine_reprojection(cal.X, cal.Z, f2b, obj, img, K, dist, "eye_in_hand", **kw)
    assert clean.rejected_images == () and clean.n_rejected == 0


@pytest.mark.slow
def test_the_cores_robot_aware_pixel_fit_eliminates_each_poses_error(monkeypatch):
    """The pixel refinement with each robot pose's error fitted, through the one estimation core
    (CameraCorners x PoseErrors; from 10 views the errors eliminated view by view): refine_reprojection
    is the same fit, X within 3 std of the truth; the joint and the eliminated fit at the same optimum;
    a fold's downdate lands where a refit on its views does; and a view 40 px off (a wrong robot pose)
    is set aside whole, X then what the other views give."""
    from handeye.estimation import core as core_module
    from handeye.estimation.core import downdated
    from handeye.estimation.core import fit as core_fit
    from handeye.estimation.estimators import corners_fit
    from handeye.estimation.validation import Views

    n = 20
    scene, f2b, poses, cal, obj, img, K, dist = _robot_noise_scene(np.random.default_rng(9), n_poses=n)
    sigma = (np.radians(0.05), 0.2e-3)
    views = Views(f2b, poses, "eye_in_hand", obj, img, K, dist)
    core = corners_fit(views, np.arange(n), cal.X, cal.Z, robot_sigma=sigma)
    assert core_module._eliminates(core.problem)
    # refine_reprojection is the same fit (its thin wrapper)
    ref = refine_reprojection(cal.X, cal.Z, f2b, obj, img, K, dist, "eye_in_hand", robust=True, robot_noise=sigma)
    assert translation_error(core.result.X, ref.X) < 1e-12 and np.allclose(core.result.cov_X, ref.cov_X, rtol=1e-9, atol=0)
    std_core = np.sqrt(np.diag(core.result.cov_X))
    # X closer to the truth than the robot's own error moves it, and within 3 std of it
    assert translation_error(core.result.X, scene.X) < 3 * np.linalg.norm(std_core[3:])
    # the corrected poses moved towards the truth
    assert translation_error(core.result.flange2base, scene.flange2base).mean() < translation_error(f2b, scene.flange2base).mean()
    # a fold: the downdate (one step, each view's errors eliminated) against the refit on its views
    train = np.setdiff1d(np.arange(n), [2, 7])
    step = downdated(core.problem, core.fitted, train, guard=False)
    refit = core_fit(core.problem, train, start=core.fitted)
    assert translation_error(step.X, refit.X) < 0.02 * translation_error(refit.X, core.fitted.X)
    assert np.all(step.d.reshape(n, 6)[[2, 7]] == 0)  # the views left out: predicted from the robot alone
    # a view its robot pose contradicts goes whole
    bad = [im.copy() for im in img]
    bad[6] += 40.0
    got = corners_fit(Views(f2b, poses, "eye_in_hand", obj, bad, K, dist), np.arange(n), cal.X, cal.Z, robot_sigma=sigma)
    keep = np.flatnonzero(np.arange(n) != 6)
    without = corners_fit(views, keep, cal.X, cal.Z, robot_sigma=sigma)
    assert got.result.rejected_images == (6,) and got.result.n_rejected == len(obj[6])
    # (the same up to the noise scale each estimates from its own rows)
    assert translation_error(got.result.X, without.result.X) < 0.01 * translation_error(without.result.X, scene.X)
    assert rotation_error(got.result.X, without.result.X) < 0.01 * rotation_error(without.result.X, scene.X)
    assert core.result.rejected_images == () and core.result.n_rejected == 0
    # the joint Jacobian below ELIMINATE_OWN_FROM: the same optimum, the same view set aside
    monkeypatch.setattr(core_module, "ELIMINATE_FROM", 10**9)
    monkeypatch.setattr(core_module, "ELIMINATE_OWN_FROM", 10**9)
    joint = corners_fit(views, np.arange(n), cal.X, cal.Z, robot_sigma=sigma)
    assert not core_module._eliminates(joint.problem)
    assert translation_error(joint.result.X, core.result.X) < 1e-3 * translation_error(ref.X, scene.X)
    assert np.abs(np.sqrt(np.diag(joint.result.cov_X)) / std_core - 1).max() < 1e-3
    got = corners_fit(Views(f2b, poses, "eye_in_hand", obj, bad, K, dist), np.arange(n), cal.X, cal.Z, robot_sigma=sigma)
    assert got.result.rejected_images == (6,)


def test_robot_aware_refinement_with_a_long_distortion_model():
    """OpenCV's 14-term model (thin prism, tilt) with those terms zero is the 5-term camera: the same
    optimum; with any of them nonzero, the refinement says it does not model them (no wrong answer)."""
    scene, f2b, poses, cal, obj, img, K, dist = _robot_noise_scene(np.random.default_rng(6), n_poses=8)
    kw = dict(robot_noise=(np.radians(0.05), 0.2e-3))
    short = refine_reprojection(cal.X, cal.Z, f2b, obj, img, K, dist, "eye_in_hand", **kw)
    long = refine_reprojection(cal.X, cal.Z, f2b, obj, img, K, np.r_[np.ravel(dist)[:5], np.zeros(9)], "eye_in_hand", **kw)
    assert translation_error(short.X, long.X) < 1e-12 and rotation_error(short.X, long.X) < 1e-12
    assert np.abs(short.cov_X - long.cov_X).max() < 1e-9 * np.abs(short.cov_X).max()
    prism = np.r_[np.ravel(dist)[:5], np.zeros(3), 1e-3, np.zeros(5)]
    with pytest.raises(handeye.InputMismatchError, match="thin-prism or tilt"):
        refine_reprojection(cal.X, cal.Z, f2b, obj, img, K, prism, "eye_in_hand", **kw)


@pytest.mark.parametrize("setup", ["eye_in_hand", "eye_to_hand"])
def test_reprojection_jacobians_match_central_differences(setup):
    """The pixel refinement's Jacobian in the core (X, the target, the intrinsics; each pose's error
    by the chain rule through X's derivatives and the robot's poses) against central differences of
    its residuals, away from the start (the rotation unknowns' left Jacobians matter there), for
    both setups and 5 or 8 distortion terms, the joint Jacobian and the eliminated one's parts."""
    from handeye.estimation import core as core_module
    from handeye.estimation.refinement import corners_problem

    rng = np.random.default_rng(3)
    sc = handeye.simulate.random_scene(5, setup, rng=3)
    K = np.array([[1200.0, 0, 640], [0, 1150, 500], [0, 0, 1]])
    P = np.array([[x, y, 0.0] for x in np.linspace(0, 0.2, 4) for y in np.linspace(0, 0.15, 3)])
    T = handeye.frames.setups.predicted_target2cam(sc.X, sc.Z, sc.flange2base, setup)
    for dist in (np.array([-0.2, 0.1, 0.001, -0.002, 0.05]), np.array([-0.2, 0.1, 0.001, -0.002, 0.05, 0.01, 0.02, -0.03])):
        img = [handeye.sensors.camera.pnp.project_points(t, P, K, dist) for t in T]
        for intrinsics in (False, True) if len(dist) == 5 else (False,):
            problem = corners_problem(setup, [str(i) for i in range(5)], sc.flange2base, [P] * 5, img, K, dist, sc.X, sc.Z,
                                      intrinsics, (np.radians(0.05), 0.2e-3))
            rows = np.arange(len(problem.sensor.owner))
            sigma = np.array([1e-4])
            x = rng.normal(scale=0.05, size=sum(problem.sizes)) * np.r_[np.ones(6), problem.scale()[6:-30] * 50, np.ones(30)]
            fun = core_module._function(problem, rows, sigma)
            h = 1e-6
            num = np.stack([(fun(x + h * e) - fun(x - h * e)) / (2 * h) for e in np.eye(len(x))], axis=1)
            J = core_module._per_view_jacobian(problem, rows, sigma)(x)
            assert np.abs(J - num).max() < 1e-5 * np.abs(num).max()
            parts = core_module._Eliminated(problem, rows, sigma, x[-30:])
            parts.evaluate_at(x)
            m = len(parts.f)
            n_g = parts.n_g
            assert np.abs(parts.by_globals(x[:n_g]) - num[:m, :n_g]).max() < 1e-5 * np.abs(num).max()
            assert parts._chained  # the chain rule through X's derivatives, checked against differences once
            by_errors = np.zeros((m, 30))
            view = parts.entry_view
            for a in range(6):
                by_errors[np.arange(m), 6 * view + a] = parts.by_errors()[:, a]
            assert np.abs(by_errors - num[:m, n_g:]).max() < 1e-5 * np.abs(num).max()


def test_robot_noise_is_never_silently_ignored(tmp_path):
    session = tmp_path / "s"
    handeye.simulate.simulate_session(session, n_poses=4, seed=3)
    for kw, expect in (({"refine": "pose", "robot_noise": (0.05, 0.2)}, "would ignore it"),
                       ({"robot_noise": (0.0, 0.2)}, "positive"), ({"robot_noise": "a"}, "degrees, millimetres")):
        with pytest.raises(handeye.InputMismatchError, match=expect):
            handeye.calibrate(session, progress=False, **kw)


def _named_run(args):
    """X's error over its reported std per axis, on one realistic session fitted as ``refine`` says."""
    n, setup, seed, refine = args
    sc = realistic_scene(n, setup, seed, errors=REALISTIC)
    cal = handeye.calibrate_poses(sc.flange2base, sc.target2cam, setup, refine=refine)
    d_rot = np.degrees(Rotation.from_matrix(cal.X[:3, :3] @ sc.X[:3, :3].T).as_rotvec())
    return np.abs(np.concatenate([d_rot, 1e3 * (cal.X[:3, 3] - sc.X[:3, 3])])) / cal.std, cal.std_sources


@pytest.mark.slow
@pytest.mark.parametrize("n, refine", [(4, "auto"), (8, "pose")])
def test_std_covers_the_error_with_few_poses_or_a_named_estimator(n, refine):
    """With fewer than 5 poses (no choice to make) or refine='pose', the std is the one 'auto' reports:
    the noise model widened by the jackknife, plus the robot's accuracy. On realistic sessions X's
    error is within 3 std on >= 95% of the axes, both setups (the noise model alone: 80-94%)."""
    tasks = [(n, setup, seed, refine) for setup in ("eye_in_hand", "eye_to_hand") for seed in range(40)]
    with realdata.worker_pool() as pool:
        results = list(pool.map(_named_run, tasks, chunksize=10))
    for setup, part in (("eye_in_hand", results[:40]), ("eye_to_hand", results[40:])):
        z = np.array([r[0] for r in part])
        print(f"{n} poses, refine={refine}, {setup}: within 3 std {np.mean(z <= 3):.1%} of the axes")
        assert np.mean(z <= 3) >= 0.95
    assert all(r[1]["jackknife"] is not None and r[1]["robot_accuracy"] is not None for r in results)


# --- intrinsics estimated from the same images --------------------------------------------------

def _observed_without_intrinsics(setup: str, seed: int):
    """What observe makes of 8 rendered images (exact robot poses) whose session.yaml gives no intrinsics."""
    with tempfile.TemporaryDirectory() as d:
        handeye.simulate.simulate_session(Path(d) / "s", setup, 8, seed=seed, write_intrinsics=False)
        return observe(load_session(Path(d) / "s"), progress=False)


def _estimated_intrinsics_session(args):
    """One rendered session whose intrinsics handeye estimates: the pose refinement's X with the
    intrinsics as estimated and as true (every PnP pose refitted to them), and the covariance
    intrinsics_cov propagates from the estimate's error."""
    seed, setup = args
    obs = _observed_without_intrinsics(setup, seed)
    assert obs.intrinsics_source == "estimated"
    views = obs.views()
    fit = pose_fit("daniilidis", views)
    X, Z = fit(views.flange2base, views.target2cam, setup, np.arange(len(views)))
    K, dist = default_camera((640, 480))
    true_poses = np.array([refine_pnp(T, P, uv, K, dist) for T, P, uv in
                           zip(views.target2cam, views.object_points, views.image_points)])
    X_true_K = fit(views.flange2base, true_poses, setup, np.arange(len(views)))[0]
    d = np.r_[np.degrees(Rotation.from_matrix(X[:3, :3] @ X_true_K[:3, :3].T).as_rotvec()), 1e3 * (X[:3, 3] - X_true_K[:3, 3])]
    cov = intrinsics_cov(POSE, fit, views, X, Z)
    std = np.r_[np.degrees(np.sqrt(np.diag(cov)[:3])), 1e3 * np.sqrt(np.diag(cov)[3:])]
    return d / std, np.abs(d).max()


def test_intrinsics_covariance_is_opencvs():
    """The covariance of the intrinsics (Schur complement over the views' poses) has OpenCV's
    stdDeviationsIntrinsics on its diagonal, from the same detections."""
    obs = _observed_without_intrinsics("eye_in_hand", 3)
    obj = [np.asarray(o, np.float32) for o in obs.object_points]
    img = [np.asarray(i, np.float32) for i in obs.image_points]
    out = cv2.calibrateCameraExtended(obj, img, (640, 480), None, None)
    opencv_std = out[5].ravel()[:9]
    cov = intrinsics_covariance(obs.object_points, obs.image_points, obs.target2cam, obs.K, obs.dist)
    assert np.allclose(np.sqrt(np.diag(cov)), opencv_std, rtol=1e-3)
    corr = cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1])
    assert corr > 0.8  # fx and fy move together: a per-parameter std alone would understate X's spread


@pytest.mark.slow
def test_intrinsics_error_is_propagated_to_x():
    """Intrinsics estimated from 8 rendered images (exact robot poses): X with them differs from X
    with the true intrinsics (the same detections) by what intrinsics_cov promises: over 12
    sessions >= 90% of the axes within 3 std, none beyond 4, the median ratio near a Gaussian's
    0.67 (measured: 97%, 3.1, 0.84), and the difference large enough (over 0.5 mm somewhere) for
    the test to mean something. The analytic covariance of the intrinsics (OpenCV's) understates
    their error by ~1.15x in std when detection errors are correlated within an image, as the
    renderer's are (mean Mahalanobis^2 of the estimated intrinsics 11.7 over 12 sessions, 9 if exact)."""
    tasks = [(seed, ("eye_in_hand", "eye_to_hand")[seed % 2]) for seed in range(12)]
    with realdata.worker_pool() as pool:
        results = list(pool.map(_estimated_intrinsics_session, tasks))
    z = np.abs(np.array([r[0] for r in results]))
    print(f"|X(K estimated) - X(K true)| / std: median {np.median(z):.2f}, max {z.max():.2f}, "
          f"within 3 std {np.mean(z <= 3):.1%}")
    assert np.mean(z <= 3) >= 0.9 and z.max() <= 4.0 and 0.3 <= np.median(z) <= 1.2
    assert max(r[1] for r in results) > 0.5


def test_calibrate_with_estimated_intrinsics_reports_their_error(tmp_path, monkeypatch):
    handeye.simulate.simulate_session(tmp_path / "s", "eye_in_hand", 8, seed=2, write_intrinsics=False)
    cal = handeye.calibrate(tmp_path / "s", progress=False, refine="pose")
    assert cal.intrinsics_source == "estimated" and cal.std_sources["intrinsics"] is not None
    assert any("error of the intrinsics estimated from these images" in n for n in cal.notes)
    assert np.all(cal.std >= cal.std_sources["intrinsics"] - 1e-12)
    # 8 images of 640x480 pin the intrinsics down to ~4 mm per std of X: the verdict says where to act
    assert cal.verdict == "weak" and any("calibrate the camera on its own" in a for a in cal.diagnostics.advice)
    def fails(*args):
        raise ValueError("no pose")

    with monkeypatch.context() as m:  # a refit that fails: answered, and the missing term said
        m.setattr("handeye.estimation.estimators.refine_pnp", fails)
        cal = handeye.calibrate(tmp_path / "s", progress=False, refine="pose")
        assert "intrinsics" not in cal.std_sources and any("could not be propagated" in n for n in cal.notes)
    handeye.simulate.simulate_session(tmp_path / "given", "eye_in_hand", 8, seed=2, write_intrinsics=True)
    cal = handeye.calibrate(tmp_path / "given", progress=False, refine="pose")
    assert "intrinsics" not in cal.std_sources


@pytest.mark.parametrize("intrinsics", [False, True])
def test_pixel_downdate_matches_a_refit_and_drops_nothing_when_asked(intrinsics):
    """The pixel refinement's folds (the core's fit of the corners, downdated: CornersFit.on): X without
    one image within 2% of X's move of a refit without it, the intrinsics too when refined; with no
    image dropped, the fit itself."""
    from handeye.estimation.estimators import corners_fit
    from handeye.estimation.validation import Views

    rng = np.random.default_rng(4)
    size, K, dist, target = _mc_camera()
    renderer = Renderer(K, dist, size, supersample=1)
    obj = target.object_points()
    scene = scene_from_viewpoints(visible_viewpoints(10, rng, renderer, target_texture(target).outline()), "eye_in_hand", rng)
    pixels = [renderer.project(obj, T) + rng.normal(0.0, 0.3, (len(obj), 2)) for T in scene.target2cam]
    cal = handeye.calibrate_poses(scene.flange2base, scene.target2cam, refine="none", uncertainty=False, check=False)
    views = Views(scene.flange2base, scene.target2cam, "eye_in_hand", [obj] * 10, pixels, K, dist)
    full = corners_fit(views, np.arange(10), cal.X, cal.Z, refine_intrinsics=intrinsics)
    same = full.on(np.arange(10))
    assert np.allclose(same[0], full.result.X, atol=1e-12) and np.allclose(same[1], full.result.Z, atol=1e-12)
    keep = np.arange(1, 10)
    sub = corners_fit(views, keep, full.result.X, full.result.Z, refine_intrinsics=intrinsics).result
    down = full.on(keep)
    assert translation_error(down[0], sub.X) <= 0.02 * translation_error(full.result.X, sub.X) + 1e-9
    if intrinsics:
        assert abs(down[2][0, 0] - sub.K[0, 0]) <= 0.02 * abs(full.result.K[0, 0] - sub.K[0, 0]) + 1e-6


@pytest.mark.slow
def test_closed_form_alone_reports_a_std_that_holds_under_real_robot_errors():
    """refine='none' (the closed form as is) has no noise model: its std is the jackknife spread
    plus the robot's accuracy (raised to what the poses show), as every estimator's. On pose-only
    sessions of arms 1 and 3 mm off (both setups, 12 views, 10 each) X is within 3 std in >= 95%
    (the sweep's 600 sessions: 99.3-100%) and the std is not so wide that it says nothing: its
    median under 3x the median error. (Through images: test_vision's AprilTag session, with the
    intrinsics' error added.)"""
    from dataclasses import replace

    covered, errors, stds = [], [], []
    for level in (1, 3):
        errors_model = replace(REALISTIC, pixel_px=0.1, joint_wave_deg=0.02).scaled(level)
        for setup in ("eye_in_hand", "eye_to_hand"):
            for seed in range(10):
                sc = realistic_scene(12, setup, seed, errors=errors_model)
                cal = handeye.calibrate_poses(sc.flange2base, sc.target2cam, setup, refine="none", progress=False)
                assert cal.std_sources["model"] is None and cal.std_sources["jackknife"] is not None
                rot, trans = np.degrees(rotation_error(cal.X, sc.X)), 1e3 * translation_error(cal.X, sc.X)
                covered.append(rot <= 3 * np.linalg.norm(cal.std[:3]) and trans <= 3 * np.linalg.norm(cal.std[3:]))
                errors.append(trans)
                stds.append(np.linalg.norm(cal.std[3:]))
    print(f"closed form alone: within 3 std {np.mean(covered):.1%}, median error {np.median(errors):.2f} mm, "
          f"median std {np.median(stds):.2f} mm")
    assert np.mean(covered) >= 0.95
    assert np.median(stds) < 3 * np.median(errors)
    # 3 poses: no refit without one is possible, and the std says what it leaves out
    few = handeye.calibrate_poses(sc.flange2base[:3], sc.target2cam[:3], setup, refine="none", progress=False)
    assert few.std_sources["jackknife"] is None and any("leaves out the poses' noise" in n for n in few.notes)
