"""Andreff-Horaud-Espiau (1999): AX = XB as one linear system via the Kronecker product.

N. Andreff, R. Horaud, B. Espiau, "On-line hand-eye calibration", 3DIM 1999.

With row-major ``vec``: ``R_A R_X R_B^T = R_X`` gives ``(I9 - R_A kron R_B) vec(R_X) = 0`` and the
translation equation gives ``(I3 kron t_B^T) vec(R_X) + (I3 - R_A) t_X = t_A``: 12 unknowns, 12
equations per motion, solved in the least-squares sense (normal equations summed over motions);
the 3x3 estimate is then projected onto the nearest rotation and the translation kept.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..motions import MotionSet
from ._common import assemble, nearest_rotation
from ._registry import register


@register("andreff", reference="Andreff, Horaud & Espiau 1999, 3DIM")
def solve(motions: MotionSet) -> NDArray[np.float64]:
    """Solve ``A X = X B`` with Andreff's linear Kronecker formulation."""
    A, B = motions.A, motions.B
    R_A, R_B = A[:, :3, :3], B[:, :3, :3]
    n = len(A)
    M = np.zeros((n, 12, 12))
    M[:, :9, :9] = np.eye(9) - np.einsum("kij,kab->kiajb", R_A, R_B).reshape(n, 9, 9)
    M[:, 9:, :9] = np.einsum("ij,ka->kija", np.eye(3), B[:, :3, 3]).reshape(n, 3, 9)
    M[:, 9:, 9:] = np.eye(3) - R_A
    y = np.zeros((n, 12))
    y[:, 9:] = A[:, :3, 3]
    Ms = M.reshape(-1, 12)
    sol = np.linalg.lstsq(Ms, y.reshape(-1), rcond=None)[0]
    return assemble(nearest_rotation(sol[:9].reshape(3, 3)), sol[9:])
