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


@register("andreff", reference="Andreff, Horaud & Espiau 1999, 3DIM")
def solve(motions: MotionSet) -> NDArray[np.float64]:
    """Solve ``A X = X B`` with Andreff's linear Kronecker formulation."""
    A, B = motions.A, motions.B
    n = len(A)
    R_A, t_A, t_B = A[:, :3, :3], A[:, :3, 3], B[:, :3, 3]
    I3 = np.eye(3)
    # sum_k kron(R_A, R_B), row-major vec: [3i+a, 3j+b] = sum R_A[i,j] R_B[a,b]
    sumK = (R_A.reshape(n, 9).T @ B[:, :3, :3].reshape(n, 9)).reshape(3, 3, 3, 3).transpose(0, 2, 1, 3).reshape(9, 9)
    sumRA = R_A.sum(axis=0)
    G = np.zeros((12, 12))
    G[:9, :9] = 2 * n * np.eye(9) - sumK - sumK.T + np.kron(I3, t_B.T @ t_B)
    # sum_k kron(I3, t_B) (I - R_A): [3a+b, c] = sum t_B[b] (delta_ac - R_A[a,c])
    tb_ra = (t_B.T @ R_A.reshape(n, 9)).reshape(3, 3, 3)  # [b, a, c]
    cross = np.einsum("b,ac->abc", t_B.sum(axis=0), I3) - tb_ra.transpose(1, 0, 2)
    G[:9, 9:] = cross.reshape(9, 3)
    G[9:, :9] = G[:9, 9:].T
    G[9:, 9:] = 2 * n * I3 - sumRA - sumRA.T
    rhs = np.zeros(12)
    rhs[:9] = (t_A.T @ t_B).reshape(9)  # sum kron(I3, t_B) t_A: [3a+b] = sum t_A[a] t_B[b]
    rhs[9:] = t_A.sum(axis=0) - np.einsum("kji,kj->i", R_A, t_A)  # sum (I - R_A)^T t_A
    sol = np.linalg.solve(G, rhs)
    return make_transform(nearest_rotation(sol[:9].reshape(3, 3)), sol[9:])
