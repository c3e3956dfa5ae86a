"""Rigid transforms as stacks of 4x4 homogeneous matrices.

Every function accepts a single transform ``(4, 4)`` or a stack ``(..., 4, 4)`` and works on the
whole stack at once. A transform named ``a2b`` maps coordinates in frame ``a`` to frame ``b``.

Rotation conversions go through :class:`scipy.spatial.transform.Rotation`; this module only adds
what scipy does not have: batched rigid inverse and composition, and the screw parameters of a
motion (Chasles' theorem; thesis §2.2.3).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from ..errors import InputMismatchError

__all__ = [
    "make_transform",
    "invert",
    "compose",
    "skew",
    "perpendicular_basis",
    "so3_left_jacobian",
    "pairwise_matmul",
    "rotation_angle",
    "rotation_axis_angle",
    "screw_parameters",
    "PITCH_ANGLE",
    "from_rotvec_translation",
    "perturb",
    "to_rotvec_translation",
    "orthonormality_error",
    "random_rotations",
]


def make_transform(rotation: ArrayLike, translation: ArrayLike) -> NDArray[np.float64]:
    """Assemble homogeneous transforms from rotation matrices and translations.

    Parameters
    ----------
    rotation : array_like, shape (..., 3, 3)
        Rotation matrices.
    translation : array_like, shape (..., 3)
        Translations.

    Returns
    -------
    T : ndarray, shape (..., 4, 4)
    """
    R = np.asarray(rotation, dtype=float)
    t = np.asarray(translation, dtype=float)
    batch = R.shape[:-2]
    if t.shape[:-1] != batch:
        batch = np.broadcast_shapes(batch, t.shape[:-1])
    T = np.zeros(batch + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = t
    T[..., 3, 3] = 1.0
    return T


def invert(T: ArrayLike) -> NDArray[np.float64]:
    """Invert rigid transforms using the rotation transpose (exact and cheaper than ``inv``).

    Parameters
    ----------
    T : array_like, shape (..., 4, 4)

    Returns
    -------
    T_inv : ndarray, shape (..., 4, 4)
    """
    T = np.asarray(T, dtype=float)
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    return make_transform(Rt, -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3]))


def compose(*transforms: ArrayLike) -> NDArray[np.float64]:
    """Compose transforms left to right: ``compose(a, b, c) == a @ b @ c`` (broadcast over stacks)."""
    if not transforms:
        raise InputMismatchError("compose() needs at least one transform")
    out = np.asarray(transforms[0], dtype=float)
    for T in transforms[1:]:
        out = out @ np.asarray(T, dtype=float)
    return out


def pairwise_matmul(L: ArrayLike, R: ArrayLike, il: ArrayLike, ir: ArrayLike) -> NDArray[np.float64]:
    """``L[il] @ R[ir]`` for many index pairs into two short stacks ``(n_l, r, c)``, ``(n_r, c, k)``.

    With many pairs (e.g. all N(N-1)/2 of N poses), every product ``L_a R_b`` comes out of one
    matrix product ``(n_l r x c) @ (c x n_r k)`` and the wanted blocks are gathered: one BLAS call
    instead of K small products. With few pairs, the products are formed directly.
    """
    L = np.asarray(L, dtype=float)
    R = np.asarray(R, dtype=float)
    il = np.asarray(il)
    ir = np.asarray(ir)
    (n_l, r, c), (n_r, _, k) = L.shape, R.shape
    if len(il) < 0.25 * n_l * n_r:
        return L[il] @ R[ir]
    if k == 1:
        # matrices times vectors: n_l products (n_r x c) @ (c x r), laid out (n_l, n_r, r) so the
        # gather reads contiguous rows. Batched small products rather than one large one: OpenBLAS
        # spreads a single (n_l r x c x n_r) product over its threads at a cost far above the work.
        prod = np.matmul(R[:, :, 0], np.swapaxes(L, -1, -2))
        return np.take(prod.reshape(n_l * n_r, r), il * n_r + ir, axis=0)[:, :, None]
    prod = L.reshape(n_l * r, c) @ R.transpose(1, 0, 2).reshape(c, n_r * k)
    return prod.reshape(n_l, r, n_r, k).transpose(0, 2, 1, 3)[il, ir]


def perpendicular_basis(e: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Two unit vectors completing the unit vector(s) ``e`` (..., 3) to a right-handed orthonormal
    basis ``(u, w, e)``.

    Examples
    --------
    >>> u, w = perpendicular_basis(np.array([0.0, 0.0, 1.0]))
    >>> bool(np.allclose(np.cross(u, w), [0.0, 0.0, 1.0]))
    True
    """
    e = np.asarray(e, dtype=float)
    helper = np.where(np.abs(e[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    u = np.cross(e, helper)
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    return u, np.cross(e, u)


def skew(v: ArrayLike) -> NDArray[np.float64]:
    """Cross-product matrices: ``skew(v) @ w == cross(v, w)``.

    Parameters
    ----------
    v : array_like, shape (..., 3)

    Returns
    -------
    S : ndarray, shape (..., 3, 3)
    """
    v = np.asarray(v, dtype=float)
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1] = -v[..., 2]
    S[..., 0, 2] = v[..., 1]
    S[..., 1, 0] = v[..., 2]
    S[..., 1, 2] = -v[..., 0]
    S[..., 2, 0] = -v[..., 1]
    S[..., 2, 1] = v[..., 0]
    return S


def so3_left_jacobian(phi: ArrayLike) -> NDArray[np.float64]:
    """Left Jacobians of SO(3) at rotation vectors ``phi`` (..., 3): ``exp(phi + d) = exp(J_l d) exp(phi)``
    to first order, so ``d (exp(phi) v) / d phi = -[exp(phi) v]x J_l(phi)``.

    Below 1e-6 rad the series ``I + K/2 + K^2/6`` is used: the closed form's ``1 - cos`` cancels there.
    """
    phi = np.asarray(phi, dtype=float)
    theta = np.linalg.norm(phi, axis=-1)[..., None, None]
    K = skew(phi)
    small = theta < 1e-6
    t = np.where(small, 1.0, theta)
    c1 = np.where(small, 0.5, (1.0 - np.cos(t)) / t**2)
    c2 = np.where(small, 1.0 / 6.0, (t - np.sin(t)) / t**3)
    return np.eye(3) + c1 * K + c2 * (K @ K)


def _rotations(T_or_R: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rotation blocks of transforms, or the matrices themselves when already 3x3."""
    if T_or_R.shape[-2:] == (4, 4):
        return T_or_R[..., :3, :3]
    if T_or_R.shape[-2:] == (3, 3):
        return T_or_R
    raise InputMismatchError(f"expected (...,3,3) rotations or (...,4,4) transforms, got shape {T_or_R.shape}")


def rotation_axis_angle(T: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rotation axis (unit) and angle in [0, pi] of rotations or transforms.

    The angle is computed from the quaternion with ``2 atan2(|v|, |w|)``, which stays accurate near
    0 and pi (``arccos`` of the trace loses half the digits near 0). For a zero rotation the axis is
    returned as zeros.
    """
    R = _rotations(np.asarray(T, dtype=float))
    batch = R.shape[:-2]
    quat = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_quat(scalar_first=True)
    quat *= np.where(quat[:, :1] < 0, -1.0, 1.0)
    vnorm = np.linalg.norm(quat[:, 1:], axis=1)
    angle = 2.0 * np.arctan2(vnorm, quat[:, 0])
    with np.errstate(invalid="ignore", divide="ignore"):
        axis = np.where(vnorm[:, None] > 0, quat[:, 1:] / vnorm[:, None], 0.0)
    return axis.reshape(batch + (3,)), angle.reshape(batch)


def rotation_angle(T: ArrayLike) -> NDArray[np.float64]:
    """Rotation angle in [0, pi] of rotations ``(..., 3, 3)`` or transforms ``(..., 4, 4)``."""
    return rotation_axis_angle(T)[1]


#: From this rotation angle (rad, 20 deg) a motion's pitch (its translation along the screw axis)
#: is compared in full; below it the axis, and with it the pitch, is set more and more by the poses'
#: noise: with 1 deg of rotation noise per pose the axis of a pure translation points anywhere and
#: its pitch takes any value up to the translation's length (0.5 m: 5 rad in the labelling cost of
#: :func:`handeye.sensors.camera.pnp.symmetry_costs`, beyond a wrong labelling's quarter turn). On
#: ROS-Industrial's 10x10 capture, 24 of its 105 motions turn less; the pitch difference of the
#: others is 1.9% of the motion in the median.
PITCH_ANGLE = 0.35


def screw_parameters(
    T: ArrayLike, eps: float = 1e-12
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Screw parameters of rigid motions (thesis §2.2.3, Chasles' theorem).

    A motion is a rotation by ``theta`` about a line (direction ``l``, moment ``m = c x l`` for any
    point ``c`` on it) followed by a translation ``d`` along that line.

    Parameters
    ----------
    T : array_like, shape (..., 4, 4)
    eps : float
        Below this rotation angle (rad) the screw axis is undefined; the motion is treated as a pure
        translation: ``l`` is the translation direction, ``d = |t|`` and ``m = 0``.

    Returns
    -------
    l : ndarray, shape (..., 3)
        Unit axis direction.
    m : ndarray, shape (..., 3)
        Moment of the axis, ``m = c x l``; ``l . m = 0``.
    theta : ndarray, shape (...)
        Rotation angle in [0, pi].
    d : ndarray, shape (...)
        Translation along the axis (the pitch times theta), ``d = l . t``.
    """
    T = np.asarray(T, dtype=float)
    t = T[..., :3, 3]
    l, theta = rotation_axis_angle(T)
    d = np.einsum("...i,...i->...", l, t)
    # c is the point of the axis closest to the origin; m = c x l (thesis §2.2.3).
    half = 0.5 * theta
    with np.errstate(invalid="ignore", divide="ignore"):
        cot = np.where(theta > eps, np.cos(half) / np.sin(half), 0.0)
    c = 0.5 * (t - d[..., None] * l + cot[..., None] * np.cross(l, t))
    m = np.cross(c, l)
    pure = theta <= eps
    if np.any(pure):
        tn = np.linalg.norm(t, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            tdir = np.where(tn[..., None] > 0, t / tn[..., None], 0.0)
        l = np.where(pure[..., None], tdir, l)
        d = np.where(pure, tn, d)
        m = np.where(pure[..., None], 0.0, m)
    return l, m, theta, d


def _rotvec_matrices(rotvec: ArrayLike) -> NDArray[np.float64]:
    rotvec = np.asarray(rotvec, dtype=float)
    return Rotation.from_rotvec(rotvec.reshape(-1, 3)).as_matrix().reshape(rotvec.shape[:-1] + (3, 3))


def from_rotvec_translation(rotvec: ArrayLike, translation: ArrayLike) -> NDArray[np.float64]:
    """Transforms from rotation vectors (axis * angle, rad) and translations."""
    return make_transform(_rotvec_matrices(rotvec), translation)


def perturb(T: ArrayLike, rotvec: ArrayLike, translation: ArrayLike) -> NDArray[np.float64]:
    """Transforms ``T`` moved by small steps: the rotation ``exp(rotvec)`` applied on the left (about
    the axes of T's reference frame) and ``translation`` added to the origin.

    This is the local parametrisation of every pose update and pose-noise model in handeye:
    ``R' = exp([rotvec]x) R``, ``t' = t + translation`` (broadcast over stacks).
    """
    T = np.asarray(T, dtype=float)
    return make_transform(_rotvec_matrices(rotvec) @ T[..., :3, :3], T[..., :3, 3] + np.asarray(translation, float))


def to_rotvec_translation(T: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rotation vectors (rad) and translations of transforms."""
    T = np.asarray(T, dtype=float)
    rv = Rotation.from_matrix(T[..., :3, :3].reshape(-1, 3, 3)).as_rotvec()
    return rv.reshape(T.shape[:-2] + (3,)), T[..., :3, 3].copy()


_EYE3_FLAT = np.eye(3).ravel()


def orthonormality_error(R: ArrayLike) -> NDArray[np.float64]:
    """Largest absolute entry of ``R^T R - I`` per matrix (0 for an exact rotation)."""
    R = np.asarray(R, dtype=float)
    gram = (np.swapaxes(R, -1, -2) @ R).reshape(R.shape[:-2] + (9,))
    return np.abs(gram - _EYE3_FLAT).max(axis=-1)


def random_rotations(n: int, rng: np.random.Generator) -> NDArray[np.float64]:
    """``n`` rotation matrices drawn uniformly from SO(3) (normalised Gaussian quaternions)."""
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return Rotation.from_quat(q).as_matrix()


def _takes_assume_valid() -> bool:
    try:
        Rotation.from_matrix(np.eye(3), assume_valid=True)
        return True
    except TypeError:  # scipy < 1.17
        return False


_ASSUME_VALID = {"assume_valid": True} if _takes_assume_valid() else {}


def rotation_of_valid(R: ArrayLike) -> Rotation:
    """``Rotation.from_matrix`` of matrices already orthonormal (validated inputs and products of
    them): scipy >= 1.17 then skips its own orthonormalisation, ~20x faster (earlier scipy does it
    all the same)."""
    return Rotation.from_matrix(R, **_ASSUME_VALID)


def mean_transform(T: ArrayLike) -> NDArray[np.float64]:
    """Chordal mean of the rotations (scipy's ``Rotation.mean``) and arithmetic mean of the
    translations of a stack ``(N, 4, 4)`` whose rotations are orthonormal (validated, or products
    of validated ones)."""
    T = np.asarray(T, dtype=float)
    R = rotation_of_valid(T[:, :3, :3]).mean().as_matrix()  # transforms are validated or built from validated ones
    return make_transform(R, T[:, :3, 3].mean(axis=0))
