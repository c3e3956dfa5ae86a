"""Depth cameras' captures: organized clouds of a board or a sphere, with the depth camera's own errors."""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..._shared.io import atomic_write, check_output_folder
from ..._shared.lazy import lazy_module
from ...errors import HandEyeError
from ...frames.setups import check_setup, predicted_target2cam, setup_info
from ...io.session import write_joint_table, write_pose_table
from ...robot.kinematics import Chain, load_arm
from ...sensors.camera.pnp import project_points
from ...sensors.camera.render import Renderer, target_texture
from ...sensors.camera.targets import target_from_spec

cv2 = lazy_module("cv2")


from ...simulate import DEFAULT_TARGETS, default_camera, real_chain, reported_poses, sample_joints, scene_layout
from ...simulate.scenes import Scene, look_at_viewpoints, scene_from_viewpoints, visible_viewpoints


@dataclass(frozen=True)
class DepthScene(Scene):
    """A simulated depth-camera capture: per view the board's corners in the intensity image
    (``image_points``, with detection noise) and the organized cloud registered to it (``clouds``,
    H x W x 3 metres in the camera frame, float32, NaN where there is no depth), from a camera
    whose depths are ``depth_scale`` times the true ones plus ``depth_bias``."""

    K: NDArray[np.float64] = None  # type: ignore[assignment]
    image_size: tuple[int, int] = (640, 480)
    object_points: NDArray[np.float64] = None  # type: ignore[assignment]
    image_points: list = None  # type: ignore[assignment]
    clouds: list = None  # type: ignore[assignment]
    depth_scale: float = 1.0
    depth_bias: float = 0.0
    target_spec: dict = None  # type: ignore[assignment]
    #: with an arm: the joint angles the controller reports (rad), the arm's name, its nominal and real tables
    joints: NDArray[np.float64] | None = None
    arm: str | None = None
    chain: Chain | None = None
    chain_true: Chain | None = None


def pixel_rays(K, size) -> NDArray[np.float64]:
    """(H, W, 3): each pixel's ray (z = 1) of a pinhole camera ``K`` without distortion."""
    w, h = size
    u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    return np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], axis=-1)


def depth_reading(truth, mask, behind, rng: np.random.Generator, depth_scale: float, depth_bias: float,
                   depth_noise: tuple[float, float], holes: float) -> NDArray[np.float32]:
    """What a depth camera measures of the true points ``truth`` (H, W, 3): each moved along its ray
    to depth ``depth_scale z + depth_bias`` plus noise ``depth_noise[0] + depth_noise[1] z^2``; the
    pixels on the outline of ``mask`` flying half-way to ``behind``; a share ``holes`` without depth."""
    z = truth[..., 2]
    measured_z = depth_scale * z + depth_bias + rng.normal(0.0, 1.0, z.shape) * (depth_noise[0] + depth_noise[1] * z**2)
    cloud = truth * (measured_z / z)[..., None]
    edge = mask & ~(np.roll(mask, 1, 0) & np.roll(mask, -1, 0) & np.roll(mask, 1, 1) & np.roll(mask, -1, 1))
    cloud[edge] = 0.5 * (cloud[edge] + behind[edge])
    cloud[rng.random(z.shape) < holes] = np.nan
    return cloud.astype(np.float32)


def board_depth_image(K, size, target2cam, outline, background: float):
    """Per pixel, the true point (H, W, 3) where its ray meets the board's sheet (its ``outline``),
    else the background plane at depth ``background``; and the board's mask."""
    rays = pixel_rays(K, size)
    R, t = target2cam[:3, :3], target2cam[:3, 3]
    normal = R[:, 2]  # the board's z axis in the camera frame
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = (normal @ t) / (rays @ normal)  # along each ray, to the board's plane
    on_plane = rays * depth[..., None]
    local = (on_plane - t) @ R  # in the board's frame
    lo, hi = outline[:, :2].min(axis=0), outline[:, :2].max(axis=0)
    board = (depth > 0) & np.all((local[..., :2] >= lo) & (local[..., :2] <= hi), axis=-1)
    points = np.where(board[..., None], on_plane, rays * background)
    return points, board


