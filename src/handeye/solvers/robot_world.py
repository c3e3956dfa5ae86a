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
from ._common import kron_eye, nearest_rotation, solve, svd
from ._registry import register


def _moments(A: NDArray[np.float64], B: NDArray[np.float64]) -> NDArray[np.float64]:
    """Second moments of the flattened poses, ``Q[..., s, i, j, s', k, l] = sum_n P_s[i, j] P_s'[k, l]``
    with ``P_0 = A_n``, ``P_1 = B_n``: one (32 x N) @ (N x 32) product.

    Both methods need nothing else. The bottom-right entry of every pose is 1, so
    ``Q[..., s, i, j, 0, 3, 3]`` are the first moments (``sum R_A``, ``sum t_B``, ...).
    """
    batch, n = A.shape[:-3], A.shape[-3]
    X = np.concatenate([A.reshape(batch + (n, 16)), B.reshape(batch + (n, 16))], axis=-1)
    return (np.swapaxes(X, -1, -2) @ X).reshape(batch + (2, 4, 4, 2, 4, 4))


def _sum_RA_tA(Q: NDArray[np.float64]) -> NDArray[np.float64]:
    """``sum R_A^T t_A`` from the moments: ``[j] = sum_i Q[0, i, j, 0, i, 3]``."""
    return np.einsum("...iji->...j", Q[..., 0, :3, :3, 0, :3, 3])


def _translations(Q: NDArray[np.float64], R_Z: NDArray[np.float64], n: int) -> tuple:
    """``t_X, t_Z`` minimising ``sum |R_Ai t_X - t_Z - r_i|^2``, ``r_i = R_Z t_Bi - t_Ai`` (per run).

    The normal equations of the rows ``[R_Ai, -I]`` are ``n t_X - S^T t_Z = sum R_Ai^T r_i`` and
    ``-S t_X + n t_Z = -sum r_i`` with ``S = sum R_Ai``; eliminating ``t_Z`` leaves one 3x3 system
    (Schur complement): ``(n I - S^T S / n) t_X = sum R_Ai^T r_i - S^T sum r_i / n``. Every sum is
    read off the moments ``Q`` of :func:`_moments`: ``sum R_A^T R_Z t_B`` is
    ``[i] = sum_jl R_Z[j, l] Q[0, j, i, 1, l, 3]``.
    """
    S = Q[..., 0, :3, :3, 0, 3, 3]
    ST = np.swapaxes(S, -1, -2)
    r_sum = (R_Z @ Q[..., 1, :3, 3, 0, 3, 3, None])[..., 0] - Q[..., 0, :3, 3, 0, 3, 3]
    RA_r = np.einsum("...jil,...jl->...i", Q[..., 0, :3, :3, 1, :3, 3], R_Z) - _sum_RA_tA(Q)
    t_X = solve(n * np.eye(3) - (ST @ S) / n, RA_r - (ST @ r_sum[..., None])[..., 0] / n)
    t_Z = ((S @ t_X[..., None])[..., 0] - r_sum) / n
    return t_X, t_Z


