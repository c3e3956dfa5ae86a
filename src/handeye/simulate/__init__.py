"""Synthetic hand-eye scenes with ground truth, for tests, examples and the simulation study.

A scene is a set of camera viewpoints of the target (the camera looks at the target from a cone
of directions about its normal, as in the thesis's §5.2 set-up), turned into robot poses through
the ground-truth ``X`` and ``Z``:

* eye-in-hand: ``X = cam2flange``, ``Z = target2base``; ``flange2base_i = Z @ cam2target_i @ inv(X)``.
* eye-to-hand: ``X = cam2base``, ``Z = target2flange``; ``flange2base_i = X @ target2cam_i @ inv(Z)``.

(:func:`handeye.frames.setups.flange_poses`; sessions are written by :func:`handeye.io.session.write_session`.)
"""

from __future__ import annotations

import io
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from .._shared.io import atomic_write, check_output_folder
from .._shared.lazy import lazy_module
from ..errors import HandEyeError, InputMismatchError
from ..frames.setups import check_setup, flange_poses, predicted_target2cam, setup_info
from ..geometry.se3 import invert, make_transform, perturb, random_rotations
from ..io.session import write_joint_session, write_pose_table, write_session, write_stream_session
from ..robot.kinematics import Chain, absorbed_parameters, arm_names, load_arm
from ..sensors.camera.pnp import project_points
from ..sensors.camera.render import Renderer, target_texture
from ..sensors.camera.targets import target_from_spec

cv2 = lazy_module("cv2")

__all__ = ["Scene", "SceneBatch", "Noise", "random_scene", "flange_poses", "look_at", "look_at_viewpoints", "perturb_poses",
           "seed_viewpoints",
           "seed_scenes", "add_noise", "simulate_session", "RealisticErrors", "RealisticScene", "REALISTIC", "EXACT",
           "realistic_scene", "arm_forward_kinematics", "ARM_DH", "robot_accuracy_of", "simulate_realistic_session",
           "KinematicScene", "kinematic_scene", "simulate_kinematic_session", "capture_joint_views",
           "low_dof_scene", "LOW_DOF_ROBOTS", "StreamScene", "stream_scene", "JointStreamScene", "joint_stream_scene",
           "simulate_stream_session", "DepthScene", "depth_scene", "SphereScene", "sphere_scene", "write_depth_session"]


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
    check_setup(setup)
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


# --- the thesis's chapter 5 set-up, batched over Monte-Carlo runs --------------------------------

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
    check_setup(setup)
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


#: Targets that ``simulate_session`` renders by default (sizes in metres).
DEFAULT_TARGETS: dict[str, dict] = {
    "chessboard": {"type": "chessboard", "cols": 9, "rows": 6, "square": 0.03},
    "charuco": {"type": "charuco", "cols": 7, "rows": 5, "square": 0.04, "marker": 0.03, "dictionary": "DICT_6X6_250"},
    "circles": {"type": "circles", "cols": 7, "rows": 5, "square": 0.04},
    "asymmetric_circles": {"type": "asymmetric_circles", "cols": 4, "rows": 11, "square": 0.025},
    "apriltag": {"type": "apriltag", "square": 0.12, "id": 3, "dictionary": "DICT_APRILTAG_36h11"},
}


