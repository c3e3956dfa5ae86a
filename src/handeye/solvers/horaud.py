"""Horaud-Dornaika (1995): unit-quaternion rotation (closed form), and rotation + translation
together (nonlinear).

R. Horaud, F. Dornaika, "Hand-eye calibration", IJRR 14(3), 1995; thesis §2.2.2.

Closed form ("R then t"): ``q_A q_X = q_X q_B`` is linear in ``q_X``: ``(Q(q_A) - W(q_B)) q_X = 0``
with ``Q``/``W`` the left/right multiplication matrices. ``q_X`` is the eigenvector of the smallest
eigenvalue of ``sum (Q(q_A) - W(q_B))^T (Q(q_A) - W(q_B))`` (thesis: ``A q = lambda q``), then the
translation by least squares (eq. 2.4).

The thesis writes the rotation term ``f1`` with the unit rotation axes ``v, v'``; like OpenCV we use
the full unit quaternions, whose vector parts are the axes scaled by ``sin(theta/2)``: a motion
with a small, noisy rotation then weighs little instead of as much as a large one.

Nonlinear ("R and t"): minimise ``lambda1 f1 + lambda2 f2`` (thesis eq. 2.10) with
``f1 = sum |a - R b|^2`` (a, b: quaternion vector parts of A, B) and
``f2 = sum |R t_B - (R_A - I) t - t_A|^2``, with ``scipy.optimize.least_squares`` on a rotation
vector about the closed-form start instead of the thesis's quaternion with a norm penalty. The
weights make both terms unitless: ``lambda_k = 1 / mean residual^2`` of each term at the start.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ..geometry.dualquat import quat_to_matrix, qmul_matrix
from ..geometry.se3 import make_transform, skew
from ..motions import MotionSet
from ._common import translation_least_squares
from ._registry import register


def _qmul_right_matrix(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Right-multiplication matrices ``W(q)`` with ``W(q) @ p == qmul(p, q)``, shape (..., 4, 4)."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            np.stack([w, -x, -y, -z], axis=-1),
            np.stack([x, w, z, -y], axis=-1),
            np.stack([y, -z, w, x], axis=-1),
            np.stack([z, y, -x, w], axis=-1),
        ],
        axis=-2,
    )


def closed_form_rotation(motions: MotionSet) -> NDArray[np.float64]:
    """The closed-form rotation of Horaud-Dornaika (eigenvector of the summed 4x4 matrix)."""
    D = qmul_matrix(motions.dq_a[:, :4]) - _qmul_right_matrix(motions.dq_b[:, :4])
    Ds = D.reshape(-1, 4)
    _, vecs = np.linalg.eigh(Ds.T @ Ds)
    return quat_to_matrix(vecs[:, 0])


@register("horaud", reference="Horaud & Dornaika 1995, IJRR 14(3); thesis §2.2.2 (R then t)")
def solve(motions: MotionSet) -> NDArray[np.float64]:
    """Solve ``A X = X B``: closed-form quaternion rotation, then translation."""
    R_X = closed_form_rotation(motions)
    return make_transform(R_X, translation_least_squares(motions, R_X))


def _left_jacobian(phi: NDArray[np.float64]) -> NDArray[np.float64]:
    """Left Jacobian of SO(3): ``d exp(phi) v / d phi = -[exp(phi) v]x J_l(phi)``."""
    th = np.linalg.norm(phi)
    K = skew(phi)
    if th < 1e-8:
        return np.eye(3) + 0.5 * K
    return np.eye(3) + (1 - np.cos(th)) / th**2 * K + (th - np.sin(th)) / th**3 * (K @ K)


@register("horaud_nonlinear", reference="Horaud & Dornaika 1995, IJRR 14(3); thesis §2.2.2 (R and t)")
def solve_nonlinear(motions: MotionSet) -> NDArray[np.float64]:
    """Solve ``A X = X B`` for rotation and translation together (see the module docstring)."""
    X0 = solve(motions)
    R0, t0 = X0[:3, :3], X0[:3, 3]
    a, b = motions.dq_a[:, 1:4], motions.dq_b[:, 1:4]
    C = motions.R_A - np.eye(3)
    t_A, t_B = motions.t_A, motions.t_B
    n = len(motions)

    def parts(x):
        R = Rotation.from_rotvec(x[:3]).as_matrix() @ R0
        r1 = a - b @ R.T
        r2 = t_B @ R.T - np.einsum("kij,j->ki", C, x[3:]) - t_A
        return R, r1, r2

    _, r1, r2 = parts(np.r_[np.zeros(3), t0])
    tiny = 1e-30
    w1 = 1.0 / np.sqrt(max(np.mean(r1**2), tiny))
    w2 = 1.0 / np.sqrt(max(np.mean(r2**2), tiny))

    def fun(x):
        _, r1, r2 = parts(x)
        return np.concatenate([w1 * r1.ravel(), w2 * r2.ravel()])

    def jac(x):
        R, _, _ = parts(x)
        Jl = _left_jacobian(x[:3])
        J = np.zeros((6 * n, 6))
        # d(-R b)/dphi = [R b]x J_l ; d(R t_B)/dphi = -[R t_B]x J_l ; d r2/dt = -(R_A - I)
        J[: 3 * n, :3] = w1 * (skew(b @ R.T) @ Jl).reshape(-1, 3)
        J[3 * n :, :3] = -w2 * (skew(t_B @ R.T) @ Jl).reshape(-1, 3)
        J[3 * n :, 3:] = -w2 * C.reshape(-1, 3)
        return J

    res = least_squares(fun, np.r_[np.zeros(3), t0], jac=jac, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    R, _, _ = parts(res.x)
    return make_transform(R, res.x[3:])
