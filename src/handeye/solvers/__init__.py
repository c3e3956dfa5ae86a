"""Hand-eye solvers behind one signature and one registry.

>>> import handeye
>>> "daniilidis" in handeye.solvers.available()
True

Each family lives in its own module and registers itself on import.
"""

from __future__ import annotations

import re

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import DegenerateMotionError, InputMismatchError, PoseFormatError
from ..frames.motions import MotionSet, Pairs
from ..frames.poses import validate_transform_pair, validate_transforms
from ..frames.setups import constant_transforms, robot_world_inputs
from ..geometry.se3 import mean_transform
from . import andreff, certifiable, daniilidis, horaud, park_martin, robot_world, tsai_lenz  # noqa: F401  (register themselves)
from ._registry import SolverInfo, available, get, register
from .certifiable import Certificate, certify, certify_robot_world
from .observability import check_observability, validate_motions

__all__ = ["closed_form",
           "solve", "solve_batch", "solve_motions", "solve_robot_world", "solve_robot_world_batch", "available", "get", "register",
           "SolverInfo",
           "Certificate", "certify", "certify_robot_world"]


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

    Examples
    --------
    >>> import handeye
    >>> from handeye.simulate import random_scene
    >>> scene = random_scene(6, "eye_in_hand", rng=0)        # noise-free poses
    >>> A, B = handeye.relative_motions(scene.flange2base, scene.target2cam, setup="eye_in_hand")
    >>> X = handeye.solve(A, B, method="daniilidis")
    >>> bool(np.allclose(X, scene.X, atol=1e-9))
    True
    """
    info = get(method, kind="hand_eye")
    return solve_motions(validate_motions(A, B), method=info.name)


def _validate_batch(A: ArrayLike, B: ArrayLike, minimum: int = 2) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Validated (S, K, 4, 4) stacks: same shape, every 4x4 finite and rigid."""
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    for name, M in (("A", A), ("B", B)):
        if M.ndim != 4 or M.shape[-2:] != (4, 4):
            raise InputMismatchError(f"{name}: expected a batch of motion stacks (S runs, K motions, 4, 4), got shape {M.shape}")
    if A.shape != B.shape:
        raise InputMismatchError(f"A has shape {A.shape} but B has {B.shape}; runs and motions must pair up")
    S, K = A.shape[:2]
    if K < minimum:
        what = "motion(s) per run: AX = XB" if minimum == 2 else "pose pair(s) per run: A_i X = Z B_i"
        raise DegenerateMotionError(f"{K} {what} needs at least {minimum} with non-parallel rotation axes")
    try:
        A = validate_transforms(A.reshape(-1, 4, 4), what="A (robot motions)").reshape(S, K, 4, 4)
        B = validate_transforms(B.reshape(-1, 4, 4), what="B (camera motions)").reshape(S, K, 4, 4)
    except PoseFormatError as exc:
        # name the run and motion rather than the flat index
        msg = str(exc)
        m = re.search(r"entry (\d+)", msg)
        if m:
            i = int(m.group(1))
            msg = msg.replace(m.group(0), f"run {i // K}, {'motion' if minimum == 2 else 'pose'} {i % K}")
        raise PoseFormatError(msg) from None
    return A, B


def solve_batch(A: ArrayLike, B: ArrayLike, method: str = "daniilidis") -> NDArray[np.float64]:
    """Solve many independent ``A @ X = X @ B`` problems at once (e.g. Monte-Carlo runs).

    Every solver is vectorised over runs (``horaud_nonlinear`` by a batched Levenberg-Marquardt):
    one set of array operations for all of them, and the same numbers as :func:`solve` run by run.

    Parameters
    ----------
    A, B : array_like, shape (S, K, 4, 4)
        ``S`` runs of ``K`` robot and camera motions each.
    method : str
        A name from ``handeye.solvers.available("hand_eye")``.

    Returns
    -------
    X : ndarray, shape (S, 4, 4)
        Unlike :func:`solve`, no run is checked for observability (a study wants to see what a
        solver does with poor motions); a run the solver cannot solve at all is NaN.

    Raises
    ------
    InputMismatchError
        Unknown method, shapes that are not (S, K, 4, 4) or do not match.
    PoseFormatError
        A motion that is not a rigid transform (its run and index are named).
    """
    info = get(method, kind="hand_eye")
    A, B = _validate_batch(A, B)
    motions = MotionSet.from_matrices(A, B)
    return info.func(motions)


