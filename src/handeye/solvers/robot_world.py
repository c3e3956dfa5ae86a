"""Robot-world/hand-eye: ``A_i X = Z B_i`` for both unknowns at once, from absolute poses.

* ``shah``: M. Shah, "Solving the robot-world/hand-eye calibration problem using the Kronecker
  product", J. Mechanisms and Robotics 5(3), 2013. Rotations from the top singular pair of
  ``sum_i R_Bi kron R_Ai``, then both translations by linear least squares.
* ``li``: A. Li, L. Wang, D. Wu, "Simultaneous robot-world and hand-eye calibration using
  dual-quaternions and Kronecker product", Int. J. Physical Sciences 5(10), 2010, in its Kronecker
  form: one linear system in ``vec(R_X), vec(R_Z), t_X, t_Z``. Two changes from OpenCV's LI, both
  measured on Tabb's real pairs (median |A_i X - Z B_i|: OpenCV LI 17.8 mm, ours 11.1 mm, OpenCV
  SHAH 11.2 mm): (1) the system mixes unitless rotation rows with translation rows in length
  units, so OpenCV's answer changes with the unit (mm or m); we divide all lengths by the RMS of
  ``t_Ai`` (the translation rows' right-hand side), which makes it unit-free; (2) the rotations
  come out of the linear solve non-orthonormal and its translations belong to those; after
  projecting the rotations we re-solve the translations for them, as Shah does.

How handeye maps its poses onto this form (DESIGN §2):

* eye-in-hand: ``flange2base_i @ X = Z @ inv(target2cam_i)`` with ``X = cam2flange``,
  ``Z = target2base``;
* eye-to-hand: ``inv(flange2base_i) @ X = Z @ inv(target2cam_i)`` with ``X = cam2base``,
  ``Z = target2flange``.

OpenCV's ``calibrateRobotWorldHandEye(R_world2cam, ..., R_base2gripper, ...)`` solves the same
equation with ``A_i = world2cam`` (target2cam), ``X = base2world``, ``Z = gripper2cam``,
``B_i = base2gripper``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..geometry.se3 import make_transform
from ._common import kron_eye, kron_eye_vec_sum, kron_sum, nearest_rotation
from ._registry import register


def _translations(A: NDArray[np.float64], B: NDArray[np.float64], R_Z: NDArray[np.float64]) -> tuple:
    """``t_X, t_Z`` minimising ``sum |R_Ai t_X - t_Z - (R_Z t_Bi - t_Ai)|^2`` (per run of a batch).

    Normal equations of the rows ``[R_Ai, -I]``: ``[[n I, -sum R_Ai^T], [-sum R_Ai, n I]]``.
    """
    n = A.shape[-3]
    R_A = A[..., :3, :3]
    r = np.einsum("...ij,...kj->...ki", R_Z, B[..., :3, 3]) - A[..., :3, 3]
    S = R_A.sum(axis=-3)
    batch = S.shape[:-2]
    N = np.zeros(batch + (6, 6))
    N[..., :3, :3] = N[..., 3:, 3:] = n * np.eye(3)
    N[..., :3, 3:] = -np.swapaxes(S, -1, -2)
    N[..., 3:, :3] = -S
    rhs = np.concatenate([np.einsum("...kji,...kj->...i", R_A, r), -r.sum(axis=-2)], axis=-1)
    sol = np.linalg.solve(N, rhs[..., None])[..., 0]
    return sol[..., :3], sol[..., 3:]


@register("shah", kind="robot_world", reference="Shah 2013, J. Mech. Robotics 5(3)")
def solve_shah(A: NDArray[np.float64], B: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Solve ``A_i X = Z B_i`` with Shah's Kronecker-product method; returns ``(X, Z)``.

    Vectorised: stacks ``(..., N, 4, 4)`` give ``X, Z`` of shape ``(..., 4, 4)``.
    """
    batch = A.shape[:-3]
    # R_Ai R_X = R_Z R_Bi  <=>  vec(R_Z) = (R_Bi kron R_Ai) vec(R_X)  (column-major vec)
    K = kron_sum(B[..., :3, :3], A[..., :3, :3])
    U, _, Vt = np.linalg.svd(K)
    # u and v share one arbitrary sign; nearest_rotation undoes it for each from its determinant.
    R_X, R_Z = nearest_rotation(np.swapaxes(np.stack([Vt[..., 0, :], U[..., :, 0]]).reshape((2,) + batch + (3, 3)), -1, -2))
    t_X, t_Z = _translations(A, B, R_Z)
    return make_transform(R_X, t_X), make_transform(R_Z, t_Z)


