"""Depth cameras: board corners lifted from organized clouds, X with the depth scale and bias,
against the simulator's truth; clouds that do not fit their images refused with the reason."""

from __future__ import annotations

import numpy as np
import pytest

from handeye.errors import InputMismatchError
from handeye.frames.metrics import rotation_error, translation_error
from handeye.geometry.se3 import make_transform
from handeye.pipelines.depth.pipeline import calibrate_depth
from handeye.pipelines.depth.simulate_board import depth_scene
from handeye.sensors.depth import board_pose, check_cloud, lift_points, plane_points


@pytest.mark.parametrize("setup", ["eye_in_hand", "eye_to_hand"])
def test_x_and_the_depth_scale_from_lifted_corners(setup):
    """12 views at 0.5-1 m, depth noise 0.2-0.6 mm, depth scale 1.002, holes and flying pixels:
    X within 0.3 mm / 0.1 deg of the truth and within 3 std, the scale within 3 std of 1.002 and
    named in the notes (0.2% is far beyond its std), the bias (none) within 3 std."""
    sc = depth_scene(12, setup, 5)
    lifted = [lift_points(check_cloud(c, sc.image_size, f"view {k}"), p)[0]
              for k, (c, p) in enumerate(zip(sc.clouds, sc.image_points))]
    assert min(np.isfinite(q).all(axis=1).sum() for q in lifted) >= 40  # holes and edges refused, most kept
    cal = calibrate_depth(sc.flange2base, [sc.object_points] * len(lifted), lifted, setup)
    rot, trans = np.degrees(rotation_error(cal.X, sc.X)), 1e3 * translation_error(cal.X, sc.X)
    scale, bias = cal.sensor.figures["depth_scale"], cal.sensor.figures["depth_bias_mm"]
    print(f"{setup}: {rot:.4f} deg {trans:.3f} mm, scale {scale['value']:.5f} +- {scale['std']:.5f}")
    assert rot < 0.1 and trans < 0.3
    assert np.all(np.abs(1e3 * (cal.X[:3, 3] - sc.X[:3, 3])) <= 3 * cal.std_sources["data"][3:])  # the robot is exact here
    assert abs(scale["value"] - 1.002) <= 3 * scale["std"] and abs(bias["value"]) <= 3 * bias["std"]
    assert any("depth scale 1.00" in n and "beyond 3 std" in n for n in cal.notes)
    # without the scale as an unknown, X absorbs it: further from the truth
    fixed = calibrate_depth(sc.flange2base, [sc.object_points] * len(lifted), lifted, setup, fit_depth=False)
    assert 1e3 * translation_error(fixed.X, sc.X) > trans


def test_board_pose_and_lifting_on_exact_data():
    """Exact lifted points give the board's pose to 1e-9 and a flatness of 0; a corner on a hole
    or across a depth edge is not lifted; one between four pixels of a plane is interpolated."""
    sc = depth_scene(1, "eye_in_hand", 2, depth_noise=(0.0, 0.0), depth_scale=1.0, noise_px=0.0, holes=0.0)
    T = sc.target2cam[0]
    exact = sc.object_points @ T[:3, :3].T + T[:3, 3]
    pose, flatness = board_pose(sc.object_points, exact)
    assert np.abs(pose - T).max() < 1e-9 and flatness < 1e-12
    cloud = sc.clouds[0].astype(float)
    points, ok = lift_points(cloud, sc.image_points[0])
    assert ok.sum() >= len(ok) - 4 and np.nanmax(np.abs(points - exact)) < 2e-5  # float32 cloud, bilinear
    u, v = np.floor(sc.image_points[0][0]).astype(int)
    cloud[v, u] = np.nan  # a hole next to the first corner
    cloud[v + 1, u + 1, 2] *= 1.5  # and a depth edge in the same cell: refused either way
    _, ok2 = lift_points(cloud, sc.image_points[0])
    assert not ok2[0] and ok2[1:].sum() == ok[1:].sum()
    with pytest.raises(InputMismatchError, match="only 3 corners have a depth"):
        board_pose(sc.object_points[:3], exact[:3])


def test_clouds_that_do_not_fit_their_images_are_refused():
    cloud = np.ones((48, 64, 3))
    with pytest.raises(InputMismatchError, match=r"view 3: the cloud is 64x48 and its image 640x480"):
        check_cloud(cloud, (640, 480), "view 3")
    with pytest.raises(InputMismatchError, match="H x W x 3"):
        check_cloud(np.ones((48, 64)), None, "c.npy")
    with pytest.raises(InputMismatchError, match="c.npy: no point has a depth"):
        check_cloud(np.full((48, 64, 3), np.nan), (64, 48), "c.npy")
    with pytest.raises(InputMismatchError, match="looks like millimetres"):
        check_cloud(cloud * 750.0, (64, 48), "c.npy")
    with pytest.raises(InputMismatchError, match="not in the camera's optical frame"):
        check_cloud(-cloud, (64, 48), "c.npy")
    with pytest.raises(InputMismatchError, match="one of each per view"):
        calibrate_depth(np.tile(make_transform(np.eye(3), np.zeros(3)), (3, 1, 1)), [np.zeros((4, 3))] * 3,
                        [np.zeros((4, 3))] * 2)


