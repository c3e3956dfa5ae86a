"""Tsai-Lenz (1989): rotation from modified Rodrigues vectors, then translation.

R. Y. Tsai, R. K. Lenz, "A new technique for fully autonomous and efficient 3D robotics hand/eye
calibration", IEEE Trans. Robotics and Automation 5(3), 1989; thesis §2.2.1; the notes
``001_...txt`` (the steps below, for both setups).

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

from ..geometry.se3 import make_transform, skew
from ..motions import MotionSet
from ._common import translation_least_squares
from ._registry import register


@register("tsai_lenz", reference="Tsai & Lenz 1989; thesis §2.2.1; notes 001")
def solve(motions: MotionSet) -> NDArray[np.float64]:
    """Solve ``A X = X B`` with Tsai and Lenz's two-step method (see the module docstring).

    Vectorised: a batch of motion sets ``(..., K, 8)`` gives ``X`` of shape ``(..., 4, 4)``.
    """
    P_A = 2.0 * motions.dq_a[..., 1:4]  # 2 sin(theta/2) n, signs aligned between A and B
    P_B = 2.0 * motions.dq_b[..., 1:4]
    s = P_A + P_B
    d = P_B - P_A
    # normal equations of skew(s) p' = d: skew(s)^T skew(s) = |s|^2 I - s s^T, skew(s)^T d = d x s
    normal = np.einsum("...ki,...ki->...", s, s)[..., None, None] * np.eye(3) - np.swapaxes(s, -1, -2) @ s
    p_prime = np.linalg.solve(normal, np.cross(d, s).sum(axis=-2)[..., None])[..., 0]
    P_X = 2.0 * p_prime / np.sqrt(1.0 + np.sum(p_prime * p_prime, axis=-1, keepdims=True))
    n2 = np.sum(P_X * P_X, axis=-1)[..., None, None]
    outer = P_X[..., :, None] * P_X[..., None, :]
    R_X = (1.0 - 0.5 * n2) * np.eye(3) + 0.5 * (outer + np.sqrt(np.maximum(4.0 - n2, 0.0)) * skew(P_X))
    return make_transform(R_X, translation_least_squares(motions, R_X))
