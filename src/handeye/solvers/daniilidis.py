"""Daniilidis (1999): hand-eye calibration with dual quaternions, in one SVD.

K. Daniilidis, "Hand-eye calibration using dual quaternions", IJRR 18(3), 1999; thesis §2.2.3
(derivation), §3.2 (the five steps) and §4.1.2 (implementation).

With ``a``, ``a'`` the vector parts of the unit dual quaternion of the robot motion ``A`` and
``b``, ``b'`` those of the camera motion ``B``, ``A X = X B`` becomes, for the dual quaternion
``(q, q')`` of ``X``, six linear equations per motion (``a q - q b = 0`` and
``(a' q - q b') + (a q' - q' b) = 0``)::

    | a - b    [a + b]x    0      0       | (q )
    | a'- b'   [a'+ b']x   a - b  [a + b]x| (q') = 0

Stacking ``n`` motions gives ``T`` (6n x 8), of rank 6 for noise-free data with non-parallel axes;
its null space is spanned by the last two right singular vectors ``v7 = (u1, v1)``,
``v8 = (u2, v2)`` and ``(q, q') = l1 v7 + l2 v8`` with ``|q| = 1`` and ``q . q' = 0``.

Notes on the seed's text, which has slips the implementation does not follow:

* §2.2.3 writes the unit-norm constraint as ``l2 u1.u1 + 2 l1 l2 u1.u2 + l2^2 u2.u2 = 1`` and the
  orthogonality constraint as ``l1 u1.v1 + ...``: both first terms need ``l1^2``. It then substitutes
  ``s = l1/l2`` "into the first equation"; it is the second (``q . q' = 0``) that becomes the
  quadratic ``s^2 u1.v1 + s (u1.v2 + u2.v1) + u2.v2 = 0``.
* §4.1.2 defines ``s = l2/l1`` (the inverse of §2.2.3), computes ``l2 = sqrt(1/s+)`` where
  ``l2 = 1/sqrt(s^2 u1.u1 + 2 s u1.u2 + u2.u2)`` belongs, and assembles ``q = l1 v7``,
  ``q' = l2 v8`` where the solution is ``(q, q') = l1 v7 + l2 v8``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..errors import DegenerateMotionError
from ..frames.motions import MotionSet
from ..geometry.dualquat import dq_to_matrix
from ..geometry.se3 import skew
from ._registry import register

__all__ = ["solve", "solve_leave_one_out", "motion_groups", "system_matrix", "normal_matrix", "singular_values"]

#: sigma_6 / sigma_1 below this means T has rank < 6 (thesis: rank 5 when all axes are parallel).
RANK_TOL = 1e-9
#: Up to this sigma_1 / sigma_6 the 8x8 normal matrix T^T T is accurate enough (its null vectors
#: carry an error of about eps * cond^2 <= 1e-10); beyond it the SVD of T itself is used.
NORMAL_COND_MAX = 1e3


def system_matrix(motions: MotionSet) -> NDArray[np.float64]:
    """The stacked 6n x 8 matrix ``T`` of the thesis (§2.2.3), one 6x8 block ``S_i`` per motion."""
    blocks = _blocks(motions.dq_a, motions.dq_b)
    return blocks.reshape(blocks.shape[:-3] + (-1, 8))


def _gram_basis() -> NDArray[np.float64]:
    """``F[m, n] = E_m^T E_n`` where ``S = sum_m y_m E_m`` writes a motion's 6x8 block of ``T`` as a
    linear function of ``y = [dq_a, dq_b]`` (16 numbers)."""
    E = np.zeros((16, 6, 8))
    for m in range(16):
        y = np.zeros((1, 16))
        y[0, m] = 1.0
        E[m] = _blocks(y[:, :8], y[:, 8:])[0]
    return np.einsum("mri,nrj->mnij", E, E)


def _blocks(dq_a: NDArray[np.float64], dq_b: NDArray[np.float64]) -> NDArray[np.float64]:
    """The 6x8 blocks ``S_i`` of ``T``, shape (..., n, 6, 8)."""
    diff = dq_a - dq_b
    summ = dq_a + dq_b
    S = np.zeros(diff.shape[:-1] + (6, 8))
    S[..., :3, 0] = diff[..., 1:4]
    S[..., :3, 1:4] = skew(summ[..., 1:4])
    S[..., 3:, 0] = diff[..., 5:8]
    S[..., 3:, 1:4] = skew(summ[..., 5:8])
    S[..., 3:, 4:] = S[..., :3, :4]
    return S


_F = _gram_basis()


def normal_matrix(motions: MotionSet) -> NDArray[np.float64]:
    """``T^T T`` (8x8, or (..., 8, 8) for a batch) without forming ``T``.

    Each block ``S_i`` is linear in the 16 numbers ``y_i = [dq_a, dq_b]``, so
    ``T^T T = sum_i S_i^T S_i`` is a fixed contraction of the 16x16 moment matrix ``sum_i y_i y_i^T``
    (:attr:`~handeye.frames.motions.MotionSet.dq_moments`): BLAS products over the motions and no 6K x 8 array.
    """
    return np.tensordot(motions.dq_moments, _F, axes=2)


def _null_space(normal: NDArray[np.float64], svd_of_runs) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Singular values (descending) and right singular vectors (rows) of ``T``, per run ``(S, 8)``,
    ``(S, 8, 8)``, from the normal matrices ``T^T T`` ``(S, 8, 8)``.

    Ill-conditioned runs: the normal matrix squares the condition number; there the SVD of ``T``
    itself is used, ``svd_of_runs(runs) -> (sigma, vt)``.
    """
    lam, V = np.linalg.eigh(normal)
    sigma = np.sqrt(np.clip(lam[..., ::-1], 0.0, None))
    vt = np.swapaxes(V[..., ::-1], -1, -2).copy()
    redo = np.flatnonzero(sigma[:, 5] <= sigma[:, 0] / NORMAL_COND_MAX)
    if len(redo):
        sigma[redo], vt[redo] = svd_of_runs(redo)
    return sigma, vt