def default_camera(image_size: tuple[int, int]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A plausible camera for an image size: ~50 deg horizontal field of view, mild distortion."""
    w, h = image_size
    f = 1.07 * w
    K = np.array([[f, 0.0, 0.5 * w + 3.7], [0.0, f * 1.001, 0.5 * h - 2.9], [0.0, 0.0, 1.0]])
    dist = np.array([-0.11, 0.09, 3e-4, -2e-4, 0.0])
    return K, dist


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


#: The smallest image side simulate_session renders (a target must fit in it with a margin).
MIN_IMAGE_SIDE = 64
SIMULATED_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


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
    check_setup(setup)
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


def _new_session_folder(out_dir) -> Path:
    """The output folder of a simulated session, checked, and holding no session yet."""
    out = check_output_folder(out_dir)
    if (out / "session.yaml").exists() or (out / "images").exists():
        raise HandEyeError(f"{out} already holds a session; choose an empty folder")
    return out


def _write_images(out: Path, renderer: Renderer, texture, target2cam, rng: np.random.Generator, noise_px: float,
                  blur: float = 0.0, image_ext: str = ".png") -> list[str]:
    """Render the target at each pose into ``out/images`` (000.png, 001.png, ...); their names."""
    (out / "images").mkdir(parents=True, exist_ok=True)
    params = [cv2.IMWRITE_JPEG_QUALITY, 92] if image_ext.lower() in (".jpg", ".jpeg") else []
    names = []
    for k, T in enumerate(target2cam):
        name = f"{k:03d}{image_ext}"
        if not cv2.imwrite(str(out / "images" / name), renderer.render(texture, T, rng=rng, noise_px=noise_px, blur=blur),
                           params):
            raise HandEyeError(f"cannot write {out / 'images' / name}")
        names.append(name)
    return names


def _write_truth(out: Path, setup: str, X, Z, K, dist, seed, **extra) -> None:
    """``ground_truth.yaml``: X and Z under the setup's names, the camera, ``extra``, the seed."""
    info = setup_info(setup)
    truth = {"setup": setup, info.x_name: np.asarray(X).tolist(), info.z_name: np.asarray(Z).tolist(),
             "K": np.asarray(K).tolist(), "dist": np.asarray(dist).tolist(), **extra, "seed": seed}
    atomic_write(out / "ground_truth.yaml", yaml.safe_dump(truth, sort_keys=False))


# ----------------------------------------------------------------------------------------------------
# A realistic simulator: the errors real robots and cameras have, not only Gaussian pose noise.

#: A 6-axis arm (Universal Robots UR5's published standard DH parameters): per joint
#: ``(a, alpha, d, theta offset)``, metres and radians.
ARM_DH = np.array([
    [0.0, np.pi / 2, 0.089159, 0.0],
    [-0.425, 0.0, 0.0, 0.0],
    [-0.39225, 0.0, 0.0, 0.0],
    [0.0, np.pi / 2, 0.10915, 0.0],
    [0.0, -np.pi / 2, 0.09465, 0.0],
    [0.0, 0.0, 0.0823, 0.0],
])
#: Joint angles (rad) where the realistic scenes centre: the flange looks down (eye-in-hand, camera
#: above a table target) or sideways (eye-to-hand, board towards a camera on a stand).
ARM_HOME = {"eye_in_hand": np.radians([0.0, -110.0, 110.0, -90.0, -90.0, 0.0]),
            "eye_to_hand": np.radians([0.0, -110.0, 110.0, -180.0, -90.0, 0.0])}


def arm_forward_kinematics(q: NDArray[np.float64], dh: NDArray[np.float64] = ARM_DH) -> NDArray[np.float64]:
    """``flange2base`` (..., 4, 4) of joint angles ``q`` (..., 6) for standard DH parameters
    ``dh`` (6, 4) or (..., 6, 4) (``a, alpha, d, theta offset`` per joint)."""
    q = np.asarray(q, dtype=float)
    dh = np.broadcast_to(dh, q.shape + (4,))
    th = q + dh[..., 3]
    ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(dh[..., 1]), np.sin(dh[..., 1])
    A = np.zeros(q.shape + (4, 4))
    A[..., 0, 0], A[..., 0, 1], A[..., 0, 2], A[..., 0, 3] = ct, -st * ca, st * sa, dh[..., 0] * ct
    A[..., 1, 0], A[..., 1, 1], A[..., 1, 2], A[..., 1, 3] = st, ct * ca, -ct * sa, dh[..., 0] * st
    A[..., 2, 1], A[..., 2, 2], A[..., 2, 3] = sa, ca, dh[..., 2]
    A[..., 3, 3] = 1.0
    T = A[..., 0, :, :]
    for k in range(1, 6):
        T = T @ A[..., k, :, :]
    return T


@dataclass(frozen=True)
class RealisticErrors:
    """The errors of a real capture (defaults: a calibrated industrial arm, a good camera).

    * kinematics: the robot reports the forward kinematics of its nominal DH parameters while the
      arm follows perturbed ones (``dh_length_mm``, ``dh_angle_deg`` per parameter, joint zero
      offsets included): a systematic error that depends on the pose, ~0.5-1 mm at the flange;
    * ``joint_wave_deg``: a smooth joint-dependent error on top (gear eccentricity, compliance): each
      joint turns ``joint_wave_deg * sin(q + phase)`` more than commanded, a random phase per joint;
    * ``robot_rot_deg``, ``robot_mm``: random pose noise on top, Student-t with ``robot_dof``
      degrees of freedom (heavy tails; the scale is the t's, not a standard deviation);
    * ``jitter_ms``: the pose is read that long (Gaussian, std) before or after the image while the
      arm still moves at ``speed_mm_s`` / ``speed_deg_s`` along a random direction;
    * camera: the target's points are projected with ``pixel_px`` Gaussian pixel noise and the pose
      is solved by PnP (IPPE + Levenberg-Marquardt), so its error grows along the optical axis as a
      real PnP's does; with probability ``flip_probability`` the other planar solution is kept (the
      flipped-pose outlier of planar targets).
    """

    dh_length_mm: float = 0.3
    dh_angle_deg: float = 0.02
    robot_rot_deg: float = 0.01
    robot_mm: float = 0.03
    robot_dof: float = 3.0
    jitter_ms: float = 3.0
    speed_mm_s: float = 50.0
    speed_deg_s: float = 10.0
    pixel_px: float = 0.3
    flip_probability: float = 0.02
    joint_wave_deg: float = 0.0

    def scaled(self, factor: float) -> "RealisticErrors":
        """The same errors with the robot's kinematic part (DH errors and joint waves) ``factor`` times
        as large: the sweep from a calibrated arm (~0.2 mm absolute error at 0.25) to an
        uncalibrated one (~3 mm at 3; measured by :func:`robot_accuracy_of`)."""
        if not (np.isfinite(factor) and factor >= 0):
            raise HandEyeError(f"factor={factor!r}: give a finite factor >= 0")
        return replace(self, dh_length_mm=factor * self.dh_length_mm, dh_angle_deg=factor * self.dh_angle_deg,
                       joint_wave_deg=factor * self.joint_wave_deg)


#: The preset that mixes every error above at its default level.
REALISTIC = RealisticErrors()
#: No error at all (the same scenes, for ground-truth checks).
EXACT = RealisticErrors(0.0, 0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class RealisticScene:
    """A simulated capture with realistic errors (:func:`realistic_scene`); ``*_true`` are exact."""

    setup: str
    X: NDArray[np.float64]
    Z: NDArray[np.float64]
    joints: NDArray[np.float64]  #: (N, 6) rad for the arm; (N, 4) x, y, z (m), yaw (rad) for low_dof_scene
    flange2base_true: NDArray[np.float64]
    flange2base: NDArray[np.float64]  #: what the robot reports
    target2cam_true: NDArray[np.float64]
    target2cam: NDArray[np.float64]  #: what PnP returns
    object_points: NDArray[np.float64]  #: (M, 3) target frame
    image_points: NDArray[np.float64]  #: (N, M, 2) noisy detections, px
    K: NDArray[np.float64]
    dist: NDArray[np.float64]
    image_size: tuple[int, int]
    flipped: NDArray[np.bool_]  #: (N,) poses where PnP kept the other planar solution


def _scene_layout(setup: str, object_points: NDArray[np.float64], rng: np.random.Generator,
                  home: NDArray[np.float64] | None = None):
    """X and Z of a realistic cell: the camera 5-10 cm off the flange looking along it (eye-in-hand)
    or on a stand 0.6-0.8 m in front of the board on the flange (eye-to-hand). ``home``: the arm's
    flange pose at the centre of the capture (default :data:`ARM_DH`'s at :data:`ARM_HOME`)."""
    home = arm_forward_kinematics(ARM_HOME[setup]) if home is None else home
    centre = 0.5 * (object_points.min(axis=0) + object_points.max(axis=0))
    tilt = make_transform(Rotation.from_rotvec(rng.normal(0.0, np.radians(5.0), 3)).as_matrix(), np.zeros(3))
    if setup_info(setup).camera_on_flange:
        X = make_transform(Rotation.from_euler("z", rng.uniform(-180, 180), degrees=True).as_matrix()
                           @ tilt[:3, :3], rng.uniform(-0.07, 0.07, 3) * [1, 1, 0.5])
        cam = home @ X
        standoff = rng.uniform(0.35, 0.5)
        # the target centre on the optical axis, printed side towards the camera (z along the view)
        R_t = cam[:3, :3] @ Rotation.from_euler("z", rng.uniform(-180, 180), degrees=True).as_matrix()
        Z = make_transform(R_t, cam[:3, 3] + standoff * cam[:3, 2] - R_t @ centre)
        return X, Z
    Z = make_transform(Rotation.from_euler("x", 180, degrees=True).as_matrix() @ tilt[:3, :3],
                       [rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03), 0.02])
    target = home @ Z
    R_c = target[:3, :3] @ Rotation.from_euler("z", rng.uniform(-180, 180), degrees=True).as_matrix()
    c = target[:3, :3] @ centre + target[:3, 3]
    X = make_transform(R_c, c - rng.uniform(0.6, 0.8) * R_c[:, 2])
    return X, Z


def _sample_joints(setup, X, Z, object_points, K, image_size, n, rng, margin_px=10.0, spread_deg=(25, 25, 25, 40, 40, 60),
                   chain=None):
    """Joint angles around the home pose whose views see the whole target, 0.25-1.2 m away and
    less than 60 deg from face-on (``chain``: another arm than :data:`ARM_DH`, its home and spread)."""
    forward = arm_forward_kinematics if chain is None else chain.forward
    out = []
    for _ in range(50):
        if chain is None:
            q = ARM_HOME[setup] + np.radians(rng.uniform(-1, 1, (400, 6)) * spread_deg)
        else:
            q = chain.home[setup] + rng.uniform(-1, 1, (400, chain.n_joints)) * chain.spread
        t2c = predicted_target2cam(X, Z, forward(q), setup)
        out.extend(q[_sees_target(t2c, object_points, K, image_size, margin_px)])
        if len(out) >= n:
            return np.array(out[:n])
    raise HandEyeError(f"could not find {n} views of the target for the realistic {setup} scene")


def _sees_target(t2c: NDArray[np.float64], object_points: NDArray[np.float64], K: NDArray[np.float64],
                 image_size: tuple[int, int], margin_px: float = 10.0) -> NDArray[np.bool_]:
    """Per view: the whole target in the image (``margin_px`` from the border), 0.25-1.2 m away
    and less than 60 deg from face-on."""
    w, h = image_size
    p = np.einsum("nij,mj->nmi", t2c[:, :3, :3], object_points) + t2c[:, None, :3, 3]
    z = p[..., 2]
    ok = (z.min(axis=1) > 0.25) & (z.max(axis=1) < 1.2) & (t2c[:, 2, 2] > np.cos(np.radians(60)))
    uv = np.einsum("ij,nmj->nmi", K[:2, :2], p[..., :2] / np.where(z > 0, z, 1.0)[..., None]) + K[:2, 2]
    return ok & ((uv[..., 0] > margin_px) & (uv[..., 0] < w - margin_px) & (uv[..., 1] > margin_px)
                 & (uv[..., 1] < h - margin_px)).all(axis=1)


def _robot_reading(q, flange2base_true, errors: RealisticErrors, rng):
    """What the controller reports: nominal kinematics at ``q`` (the arm follows perturbed ones:
    the caller's ``flange2base_true``), read a little off in time, with heavy-tailed noise."""
    reported = arm_forward_kinematics(q)  # nominal parameters
    n = len(q)
    if errors.jitter_ms > 0:
        dt = 1e-3 * rng.normal(0.0, errors.jitter_ms, n)
        direction = rng.normal(size=(n, 2, 3))
        direction /= np.linalg.norm(direction, axis=2, keepdims=True)
        reported = perturb(reported, np.radians(errors.speed_deg_s) * dt[:, None] * direction[:, 0],
                           1e-3 * errors.speed_mm_s * dt[:, None] * direction[:, 1])
    if errors.robot_rot_deg > 0 or errors.robot_mm > 0:
        rot = np.radians(errors.robot_rot_deg) * rng.standard_t(errors.robot_dof, (n, 3))
        tra = 1e-3 * errors.robot_mm * rng.standard_t(errors.robot_dof, (n, 3))
        reported = perturb(reported, rot, tra)
    return reported


def _camera_reading(target2cam_true, object_points, K, dist, errors: RealisticErrors, rng):
    """Noisy detections, and the PnP pose of each (sometimes the flipped planar solution)."""
    obj = np.ascontiguousarray(object_points, dtype=np.float64)
    n = len(target2cam_true)
    image_points = np.stack([project_points(T, obj, K, dist) for T in target2cam_true])
    image_points = image_points + rng.normal(0.0, errors.pixel_px, image_points.shape)
    flipped = rng.random(n) < errors.flip_probability
    poses = np.empty((n, 4, 4))
    for i in range(n):
        img = np.ascontiguousarray(image_points[i])
        if errors.pixel_px == 0 and not flipped[i]:
            poses[i] = target2cam_true[i]
            continue
        _, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, img, K, dist, flags=cv2.SOLVEPNP_IPPE)
        k = 1 if flipped[i] and len(rvecs) > 1 else 0
        flipped[i] = k == 1
        rvec, tvec = rvecs[k], tvecs[k]
        if k == 0:  # refined from the other solution, LM would often slide back to this one
            rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, dist, rvec, tvec)
        poses[i] = make_transform(Rotation.from_rotvec(rvec.ravel()).as_matrix(), tvec.ravel())
    return poses, image_points, flipped


