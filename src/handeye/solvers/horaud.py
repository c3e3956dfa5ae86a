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
``f2 = sum |R t_B - (R_A - I) t - t_A|^2``, by Levenberg-Marquardt on a rotation vector about the
closed-form start instead of the thesis's quaternion with a norm penalty (vectorised over runs,
so the simulation study does not loop; checked against ``scipy.optimize.least_squares`` in the tests). The
weights make both terms unitless: ``lambda_k = 1 / mean residual^2`` of each term at the start.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..frames.motions import MotionSet
from ..geometry.dualquat import qmul_matrix, quat_to_matrix
from ..geometry.se3 import make_transform, skew, so3_left_jacobian
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


#: ``Q(e_c)^T W(e_d)`` for the unit quaternions ``e_c, e_d``, so that
#: ``Q(a)^T W(b) = sum_cd a_c b_d _QW_BASIS[c, d]``.
_QW_BASIS = np.einsum("cki,dkj->cdij", qmul_matrix(np.eye(4)), _qmul_right_matrix(np.eye(4)))


def closed_form_rotation(motions: MotionSet) -> NDArray[np.float64]:
    """The closed-form rotation of Horaud-Dornaika (eigenvector of the summed 4x4 matrix)."""
    # sum D^T D with D = Q(a) - W(b) (a, b: the rotation quaternions): Q(a)^T Q(a) = |a|^2 I (and
    # W likewise), and Q(a)^T W(b) is bilinear, so the cross term is the 4x4 moment sum a b^T
    # contracted with a constant tensor: both read off the motions' moment matrix.
    Y = motions.dq_moments
    cross = np.einsum("...cd,cdij->...ij", Y[..., :4, 8:12], _QW_BASIS)
    norms = np.trace(Y[..., :4, :4], axis1=-2, axis2=-1) + np.trace(Y[..., 8:12, 8:12], axis1=-2, axis2=-1)
    _, vecs = np.linalg.eigh(norms[..., None, None] * np.eye(4) - cross - np.swapaxes(cross, -1, -2))
    return quat_to_matrix(vecs[..., :, 0])


@register("horaud", reference="Horaud & Dornaika 1995, IJRR 14(3); thesis §2.2.2 (R then t)")
def solve(motions: MotionSet) -> NDArray[np.float64]:
    """Solve ``A X = X B``: closed-form quaternion rotation, then translation.

    Vectorised: a batch of motion sets ``(..., K, 8)`` gives ``X`` of shape ``(..., 4, 4)``.
    """
    R_X = closed_form_rotation(motions)
    return make_transform(R_X, translation_least_squares(motions, R_X))


#: Levenberg-Marquardt stops when a step changes the unknowns by less than this (relative).
_XTOL = 1e-14
_MAX_ITER = 100


@register("horaud_nonlinear", reference="Horaud & Dornaika 1995, IJRR 14(3); thesis §2.2.2 (R and t)")
def solve_nonlinear(motions: MotionSet) -> NDArray[np.float64]:
    """Solve ``A X = X B`` for rotation and translation together (see the module docstring).

    Levenberg-Marquardt with the analytic Jacobian, written over a batch of runs at once (six
    unknowns per run): a single problem is a batch of one, so both give the same numbers.
    """
    batch, k = motions.batch_shape, len(motions)
    flat = MotionSet(motions.dq_a.reshape(-1, k, 8), motions.dq_b.reshape(-1, k, 8))
    X0 = solve(flat)
    R0, t = X0[:, :3, :3], X0[:, :3, 3].copy()
    a, b = flat.dq_a[..., 1:4], flat.dq_b[..., 1:4]
    C = flat.R_A - np.eye(3)
    t_A, t_B = flat.t_A, flat.t_B
    S = len(R0)

    def rotation(phi):
        return Rotation.from_rotvec(phi).as_matrix() @ R0

    def residuals(R, t):
        r1 = a - np.einsum("sij,skj->ski", R, b)
        r2 = np.einsum("sij,skj->ski", R, t_B) - np.einsum("skij,sj->ski", C, t) - t_A
        return r1, r2

    phi = np.zeros((S, 3))
    R = R0.copy()
    r1, r2 = residuals(R, t)
    tiny = 1e-30
    # both terms made unitless: lambda_k = 1 / mean residual^2 of each at the start
    w1 = 1.0 / np.sqrt(np.maximum(np.mean(r1**2, axis=(1, 2)), tiny))[:, None, None]
    w2 = 1.0 / np.sqrt(np.maximum(np.mean(r2**2, axis=(1, 2)), tiny))[:, None, None]

    def cost(r1, r2):
        return np.sum((w1 * r1) ** 2, axis=(1, 2)) + np.sum((w2 * r2) ** 2, axis=(1, 2))

    f = cost(r1, r2)
    lam = np.full(S, 1e-3)
    active = np.ones(S, bool)
    for _ in range(_MAX_ITER):
        if not active.any():
            break
        Jl = so3_left_jacobian(phi)[:, None]
        J = np.zeros((S, k, 6, 6))
        # d(-R b)/dphi = [R b]x J_l ; d(R t_B)/dphi = -[R t_B]x J_l ; d r2/dt = -(R_A - I)
        J[:, :, :3, :3] = w1[..., None] * (skew(np.einsum("sij,skj->ski", R, b)) @ Jl)
        J[:, :, 3:, :3] = -w2[..., None] * (skew(np.einsum("sij,skj->ski", R, t_B)) @ Jl)
        J[:, :, 3:, 3:] = -w2[..., None] * C
        r = np.concatenate([w1 * r1, w2 * r2], axis=2)
        JtJ = np.einsum("skri,skrj->sij", J, J)
        g = np.einsum("skri,skr->si", J, r)
        damped = JtJ + lam[:, None, None] * (np.eye(6) * np.maximum(np.diagonal(JtJ, axis1=1, axis2=2), 1e-30)[:, None, :])
        step = -np.linalg.solve(damped, g[..., None])[..., 0]
        step[~active] = 0.0
        phi_new, t_new = phi + step[:, :3], t + step[:, 3:]
        R_new = rotation(phi_new)
        n1, n2 = residuals(R_new, t_new)
        f_new = cost(n1, n2)
        better = active & (f_new < f)
        phi[better], t[better], R[better] = phi_new[better], t_new[better], R_new[better]
        r1[better], r2[better], f[better] = n1[better], n2[better], f_new[better]
        lam = np.where(better, np.maximum(lam / 3.0, 1e-12), lam * 4.0)
        size = np.linalg.norm(np.concatenate([phi, t], axis=1), axis=1) + 1e-12
        small_step = np.linalg.norm(step, axis=1) <= _XTOL * size
        active &= ~(small_step | (lam > 1e12) | (f <= tiny))
    return make_transform(R, t).reshape(batch + (4, 4))
