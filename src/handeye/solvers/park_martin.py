"""Park-Martin (1994): rotation from the log maps by orthogonal Procrustes, then translation.

F. C. Park, B. J. Martin, "Robot sensor calibration: solving AX = XB on the Euclidean group",
IEEE Trans. Robotics and Automation 10(5), 1994.

With ``alpha = log R_A`` and ``beta = log R_B`` (rotation vectors), ``R_A R_X = R_X R_B`` gives
``alpha = R_X beta``; ``R_X`` minimises ``sum |alpha - R_X beta|^2``: with ``M = sum beta alpha^T``,
``R_X = (M^T M)^(-1/2) M^T``, computed here as the SVD polar factor (the same matrix whenever
det > 0, and a proper rotation always). Translation as Tsai-Lenz (thesis eq. 2.4).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..frames.motions import MotionSet
from ..geometry.se3 import make_transform
from ._common import log_rotations, translation_least_squares
from ._registry import register


@register("park_martin", reference="Park & Martin 1994, IEEE TRA 10(5)")
def solve(motions: MotionSet) -> NDArray[np.float64]:
    """Solve ``A X = X B`` with Park and Martin's log-map Procrustes (see the module docstring).

    Vectorised: a batch of motion sets ``(..., K, 8)`` gives ``X`` of shape ``(..., 4, 4)``.
    """
    alpha = log_rotations(motions.dq_a)
    beta = log_rotations(motions.dq_b)
    U, _, Vt = np.linalg.svd(np.swapaxes(alpha, -1, -2) @ beta)  # sum alpha beta^T = M^T
    U[..., :, 2] *= np.sign(np.linalg.det(U @ Vt))[..., None]  # U diag(1, 1, det) Vt
    R_X = U @ Vt
    return make_transform(R_X, translation_least_squares(motions, R_X))
