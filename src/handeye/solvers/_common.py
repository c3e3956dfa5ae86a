"""Pieces shared by the solver families: the translation least squares and rotation projection.

Every function here works on one problem or on a batch of them (leading axes, e.g. Monte-Carlo
runs), so a solver written with them is vectorised over runs for free.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import lapack as _lapack
from scipy.spatial.transform import Rotation

from ..frames.motions import MotionSet
from ..geometry.se3 import make_transform


def translation_least_squares(motions: MotionSet, R_X: NDArray[np.float64]) -> NDArray[np.float64]:
    """``t_X`` minimising ``sum |(R_A - I) t_X - (R_X t_B - t_A)|^2`` (thesis eq. 2.4).

    The "then translation" step of the rotation-first methods (Tsai-Lenz, Park-Martin, Horaud).
    Solved through the 3x3 normal equations; for rotations ``(R - I)^T (R - I) = 2I - R - R^T``,
    so the normal matrix is a plain sum over the motions. ``R_X`` is ``(..., 3, 3)``, one per run.
    """
    if motions.all_pairs_factors is not None:
        return _translation_all_pairs(motions.all_pairs_factors, R_X)
    # sum R_A^T d = sum R_A^T R_X t_B - sum R_A^T t_A, and the plain sums: entries of
    # MotionSet.translation_moments, [i, c, j] = sum A[i, c] A[j, 3] and [i, c, 4 + j] = sum A[i, c] B[j, 3]
    M = motions.translation_moments
    M = M.reshape(M.shape[:-2] + (4, 4, 8))
    S = M[..., :3, :3, 3]  # sum R_A
    sum_d = (R_X @ M[..., 3, 3, 4:7, None])[..., 0] - M[..., 3, 3, :3]
    rhs = (np.einsum("...ij,...icj->...c", R_X, M[..., :3, :3, 4:7]) - np.einsum("...ici->...c", M[..., :3, :3, :3])
           - sum_d)
    normal = 2 * len(motions) * np.eye(3) - S - np.swapaxes(S, -1, -2)
    return np.linalg.solve(normal, rhs[..., None])[..., 0]


def _translation_all_pairs(factors: tuple, R_X: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`translation_least_squares` over every pair ``i < j`` of N poses in O(N).

    With ``A_ij = G_j H_i`` and ``B_ij = G'_j H'_i`` (rotations ``g, h``, translations ``gamma,
    tau``): ``R_A = g_j h_i``, ``t_A = g_j tau_i + gamma_j``, ``t_B = g'_j tau'_i + gamma'_j``, so

    * ``sum R_A = sum_j g_j sum_{i<j} h_i``;
    * ``sum d = R_X sum_j g'_j sum_{i<j} tau'_i + R_X sum_j j gamma'_j - sum_j g_j sum_{i<j} tau_i
      - sum_j j gamma_j`` (``d = R_X t_B - t_A``);
    * ``sum R_A^T d = sum_i h_i^T [(sum_{j>i} g_j^T R_X g'_j) tau'_i + sum_{j>i} g_j^T (R_X gamma'_j
      - gamma_j) - (N - 1 - i) tau_i]`` (``g_j^T g_j = I``);

    prefix sums over the poses replace the sums over the N(N-1)/2 motions.
    """
    (G_A, H_A), (G_B, H_B) = factors
    g, gamma, h, tau = G_A[..., :3, :3], G_A[..., :3, 3], H_A[..., :3, :3], H_A[..., :3, 3]
    gb, gamma_b, tau_b = G_B[..., :3, :3], G_B[..., :3, 3], H_B[..., :3, 3]
    n = g.shape[-3]
    R_X = R_X[..., None, :, :]  # broadcast over the poses
    before = np.arange(n, dtype=float)[:, None]  # number of i < j for each j
    after = (n - 1.0) - before  # number of j > i for each i
    S = (g @ (np.cumsum(h, axis=-3) - h)).sum(axis=-3)  # sum_j g_j sum_{i<j} h_i
    rb = R_X @ gb  # R_X g'_j
    r_gamma_b = (R_X @ gamma_b[..., None])[..., 0]  # R_X gamma'_j
    tau_b_before = np.cumsum(tau_b, axis=-2) - tau_b  # sum_{i<j}
    tau_before = np.cumsum(tau, axis=-2) - tau
    sum_d = ((rb @ tau_b_before[..., None])[..., 0] + before * r_gamma_b
             - (g @ tau_before[..., None])[..., 0] - before * gamma).sum(axis=-2)
    gT = np.swapaxes(g, -1, -2)
    M = gT @ rb  # g_j^T R_X g'_j
    w = (gT @ (r_gamma_b - gamma)[..., None])[..., 0]
    M_after = M.sum(axis=-3, keepdims=True) - np.cumsum(M, axis=-3)  # sum_{j > i}
    w_after = w.sum(axis=-2, keepdims=True) - np.cumsum(w, axis=-2)
    inner = (M_after @ tau_b[..., None])[..., 0] + w_after - after * tau
    sum_RAt_d = (np.swapaxes(h, -1, -2) @ inner[..., None])[..., 0].sum(axis=-2)
    k = n * (n - 1) / 2
    normal = 2 * k * np.eye(3) - S - np.swapaxes(S, -1, -2)
    return np.linalg.solve(normal, (sum_RAt_d - sum_d)[..., None])[..., 0]


