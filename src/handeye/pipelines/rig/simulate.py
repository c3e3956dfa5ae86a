"""Rigs: several cameras, one robot, one target, with ground truth.

:func:`rig_scene` draws a stereo pair (or more cameras) on the flange looking at a board fixed in
the cell (eye-in-hand), or cameras fixed around the cell looking at a board on the flange
(eye-to-hand). Each camera sees the board in the views where all its corners fall inside its image
(a camera may miss views, or be told to); the corners carry pixel noise, the controller's poses the
robot's error.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..._shared.io import atomic_write, check_output_folder, write_png
from ...errors import HandEyeError, InputMismatchError
from ...frames.setups import check_setup, flange_poses, predicted_target2cam, setup_info
from ...geometry.se3 import invert, make_transform, random_rotations
from ...io.session import write_joint_table, write_pose_table
from ...robot.kinematics import Chain
from ...sensors.camera.model import CameraCorners
from ...sensors.camera.pnp import project_points, project_points_many
from ...sensors.camera.render import Renderer
from ...sensors.camera.targets.chessboard import Chessboard
from ...simulate import reported_poses
from ...simulate.arms import kinematic_scene
from ...simulate.scenes import look_at, scene_from_viewpoints
from ..depth.simulate_board import board_depth_image, depth_reading
from ..kinds import SimulateRequest
from ..laser.simulate import profile_reading, profiler_views, write_profile

__all__ = ["RigCamera", "RigScene", "rig_scene", "rig_joint_scene", "write_rig_session", "CameraLaserScene", "camera_laser_scene",
           "write_camera_laser_session", "ProfilerPairScene", "profiler_pair_scene", "write_profiler_pair_session",
           "CameraDepthScene", "camera_depth_scene", "write_camera_depth_session", "simulate_command"]


@dataclass(frozen=True)
class RigCamera:
    """One camera of a simulated rig: its X (cam2flange eye-in-hand, cam2base eye-to-hand), its
    intrinsics, and per view the corners it found (empty where it missed the board)."""

    name: str
    X: NDArray[np.float64]
    K: NDArray[np.float64]
    dist: NDArray[np.float64]
    image_points: list = field(default_factory=list)
    object_points: list = field(default_factory=list)

    @property
    def seen(self) -> NDArray[np.bool_]:
        """Per view whether the camera found the board."""
        return np.array([len(p) > 0 for p in self.image_points])


@dataclass(frozen=True)
class RigScene:
    """A simulated rig capture: the views' names, the controller's (``flange2base``) and the true
    flange poses, the board's pose ``Z`` and each camera."""

    setup: str
    names: list[str]
    flange2base: NDArray[np.float64]
    flange2base_true: NDArray[np.float64]
    Z: NDArray[np.float64]
    cameras: list[RigCamera]
    #: the joint angles the controller reported (N, n; rad) and the arm's nominal table, for a rig
    #: on an arm whose real table differs (:func:`rig_joint_scene`); None for controller poses
    joints: NDArray[np.float64] | None = None
    chain: Chain | None = None

    def camera_models(self, focal_error: dict[int, float] | None = None) -> list[CameraCorners]:
        """Each camera's corners as a sensor model over every view
        (:class:`~handeye.sensors.camera.model.CameraCorners`); ``focal_error``: per camera index a
        relative error put on the focal length it is given (a camera with the wrong intrinsics)."""
        out = []
        for k, c in enumerate(self.cameras):
            K = c.K.copy()
            K[:2, :2] *= 1.0 + (focal_error or {}).get(k, 0.0)
            out.append(CameraCorners(self.setup, self.names, c.image_points, c.object_points, K, c.dist))
        return out

    def relative(self, k: int) -> NDArray[np.float64]:
        """The true pose of camera ``k`` in camera 0's frame (``cam_k2cam_0``)."""
        return invert(self.cameras[0].X) @ self.cameras[k].X


#: Each camera's image (px) and its intrinsics (f, distortion k1, k2).
IMAGE = (1280, 1024)
BOARD = (9, 6, 0.03)


def _camera(rng: np.random.Generator) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    w, h = IMAGE
    f = rng.uniform(1300, 1500)
    return np.array([[f, 0, w / 2 + rng.uniform(-8, 8)], [0, f, h / 2 + rng.uniform(-8, 8)], [0, 0, 1.0]]), \
        np.array([rng.uniform(-0.12, -0.05), rng.uniform(0.02, 0.08), 0.0, 0.0, 0.0])


