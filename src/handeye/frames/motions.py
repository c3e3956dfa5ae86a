"""Absolute poses -> relative motions ``A X = X B``, and per-motion consistency residuals.

Conventions (docs/guide.md, Conventions; derived for both setups in the notes on AX = XB that come with the thesis):

* eye-in-hand, ``X = cam2flange``: ``A = inv(flange2base_j) @ flange2base_i``,
  ``B = target2cam_j @ inv(target2cam_i)``.
* eye-to-hand, ``X = cam2base``: ``A = flange2base_j @ inv(flange2base_i)``, same ``B``.

For ``i < j``, this is exactly what OpenCV's ``calibrateHandEye`` builds from its
``R_gripper2base``/``R_target2cam`` inputs; eye-to-hand maps onto OpenCV by passing the inverted
robot poses (``base2flange``) as ``gripper2base``, which then returns ``cam2base``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from typing import Literal, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import InputMismatchError
from ..geometry.dualquat import dq_conj, dq_from_matrix, dq_mul_pairs, dq_to_matrix, dq_translation, quat_to_matrix
from ..geometry.se3 import invert, pairwise_matmul, screw_parameters
from .poses import validate_transforms
from .setups import check_setup, robot_world_A, robot_world_A_inv, robot_world_dq

__all__ = ["relative_motions", "pair_indices", "screw_congruence", "motion_matrices", "validate_poses", "MotionSet",
           "Pairs", "order_path"]

Pairs = Union[Literal["all", "auto", "consecutive"], ArrayLike]

#: ``pairs='auto'`` takes every pair while they are at most this many motions (141 poses), and
#: beyond that pairs each pose with about ``AUTO_MAX_MOTIONS / N`` others: all pairs grow as N^2
#: (500,000 motions for 1,000 poses) while the information stays that of the N poses.
AUTO_MAX_MOTIONS = 10_000


@lru_cache(maxsize=64)
def _standard_pairs(n_poses: int, pairs: str) -> NDArray[np.intp]:
    if pairs == "auto" and n_poses * (n_poses - 1) // 2 <= AUTO_MAX_MOTIONS:
        return _standard_pairs(n_poses, "all")  # the same array: the all-pairs fast paths recognise it
    if pairs == "all":
        i, j = np.triu_indices(n_poses, k=1)
    elif pairs == "auto":
        # each pose with the poses 1, 2, 4, ... n/2 places further in capture order (cyclic): near
        # and far partners alike, so that large motions are among them whatever the capture order
        strides = np.unique(np.round(np.geomspace(1, n_poses // 2, max(1, AUTO_MAX_MOTIONS // n_poses))).astype(np.intp))
        i = np.repeat(np.arange(n_poses), len(strides))
        j = (i + np.tile(strides, n_poses)) % n_poses
        ij = np.unique(np.sort(np.stack([i, j], axis=1), axis=1), axis=0)  # n/2 apart: each pair once
        i, j = ij[:, 0], ij[:, 1]
    else:
        i = np.arange(n_poses - 1)
        j = i + 1
    ij = np.stack([i, j], axis=1)
    ij.setflags(write=False)  # shared between calls
    return ij


def pair_indices(n_poses: int, pairs: Pairs = "all") -> NDArray[np.intp]:
    """Index pairs ``(i, j)`` of the motions built from ``n_poses`` poses.

    Parameters
    ----------
    n_poses : int
    pairs : {'all', 'auto', 'consecutive'} or array_like of shape (K, 2)
        ``all``: every ``i < j`` (as OpenCV); ``auto``: every pair up to :data:`AUTO_MAX_MOTIONS`
        motions, else each pose with a spread of about ``AUTO_MAX_MOTIONS / N`` others (linear in
        N); ``consecutive``: ``(i, i + 1)``; or explicit pairs.

    Returns
    -------
    ij : ndarray, shape (K, 2)
    """
    if isinstance(pairs, str):
        if pairs in ("all", "auto", "consecutive"):
            return _standard_pairs(n_poses, pairs)
        raise InputMismatchError(f"unknown pairs strategy {pairs!r}; use 'all', 'auto', 'consecutive' or an (K, 2) "
                                 "index array")
    ij = np.asarray(pairs)
    if ij.ndim != 2 or ij.shape[1] != 2 or not np.issubdtype(ij.dtype, np.integer):
        raise InputMismatchError(f"pairs must be 'all', 'auto', 'consecutive' or an integer array (K, 2); got shape {ij.shape}")
    if len(ij) and (ij.min() < 0 or ij.max() >= n_poses):
        raise InputMismatchError(f"pairs index a pose outside 0..{n_poses - 1}")
    if (ij[:, 0] == ij[:, 1]).any():
        raise InputMismatchError("pairs contain a pose paired with itself")
    return ij.astype(np.intp)


def validate_poses(flange2base: ArrayLike, target2cam: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Validated copies of the two absolute pose stacks, which must pair up one to one."""
    flange2base = validate_transforms(flange2base, what="flange2base")
    target2cam = validate_transforms(target2cam, what="target2cam")
    if len(flange2base) != len(target2cam):
        raise InputMismatchError(
            f"{len(flange2base)} robot poses but {len(target2cam)} camera poses: each robot pose needs "
            f"the target pose seen at that moment"
        )
    if len(flange2base) < 2:
        raise InputMismatchError(f"need at least 2 poses to form a motion, got {len(flange2base)}")
    return flange2base, target2cam


