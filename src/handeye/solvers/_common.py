"""Pieces shared by the solver families: the translation least squares and rotation projection.

Every function here works on one problem or on a batch of them (leading axes, e.g. Monte-Carlo
runs), so a solver written with them is vectorised over runs for free.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..motions import MotionSet


def translation_least_squares(motions: MotionSet, R_X: NDArray[np.float64]) -> NDArray[np.float64]:
    """``t_X`` minimising ``sum |(R_A - I) t_X - (R_X t_B - t_A)|^2`` (thesis eq. 2.4).

    The "then translation" step of the rotation-first methods (Tsai-Lenz, Park-Martin, Horaud).
    Solved through the 3x3 normal equations; for rotations ``(R - I)^T (R - I) = 2I - R - R^T``,
    so the normal matrix is a plain sum over the motions. ``R_X`` is ``(..., 3, 3)``, one per run.
    """
    R_A = motions.R_A
    d = motions.t_B @ np.swapaxes(R_X, -1, -2) - motions.t_A
    S = R_A.sum(axis=-3)
    normal = 2 * len(motions) * np.eye(3) - S - np.swapaxes(S, -1, -2)
    stacked = R_A.reshape(R_A.shape[:-3] + (-1, 3))  # rows 3k + j: sum_k R_A^T d = stacked^T vec(d)
    rhs = (np.swapaxes(stacked, -1, -2) @ d.reshape(d.shape[:-2] + (-1, 1)))[..., 0] - d.sum(axis=-2)
    return np.linalg.solve(normal, rhs[..., None])[..., 0]


def nearest_rotation(M: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rotations closest (Frobenius) to 3x3 estimates ``(..., 3, 3)`` from a linear solve.

    As OpenCV's ``normalizeRotation``: scale to unit |det| keeping the sign of det (an estimate
    with negative determinant is the negated rotation), then project with the SVD and correct a
    remaining reflection. A singular estimate raises for one matrix and gives NaN in a batch.
    """
    det = np.linalg.det(M)
    singular = np.abs(det) < 1e-12
    if M.ndim == 2 and singular:
        raise np.linalg.LinAlgError("rotation estimate is singular")
    scale = np.cbrt(np.sign(det) / np.where(singular, 1.0, np.abs(det)))
    U, _, Vt = np.linalg.svd(scale[..., None, None] * M)
    reflect = np.linalg.det(U @ Vt) < 0
    U[..., :, 2] *= np.where(reflect, -1.0, 1.0)[..., None]
    R = U @ Vt
    R[singular] = np.nan
    return R


def log_rotations(dq: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation vectors (log maps) of the rotation parts of sign-aligned motion dual quaternions.

    Computed from the quaternions as ``2 atan2(|v|, w) v / |v|`` rather than with scipy, on
    purpose: scipy canonicalises each quaternion to w >= 0, which for a motion near 180 deg can
    flip the robot's rotation vector against the camera's; the aligned signs keep them paired.
    """
    v = dq[..., 1:4]
    vn = np.linalg.norm(v, axis=-1)
    angle = 2.0 * np.arctan2(vn, dq[..., 0])
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(vn > 1e-15, angle / vn, 2.0)  # limit of 2 atan(x)/x at 0
    return v * scale[..., None]