def realistic_scene(
    n_poses: int,
    setup: str = "eye_in_hand",
    rng: np.random.Generator | int | None = None,
    errors: RealisticErrors = REALISTIC,
    target: str | dict = "chessboard",
    image_size: tuple[int, int] = (1280, 1024),
) -> RealisticScene:
    """A capture by a 6-axis arm (:data:`ARM_DH`) with the errors of :class:`RealisticErrors`.

    Joint angles are drawn around a home pose until ``n_poses`` views see the whole target; the
    arm's true kinematics are the nominal ones perturbed once per scene; the robot reports the
    nominal forward kinematics (plus timing jitter and heavy-tailed noise); the camera's poses
    come from PnP on noisy projections of the target's points (sometimes flipped).
    """
    check_setup(setup)
    rng = np.random.default_rng(rng)
    spec = dict(DEFAULT_TARGETS[target]) if isinstance(target, str) else dict(target)
    obj = target_from_spec(spec).object_points()
    K, dist = default_camera(image_size)
    X, Z = _scene_layout(setup, obj, rng)
    q = _sample_joints(setup, X, Z, obj, K, image_size, n_poses, rng)
    dh = ARM_DH.copy()
    dh[:, [0, 2]] += 1e-3 * rng.normal(0.0, errors.dh_length_mm, (6, 2))
    dh[:, [1, 3]] += np.radians(rng.normal(0.0, errors.dh_angle_deg, (6, 2)))
    q_true = q
    if errors.joint_wave_deg > 0:  # drawn only when asked: scenes without it stay as they were
        q_true = q + np.radians(errors.joint_wave_deg) * np.sin(q + rng.uniform(0.0, 2 * np.pi, 6))
    f2b_true = arm_forward_kinematics(q_true, dh)
    t2c_true = predicted_target2cam(X, Z, f2b_true, setup)
    reported = _robot_reading(q, f2b_true, errors, rng)
    t2c, image_points, flipped = _camera_reading(t2c_true, obj, K, dist, errors, rng)
    return RealisticScene(setup, X, Z, q, f2b_true, reported, t2c_true, t2c, obj, image_points, K, dist,
                          tuple(image_size), flipped)


@dataclass(frozen=True)
class KinematicScene(RealisticScene):
    """A capture by an arm whose kinematics differ from its nominal ones (:func:`kinematic_scene`):
    ``joints`` as the controller reports them, ``flange2base`` the nominal chain's forward
    kinematics there (what a black-box calibration gets), ``chain_true`` the arm's real table."""

    chain: Chain | None = None
    chain_true: Chain | None = None
    joints_true: NDArray[np.float64] | None = None