def kron_eye(M: NDArray[np.float64]) -> NDArray[np.float64]:
    """``kron(I3, M)`` of matrices ``(..., p, q)``, shape ``(..., 3p, 3q)``."""
    p, q = M.shape[-2:]
    return np.einsum("ac,...bd->...abcd", np.eye(3), M).reshape(M.shape[:-2] + (3 * p, 3 * q))


# One matrix goes to LAPACK directly: np.linalg calls the same routines (dgesdd, dgesv), but its
# per-call Python overhead (~8 us) is most of the time for the 3x3 to 24x24 systems solved here.


def svd(M: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """``np.linalg.svd(M)`` of one matrix ``(m, n)`` or a batch ``(..., m, n)``."""
    if M.ndim != 2:
        return np.linalg.svd(M)
    U, s, Vt, info = _lapack.dgesdd(M)
    if info != 0:
        raise np.linalg.LinAlgError("SVD did not converge")
    return U, s, Vt


def solve(N: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """``np.linalg.solve(N, b[..., None])[..., 0]``: one square system or a batch, ``b (..., n)``."""
    if N.ndim != 2:
        return np.linalg.solve(N, b[..., None])[..., 0]
    _, _, x, info = _lapack.dgesv(N, b)
    if info != 0:
        raise np.linalg.LinAlgError("Singular matrix")
    return x


def top_eigenvector(M: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit eigenvector of the largest eigenvalue of symmetric matrices ``(..., n, n)``, ``(..., n)``.

    A few matrices are decomposed one by one with LAPACK's ``dsyevd`` (as ``np.linalg.eigh``, which
    costs about twice as much per call on 3x3 matrices); sign arbitrary.
    """
    flat = M.reshape((-1,) + M.shape[-2:])
    if len(flat) > 8:
        return np.linalg.eigh(M)[1][..., :, -1]
    vecs = []
    for m in flat:
        _, v, info = _lapack.dsyevd(m)
        if info != 0:
            raise np.linalg.LinAlgError("eigenvalue decomposition did not converge")
        vecs.append(v[:, -1])
    return np.array(vecs).reshape(M.shape[:-1])


def _det3(M: NDArray[np.float64]) -> float:
    (a, b, c), (d, e, f), (g, h, i) = M.tolist()
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)


def nearest_rotation(M: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rotations closest (Frobenius) to 3x3 estimates ``(..., 3, 3)`` from a linear solve.

    As OpenCV's ``normalizeRotation``: an estimate with negative determinant is the negated
    rotation, so it is negated first; then the orthogonal factor of the SVD, with a remaining
    reflection corrected. A singular estimate (``|det| < 1e-12``) raises for one matrix and gives
    NaN in a batch.
    """
    if M.ndim == 2:
        det = _det3(M)
        if abs(det) < 1e-12:
            raise np.linalg.LinAlgError("rotation estimate is singular")
        U, _, Vt = svd(M if det > 0 else -M)
        if _det3(U) * _det3(Vt) < 0:
            U[:, 2] = -U[:, 2]
        return U @ Vt
    det = np.linalg.det(M)
    singular = np.abs(det) < 1e-12
    U, _, Vt = np.linalg.svd(np.where(det < 0, -1.0, 1.0)[..., None, None] * M)
    reflect = np.linalg.det(U @ Vt) < 0
    U[..., :, 2] *= np.where(reflect, -1.0, 1.0)[..., None]
    R = U @ Vt
    R[singular] = np.nan
    return R


def log_rotations(dq: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation vectors (log maps) of the rotation parts of sign-aligned motion dual quaternions.

    Computed from the quaternions as ``2 atan2(|v|, w) v / |v|`` rather than with scipy, on
    purpose: scipy canonicalises each quaternion to w >= 0, which for a motion near 180 deg can
    flip the robot's rotation vector against the camera's; the aligned signs keep them paired.
    """
    v = dq[..., 1:4]
    vn = np.linalg.norm(v, axis=-1)
    angle = 2.0 * np.arctan2(vn, dq[..., 0])
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(vn > 1e-15, angle / vn, 2.0)  # limit of 2 atan(x)/x at 0
    return v * scale[..., None]


def _xz_increment(x: NDArray[np.float64], X0: NDArray[np.float64], Z0: NDArray[np.float64]):
    """X and Z moved by the first 12 unknowns: left rotation-vector increments and translation
    increments of X, then of Z."""
    dR = Rotation.from_rotvec(np.stack([x[:3], x[6:9]])).as_matrix()  # one scipy call for both
    return (make_transform(dR[0] @ X0[:3, :3], X0[:3, 3] + x[3:6]),
            make_transform(dR[1] @ Z0[:3, :3], Z0[:3, 3] + x[9:12]))


def _normal_inverse(J: NDArray[np.float64]) -> NDArray[np.float64]:
    """``inv(J^T J)`` from the SVD of ``J``: symmetric and positive semi-definite however poorly
    conditioned ``J`` is (whitened by variances 1e13 apart, ``J^T J`` squares a 1e12 condition
    number past double precision and its inverse came out with negative variances); a ``J`` with
    a direction it does not constrain at all gives every variance infinite."""
    _, s, Vt = np.linalg.svd(J, full_matrices=False)
    if not s.min() > 0.0:
        out = np.zeros((J.shape[1], J.shape[1]))
        np.fill_diagonal(out, np.inf)
        return out
    return (Vt.T / s**2) @ Vt
