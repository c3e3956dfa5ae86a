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
from ._common import nearest_rotation
from ._registry import register


def _translations(A: NDArray[np.float64], B: NDArray[np.float64], R_Z: NDArray[np.float64]) -> tuple:
    """``t_X, t_Z`` minimising ``sum |R_Ai t_X - t_Z - (R_Z t_Bi - t_Ai)|^2``."""
    n = len(A)
    M = np.zeros((n, 3, 6))
    M[:, :, :3] = A[:, :3, :3]
    M[:, :, 3:] = -np.eye(3)
    rhs = B[:, :3, 3] @ R_Z.T - A[:, :3, 3]
    sol = np.linalg.lstsq(M.reshape(-1, 6), rhs.reshape(-1), rcond=None)[0]
    return sol[:3], sol[3:]


@register("shah", kind="robot_world", reference="Shah 2013, J. Mech. Robotics 5(3)")
def solve_shah(A: NDArray[np.float64], B: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Solve ``A_i X = Z B_i`` with Shah's Kronecker-product method; returns ``(X, Z)``."""
    # R_Ai R_X = R_Z R_Bi  <=>  vec(R_Z) = (R_Bi kron R_Ai) vec(R_X)  (column-major vec)
    K = np.einsum("kij,kab->iajb", B[:, :3, :3], A[:, :3, :3]).reshape(9, 9)
    U, _, Vt = np.linalg.svd(K)
    R_X = nearest_rotation(Vt[0].reshape(3, 3).T)
    R_Z = nearest_rotation(U[:, 0].reshape(3, 3).T)
    # u and v share one arbitrary sign; nearest_rotation undoes it for each from its determinant.
    t_X, t_Z = _translations(A, B, R_Z)
    return make_transform(R_X, t_X), make_transform(R_Z, t_Z)


@register("li", kind="robot_world", reference="Li, Wang & Wu 2010, Int. J. Phys. Sci. 5(10)")
def solve_li(A: NDArray[np.float64], B: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Solve ``A_i X = Z B_i`` with Li's linear Kronecker system; returns ``(X, Z)``."""
    n = len(A)
    R_A, R_B = A[:, :3, :3], B[:, :3, :3]
    scale = float(np.sqrt(np.mean(np.sum(A[:, :3, 3] ** 2, axis=1)))) or 1.0
    t_A, t_B = A[:, :3, 3] / scale, B[:, :3, 3] / scale
    I3 = np.eye(3)
    M = np.zeros((n, 12, 24))
    # row-major vec: vec(R_A R_X) = (R_A kron I) vec(R_X), vec(R_Z R_B) = (I kron R_B^T) vec(R_Z)
    M[:, :9, :9] = np.einsum("kij,ab->kiajb", R_A, I3).reshape(n, 9, 9)
    M[:, :9, 9:18] = -np.einsum("ij,kba->kiajb", I3, R_B).reshape(n, 9, 9)
    # R_Z t_B - R_A t_X + t_Z = t_A
    M[:, 9:, 9:18] = np.einsum("ij,ka->kija", I3, t_B).reshape(n, 3, 9)
    M[:, 9:, 18:21] = -R_A
    M[:, 9:, 21:24] = I3
    y = np.zeros((n, 12))
    y[:, 9:] = t_A
    sol = np.linalg.lstsq(M.reshape(-1, 24), y.reshape(-1), rcond=None)[0]
    R_X = nearest_rotation(sol[:9].reshape(3, 3))
    R_Z = nearest_rotation(sol[9:18].reshape(3, 3))
    t_X, t_Z = _translations(A, B, R_Z)
    return make_transform(R_X, t_X), make_transform(R_Z, t_Z)
