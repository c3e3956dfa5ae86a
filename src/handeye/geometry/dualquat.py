"""Dual quaternions: the algebra behind the Daniilidis solver (thesis §2.2.3, §4.1.1, appendix B).

A dual quaternion is ``q + eps q'`` with ``eps**2 = 0``; quaternions are stored scalar first,
``(w, x, y, z)``, the thesis's ``(q0, q)``. A unit dual quaternion (``|q| = 1``, ``q . q' = 0``)
represents the rigid transform with rotation ``q`` and translation ``t = 2 q' conj(q)``, i.e.
``q' = t q / 2``.

Two layers:

* batched array functions (``qmul``, ``dq_mul``, ``dq_from_matrix`` ...) on arrays of shape
  ``(..., 4)`` / ``(..., 8)`` for the hot paths of the solvers;
* the :class:`DualQuaternion` class with the API of the thesis's ``DualQuaternion.h`` (§4.1.1).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from ..errors import InputMismatchError
from .se3 import make_transform, pairwise_matmul, rotation_of_valid

__all__ = [
    "DualQuaternion",
    "qmul",
    "qconj",
    "quat_from_matrix",
    "quat_to_matrix",
    "dq_mul",
    "dq_mul_pairs",
    "qmul_matrix",
    "dq_conj",
    "dq_from_matrix",
    "dq_to_matrix",
    "dq_translation",
    "dq_from_rotation_translation",
]


# --- quaternions, scalar first -------------------------------------------------------------

def qmul(p: ArrayLike, q: ArrayLike) -> NDArray[np.float64]:
    """Hamilton products ``p q`` of quaternions ``(..., 4)`` (scalar first), broadcast."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    p0, p1, p2, p3 = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    q0, q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(np.broadcast_shapes(p.shape, q.shape))
    out[..., 0] = p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3
    out[..., 1] = p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2
    out[..., 2] = p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1
    out[..., 3] = p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0
    return out


def qmul_matrix(p: ArrayLike) -> NDArray[np.float64]:
    """Left-multiplication matrices ``L(p)`` with ``L(p) @ q == qmul(p, q)``, shape (..., 4, 4)."""
    p = np.asarray(p, dtype=float)
    w, x, y, z = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    L = np.empty(p.shape[:-1] + (4, 4))
    L[..., 0, 0], L[..., 0, 1], L[..., 0, 2], L[..., 0, 3] = w, -x, -y, -z
    L[..., 1, 0], L[..., 1, 1], L[..., 1, 2], L[..., 1, 3] = x, w, -z, y
    L[..., 2, 0], L[..., 2, 1], L[..., 2, 2], L[..., 2, 3] = y, z, w, -x
    L[..., 3, 0], L[..., 3, 1], L[..., 3, 2], L[..., 3, 3] = z, -y, x, w
    return L


def dq_mul_pairs(p: ArrayLike, q: ArrayLike, ip: ArrayLike, iq: ArrayLike) -> NDArray[np.float64]:
    """``dq_mul(p[ip], q[iq])`` for many index pairs into two short stacks ``(N, 8)``.

    A dual-quaternion product is linear in its right factor, ``p q = L(p) q`` with the 8x8
    ``L(p) = [[Q(p), 0], [Q(p'), Q(p)]]``, so all pairwise products go through one matrix product
    (:func:`~handeye.geometry.se3.pairwise_matmul`).
    """
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    L = np.zeros((len(p), 8, 8))
    L[:, :4, :4] = qmul_matrix(p[:, :4])
    L[:, 4:, :4] = qmul_matrix(p[:, 4:])
    L[:, 4:, 4:] = L[:, :4, :4]
    return pairwise_matmul(L, q[:, :, None], ip, iq)[:, :, 0]


def qconj(q: ArrayLike) -> NDArray[np.float64]:
    """Quaternion conjugates ``(w, -v)``."""
    q = np.array(q, dtype=float)
    q[..., 1:] *= -1.0
    return q