def kinematic_scene(
    n_poses: int,
    setup: str = "eye_in_hand",
    rng: np.random.Generator | int | None = None,
    arm: str | Chain = "ur5",
    length_mm: float = 0.5,
    angle_deg: float = 0.05,
    pixel_px: float = 0.2,
    joint_noise_deg: float = 0.002,
    target: str | dict = "chessboard",
    image_size: tuple[int, int] = (1280, 1024),
    compliance_deg_per_m: float = 0.0,
) -> KinematicScene:
    """A capture by ``arm`` (a name of :func:`handeye.robot.kinematics.arm_names` or a chain) whose real
    table differs from the nominal one: every entry the arm owns (not one that only moves its base
    or flange, :func:`handeye.robot.kinematics.absorbed_parameters`: those are X's and Z's by definition)
    off by Gaussian ``length_mm`` (a, d) or ``angle_deg`` (alpha, theta offsets), which puts the
    flange 1-3 mm from where the nominal chain says at the defaults. Joint angles are drawn about
    the arm's home until ``n_poses`` views see the whole target; the controller reports them with
    ``joint_noise_deg`` of encoder noise; detections carry ``pixel_px`` of noise, and the camera's
    poses are PnP's on them. With ``compliance_deg_per_m``, every joint of the real arm gives way
    under the flange's load by 0.5-1.5x that (uniform) per metre of the load's moment arm
    (:meth:`handeye.robot.kinematics.Chain.moment_arms`)."""
    check_setup(setup)
    rng = np.random.default_rng(rng)
    chain = load_arm(arm) if isinstance(arm, str) else arm
    spec = dict(DEFAULT_TARGETS[target]) if isinstance(target, str) else dict(target)
    obj = target_from_spec(spec).object_points()
    K, dist = default_camera(image_size)
    X, Z = _scene_layout(setup, obj, rng, chain.forward(chain.home[setup][None])[0])
    q_true = _sample_joints(setup, X, Z, obj, K, image_size, n_poses, rng, chain=chain)
    true = _real_chain(chain, rng, length_mm, angle_deg, compliance_deg_per_m)
    f2b_true = true.forward(q_true)
    joints = q_true + np.radians(rng.normal(0.0, joint_noise_deg, q_true.shape))
    t2c_true = predicted_target2cam(X, Z, f2b_true, setup)
    t2c, image_points, flipped = _camera_reading(t2c_true, obj, K, dist,
                                                 replace(EXACT, pixel_px=pixel_px, flip_probability=0.0), rng)
    return KinematicScene(setup, X, Z, joints, f2b_true, chain.forward(joints), t2c_true, t2c, obj, image_points, K,
                          dist, tuple(image_size), flipped, chain=chain, chain_true=true, joints_true=q_true)


def capture_joint_views(scene: KinematicScene, joints: ArrayLike, rng: np.random.Generator | int | None = None,
                        pixel_px: float = 0.2, joint_noise_deg: float = 0.002
                        ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """More views in ``scene``'s cell (:func:`kinematic_scene`): its real arm at the commanded
    ``joints`` (N, n; rad), e.g. the views :func:`handeye.planning.joints.suggest_joint_views`
    proposes. Returns the joint angles the controller reports (``joint_noise_deg`` of encoder
    noise), the camera's PnP poses (target2cam) and the detections (N, M, 2; ``pixel_px`` of noise)."""
    q = np.atleast_2d(np.asarray(joints, dtype=float))
    if scene.chain_true is None or q.shape[1] != scene.chain_true.n_joints:
        raise InputMismatchError(f"joints of shape {q.shape} for a scene of "
                                 f"{'no arm' if scene.chain_true is None else scene.chain_true.name}")
    rng = np.random.default_rng(rng)
    t2c_true = predicted_target2cam(scene.X, scene.Z, scene.chain_true.forward(q), scene.setup)
    t2c, image_points, _ = _camera_reading(t2c_true, scene.object_points, scene.K, scene.dist,
                                           replace(EXACT, pixel_px=pixel_px, flip_probability=0.0), rng)
    return q + np.radians(rng.normal(0.0, joint_noise_deg, q.shape)), t2c, image_points


def _real_chain(chain: Chain, rng: np.random.Generator, length_mm: float, angle_deg: float,
                compliance_deg_per_m: float = 0.0) -> Chain:
    """The arm as built: every entry of ``chain``'s table it owns (not one X or Z absorbs) off by
    Gaussian ``length_mm`` or ``angle_deg``, and each joint's compliance 0.5-1.5x
    ``compliance_deg_per_m`` (uniform) when that is positive."""
    deltas = np.zeros(chain.table.size)
    absorbed = set(absorbed_parameters(chain))
    for k, name in enumerate(chain.parameter_names()):
        if name not in absorbed:
            deltas[k] = (np.radians(rng.normal(0.0, angle_deg)) if name.endswith((".alpha", ".theta"))
                         else 1e-3 * rng.normal(0.0, length_mm))
    true = chain.corrected(deltas)
    if compliance_deg_per_m > 0:
        true = replace(true, compliance=np.radians(compliance_deg_per_m) * rng.uniform(0.5, 1.5, chain.n_joints))
    return true


def robot_accuracy_of(scene: RealisticScene) -> tuple[float, float]:
    """The median error of the robot poses ``scene`` reports (deg, mm at the flange): the absolute
    accuracy of its simulated arm over that capture."""
    D = invert(scene.flange2base_true) @ scene.flange2base
    rot = np.degrees(np.linalg.norm(Rotation.from_matrix(D[:, :3, :3]).as_rotvec(), axis=1))
    return float(np.median(rot)), float(1e3 * np.median(np.linalg.norm(D[:, :3, 3], axis=1)))


def simulate_realistic_session(
    out_dir,
    n_poses: int = 12,
    setup: str = "eye_in_hand",
    seed: int | None = None,
    errors: RealisticErrors = REALISTIC,
    target: str | dict = "chessboard",
    image_size: tuple[int, int] = (640, 480),
    write_intrinsics: bool = True,
) -> RealisticScene:
    """Render a capture session of :func:`realistic_scene`: the images show the target where the
    arm truly put it (feature noise ``errors.pixel_px``), ``poses.csv`` holds what the controller
    reports (kinematic errors, timing jitter, heavy-tailed noise), ``ground_truth.yaml`` the truth.
    The camera's poses come from handeye's own detection and PnP on the images, as for a real
    capture. ``out_dir`` must not already hold a session. Returns the scene."""
    out = _new_session_folder(out_dir)
    sc = realistic_scene(n_poses, setup, seed, errors=errors, target=target, image_size=image_size)
    spec = dict(DEFAULT_TARGETS[target]) if isinstance(target, str) else dict(target)
    renderer = Renderer(sc.K, sc.dist, image_size)
    texture = target_texture(target_from_spec(spec))
    rng = np.random.default_rng(None if seed is None else [seed, 1])
    names = _write_images(out, renderer, texture, sc.target2cam_true, rng, errors.pixel_px)
    write_session(out, setup, spec, names, sc.flange2base, "quat_wxyz", "mm", "deg",
                  camera=(sc.K, sc.dist) if write_intrinsics else None,
                  comment="Rendered by handeye's realistic simulator; ground truth in ground_truth.yaml")
    _write_truth(out, setup, sc.X, sc.Z, sc.K, sc.dist, seed, errors={k: float(v) for k, v in vars(errors).items()},
                 robot_accuracy_deg_mm=list(robot_accuracy_of(sc)))
    return sc


def simulate_kinematic_session(
    out_dir,
    n_poses: int = 30,
    setup: str = "eye_in_hand",
    seed: int | None = None,
    arm: str | Chain = "ur5",
    controller_poses: bool = True,
    target: str | dict = "chessboard",
    image_size: tuple[int, int] = (1280, 1024),
    **errors,
) -> KinematicScene:
    """Render a capture session of :func:`kinematic_scene` with the joint angles the controller
    reports in ``joints.csv`` (degrees; ``session.yaml``'s ``joints:`` block names ``arm``), and
    (``controller_poses``) the flange poses its nominal kinematics give in ``poses.csv``;
    ``ground_truth.yaml`` holds X, Z and the arm's true table. ``errors``: :func:`kinematic_scene`'s
    ``length_mm``, ``angle_deg``, ``pixel_px``, ``joint_noise_deg``. ``arm``: a shipped arm's name,
    or a chain named so whose ``home`` / ``spread`` steer the captures (e.g. a joint held still).
    Returns the scene."""
    name = arm if isinstance(arm, str) else arm.name.lower()
    if name.lower() not in arm_names():
        raise InputMismatchError(f"arm {name!r}: a session names a shipped arm ({', '.join(arm_names())})")
    out = _new_session_folder(out_dir)
    sc = kinematic_scene(n_poses, setup, seed, arm=arm, target=target, image_size=image_size, **errors)
    spec = dict(DEFAULT_TARGETS[target]) if isinstance(target, str) else dict(target)
    renderer = Renderer(sc.K, sc.dist, image_size)
    texture = target_texture(target_from_spec(spec))
    rng = np.random.default_rng(None if seed is None else [seed, 1])
    names = _write_images(out, renderer, texture, sc.target2cam_true, rng, errors.get("pixel_px", 0.2))
    write_joint_session(out, setup, spec, names, sc.joints, name, sc.flange2base if controller_poses else None,
                        camera=(sc.K, sc.dist), comment=f"Rendered by handeye's kinematic simulator ({sc.chain.name} off its "
                        "nominal table); ground truth in ground_truth.yaml")
    _write_truth(out, setup, sc.X, sc.Z, sc.K, sc.dist, seed, arm=sc.chain.name, table_true=sc.chain_true.table.tolist(),
                 robot_accuracy_deg_mm=list(robot_accuracy_of(sc)))
    return sc


#: Robots whose flange cannot rotate freely (:func:`low_dof_scene`): a SCARA turns its flange about
#: the vertical only; a Cartesian gantry only translates it.
LOW_DOF_ROBOTS = ("scara", "cartesian")


def _low_dof_layout(setup: str, centre: NDArray[np.float64], rng: np.random.Generator):
    """X and Z of a cell whose flange points down: eye-in-hand, a camera beside the flange looking
    down at a table target; eye-to-hand, a camera on the floor looking up at a target under the flange."""
    tilt = Rotation.from_rotvec(rng.normal(0.0, np.radians(4.0), 3)).as_matrix()
    yaw = Rotation.from_euler("z", rng.uniform(-180, 180), degrees=True).as_matrix()
    down = Rotation.from_euler("x", 180, degrees=True).as_matrix()  # z along -z of the base
    if setup_info(setup).camera_on_flange:
        # the camera looks along the flange z axis (down); its offset along that axis is what SCARA data cannot see
        X = make_transform(yaw @ tilt, [rng.uniform(-0.06, 0.06), rng.uniform(-0.06, 0.06), rng.uniform(0.03, 0.09)])
        R_t = down @ Rotation.from_euler("z", rng.uniform(-180, 180), degrees=True).as_matrix()
        Z = make_transform(R_t, np.array([0.45, 0.0, rng.uniform(-0.05, 0.05)]) - R_t @ centre)
        return X, Z
    Z = make_transform(down @ tilt, [rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03), 0.02])
    X = make_transform(yaw @ tilt.T, [0.45, 0.0, rng.uniform(-0.1, 0.0)])  # looking up (+z of the base)
    return X, Z


