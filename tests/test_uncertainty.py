"""Calibrated uncertainty: the covariance of the reprojection refinement against Monte-Carlo truth."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import handeye
from handeye.simulate import default_camera, scene_from_viewpoints, visible_viewpoints
from handeye.solvers.refine import refine_reprojection
from handeye.vision import Detection, solve_pnp, target_from_spec
from handeye.vision.render import Renderer, target_texture


def _monte_carlo(runs: int, sigma_px: float, setup: str, seed: int):
    rng = np.random.default_rng(seed)
    size = (640, 480)
    K, dist = default_camera(size)
    renderer = Renderer(K, dist, size, supersample=1)
    target = target_from_spec({"type": "chessboard", "cols": 9, "rows": 6, "square": 0.03})
    outline = target_texture(target).outline()
    obj = target.object_points()
    err_rot, err_t, var_rot, var_t = [], [], [], []
    for _ in range(runs):
        scene = scene_from_viewpoints(visible_viewpoints(15, rng, renderer, outline), setup, rng)
        dets, poses = [], []
        for T in scene.target2cam:
            px = renderer.project(obj, T) + rng.normal(0.0, sigma_px, (len(obj), 2))
            det = Detection(np.arange(len(obj)), px, obj)
            dets.append(det)
            poses.append(solve_pnp(det, K, dist)[0])
        cal = handeye.calibrate_poses(scene.flange2base, np.array(poses), setup=setup)
        ref = refine_reprojection(cal.X, cal.Z, scene.flange2base, [d.object_points for d in dets],
                                  [d.image_points for d in dets], K, dist, setup)
        # errors in the covariance's own parameterisation: left rotation increment, translation
        err_rot.append(Rotation.from_matrix(ref.X[:3, :3] @ scene.X[:3, :3].T).as_rotvec())
        err_t.append(ref.X[:3, 3] - scene.X[:3, 3])
        var_rot.append(np.trace(ref.cov_X[:3, :3]))
        var_t.append(np.trace(ref.cov_X[3:, 3:]))
    rms = lambda e: float(np.sqrt(np.mean(np.sum(np.square(e), axis=1))))  # noqa: E731
    return rms(err_rot), float(np.sqrt(np.mean(var_rot))), rms(err_t), float(np.sqrt(np.mean(var_t)))


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
    none = handeye.calibrate_poses(scene.flange2base, scene.target2cam)
    with pytest.raises(ValueError, match="no covariance"):
        none.predict_error([0, 0, 1])