def quat_from_matrix(R: ArrayLike, assume_valid: bool = False) -> NDArray[np.float64]:
    """Unit quaternions (scalar first, ``w >= 0``) of rotation matrices ``(..., 3, 3)``.

    ``assume_valid``: the matrices are already orthonormal (validated by
    :func:`handeye.frames.poses.validate_transforms`), so scipy need not orthonormalise them again (~20x
    faster; scipy >= 1.17, ignored before)."""
    R = np.asarray(R, dtype=float)
    rot = rotation_of_valid(R.reshape(-1, 3, 3)) if assume_valid else Rotation.from_matrix(R.reshape(-1, 3, 3))
    xyzw = rot.as_quat()  # scipy's own array; scalar_first=True would copy it once more
    q = xyzw[:, _WXYZ] * np.where(xyzw[:, 3:] < 0, -1.0, 1.0)
    return q.reshape(R.shape[:-2] + (4,))


_WXYZ = np.array([3, 0, 1, 2])


def quat_to_matrix(q: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrices of quaternions (scalar first; normalised first)."""
    q = np.asarray(q, dtype=float)
    R = Rotation.from_quat(q.reshape(-1, 4), scalar_first=True).as_matrix()
    return R.reshape(q.shape[:-1] + (3, 3))


# --- dual quaternions as (..., 8) arrays: [real wxyz, dual wxyz] ---------------------------

def dq_mul(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Products of dual quaternions ``(..., 8)``: ``(p + eps p')(q + eps q') = pq + eps(pq' + p'q)``."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    real = qmul(a[..., :4], b[..., :4])
    dual = qmul(a[..., :4], b[..., 4:]) + qmul(a[..., 4:], b[..., :4])
    return np.concatenate([real, dual], axis=-1)


def dq_conj(a: ArrayLike) -> NDArray[np.float64]:
    """Quaternion conjugate of both parts, ``conj(q) + eps conj(q')``; the inverse of a unit one."""
    a = np.array(a, dtype=float)
    a[..., 1:4] *= -1.0
    a[..., 5:8] *= -1.0
    return a


def dq_from_rotation_translation(q: ArrayLike, t: ArrayLike) -> NDArray[np.float64]:
    """Unit dual quaternions from unit quaternions ``(..., 4)`` and translations ``(..., 3)``:
    ``q' = (0, t) q / 2``."""
    q = np.asarray(q, dtype=float)
    t = np.asarray(t, dtype=float)
    lead = np.broadcast_shapes(q.shape[:-1], t.shape[:-1])
    q = np.broadcast_to(q, lead + (4,)).reshape(-1, 4)
    t = np.broadcast_to(t, lead + (3,)).reshape(-1, 3)
    # on contiguous component rows: numpy's passes over (M, 4) columns cost several times more
    out = np.empty((8, len(q)))
    out[:4] = q.T
    w, x, y, z = 0.5 * out[:4]
    tx, ty, tz = np.ascontiguousarray(t.T)
    out[4] = -(tx * x + ty * y + tz * z)
    out[5] = w * tx + ty * z - tz * y
    out[6] = w * ty + tz * x - tx * z
    out[7] = w * tz + tx * y - ty * x
    return np.ascontiguousarray(out.T).reshape(lead + (8,))


def dq_from_matrix(T: ArrayLike, assume_valid: bool = False) -> NDArray[np.float64]:
    """Unit dual quaternions (real scalar part >= 0) of transforms ``(..., 4, 4)``;
    ``assume_valid`` as :func:`quat_from_matrix`."""
    T = np.asarray(T, dtype=float)
    return dq_from_rotation_translation(quat_from_matrix(T[..., :3, :3], assume_valid), T[..., :3, 3])


def dq_translation(a: ArrayLike) -> NDArray[np.float64]:
    """Translations ``(..., 3)`` of unit dual quaternions ``(..., 8)``: the vector part of ``2 q' conj(q)``,
    i.e. ``2 (w v' - w' v + v x v')``, computed on contiguous component rows."""
    d = np.ascontiguousarray(np.moveaxis(np.asarray(a, dtype=float), -1, 0))
    w, v, wd, vd = d[0], d[1:4], d[4], d[5:8]
    c = np.empty_like(v)
    c[0] = v[1] * vd[2] - v[2] * vd[1]
    c[1] = v[2] * vd[0] - v[0] * vd[2]
    c[2] = v[0] * vd[1] - v[1] * vd[0]
    return np.moveaxis(2.0 * (w * vd - wd * v + c), 0, -1)


def dq_to_matrix(a: ArrayLike) -> NDArray[np.float64]:
    """Transforms ``(..., 4, 4)`` of unit dual quaternions ``(..., 8)``; ``t = 2 q' conj(q)``."""
    a = np.asarray(a, dtype=float)
    t = 2.0 * qmul(a[..., 4:], qconj(a[..., :4]))[..., 1:]
    return make_transform(quat_to_matrix(a[..., :4]), t)


def _dq_exp(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """exp of dual quaternions ``(..., 8)``.

    The dual scalar part commutes with everything, so ``exp(s + v) = exp(s) exp(v)``; for the pure
    part ``v + eps v'`` with ``phi = |v|``: ``exp = (cos phi, sinc(phi) v)
    + eps(-(v.v') sinc(phi), sinc(phi) v' + (v.v') c(phi) v)`` with ``c = (cos phi - sinc phi)/phi^2``.
    """
    s, sd = a[..., 0], a[..., 4]
    v, vd = a[..., 1:4], a[..., 5:8]
    phi = np.linalg.norm(v, axis=-1)
    sinc = np.sinc(phi / np.pi)
    small = phi < 1e-4
    phi2 = np.where(small, 1.0, phi * phi)
    c = np.where(small, -1.0 / 3.0 + phi * phi / 30.0, (np.cos(phi) - sinc) / phi2)
    vvd = np.sum(v * vd, axis=-1)
    real = np.concatenate([np.cos(phi)[..., None], sinc[..., None] * v], axis=-1)
    dual = np.concatenate(
        [(-vvd * sinc)[..., None], sinc[..., None] * vd + (vvd * c)[..., None] * v], axis=-1
    )
    # exp of the dual number s + eps sd is e^s (1 + eps sd)
    es = np.exp(s)[..., None]
    return np.concatenate([es * real, es * (dual + sd[..., None] * real)], axis=-1)


def _dq_log(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """log of unit dual quaternions ``(..., 8)``: the pure dual quaternion ``theta_dual/2 * l_dual``.

    Inverse of :func:`_dq_exp` on pure arguments; defined for rotation angles below 2 pi (real
    scalar part > -1).
    """
    w, v = a[..., 0], a[..., 1:4]
    wd, vd = a[..., 4], a[..., 5:8]
    vn = np.linalg.norm(v, axis=-1)
    phi = np.arctan2(vn, w)
    sinc = np.sinc(phi / np.pi)
    small = phi < 1e-4
    phi2 = np.where(small, 1.0, phi * phi)
    c = np.where(small, -1.0 / 3.0 + phi * phi / 30.0, (np.cos(phi) - sinc) / phi2)
    u = v / sinc[..., None]
    uud = -wd / sinc
    ud = (vd - (uud * c)[..., None] * u) / sinc[..., None]
    zero = np.zeros_like(w)[..., None]
    return np.concatenate([zero, u, zero, ud], axis=-1)


class DualQuaternion:
    """A dual quaternion ``q + eps q'``, the API of the thesis's ``DualQuaternion.h`` (§4.1.1).

    Parameters
    ----------
    real : array_like, shape (4,)
        The real part ``q`` (scalar first ``w, x, y, z``).
    dual : array_like, shape (4,)
        The dual part ``q'``.

    Notes
    -----
    Unit dual quaternions represent rigid transforms: ``q`` is the rotation and ``q' = t q / 2``.
    ``q`` and ``-q`` represent the same transform; constructors from transforms return the one with
    a non-negative real scalar part (thesis §2.2.3).

    Examples
    --------
    >>> import numpy as np
    >>> from handeye import DualQuaternion
    >>> dq = DualQuaternion.from_rotation_translation([1, 0, 0, 0], [0.1, 0.2, 0.3])
    >>> np.allclose(dq.transform_point([0, 0, 0]), [0.1, 0.2, 0.3])
    True
    """

    __slots__ = ("_q",)

    def __init__(self, real: ArrayLike = (1.0, 0.0, 0.0, 0.0), dual: ArrayLike = (0.0, 0.0, 0.0, 0.0)):
        real = np.asarray(real, dtype=float)
        dual = np.asarray(dual, dtype=float)
        if real.shape != (4,) or dual.shape != (4,):
            raise InputMismatchError(f"real and dual must be 4-vectors (w, x, y, z); got {real.shape}, {dual.shape}")
        self._q = np.concatenate([real, dual])

    # --- constructors
    @classmethod
    def from_array(cls, a: ArrayLike) -> "DualQuaternion":
        """From an 8-vector ``[w, x, y, z, w', x', y', z']``."""
        a = np.asarray(a, dtype=float)
        if a.shape != (8,):
            raise InputMismatchError(f"expected an 8-vector, got shape {a.shape}")
        return cls(a[:4], a[4:])

    @classmethod
    def from_rotation_translation(cls, quaternion: ArrayLike, translation: ArrayLike) -> "DualQuaternion":
        """From a rotation quaternion (scalar first; normalised here) and a translation."""
        q = np.asarray(quaternion, dtype=float)
        n = np.linalg.norm(q)
        if q.shape != (4,) or not np.isfinite(n) or n == 0:
            raise InputMismatchError(f"quaternion must be a finite non-zero 4-vector, got {quaternion!r}")
        return cls.from_array(dq_from_rotation_translation(q / n, translation))

    @classmethod
    def from_matrix(cls, T: ArrayLike) -> "DualQuaternion":
        """From a 4x4 homogeneous transform."""
        T = np.asarray(T, dtype=float)
        if T.shape != (4, 4):
            raise InputMismatchError(f"expected a 4x4 transform, got shape {T.shape}")
        return cls.from_array(dq_from_matrix(T))

    @classmethod
    def from_screw(cls, theta: float, d: float, l: ArrayLike, m: ArrayLike) -> "DualQuaternion":
        """From screw parameters: angle ``theta``, translation ``d`` along the axis, axis ``(l, m)``.

        ``q = (cos(theta/2), sin(theta/2) l)``, ``q' = (-d/2 sin(theta/2), sin(theta/2) m
        + d/2 cos(theta/2) l)`` (thesis eq. 2.12).
        """
        l = np.asarray(l, dtype=float)
        m = np.asarray(m, dtype=float)
        s, c = np.sin(0.5 * theta), np.cos(0.5 * theta)
        real = np.concatenate([[c], s * l])
        dual = np.concatenate([[-0.5 * d * s], s * m + 0.5 * d * c * l])
        return cls(real, dual)

    @classmethod
    def identity(cls) -> "DualQuaternion":
        """The identity transform ``1 + eps 0``."""
        return cls()

    @classmethod
    def zeros(cls) -> "DualQuaternion":
        """The zero dual quaternion (the thesis's ``zeros()``)."""
        return cls(np.zeros(4), np.zeros(4))

    # --- parts
    @property
    def real(self) -> NDArray[np.float64]:
        """The real part ``q`` (a copy)."""
        return self._q[:4].copy()

    @property
    def dual(self) -> NDArray[np.float64]:
        """The dual part ``q'`` (a copy)."""
        return self._q[4:].copy()

    def as_array(self) -> NDArray[np.float64]:
        """The 8-vector ``[q, q']``."""
        return self._q.copy()

    # --- algebra
    def __mul__(self, other: "DualQuaternion") -> "DualQuaternion":
        if not isinstance(other, DualQuaternion):
            if np.isscalar(other):
                return DualQuaternion.from_array(self._q * float(other))
            return NotImplemented
        return DualQuaternion.from_array(dq_mul(self._q, other._q))

    def __rmul__(self, other: float) -> "DualQuaternion":
        if np.isscalar(other):
            return DualQuaternion.from_array(self._q * float(other))
        return NotImplemented

    def __add__(self, other: "DualQuaternion") -> "DualQuaternion":
        if not isinstance(other, DualQuaternion):
            return NotImplemented
        return DualQuaternion.from_array(self._q + other._q)

    def __neg__(self) -> "DualQuaternion":
        return DualQuaternion.from_array(-self._q)

    def conjugate(self) -> "DualQuaternion":
        """Quaternion conjugate of both parts; for a unit dual quaternion this is its inverse."""
        return DualQuaternion.from_array(dq_conj(self._q))

    def norm(self) -> tuple[float, float]:
        """The dual-number norm ``|q| + eps (q . q') / |q|`` as ``(real, dual)``."""
        n = float(np.linalg.norm(self._q[:4]))
        if n == 0.0:
            return 0.0, 0.0
        return n, float(self._q[:4] @ self._q[4:]) / n

    def normalized(self) -> "DualQuaternion":
        """This divided by its dual norm: a unit dual quaternion (``|q| = 1``, ``q . q' = 0``)."""
        n, nd = self.norm()
        if n == 0.0:
            raise ZeroDivisionError("cannot normalise a dual quaternion whose real part is zero")
        q, qd = self._q[:4], self._q[4:]
        # 1 / (n + eps nd) = 1/n - eps nd/n^2
        return DualQuaternion(q / n, qd / n - q * nd / n**2)

    def normalize(self) -> "DualQuaternion":
        """Normalise in place (see :meth:`normalized`); returns self."""
        self._q = self.normalized()._q
        return self

    def inverse(self) -> "DualQuaternion":
        """The multiplicative inverse: ``q^-1 - eps q^-1 q' q^-1``."""
        q, qd = self._q[:4], self._q[4:]
        n2 = float(q @ q)
        if n2 == 0.0:
            raise ZeroDivisionError("a dual quaternion with zero real part has no inverse")
        qi = qconj(q) / n2
        return DualQuaternion(qi, -qmul(qmul(qi, qd), qi))

    def exp(self) -> "DualQuaternion":
        """The exponential; ``exp(log(q)) == q`` for unit dual quaternions."""
        return DualQuaternion.from_array(_dq_exp(self._q))

    def log(self) -> "DualQuaternion":
        """The logarithm of a unit dual quaternion: ``(theta + eps d)/2 * (l + eps m)`` (pure)."""
        return DualQuaternion.from_array(_dq_log(self._q))

    def is_unit(self, atol: float = 1e-9) -> bool:
        """Whether ``|q| = 1`` and ``q . q' = 0`` within ``atol`` (appendix B)."""
        q, qd = self._q[:4], self._q[4:]
        return abs(q @ q - 1.0) <= atol and abs(q @ qd) <= atol

    # --- as a transform
    def rotation(self) -> NDArray[np.float64]:
        """The 3x3 rotation matrix of the real part."""
        return quat_to_matrix(self._q[:4])

    def translation(self) -> NDArray[np.float64]:
        """The translation vector ``t = 2 q' conj(q)`` (vector part)."""
        return self.translation_quaternion()[1:]

    def translation_quaternion(self) -> NDArray[np.float64]:
        """The translation as a pure quaternion ``(0, t)``."""
        return 2.0 * qmul(self._q[4:], qconj(self._q[:4]))

    def to_matrix(self) -> NDArray[np.float64]:
        """The 4x4 homogeneous transform."""
        return dq_to_matrix(self._q)

    def transform_point(self, point: ArrayLike) -> NDArray[np.float64]:
        """Apply rotation and translation to points ``(..., 3)``: ``q p conj(q) + t``."""
        return self.transform_vector(point) + self.translation()

    def transform_vector(self, vector: ArrayLike) -> NDArray[np.float64]:
        """Apply only the rotation to vectors ``(..., 3)``: ``q v conj(q)``."""
        v = np.asarray(vector, dtype=float)
        vq = np.concatenate([np.zeros(v.shape[:-1] + (1,)), v], axis=-1)
        q = self._q[:4] / np.linalg.norm(self._q[:4])
        return qmul(qmul(q, vq), qconj(q))[..., 1:]

    def screw(self) -> tuple[float, float, NDArray[np.float64], NDArray[np.float64]]:
        """Screw parameters ``(theta, d, l, m)`` of a unit dual quaternion (inverse of from_screw)."""
        lg = _dq_log(self._q)
        u, ud = lg[1:4], lg[5:8]
        half = float(np.linalg.norm(u))
        if half < 1e-12:
            tn = float(np.linalg.norm(ud))
            l = ud / tn if tn > 0 else np.zeros(3)
            return 0.0, 2.0 * tn, l, np.zeros(3)
        l = u / half
        half_d = float(l @ ud)
        m = (ud - half_d * l) / half
        return 2.0 * half, 2.0 * half_d, l, m

    def __repr__(self) -> str:
        r = ", ".join(f"{x:.6g}" for x in self._q[:4])
        d = ", ".join(f"{x:.6g}" for x in self._q[4:])
        return f"DualQuaternion(real=[{r}], dual=[{d}])"
