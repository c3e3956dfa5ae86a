"""Globally optimal, certified hand-eye calibration by semidefinite relaxation.

The thesis (§2.2.5) presents Heller, Havlena and Pajdla's branch-and-bound as the way to a global
optimum with a guarantee and sets it aside as too slow. A convex relaxation gives the same
guarantee in milliseconds (the approach of Giamou et al. 2019 and Wise et al. 2020, written here
from the equations):

**The cost** (stated, and the one certified). For AX = XB with motions ``(A_k, B_k)``::

    C(X) = sum_k |R_A R - R R_B|_F^2 / s_R^2 + |R_A t + t_A - R t_B - t|^2 / s_t^2

the chordal rotation residual and the translation residual of every motion, weighted by the
rotation and translation scales ``s_R`` (rad) and ``s_t`` (m) (defaults 1e-3 rad and 1e-3 m: a
milliradian counts as a millimetre). For the robot-world form ``A_i X = Z B_i``, the same two terms
per pose with ``R_A R_X - R_Z R_B`` and ``R_A t_X + t_A - R_Z t_B - t_Z``.

**The relaxation.** ``C`` is a quadratic form in ``y = [vec R, t, 1]``; minimising over the
translations (unconstrained) leaves a quadratic form ``u^T Q u`` in ``u = [vec R, 1]``. With
``W = u u^T`` the problem is ``min tr(Q W)`` over rank-one ``W`` satisfying the quadratic
equations of a rotation: orthonormal rows and columns and right-handed rows (``r_a x r_b = r_c``),
all linear in ``W``. Dropping the rank gives a semidefinite program (cvxpy with the Clarabel
solver: the optional extra ``handeye[certifiable]``) whose value is a lower bound of ``C`` over all
of SE(3). When its solution has rank one (the relaxation is *tight*), it is the global optimum;
the rotation is read off its top eigenvector and polished by a local Gauss-Newton on the same cost.

**The certificate** of any X (:func:`certify`): the duality gap ``C(X) - bound``. X is certified
optimal when the gap is within the solver's accuracy (``optimal``). Tightness is known to hold
for noise well beyond what robots and cameras have (Wise et al. report it up to several degrees);
it can fail with very few, nearly degenerate motions, and then ``tight`` is False and no claim is
made about the extracted X (``optimal`` only certifies what the gap proves).

The unknown-scale variant (:func:`solve_certifiable_scaled`): camera translations known up to a
factor (structure from motion, visual odometry): with ``alpha = 1 / scale`` the translation residual
``(R_A - I) alpha t + alpha t_A - R t_B`` is linear in ``(alpha t, alpha)``, which are eliminated
as the translation is; the relaxation is the same.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from .._shared.lazy import lazy_module
from ..errors import DegenerateMotionError, HandEyeError
from ..frames.motions import MotionSet
from ..geometry.dualquat import quat_to_matrix
from ..geometry.se3 import make_transform
from ._common import nearest_rotation
from ._registry import register
from .observability import validate_motions

cp = lazy_module("cvxpy")

__all__ = ["Certificate", "Relaxation", "certify", "certify_robot_world", "hand_eye_cost", "relax", "relax_robot_world",
           "robot_world_cost", "solve_certifiable_scaled", "ROTATION_SCALE", "TRANSLATION_SCALE"]

#: Default weights of the certified cost: a residual of this many radians (chordal) and metres
#: counts one unit.
ROTATION_SCALE = 1e-3
TRANSLATION_SCALE = 1e-3
#: The relaxation is tight (rank one) when its second eigenvalue is below this fraction of the first.
TIGHT_RATIO = 1e-5
#: A gap below this fraction of the cost, or of the cost matrix's scale, is the solver's accuracy.
GAP_RELATIVE = 1e-6
GAP_ABSOLUTE = 1e-8


def _need_cvxpy():
    try:
        cp.Problem  # noqa: B018  (imports cvxpy)
    except ImportError:
        raise HandEyeError("the certifiable solvers need cvxpy and Clarabel: pip install 'handeye[certifiable]'") from None


@dataclass(frozen=True)
class Certificate:
    """Whether a given X (and Z) is the global minimum of the stated cost (module docstring).

    Attributes
    ----------
    optimal : bool
        The duality gap is within the solver's accuracy: no X has a lower cost.
    gap : float
        ``cost - lower_bound``, in the cost's units.
    cost, lower_bound : float
        The cost of the X given, and the relaxation's value (a bound over all X).
    tight : bool
        The relaxation's solution has rank one (its value is the global minimum, attained).
    cost_name : str
    """

    optimal: bool
    gap: float
    cost: float
    lower_bound: float
    tight: bool
    cost_name: str

    def as_dict(self) -> dict:
        return {"optimal": self.optimal, "gap": self.gap, "cost": self.cost, "lower_bound": self.lower_bound,
                "tight": self.tight, "cost_name": self.cost_name}


@dataclass(frozen=True)
class Relaxation:
    """The quadratic forms of a problem and its semidefinite relaxation's solution."""

    Q_full: NDArray[np.float64]  #: over y = [rotations..., eliminated..., 1]
    Q: NDArray[np.float64]  #: over u = [rotations..., 1], the eliminated variables minimised out
    recover: NDArray[np.float64]  #: eliminated = recover @ u
    n_rot: int
    lower_bound: float
    W: NDArray[np.float64]
    tight: bool
    cost_name: str

    def cost_of(self, y: NDArray[np.float64]) -> float:
        return float(y @ self.Q_full @ y)

    def tolerance(self, cost: float) -> float:
        return max(GAP_RELATIVE * abs(cost), GAP_ABSOLUTE * float(np.trace(self.Q)))

    def certificate(self, y: NDArray[np.float64]) -> Certificate:
        cost = self.cost_of(y)
        gap = cost - self.lower_bound
        return Certificate(bool(gap <= self.tolerance(cost)), float(gap), cost, self.lower_bound, self.tight,
                           self.cost_name)