def rig_scene(n_views: int = 15, setup: str = "eye_in_hand", rng: np.random.Generator | int | None = None, *,
              cameras: int = 2, noise_px: float = 0.2, robot_error: tuple[float, float] | None = None,
              missing: dict[int, float] | None = None, baseline: float = 0.12) -> RigScene:
    """A rig's capture (the module docstring).

    ``cameras`` cameras: eye-in-hand a rig on the flange (camera 0 with a random mount; the others
    ``baseline`` (m) beside it, turned in by a few degrees), eye-to-hand fixed around the cell 0.8 m
    from the middle of the board's moves. ``n_views`` robot poses, each board view within 35 deg of
    the cameras' common view; the corners with ``noise_px`` of pixel noise; ``robot_error`` (deg,
    mm) as :func:`~handeye.pipelines.laser.simulate.laser_scene`'s; ``missing``: per camera index the share of
    views it is told to miss (a camera that saw less).

    Examples
    --------
    >>> sc = rig_scene(10, "eye_in_hand", rng=0)
    >>> len(sc.cameras), int(sc.cameras[1].seen.sum()) > 5
    (2, True)
    """
    setup = check_setup(setup)
    if cameras < 1 or n_views < 3:
        raise InputMismatchError(f"cameras={cameras}, n_views={n_views}: at least 1 camera and 3 views")
    rng = np.random.default_rng(rng)
    board = Chessboard(*BOARD)
    points = board.object_points()
    middle = points.mean(axis=0)
    intrinsics = [_camera(rng) for _ in range(cameras)]
    if setup_info(setup).camera_on_flange:
        X0 = make_transform(random_rotations(1, rng)[0], rng.uniform(-0.05, 0.05, 3))
        rel = [np.eye(4)] + [make_transform(Rotation.from_euler("xyz", [rng.uniform(-3, 3), -k * 6.0 + rng.uniform(-2, 2),
                                                                      rng.uniform(-3, 3)], degrees=True).as_matrix(),
                                            [k * baseline, rng.uniform(-0.01, 0.01), rng.uniform(-0.01, 0.01)])
                             for k in range(1, cameras)]
        Xs = [X0 @ r for r in rel]
        Z = make_transform(random_rotations(1, rng)[0], rng.uniform(-0.3, 0.3, 3) + [0.6, 0.0, 0.0])
        # camera 0's viewpoints: within 35 deg of the board's normal (-z of the board frame faces it), 0.5-0.8 m
        tilt = np.radians(35.0) * np.sqrt(rng.uniform(size=n_views))
        az = rng.uniform(0, 2 * np.pi, n_views)
        dist = rng.uniform(0.5, 0.8, n_views)
        direction = np.c_[np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), -np.cos(tilt)]
        aim = middle + np.c_[rng.uniform(-0.04, 0.04, (n_views, 2)), np.zeros(n_views)]
        cam2target = look_at(aim + dist[:, None] * direction, aim, rng.uniform(-np.pi, np.pi, n_views))
        # the rig's middle (between the cameras) looks at the board: camera 0 sits half a baseline off it
        shift = make_transform(np.eye(3), [-0.5 * baseline * (cameras - 1), 0.0, 0.0])
        cam2target = cam2target @ shift
        F = flange_poses(cam2target, X0, Z, setup)
        target2cam = [invert(cam2target @ r) for r in rel]
    else:
        centre = np.array([0.6, 0.0, 0.3])
        Z = make_transform(random_rotations(1, rng)[0], rng.uniform(-0.05, 0.05, 3) + [0.0, 0.0, 0.1])
        az0 = rng.uniform(0, 2 * np.pi)
        Xs = []
        for k in range(cameras):  # around the cell, looking down at the middle of the board's moves
            a = az0 + 2 * np.pi * k / max(cameras, 3)
            pos = centre + 0.8 * np.array([np.cos(a) * np.sin(np.radians(40)), np.sin(a) * np.sin(np.radians(40)),
                                           np.cos(np.radians(40))])
            Xs.append(look_at(pos, centre, rng.uniform(-np.pi, np.pi))[0])
        view = np.mean([X[:3, 3] for X in Xs], axis=0) - centre
        view /= np.linalg.norm(view)
        target2base = np.empty((n_views, 4, 4))
        for i in range(n_views):  # the board faces the cameras (its -z towards them), turned within 35 deg
            R = look_at(centre, centre - view, rng.uniform(-np.pi, np.pi))[0, :3, :3]  # +z away from the cameras
            R = Rotation.from_rotvec(np.radians(35.0) * np.sqrt(rng.uniform()) * _unit(rng)).as_matrix() @ R
            o = centre + rng.uniform(-0.08, 0.08, 3)
            target2base[i] = make_transform(R, o - R @ middle)
        F = target2base @ invert(Z)
        rel = [invert(Xs[0]) @ X for X in Xs]
        target2cam = [invert(X) @ target2base for X in Xs]
    names = [f"v{i + 1:02d}" for i in range(n_views)]
    cams = []
    for k, (X, (K, d), T) in enumerate(zip(Xs, intrinsics, target2cam)):
        drop = rng.random(n_views) < (missing or {}).get(k, 0.0)
        cams.append(RigCamera(f"cam{k}", X, K, d, *_corners(T, points, K, d, noise_px, rng, drop)))
    return RigScene(setup, names, reported_poses(F, robot_error, rng), F, Z, cams)