@dataclass(frozen=True)
class ArmViews:
    """Views of a target by an arm off its nominal table (:func:`arm_views`)."""

    scene: Scene  #: X, Z, the flange poses the controller's nominal table gives, the true target2cam
    joints: NDArray[np.float64]
    arm: str
    chain: Chain
    chain_true: Chain


def arm_views(setup: str, points: NDArray[np.float64], K, image_size, n: int, rng: np.random.Generator, arm: str,
              length_mm: float, angle_deg: float, joint_noise_deg: float) -> ArmViews:
    """``n`` views of a target (``points`` in its frame) by ``arm`` whose real table is off its
    nominal one by ``length_mm`` / ``angle_deg`` per entry (1-3 mm at the flange at the defaults): the
    joint angles drawn about the arm's home until the camera sees the target whole, reported with
    ``joint_noise_deg`` of encoder noise; ``flange2base`` the nominal table's poses at them (what the
    controller reports), ``target2cam`` where the real arm put the target."""
    chain = load_arm(arm)
    X, Z = scene_layout(setup, points, rng, chain.forward(chain.home[setup][None])[0])
    q_true = sample_joints(setup, X, Z, points, K, image_size, n, rng, chain=chain)
    true = real_chain(chain, rng, length_mm, angle_deg)
    joints = q_true + np.radians(rng.normal(0.0, joint_noise_deg, q_true.shape))
    t2c = predicted_target2cam(X, Z, true.forward(q_true), setup)
    return ArmViews(Scene(setup, X, Z, chain.forward(joints), t2c), joints, arm, chain, true)


def depth_scene(n_views: int = 15, setup: str = "eye_in_hand", rng: np.random.Generator | int | None = None, *,
                target: str | dict = "chessboard", image_size: tuple[int, int] = (640, 480),
                depth_noise: tuple[float, float] = (1e-4, 5e-4), depth_scale: float = 1.002,
                depth_bias: float = 0.0, noise_px: float = 0.2, holes: float = 0.01,
                distance: tuple[float, float] = (0.5, 1.0), robot_error: tuple[float, float] | None = None,
                arm: str | None = None, length_mm: float = 0.5, angle_deg: float = 0.05,
                joint_noise_deg: float = 0.002) -> DepthScene:
    """A depth camera's capture of a board: ``n_views`` views at ``distance`` (m), each an organized
    cloud and the board's corners in the registered intensity image.

    The cloud's depth noise (std, m) is ``depth_noise[0] + depth_noise[1] z^2`` (0.2 mm at 0.5 m to
    0.6 mm at 1 m by default), each point moved along its ray; measured depths are
    ``depth_scale z + depth_bias``; a share ``holes`` of the pixels has no depth (NaN), and the
    pixels on the board's edge are flying pixels (their depth half-way to the background). The
    corners are the projections of the board's inner corners (pinhole, no distortion) with
    ``noise_px`` pixel noise, as a detector finds them in the intensity image. ``robot_error``
    (deg, mm): the reported flange poses are off by a constant and a heavy-tailed error per pose of
    that size per axis (``flange2base`` is what the controller reports; None: exact). ``arm`` (a
    shipped arm's name): the views are the arm's at joint angles drawn about its home
    (:func:`arm_views`: its real table off the nominal one by ``length_mm`` / ``angle_deg`` per
    entry, the joints reported with ``joint_noise_deg``), ``flange2base`` its nominal table's poses.
    """
    setup = check_setup(setup)
    rng = np.random.default_rng(rng)
    spec = DEFAULT_TARGETS[target] if isinstance(target, str) else dict(target)
    tgt = target_from_spec(spec)
    obj = tgt.object_points()
    K = default_camera(image_size)[0]
    outline = target_texture(tgt).outline()
    views = None
    if arm is not None:
        views = arm_views(setup, obj, K, image_size, n_views, rng, arm, length_mm, angle_deg, joint_noise_deg)
        scene = views.scene
    else:
        renderer = Renderer(K, np.zeros(5), image_size, supersample=1)
        cam2target = visible_viewpoints(n_views, rng, renderer, outline, margin_px=10.0)
        scale = np.linalg.norm(cam2target[:, :3, 3] - outline.mean(axis=0), axis=1)
        # the views' distances spread over ``distance``: depth noise, scale and bias differ with depth
        want = rng.uniform(*distance, n_views)
        centre = outline.mean(axis=0)
        cam2target[:, :3, 3] = centre + (cam2target[:, :3, 3] - centre) * (want / scale)[:, None]
        scene = scene_from_viewpoints(cam2target, setup, rng)
    image_points, clouds = [], []
    for T in scene.target2cam:
        truth, board = board_depth_image(K, image_size, T, outline, background=2.5)
        behind = truth * (2.5 / truth[..., 2])[..., None]  # the background where the board is
        clouds.append(depth_reading(truth, board, behind, rng, depth_scale, depth_bias, depth_noise, holes))
        px = project_points(T, obj, K, np.zeros(5))
        image_points.append(px + rng.normal(0.0, noise_px, px.shape))
    return DepthScene(setup, scene.X, scene.Z, reported_poses(scene.flange2base, robot_error, rng), scene.target2cam, K=K,
                      image_size=tuple(image_size),
                      object_points=obj, image_points=image_points, clouds=clouds, depth_scale=depth_scale,
                      depth_bias=depth_bias, target_spec=dict(spec), **arm_fields(views))


