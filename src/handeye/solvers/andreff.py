"""Andreff-Horaud-Espiau (1999): AX = XB as one linear system via the Kronecker product.

N. Andreff, R. Horaud, B. Espiau, "On-line hand-eye calibration", 3DIM 1999.

With row-major ``vec``: ``R_A R_X R_B^T = R_X`` gives ``(I9 - R_A kron R_B) vec(R_X) = 0`` and the
translation equation gives ``(I3 kron t_B^T) vec(R_X) + (I3 - R_A) t_X = t_A``: 12 unknowns, 12
equations per motion, solved in the least-squares sense; the 3x3 estimate is then projected onto
the nearest rotation and the translation kept.

The 12x12 normal matrix is summed in closed form rather than stacking a 12K x 12 system: with
``K = R_A kron R_B`` orthogonal, ``(I - K)^T (I - K) = 2I - K - K^T``, and every other block is a
moment such as ``sum t_B t_B^T`` or ``sum t_B kron R_A`` (one BLAS product over the motions each).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..geometry.se3 import make_transform
from ..motions import MotionSet
from ._common import nearest_rotation
from ._registry import register


@register("andreff", reference="Andreff, Horaud & Espiau 1999, 3DIM", batched=True)
def solve(motions: MotionSet) -> NDArray[np.float64]:
    """Solve ``A X = X B`` with Andreff's linear Kronecker formulation.

    Vectorised: a batch of motion sets ``(..., K, 8)`` gives ``X`` of shape ``(..., 4, 4)``.
    """
    A, B = motions.A, motions.B
    n = len(motions)
    R_A, R_B, t_A, t_B = A[..., :3, :3], B[..., :3, :3], A[..., :3, 3], B[..., :3, 3]
    batch = R_A.shape[:-3]
    I3 = np.eye(3)
    # sum_k kron(R_A, R_B), row-major vec: [3i+a, 3j+b] = sum R_A[i,j] R_B[a,b]
    sumK = np.einsum("...kij,...kab->...iajb", R_A, R_B).reshape(batch + (9, 9))
    sumRA = R_A.sum(axis=-3)
    G = np.zeros(batch + (12, 12))
    tbtb = np.einsum("...ka,...kb->...ab", t_B, t_B)
    G[..., :9, :9] = (2 * n * np.eye(9) - sumK - np.swapaxes(sumK, -1, -2)
                      + np.einsum("ac,...bd->...abcd", I3, tbtb).reshape(batch + (9, 9)))  # + kron(I3, sum t_B t_B^T)
    # sum_k kron(I3, t_B) (I - R_A): [3a+b, c] = sum t_B[b] (delta_ac - R_A[a,c])
    tb_ra = np.einsum("...kb,...kac->...abc", t_B, R_A)
    cross = np.einsum("...b,ac->...abc", t_B.sum(axis=-2), I3) - tb_ra
    G[..., :9, 9:] = cross.reshape(batch + (9, 3))
    G[..., 9:, :9] = np.swapaxes(G[..., :9, 9:], -1, -2)
    G[..., 9:, 9:] = 2 * n * I3 - sumRA - np.swapaxes(sumRA, -1, -2)
    rhs = np.zeros(batch + (12,))
    rhs[..., :9] = np.einsum("...ka,...kb->...ab", t_A, t_B).reshape(batch + (9,))  # sum kron(I3, t_B) t_A
    rhs[..., 9:] = t_A.sum(axis=-2) - np.einsum("...kji,...kj->...i", R_A, t_A)  # sum (I - R_A)^T t_A
    sol = np.linalg.solve(G, rhs[..., None])[..., 0]
    return make_transform(nearest_rotation(sol[..., :9].reshape(batch + (3, 3))), sol[..., 9:])