def test_corners_on_the_fitted_plane_beat_corners_lifted_alone():
    """Exact data: a corner's ray meets the fitted plane at its true point (1e-9 m). Noisy clouds
    (0.2-0.6 mm): the plane averages the depth noise, so the corners land closer to the truth than
    lifted from their four pixels; a cloud without depth on the board is refused, named."""
    exact = depth_scene(2, "eye_in_hand", 2, depth_noise=(0.0, 0.0), depth_scale=1.0, noise_px=0.0, holes=0.0)
    for cloud, px, T in zip(exact.clouds, exact.image_points, exact.target2cam):
        points, rms, n = plane_points(cloud.astype(float), px)
        np.testing.assert_allclose(points, exact.object_points @ T[:3, :3].T + T[:3, 3], atol=1e-6)  # float32 cloud
        assert rms < 1e-6 and n > 1000
    sc = depth_scene(6, "eye_to_hand", 3)
    truth = [(sc.object_points @ T[:3, :3].T + T[:3, 3]) * sc.depth_scale for T in sc.target2cam]
    plane = np.concatenate([plane_points(c, p)[0] - t for c, p, t in zip(sc.clouds, sc.image_points, truth)])
    alone = np.concatenate([lift_points(c, p)[0] - t for c, p, t in zip(sc.clouds, sc.image_points, truth)])
    along = np.concatenate([t / np.linalg.norm(t, axis=1, keepdims=True) for t in truth])
    err_plane = np.abs(np.einsum("mi,mi->m", plane, along))
    err_alone = np.abs(np.einsum("mi,mi->m", alone, along))
    assert np.median(err_plane) < 0.7 * np.nanmedian(err_alone)  # along the rays, where the depth noise is (0.48x here)
    with pytest.raises(InputMismatchError, match="view 1: only .* points with depth on the target"):
        plane_points(np.full_like(sc.clouds[0], np.nan), sc.image_points[0], where="view 1")


def _grid_through_points(sec) -> float:
    """The median distance (mm) from each point of a report section to the nearest corner of its
    fitted grid (the curve's vertices)."""
    from scipy.spatial import cKDTree

    curve = np.asarray(sec["curve_mm"], float)
    return float(np.median(cKDTree(curve[np.isfinite(curve).all(axis=1)]).query(sec["points_mm"])[0]))


@pytest.mark.slow
def test_the_report_draws_each_views_board_and_balls_where_the_fit_puts_them():
    """Issue 77: a depth camera's report had no picture of the fit on its data. Each view's section:
    the corners in the image (mm at the target) with their error's size, and the board's grid
    through the corners the fit predicts (9 + 6 lines of a 10 x 7 board); a ball's outline about
    its centre, of its radius."""
    sc = depth_scene(8, "eye_in_hand", 5)
    lifted = [lift_points(check_cloud(c, sc.image_size, f"view {k}"), p)[0]
              for k, (c, p) in enumerate(zip(sc.clouds, sc.image_points))]
    cal = calibrate_depth(sc.flange2base, [sc.object_points] * len(lifted), lifted, "eye_in_hand")
    assert len(cal.sensor.sections) == len(cal.sensor.views)
    for sec, rms in zip(cal.sensor.sections, cal.sensor.residual_mm):
        assert np.all(sec["residual_mm"] >= 0) and np.isclose(np.sqrt(np.mean(sec["residual_mm"] ** 2)), rms, rtol=1e-6)
        assert _grid_through_points(sec) < 3 * rms
        assert np.isnan(sec["curve_mm"][:, 0]).sum() == len(np.unique(sc.object_points[:, 0])) + len(np.unique(sc.object_points[:, 1]))
    from handeye.sensors.depth.model import SphereCentres

    centres = np.array([[0.01, 0.02, 0.8], [0.05, -0.03, 0.9]])
    balls = SphereCentres("eye_in_hand", ["a", "b"], centres, radii=np.array([0.025, 0.025]))
    X = np.eye(4)
    F = np.stack([make_transform(np.eye(3), -c) for c in centres])  # every view's centre at the origin of Z
    sections = balls.sections(X, np.zeros(5), F, [0, 1])
    for sec, c in zip(sections, centres):
        ring = sec["curve_mm"][np.isfinite(sec["curve_mm"]).all(axis=1)]
        assert np.allclose(ring.mean(axis=0), sec["points_mm"][0], atol=1.0) and sec["residual_mm"][0] < 1e-9  # perspective
        assert np.allclose(np.linalg.norm(ring - sec["points_mm"][0], axis=1), 25.0, rtol=0.05)  # mm at the ball
