"""Captures by arms with real robots' errors: kinematic tables off their nominal values, timing jitter,
heavy-tailed noise; joint angles through shipped arms' tables; robots that cannot rotate freely."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from .._shared.lazy import lazy_module
from ..errors import HandEyeError, InputMismatchError
from ..frames.setups import check_setup, predicted_target2cam, setup_info
from ..geometry.se3 import invert, make_transform, perturb
from ..io.session import write_joint_session, write_session
from ..robot.kinematics import Chain, arm_names, load_arm
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
    _new_session_folder,
    _robot_reading,
    _sees_target,
    _write_images,
    _write_truth,
    arm_forward_kinematics,
    default_camera,
    real_chain,
    sample_joints,
    scene_layout,
)


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
    setup = check_setup(setup)
    rng = np.random.default_rng(rng)
    spec = dict(DEFAULT_TARGETS[target]) if isinstance(target, str) else dict(target)
    obj = target_from_spec(spec).object_points()
    K, dist = default_camera(image_size)
    X, Z = scene_layout(setup, obj, rng)
    q = sample_joints(setup, X, Z, obj, K, image_size, n_poses, rng)
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
    setup = check_setup(setup)
    rng = np.random.default_rng(rng)
    chain = load_arm(arm) if isinstance(arm, str) else arm
    spec = dict(DEFAULT_TARGETS[target]) if isinstance(target, str) else dict(target)
    obj = target_from_spec(spec).object_points()
    K, dist = default_camera(image_size)
    X, Z = scene_layout(setup, obj, rng, chain.forward(chain.home[setup][None])[0])
    q_true = sample_joints(setup, X, Z, obj, K, image_size, n_poses, rng, chain=chain)
    true = real_chain(chain, rng, length_mm, angle_deg, compliance_deg_per_m)
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
    setup = check_setup(setup)
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
