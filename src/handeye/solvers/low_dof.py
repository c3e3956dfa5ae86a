"""Robots that cannot rotate freely: SCARA, planar, 4-axis and Cartesian robots.

When every robot rotation is about one axis ``a`` (a SCARA's vertical, a planar robot's normal),
``A X = X B`` cannot determine all of X (the thesis's §2.2.3: the matrix T then has rank 5):

* the rotation axes give one direction, ``a = R_X b`` (robot axis ``a``, camera axis ``b``); the
  rotation of X about ``a`` is fixed by the translations: writing ``R_X = Rot(a, phi) R_0`` with
  ``R_0 b = a``, the translation equation ``(R_A - I) t_X = R_X t_B - t_A`` is linear in ``t_X``
  and in ``(cos phi, sin phi)``, solved here by one linear least squares (Ulrich and Steger,
  "Hand-eye calibration of SCARA robots using dual quaternions", PRIA 26(1), 2016, reach the
  same determined part by extending Daniilidis' dual-quaternion method; as in their paper, a
  nonlinear refinement follows: :mod:`handeye.estimation.partial`);
* ``(R_A - I) a = 0`` for every motion, so the translation of X along ``a`` is undetermined: a
  camera shifted along the axis sees the same motions. In the robot-world form only the
  difference of that component and the matching component of Z (e.g. the target's height in the
  base frame) is determined.

With pure translations (a Cartesian gantry), ``t_A = R_X t_B`` gives ``R_X`` (orthogonal
Procrustes, needing translations along at least two directions) and nothing determines ``t_X``.

The solvers here return X with the undetermined part of the translation set to zero (the
least-norm translation) and say which directions that is (:class:`LowDofSolution`); the pipeline
(``handeye.calibrate_poses``) fixes them with the user's ``known`` values or reports them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..errors import DegenerateMotionError
from ..frames.motions import MotionSet
from ..frames.setups import robot_world_A
from ..geometry.se3 import invert, make_transform, perpendicular_basis
from ._common import top_eigenvector
from .observability import MIN_AXIS_SPREAD, MIN_ROTATION, rotation_spread, rotation_spread_absolute
from .refine import TranslationPriors

__all__ = ["GAUGE_STD", "GENERAL", "LowDofSolution", "ONE_AXIS", "TRANSLATION_ONLY", "gauge_priors", "gauge_rows",
           "motion_kind", "partial_kind", "solve_low_dof", "low_dof_kind"]

GENERAL, ONE_AXIS, TRANSLATION_ONLY = "general", "one_axis", "translation_only"
#: Below this reciprocal condition number the system that fixes the determined part of X is
#: singular: the motions translate too little (one axis) or along one line only (pure translations).
MIN_CONDITION = 1e-9


@dataclass(frozen=True)
class LowDofSolution:
    """What one-axis or translation-only motions determine of X.

    Attributes
    ----------
    X : ndarray (..., 4, 4)
        The rotation of X and its translation with the undetermined part set to zero.
    kind : {'one_axis', 'translation_only'}
    null_space : ndarray (..., m, 3)
        Orthonormal directions, in the frame X maps into (flange for eye-in-hand, base for
        eye-to-hand), along which the translation of X is undetermined: the rotation axis
        (``m = 1``) or every direction (``m = 3``).
    axis_camera : ndarray (..., 3) or None
        One axis: the rotation axis in the camera frame (``R_X axis_camera = null_space[0]``).
    condition : ndarray (...)
        Reciprocal condition number of the system that gave the determined part (0 to 1).
    """

    X: NDArray[np.float64]
    kind: str
    null_space: NDArray[np.float64]
    axis_camera: NDArray[np.float64] | None
    condition: NDArray[np.float64]


def motion_kind(motions: MotionSet) -> str:
    """``'general'``, ``'one_axis'`` or ``'translation_only'``: the rotations of the motions, by
    the thresholds of :func:`handeye.solvers.observability.check_observability`. The more
    degenerate of the robot and camera sides decides (a single problem, no batch)."""
    kinds = []
    for dq in (motions.dq_a, motions.dq_b):
        largest, spread, _ = rotation_spread(dq)
        kinds.append(low_dof_kind(largest, spread))
    order = (GENERAL, ONE_AXIS, TRANSLATION_ONLY)
    return max(kinds, key=order.index)


def solve_low_dof(motions: MotionSet, kind: str | None = None) -> LowDofSolution:
    """The part of X that one-axis or translation-only motions determine (module docstring).

    Parameters
    ----------
    motions : MotionSet
        Validated motions, one problem or a batch ``(..., K, 8)``.
    kind : {'one_axis', 'translation_only'}, optional
        Default: :func:`motion_kind` (single problems only).

    Raises
    ------
    DegenerateMotionError
        A single problem whose motions do not determine even that part (too few motions, no
        translation off the axis, translations along one line only), or motions that rotate about
        more than one axis (use the general solvers).
    """
    if kind is None:
        kind = motion_kind(motions)
    if kind == GENERAL:
        raise DegenerateMotionError("the motions rotate about more than one axis: X is fully determined; use "
                                    "handeye.solve (the low-DOF solvers are for one-axis or translation-only motions)")
    if len(motions) < 2:
        raise DegenerateMotionError(f"{len(motions)} motion(s): the low-DOF solvers need at least 2 motions (3 poses)")
    sol = _one_axis(motions) if kind == ONE_AXIS else _translation_only(motions)
    if not motions.batch_shape and not sol.condition > MIN_CONDITION:
        what = ("the motions about the single axis do not translate the camera off that axis"
                if kind == ONE_AXIS else "the translations all lie along one line")
        raise DegenerateMotionError(f"{what}: the rotation of X is undetermined. Move the flange to positions "
                                    f"spread over the working plane (at least 3 not on one line)")
    return sol


def _rotation_between(b: NDArray[np.float64], a: NDArray[np.float64]) -> NDArray[np.float64]:
    """The smallest rotations taking unit vectors ``b`` onto ``a`` (..., 3, 3)."""
    c = np.einsum("...i,...i->...", a, b)
    k = np.cross(b, a)
    # near-opposite vectors: a half turn about a vector perpendicular to b
    p = np.cross(b, np.where(np.abs(b[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]))
    p /= np.linalg.norm(p, axis=-1, keepdims=True)
    half_turn = 2.0 * p[..., :, None] * p[..., None, :] - np.eye(3)
    K = np.zeros(k.shape + (3,))
    K[..., 0, 1], K[..., 0, 2], K[..., 1, 2] = -k[..., 2], k[..., 1], -k[..., 0]
    K -= np.swapaxes(K, -1, -2)
    near = c < -1.0 + 1e-9
    c_safe = np.where(near, 0.0, c)
    R = np.eye(3) + K + (K @ K) / (1.0 + c_safe)[..., None, None]
    return np.where(near[..., None, None], half_turn, R)


def _reciprocal_condition(N: NDArray[np.float64]) -> NDArray[np.float64]:
    w = np.linalg.eigvalsh(N)
    return np.where(w[..., -1] > 0, w[..., 0] / np.where(w[..., -1] > 0, w[..., -1], 1.0), 0.0)


def _one_axis(motions: MotionSet) -> LowDofSolution:
    v_a, v_b = motions.dq_a[..., 1:4], motions.dq_b[..., 1:4]  # sin(theta/2) * axis, signs aligned
    e_a = top_eigenvector(np.swapaxes(v_a, -1, -2) @ v_a)
    e_b = top_eigenvector(np.swapaxes(v_b, -1, -2) @ v_b)
    # the eigenvectors' signs are arbitrary: a = R_X b needs the same sign of turn on both sides
    agree = np.einsum("...k,...k->...", np.einsum("...ki,...i->...k", v_a, e_a), np.einsum("...ki,...i->...k", v_b, e_b))
    e_b = e_b * np.where(agree < 0, -1.0, 1.0)[..., None]
    R_0 = _rotation_between(e_b, e_a)
    b = motions.t_B @ np.swapaxes(R_0, -1, -2)  # R_0 t_B per motion
    e = e_a[..., None, :]
    b_par = np.einsum("...ki,...ki->...k", b, np.broadcast_to(e, b.shape))
    b_perp = b - b_par[..., None] * e
    e_cross_b = np.cross(np.broadcast_to(e, b.shape), b)
    u, w = perpendicular_basis(e_a)
    RmI = motions.R_A - np.eye(3)
    c_u = np.einsum("...kij,...j->...ki", RmI, u)
    c_w = np.einsum("...kij,...j->...ki", RmI, w)
    # (R_A - I)(alpha u + beta w) - cos(phi) b_perp - sin(phi) (e x b) = (e . b) e - t_A
    M = np.stack([c_u, c_w, -b_perp, -e_cross_b], axis=-1)  # (..., K, 3, 4)
    rhs = b_par[..., None] * e - motions.t_A
    N = np.einsum("...kji,...kjl->...il", M, M)
    g = np.einsum("...kji,...kj->...i", M, rhs)
    condition = _reciprocal_condition(N)
    y = np.linalg.solve(N + np.where(condition > MIN_CONDITION, 0.0, 1.0)[..., None, None] * np.eye(4), g[..., None])[..., 0]
    phi = np.arctan2(y[..., 3], y[..., 2])
    R_X = Rotation.from_rotvec((e_a * phi[..., None]).reshape(-1, 3)).as_matrix().reshape(R_0.shape) @ R_0
    # the translation again with the rotation fixed (the (cos, sin) pair was not constrained to a circle)
    M2 = M[..., :2]
    rhs2 = np.einsum("...ij,...kj->...ki", R_X, motions.t_B) - motions.t_A
    N2 = np.einsum("...kji,...kjl->...il", M2, M2)
    ab = np.linalg.solve(N2 + np.where(condition > MIN_CONDITION, 0.0, 1.0)[..., None, None] * np.eye(2),
                         np.einsum("...kji,...kj->...i", M2, rhs2)[..., None])[..., 0]
    t_X = ab[..., :1] * u + ab[..., 1:] * w
    X = make_transform(R_X, t_X)
    nan = ~(condition > MIN_CONDITION)
    X = np.where(nan[..., None, None], np.nan, X)
    return LowDofSolution(X, ONE_AXIS, e_a[..., None, :], e_b, condition)


def _translation_only(motions: MotionSet) -> LowDofSolution:
    t_a, t_b = motions.t_A, motions.t_B
    M = np.swapaxes(t_a, -1, -2) @ t_b  # sum t_A t_B^T: R_X maximises tr(R_X^T M)
    U, s, Vt = np.linalg.svd(M)
    U[..., :, 2] *= np.sign(np.linalg.det(U @ Vt))[..., None]
    R_X = U @ Vt
    condition = np.where(s[..., 0] > 0, s[..., 1] / np.where(s[..., 0] > 0, s[..., 0], 1.0), 0.0)
    X = make_transform(R_X, np.zeros(R_X.shape[:-2] + (3,)))
    X = np.where(~(condition > MIN_CONDITION)[..., None, None], np.nan, X)
    null = np.broadcast_to(np.eye(3), R_X.shape).copy()
    return LowDofSolution(X, TRANSLATION_ONLY, null, None, condition)


#: The std (m) that holds an undetermined direction of X's translation at its value in a refinement.
GAUGE_STD = 1e-9


def gauge_rows(null_space: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rows over ``[t_X, t_Z]`` (:class:`~handeye.solvers.refine.TranslationPriors`) measuring X's
    translation along each undetermined direction."""
    return np.concatenate([null_space, np.zeros_like(null_space)], axis=1)