def low_dof_scene(
    n_poses: int,
    setup: str = "eye_in_hand",
    robot: str = "scara",
    rng: np.random.Generator | int | None = None,
    robot_noise: tuple[float, float] = (0.05, 0.2),
    pixel_px: float = 0.3,
    target: str | dict = "chessboard",
    image_size: tuple[int, int] = (1280, 1024),
    yaw_range_deg: float = 150.0,
) -> RealisticScene:
    """A capture by a robot that cannot rotate its flange freely.

    ``robot='scara'``: the flange points down and turns about the vertical only (a 4-axis SCARA:
    x, y, z, yaw); ``'cartesian'``: a gantry whose flange only translates. The controller reports
    exactly that form (``joints``: x, y, z in m and yaw in rad per pose); the true flange pose
    differs from it by Gaussian noise of ``robot_noise`` (deg, mm per axis; the arm is not perfect,
    so the true pose may tilt a little). The camera's poses come from PnP on projections of the
    target with ``pixel_px`` Gaussian noise. Eye-in-hand: a camera beside the flange looks down at
    a table target; eye-to-hand: a camera on the floor looks up at a target under the flange.
    """
    check_setup(setup)
    if robot not in LOW_DOF_ROBOTS:
        raise HandEyeError(f"unknown robot {robot!r}; use one of {', '.join(LOW_DOF_ROBOTS)}")
    rng = np.random.default_rng(rng)
    spec = dict(DEFAULT_TARGETS[target]) if isinstance(target, str) else dict(target)
    obj = target_from_spec(spec).object_points()
    K, dist = default_camera(image_size)
    centre = 0.5 * (obj.min(axis=0) + obj.max(axis=0))
    X, Z = _low_dof_layout(setup, centre, rng)
    down = Rotation.from_euler("x", 180, degrees=True).as_matrix()
    yaw0 = rng.uniform(-np.pi, np.pi)
    chosen = []
    for _ in range(50):
        m = 400
        yaw = yaw0 + (np.radians(rng.uniform(-yaw_range_deg, yaw_range_deg, m)) if robot == "scara" else np.zeros(m))
        R_f = Rotation.from_euler("z", yaw[:, None]).as_matrix() @ down
        offset = np.stack([rng.uniform(-0.12, 0.12, m), rng.uniform(-0.12, 0.12, m), rng.uniform(0.3, 0.5, m)], axis=1)
        if setup_info(setup).camera_on_flange:
            # the camera above the target centre; the flange where that puts it
            cam = (Z[:3, :3] @ centre + Z[:3, 3]) + offset
            p = cam - R_f @ X[:3, 3]
        else:
            # the target centre above the camera
            p = X[:3, 3] + offset - R_f @ (Z[:3, :3] @ centre + Z[:3, 3])
        reported = make_transform(R_f, p)
        ok = _sees_target(predicted_target2cam(X, Z, reported, setup), obj, K, image_size)
        chosen.extend(np.concatenate([p, yaw[:, None]], axis=1)[ok])
        if len(chosen) >= n_poses:
            break
    else:
        raise HandEyeError(f"could not find {n_poses} views of the target for the {robot} {setup} scene")
    joints = np.array(chosen[:n_poses])
    reported = make_transform(Rotation.from_euler("z", joints[:, 3:]).as_matrix() @ down, joints[:, :3])
    rot = np.radians(robot_noise[0]) * rng.normal(size=(n_poses, 3))
    tra = 1e-3 * robot_noise[1] * rng.normal(size=(n_poses, 3))
    f2b_true = perturb(reported, rot, tra)
    t2c_true = predicted_target2cam(X, Z, f2b_true, setup)
    errors = replace(EXACT, pixel_px=pixel_px)
    t2c, image_points, flipped = _camera_reading(t2c_true, obj, K, dist, errors, rng)
    return RealisticScene(setup, X, Z, joints, f2b_true, reported, t2c_true, t2c, obj, image_points, K, dist,
                          tuple(image_size), flipped)