def solve_motions(motions: MotionSet, method: str = "daniilidis") -> NDArray[np.float64]:
    """Solve ``A X = X B`` on an already validated :class:`~handeye.frames.motions.MotionSet`."""
    info = get(method, kind="hand_eye")
    check_observability(motions)
    return _solved(info, motions)


def _solved(info: SolverInfo, *args):
    """``info.func(*args)``, with a linear algebra failure (a singular rotation estimate, a normal
    matrix that is not positive definite) said as what it means for the user."""
    try:
        return info.func(*args)
    except np.linalg.LinAlgError as exc:
        raise DegenerateMotionError(
            f"{info.name} cannot solve these motions ({exc}), although they rotate about several axes: the robot "
            f"and camera motions disagree badly (inverted poses, the other setup, mixed-up pairs: handeye check, or "
            f"handeye.diagnose, names them), or this method fails on them; try method "
            f"'{'tsai_lenz' if info.name == 'daniilidis' else 'daniilidis'}'"
        ) from None


def solve_robot_world(
    A_abs: ArrayLike, B_abs: ArrayLike, method: str = "shah"
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Solve ``A_i @ X = Z @ B_i`` for ``X`` and ``Z`` from absolute poses.

    Parameters
    ----------
    A_abs, B_abs : array_like, shape (N, 4, 4)
        For handeye's setups see :mod:`handeye.solvers.robot_world` (eye-in-hand:
        ``A_i = flange2base_i``, ``B_i = inv(target2cam_i)``).
    method : str
        A name from ``handeye.solvers.available("robot_world")``.

    Returns
    -------
    X, Z : ndarray, shape (4, 4)

    Raises
    ------
    InputMismatchError, PoseFormatError, DegenerateMotionError
        As :func:`solve`; the motions ``inv(A_0) A_i`` and ``inv(B_0) B_i`` must determine X.
    """
    info = get(method, kind="robot_world")
    pair = validate_transform_pair(
        A_abs, B_abs, ("A (absolute robot-side poses)", "B (absolute camera-side poses)"), ("poses A", "poses B")
    )
    if pair.shape[1] < 3:
        raise DegenerateMotionError(f"{pair.shape[1]} pose pair(s): A_i X = Z B_i needs at least 3 with non-parallel rotation axes")
    # Eliminating Z: (A_0^-1 A_i) X = X (B_0^-1 B_i); these N-1 motions decide observability.
    check_observability(absolute=pair)
    return _solved(info, pair[0], pair[1])


def solve_robot_world_batch(
    A_abs: ArrayLike, B_abs: ArrayLike, method: str = "shah"
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Solve many independent ``A_i @ X = Z @ B_i`` problems at once, vectorised over runs.

    Parameters
    ----------
    A_abs, B_abs : array_like, shape (S, N, 4, 4)
        ``S`` runs of ``N`` absolute pose pairs (see :func:`solve_robot_world`).
    method : str
        A name from ``handeye.solvers.available("robot_world")``.

    Returns
    -------
    X, Z : ndarray, shape (S, 4, 4)
        As :func:`solve_batch`, no run is checked for observability; a run whose rotation
        estimate is singular is NaN.
    """
    info = get(method, kind="robot_world")
    A_abs, B_abs = _validate_batch(A_abs, B_abs, minimum=3)
    return info.func(A_abs, B_abs)


def closed_form(flange2base: NDArray[np.float64], target2cam: NDArray[np.float64], setup: str, method: str,
                pairs: Pairs = "auto", motions: MotionSet | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64], MotionSet]:
    """``(X, Z, motions)`` of one solver on validated poses, without refinement or checks: an
    AX = XB solver on the motions of ``pairs`` (Z the mean of the per-pose ``Z_i``), or a
    robot-world one on the poses. ``motions``: those of these poses and ``pairs``, already made and
    found to determine X (:func:`check_observability`), e.g. one set for every closed form on the same poses."""
    checked = motions is not None
    motions = MotionSet.from_poses(flange2base, target2cam, setup, pairs) if motions is None else motions
    if get(method).kind == "robot_world":
        X, Z = solve_robot_world(*robot_world_inputs(flange2base, target2cam, setup), method=method)
    else:
        X = _solved(get(method, kind="hand_eye"), motions) if checked else solve_motions(motions, method=method)
        Z = mean_transform(constant_transforms(X, flange2base, target2cam, setup))
    return X, Z, motions