@register("shah", kind="robot_world", reference="Shah 2013, J. Mech. Robotics 5(3)")
def solve_shah(A: NDArray[np.float64], B: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Solve ``A_i X = Z B_i`` with Shah's Kronecker-product method; returns ``(X, Z)``.

    Vectorised: stacks ``(..., N, 4, 4)`` give ``X, Z`` of shape ``(..., 4, 4)``.
    """
    batch, n = A.shape[:-3], A.shape[-3]
    Q = _moments(A, B)
    # R_Ai R_X = R_Z R_Bi  <=>  vec(R_Z) = (R_Bi kron R_Ai) vec(R_X)  (column-major vec);
    # sum kron(R_B, R_A)[3i + a, 3j + b] = Q[1, i, j, 0, a, b]
    K = np.swapaxes(Q[..., 1, :3, :3, 0, :3, :3], -3, -2).reshape(batch + (9, 9))
    U, _, Vt = svd(K)
    # u and v share one arbitrary sign; nearest_rotation undoes it for each from its determinant.
    # Column-major vec: the 3x3 of a singular vector is its reshape, transposed.
    R_X = nearest_rotation(np.swapaxes(Vt[..., 0, :].reshape(batch + (3, 3)), -1, -2))
    R_Z = nearest_rotation(np.swapaxes(U[..., :, 0].reshape(batch + (3, 3)), -1, -2))
    t_X, t_Z = _translations(Q, R_Z, n)
    return make_transform(R_X, t_X), make_transform(R_Z, t_Z)


#: Positions of translation entries in the 32 flattened pose entries of :func:`_moments`.
_TRANSLATION_ENTRIES = np.isin(np.arange(32) % 16, (3, 7, 11))
_DIAG24 = np.arange(24)


@register("li", kind="robot_world", reference="Li, Wang & Wu 2010, Int. J. Phys. Sci. 5(10)")
def solve_li(A: NDArray[np.float64], B: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Solve ``A_i X = Z B_i`` with Li's linear Kronecker system; returns ``(X, Z)``.

    Vectorised: stacks ``(..., N, 4, 4)`` give ``X, Z`` of shape ``(..., 4, 4)``. The 24-unknown
    system is solved through its normal equations (unit-free after the scaling below).
    """
    batch, n = A.shape[:-3], A.shape[-3]
    Q = _moments(A, B)
    # Lengths divided by the RMS |t_A|: the moments of the scaled poses, d_a d_b Q_ab.
    scale = np.sqrt(np.einsum("...ii->...", Q[..., 0, :3, 3, 0, :3, 3]) / n)
    d = np.where(_TRANSLATION_ENTRIES, 1.0 / np.where(scale > 0, scale, 1.0)[..., None], 1.0)
    Qs = Q * (d[..., :, None] * d[..., None, :]).reshape(Q.shape)
    # Rows of pose k (row-major vec): (R_A kron I) vec(R_X) - (I kron R_B^T) vec(R_Z) = 0 and
    # (I kron t_B^T) vec(R_Z) - R_A t_X + t_Z = t_A. Their normal equations are sums of products,
    # each read off the moments (R^T R = I makes four blocks n I):
    #   XZ = -sum R_A^T kron R_B^T,  ZZ = n I + I kron sum t_B t_B^T,  Z,tX = -sum (I kron t_B) R_A,
    #   Z,tZ = I kron sum t_B,  tX,tZ = -sum R_A^T;  rhs = [0, vec(sum t_A t_B^T), -sum R_A^T t_A, sum t_A].
    N = np.zeros(batch + (24, 24))
    N[..., _DIAG24, _DIAG24] = n
    # sum kron(R_A, R_B)[3i + a, 3j + b] = Q[0, i, j, 1, a, b]; kron(P, Q)^T = kron(P^T, Q^T)
    N[..., 9:18, :9] = np.swapaxes(-Qs[..., 0, :3, :3, 1, :3, :3], -3, -2).reshape(batch + (9, 9))
    N[..., 9:18, 9:18] += kron_eye(Qs[..., 1, :3, 3, 1, :3, 3])
    # sum kron(I, t_B) R_A [3a + b, c] = sum t_B[b] R_A[a, c] = Q[0, a, c, 1, b, 3]
    N[..., 9:18, 18:21] = np.swapaxes(-Qs[..., 0, :3, :3, 1, :3, 3], -2, -1).reshape(batch + (9, 3))
    N[..., 9:18, 21:24] = kron_eye(Qs[..., 1, :3, 3, 0, 3, 3, None])
    N[..., 21:24, 18:21] = -Qs[..., 0, :3, :3, 0, 3, 3]
    # the blocks below the diagonal mirror those above
    N[..., :9, 9:18] = np.swapaxes(N[..., 9:18, :9], -1, -2)
    N[..., 18:24, 9:18] = np.swapaxes(N[..., 9:18, 18:24], -1, -2)
    N[..., 18:21, 21:24] = np.swapaxes(N[..., 21:24, 18:21], -1, -2)
    rhs = np.zeros(batch + (24,))
    rhs[..., 9:18] = Qs[..., 0, :3, 3, 1, :3, 3].reshape(batch + (9,))
    rhs[..., 18:21] = -_sum_RA_tA(Qs)
    rhs[..., 21:24] = Qs[..., 0, :3, 3, 0, 3, 3]
    sol = solve(N, rhs)
    R_X = nearest_rotation(sol[..., :9].reshape(batch + (3, 3)))
    R_Z = nearest_rotation(sol[..., 9:18].reshape(batch + (3, 3)))
    t_X, t_Z = _translations(Q, R_Z, n)
    return make_transform(R_X, t_X), make_transform(R_Z, t_Z)