def _corners(T: NDArray[np.float64], points: NDArray[np.float64], K: NDArray[np.float64], dist: NDArray[np.float64],
             noise_px: float, rng: np.random.Generator, drop: NDArray[np.bool_] | None = None) -> tuple[list, list]:
    """Per view the board's corners a camera finds at the true ``T`` (target2cam, N): all of them with
    ``noise_px`` of noise where every corner is in the image and in front, none elsewhere or where
    ``drop``."""
    n = len(T)
    w, h = IMAGE
    px = project_points_many(T, np.tile(points, (n, 1)), np.repeat(np.arange(n), len(points)), K, dist).reshape(n, len(points), 2)
    depth = np.einsum("nij,mj->nmi", T[:, :3, :3], points)[..., 2] + T[:, None, 2, 3]
    inside = np.all((px[..., 0] > 5) & (px[..., 0] < w - 5) & (px[..., 1] > 5) & (px[..., 1] < h - 5) & (depth > 0), axis=1)
    keep = inside if drop is None else inside & ~drop
    img = [px[i] + rng.normal(0.0, noise_px, px[i].shape) if keep[i] else np.zeros((0, 2)) for i in range(n)]
    return img, [points if keep[i] else np.zeros((0, 3)) for i in range(n)]


def rig_joint_scene(n_views: int = 15, setup: str = "eye_in_hand", rng: np.random.Generator | int | None = None, *,
                    arm: str = "ur5", cameras: int = 2, noise_px: float = 0.2, length_mm: float = 0.5,
                    angle_deg: float = 0.05, baseline: float = 0.1) -> RigScene:
    """A rig on an arm whose real kinematic table differs from its nominal one
    (:func:`~handeye.simulate.arms.kinematic_scene`'s arm: every entry off by ``length_mm`` /
    ``angle_deg``, the flange 1-3 mm from where the nominal table puts it): camera 0 where that
    scene puts its camera, the others ``baseline`` (m) beside it, turned in by a few degrees; the
    controller reports the joint angles (``joints``, with encoder noise) and the nominal table's
    flange poses (``flange2base``). A camera that does not see the whole board in a view misses it.

    Examples
    --------
    >>> sc = rig_joint_scene(10, "eye_in_hand", rng=0)
    >>> sc.joints.shape, sc.chain.name
    ((10, 6), 'UR5')
    """
    rng = np.random.default_rng(rng)
    ks = kinematic_scene(n_views, setup, rng, arm=arm, length_mm=length_mm, angle_deg=angle_deg, pixel_px=noise_px)
    points = ks.object_points
    cams = [RigCamera("cam0", ks.X, ks.K, ks.dist, [p for p in ks.image_points], [points] * n_views)]
    for k in range(1, cameras):
        rel = make_transform(Rotation.from_euler("xyz", [rng.uniform(-3, 3), -k * 5.0 + rng.uniform(-2, 2), rng.uniform(-3, 3)],
                                                 degrees=True).as_matrix(), [k * baseline, rng.uniform(-0.01, 0.01), 0.0])
        X = ks.X @ rel
        K, dist = _camera(rng)
        img, obj = _corners(predicted_target2cam(X, ks.Z, ks.flange2base_true, setup), points, K, dist, noise_px, rng)
        cams.append(RigCamera(f"cam{k}", X, K, dist, img, obj))
    names = [f"v{i + 1:02d}" for i in range(n_views)]
    return RigScene(ks.setup, names, ks.flange2base, ks.flange2base_true, ks.Z, cams, ks.joints, ks.chain)