def arm_fields(views: ArmViews | None) -> dict:
    """A scene's arm fields (joints, arm, chain, chain_true) from ``views``; none without an arm."""
    return {} if views is None else dict(joints=views.joints, arm=views.arm, chain=views.chain, chain_true=views.chain_true)


@dataclass(frozen=True)
class SphereScene(Scene):
    """A simulated depth-camera capture of a sphere (no board): per view an organized cloud
    (``clouds``, as :class:`DepthScene`'s) in which the sphere of ``radius`` sits at the origin
    of the target frame (``Z``'s translation: the centre in the base frame for eye-in-hand, in
    the flange frame for eye-to-hand; ``Z``'s rotation means nothing for a sphere)."""

    K: NDArray[np.float64] = None  # type: ignore[assignment]
    image_size: tuple[int, int] = (640, 480)
    radius: float = 0.025
    clouds: list = None  # type: ignore[assignment]
    depth_scale: float = 1.0
    depth_bias: float = 0.0
    #: with an arm: the joint angles the controller reports (rad), the arm's name, its nominal and real tables
    joints: NDArray[np.float64] | None = None
    arm: str | None = None
    chain: Chain | None = None
    chain_true: Chain | None = None


def _stem_depth(rays, start, axis, radius: float, length: float):
    """Per ray, where it meets the side of a rod of ``radius`` from ``start`` along ``axis`` for
    ``length`` (inf where it does not)."""
    d_perp = rays - (rays @ axis)[..., None] * axis
    w = -start
    w_perp = w - (w @ axis) * axis
    a = np.einsum("hwi,hwi->hw", d_perp, d_perp)
    b = d_perp @ w_perp
    c = w_perp @ w_perp - radius**2
    with np.errstate(invalid="ignore", divide="ignore"):
        t = (-b - np.sqrt(b**2 - a * c)) / a
        along = t * (rays @ axis) + w @ axis
    return np.where((t > 0) & (along >= 0) & (along <= length), t, np.inf)


def _sphere_image(K, size, centre, radius, plane_point, plane_normal, stem=None):
    """Per pixel the true point where its ray meets the sphere (or the rod holding it, ``stem``:
    its direction in the camera frame and radius), else the background plane; and the sphere's mask."""
    rays = pixel_rays(K, size)
    dd = np.einsum("hwi,hwi->hw", rays, rays)
    dc = rays @ centre
    disc = dc**2 - dd * (centre @ centre - radius**2)
    with np.errstate(invalid="ignore", divide="ignore"):
        t_sphere = np.where(disc > 0, (dc - np.sqrt(np.where(disc > 0, disc, 0.0))) / dd, np.inf)
        t_plane = (plane_normal @ plane_point) / (rays @ plane_normal)
    t_stem = np.full(t_sphere.shape, np.inf)
    if stem is not None:
        axis, stem_radius = stem
        t_stem = _stem_depth(rays, centre + 0.8 * radius * axis, axis, stem_radius, 0.15)
    sphere = t_sphere < t_stem
    t = np.where(sphere & np.isfinite(t_sphere), t_sphere, np.where(np.isfinite(t_stem), t_stem, t_plane))
    return rays * t[..., None], sphere & np.isfinite(t_sphere)


