"""Checks every solver runs before solving: input shapes, and whether the motions determine X
(rotation spread of the motions, observability of X and of leave-one-out runs)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import DegenerateMotionError
from ..frames.motions import MotionSet
from ..frames.poses import validate_transform_pair
from ._common import top_eigenvector

#: A motion whose quaternion vector part |sin(theta/2) l| is below this rotates by < 0.57 deg.
MIN_ROTATION = 5e-3
#: Largest rotation "off" the dominant axis (sin(theta/2) times the sine of the axis deviation)
#: below which all axes count as parallel: X's rotation about that axis is then undetermined.
MIN_AXIS_SPREAD = 5e-3


def validate_motions(A: ArrayLike, B: ArrayLike) -> MotionSet:
    """A :class:`MotionSet` from motion stacks ``A``, ``B`` (same count, 4x4, finite, orthonormal)."""
    A, B = validate_transform_pair(A, B, ("A (robot motions)", "B (camera motions)"), ("robot motions A", "camera motions B"))
    return MotionSet.from_matrices(A, B)


def rotation_spread(dq: NDArray[np.float64], moment: NDArray[np.float64] | None = None) -> tuple[float, float, NDArray[np.float64]]:
    """Largest rotation, largest off-dominant-axis rotation (both as ``sin(theta/2)``) and the
    dominant axis of motions given as dual quaternions ``(K, 8)``. The dominant axis is the
    principal direction of the axis vectors ``v = sin(theta/2) n`` (sign-free). ``moment``:
    ``sum v v^T`` when known (:attr:`~handeye.frames.motions.MotionSet.dq_moments`)."""
    v = dq[:, 1:4]
    e1 = top_eigenvector(v.T @ v if moment is None else moment)
    sq = np.einsum("ki,ki->k", v, v)
    off_sq = np.clip(sq - (v @ e1) ** 2, 0.0, None)
    return float(np.sqrt(sq.max())), float(np.sqrt(off_sq.max())), e1


def rotation_spread_absolute(T: NDArray[np.float64]) -> tuple:
    """``(largest, spread), axis``: the largest rotation, the largest rotation off the dominant
    axis (both as ``sin(theta/2)``) and that axis, of the motions ``R_0^T R_i`` of absolute
    poses ``(..., N, 4, 4)``: what :func:`rotation_spread` computes from quaternions, without
    forming the motions.

    With ``v = sin(theta/2) n``: ``|v|^2 = (3 - tr R) / 4`` and ``v v^T = (R + R^T) / 4 -
    (tr R - 1) / 4 I`` (from ``R = cos(theta) I + 2 v v^T + 2 cos(theta/2) [v]x``), exact for
    every angle and sign-free. So the dominant axis is the top eigenvector of ``sum (R + R^T)``
    and the rotation off it is ``|v|^2 - (e . v)^2 = (1 - e^T R e) / 2``. For ``R = R_0^T R_i``
    each term is a product with the flattened poses: ``tr R = vec R_0 . vec R_i``, ``sum R =
    R_0^T sum R_i``, ``e^T R e = vec(R_0 e e^T) . vec R_i``. ``i = 0`` is the identity: it adds
    nothing. Leading axes: independent sets (robot and camera).
    """
    x = T.reshape(T.shape[:-3] + (-1, 16))
    R0 = T[..., 0, :3, :3]
    # sums over the poses as products with ones: a reduction over a middle axis costs several times more
    total = np.swapaxes(R0, -1, -2) @ (np.ones(x.shape[-2]) @ x).reshape(R0.shape[:-2] + (4, 4))[..., :3, :3]
    e = top_eigenvector(total + np.swapaxes(total, -1, -2))
    # products with vec R_0 and vec(R_0 e e^T), zero outside the rotation block: one matmul
    w = np.zeros(R0.shape[:-2] + (2, 4, 4))
    w[..., 0, :3, :3] = R0
    w[..., 1, :3, :3] = (R0 @ e[..., :, None]) * e[..., None, :]
    smallest = (w.reshape(w.shape[:-3] + (2, 16)) @ np.swapaxes(x, -1, -2)).min(axis=-1)  # min tr R, min e^T R e
    # |v|^2 = (3 - tr R) / 4 and |v|^2 - (e . v)^2 = (1 - e^T R e) / 2
    return np.sqrt(np.maximum((_SPREAD_OFFSET - smallest) * _SPREAD_SCALE, 0.0)).T, e


_SPREAD_OFFSET = np.array([3.0, 1.0])
_SPREAD_SCALE = np.array([0.25, 0.5])


def check_observability(motions: MotionSet | None = None, absolute: NDArray[np.float64] | None = None) -> None:
    """Raise :class:`DegenerateMotionError` when the motions cannot determine ``X``.

    ``AX = XB`` needs at least two motions whose rotation axes are not parallel (thesis §2.2.3:
    the matrix T has rank 5 when all axes are parallel; pure translations leave the rotation free).
    Both the robot and the camera motions are checked, so a consistent pair of inputs is required.
    Takes a :class:`MotionSet`, or ``absolute``: the absolute poses ``A_i, B_i`` as one array
    ``(2, N, 4, 4)``, whose motions ``inv(A_0) A_i`` decide (the robot-world solvers: axes
    parallel relative to pose 0 means parallel between every pair).
    """
    if absolute is not None:
        count = absolute.shape[1] - 1
    else:
        count = len(motions)
    if count < 2:
        raise DegenerateMotionError(
            f"{count} motion(s): hand-eye calibration needs at least 2 motions (3 poses) with "
            f"non-parallel rotation axes"
        )
    if absolute is not None:
        (largest, spread), axis = rotation_spread_absolute(absolute)
        sides = zip(("robot", "camera"), largest.tolist(), spread.tolist(), axis)
    else:
        Y = motions.dq_moments
        sides = ((name, *rotation_spread(dq, Y[o + 1:o + 4, o + 1:o + 4]))
                 for name, dq, o in (("robot", motions.dq_a, 0), ("camera", motions.dq_b, 8)))
    sides = list(sides)
    for name, largest, spread, axis in sides:
        if largest < MIN_ROTATION:
            other, other_largest = next((n, lg) for n, lg, _, _ in sides if n != name)
            if other_largest >= 5 * MIN_ROTATION:  # one side rotates, the other does not: inconsistent data
                raise DegenerateMotionError(
                    f"the {name} motions are (nearly) pure translations (the largest rotation between two poses is "
                    f"{_degrees(largest):.3g} deg) while the {other} motions rotate by up to {_degrees(other_largest):.3g} "
                    f"deg: the {name} poses do not show the rotations the {other} poses do. Check that the camera is "
                    f"fixed where the setup says, that both pose sets come from the same run, and, for a robot that "
                    f"only translates (a gantry), that its rotation readings are not noise"
                )
            raise DegenerateMotionError(
                f"the {name} motions are (nearly) pure translations: the largest rotation between two "
                f"poses is {_degrees(largest):.3g} deg; translations alone "
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


def _degrees(sin_half: float) -> float:
    """The rotation angle (deg) of a quaternion vector part's norm ``sin(theta/2)``."""
    return float(np.degrees(2 * np.arcsin(min(sin_half, 1.0))))


