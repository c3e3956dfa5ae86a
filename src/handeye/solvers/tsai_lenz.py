"""Tsai-Lenz (1989): rotation from modified Rodrigues vectors, then translation.

R. Y. Tsai, R. K. Lenz, "A new technique for fully autonomous and efficient 3D robotics hand/eye
calibration", IEEE Trans. Robotics and Automation 5(3), 1989; thesis §2.2.1; the notes on AX = XB
for eye-in-hand and eye-to-hand that come with it (the steps below, for both setups).

Steps, with ``P = 2 sin(theta/2) n`` the modified Rodrigues vector of a motion's rotation:

1. least squares over all motions: ``skew(P_A + P_B) P'_X = P_B - P_A``;
2. ``P_X = 2 P'_X / sqrt(1 + |P'_X|^2)``;
3. ``R_X = (1 - |P_X|^2 / 2) I + (P_X P_X^T + sqrt(4 - |P_X|^2) skew(P_X)) / 2``;
4. least squares: ``(R_A - I) t_X = R_X t_B - t_A``.

The thesis (§2.2.1) writes the same system with g (gripper) = A and c (camera) = B. Unlike
OpenCV since its 2024 change, no motion is dropped for having a small rotation: each motion's
equation is already weighted by ``|P_A + P_B| ~ 4 sin(theta/2)``, so small rotations count little.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..frames.motions import MotionSet
from ..geometry.se3 import make_transform, skew
from ._common import translation_least_squares
from ._registry import register


@register("tsai_lenz", reference="Tsai & Lenz 1989; thesis §2.2.1; notes 001")
def solve(motions: MotionSet) -> NDArray[np.float64]:
    """Solve ``A X = X B`` with Tsai and Lenz's two-step method (see the module docstring).

    Vectorised: a batch of motion sets ``(..., K, 8)`` gives ``X`` of shape ``(..., 4, 4)``.
    """
    # With P = 2 v (v: the aligned quaternion vector parts), s = P_A + P_B and d = P_B - P_A, the
    # normal equations of skew(s) p' = d are sum(|s|^2 I - s s^T) p' = sum d x s = 8 sum v_B x v_A:
    # all sums of products of v_A and v_B, read off the motions' moment matrix
    Y = motions.dq_moments
    M_ab = Y[..., 1:4, 9:12]  # sum v_A v_B^T
    M_ss = 4.0 * (Y[..., 1:4, 1:4] + Y[..., 9:12, 9:12] + M_ab + np.swapaxes(M_ab, -1, -2))
    normal = np.trace(M_ss, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) - M_ss
    rhs = 8.0 * np.stack([M_ab[..., 2, 1] - M_ab[..., 1, 2], M_ab[..., 0, 2] - M_ab[..., 2, 0],
                          M_ab[..., 1, 0] - M_ab[..., 0, 1]], axis=-1)
    p_prime = np.linalg.solve(normal, rhs[..., None])[..., 0]
    P_X = 2.0 * p_prime / np.sqrt(1.0 + np.sum(p_prime * p_prime, axis=-1, keepdims=True))
    n2 = np.sum(P_X * P_X, axis=-1)[..., None, None]
    outer = P_X[..., :, None] * P_X[..., None, :]
    R_X = (1.0 - 0.5 * n2) * np.eye(3) + 0.5 * (outer + np.sqrt(np.maximum(4.0 - n2, 0.0)) * skew(P_X))
    return make_transform(R_X, translation_least_squares(motions, R_X))