def _unit(rng: np.random.Generator) -> NDArray[np.float64]:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def write_rig_session(folder: str | Path, scene: RigScene, rng: np.random.Generator | int | None = None,
                      noise_px: float = 0.0) -> Path:
    """Write a simulated rig capture as a rig session folder (:mod:`handeye.pipelines.rig.session`): per
    camera a folder of its rendered images (``v01.png``, ...; none where it missed the view), its
    K and dist in session.yaml, ``poses.csv`` (first column ``view``; the controller's poses,
    quat_wxyz, mm, deg), or ``joints.csv`` (degrees) when the scene has joint angles, and
    ``ground_truth.yaml`` (every camera's X, the board's pose). Returns the folder."""
    out = check_output_folder(folder)
    if (out / "session.yaml").exists():
        raise HandEyeError(f"{out} already holds a session; choose an empty folder")
    rng = np.random.default_rng(rng)
    board = Chessboard(*BOARD)
    texture = board.texture()
    sensors, truth = {}, {"setup": scene.setup, setup_info(scene.setup).z_name: scene.Z.tolist(), "cameras": {}}
    for cam in scene.cameras:
        (out / cam.name).mkdir(parents=True, exist_ok=True)
        renderer = Renderer(cam.K, cam.dist, IMAGE)
        target2cam = predicted_target2cam(cam.X, scene.Z, scene.flange2base_true, scene.setup)
        for name, T, seen in zip(scene.names, target2cam, cam.seen):
            if not seen:
                continue
            write_png(out / cam.name / f"{name}.png", renderer.render(texture, T, rng=rng, noise_px=noise_px))
        sensors[cam.name] = {"camera": {"K": cam.K.tolist(), "dist": cam.dist.tolist()}, "images": cam.name}
        truth["cameras"][cam.name] = {setup_info(scene.setup).x_name: cam.X.tolist()}
    spec: dict = {"setup": scene.setup, "target": {"type": "chessboard", "cols": BOARD[0], "rows": BOARD[1], "square": BOARD[2]}}
    if scene.joints is not None:  # the controller's joint angles: the arm's table is fitted with the rig
        write_joint_table(out / "joints.csv", scene.names, scene.joints, "deg", id_column="view",
                          joint_names=list(scene.chain.joint_names) if scene.chain.joint_names else None)
        spec["joints"] = {"file": "joints.csv", "unit": "deg", "arm": scene.chain.name.lower()}
    else:
        write_pose_table(out / "poses.csv", scene.names, scene.flange2base, "quat_wxyz", "mm", "deg", id_column="view")
        spec["poses"] = {"file": "poses.csv", "format": "quat_wxyz", "length_unit": "mm", "angle_unit": "deg"}
    spec["sensors"] = sensors
    atomic_write(out / "session.yaml", yaml.safe_dump(spec, sort_keys=False))
    atomic_write(out / "ground_truth.yaml", yaml.safe_dump(truth, sort_keys=False))
    return out


@dataclass(frozen=True)
class CameraLaserScene:
    """A camera and a laser profiler on one flange (eye-in-hand) or fixed side by side (eye-to-hand):
    the camera's views of a small board (``camera``), the profiler's profiles of a ball (``profiles``,
    its X ``laser_X``), the ball's pose ``Z_ball`` and the board's ``Z_board``."""

    setup: str
    names: list[str]
    flange2base: NDArray[np.float64]
    flange2base_true: NDArray[np.float64]
    camera: RigCamera
    laser_X: NDArray[np.float64]
    profiles: list
    radius: float
    Z_ball: NDArray[np.float64]
    Z_board: NDArray[np.float64]

    def relative(self) -> NDArray[np.float64]:
        """The camera's true pose in the profiler's frame (``cam2laser``)."""
        return invert(self.laser_X) @ self.camera.X


#: The mixed rig's profiler's noise along z (m).
PROFILE_NOISE_M = 2e-5
#: The mixed rig's board: small enough to stay in view while the profiler circles the ball beside it.
SMALL_BOARD = (9, 6, 0.01)


def camera_laser_scene(n_views: int = 20, setup: str = "eye_in_hand", rng: np.random.Generator | int | None = None, *,
                       noise_px: float = 0.2, robot_error: tuple[float, float] | None = None,
                       cone_deg: float = 25.0) -> CameraLaserScene:
    """A camera beside a laser profiler (the profiler of :func:`~handeye.pipelines.laser.simulate.laser_scene`,
    scanning a 40 mm ball from within ``cone_deg`` of its top; the camera 60 mm beside it, looking the
    same way, with a wider lens, at a 90 x 60 mm board the ball rests on): the views the robot took
    for the profiler, each camera image kept where the whole board is in it.

    Examples
    --------
    >>> sc = camera_laser_scene(12, "eye_in_hand", rng=0)
    >>> len(sc.profiles), int(sc.camera.seen.sum()) >= 6
    (12, True)
    """

    setup = check_setup(setup)
    rng = np.random.default_rng(rng)
    radius = 0.02
    sensor2ball = profiler_views("sphere", n_views, radius, rng, cone_deg)
    scene = scene_from_viewpoints(sensor2ball, setup, rng)
    laser_X, Z_ball, F = scene.X, scene.Z, scene.flange2base
    cam2laser = make_transform(Rotation.from_euler("xyz", [rng.uniform(-3, 3), -24.0, rng.uniform(-3, 3)], degrees=True)
                               .as_matrix(), [0.06, rng.uniform(-0.01, 0.01), 0.0])
    board = Chessboard(*SMALL_BOARD)
    points = board.object_points()
    K, dist = _camera(rng)
    K[:2, :2] *= 0.6  # a wider lens: the board is near
    # the board flat under the ball (the ball resting on it), in the target's frame: in view of the
    # camera beside the profiler whichever way the profiler turns about the ball
    X_cam = laser_X @ cam2laser
    Z_board = Z_ball @ make_transform(np.eye(3), [0.0, 0.0, -radius]) @ make_transform(np.eye(3), -points.mean(axis=0))
    img, obj = _corners(predicted_target2cam(X_cam, Z_board, F, setup), points, K, dist, noise_px, rng)
    ball2sensor = predicted_target2cam(laser_X, Z_ball, F, setup)
    profiles = [profile_reading("sphere", T, radius, rng, PROFILE_NOISE_M, 0.02, 0.002) for T in ball2sensor]
    names = [f"v{i + 1:02d}" for i in range(n_views)]
    return CameraLaserScene(setup, names, reported_poses(F, robot_error, rng), F, RigCamera("camera", X_cam, K, dist, img, obj),
                            laser_X, profiles, radius, Z_ball, Z_board)