# ----------------------------------------------------------------------------------------------------
# Streams: a continuous trajectory recorded by two clocks.

@dataclass(frozen=True)
class StreamScene:
    """A continuous recording (:func:`stream_scene`): the robot's and the camera's time-stamped
    poses, each on its own clock; ``time_offset`` is the camera clock minus the robot clock."""

    setup: str
    X: NDArray[np.float64]
    Z: NDArray[np.float64]
    time_offset: float  #: s, camera clock minus robot clock
    robot_times: NDArray[np.float64]  #: stamps on the robot clock (s)
    flange2base: NDArray[np.float64]  #: what the robot reports (nominal kinematics, noise)
    flange2base_true: NDArray[np.float64]
    camera_times: NDArray[np.float64]  #: stamps on the camera clock (s), frames that see the target
    target2cam: NDArray[np.float64]  #: what PnP returns
    target2cam_true: NDArray[np.float64]
    camera_robot_times: NDArray[np.float64]  #: when each camera frame was taken, on the robot clock
    flipped: NDArray[np.bool_]


def stream_scene(
    duration: float = 30.0,
    setup: str = "eye_in_hand",
    rng: np.random.Generator | int | None = None,
    errors: RealisticErrors = REALISTIC,
    robot_hz: float = 100.0,
    camera_hz: float = 30.0,
    time_offset: float = 0.037,
    jitter_ms: float = 1.0,
    waypoint_s: float = 2.5,
    target: str | dict = "chessboard",
    image_size: tuple[int, int] = (1280, 1024),
) -> StreamScene:
    """A 6-axis arm (:data:`ARM_DH`) moving continuously for ``duration`` seconds, recorded by the
    controller at ``robot_hz`` and by the camera at ``camera_hz`` on clocks ``time_offset`` apart.

    The joints follow a smooth (clamped cubic spline) path through random waypoints
    ``waypoint_s`` apart whose views see the target; the arm's true kinematics are the nominal
    ones perturbed as in :func:`realistic_scene`. Every stamp is off by Gaussian ``jitter_ms``.
    The robot reports the nominal forward kinematics with ``errors``' heavy-tailed noise (its
    ``jitter_ms`` is not used: the timing is this function's); the camera's poses come from PnP on
    noisy projections (sometimes flipped); frames that do not see the whole target are dropped.
    """
    check_setup(setup)
    rng = np.random.default_rng(rng)
    if not (duration > 2 * waypoint_s and robot_hz > 0 and camera_hz > 0):
        raise HandEyeError("stream_scene: duration must exceed two waypoint intervals; rates must be positive")
    spec = dict(DEFAULT_TARGETS[target]) if isinstance(target, str) else dict(target)
    obj = target_from_spec(spec).object_points()
    K, dist = default_camera(image_size)
    X, Z = _scene_layout(setup, obj, rng)
    path = _waypoint_path(setup, X, Z, obj, K, image_size, duration, waypoint_s, rng)
    dh = ARM_DH.copy()
    dh[:, [0, 2]] += 1e-3 * rng.normal(0.0, errors.dh_length_mm, (6, 2))
    dh[:, [1, 3]] += np.radians(rng.normal(0.0, errors.dh_angle_deg, (6, 2)))
    jitter = 1e-3 * jitter_ms
    # the robot: true sample times k / rate, stamps off by the jitter
    t_robot = np.arange(0.0, duration, 1.0 / robot_hz)
    q = path(t_robot)
    f2b_true = arm_forward_kinematics(q, dh)
    reported = _robot_reading(q, f2b_true, replace(errors, jitter_ms=0.0), rng)
    robot_stamps = t_robot + rng.normal(0.0, jitter, len(t_robot))
    t_cam, cam_stamps, t2c, t2c_true, flipped = _camera_stream(
        lambda t: predicted_target2cam(X, Z, arm_forward_kinematics(path(t), dh), setup), obj, K, dist, image_size,
        duration, camera_hz, time_offset, jitter, errors, rng)
    order_r, order_c = np.argsort(robot_stamps), np.argsort(cam_stamps)  # jitter may swap neighbours
    return StreamScene(setup, X, Z, time_offset, robot_stamps[order_r], reported[order_r], f2b_true[order_r],
                       cam_stamps[order_c], t2c[order_c], t2c_true[order_c], t_cam[order_c], flipped[order_c])


def _waypoint_path(setup, X, Z, obj, K, image_size, duration: float, waypoint_s: float, rng, chain=None):
    """A smooth joint path (clamped cubic spline, seconds to joint angles) through random waypoints
    ``waypoint_s`` apart for ``duration`` seconds whose views see the target (:func:`_sample_joints`)."""
    from scipy.interpolate import CubicSpline  # noqa: PLC0415  (scipy's interpolate costs import time)

    n_way = int(np.ceil(duration / waypoint_s)) + 1
    q_way = _sample_joints(setup, X, Z, obj, K, image_size, n_way, rng, chain=chain)
    return CubicSpline(np.arange(n_way) * waypoint_s, q_way, bc_type="clamped")


def _camera_stream(target2cam_at, obj, K, dist, image_size, duration: float, camera_hz: float, time_offset: float,
                   jitter: float, errors: RealisticErrors, rng):
    """The camera's frames at its own rate from a random phase (true times on the robot clock),
    those that see the whole target read with ``errors`` (:func:`_camera_reading`) and stamped on
    the camera clock (``time_offset`` ahead, Gaussian ``jitter`` s): (true times, stamps, PnP
    target2cam, true target2cam, flipped). ``target2cam_at``: true times to true target2cam."""
    t_cam = np.arange(rng.uniform(0, 1.0 / camera_hz), duration, 1.0 / camera_hz)
    t2c_true = target2cam_at(t_cam)
    sees = _sees_target(t2c_true, obj, K, image_size)
    t_cam, t2c_true = t_cam[sees], t2c_true[sees]
    t2c, _, flipped = _camera_reading(t2c_true, obj, K, dist, errors, rng)
    return t_cam, t_cam + time_offset + rng.normal(0.0, jitter, len(t_cam)), t2c, t2c_true, flipped


