"""Scenes of viewpoints with ground truth (the thesis's §5.2 set-up), their noise, and rendered sessions.

A scene is a set of camera viewpoints of the target (the camera looks at the target from a cone
of directions about its normal), turned into robot poses through the ground-truth ``X`` and ``Z``:

* eye-in-hand: ``X = cam2flange``, ``Z = target2base``; ``flange2base_i = Z @ cam2target_i @ inv(X)``.
* eye-to-hand: ``X = cam2base``, ``Z = target2flange``; ``flange2base_i = X @ target2cam_i @ inv(Z)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from .._shared.lazy import lazy_module
from ..errors import HandEyeError, InputMismatchError
from ..frames.setups import check_setup, flange_poses, setup_info
from ..geometry.se3 import invert, make_transform, random_rotations
from ..io.session import write_session
from ..sensors.camera.render import Renderer, target_texture
from ..sensors.camera.targets import target_from_spec

cv2 = lazy_module("cv2")


from ._common import (
    DEFAULT_TARGETS,
    MIN_IMAGE_SIDE,
    SIMULATED_IMAGE_SUFFIXES,
    _new_session_folder,
    _write_images,
    _write_truth,
    default_camera,
)
from .arms import LOW_DOF_ROBOTS, low_dof_scene


@dataclass(frozen=True)
class Scene:
    """Ground truth and noise-free measurements of a simulated capture."""

    setup: str
    X: NDArray[np.float64]  #: cam2flange (eye_in_hand) or cam2base (eye_to_hand)
    Z: NDArray[np.float64]  #: target2base (eye_in_hand) or target2flange (eye_to_hand)
    flange2base: NDArray[np.float64]
    target2cam: NDArray[np.float64]


def look_at_viewpoints(
    n: int,
    rng: np.random.Generator,
    distance: tuple[float, float] = (0.5, 1.0),
    tilt_max_deg: float = 45.0,
    aim_jitter: float = 0.05,
    side: float = 1.0,
    centre: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """``cam2target`` poses of a camera looking at the target.

    The viewing direction lies within ``tilt_max_deg`` of the target normal, the camera on the
    ``side`` (+1: +z, -1: -z, where a printed target is seen from) at a distance uniform in
    ``distance`` (m) from ``centre`` (default the origin), the roll about the optical axis is free,
    and the aim point is jittered by ``aim_jitter`` (m) so the target is not always centred.
    """
    # Directions uniform over the spherical cap of half-angle tilt_max about +z.
    cos_max = np.cos(np.radians(tilt_max_deg))
    cz = rng.uniform(cos_max, 1.0, n)
    phi = rng.uniform(0.0, 2 * np.pi, n)
    sz = np.sqrt(1.0 - cz**2)
    direction = np.stack([sz * np.cos(phi), sz * np.sin(phi), side * cz], axis=1)
    c0 = np.zeros(3) if centre is None else np.asarray(centre, dtype=float)
    position = c0 + direction * rng.uniform(*distance, n)[:, None]
    aim = c0 + rng.uniform(-aim_jitter, aim_jitter, (n, 3)) * [1.0, 1.0, 0.0]
    return look_at(position, aim, rng.uniform(-np.pi, np.pi, n))


def look_at(position: NDArray[np.float64], aim: NDArray[np.float64], roll: NDArray[np.float64]) -> NDArray[np.float64]:
    """``cam2target`` poses (N, 4, 4) of cameras at ``position`` (N, 3) whose optical axis (+z) points
    at ``aim`` (N, 3), turned by ``roll`` (N,) rad about that axis from a reference orientation
    (x along ``helper x z``, helper = target x, or y when the axis is near target x)."""
    position, aim = np.atleast_2d(position).astype(float), np.atleast_2d(aim).astype(float)
    z = aim - position
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    helper = np.where(np.abs(z[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(z, x)
    R = np.stack([x, y, z], axis=2)
    turn = Rotation.from_rotvec(np.outer(np.broadcast_to(roll, len(z)), [0.0, 0.0, 1.0])).as_matrix()
    return make_transform(R @ turn, position)


def random_scene(
    n_poses: int,
    setup: str = "eye_in_hand",
    rng: np.random.Generator | int | None = None,
    *,
    x_translation: float = 0.05,
    distance: tuple[float, float] = (0.5, 1.0),
    tilt_max_deg: float = 45.0,
) -> Scene:
    """A random noise-free scene.

    Parameters
    ----------
    n_poses : int
    setup : {'eye_in_hand', 'eye_to_hand'}
    rng : numpy Generator or seed
    x_translation : float
        Eye-in-hand: the camera offset on the flange is uniform in +-``x_translation`` (m) per axis
        with a uniformly random rotation (thesis §5.2: +-50 mm). Eye-to-hand: the target offset on
        the flange, likewise.
    distance, tilt_max_deg
        Viewpoint distribution, see :func:`look_at_viewpoints`.
    """
    setup = check_setup(setup)
    rng = np.random.default_rng(rng)
    cam2target = look_at_viewpoints(n_poses, rng, distance=distance, tilt_max_deg=tilt_max_deg)
    return scene_from_viewpoints(cam2target, setup, rng, x_translation=x_translation)


def scene_from_viewpoints(
    cam2target: NDArray[np.float64], setup: str, rng: np.random.Generator, x_translation: float = 0.05
) -> Scene:
    """A scene whose camera sees the target from ``cam2target``: random X and Z, robot poses from them."""
    target2cam = invert(cam2target)
    offset = make_transform(random_rotations(1, rng)[0], rng.uniform(-x_translation, x_translation, 3))
    if setup_info(setup).camera_on_flange:
        X = offset
        Z = make_transform(random_rotations(1, rng)[0], rng.uniform(-0.5, 0.5, 3) + [0.6, 0.0, 0.0])
    else:
        Z = offset
        X = make_transform(random_rotations(1, rng)[0], rng.uniform(-0.5, 0.5, 3) + [1.0, 0.0, 0.5])
    return Scene(setup, X, Z, flange_poses(cam2target, X, Z, setup), target2cam)


def perturb_poses(
    T: NDArray[np.float64],
    rot_sigma_rad: float,
    trans_sigma_m: float,
    rng: np.random.Generator,
) -> NDArray[np.float64]:
    """Poses with Gaussian noise: a random rotation vector (sigma per axis) and translation offset."""
    T = np.asarray(T, dtype=float)
    n = T.reshape(-1, 4, 4).shape[0]
    dR = Rotation.from_rotvec(rng.normal(0.0, rot_sigma_rad, (n, 3))).as_matrix()
    noisy = T.reshape(-1, 4, 4).copy()
    noisy[:, :3, :3] = dR @ noisy[:, :3, :3]
    noisy[:, :3, 3] += rng.normal(0.0, trans_sigma_m, (n, 3))
    return noisy.reshape(T.shape)


@dataclass(frozen=True)
class SceneBatch:
    """``S`` independent simulated captures of ``N`` poses each (ground truth, noise-free)."""

    setup: str
    X: NDArray[np.float64]  #: (S, 4, 4): cam2flange (eye_in_hand) or cam2base (eye_to_hand)
    Z: NDArray[np.float64]  #: (S, 4, 4): target2base (eye_in_hand) or target2flange (eye_to_hand)
    flange2base: NDArray[np.float64]  #: (S, N, 4, 4)
    target2cam: NDArray[np.float64]  #: (S, N, 4, 4)

    def __len__(self) -> int:
        return len(self.X)


def seed_viewpoints(
    runs: int,
    n_poses: int,
    rng: np.random.Generator,
    start_distance: float = 1.0,
    cube: float = 1.0,
    tilt_max_deg: float = 45.0,
) -> NDArray[np.float64]:
    """``cam2target`` poses ``(runs, n_poses, 4, 4)`` of the thesis's simulation (§5.2).

    The robot starts with the camera ``start_distance`` (m) in front of the target, looking at it
    along the target normal; it moves within a cube of side ``cube`` (m) centred there, tilting the
    camera by up to ``tilt_max_deg`` about the two axes parallel to the image plane and freely
    about the optical axis. As in the thesis, the camera is assumed to see the target from
    everywhere (this generator is for pose-level studies; rendered sessions use
    :func:`look_at_viewpoints`, which keeps the target in the image).
    """
    shape = (runs, n_poses)
    position = np.array([0.0, 0.0, start_distance]) + rng.uniform(-0.5 * cube, 0.5 * cube, shape + (3,))
    # Facing the target: camera z along -z of the target, x along the target's x.
    facing = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
    tilt = np.radians(tilt_max_deg)
    angles = np.stack([rng.uniform(-tilt, tilt, shape), rng.uniform(-tilt, tilt, shape),
                       rng.uniform(-np.pi, np.pi, shape)], axis=-1)
    # intrinsic X-Y-Z: tilt about the camera's x, then its (new) y, then spin about the optical axis
    R = facing @ Rotation.from_euler("XYZ", angles.reshape(-1, 3)).as_matrix().reshape(shape + (3, 3))
    return make_transform(R, position)


def seed_scenes(
    runs: int,
    n_poses: int,
    setup: str = "eye_in_hand",
    rng: np.random.Generator | int | None = None,
    *,
    x_translation: float = 0.05,
    start_distance: float = 1.0,
    cube: float = 1.0,
    tilt_max_deg: float = 45.0,
) -> SceneBatch:
    """``runs`` random noise-free scenes of the thesis's §5.2 set-up, generated all at once.

    Parameters
    ----------
    runs, n_poses : int
        Number of independent scenes and of poses in each (``n_poses - 1`` consecutive motions).
    setup : {'eye_in_hand', 'eye_to_hand'}
    rng : numpy Generator or seed
    x_translation : float
        The unknown offset on the flange has a uniformly random rotation and a translation uniform
        in +-``x_translation`` (m) per axis (thesis: +-50 mm): ``X = cam2flange`` for eye-in-hand,
        ``Z = target2flange`` for eye-to-hand (the other unknown is a random placement in the cell).
    start_distance, cube, tilt_max_deg
        See :func:`seed_viewpoints`.
    """
    setup = check_setup(setup)
    rng = np.random.default_rng(rng)
    cam2target = seed_viewpoints(runs, n_poses, rng, start_distance, cube, tilt_max_deg)
    target2cam = invert(cam2target)
    offset = make_transform(random_rotations(runs, rng), rng.uniform(-x_translation, x_translation, (runs, 3)))
    # the other unknown: the target ~0.6 m from the base (eye-in-hand) or the camera ~1 m (eye-to-hand)
    on_flange = setup_info(setup).camera_on_flange
    centre = [0.6, 0.0, 0.0] if on_flange else [1.0, 0.0, 0.5]
    cell = make_transform(random_rotations(runs, rng), rng.uniform(-0.5, 0.5, (runs, 3)) + centre)
    X, Z = (offset, cell) if on_flange else (cell, offset)
    return SceneBatch(setup, X, Z, flange_poses(cam2target, X[:, None], Z[:, None], setup), target2cam)


@dataclass(frozen=True)
class Noise:
    """Pose noise of the thesis's study (§5.2): per component, Gaussian with ``sigma = n``.

    Orientation and position errors are independent, as a robot's data sheet states them: the
    rotation error turns the pose about its own origin and the translation error moves the origin.
    Their components are drawn in the frame the pose is given in (``frame='reference'``: the robot
    base for ``flange2base``, the camera for ``target2cam``) or in the pose's own frame
    (``frame='local'``: the flange or the target). Rotation-vector components ~ N(rot_bias_deg,
    rot_deg) degrees, translation components ~ N(trans_bias_mm, trans_mm) millimetres; non-zero
    biases are the thesis's systematic errors.
    """

    rot_deg: float = 0.0
    trans_mm: float = 0.0
    rot_bias_deg: float = 0.0
    trans_bias_mm: float = 0.0
    frame: str = "reference"

    def __post_init__(self) -> None:
        if self.frame not in ("reference", "local"):
            raise InputMismatchError(f"Noise.frame={self.frame!r}; use 'reference' or 'local'")
        for name in ("rot_deg", "trans_mm"):
            if not getattr(self, name) >= 0:
                raise InputMismatchError(f"Noise.{name} must be >= 0, got {getattr(self, name)}")

    @property
    def is_zero(self) -> bool:
        return not (self.rot_deg or self.trans_mm or self.rot_bias_deg or self.trans_bias_mm)


def add_noise(T: NDArray[np.float64], noise: Noise, rng: np.random.Generator) -> NDArray[np.float64]:
    """Poses ``(..., 4, 4)`` with :class:`Noise` applied independently to each; a new array."""
    T = np.asarray(T, dtype=float)
    if noise.is_zero:
        return T.copy()
    lead = T.shape[:-2]
    rotvec = np.radians(rng.normal(noise.rot_bias_deg, noise.rot_deg, lead + (3,)))
    dR = Rotation.from_rotvec(rotvec.reshape(-1, 3)).as_matrix().reshape(lead + (3, 3))
    dt = 1e-3 * rng.normal(noise.trans_bias_mm, noise.trans_mm, lead + (3,))
    R, t = T[..., :3, :3], T[..., :3, 3]
    if noise.frame == "reference":
        return make_transform(dR @ R, t + dt)
    return make_transform(R @ dR, t + np.einsum("...ij,...j->...i", R, dt))


def visible_viewpoints(
    n: int,
    rng: np.random.Generator,
    renderer,
    outline: NDArray[np.float64],
    tilt_max_deg: float = 40.0,
    fill: tuple[float, float] = (0.45, 0.8),
    margin_px: float = 20.0,
) -> NDArray[np.float64]:
    """``cam2target`` poses from which the whole target sheet is in the image, ``margin_px`` inside.

    The distance makes the sheet span a fraction ``fill`` of the image width; the camera sees
    the printed side (target -z), tilted up to ``tilt_max_deg``, any roll.
    """
    K = renderer.K
    w, h = renderer.size
    centre = outline.mean(axis=0)
    extent = float(np.linalg.norm(outline.max(axis=0) - outline.min(axis=0)))
    d_lo, d_hi = (K[0, 0] * extent / (fr * w) for fr in (fill[1], fill[0]))
    out: list[NDArray[np.float64]] = []
    for _ in range(200):
        cand = look_at_viewpoints(4 * n, rng, distance=(d_lo, d_hi), tilt_max_deg=tilt_max_deg,
                                  aim_jitter=0.1 * extent, side=-1.0, centre=centre)
        for c2t in cand:
            px = renderer.project(outline, invert(c2t))
            if np.all(px > margin_px) and np.all(px[:, 0] < w - margin_px) and np.all(px[:, 1] < h - margin_px):
                out.append(c2t)
                if len(out) == n:
                    return np.array(out)
    raise HandEyeError(f"could not place the camera so that the whole target fits in a {w}x{h} image, {margin_px:g} px "
                       "inside: use a larger image or a smaller target")


def _check_simulation_options(n_poses, noise_px, image_size, image_ext, blur, robot_noise) -> None:
    """simulate_session's options, each checked with a message that names it."""
    if isinstance(n_poses, bool) or not isinstance(n_poses, (int, np.integer)) or n_poses < 1:
        raise HandEyeError(f"n_poses={n_poses!r}: give a whole number of poses >= 1")
    for name, v in (("noise_px", noise_px), ("blur", blur)):
        if not isinstance(v, (int, float, np.number)) or not np.isfinite(v) or v < 0:
            raise HandEyeError(f"{name}={v!r}: give a finite number >= 0")
    try:
        w, h = image_size
        ok = all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in (w, h))
    except (TypeError, ValueError):
        ok = False
    if not ok or min(w, h) < MIN_IMAGE_SIDE:
        raise HandEyeError(f"image_size={image_size!r}: give (width, height) in whole pixels, each >= {MIN_IMAGE_SIDE}")
    if str(image_ext).lower() not in SIMULATED_IMAGE_SUFFIXES:
        raise HandEyeError(f"image_ext={image_ext!r}: use one of {', '.join(SIMULATED_IMAGE_SUFFIXES)}")
    try:
        deg, mm = (float(v) for v in robot_noise)
    except (TypeError, ValueError):
        raise HandEyeError(f"robot_noise={robot_noise!r}: give (degrees, millimetres)") from None
    if not (np.isfinite(deg) and np.isfinite(mm) and deg >= 0 and mm >= 0):
        raise HandEyeError(f"robot_noise={robot_noise!r}: give finite standard deviations >= 0")