def write_camera_laser_session(folder: str | Path, scene: CameraLaserScene, rng: np.random.Generator | int | None = None,
                               noise_px: float = 0.0) -> Path:
    """Write a camera beside a laser profiler (:func:`camera_laser_scene`) as a rig session folder
    (:mod:`handeye.pipelines.rig.session`): ``camera/`` the camera's rendered images of the small board
    (none where it missed the view), ``laser/`` the profiler's profiles of the ball (``x,z`` in mm),
    ``poses.csv`` (first column ``view``; the controller's poses), session.yaml (the board as the
    session's target, the ball as the profiler's own) and ``ground_truth.yaml`` (both X, the board's
    and the ball's poses). Returns the folder."""
    out = check_output_folder(folder)
    if (out / "session.yaml").exists():
        raise HandEyeError(f"{out} already holds a session; choose an empty folder")
    rng = np.random.default_rng(rng)
    cam, info = scene.camera, setup_info(scene.setup)
    (out / "camera").mkdir(parents=True, exist_ok=True)
    (out / "laser").mkdir(parents=True, exist_ok=True)
    renderer, texture = Renderer(cam.K, cam.dist, IMAGE), Chessboard(*SMALL_BOARD).texture()
    for name, T, seen in zip(scene.names, predicted_target2cam(cam.X, scene.Z_board, scene.flange2base_true, scene.setup),
                             cam.seen):
        if seen:
            write_png(out / "camera" / f"{name}.png", renderer.render(texture, T, rng=rng, noise_px=noise_px))
    for name, p in zip(scene.names, scene.profiles):
        write_profile(out / "laser" / f"{name}.csv", p, "mm")
    write_pose_table(out / "poses.csv", scene.names, scene.flange2base, "quat_wxyz", "mm", "deg", id_column="view")
    board = {"type": "chessboard", "cols": SMALL_BOARD[0], "rows": SMALL_BOARD[1], "square": SMALL_BOARD[2]}
    spec = {"setup": scene.setup, "target": board,
            "poses": {"file": "poses.csv", "format": "quat_wxyz", "length_unit": "mm", "angle_unit": "deg"},
            "sensors": {"camera": {"camera": {"K": cam.K.tolist(), "dist": cam.dist.tolist()}, "images": "camera"},
                        "laser": {"laser": {"unit": "mm", "noise": 1e3 * PROFILE_NOISE_M}, "profiles": "laser",
                                  "target": {"type": "sphere", "diameter": 2 * scene.radius}}}}
    atomic_write(out / "session.yaml", yaml.safe_dump(spec, sort_keys=False))
    truth = {"setup": scene.setup, "sensors": {"camera": {info.x_name: cam.X.tolist()},
                                               "laser": {info.x_name: scene.laser_X.tolist()}},
             "board": {info.z_name: scene.Z_board.tolist()}, "ball": {info.z_name: scene.Z_ball.tolist()}}
    atomic_write(out / "ground_truth.yaml", yaml.safe_dump(truth, sort_keys=False))
    return out


@dataclass(frozen=True)
class ProfilerPairScene:
    """Two laser profilers on one flange (eye-in-hand) or fixed side by side (eye-to-hand) that scanned
    one ball, each from robot poses of its own: per view its name, the controller's and the true poses,
    and per profiler its X and its profiles (None where it did not scan)."""

    setup: str
    names: list[str]
    flange2base: NDArray[np.float64]
    flange2base_true: NDArray[np.float64]
    X: list[NDArray[np.float64]]
    profiles: list[list]
    radius: float
    Z_ball: NDArray[np.float64]

    def relative(self) -> NDArray[np.float64]:
        """The second profiler's true pose in the first one's frame."""
        return invert(self.X[0]) @ self.X[1]


