"""Pieces shared by the solver families: the translation least squares and rotation projection."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..motions import MotionSet


def translation_least_squares(motions: MotionSet, R_X: NDArray[np.float64]) -> NDArray[np.float64]:
    """``t_X`` minimising ``sum |(R_A - I) t_X - (R_X t_B - t_A)|^2`` (thesis eq. 2.4).

    The "then translation" step of the rotation-first methods (Tsai-Lenz, Park-Martin, Horaud).
    Solved through the 3x3 normal equations; for rotations ``(R - I)^T (R - I) = 2I - R - R^T``,
    so the normal matrix is a plain sum over the motions.
    """
    R_A = motions.R_A
    d = motions.t_B @ R_X.T - motions.t_A
    S = R_A.sum(axis=0)
    normal = 2 * len(R_A) * np.eye(3) - S - S.T
    rhs = np.einsum("kji,kj->i", R_A, d) - d.sum(axis=0)  # sum (R_A - I)^T d
    return np.linalg.solve(normal, rhs)


def nearest_rotation(M: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rotation closest (Frobenius) to a 3x3 estimate from a linear solve.

    As OpenCV's ``normalizeRotation``: scale to unit |det| keeping the sign of det (an estimate
    with negative determinant is the negated rotation), then project with the SVD and correct a
    remaining reflection.
    """
    det = np.linalg.det(M)
    if abs(det) < 1e-12:
        raise np.linalg.LinAlgError("rotation estimate is singular")
    M = np.cbrt(np.sign(det) / abs(det)) * M
    U, _, Vt = np.linalg.svd(M)
    R = U @ Vt
    if np.linalg.det(R) < 0:
        R = U @ np.diag([1.0, 1.0, -1.0]) @ Vt
    return R


def log_rotations(dq: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation vectors (log maps) of the rotation parts of sign-aligned motion dual quaternions.

    Computed from the quaternions as ``2 atan2(|v|, w) v / |v|`` rather than with scipy, on
    purpose: scipy canonicalises each quaternion to w >= 0, which for a motion near 180 deg can
    flip the robot's rotation vector against the camera's; the aligned signs keep them paired.
    """
    v = dq[:, 1:4]
    vn = np.linalg.norm(v, axis=1)
    angle = 2.0 * np.arctan2(vn, dq[:, 0])
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(vn > 1e-15, angle / vn, 2.0)  # limit of 2 atan(x)/x at 0
    return v * scale[:, None]