def simulate_session(
    out_dir,
    setup: str = "eye_in_hand",
    n_poses: int = 15,
    target: str | dict = "chessboard",
    noise_px: float = 0.2,
    seed: int | None = None,
    image_size: tuple[int, int] = (640, 480),
    pose_format: str = "quat_wxyz",
    length_unit: str = "mm",
    angle_unit: str = "deg",
    write_intrinsics: bool = True,
    image_ext: str = ".png",
    blur: float = 0.0,
    robot_noise: tuple[float, float] = (0.0, 0.0),
    robot: str = "arm",
):
    """Render a complete capture session (the session format in docs/guide.md) with its ground truth.

    Writes ``session.yaml``, ``poses.csv``, ``images/`` and ``ground_truth.yaml`` (X, Z, K, dist)
    into ``out_dir``, which must not already hold a session. Returns the :class:`Scene`.

    Parameters
    ----------
    target : str or dict
        A key of :data:`DEFAULT_TARGETS` or a full target mapping as in session.yaml.
    noise_px : float
        Feature position noise in pixels (a smooth random displacement of each image).
    write_intrinsics : bool
        Put K and dist into session.yaml; otherwise handeye estimates them from the images.
    robot_noise : (deg, mm)
        Gaussian noise per axis on the written robot poses.
    robot : {'arm', 'scara', 'cartesian'}
        'arm' (default): viewpoints all around the target (a 6-axis arm); 'scara' or 'cartesian':
        the poses of :func:`low_dof_scene` (the flange turns about the vertical only, or only
        translates), which determine only part of X.
    """
    out = _new_session_folder(out_dir)
    setup = check_setup(setup)
    _check_simulation_options(n_poses, noise_px, image_size, image_ext, blur, robot_noise)
    if isinstance(target, str) and target not in DEFAULT_TARGETS:
        raise HandEyeError(f"unknown target {target!r}; use one of {', '.join(DEFAULT_TARGETS)} or a target mapping")
    spec = dict(DEFAULT_TARGETS[target]) if isinstance(target, str) else dict(target)
    tgt = target_from_spec(spec)
    rng = np.random.default_rng(seed)
    K, dist = default_camera(image_size)
    renderer = Renderer(K, dist, image_size)
    texture = target_texture(tgt)
    if robot == "arm":
        scene = scene_from_viewpoints(visible_viewpoints(n_poses, rng, renderer, texture.outline()), setup, rng)
    elif robot in LOW_DOF_ROBOTS:
        low = low_dof_scene(n_poses, setup, robot, rng, robot_noise=(0.0, 0.0), pixel_px=0.0, target=spec,
                            image_size=image_size)
        scene = Scene(setup, low.X, low.Z, low.flange2base, low.target2cam)
    else:
        raise HandEyeError(f"unknown robot {robot!r}; use 'arm', {', '.join(map(repr, LOW_DOF_ROBOTS))}")
    flange2base = scene.flange2base
    if robot_noise[0] > 0 or robot_noise[1] > 0:
        flange2base = perturb_poses(flange2base, np.radians(robot_noise[0]), robot_noise[1] * 1e-3, rng)
    names = _write_images(out, renderer, texture, scene.target2cam, rng, noise_px, blur, image_ext)
    write_session(out, setup, spec, names, flange2base, pose_format, length_unit, angle_unit,
                  camera=(K, dist) if write_intrinsics else None,
                  comment="Rendered by handeye simulate; ground truth in ground_truth.yaml")
    _write_truth(out, setup, scene.X, scene.Z, K, dist, seed, noise_px=float(noise_px),
                 robot_noise_deg_mm=list(robot_noise), robot=robot)
    return scene