def profiler_pair_scene(n_views: int = 12, setup: str = "eye_in_hand", rng: np.random.Generator | int | None = None, *,
                        robot_error: tuple[float, float] | None = None, radius: float = 0.02,
                        cone_deg: float = 45.0) -> ProfilerPairScene:
    """Two profilers (:func:`~handeye.pipelines.laser.simulate.laser_scene`'s, the second 80 mm beside the first
    and turned 20 deg) that scanned one ball: ``n_views`` robot poses for each, of its own (no pose
    shared: each pose's own error does not cancel between them); the controller's poses off by
    ``robot_error`` (deg, mm) as :func:`~handeye.pipelines.laser.simulate.laser_scene`'s.

    Examples
    --------
    >>> sc = profiler_pair_scene(6, "eye_in_hand", rng=0)
    >>> len(sc.names), [sum(p is not None for p in ps) for ps in sc.profiles]
    (12, [6, 6])
    """
    setup = check_setup(setup)
    rng = np.random.default_rng(rng)
    rel = make_transform(Rotation.from_euler("xyz", [0.0, 20.0, rng.uniform(-5, 5)], degrees=True).as_matrix(),
                         [0.08, rng.uniform(-0.01, 0.01), 0.0])
    first = scene_from_viewpoints(profiler_views("sphere", n_views, radius, rng, cone_deg), setup, rng)
    X = [first.X, first.X @ rel]
    F = [first.flange2base, flange_poses(profiler_views("sphere", n_views, radius, rng, cone_deg), X[1], first.Z, setup)]
    F_true = np.concatenate(F)
    n = len(F_true)
    seen = [np.arange(n) < n_views, np.arange(n) >= n_views]
    profiles = []
    for k in range(2):
        ball2sensor = predicted_target2cam(X[k], first.Z, F_true, setup)
        profiles.append([profile_reading("sphere", T, radius, rng, PROFILE_NOISE_M, 0.02, 0.002) if s else None
                         for T, s in zip(ball2sensor, seen[k])])
    names = [f"v{i + 1:02d}" for i in range(n)]
    return ProfilerPairScene(setup, names, reported_poses(F_true, robot_error, rng), F_true, X, profiles, radius, first.Z)


def write_profiler_pair_session(folder: str | Path, scene: ProfilerPairScene) -> Path:
    """Write :func:`profiler_pair_scene` as a rig session folder (:mod:`handeye.pipelines.rig.session`):
    ``laser_a/`` and ``laser_b/`` the profilers' profiles named by view (``x,z`` in mm; none where a
    profiler did not scan), ``poses.csv`` (first column ``view``), session.yaml (the ball as both
    profilers' target) and ``ground_truth.yaml``. Returns the folder."""
    out = check_output_folder(folder)
    if (out / "session.yaml").exists():
        raise HandEyeError(f"{out} already holds a session; choose an empty folder")
    info = setup_info(scene.setup)
    sensors, truth = {}, {}
    for name, X, profiles in zip(("laser_a", "laser_b"), scene.X, scene.profiles):
        (out / name).mkdir(parents=True, exist_ok=True)
        for view, p in zip(scene.names, profiles):
            if p is not None:
                write_profile(out / name / f"{view}.csv", p, "mm")
        sensors[name] = {"laser": {"unit": "mm", "noise": 1e3 * PROFILE_NOISE_M}, "profiles": name}
        truth[name] = {info.x_name: X.tolist()}
    write_pose_table(out / "poses.csv", scene.names, scene.flange2base, "quat_wxyz", "mm", "deg", id_column="view")
    spec = {"setup": scene.setup, "target": {"type": "sphere", "diameter": 2 * scene.radius},
            "poses": {"file": "poses.csv", "format": "quat_wxyz", "length_unit": "mm", "angle_unit": "deg"},
            "sensors": sensors}
    atomic_write(out / "session.yaml", yaml.safe_dump(spec, sort_keys=False))
    atomic_write(out / "ground_truth.yaml", yaml.safe_dump({"setup": scene.setup, "sensors": truth,
                                                            "ball": {info.z_name: scene.Z_ball.tolist()}}, sort_keys=False))
    return out


@dataclass(frozen=True)
class CameraDepthScene:
    """A camera and a depth camera on one flange (eye-in-hand) or fixed side by side (eye-to-hand),
    both seeing one board: the camera's corners (``camera``), the depth camera's X (``depth_X``), its
    intensity image's intrinsics and size, and per view its corners and organized cloud (None where
    the whole board is not in its image), from depths ``depth_scale`` times the true ones plus
    ``depth_bias``."""

    setup: str
    names: list[str]
    flange2base: NDArray[np.float64]
    flange2base_true: NDArray[np.float64]
    Z: NDArray[np.float64]
    camera: RigCamera
    depth_X: NDArray[np.float64]
    depth_K: NDArray[np.float64]
    depth_size: tuple[int, int]
    depth_points: list
    clouds: list
    depth_scale: float
    depth_bias: float

    def relative(self) -> NDArray[np.float64]:
        """The depth camera's true pose in the camera's frame (``depth2camera``)."""
        return invert(self.camera.X) @ self.depth_X