# --------------------------------------------------------------------------------------------------
# the quadratic forms


def _row_vec(R: NDArray[np.float64]) -> NDArray[np.float64]:
    return R.reshape(R.shape[:-2] + (9,))


def _times_vec(t: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(K, 3, 9)`` matrices ``M`` with ``M vec(R) = R t`` (row-major vec)."""
    M = np.zeros(t.shape[:-1] + (3, 9))
    for i in range(3):
        M[..., i, 3 * i:3 * i + 3] = t
    return M


def _gram(blocks: NDArray[np.float64], weight: float) -> NDArray[np.float64]:
    """``weight * sum_k M_k^T M_k`` of residual matrices ``(K, m, d)``."""
    M = blocks.reshape(-1, blocks.shape[-1])
    return weight * (M.T @ M)


def hand_eye_quadratic(motions: MotionSet, rotation_scale: float = ROTATION_SCALE,
                       translation_scale: float = TRANSLATION_SCALE, scaled: bool = False) -> NDArray[np.float64]:
    """``Q_full`` (13, 13) over ``[vec R, t, 1]`` with ``y^T Q_full y = C(X)`` (module docstring);
    ``scaled``: (14, 14) over ``[vec R, alpha t, alpha, 1]`` for the unknown-scale variant."""
    R_A, R_B, t_A, t_B = motions.R_A, quat_to_matrix(motions.dq_b[..., :4]), motions.t_A, motions.t_B
    K = len(motions)
    d = 14 if scaled else 13
    I3 = np.eye(3)
    rot = np.zeros((K, 9, d))
    rot[:, :, :9] = np.einsum("kij,ab->kiajb", R_A, I3).reshape(K, 9, 9) - np.einsum("ij,kba->kiajb", I3, R_B).reshape(K, 9, 9)
    tra = np.zeros((K, 3, d))
    tra[:, :, :9] = -_times_vec(t_B)
    tra[:, :, 9:12] = R_A - I3
    tra[:, :, 12] = t_A  # the constant (column 12), or alpha's column when scaled
    return _gram(rot, 1 / rotation_scale**2) + _gram(tra, 1 / translation_scale**2)


def robot_world_quadratic(A_abs: NDArray[np.float64], B_abs: NDArray[np.float64], rotation_scale: float = ROTATION_SCALE,
                          translation_scale: float = TRANSLATION_SCALE) -> NDArray[np.float64]:
    """``Q_full`` (25, 25) over ``[vec R_X, vec R_Z, t_X, t_Z, 1]`` for ``A_i X = Z B_i``."""
    R_A, t_A, R_B, t_B = A_abs[:, :3, :3], A_abs[:, :3, 3], B_abs[:, :3, :3], B_abs[:, :3, 3]
    N = len(A_abs)
    I3 = np.eye(3)
    rot = np.zeros((N, 9, 25))
    rot[:, :, :9] = np.einsum("kij,ab->kiajb", R_A, I3).reshape(N, 9, 9)
    rot[:, :, 9:18] = -np.einsum("ij,kba->kiajb", I3, R_B).reshape(N, 9, 9)
    tra = np.zeros((N, 3, 25))
    tra[:, :, 9:18] = -_times_vec(t_B)
    tra[:, :, 18:21] = R_A
    tra[:, :, 21:24] = -I3
    tra[:, :, 24] = t_A
    return _gram(rot, 1 / rotation_scale**2) + _gram(tra, 1 / translation_scale**2)


def _reduce(Q_full: NDArray[np.float64], n_rot: int):
    """Minimise out the variables between the rotations and the constant: ``(Q, recover)``."""
    d = len(Q_full)
    keep = np.r_[np.arange(9 * n_rot), d - 1]
    elim = np.arange(9 * n_rot, d - 1)
    Qee = Q_full[np.ix_(elim, elim)]
    Qek = Q_full[np.ix_(elim, keep)]
    w = np.linalg.eigvalsh(Qee)
    if not w[0] > 1e-12 * max(w[-1], 1e-300):
        raise DegenerateMotionError("the motions do not determine the translation (the robot rotations are all "
                                    "the same): take poses with rotations about different axes")
    recover = -np.linalg.solve(Qee, Qek)
    Q = Q_full[np.ix_(keep, keep)] + Qek.T @ recover
    return 0.5 * (Q + Q.T), recover


# --------------------------------------------------------------------------------------------------
# the semidefinite program


@lru_cache(maxsize=4)
def _constraints(n_rot: int) -> tuple[NDArray[np.float64], ...]:
    """Matrices ``A`` with ``tr(A W) = 0`` for ``W = u u^T``, ``u = [vec R_1, ..., 1]``: orthonormal
    columns and rows and right-handed rows of every rotation."""
    d = 9 * n_rot + 1
    one = d - 1
    out = []

    def form(quad, lin=(), const=0.0):
        A = np.zeros((d, d))
        for p, q, c in quad:
            A[p, q] += 0.5 * c
            A[q, p] += 0.5 * c
        for p, c in lin:
            A[p, one] += 0.5 * c
            A[one, p] += 0.5 * c
        A[one, one] += const
        out.append(A)

    for b in range(n_rot):
        def ix(i, j, b=b):
            return 9 * b + 3 * i + j
        for j in range(3):
            for k in range(j, 3):
                form([(ix(i, j), ix(i, k), 1.0) for i in range(3)], const=-float(j == k))  # columns
                form([(ix(j, i), ix(k, i), 1.0) for i in range(3)], const=-float(j == k))  # rows
        for a, bb, c in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
            for m in range(3):
                m1, m2 = (m + 1) % 3, (m + 2) % 3
                form([(ix(a, m1), ix(bb, m2), 1.0), (ix(a, m2), ix(bb, m1), -1.0)], lin=[(ix(c, m), -1.0)])
    return tuple(out)


@lru_cache(maxsize=4)
def _program(n_rot: int):
    """The SDP ``min tr(Q W)``, ``W >= 0``, ``W_11 = 1``, the rotation constraints; ``Q`` a parameter
    (cvxpy compiles the problem once per size)."""
    d = 9 * n_rot + 1
    Q = cp.Parameter((d, d), symmetric=True)
    W = cp.Variable((d, d), symmetric=True)
    cons = [W >> 0, W[d - 1, d - 1] == 1] + [cp.trace(A @ W) == 0 for A in _constraints(n_rot)]
    return cp.Problem(cp.Minimize(cp.trace(Q @ W)), cons), Q, W


def _solve_sdp(Q: NDArray[np.float64], n_rot: int) -> tuple[float, NDArray[np.float64]]:
    _need_cvxpy()
    scale = float(np.trace(Q)) or 1.0
    problem, Qp, W = _program(n_rot)
    Qp.value = Q / scale
    problem.solve(solver="CLARABEL")
    if problem.status not in ("optimal", "optimal_inaccurate") or W.value is None:
        raise HandEyeError(f"the semidefinite relaxation did not solve ({problem.status})")
    # a rigorous bound from the dual: for every feasible u (|u|^2 = 3 n_rot + 1), u^T Q u = nu +
    # u^T S u >= nu + min(0, lambda_min(S)) |u|^2 with S = Q - nu E - sum lambda_i A_i; the primal
    # value is only as accurate as the solver
    duals = [c.dual_value for c in problem.constraints[1:]]
    d = len(Q)
    S = Qp.value.copy()
    S[d - 1, d - 1] += float(duals[0])
    for lam, A in zip(duals[1:], _constraints(n_rot)):
        S += float(lam) * A
    bound = float(duals[0]) * -1.0 + min(0.0, float(np.linalg.eigvalsh(S)[0])) * (3 * n_rot + 1)
    return bound * scale, np.asarray(W.value)


def _relax(Q_full: NDArray[np.float64], n_rot: int, cost_name: str) -> Relaxation:
    Q, recover = _reduce(Q_full, n_rot)
    bound, W = _solve_sdp(Q, n_rot)
    w = np.linalg.eigvalsh(W)
    return Relaxation(Q_full, Q, recover, n_rot, bound, W, bool(w[-2] <= TIGHT_RATIO * w[-1]), cost_name)


def _y_hand_eye(X: NDArray[np.float64]) -> NDArray[np.float64]:
    """``y = [vec R, t, 1]`` of an X, the variables of :func:`hand_eye_quadratic`."""
    X = np.asarray(X, float)
    return np.r_[_row_vec(X[:3, :3]), X[:3, 3], 1.0]


def _y_robot_world(X: NDArray[np.float64], Z: NDArray[np.float64]) -> NDArray[np.float64]:
    """``y = [vec R_X, vec R_Z, t_X, t_Z, 1]``, the variables of :func:`robot_world_quadratic`."""
    X, Z = np.asarray(X, float), np.asarray(Z, float)
    return np.r_[_row_vec(X[:3, :3]), _row_vec(Z[:3, :3]), X[:3, 3], Z[:3, 3], 1.0]


def _u_of(rotations: list[NDArray[np.float64]]) -> NDArray[np.float64]:
    return np.r_[np.concatenate([_row_vec(R) for R in rotations]), 1.0]


def _extract(rel: Relaxation) -> list[NDArray[np.float64]]:
    """The rotations of the relaxation's top eigenvector, projected onto SO(3) and polished."""
    w, V = np.linalg.eigh(rel.W)
    u = V[:, -1] * np.sqrt(max(w[-1], 0.0))
    u = u / u[-1] if abs(u[-1]) > 1e-12 else u
    rotations = [nearest_rotation(u[9 * b:9 * b + 9].reshape(3, 3)) for b in range(rel.n_rot)]
    return _polish(rel.Q, rel.n_rot, rotations)


def _polish(Q: NDArray[np.float64], n: int, rotations: list[NDArray[np.float64]], iterations: int = 50) -> list[NDArray[np.float64]]:
    """A local minimum of ``u^T Q u`` over the rotations, from ``rotations``: Gauss-Newton on
    ``f = L^T u`` (``Q = L L^T``) with left rotation increments, whose Jacobian is exact:
    ``d vec(exp([d]x) R) / d d_k = vec([e_k]x R)``; a step that does not lower the cost is halved."""
    w, V = np.linalg.eigh(Q)
    L = V * np.sqrt(np.clip(w, 0.0, None))
    generators = np.array([[[0, 0, 0], [0, 0, -1], [0, 1, 0]], [[0, 0, 1], [0, 0, 0], [-1, 0, 0]],
                           [[0, -1, 0], [1, 0, 0], [0, 0, 0]]], dtype=float)
    rotations = [np.asarray(R, float) for R in rotations]
    f = L.T @ _u_of(rotations)
    cost = float(f @ f)
    for _ in range(iterations):
        J = np.zeros((len(f), 3 * n))
        for b, R in enumerate(rotations):
            J[:, 3 * b:3 * b + 3] = L.T[:, 9 * b:9 * b + 9] @ (generators @ R).reshape(3, 9).T
        step = -np.linalg.lstsq(J, f, rcond=None)[0]
        for _ in range(30):
            dR = Rotation.from_rotvec(step.reshape(-1, 3)).as_matrix()
            trial = [d @ R for d, R in zip(dR, rotations)]
            f_new = L.T @ _u_of(trial)
            if float(f_new @ f_new) <= cost:
                break
            step = 0.5 * step
        else:
            break
        done = cost - float(f_new @ f_new) <= 1e-15 * max(cost, 1e-300)
        rotations, f, cost = trial, f_new, float(f_new @ f_new)
        if done or np.abs(step).max() < 1e-13:
            break
    return rotations


# --------------------------------------------------------------------------------------------------
# the public face


_HAND_EYE_COST = "sum over motions of |R_A R - R R_B|_F^2 / {:g}^2 + |R_A t + t_A - R t_B - t|^2 / {:g}^2"
_ROBOT_WORLD_COST = ("sum over poses of |R_A R_X - R_Z R_B|_F^2 / {:g}^2 + |R_A t_X + t_A - R_Z t_B - t_Z|^2 "
                     "/ {:g}^2")


def relax(motions: MotionSet, rotation_scale: float = ROTATION_SCALE,
          translation_scale: float = TRANSLATION_SCALE) -> Relaxation:
    """The semidefinite relaxation of AX = XB under the stated cost (module docstring)."""
    return _relax(hand_eye_quadratic(motions, rotation_scale, translation_scale), 1,
                  _HAND_EYE_COST.format(rotation_scale, translation_scale))


def relax_robot_world(A_abs: NDArray[np.float64], B_abs: NDArray[np.float64], rotation_scale: float = ROTATION_SCALE,
                      translation_scale: float = TRANSLATION_SCALE) -> Relaxation:
    """The relaxation of ``A_i X = Z B_i`` (absolute poses, as :func:`handeye.solve_robot_world`)."""
    return _relax(robot_world_quadratic(A_abs, B_abs, rotation_scale, translation_scale), 2,
                  _ROBOT_WORLD_COST.format(rotation_scale, translation_scale))


def _solution(rel: Relaxation) -> tuple[list[NDArray[np.float64]], NDArray[np.float64]]:
    rotations = _extract(rel)
    return rotations, rel.recover @ _u_of(rotations)


def hand_eye_cost(motions: MotionSet, X: NDArray[np.float64], rotation_scale: float = ROTATION_SCALE,
                  translation_scale: float = TRANSLATION_SCALE) -> float:
    """The certified cost ``C(X)`` of AX = XB (module docstring)."""
    y = _y_hand_eye(X)
    return float(y @ hand_eye_quadratic(motions, rotation_scale, translation_scale) @ y)


def robot_world_cost(A_abs, B_abs, X, Z, rotation_scale: float = ROTATION_SCALE,
                     translation_scale: float = TRANSLATION_SCALE) -> float:
    """The certified cost of ``A_i X = Z B_i``."""
    y = _y_robot_world(X, Z)
    return float(y @ robot_world_quadratic(np.asarray(A_abs, float), np.asarray(B_abs, float), rotation_scale,
                                           translation_scale) @ y)


@register("certifiable", reference="SDP relaxation (Giamou et al. 2019, Wise et al. 2020); issue 22", extra="certifiable")
def solve(motions: MotionSet) -> NDArray[np.float64]:
    """The global minimum of the stated cost (module docstring) for AX = XB, one SDP per run."""
    if motions.batch_shape:
        flat = [MotionSet(a, b) for a, b in zip(motions.dq_a.reshape(-1, *motions.dq_a.shape[-2:]),
                                                 motions.dq_b.reshape(-1, *motions.dq_b.shape[-2:]))]
        return np.stack([solve(m) for m in flat]).reshape(motions.batch_shape + (4, 4))
    (R,), t = _solution(relax(motions))
    return make_transform(R, t)


@register("certifiable_robot_world", kind="robot_world", reference="SDP relaxation of A_i X = Z B_i; issue 22",
          extra="certifiable")
def solve_robot_world(A_abs: NDArray[np.float64], B_abs: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The global minimum of the stated robot-world cost, one SDP per run."""
    if A_abs.ndim == 4:
        out = [solve_robot_world(a, b) for a, b in zip(A_abs, B_abs)]
        return np.stack([o[0] for o in out]), np.stack([o[1] for o in out])
    (R_X, R_Z), t = _solution(relax_robot_world(A_abs, B_abs))
    return make_transform(R_X, t[:3]), make_transform(R_Z, t[3:])


def certify(A, B, X, rotation_scale: float = ROTATION_SCALE, translation_scale: float = TRANSLATION_SCALE,
            relaxation: Relaxation | None = None) -> Certificate:
    """Whether ``X`` (from any solver) is the global minimum of the stated AX = XB cost.

    Parameters
    ----------
    A, B : (K, 4, 4) or MotionSet
        The motions (``A`` a :class:`~handeye.frames.motions.MotionSet` and ``B`` None also works).
    X : (4, 4)
    relaxation : Relaxation, optional
        Of the same motions and weights (:func:`relax`), to certify several X at the cost of one SDP.
    """
    motions = A if isinstance(A, MotionSet) else validate_motions(A, B)
    rel = relaxation or relax(motions, rotation_scale, translation_scale)
    return rel.certificate(_y_hand_eye(X))


def certify_robot_world(A_abs, B_abs, X, Z, rotation_scale: float = ROTATION_SCALE,
                        translation_scale: float = TRANSLATION_SCALE, relaxation: Relaxation | None = None) -> Certificate:
    """Whether ``(X, Z)`` is the global minimum of the stated robot-world cost."""
    rel = relaxation or relax_robot_world(np.asarray(A_abs, float), np.asarray(B_abs, float), rotation_scale,
                                          translation_scale)
    return rel.certificate(_y_robot_world(X, Z))


def local_minimum(motions: MotionSet, X0: NDArray[np.float64], rotation_scale: float = ROTATION_SCALE,
                  translation_scale: float = TRANSLATION_SCALE) -> NDArray[np.float64]:
    """The local minimum of the stated AX = XB cost reached from ``X0``'s rotation (no SDP)."""
    Q, recover = _reduce(hand_eye_quadratic(motions, rotation_scale, translation_scale), 1)
    (R,) = _polish(Q, 1, [np.asarray(X0, float)[:3, :3]])
    return make_transform(R, recover @ _u_of([R]))


def solve_certifiable_scaled(motions: MotionSet, rotation_scale: float = ROTATION_SCALE,
                             translation_scale: float = TRANSLATION_SCALE) -> tuple[NDArray[np.float64], float, Certificate]:
    """X and the scale of the camera translations (metric ``t_B = scale * t_B given``), certified.

    For camera trajectories without a metric target (structure from motion, visual odometry). The
    cost is the module's with the translation residual ``(R_A - I) alpha t + alpha t_A - R t_B``,
    ``alpha = 1 / scale`` (camera units): linear in ``(alpha t, alpha)``, which are minimised out.
    """
    Q_full = hand_eye_quadratic(motions, rotation_scale, translation_scale, scaled=True)
    # the translation residual has no constant: index 12 is alpha, 13 the (unused) constant
    rel = _relax(Q_full, 1, "unknown-scale: " + _HAND_EYE_COST.format(rotation_scale, translation_scale))
    (R,), elim = _solution(rel)
    t_alpha, alpha = elim[:3], elim[3]
    if not alpha > 0:
        raise DegenerateMotionError("the motions do not determine the scale (the robot barely translates)")
    X = make_transform(R, t_alpha / alpha)
    return X, float(1.0 / alpha), rel.certificate(np.r_[_row_vec(R), elim, 1.0])