def relative_motions(
    flange2base: ArrayLike,
    target2cam: ArrayLike,
    setup: str = "eye_in_hand",
    pairs: Pairs = "all",
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Relative motions ``(A, B)`` with ``A @ X = X @ B`` from absolute poses.

    Parameters
    ----------
    flange2base : array_like, shape (N, 4, 4)
        Robot flange poses as the controller reports them.
    target2cam : array_like, shape (N, 4, 4)
        Target poses in the camera (what ``solvePnP`` returns).
    setup : {'eye_in_hand', 'eye_to_hand'}
    pairs : {'all', 'auto', 'consecutive'} or array_like (K, 2)
        See :func:`pair_indices`.

    Returns
    -------
    A, B : ndarray, shape (K, 4, 4)
        Robot and camera motions, one per pair of :func:`pair_indices`.

    Examples
    --------
    >>> import handeye
    >>> from handeye.simulate import random_scene
    >>> scene = random_scene(5, "eye_to_hand", rng=1)
    >>> A, B = handeye.relative_motions(scene.flange2base, scene.target2cam, setup="eye_to_hand")
    >>> A.shape                                              # all pairs of 5 poses
    (10, 4, 4)
    >>> bool(np.allclose(A @ scene.X, scene.X @ B))         # A X = X B for every motion
    True
    """
    setup = check_setup(setup)
    flange2base, target2cam = validate_poses(flange2base, target2cam)
    ij = pair_indices(len(flange2base), pairs)
    return motion_matrices(flange2base, target2cam, setup, ij)


def _pair_factors(
    flange2base: NDArray[np.float64], target2cam: NDArray[np.float64], setup: str
) -> tuple[tuple[NDArray[np.float64], NDArray[np.float64]], tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """``((G_A, H_A), (G_B, H_B))`` with the motion of pair ``(i, j)`` ``A = G_A[j] @ H_A[i]``,
    ``B = G_B[j] @ H_B[i]``; ``A_ij = inv(A_j) A_i`` with ``A_i`` of the robot-world form (setups)."""
    robot = (robot_world_A_inv(flange2base, setup), robot_world_A(flange2base, setup))
    return robot, (target2cam, invert(target2cam))


def motion_matrices(
    flange2base: NDArray[np.float64], target2cam: NDArray[np.float64], setup: str, ij: NDArray[np.intp]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Motions ``(A, B)`` of the pairs ``ij`` from poses ``(N, 4, 4)``, or from a batch of runs
    ``(S, N, 4, 4)`` (then ``(S, K, 4, 4)``)."""
    i, j = ij[:, 0], ij[:, 1]
    (G_A, H_A), (G_B, H_B) = _pair_factors(flange2base, target2cam, setup)
    if flange2base.ndim == 4:
        return G_A[:, j] @ H_A[:, i], G_B[:, j] @ H_B[:, i]
    return pairwise_matmul(G_A, H_A, j, i), pairwise_matmul(G_B, H_B, j, i)


def _align_signs(dq_a: NDArray[np.float64], dq_b: NDArray[np.float64],
                 nonnegative: bool = False) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Unit dual quaternions with real scalar part >= 0, and b's sign matched to a's (in place).
    ``nonnegative``: both already have real scalar parts >= 0 (as converted from matrices).

    ``q`` and ``-q`` are the same motion, but the equations of AX = XB hold only when a and b carry
    the same sign: their scalar parts (cos(theta/2), -d/2 sin(theta/2)) are equal. ``w >= 0`` fixes
    the sign except near theta = pi, where w ~ 0 and the dual scalar part decides. (OpenCV's
    Daniilidis takes the signs its matrix-to-quaternion branch happens to give, which disagree for
    some motions near 180 deg.)
    """
    # in place: both callers pass arrays they have just built. Signs are applied by multiplying
    # with +-1 (a boolean-mask update gathers and scatters, ~2x slower at thousands of motions).
    if not nonnegative:
        dq_a *= np.where(dq_a[..., :1] < 0, -1.0, 1.0)
        dq_b *= np.where(dq_b[..., :1] < 0, -1.0, 1.0)
    flip = dq_a[..., 0] * dq_b[..., 0] + dq_a[..., 4] * dq_b[..., 4] < 0
    if flip.any():
        dq_b *= np.where(flip, -1.0, 1.0)[..., None]
    # At theta ~ pi both scalar parts can vanish (a half turn with no pitch, e.g. a 180 deg roll
    # about the optical axis) and the rule above is a coin toss. The vector parts v = sin(theta/2) n
    # obey v_a = s R_X v_b, with s = +1 for the right sign, so dot products with any correctly signed
    # motion r agree: (v_a . v_a_r)(v_b . v_b_r) has the sign of s. Summed over the reliable motions
    # that is v_a^T M v_b with M = sum_r v_a_r v_b_r^T: O(K), no X needed; evaluated for the
    # motions near pi only (a few in a thousand among random motions).
    near_pi = dq_a[..., 0] < SIGN_FROM_SCALAR_MIN
    if near_pi.any():
        k = dq_a.shape[-2]
        va, vb = dq_a.reshape(-1, k, 8)[..., 1:4], dq_b.reshape(-1, k, 8)[..., 1:4]
        near = near_pi.reshape(-1, k)
        M = np.swapaxes(va, -1, -2) @ (vb * (~near)[..., None])  # per run
        run, idx = np.nonzero(near)
        a, b, M = va[run, idx], vb[run, idx], M[run]
        score = np.einsum("ni,nij,nj->n", a, M, b)
        # |v| <= 1 for unit quaternions; the product of the norms scales the threshold
        scale = np.einsum("nii->n", np.abs(M)) * np.sqrt(np.einsum("ni,ni->n", a, a) * np.einsum("ni,ni->n", b, b))
        wrong = (np.abs(score) > 1e-6 * scale) & (score < 0)
        if wrong.any():
            sign = np.ones(near.shape)
            sign[run[wrong], idx[wrong]] = -1.0
            dq_b *= sign.reshape(near_pi.shape)[..., None]
    return dq_a, dq_b


#: Below this scalar part (theta above ~174 deg) the sign of a motion's dual quaternion is taken from
#: the other motions (see _align_signs), not from the scalar parts, which noise can flip.
SIGN_FROM_SCALAR_MIN = 0.05


@dataclass
class MotionSet:
    """Motions ``A_k X = X B_k`` in the forms the solvers use.

    A batch of independent problems (e.g. Monte-Carlo runs) is a MotionSet whose arrays carry
    leading axes, ``(S, K, 8)``; the vectorised solvers return one ``X`` per run.

    Attributes
    ----------
    dq_a, dq_b : ndarray (..., K, 8)
        Their unit dual quaternions ``[w x y z, w' x' y' z']`` with ``w >= 0`` and consistent signs
        between each ``a`` and ``b`` (see :func:`_align_signs`).
    pairs : ndarray (K, 2) or None
        The pose indices of each motion, when built from absolute poses.
    A, B : ndarray (..., K, 4, 4)
        Robot and camera motions (properties).
    """

    dq_a: NDArray[np.float64]
    dq_b: NDArray[np.float64]
    pairs: NDArray[np.intp] | None = None
    _AB: tuple[NDArray[np.float64], NDArray[np.float64]] | None = field(default=None, repr=False)
    _poses: tuple | None = field(default=None, repr=False)

    def __len__(self) -> int:
        return self.dq_a.shape[-2]

    @property
    def batch_shape(self) -> tuple[int, ...]:
        """The leading (run) axes: ``()`` for a single problem."""
        return self.dq_a.shape[:-2]

    @property
    def A(self) -> NDArray[np.float64]:
        """Robot motions (K, 4, 4); built on first use (Daniilidis needs only the dual quaternions)."""
        return self._matrices()[0]

    @property
    def B(self) -> NDArray[np.float64]:
        """Camera motions (K, 4, 4)."""
        return self._matrices()[1]

    @cached_property
    def R_A(self) -> NDArray[np.float64]:
        """Robot motion rotations (..., K, 3, 3), from the dual quaternions (no motion matrices needed)."""
        return self._AB[0][..., :3, :3] if self._AB is not None else quat_to_matrix(self.dq_a[..., :4])

    @cached_property
    def t_A(self) -> NDArray[np.float64]:
        """Robot motion translations (..., K, 3)."""
        return self._AB[0][..., :3, 3] if self._AB is not None else dq_translation(self.dq_a)

    @cached_property
    def t_B(self) -> NDArray[np.float64]:
        """Camera motion translations (..., K, 3)."""
        return self._AB[1][..., :3, 3] if self._AB is not None else dq_translation(self.dq_b)

    @cached_property
    def dq_moments(self) -> NDArray[np.float64]:
        """``sum_k y_k y_k^T`` over the motions of ``y = [dq_a, dq_b]``, ``(..., 16, 16)``.

        Every closed-form solver that is quadratic in the dual quaternions (Tsai-Lenz, Horaud,
        Daniilidis) and the observability check read their sums off this one matrix: three BLAS
        products over the motions, computed once per motion set."""
        a, b = self.dq_a, self.dq_b
        aT, bT = np.swapaxes(a, -1, -2), np.swapaxes(b, -1, -2)
        ab = aT @ b
        return np.concatenate([np.concatenate([aT @ a, ab], axis=-1),
                               np.concatenate([np.swapaxes(ab, -1, -2), bT @ b], axis=-1)], axis=-2)

    @cached_property
    def translation_moments(self) -> NDArray[np.float64]:
        """``sum_k vec(A_k) [a_k, b_k]^T`` over the motions, ``(..., 16, 8)``, with ``vec`` the
        row-major 4x4 and ``a``, ``b`` the last columns ``(t, 1)`` of ``A`` and ``B``: entry
        ``[4i + c, j]`` is ``sum A[i, c] A[j, 3]``, ``[4i + c, 4 + j]`` is ``sum A[i, c] B[j, 3]``
        (``A[3, 3] = 1``: row 15 and columns 3, 7 hold the plain sums). The translation step of
        the rotation-first solvers reads its sums off it (a product with 8 columns, not 32)."""
        A = self.A.reshape(self.A.shape[:-2] + (16,))
        B = self.B.reshape(self.B.shape[:-2] + (16,))
        return np.swapaxes(A, -1, -2) @ np.concatenate([A[..., 3::4], B[..., 3::4]], axis=-1)

    @cached_property
    def all_pairs_factors(self) -> tuple | None:
        """``((G_A, H_A), (G_B, H_B))`` with ``A_ij = G_A[j] H_A[i]`` (see :func:`_pair_factors`)
        when the motions are every pair ``i < j`` of absolute poses, else None.

        Sums over all N(N-1)/2 pairs of terms that factor into a j-part and an i-part are then
        O(N) with prefix sums (used by the translation step of the rotation-first solvers)."""
        if self._poses is None:
            return None
        flange2base, target2cam, setup = self._poses
        ij = _standard_pairs(len(flange2base), "all")
        if self.pairs is not ij and not np.array_equal(self.pairs, ij):
            return None
        return _pair_factors(flange2base, target2cam, setup)

    def _matrices(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        if self._AB is None:
            if self._poses is not None:
                flange2base, target2cam, setup = self._poses
                self._AB = motion_matrices(flange2base, target2cam, setup, self.pairs)
            else:  # a set made of dual quaternions alone
                self._AB = (dq_to_matrix(self.dq_a), dq_to_matrix(self.dq_b))
        return self._AB

    @classmethod
    def from_matrices(cls, A: NDArray[np.float64], B: NDArray[np.float64]) -> "MotionSet":
        """From validated motion stacks ``(..., K, 4, 4)`` (rotations exactly orthonormal)."""
        dq_a, dq_b = _align_signs(dq_from_matrix(A, assume_valid=True), dq_from_matrix(B, assume_valid=True),
                                  nonnegative=True)
        return cls(dq_a, dq_b, _AB=(A, B))

    @classmethod
    def from_poses(
        cls, flange2base: NDArray[np.float64], target2cam: NDArray[np.float64], setup: str, pairs: Pairs = "all"
    ) -> "MotionSet":
        """From validated absolute poses.

        The motion dual quaternions are products of the N pose dual quaternions (cheap), not
        conversions of the K motion matrices (K = N(N-1)/2 for all pairs).
        """
        setup = check_setup(setup)
        ij = pair_indices(len(flange2base), pairs)
        i, j = ij[:, 0], ij[:, 1]
        n = len(flange2base)
        dq_fc = dq_from_matrix(np.concatenate([flange2base, target2cam]), assume_valid=True)
        dq_f, dq_c = dq_fc[:n], dq_fc[n:]
        dq_robot = robot_world_dq(dq_f, setup)  # A_i; A_ij = inv(A_j) A_i
        dq_a = dq_mul_pairs(dq_conj(dq_robot), dq_robot, j, i)
        dq_b = dq_mul_pairs(dq_c, dq_conj(dq_c), j, i)
        dq_a, dq_b = _align_signs(dq_a, dq_b)
        return cls(dq_a, dq_b, ij, _poses=(flange2base, target2cam, setup))


def _angle_and_pitch(dq: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rotation angle and translation along the screw axis of unit dual quaternions (w >= 0)."""
    v = dq[:, 1:4]
    vn = np.linalg.norm(v, axis=1)
    theta = 2.0 * np.arctan2(vn, np.abs(dq[:, 0]))
    t = dq_translation(dq)
    tn = np.linalg.norm(t, axis=1)
    pure = theta <= 1e-12  # no screw axis: the motion is a translation of length |t|
    with np.errstate(invalid="ignore", divide="ignore"):
        d = np.where(pure, tn, np.einsum("ni,ni->n", v, t) / np.where(pure, 1.0, vn))
    return theta, d


def screw_congruence(A: "ArrayLike | MotionSet", B: ArrayLike | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per-motion screw-congruence residuals ``|theta_A - theta_B|`` (rad) and ``|d_A - d_B|`` (m).

    ``B = X^-1 A X`` has the same rotation angle and the same translation along its screw axis as
    ``A`` whatever ``X`` is (the scalar parts of the two dual quaternions are equal, thesis §2.2.3),
    so both must be near zero for consistent data; large values point to wrong conventions.
    Takes motion stacks ``A, B`` or a :class:`MotionSet` (then from its dual quaternions).
    """
    if isinstance(A, MotionSet):
        theta_a, d_a = _angle_and_pitch(A.dq_a)
        theta_b, d_b = _angle_and_pitch(A.dq_b)
    else:
        _, _, theta_a, d_a = screw_parameters(A)
        _, _, theta_b, d_b = screw_parameters(B)
    return np.abs(theta_a - theta_b), np.abs(d_a - d_b)


def order_path(flange2base: NDArray[np.float64], metres_per_rad: float = 0.25) -> NDArray[np.intp]:
    """An order of the poses that shortens the robot path: cost = distance + ``metres_per_rad`` x
    rotation angle; nearest neighbour from the first pose, then 2-opt."""
    n = len(flange2base)
    if n < 3:
        return np.arange(n)
    t = flange2base[:, :3, 3]
    R = flange2base[:, :3, :3]
    dpos = np.linalg.norm(t[:, None] - t[None], axis=2)
    cos = np.clip((np.einsum("aji,bji->ab", R, R) - 1) / 2, -1, 1)
    cost = dpos + metres_per_rad * np.arccos(cos)
    order = [0]
    left = set(range(1, n))
    while left:
        k = min(left, key=lambda j: cost[order[-1], j])
        order.append(k)
        left.remove(k)
    improved = True
    while improved:
        improved = False
        for i in range(1, n - 1):
            for j in range(i + 1, n):
                a, b = order[i - 1], order[i]
                c = order[j]
                d = order[j + 1] if j + 1 < n else None
                before = cost[a, b] + (cost[c, d] if d is not None else 0.0)
                after = cost[a, c] + (cost[b, d] if d is not None else 0.0)
                if after < before - 1e-12:
                    order[i:j + 1] = order[i:j + 1][::-1]
                    improved = True
    return np.array(order)