def camera_depth_scene(n_views: int = 15, setup: str = "eye_in_hand", rng: np.random.Generator | int | None = None, *,
                       noise_px: float = 0.2, robot_error: tuple[float, float] | None = None,
                       depth_size: tuple[int, int] = (640, 480), depth_scale: float = 1.002, depth_bias: float = 0.0,
                       depth_noise: tuple[float, float] = (1e-4, 5e-4), holes: float = 0.01) -> CameraDepthScene:
    """A camera beside a depth camera (:func:`rig_scene`'s two cameras, the second an RGB-D camera with
    a 60 deg lens at ``depth_size`` px): the camera's corners as :func:`rig_scene`'s; the depth camera's
    clouds as :func:`~handeye.pipelines.depth.simulate_board.depth_scene`'s (``depth_noise``, scale, bias, holes,
    flying pixels on the board's edge) and its corners with ``noise_px`` in its registered intensity image.

    Examples
    --------
    >>> sc = camera_depth_scene(8, "eye_in_hand", rng=0, depth_size=(320, 240))
    >>> sc.clouds[0].shape, int(sum(c is not None for c in sc.clouds)) >= 4
    ((240, 320, 3), True)
    """
    rng = np.random.default_rng(rng)
    sc = rig_scene(n_views, setup, rng, cameras=2, noise_px=noise_px, robot_error=robot_error)
    w, h = depth_size
    f = 0.5 * w / np.tan(np.radians(30.0))
    K = np.array([[f, 0.0, w / 2], [0.0, f, h / 2], [0.0, 0.0, 1.0]])
    board = Chessboard(*BOARD)
    points, outline = board.object_points(), board.texture().outline()
    X = sc.cameras[1].X
    image_points, clouds = [], []
    for T in predicted_target2cam(X, sc.Z, sc.flange2base_true, sc.setup):
        px = project_points(T, points, K, np.zeros(5))
        depth = points @ T[2, :3] + T[2, 3]
        if not (np.all(depth > 0) and np.all((px > 5) & (px < [w - 5, h - 5]))):
            image_points.append(np.zeros((0, 2)))
            clouds.append(None)
            continue
        truth, mask = board_depth_image(K, depth_size, T, outline, background=2.5)
        behind = truth * (2.5 / truth[..., 2])[..., None]
        clouds.append(depth_reading(truth, mask, behind, rng, depth_scale, depth_bias, depth_noise, holes))
        image_points.append(px + rng.normal(0.0, noise_px, px.shape))
    return CameraDepthScene(sc.setup, sc.names, sc.flange2base, sc.flange2base_true, sc.Z, replace(sc.cameras[0], name="camera"),
                            X, K, tuple(depth_size), image_points, clouds, depth_scale, depth_bias)