def observable_leave_one_out(motions: MotionSet, groups: NDArray[np.intp], block: int = 2_000_000) -> NDArray[np.bool_]:
    """Per pose ``p``: would :func:`check_observability` pass on the motions without those of
    ``groups[p]`` (see :func:`handeye.solvers.daniilidis.motion_groups`)? All poses at once.

    The same tests as :func:`rotation_spread`, each run's dominant axis from the moment sum minus
    the left-out motions' moments. A test passes when some kept motion passes it, so each run
    counts the motions that pass (against its own axis) and subtracts those it leaves out: no
    (motions x runs) array of values to mask, and the counts over all motions come from
    (motions x runs) blocks of at most about ``block`` entries.
    """
    k = len(motions)
    n_runs = len(groups)
    kept = k - (groups < k).sum(axis=1)
    ok = kept >= 2
    chunk = max(1, block // (k + 1))
    runs_all = np.arange(n_runs)[:, None]
    for dq in (motions.dq_a, motions.dq_b):
        v = dq[:, 1:4]
        sq = np.einsum("ki,ki->k", v, v)
        vg = np.concatenate([v, np.zeros((1, 3))])[groups]
        e = top_eigenvector(v.T @ v - np.swapaxes(vg, -1, -2) @ vg)  # (n_runs, 3)
        # the largest rotation: the same for every run's axis
        rotates = np.append(np.sqrt(sq) >= MIN_ROTATION, False)  # row k pads the groups
        ok &= rotates[:-1].sum() - rotates[groups].sum(axis=1) > 0
        # the rotation off each run's axis (row k of the padding never passes)
        spread = np.zeros((n_runs, k + 1), bool)
        room = sq - MIN_AXIS_SPREAD**2  # off the axis: |v|^2 - (e . v)^2 >= MIN_AXIS_SPREAD^2
        for start in range(0, n_runs, chunk):
            runs = slice(start, min(start + chunk, n_runs))
            along = e[runs] @ v.T
            along *= along
            np.less_equal(along, room, out=spread[runs, :k])
        ok &= np.count_nonzero(spread, axis=1) - np.count_nonzero(spread[runs_all, groups], axis=1) > 0
    return ok
