"""Andreff-Horaud-Espiau (1999): AX = XB as one linear system via the Kronecker product.

N. Andreff, R. Horaud, B. Espiau, "On-line hand-eye calibration", 3DIM 1999.

With row-major ``vec``: ``R_A R_X R_B^T = R_X`` gives ``(I9 - R_A kron R_B) vec(R_X) = 0`` and the
translation equation gives ``(I3 kron t_B^T) vec(R_X) + (I3 - R_A) t_X = t_A``: 12 unknowns, 12
equations per motion, solved in the least-squares sense; the 3x3 estimate is then projected onto
the nearest rotation and the translation kept.

The 12x12 normal matrix is summed in closed form rather than stacking a 12K x 12 system: with
``K = R_A kron R_B`` orthogonal, ``(I - K)^T (I - K) = 2I - K - K^T``, and every other block is a
moment such as ``sum t_B t_B^T`` or ``sum t_B kron R_A`` (one BLAS product over the motions each).
The normal equations square the condition number: for runs where it exceeds ``NORMAL_COND_MAX``
(motions whose rotation axes are nearly parallel) the stacked system is solved by QR instead.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..frames.motions import MotionSet
from ..geometry.se3 import make_transform
from ._common import kron_eye, nearest_rotation
from ._registry import register

#: Up to this condition number of the 12x12 normal matrix its solution is accurate to ~1e-11 relative;
#: beyond it (measured: 2 motions with axes 1.7 deg apart gave 1.4e-9 m) the stacked system is solved by QR.
NORMAL_COND_MAX = 1e5


def _stacked(R_A, R_B, t_A, t_B):
    """The 12K x 12 system ``M x = y`` of one or more runs (leading axis), as in the module docstring."""
    S, n = R_A.shape[:2]
    M = np.zeros((S, n, 12, 12))
    M[..., :9, :9] = np.eye(9) - np.einsum("skij,skab->skiajb", R_A, R_B).reshape(S, n, 9, 9)
    M[..., 9:, :9] = np.einsum("ac,skd->skacd", np.eye(3), t_B).reshape(S, n, 3, 9)
    M[..., 9:, 9:] = np.eye(3) - R_A
    y = np.zeros((S, n, 12))
    y[..., 9:] = t_A
    return M.reshape(S, 12 * n, 12), y.reshape(S, 12 * n)


@register("andreff", reference="Andreff, Horaud & Espiau 1999, 3DIM")
def solve(motions: MotionSet) -> NDArray[np.float64]:
    """Solve ``A X = X B`` with Andreff's linear Kronecker formulation.

    Vectorised: a batch of motion sets ``(..., K, 8)`` gives ``X`` of shape ``(..., 4, 4)``.
    """
    n = len(motions)
    # every sum over the motions is an entry of moments of the flattened motions (row-major 4x4s,
    # A[3, 3] = B[3, 3] = 1 giving the plain sums): [i, c, j] = sum A[i, c] A[j, 3] and
    # [i, c, 4 + j] = sum A[i, c] B[j, 3] (MotionSet.translation_moments), and sum A[i, c] B[j, e]
    T = motions.translation_moments
    batch = T.shape[:-2]
    T = T.reshape(batch + (4, 4, 8))
    A, B = motions.A, motions.B
    A_flat, B_flat = A.reshape(A.shape[:-2] + (16,)), B.reshape(B.shape[:-2] + (16,))
    M_ab = (np.swapaxes(A_flat, -1, -2) @ B_flat).reshape(batch + (4, 4, 4, 4))
    t_B = B_flat[..., 3:12:4]
    sumRA = T[..., :3, :3, 3]
    sum_tA, sum_tB = T[..., 3, 3, :3], T[..., 3, 3, 4:7]
    sumK = np.swapaxes(M_ab[..., :3, :3, :3, :3], -3, -2).reshape(batch + (9, 9))  # sum kron(R_A, R_B)
    I3 = np.eye(3)
    G = np.zeros(batch + (12, 12))
    G[..., :9, :9] = 2 * n * np.eye(9) - sumK - np.swapaxes(sumK, -1, -2) + kron_eye(np.swapaxes(t_B, -1, -2) @ t_B)
    # sum_k kron(I3, t_B) (I - R_A): [3a + b, c] = sum t_B[b] (I - R_A)[a, c]
    G[..., :9, 9:] = kron_eye(sum_tB[..., :, None]) - np.swapaxes(T[..., :3, :3, 4:7], -1, -2).reshape(batch + (9, 3))
    G[..., 9:, :9] = np.swapaxes(G[..., :9, 9:], -1, -2)
    G[..., 9:, 9:] = 2 * n * I3 - sumRA - np.swapaxes(sumRA, -1, -2)
    rhs = np.zeros(batch + (12,))
    rhs[..., :9] = T[..., :3, 3, 4:7].reshape(batch + (9,))  # sum kron(I3, t_B) t_A
    rhs[..., 9:] = sum_tA - np.einsum("...ici->...c", T[..., :3, :3, :3])  # sum (I - R_A)^T t_A
    sol = np.linalg.solve(G, rhs[..., None])[..., 0]
    lam = np.linalg.eigvalsh(G)
    ill = (lam[..., 0] * NORMAL_COND_MAX < lam[..., -1]).reshape(-1)
    if ill.any():
        R_A, R_B, t_A, t_B = A[..., :3, :3], B[..., :3, :3], A[..., :3, 3], B[..., :3, 3]
        flat = lambda a: a.reshape((-1,) + a.shape[len(batch):])  # noqa: E731
        M, y = _stacked(*(flat(a)[ill] for a in (R_A, R_B, t_A, t_B)))
        Q, R = np.linalg.qr(M)
        qr_sol = np.linalg.solve(R, np.einsum("sji,sj->si", Q, y)[..., None])[..., 0]
        sol = flat(sol).copy()
        sol[ill] = qr_sol
        sol = sol.reshape(batch + (12,))
    return make_transform(nearest_rotation(sol[..., :9].reshape(batch + (3, 3))), sol[..., 9:])