@register("li", kind="robot_world", reference="Li, Wang & Wu 2010, Int. J. Phys. Sci. 5(10)")
def solve_li(A: NDArray[np.float64], B: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Solve ``A_i X = Z B_i`` with Li's linear Kronecker system; returns ``(X, Z)``.

    Vectorised: stacks ``(..., N, 4, 4)`` give ``X, Z`` of shape ``(..., 4, 4)``. The 24-unknown
    system is solved through its normal equations (unit-free after the scaling below).
    """
    batch, n = A.shape[:-3], A.shape[-3]
    R_A, R_B = A[..., :3, :3], B[..., :3, :3]
    scale = np.sqrt(np.mean(np.sum(A[..., :3, 3] ** 2, axis=-1), axis=-1))
    scale = np.where(scale > 0, scale, 1.0)[..., None, None]
    t_A, t_B = A[..., :3, 3] / scale, B[..., :3, 3] / scale
    # Rows of pose k (row-major vec): (R_A kron I) vec(R_X) - (I kron R_B^T) vec(R_Z) = 0 and
    # (I kron t_B^T) vec(R_Z) - R_A t_X + t_Z = t_A. Their normal equations are sums of products
    # that are each one small product of the flattened poses (R^T R = I makes four blocks n I):
    #   XZ = -sum R_A^T kron R_B^T,  ZZ = n I + I kron sum t_B t_B^T,  Z,tX = -sum (I kron t_B) R_A,
    #   Z,tZ = I kron sum t_B,  tX,tZ = -sum R_A^T;  rhs = [0, vec(sum t_A t_B^T), -sum R_A^T t_A, sum t_A].
    def moments(P, Q):  # sum_k P_k^T Q_k over the poses, P (..., n, p), Q (..., n, q)
        return np.swapaxes(P, -1, -2) @ Q

    N = np.zeros(batch + (24, 24))
    N[..., :9, :9] = N[..., 9:18, 9:18] = n * np.eye(9)
    N[..., :9, 9:18] = -np.swapaxes(kron_sum(R_A, R_B), -1, -2)  # kron(P, Q)^T = kron(P^T, Q^T)
    N[..., 9:18, 9:18] += kron_eye(moments(t_B, t_B))
    N[..., 9:18, 18:21] = -kron_eye_vec_sum(t_B, R_A)
    N[..., 9:18, 21:24] = kron_eye(t_B.sum(axis=-2)[..., :, None])
    N[..., 18:21, 18:21] = N[..., 21:24, 21:24] = n * np.eye(3)
    N[..., 18:21, 21:24] = -np.swapaxes(R_A.sum(axis=-3), -1, -2)
    upper = np.triu(np.ones((24, 24), bool), 1)
    N = np.where(upper, N, np.swapaxes(N, -1, -2))  # the lower triangle mirrors the upper
    rhs = np.zeros(batch + (24,))
    rhs[..., 9:18] = moments(t_A, t_B).reshape(batch + (9,))
    rhs[..., 18:21] = -np.einsum("...kij,...ki->...j", R_A, t_A)
    rhs[..., 21:24] = t_A.sum(axis=-2)
    sol = np.linalg.solve(N, rhs[..., None])[..., 0]
    R_X, R_Z = nearest_rotation(np.stack([sol[..., :9], sol[..., 9:18]]).reshape((2,) + batch + (3, 3)))
    t_X, t_Z = _translations(A, B, R_Z)
    return make_transform(R_X, t_X), make_transform(R_Z, t_Z)