def gauge_priors(null_space: NDArray[np.float64], X: NDArray[np.float64]) -> TranslationPriors:
    """X's translation held at its value along the undetermined directions, so that the pose
    refinement (and its covariance) is defined on low-DOF data."""
    return TranslationPriors(gauge_rows(null_space), null_space @ X[:3, 3], np.full(len(null_space), GAUGE_STD))


def _pose_rotation_spread(flange2base, target2cam, setup: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The largest rotation and the largest rotation off the dominant axis (``sin(theta/2)``) of the
    robot's and of the camera's motions, ``(2,)`` each (:func:`rotation_spread_absolute`)."""
    pair = np.stack([robot_world_A(flange2base, setup), invert(target2cam)])
    (largest, spread), _ = rotation_spread_absolute(pair)
    return largest, spread


def low_dof_kind(largest: float, spread: float, scale: float = 1.0) -> str:
    """The kind of motions with these rotations (``sin(theta/2)`` of the largest, and of the largest
    off the dominant axis: :func:`~handeye.solvers.observability.rotation_spread`), by the thresholds
    of ``check_observability`` times ``scale``."""
    return TRANSLATION_ONLY if largest < MIN_ROTATION * scale else ONE_AXIS if spread < MIN_AXIS_SPREAD * scale else GENERAL


#: How far beyond the robot's thresholds the camera's rotations may stray and still show the
#: robot's low-DOF motion: the robot reads its joints to hundredths of a degree, while PnP on a
#: single AprilTag or a far board is off by a degree or more (a SCARA seen that way looked
#: 'general' to the camera and was refused). 10x the 0.57 deg thresholds: ~5.7 deg.
CAMERA_ROTATION_NOISE = 10.0


#: The share of views that must agree with the robot's low-DOF kind (within the camera's noise
#: allowance) for the camera to count as showing it; the rest go to the outlier search.
AGREE_SHARE = 0.75


def _camera_agreeing(target2cam: NDArray[np.float64], kind: str, candidates: int = 50) -> NDArray[np.bool_] | None:
    """The views whose camera rotations show the robot's ``kind`` (a gantry: one orientation; a
    SCARA: rotations about one axis) to within the camera's noise allowance, when they are at least
    :data:`AGREE_SHARE` of the views (and 3); else None. A flipped planar PnP solution in one view
    (10 deg and more off) must not make a gantry's or a SCARA's camera look rotating freely.

    Relative to a reference view r, ``M_i = R_r^T R_i`` (the target's rotations in the camera);
    with ``v`` its quaternion vector part, ``|v|^2 = (3 - tr M) / 4`` and the part off an axis
    ``e`` is ``(1 - e^T M e) / 2`` (sign-free, as in
    :func:`~handeye.solvers.observability.rotation_spread_absolute`); ``e`` is the top eigenvector
    of ``sum (M + M^T)``. The reference is the view, among up to ``candidates`` spread ones, that
    most views agree with."""
    n = len(target2cam)
    R = target2cam[:, :3, :3]
    refs = R[np.unique(np.linspace(0, n - 1, min(n, candidates)).round().astype(int))]
    M = np.einsum("rji,njk->rnik", refs, R)
    if kind == TRANSLATION_ONLY:
        off2 = (3.0 - np.trace(M, axis1=2, axis2=3)) / 4.0
        limit = MIN_ROTATION * CAMERA_ROTATION_NOISE
    else:
        S = M.sum(axis=1)
        e = top_eigenvector(S + np.swapaxes(S, -1, -2))
        off2 = (1.0 - np.einsum("rj,rnjk,rk->rn", e, M, e)) / 2.0
        limit = MIN_AXIS_SPREAD * CAMERA_ROTATION_NOISE
    agree = off2 < limit**2
    best = agree[np.argmax(agree.sum(axis=1))]
    return best if best.sum() >= max(3, AGREE_SHARE * n) else None


def partial_kind(flange2base: NDArray[np.float64], target2cam: NDArray[np.float64], setup: str,
                 reasons: list[str] | None = None) -> str | None:
    """The low-DOF kind of these poses when both the robot and the camera motions show it and the
    low-DOF solver determines its part of X; else None (general data, or data that determine
    nothing: then the solver's reason is appended to ``reasons``)."""
    largest, spread = _pose_rotation_spread(flange2base, target2cam, setup)
    robot = low_dof_kind(largest[0], spread[0])
    if robot == GENERAL:
        return None
    keep = np.ones(len(target2cam), bool)
    # the camera's rotations may stray from the robot's kind by its noise, and a few views by more
    if robot not in (low_dof_kind(largest[1], spread[1]), low_dof_kind(largest[1], spread[1], CAMERA_ROTATION_NOISE)):
        keep = _camera_agreeing(target2cam, robot)
        if keep is None:
            return None
    try:  # on the views that show the kind: the others are for the outlier search to name
        solve_low_dof(MotionSet.from_poses(flange2base[keep], target2cam[keep], setup, "auto"), robot)
    except DegenerateMotionError as exc:
        if reasons is not None:
            reasons.append(str(exc))
        return None
    return robot