def sphere_scene(n_views: int = 15, setup: str = "eye_to_hand", rng: np.random.Generator | int | None = None, *,
                 radius: float = 0.025, image_size: tuple[int, int] = (640, 480),
                 depth_noise: tuple[float, float] = (1e-4, 5e-4), depth_scale: float = 1.002,
                 depth_bias: float = 0.0, holes: float = 0.01, distance: tuple[float, float] = (0.5, 1.0),
                 tilt_max_deg: float = 60.0, robot_error: tuple[float, float] | None = None,
                 stem: float | None = None, arm: str | None = None, length_mm: float = 0.5, angle_deg: float = 0.05,
                 joint_noise_deg: float = 0.002) -> SphereScene:
    """A depth camera's capture of a sphere of ``radius`` (m): on the flange in front of a fixed
    camera (eye-to-hand), or fixed in the cell and seen by the camera on the flange (eye-in-hand).

    ``n_views`` views at ``distance`` (m) from directions within ``tilt_max_deg`` of the target's z
    axis, the sphere anywhere in the middle two thirds of the image; behind it a tilted wall 0.2-0.4
    m further. Noise, scale, bias and holes as :func:`depth_scene`'s; the pixels on the sphere's
    outline are flying pixels (their depth half-way to the wall); ``robot_error`` as
    :func:`depth_scene`'s. ``stem``: the ball sits on a rod of that radius (m), 0.15 m long, towards
    the flange (eye-to-hand) or down to the table (eye-in-hand), which hides part of it from some views.
    ``arm``, ``length_mm``, ``angle_deg``, ``joint_noise_deg``: the views by an arm off its nominal
    table, as :func:`depth_scene`'s.
    """
    setup = check_setup(setup)
    rng = np.random.default_rng(rng)
    K = default_camera(image_size)[0]
    w, h = image_size
    views = None
    if arm is not None:
        ball = radius * np.array([[0.0, 0.0, 0.0], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]])
        views = arm_views(setup, ball, K, image_size, n_views, rng, arm, length_mm, angle_deg, joint_noise_deg)
        scene = views.scene
    else:
        cam2target = look_at_viewpoints(n_views, rng, distance=distance, tilt_max_deg=tilt_max_deg, aim_jitter=0.0)
        # turn each camera a little so that the sphere lands off the image centre
        off = np.c_[rng.uniform(-w / 3, w / 3, n_views) / K[0, 0], rng.uniform(-h / 3, h / 3, n_views) / K[1, 1]]
        turn = Rotation.from_rotvec(np.c_[off[:, 1], -off[:, 0], np.zeros(n_views)]).as_matrix()
        cam2target[:, :3, :3] = cam2target[:, :3, :3] @ turn
        scene = scene_from_viewpoints(cam2target, setup, rng)
    # the rod's direction in the target (ball) frame: down to the table, or to the flange's origin
    if setup_info(setup).camera_on_flange:
        stem_axis = scene.Z[:3, :3].T @ np.array([0.0, 0.0, -1.0])
    else:
        stem_axis = -scene.Z[:3, :3].T @ scene.Z[:3, 3]
        stem_axis /= np.linalg.norm(stem_axis)
    clouds = []
    for T in scene.target2cam:
        centre = T[:3, 3]
        normal = -centre / np.linalg.norm(centre) + rng.normal(0.0, 0.3, 3)
        normal /= np.linalg.norm(normal)
        wall = centre * (1.0 + rng.uniform(0.2, 0.4) / np.linalg.norm(centre))
        rod = None if stem is None else (T[:3, :3] @ stem_axis, stem)
        truth, sphere = _sphere_image(K, image_size, centre, radius, wall, normal, rod)
        behind = _sphere_image(K, image_size, centre + 10.0, radius, wall, normal)[0]  # the wall where the sphere is
        clouds.append(depth_reading(truth, sphere, behind, rng, depth_scale, depth_bias, depth_noise, holes))
    return SphereScene(setup, scene.X, scene.Z, reported_poses(scene.flange2base, robot_error, rng), scene.target2cam, K=K,
                       image_size=tuple(image_size),
                       radius=radius, clouds=clouds, depth_scale=depth_scale, depth_bias=depth_bias, **arm_fields(views))