def _svd_of_system(dq_a: NDArray[np.float64], dq_b: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    T = _blocks(dq_a, dq_b)
    return np.linalg.svd(T.reshape(T.shape[:-3] + (-1, 8)), full_matrices=False)[1:]


def singular_values(motions: MotionSet) -> NDArray[np.float64]:
    """The eight singular values of ``T``; two near zero are expected (thesis §3.2, step 2)."""
    return np.linalg.svd(system_matrix(motions), compute_uv=False)


_FAILURES = {
    1: "the Daniilidis system has rank < 6 (singular values {sigma}): the motions do not determine X; "
       "rotate about at least two non-parallel axes",
    2: "the Daniilidis quadratic has no admissible root; the motions are inconsistent",
    3: "the Daniilidis solution has a zero rotation part; the motions are inconsistent",
}


@register("daniilidis", reference="Daniilidis 1999, IJRR 18(3); thesis §2.2.3, §4.1.2")
def solve(motions: MotionSet) -> NDArray[np.float64]:
    """Solve ``A X = X B`` for ``X`` with Daniilidis' dual-quaternion SVD.

    Parameters
    ----------
    motions : MotionSet
        Validated motions, at least two with non-parallel rotation axes; or a batch of motion sets
        (arrays ``(..., K, 8)``), solved all at once.

    Returns
    -------
    X : ndarray, shape (4, 4), or (..., 4, 4) for a batch
        For a batch, runs that cannot be solved are NaN.

    Raises
    ------
    DegenerateMotionError
        Single problem only: when ``T`` has rank below 6 (e.g. all rotation axes parallel).
    """
    batch = motions.batch_shape
    k = len(motions)
    dq_a, dq_b = motions.dq_a.reshape(-1, k, 8), motions.dq_b.reshape(-1, k, 8)
    sigma, vt = _null_space(normal_matrix(motions).reshape(-1, 8, 8), lambda runs: _svd_of_system(dq_a[runs], dq_b[runs]))
    dq, status = _from_null_space(sigma, vt)
    if batch == ():
        if status[0]:
            raise DegenerateMotionError(_FAILURES[int(status[0])].format(sigma=np.array2string(sigma[0], precision=2)))
        return dq_to_matrix(dq[0])
    return _matrices(dq, status).reshape(batch + (4, 4))


def _matrices(dq: NDArray[np.float64], status: NDArray[np.intp]) -> NDArray[np.float64]:
    """``X`` per run from :func:`_from_null_space`; NaN for the runs that failed."""
    X = dq_to_matrix(np.where(status[:, None] == 0, dq, 1.0))
    X[status != 0] = np.nan
    return X


def solve_leave_one_out(motions: MotionSet, groups: NDArray[np.intp]) -> NDArray[np.float64]:
    """Daniilidis' ``X`` with each pose left out in turn: ``(n_poses, 4, 4)``, NaN where unsolvable.

    ``motions`` is one set built from absolute poses, ``groups`` the motions of each pose
    (:func:`motion_groups` of ``motions.pairs``). Leaving pose ``p`` out removes the motions
    that involve it; their moments ``y y^T`` are subtracted from the
    moment sum that :func:`normal_matrix` contracts, so all runs are one batch of 8x8 problems
    instead of a new motion set each (O(K) instead of O(N K)). The motions keep the signs they
    were given with every pose present. No observability check: see
    :func:`handeye.solvers.observability.observable_leave_one_out`.
    """
    y = np.concatenate([motions.dq_a, motions.dq_b], axis=-1)
    Y = np.concatenate([y, np.zeros((1, 16))])[groups]  # (n_poses, most motions of a pose, 16)
    moments = y.T @ y - np.swapaxes(Y, -1, -2) @ Y

    def svd_of_runs(runs):  # one at a time: runs may have different motion counts
        kept = [(motions.pairs != r).all(axis=1) for r in runs]
        out = [_svd_of_system(motions.dq_a[keep], motions.dq_b[keep]) for keep in kept]
        return np.stack([o[0] for o in out]), np.stack([o[1] for o in out])

    return _matrices(*_from_null_space(*_null_space(np.tensordot(moments, _F, axes=2), svd_of_runs)))


def motion_groups(pairs: NDArray[np.intp], n_poses: int) -> NDArray[np.intp]:
    """For motions between poses ``pairs (K, 2)``: ``groups[p]`` lists the motions that involve
    pose ``p``, ``(n_poses, most motions of a pose)``, padded with ``K``."""
    k = len(pairs)
    poses = pairs.T.ravel()
    order = np.argsort(poses, kind="stable")
    poses, motion = poses[order], np.tile(np.arange(k), 2)[order]
    counts = np.bincount(poses, minlength=n_poses)
    starts = np.cumsum(counts) - counts
    groups = np.full((n_poses, int(counts.max(initial=0))), k)
    groups[poses, np.arange(2 * k) - starts[poses]] = motion
    return groups


def _from_null_space(sigma: NDArray[np.float64], vt: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """The unit dual quaternion of ``X`` per run ``(S, 8)`` from the null space of ``T`` and a
    status per run (0: solved, else a key of ``_FAILURES``)."""
    status = np.where(sigma[:, 5] <= RANK_TOL * sigma[:, 0], 1, 0)
    u1, v1 = vt[:, 6, :4], vt[:, 6, 4:]
    u2, v2 = vt[:, 7, :4], vt[:, 7, 4:]
    # q . q' = 0 with (q, q') = l1 v7 + l2 v8 and s = l1 / l2:
    qa = np.sum(u1 * v1, axis=1)
    qb = np.sum(u1 * v2 + u2 * v1, axis=1)
    qc = np.sum(u2 * v2, axis=1)
    disc = np.maximum(qb * qb - 4.0 * qa * qc, 0.0)
    # Both roots as directions (l1, l2), without dividing by a possibly tiny qa.
    h = -0.5 * (qb + np.copysign(np.sqrt(disc), qb))
    roots = [(h, qa), (qc, h)]  # s = h/qa and s = qc/h
    crit = []
    for l1, l2 in roots:
        q = l1[:, None] * u1 + l2[:, None] * u2
        # One root is the spurious null vector (0, q) of T, whose real part vanishes: take the root
        # with the larger |q|^2 per unit (l1, l2). The thesis's criterion, s^2 u1.u1 + 2 s u1.u2 +
        # u2.u2 = |q|^2 / l2^2, assumes l2 != 0 "without loss of generality"; it is not: when the SVD
        # returns the spurious vector itself as v7, that root has l2 ~ 0 and 0/0 can win (measured:
        # 1 noise-free run in 200 at 3 motions came out 180 deg off).
        with np.errstate(divide="ignore", invalid="ignore"):
            f = np.sum(q * q, axis=1) / (l1 * l1 + l2 * l2)
        crit.append(np.where((l1 == 0.0) & (l2 == 0.0), -np.inf, f))
    second = crit[1] > crit[0]
    status = np.where((status == 0) & (crit[0] == -np.inf) & (crit[1] == -np.inf), 2, status)
    l1 = np.where(second, roots[1][0], roots[0][0])
    l2 = np.where(second, roots[1][1], roots[0][1])
    dq = l1[:, None] * vt[:, 6] + l2[:, None] * vt[:, 7]
    norm = np.linalg.norm(dq[:, :4], axis=1)
    status = np.where((status == 0) & ~(np.isfinite(norm) & (norm > 0.0)), 3, status)
    with np.errstate(divide="ignore", invalid="ignore"):
        dq = dq / np.where(dq[:, 0] < 0, -norm, norm)[:, None]
    return dq, status
