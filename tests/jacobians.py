"""The estimation core's Jacobian against central differences of its own residual function (the
joint fits' chained and per-view Jacobians are checked with it: tests/test_kinematics.py, tests/test_rig.py)."""

from __future__ import annotations

import numpy as np

from handeye.estimation.core import Problem, _function, _jacobian


def jacobian_error(problem: Problem, rows: np.ndarray, sigma: np.ndarray, x: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Per column of the core's Jacobian at ``x`` (on ``rows``, noise scales ``sigma``) its distance
    from central differences with steps ``h``, over the differences' own length."""
    J = _jacobian(problem, rows, sigma)(x)
    fun = _function(problem, rows, sigma)
    central = np.empty_like(J)
    for j in range(len(x)):
        e = np.zeros(len(x))
        e[j] = h[j]
        central[:, j] = (fun(x + e) - fun(x - e)) / (2 * h[j])
    return np.linalg.norm(J - central, axis=0) / np.linalg.norm(central, axis=0)