def write_depth_session(folder: str | Path, scene: DepthScene | SphereScene, unit: str = "m",
                        working_range: tuple[float, float] | None = None,
                        rng: np.random.Generator | int | None = 0) -> Path:
    """Write a simulated depth capture as a depth session (``handeye.pipelines.depth.session``'s format):
    ``clouds/viewNN.npy`` (float32, in ``unit``), for a board the rendered intensity images
    ``images/viewNN.png``, ``poses.csv`` (quat_wxyz, mm, deg), with an arm ``joints.csv`` (the
    joint angles the controller reports, degrees), ``session.yaml`` (with the intensity image's K,
    a ``depth:`` mapping and the ``joints:`` block) and ``ground_truth.yaml``. Returns the folder."""
    out = check_output_folder(folder)
    (out / "clouds").mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(rng)
    spheres = isinstance(scene, SphereScene)
    names = [f"view{k + 1:02d}" for k in range(len(scene.flange2base))]
    for name, cloud in zip(names, scene.clouds):
        buf = io.BytesIO()
        np.save(buf, (cloud * (1e3 if unit == "mm" else 1.0)).astype(np.float32))
        atomic_write(out / "clouds" / f"{name}.npy", buf.getvalue())
    if spheres:
        target: dict = {"type": "sphere", "diameter": 2 * scene.radius}
        ids = [f"{n}.npy" for n in names]
    else:
        target = dict(scene.target_spec)
        ids = [f"{n}.png" for n in names]
        (out / "images").mkdir(exist_ok=True)
        renderer = Renderer(scene.K, np.zeros(5), scene.image_size)
        texture = target_texture(target_from_spec(target))
        for name, T in zip(ids, scene.target2cam):
            if not cv2.imwrite(str(out / "images" / name), renderer.render(texture, T, rng=rng)):
                raise HandEyeError(f"could not write {out / 'images' / name}")
    write_pose_table(out / "poses.csv", ids, scene.flange2base, "quat_wxyz", "mm", "deg",
                     id_column="cloud" if spheres else "image")
    joints = None
    if scene.joints is not None:  # the joint angles the controller reports, degrees, as image sessions have them
        write_joint_table(out / "joints.csv", ids, scene.joints, id_column="cloud" if spheres else "image")
        joints = {"file": "joints.csv", "unit": "deg", "arm": scene.arm}
    depth: dict = {"unit": unit}
    if working_range is not None:
        depth["range"] = [float(v) for v in working_range]
    spec = {"setup": scene.setup, "target": target, "camera": {"K": scene.K.tolist(), "dist": [0.0] * 5},
            "depth": depth, "poses": {"file": "poses.csv", "format": "quat_wxyz", "length_unit": "mm", "angle_unit": "deg"}}
    if joints is not None:
        spec["joints"] = joints
    atomic_write(out / "session.yaml", yaml.safe_dump(spec, sort_keys=False))
    info = setup_info(scene.setup)
    truth = {"setup": scene.setup, info.x_name: scene.X.tolist(), info.z_name: scene.Z.tolist(),
             "depth_scale": float(scene.depth_scale), "depth_bias": float(scene.depth_bias)}
    if scene.chain_true is not None:
        truth |= {"arm": scene.arm, "table_true": scene.chain_true.table.tolist()}
    atomic_write(out / "ground_truth.yaml", yaml.safe_dump(truth, sort_keys=False))
    return out
