"""Continuous recordings: the robot's and the camera's time-stamped poses (or joint angles), each on its own clock."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import yaml
from numpy.typing import NDArray

from .._shared.io import atomic_write, check_output_folder
from .._shared.lazy import lazy_module
from ..errors import HandEyeError
from ..frames.setups import check_setup, predicted_target2cam, setup_info
from ..io.session import write_stream_session
from ..robot.kinematics import Chain, load_arm
from ..sensors.camera.render import Renderer, target_texture
from ..sensors.camera.targets import target_from_spec

cv2 = lazy_module("cv2")


from ._common import (
    ARM_DH,
    DEFAULT_TARGETS,
    EXACT,
    REALISTIC,
    RealisticErrors,
    _camera_reading,
    _robot_reading,
    _sees_target,
    arm_forward_kinematics,
    default_camera,
    real_chain,
    sample_joints,
    scene_layout,
)


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
    setup = check_setup(setup)
    rng = np.random.default_rng(rng)
    if not (duration > 2 * waypoint_s and robot_hz > 0 and camera_hz > 0):
        raise HandEyeError("stream_scene: duration must exceed two waypoint intervals; rates must be positive")
    spec = dict(DEFAULT_TARGETS[target]) if isinstance(target, str) else dict(target)
    obj = target_from_spec(spec).object_points()
    K, dist = default_camera(image_size)
    X, Z = scene_layout(setup, obj, rng)
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
    ``waypoint_s`` apart for ``duration`` seconds whose views see the target (:func:`sample_joints`)."""
    from scipy.interpolate import CubicSpline  # noqa: PLC0415  (scipy's interpolate costs import time)

    n_way = int(np.ceil(duration / waypoint_s)) + 1
    q_way = sample_joints(setup, X, Z, obj, K, image_size, n_way, rng, chain=chain)
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
    setup = check_setup(setup)
    rng = np.random.default_rng(rng)
    if not (duration > 2 * waypoint_s and robot_hz > 0 and camera_hz > 0):
        raise HandEyeError("joint_stream_scene: duration must exceed two waypoint intervals; rates must be positive")
    chain = load_arm(arm) if isinstance(arm, str) else arm
    spec = dict(DEFAULT_TARGETS[target]) if isinstance(target, str) else dict(target)
    obj = target_from_spec(spec).object_points()
    K, dist = default_camera(image_size)
    X, Z = scene_layout(setup, obj, rng, chain.forward(chain.home[setup][None])[0])
    path = _waypoint_path(setup, X, Z, obj, K, image_size, duration, waypoint_s, rng, chain)
    true = real_chain(chain, rng, length_mm, angle_deg)
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
