"""Error metrics between transforms: rotation angle and translation distance."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from ..geometry.se3 import rotation_angle

__all__ = ["rotation_error", "translation_error", "std_deg_mm", "within_std"]


def rotation_error(T_est: ArrayLike, T_ref: ArrayLike) -> NDArray[np.float64] | float:
    """Angle (rad) of the rotation between estimates and references, ``angle(R_ref^T R_est)``.

    Accepts rotations ``(..., 3, 3)`` or transforms ``(..., 4, 4)``, broadcast. The angle comes from
    the quaternion as ``2 atan2(|v|, |w|)``, accurate to ~1e-16 rad near zero, where
    ``arccos((tr - 1)/2)`` would be stuck near 1e-8.
    """
    R1 = np.asarray(T_est, dtype=float)[..., :3, :3]
    R2 = np.asarray(T_ref, dtype=float)[..., :3, :3]
    err = rotation_angle(np.swapaxes(R2, -1, -2) @ R1)
    return float(err) if np.ndim(err) == 0 else err


def translation_error(T_est: ArrayLike, T_ref: ArrayLike) -> NDArray[np.float64] | float:
    """Euclidean distance between the translations of transforms ``(..., 4, 4)`` (input units)."""
    t1 = np.asarray(T_est, dtype=float)[..., :3, 3]
    t2 = np.asarray(T_ref, dtype=float)[..., :3, 3]
    err = np.linalg.norm(t1 - t2, axis=-1)
    return float(err) if np.ndim(err) == 0 else err


def std_deg_mm(cov: ArrayLike) -> NDArray[np.float64]:
    """Standard deviations (6,) of a covariance over [rotation vector (rad), translation (m)]: the
    rotation in degrees, the translation in millimetres (``Calibration.std``'s units)."""
    d = np.sqrt(np.diag(np.asarray(cov, dtype=float)))
    return np.r_[np.degrees(d[:3]), 1e3 * d[3:]]


def within_std(T_est: ArrayLike, T_ref: ArrayLike, std: ArrayLike, k: float = 3.0) -> bool:
    """Whether ``T_est`` lies within ``k`` of its ``std`` (6: deg about each axis, then mm along it;
    ``Calibration.std``'s units) of ``T_ref``, axis by axis: the rotation vector of
    ``R_est R_ref^T`` in degrees, the translations' difference in millimetres."""
    T_est, T_ref, std = (np.asarray(a, dtype=float) for a in (T_est, T_ref, std))
    rot = Rotation.from_matrix(T_est[:3, :3] @ T_ref[:3, :3].T).as_rotvec(degrees=True)
    return bool(np.all(np.abs(rot) <= k * std[:3]) and np.all(np.abs(1e3 * (T_est[:3, 3] - T_ref[:3, 3])) <= k * std[3:]))
