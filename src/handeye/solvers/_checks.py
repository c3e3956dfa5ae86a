"""Checks every solver runs before solving: input shapes, and whether the motions determine X."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import DegenerateMotionError, InputMismatchError
from ..motions import MotionSet
from ..poses import validate_transforms

#: A motion whose quaternion vector part |sin(theta/2) l| is below this rotates by < 0.57 deg.
MIN_ROTATION = 5e-3
#: Largest rotation "off" the dominant axis (sin(theta/2) times the sine of the axis deviation)
#: below which all axes count as parallel: X's rotation about that axis is then undetermined.
MIN_AXIS_SPREAD = 5e-3


def validate_motions(A: ArrayLike, B: ArrayLike) -> MotionSet:
    """A :class:`MotionSet` from motion stacks ``A``, ``B`` (same count, 4x4, finite, orthonormal)."""
    A = validate_transforms(A, what="A (robot motions)")
    B = validate_transforms(B, what="B (camera motions)")
    if len(A) != len(B):
        raise InputMismatchError(f"{len(A)} robot motions A but {len(B)} camera motions B; they come in pairs")
    return MotionSet.from_matrices(A, B)


def _spread(sq: NDArray[np.float64], moment: NDArray[np.float64], along_sq) -> tuple[float, float, NDArray[np.float64]]:
    """Largest rotation, largest off-dominant-axis rotation and the dominant axis, from the motions'
    ``|v|^2`` (``v = sin(theta/2) n``), ``sum v v^T`` and a function giving ``(e . v)^2`` per motion.
    The dominant axis is the principal direction of the axis vectors (sign-free)."""
    _, vecs = np.linalg.eigh(moment)
    e1 = vecs[:, -1]
    off_sq = np.clip(sq - along_sq(e1), 0.0, None)
    return float(np.sqrt(sq.max())), float(np.sqrt(off_sq.max())), e1


def _rotation_spread(dq: NDArray[np.float64]) -> tuple[float, float, NDArray[np.float64]]:
    """:func:`_spread` of motions given as dual quaternions ``(K, 8)``."""
    v = np.ascontiguousarray(dq[:, 1:4].T)  # (3, K): sin(theta/2) * axis, one row per component
    return _spread((v * v).sum(axis=0), v @ v.T, lambda e: (e @ v) ** 2)


def _rotation_spread_matrices(R: NDArray[np.float64]) -> tuple[float, float, NDArray[np.float64]]:
    """:func:`_spread` of motions given as rotation matrices ``(K, 3, 3)``, without quaternions.

    With ``v = sin(theta/2) n``: ``|v|^2 = (3 - tr R) / 4`` and ``v v^T = (R + R^T) / 4 -
    (tr R - 1) / 4 I`` (from ``R = cos(theta) I + 2 v v^T + 2 cos(theta/2) [v]x``); both are
    exact for every angle, and the spread needs nothing else (it is sign-free).
    """
    tr = np.einsum("kii->k", R)
    total = R.sum(axis=0)
    moment = (total + total.T) / 4.0 - ((tr.sum() - len(R)) / 4.0) * np.eye(3)
    # (e . v)^2 = e^T v v^T e = e^T R e / 2 - (tr R - 1) / 4
    return _spread((3.0 - tr) / 4.0, moment, lambda e: R.reshape(-1, 9) @ np.outer(e, e).ravel() / 2.0 - (tr - 1.0) / 4.0)


def check_observability(motions: MotionSet | None = None, rotations: tuple | None = None) -> None:
    """Raise :class:`DegenerateMotionError` when the motions cannot determine ``X``.

    ``AX = XB`` needs at least two motions whose rotation axes are not parallel (thesis §2.2.3:
    the matrix T has rank 5 when all axes are parallel; pure translations leave the rotation free).
    Both the robot and the camera motions are checked, so a consistent pair of inputs is required.
    Takes a :class:`MotionSet`, or ``rotations=(R_A, R_B)``: the motions' rotation matrices.
    """
    if rotations is not None:
        count = len(rotations[0])
        sides = (("robot", _rotation_spread_matrices, rotations[0]), ("camera", _rotation_spread_matrices, rotations[1]))
    else:
        count = len(motions)
        sides = (("robot", _rotation_spread, motions.dq_a), ("camera", _rotation_spread, motions.dq_b))
    if count < 2:
        raise DegenerateMotionError(
            f"{count} motion(s): hand-eye calibration needs at least 2 motions (3 poses) with "
            f"non-parallel rotation axes"
        )
    for name, spread_of, data in sides:
        largest, spread, axis = spread_of(data)
        if largest < MIN_ROTATION:
            raise DegenerateMotionError(
                f"the {name} motions are (nearly) pure translations: the largest rotation between two "
                f"poses is {np.degrees(2 * np.arcsin(min(largest, 1.0))):.3g} deg; translations alone "
                f"cannot determine the camera rotation. Rotate the flange by 20-45 deg about at least "
                f"two different axes between poses"
            )
        if spread < MIN_AXIS_SPREAD:
            ax = np.array2string(axis, precision=3, suppress_small=True)
            raise DegenerateMotionError(
                f"all {name} rotation axes are parallel (to {ax} in the {name} frame): the rotation "
                f"about that axis and the translation along it are undetermined. Add rotations about "
                f"a second axis, at least 30 deg away from it"
            )