@dataclass(frozen=True)
class JointStreamScene:
    """A continuous recording by an arm whose kinematics differ from its nominal ones
    (:func:`joint_stream_scene`): the controller's time-stamped joint angles and the camera's
    time-stamped poses, each on its own clock; ``time_offset`` is the camera clock minus the robot's."""

    setup: str
    X: NDArray[np.float64]
    Z: NDArray[np.float64]
    time_offset: float
    robot_times: NDArray[np.float64]  #: stamps on the robot clock (s)
    joints: NDArray[np.float64]  #: (N, n) rad, as the controller reports them (encoder noise)
    camera_times: NDArray[np.float64]  #: stamps on the camera clock (s), frames that see the target
    target2cam: NDArray[np.float64]  #: what PnP returns
    target2cam_true: NDArray[np.float64]
    chain: Chain  #: the nominal kinematics
    chain_true: Chain  #: the arm's real ones


def joint_stream_scene(
    duration: float = 40.0,
    setup: str = "eye_in_hand",
    rng: np.random.Generator | int | None = None,
    arm: str | Chain = "ur5",
    robot_hz: float = 100.0,
    camera_hz: float = 15.0,
    time_offset: float = 0.037,
    jitter_ms: float = 1.0,
    waypoint_s: float = 2.5,
    length_mm: float = 0.5,
    angle_deg: float = 0.05,
    joint_noise_deg: float = 0.002,
    pixel_px: float = 0.2,
    target: str | dict = "chessboard",
    image_size: tuple[int, int] = (1280, 1024),
) -> JointStreamScene:
    """``arm`` moving continuously for ``duration`` seconds through random joint waypoints
    ``waypoint_s`` apart whose views see the target (a clamped cubic spline, as
    :func:`stream_scene`), its real table off the nominal one as in :func:`kinematic_scene`; the
    controller records the joint angles at ``robot_hz`` (``joint_noise_deg`` of encoder noise), the
    camera its PnP poses at ``camera_hz`` (``pixel_px`` of detection noise), on clocks
    ``time_offset`` apart, every stamp off by Gaussian ``jitter_ms``."""
    check_setup(setup)
    rng = np.random.default_rng(rng)
    if not (duration > 2 * waypoint_s and robot_hz > 0 and camera_hz > 0):
        raise HandEyeError("joint_stream_scene: duration must exceed two waypoint intervals; rates must be positive")
    chain = load_arm(arm) if isinstance(arm, str) else arm
    spec = dict(DEFAULT_TARGETS[target]) if isinstance(target, str) else dict(target)
    obj = target_from_spec(spec).object_points()
    K, dist = default_camera(image_size)
    X, Z = _scene_layout(setup, obj, rng, chain.forward(chain.home[setup][None])[0])
    path = _waypoint_path(setup, X, Z, obj, K, image_size, duration, waypoint_s, rng, chain)
    true = _real_chain(chain, rng, length_mm, angle_deg)
    jitter = 1e-3 * jitter_ms
    t_robot = np.arange(0.0, duration, 1.0 / robot_hz)
    joints = path(t_robot) + np.radians(rng.normal(0.0, joint_noise_deg, (len(t_robot), chain.n_joints)))
    robot_stamps = t_robot + rng.normal(0.0, jitter, len(t_robot))
    _, cam_stamps, t2c, t2c_true, _ = _camera_stream(
        lambda t: predicted_target2cam(X, Z, true.forward(path(t)), setup), obj, K, dist, image_size, duration,
        camera_hz, time_offset, jitter, replace(EXACT, pixel_px=pixel_px, flip_probability=0.0), rng)
    order_r, order_c = np.argsort(robot_stamps), np.argsort(cam_stamps)  # jitter may swap neighbours
    return JointStreamScene(setup, X, Z, time_offset, robot_stamps[order_r], joints[order_r], cam_stamps[order_c],
                            t2c[order_c], t2c_true[order_c], chain, true)


def simulate_stream_session(
    out_dir,
    setup: str = "eye_in_hand",
    duration: float = 6.0,
    camera_hz: float = 10.0,
    robot_hz: float = 100.0,
    time_offset: float = 0.037,
    seed: int | None = None,
    target: str | dict = "chessboard",
    image_size: tuple[int, int] = (640, 480),
    noise_px: float = 0.2,
    errors: RealisticErrors = REALISTIC,
) -> StreamScene:
    """Render a session whose poses are a robot stream (:func:`stream_scene`): ``robot.csv`` (time,
    pose at ``robot_hz`` on the robot's clock), ``images/`` (frames at ``camera_hz`` that see the
    target) with ``images.csv`` (their times on the camera's clock, ``time_offset`` ahead) and
    ``ground_truth.yaml``. Returns the scene."""
    out = check_output_folder(out_dir)
    if (out / "session.yaml").exists() or (out / "images").exists():
        raise HandEyeError(f"{out} already holds a session; choose an empty folder")
    spec = dict(DEFAULT_TARGETS[target]) if isinstance(target, str) else dict(target)
    scene = stream_scene(duration, setup, seed, replace(errors, pixel_px=0.0, flip_probability=0.0), robot_hz,
                         camera_hz, time_offset, waypoint_s=min(2.5, duration / 3.0), target=spec, image_size=image_size)
    rng = np.random.default_rng(None if seed is None else seed + 1)
    K, dist = default_camera(image_size)
    renderer = Renderer(K, dist, image_size)
    texture = target_texture(target_from_spec(spec))
    (out / "images").mkdir(parents=True, exist_ok=True)
    names = []
    for k, T in enumerate(scene.target2cam_true):
        name = f"{k:04d}.png"
        if not cv2.imwrite(str(out / "images" / name), renderer.render(texture, T, rng=rng, noise_px=noise_px)):
            raise HandEyeError(f"cannot write {out / 'images' / name}")
        names.append(name)
    write_stream_session(out, setup, spec, scene.robot_times, scene.flange2base, names, scene.camera_times,
                         camera=(K, dist), comment="Rendered by handeye simulate (a robot stream); ground truth in "
                         "ground_truth.yaml")
    info = setup_info(setup)
    truth = {"setup": setup, info.x_name: scene.X.tolist(), info.z_name: scene.Z.tolist(), "K": K.tolist(),
             "dist": dist.tolist(), "time_offset_s": float(time_offset), "seed": seed}
    atomic_write(out / "ground_truth.yaml", yaml.safe_dump(truth, sort_keys=False))
    return scene


# --- depth cameras: organized point clouds ------------------------------------------------------


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


def _pixel_rays(K, size) -> NDArray[np.float64]:
    """(H, W, 3): each pixel's ray (z = 1) of a pinhole camera ``K`` without distortion."""
    w, h = size
    u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    return np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones_like(u)], axis=-1)