def write_camera_depth_session(folder: str | Path, scene: CameraDepthScene, rng: np.random.Generator | int | None = None,
                               noise_px: float = 0.0) -> Path:
    """Write a camera beside a depth camera (:func:`camera_depth_scene`) as a rig session folder
    (:mod:`handeye.pipelines.rig.session`): ``camera/`` the camera's rendered images, ``depth/`` the depth
    camera's clouds (``v01.npy``, metres, float32) beside its rendered intensity images (``v01.png``;
    neither where it missed the board), ``poses.csv`` (first column ``view``; the controller's poses),
    session.yaml (the board the session's target, seen by both) and ``ground_truth.yaml`` (both X,
    the board's pose, the depth scale and bias). Returns the folder."""
    out = check_output_folder(folder)
    if (out / "session.yaml").exists():
        raise HandEyeError(f"{out} already holds a session; choose an empty folder")
    rng = np.random.default_rng(rng)
    cam, info = scene.camera, setup_info(scene.setup)
    texture = Chessboard(*BOARD).texture()
    for sub in ("camera", "depth"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    renderer = Renderer(cam.K, cam.dist, IMAGE)
    for name, T, seen in zip(scene.names, predicted_target2cam(cam.X, scene.Z, scene.flange2base_true, scene.setup), cam.seen):
        if seen:
            write_png(out / "camera" / f"{name}.png", renderer.render(texture, T, rng=rng, noise_px=noise_px))
    renderer = Renderer(scene.depth_K, np.zeros(5), scene.depth_size)
    for name, T, cloud in zip(scene.names, predicted_target2cam(scene.depth_X, scene.Z, scene.flange2base_true, scene.setup),
                              scene.clouds):
        if cloud is None:
            continue
        write_png(out / "depth" / f"{name}.png", renderer.render(texture, T, rng=rng, noise_px=noise_px))
        buf = io.BytesIO()
        np.save(buf, np.asarray(cloud, np.float32))
        atomic_write(out / "depth" / f"{name}.npy", buf.getvalue())
    write_pose_table(out / "poses.csv", scene.names, scene.flange2base, "quat_wxyz", "mm", "deg", id_column="view")
    spec = {"setup": scene.setup, "target": {"type": "chessboard", "cols": BOARD[0], "rows": BOARD[1], "square": BOARD[2]},
            "poses": {"file": "poses.csv", "format": "quat_wxyz", "length_unit": "mm", "angle_unit": "deg"},
            "sensors": {"camera": {"camera": {"K": cam.K.tolist(), "dist": cam.dist.tolist()}, "images": "camera"},
                        "depth": {"depth": {"unit": "m"}, "camera": {"K": scene.depth_K.tolist(), "dist": [0.0] * 5},
                                  "clouds": "depth"}}}
    atomic_write(out / "session.yaml", yaml.safe_dump(spec, sort_keys=False))
    truth = {"setup": scene.setup, "sensors": {"camera": {info.x_name: cam.X.tolist()}, "depth": {info.x_name: scene.depth_X.tolist()}},
             info.z_name: scene.Z.tolist(), "depth_scale": float(scene.depth_scale), "depth_bias": float(scene.depth_bias)}
    atomic_write(out / "ground_truth.yaml", yaml.safe_dump(truth, sort_keys=False))
    return out


def simulate_command(request: SimulateRequest) -> str:
    """``handeye simulate --sensor rig`` (the rig's registration's ``simulate`` hook): a rig session
    written to ``request.out`` (a stereo pair on the flange or three cameras fixed around the cell;
    ``options``: ``cameras``, their number, or ``depth`` / ``laser``: one camera beside a depth camera
    or a laser profiler); returns what was written, in words."""
    if request.robot != "arm" or request.target is not None:
        raise InputMismatchError("--sensor rig simulates a 6-axis arm (its controller's poses, or with --arm its joint "
                                 "angles) and a chessboard; leave --robot and --target out")
    on_flange = setup_info(request.setup).camera_on_flange
    n_cameras, laser, depth = request.options.get("cameras"), request.options.get("laser"), request.options.get("depth")
    if laser and depth:
        raise InputMismatchError("--laser and --depth each put one sensor beside the camera: give one of them")
    if depth or laser:  # a camera beside one other sensor: an RGB-D camera, or a profiler scanning a ball
        flag, other = ("--depth", "depth camera") if depth else ("--laser", "laser profiler")
        if request.arm is not None or n_cameras is not None:
            raise InputMismatchError(f"{flag} simulates one camera beside one {other} on controller poses; leave --arm "
                                     "and --cameras out")
        scene, write = (camera_depth_scene, write_camera_depth_session) if depth else \
            (camera_laser_scene, write_camera_laser_session)
        write(request.out, scene(request.poses, request.setup, request.seed, robot_error=(0.01, 0.05)), rng=request.seed,
              noise_px=request.noise_px)
        seen = "a chessboard both see, the depth scale 0.2% off" if depth else "a small chessboard and a 40 mm ball"
        return (f"wrote rig session {request.out} ({request.poses} poses, a camera and a {other} "
                f"{'on the flange' if on_flange else 'fixed side by side'}: {seen}; the robot 0.01 deg / 0.05 mm off); "
                f"ground truth in {Path(request.out) / 'ground_truth.yaml'}")
    cameras = n_cameras or (2 if on_flange else 3)
    if request.arm is not None:  # joint angles of an arm 1-3 mm off its nominal table, the cameras side by side
        sc = rig_joint_scene(request.poses, request.setup, request.seed, arm=request.arm, cameras=cameras)
        error = f"the {sc.chain.name}'s joint angles, its real table 1-3 mm off the nominal one"
    else:
        sc = rig_scene(request.poses, request.setup, request.seed, cameras=cameras, robot_error=(0.01, 0.05))
        error = "the robot 0.01 deg / 0.05 mm off"
    write_rig_session(request.out, sc, rng=request.seed, noise_px=request.noise_px)
    what = ("a stereo pair on the flange" if cameras == 2 else f"{cameras} cameras on the flange") if on_flange else \
        f"{cameras} cameras fixed {'side by side' if request.arm else 'around the cell'}"
    return (f"wrote rig session {request.out} ({request.poses} poses, {what}, a chessboard; {error}); "
            f"ground truth in {Path(request.out) / 'ground_truth.yaml'}")
