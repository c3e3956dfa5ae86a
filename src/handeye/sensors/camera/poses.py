"""A camera's poses of the target as a sensor model (:mod:`handeye.sensors.base`): pose pairs.

When only the target's pose in each view is known (PnP's, or another tool's ``target2cam``; no
detections), each view measures a whole pose. What a pose says reliably is where the target's
points lie across the camera's viewing rays; along the ray (the target's distance) PnP's pose is
far less certain. So the residuals are those of a virtual target's points (a 0.2 x 0.15 m grid in
the target's plane): the predicted point's offset across the measured point's viewing ray, in
metres at its depth (what pixels measure, without PnP's depth error), every point weighted alike.
(Weighted by its depth, as a pixel's size grows, X was further from the truth on simulated joint
streams: 0.18 mm against 0.12, median of 6; on 10 joint captures 0.094 against 0.102 mm.) The
unknowns besides X: the target's pose (a chart about its start). The start: the closed form on
the poses.

Examples
--------
>>> import numpy as np
>>> from handeye.estimation.core import estimate
>>> from handeye.robot.models import ControllerPoses
>>> from handeye.simulate import random_scene
>>> scene = random_scene(12, "eye_in_hand", rng=0)
>>> model = TargetPoses("eye_in_hand", [f"v{i}" for i in range(12)], scene.target2cam)
>>> cal = estimate(model, ControllerPoses(scene.flange2base))
>>> bool(1e3 * np.abs(cal.X[:3, 3] - scene.X[:3, 3]).max() < 1e-3)
True
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...errors import DegenerateMotionError, InputMismatchError
from ...frames.setups import check_setup, constant_transforms, predicted_target2cam, robot_world_A, setup_info
from ...geometry.se3 import invert, rotation_of_valid, skew, so3_left_jacobian
from ..target_pose import ChartedTarget

__all__ = ["TargetPoses", "PoseDifferences", "VIRTUAL_POINTS", "POSE_NOISE", "LEVER", "NOISE_TERMS", "DEPTH_MIN_POSES",
           "pose_residuals", "pose_jacobian", "pose_noise_shapes", "pose_noise_start"]

#: The virtual target's points (target frame, m) whose viewing rays carry a pose's residuals.
VIRTUAL_POINTS = np.array([[x, y, 0.0] for x in np.linspace(0.0, 0.2, 5) for y in np.linspace(0.0, 0.15, 4)])
#: A pose's noise across the viewing ray to state before any fit, as a share of the depth (0.2 mm at 1 m:
#: 0.3 px of a corner at a focal length of ~1500 px, averaged over a board's corners).
POSE_NOISE = 2e-4


class TargetPoses(ChartedTarget):
    """A camera's poses of the target, one per view (the module docstring).

    Parameters
    ----------
    setup : str
    names : list of str
        Per view its name.
    target2cam : array_like (N, 4, 4)
        Per view the target's pose in the camera frame (m); a view whose pose is not finite is one
        the camera did not see the target in.
    """

    kind = "camera"
    target = "target poses"
    pixel_columns: tuple[int, ...] = ()  # every point weighted alike (the module docstring)
    groups: tuple[tuple[int, ...], ...] = ((0, 1),)
    param_names = ["target.rx", "target.ry", "target.rz", "target.x", "target.y", "target.z"]

    def __init__(self, setup: str, names: list[str], target2cam: ArrayLike) -> None:
        seen = self._given(setup, names, target2cam)
        poses = self._poses
        m = len(VIRTUAL_POINTS)
        self.owner = np.repeat(seen, m).astype(np.intp)
        self.points = np.tile(VIRTUAL_POINTS, (len(seen), 1))
        measured = np.einsum("mij,mj->mi", poses[self.owner, :3, :3], self.points) + poses[self.owner, :3, 3]
        if np.any(measured[:, 2] <= 0):
            view = self.names[int(self.owner[np.argmax(measured[:, 2] <= 0)])]
            raise InputMismatchError(f"view {view}: the target lies behind the camera (z <= 0 in target2cam); give the "
                                     "target's pose in the camera frame (the camera's z axis along its view)")
        self._ray = measured[:, :2] / measured[:, 2:3]  # each virtual point's viewing ray (normalised coordinates)
        self._depth = measured[:, 2]
        self.noise_px = 1.0  # the stated noise is POSE_NOISE of the depth: a "pixel" of that size
        self.shape = np.ones((len(self.owner), 2))
        self.param_scale = np.full(6, 1e-3)

    def _given(self, setup: str, names: list[str], target2cam: ArrayLike) -> NDArray[np.intp]:
        """The setup, the names and the poses checked and kept; the views whose pose is finite."""
        self.setup = check_setup(setup)
        poses = np.asarray(target2cam, dtype=float)
        if poses.ndim != 3 or poses.shape[1:] != (4, 4) or len(poses) != len(names):
            raise InputMismatchError(f"{len(names)} views and target2cam of shape {poses.shape}: give one 4x4 pose per view")
        self.names = list(names)
        self._poses = poses
        return np.flatnonzero(np.isfinite(poses).all(axis=(1, 2)))

    def view_poses(self) -> NDArray[np.float64]:
        """The poses given."""
        return self._poses

    def start(self, flange2base, X, Z, rows=None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """X and the target from the closed form; the first start fixes the target's chart and each
        point's stated noise (:data:`POSE_NOISE` of its depth)."""
        if X is None or Z is None:
            raise DegenerateMotionError("target poses need 3 views or more for the closed form")
        self._first_start(X, Z, flange2base, 1.0 / POSE_NOISE)
        return X, self.target_params(Z)

    def residuals(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """Per virtual point (m): the predicted point's offset across its measured viewing ray, at its depth."""
        target2cam = predicted_target2cam(X, self._target2world(p), np.asarray(flange2base, float), self.setup)
        T = target2cam[self.owner[rows]]
        seen = np.einsum("mij,mj->mi", T[:, :3, :3], self.points[rows]) + T[:, :3, 3]
        return (seen[:, :2] / seen[:, 2:3] - self._ray[rows]) * self._depth[rows, None]

    def figures(self, p, cov_p) -> dict[str, Any]:
        """Nothing beyond the core's own figures."""
        return {}

    def notes(self, p, cov_p) -> list[str]:
        """Nothing beyond the core's own notes."""
        return []


# The pose refinement's residual and noise model (seed §2.2.4, Strobl and Hirzinger, with the lever
# arm between flange and target): :func:`handeye.estimation.refinement.refine_pose` and :class:`PoseDifferences`.

def pose_residuals(X, Z, flange2base, target2cam, setup):
    """Per pose ``Z^-1 Z_i`` as [rotation vector, translation] in the target frame, and ``target2flange_i``."""
    Zi = constant_transforms(X, flange2base, target2cam, setup)
    t2f = X @ target2cam if setup_info(setup).camera_on_flange else Zi  # eye-to-hand: Z_i is target2flange
    D = invert(Z) @ Zi
    r = np.concatenate([rotation_of_valid(D[:, :3, :3]).as_rotvec(), D[:, :3, 3]], axis=1)  # products of rotations
    return r, t2f, Zi


def _right_jacobian_inv(phi):
    """Inverse right Jacobians of SO(3) at rotation vectors ``phi`` (N, 3): ``d log(R exp(e)) / de``."""
    theta = np.linalg.norm(phi, axis=1)
    S = skew(phi)
    small = theta < 1e-6
    th = np.where(small, 1.0, theta)
    c = np.where(small, 1.0 / 12.0, 1.0 / th**2 - (1.0 + np.cos(th)) / (2.0 * th * np.sin(th)))
    return np.eye(3) + 0.5 * S + c[:, None, None] * (S @ S)


def pose_jacobian(X, Z, flange2base, target2cam, setup, r):
    """Jacobian (N, 6, 12) of the pose residuals over [dX rotation, dX translation, dZ rotation, dZ
    translation], left rotation increments as in ``refine_pose``'s parameterisation."""
    robot = robot_world_A(flange2base, setup)
    n = len(robot)
    R_A, R_B, t_B = robot[:, :3, :3], target2cam[:, :3, :3], target2cam[:, :3, 3]
    R_X, R_Z = X[:3, :3], Z[:3, :3]
    Zi = constant_transforms(X, flange2base, target2cam, setup)
    D_R = R_Z.T @ Zi[:, :3, :3]
    Jinv = _right_jacobian_inv(r[:, :3])
    J = np.zeros((n, 6, 12))
    J[:, :3, 0:3] = Jinv @ np.swapaxes(R_X @ R_B, 1, 2)
    J[:, :3, 6:9] = -Jinv @ np.swapaxes(D_R, 1, 2) @ R_Z.T
    RzA = R_Z.T @ R_A
    J[:, 3:, 0:3] = -RzA @ skew(t_B @ R_X.T)
    J[:, 3:, 3:6] = RzA
    J[:, 3:, 6:9] = R_Z.T @ skew(Zi[:, :3, 3] - Z[:3, 3])
    J[:, 3:, 9:12] = -R_Z.T
    return J


def pose_noise_shapes(target2flange, target2cam):
    """Per pose, the residual covariance of unit robot rotation noise, unit camera rotation noise,
    unit translation noise and unit camera depth noise (4 x (N, 6, 6)).

    The depth term is the camera's translation error along its optical axis, which PnP determines
    several times less well than across it (the target's distance from its apparent size).

    Robot noise perturbs the flange pose about the flange origin, camera noise the target pose
    about the target origin (``T -> T exp(xi)``). In the target frame the camera's enters as is, the
    robot's through the adjoint of ``flange2target``: a flange rotation also moves the target by the
    lever arm between the two origins.
    """
    n = len(target2flange)
    R = np.swapaxes(target2flange[:, :3, :3], 1, 2)  # flange2target rotation
    p = -R @ target2flange[:, :3, 3, None]  # flange2target translation
    ad_rot = np.concatenate([R, skew(p[..., 0]) @ R], axis=1)  # (N, 6, 3): adjoint's rotation columns
    robot = ad_rot @ np.swapaxes(ad_rot, 1, 2)
    cam = np.zeros((n, 6, 6))
    cam[:, [0, 1, 2], [0, 1, 2]] = 1.0
    tra = np.zeros((n, 6, 6))
    tra[:, [3, 4, 5], [3, 4, 5]] = 1.0
    axis = target2cam[:, 2, :3]  # the camera's optical axis in the target frame (where the residual lives)
    depth = np.zeros((n, 6, 6))
    depth[:, 3:, 3:] = axis[:, :, None] * axis[:, None, :]
    return robot, cam, tra, depth


#: The noise model's terms, in the order of its variances (``PoseRefinementResult.noise`` keys).
NOISE_TERMS = ("robot_rotation", "camera_rotation", "translation", "camera_depth")
#: From this many poses the camera's depth noise is a term of its own (fewer: in the translation term).
#: Four variances from 4 poses' 12 residual degrees of freedom are too loose: X within 3 std on 94% of
#: the axes of realistic 4-pose eye-in-hand sessions, 98% with three; from 8 poses 100% either way.
DEPTH_MIN_POSES = 6


def pose_noise_start(r: NDArray[np.float64], terms: int) -> NDArray[np.float64]:
    """The start of the first ``terms`` variances of :data:`NOISE_TERMS` from the residuals ``r``
    (N, 6) of :func:`pose_residuals`: half the rotation residual's mean square for the robot and
    half for the camera, half the translation's for the translation and for the depth."""
    s_rot, s_tra = float(np.mean(r[:, :3] ** 2)), float(np.mean(r[:, 3:] ** 2))
    return np.array([0.5 * s_rot, 0.5 * s_rot, 0.5 * s_tra, 0.5 * s_tra])[:terms]


#: The lever (m) a pose's rotation residual is taken at in :class:`PoseDifferences` (a point of the
#: target this far from its origin moves by it): its residuals are metres, as every sensor's.
LEVER = 0.1


class PoseDifferences(TargetPoses):
    """A camera's poses of the target, one per view, each a whole measurement: the pose
    refinement's residual and noise model (seed §2.2.4, :func:`~handeye.estimation.refinement.refine_pose`)
    as a sensor model of the estimation core.

    Each view's residual is where its pose puts the target against where the fit puts it, ``Z^-1
    Z_i`` in the target frame: a rotation vector (taken at :data:`LEVER`, metres) and a translation.
    Its 6 residuals are correlated, their covariance a sum of terms (:data:`NOISE_TERMS`), each a
    variance the core fits to the data by maximum likelihood (``noise_shapes``): the robot's rotation
    error, which moves the target through the lever arm between flange and target (different in every
    view); the camera's rotation error; the translation error; and from :data:`DEPTH_MIN_POSES` views
    the camera's error along its optical axis (PnP's depth, several times less certain than across).
    The unknowns besides X: the target's pose (a chart about its start).

    Parameters
    ----------
    setup, names, target2cam
        As for :class:`TargetPoses`.
    terms : int, optional
        How many of :data:`NOISE_TERMS` the noise model has (default: 4 from :data:`DEPTH_MIN_POSES`
        views, else 3): a refit on other poses holds an earlier fit's.

    Examples
    --------
    >>> import numpy as np
    >>> from handeye.estimation.core import Problem, fit
    >>> from handeye.estimation.diagnostics import closed_form
    >>> from handeye.robot.models import ControllerPoses
    >>> from handeye.simulate import random_scene
    >>> scene = random_scene(12, "eye_to_hand", rng=0)
    >>> model = PoseDifferences("eye_to_hand", [f"v{i}" for i in range(12)], scene.target2cam)
    >>> X0, Z0, _ = closed_form(scene.flange2base, scene.target2cam, "eye_to_hand", "tsai_lenz")
    >>> fitted = fit(Problem(model, ControllerPoses(scene.flange2base), *model.start(scene.flange2base, X0, Z0)))
    >>> bool(1e3 * np.abs(fitted.X[:3, 3] - scene.X[:3, 3]).max() < 1e-3)
    True
    """

    target = "target poses, whole"
    groups: tuple[tuple[int, ...], ...] = ((0, 1, 2, 3, 4, 5),)  # one scale: the terms below are what the core fits

    def __init__(self, setup: str, names: list[str], target2cam: ArrayLike, terms: int | None = None) -> None:
        # not TargetPoses': a whole pose needs no virtual points in front of the camera
        seen = self._given(setup, names, target2cam)
        if terms is None:
            terms = len(NOISE_TERMS) if len(seen) >= DEPTH_MIN_POSES else len(NOISE_TERMS) - 1
        self.noise_terms = NOISE_TERMS[:terms]
        self.owner = seen.astype(np.intp)
        self.points = np.zeros((len(seen), 3))  # the target's origin, where its pose's translation is
        self.shape = np.ones((len(seen), 6))
        self.param_scale = np.full(6, 1e-3)
        self.noise_px = 1.0  # the stated noise is POSE_NOISE of the depth: a "pixel" of that size
        self._scale = np.r_[np.full(3, LEVER), np.ones(3)]  # the residual's columns: rotation at the lever, metres

    def _poses_of(self, flange2base, rows) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        views = self.owner[rows]
        return np.asarray(flange2base, float)[views], self._poses[views]

    def residuals(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """Per view (rotation at :data:`LEVER`, m): ``Z^-1 Z_i`` in the target frame."""
        r, _, _ = pose_residuals(X, self._target2world(p), *self._poses_of(flange2base, rows), self.setup)
        return r * self._scale

    def jacobian(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """The residuals' derivatives (M, 6, 12) by a left increment of X and by ``p``."""
        F, B = self._poses_of(flange2base, rows)
        Z = self._target2world(p)
        J = pose_jacobian(X, Z, F, B, self.setup, pose_residuals(X, Z, F, B, self.setup)[0])
        J[..., 6:9] = J[..., 6:9] @ so3_left_jacobian(p[:3])  # p's rotation is a vector in the chart
        return J * self._scale[:, None]

    def noise_shapes(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """Per term of ``noise_terms`` the covariance (K, M, 6, 6) of each view's residual for that
        term's unit variance (:func:`pose_noise_shapes`, in the residual's units)."""
        F, B = self._poses_of(flange2base, rows)
        _, target2flange, _ = pose_residuals(X, self._target2world(p), F, B, self.setup)
        shapes = np.stack(pose_noise_shapes(target2flange, B)[:len(self.noise_terms)])
        return shapes * np.outer(self._scale, self._scale)

    def noise_start(self, residuals: NDArray[np.float64]) -> NDArray[np.float64]:
        """The variances to start from, from the residuals at the start (:func:`pose_noise_start`)."""
        return pose_noise_start(residuals / self._scale, len(self.noise_terms))
