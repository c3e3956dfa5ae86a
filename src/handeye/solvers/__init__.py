"""Hand-eye solvers behind one signature and one registry.

>>> import handeye
>>> "daniilidis" in handeye.solvers.available()
True

Each family lives in its own module and registers itself on import.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..motions import MotionSet
from ._checks import check_observability, validate_motions
from ._registry import SolverInfo, available, get, register
from . import daniilidis  # noqa: F401  (registers)

__all__ = ["solve", "solve_motions", "available", "get", "register", "SolverInfo"]


def solve(A: ArrayLike, B: ArrayLike, method: str = "daniilidis") -> NDArray[np.float64]:
    """Solve ``A @ X = X @ B`` for ``X`` from relative motions.

    Parameters
    ----------
    A : array_like, shape (K, 4, 4)
        Robot motions (see :func:`handeye.relative_motions` for the convention of each setup).
    B : array_like, shape (K, 4, 4)
        The matching camera motions.
    method : str
        A name from ``handeye.solvers.available("hand_eye")``.

    Returns
    -------
    X : ndarray, shape (4, 4)

    Raises
    ------
    InputMismatchError
        Unknown method, different counts.
    PoseFormatError
        A motion that is not a rigid transform (NaN, non-orthonormal rotation).
    DegenerateMotionError
        Motions that cannot determine ``X`` (fewer than two, all rotation axes parallel, no rotation).
    """
    info = get(method, kind="hand_eye")
    return solve_motions(validate_motions(A, B), method=info.name)


def solve_motions(motions: MotionSet, method: str = "daniilidis") -> NDArray[np.float64]:
    """Solve ``A X = X B`` on an already validated :class:`~handeye.motions.MotionSet`."""
    info = get(method, kind="hand_eye")
    check_observability(motions)
    return info.func(motions)
