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

How handeye maps its poses onto this form (docs/guide.md, Conventions):

* eye-in-hand: ``flange2base_i @ X = Z @ inv(target2cam_i)`` with ``X = cam2flange``,
  ``Z = target2base``;
* eye-to-hand: ``inv(flange2base_i) @ X = Z @ inv(target2cam_i)`` with ``X = cam2base``,
  ``Z = target2flange``.

OpenCV's ``calibrateRobotWorldHandEye(R_world2cam, ..., R_base2gripper, ...)`` solves the same
equation with ``A_i = world2cam`` (target2cam), ``X = base2world``, ``Z = gripper2cam``,
``B_i = base2gripper``.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_array, sparray

from ..geometry.se3 import make_transform
from ._common import nearest_rotation, solve, svd
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


_EYE3 = np.eye(3)


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
    RA_tB = np.swapaxes(Q[..., 0, :3, :3, 1, :3, 3], -3, -2).reshape(Q.shape[:-6] + (3, 9))  # [i, (j, l)]
    RA_r = (RA_tB @ R_Z.reshape(R_Z.shape[:-2] + (9, 1)))[..., 0] - _sum_RA_tA(Q)
    t_X = solve(n * _EYE3 - (ST @ S) / n, RA_r - (ST @ r_sum[..., None])[..., 0] / n)
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


def _li_rows(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Li's 12 rows ``[J | y]`` (12 x 25) for one pose pair, from its 32 flattened entries ``x``
    (row-major ``A``, then ``B``), unknowns ``[vec(R_X), vec(R_Z), t_X, t_Z]`` (row-major vec):
    ``(R_A kron I) vec(R_X) - (I kron R_B^T) vec(R_Z) = 0`` and ``(I kron t_B^T) vec(R_Z) - R_A t_X
    + t_Z = t_A``. Linear in ``x``: the constant coefficient of ``t_Z`` is carried by ``A[3, 3] = 1``.
    """
    A, B = x[:16].reshape(4, 4), x[16:].reshape(4, 4)
    eye = np.eye(3)
    rows = np.zeros((12, 25))
    rows[:9, :9] = np.kron(A[:3, :3], eye)
    rows[:9, 9:18] = -np.kron(eye, B[:3, :3].T)
    rows[9:, 9:18] = np.kron(eye, B[None, :3, 3])
    rows[9:, 18:21] = -A[:3, :3]
    rows[9:, 21:24] = A[3, 3] * eye
    rows[9:, 24] = A[:3, 3]
    return rows


def _normal_map(rows: Callable[[NDArray[np.float64]], NDArray[np.float64]]) -> sparray:
    """The fixed linear map from the moments of :func:`_moments` (flattened, 1024) to ``sum_k
    [J_k | y_k]^T [J_k | y_k]`` (flattened, 25 x 25) for rows linear in the pose entries: with
    ``[J | y] = sum_m x[m] E_m``, the sum is ``sum_mm' Q[m, m'] E_m^T E_m'``. Sparse (516 of 640,000
    entries for Li): one product per solve, instead of assembling the blocks one by one."""
    E = np.array([rows(unit) for unit in np.eye(32)])
    return csr_array(np.einsum("mab,nac->bcmn", E, E).reshape(625, 1024))


@cache
def _li_normal() -> sparray:
    """Li's normal map (:func:`_normal_map`), derived on first use: ``import handeye`` stays quick."""
    return _normal_map(_li_rows)


#: How many length entries each moment multiplies (0, 1 or 2): scaling lengths by 1/s scales the
#: moment by s^-power.
_LENGTH_POWER = np.add.outer(*(2 * [np.isin(np.arange(32) % 16, (3, 7, 11)).astype(int)])).reshape(1024)


@register("li", kind="robot_world", reference="Li, Wang & Wu 2010, Int. J. Phys. Sci. 5(10)")
def solve_li(A: NDArray[np.float64], B: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Solve ``A_i X = Z B_i`` with Li's linear Kronecker system; returns ``(X, Z)``.

    Vectorised: stacks ``(..., N, 4, 4)`` give ``X, Z`` of shape ``(..., 4, 4)``. The 24-unknown
    system (rows: :func:`_li_rows`) is solved through its normal equations, which are a fixed
    linear map of the poses' moments (unit-free after the scaling below).
    """
    batch, n = A.shape[:-3], A.shape[-3]
    Q = _moments(A, B)
    # Lengths divided by the RMS |t_A|: the moments of the scaled poses.
    scale = np.sqrt(np.einsum("...ii->...", Q[..., 0, :3, 3, 0, :3, 3]) / n)
    Qs = Q.reshape(batch + (1024,)) * (1.0 / np.where(scale > 0, scale, 1.0))[..., None] ** _LENGTH_POWER
    M = (_li_normal() @ Qs.reshape(-1, 1024).T).T.reshape(batch + (25, 25))
    N, rhs = M[..., :24, :24], M[..., :24, 24]
    sol = solve(N, rhs)
    R_X = nearest_rotation(sol[..., :9].reshape(batch + (3, 3)))
    R_Z = nearest_rotation(sol[..., 9:18].reshape(batch + (3, 3)))
    t_X, t_Z = _translations(Q, R_Z, n)
    return make_transform(R_X, t_X), make_transform(R_Z, t_Z)