def _depth_reading(truth, mask, behind, rng: np.random.Generator, depth_scale: float, depth_bias: float,
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


def _depth_image(K, size, target2cam, outline, background: float):
    """Per pixel, the true point (H, W, 3) where its ray meets the board's sheet (its ``outline``),
    else the background plane at depth ``background``; and the board's mask."""
    rays = _pixel_rays(K, size)
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


def _reported(flange2base: NDArray[np.float64], error: tuple[float, float] | None, rng: np.random.Generator):
    """The controller's flange poses: off by a constant error (the arm's absolute error over a
    small capture) and heavy-tailed noise per pose (Student-t, 3 dof), each of ``error`` (deg, mm)
    per axis; the true ones when ``error`` is None."""
    if error is None:
        return flange2base
    n = len(flange2base)
    rot = np.radians(error[0]) * (rng.normal(0.0, 1.0, 3) + rng.standard_t(3, (n, 3)))
    tra = 1e-3 * error[1] * (rng.normal(0.0, 1.0, 3) + rng.standard_t(3, (n, 3)))
    return perturb(flange2base, rot, tra)


def depth_scene(n_views: int = 15, setup: str = "eye_in_hand", rng: np.random.Generator | int | None = None, *,
                target: str | dict = "chessboard", image_size: tuple[int, int] = (640, 480),
                depth_noise: tuple[float, float] = (1e-4, 5e-4), depth_scale: float = 1.002,
                depth_bias: float = 0.0, noise_px: float = 0.2, holes: float = 0.01,
                distance: tuple[float, float] = (0.5, 1.0), robot_error: tuple[float, float] | None = None) -> DepthScene:
    """A depth camera's capture of a board: ``n_views`` views at ``distance`` (m), each an organized
    cloud and the board's corners in the registered intensity image.

    The cloud's depth noise (std, m) is ``depth_noise[0] + depth_noise[1] z^2`` (0.2 mm at 0.5 m to
    0.6 mm at 1 m by default), each point moved along its ray; measured depths are
    ``depth_scale z + depth_bias``; a share ``holes`` of the pixels has no depth (NaN), and the
    pixels on the board's edge are flying pixels (their depth half-way to the background). The
    corners are the projections of the board's inner corners (pinhole, no distortion) with
    ``noise_px`` pixel noise, as a detector finds them in the intensity image. ``robot_error``
    (deg, mm): the reported flange poses are off by a constant and a heavy-tailed error per pose of
    that size per axis (``flange2base`` is what the controller reports; None: exact).
    """
    check_setup(setup)
    rng = np.random.default_rng(rng)
    spec = DEFAULT_TARGETS[target] if isinstance(target, str) else dict(target)
    tgt = target_from_spec(spec)
    obj = tgt.object_points()
    K = default_camera(image_size)[0]
    renderer = Renderer(K, np.zeros(5), image_size, supersample=1)
    outline = target_texture(tgt).outline()
    cam2target = visible_viewpoints(n_views, rng, renderer, outline, margin_px=10.0)
    scale = np.linalg.norm(cam2target[:, :3, 3] - outline.mean(axis=0), axis=1)
    # the views' distances spread over ``distance``: depth noise, scale and bias differ with depth
    want = rng.uniform(*distance, n_views)
    centre = outline.mean(axis=0)
    cam2target[:, :3, 3] = centre + (cam2target[:, :3, 3] - centre) * (want / scale)[:, None]
    scene = scene_from_viewpoints(cam2target, setup, rng)
    image_points, clouds = [], []
    for T in scene.target2cam:
        truth, board = _depth_image(K, image_size, T, outline, background=2.5)
        behind = truth * (2.5 / truth[..., 2])[..., None]  # the background where the board is
        clouds.append(_depth_reading(truth, board, behind, rng, depth_scale, depth_bias, depth_noise, holes))
        px = project_points(T, obj, K, np.zeros(5))
        image_points.append(px + rng.normal(0.0, noise_px, px.shape))
    return DepthScene(setup, scene.X, scene.Z, _reported(scene.flange2base, robot_error, rng), scene.target2cam, K=K,
                      image_size=tuple(image_size),
                      object_points=obj, image_points=image_points, clouds=clouds, depth_scale=depth_scale,
                      depth_bias=depth_bias, target_spec=dict(spec))


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
    rays = _pixel_rays(K, size)
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
                 stem: float | None = None) -> SphereScene:
    """A depth camera's capture of a sphere of ``radius`` (m): on the flange in front of a fixed
    camera (eye-to-hand), or fixed in the cell and seen by the camera on the flange (eye-in-hand).

    ``n_views`` views at ``distance`` (m) from directions within ``tilt_max_deg`` of the target's z
    axis, the sphere anywhere in the middle two thirds of the image; behind it a tilted wall 0.2-0.4
    m further. Noise, scale, bias and holes as :func:`depth_scene`'s; the pixels on the sphere's
    outline are flying pixels (their depth half-way to the wall); ``robot_error`` as
    :func:`depth_scene`'s. ``stem``: the ball sits on a rod of that radius (m), 0.15 m long, towards
    the flange (eye-to-hand) or down to the table (eye-in-hand), which hides part of it from some views.
    """
    check_setup(setup)
    rng = np.random.default_rng(rng)
    K = default_camera(image_size)[0]
    w, h = image_size
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
        clouds.append(_depth_reading(truth, sphere, behind, rng, depth_scale, depth_bias, depth_noise, holes))
    return SphereScene(setup, scene.X, scene.Z, _reported(scene.flange2base, robot_error, rng), scene.target2cam, K=K,
                       image_size=tuple(image_size),
                       radius=radius, clouds=clouds, depth_scale=depth_scale, depth_bias=depth_bias)


def write_depth_session(folder: str | Path, scene: DepthScene | SphereScene, unit: str = "m",
                        working_range: tuple[float, float] | None = None,
                        rng: np.random.Generator | int | None = 0) -> Path:
    """Write a simulated depth capture as a depth session (``handeye.io.depth_session``'s format):
    ``clouds/viewNN.npy`` (float32, in ``unit``), for a board the rendered intensity images
    ``images/viewNN.png``, ``poses.csv`` (quat_wxyz, mm, deg), ``session.yaml`` (with the
    intensity image's K and a ``depth:`` mapping) and ``ground_truth.yaml``. Returns the folder."""
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
    depth: dict = {"unit": unit}
    if working_range is not None:
        depth["range"] = [float(v) for v in working_range]
    spec = {"setup": scene.setup, "target": target, "camera": {"K": scene.K.tolist(), "dist": [0.0] * 5},
            "depth": depth, "poses": {"file": "poses.csv", "format": "quat_wxyz", "length_unit": "mm", "angle_unit": "deg"}}
    atomic_write(out / "session.yaml", yaml.safe_dump(spec, sort_keys=False))
    info = setup_info(scene.setup)
    truth = {"setup": scene.setup, info.x_name: scene.X.tolist(), info.z_name: scene.Z.tolist(),
             "depth_scale": float(scene.depth_scale), "depth_bias": float(scene.depth_bias)}
    atomic_write(out / "ground_truth.yaml", yaml.safe_dump(truth, sort_keys=False))
    return out
