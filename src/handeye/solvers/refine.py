"""What the pose and pixel refinements share: their result and prior records, and the noise model's variance estimation.

``refine_pose`` and ``refine_reprojection`` moved to :mod:`handeye.estimation.refinement`: the
estimation core fits them (:class:`~handeye.sensors.camera.poses.PoseDifferences`,
:class:`~handeye.sensors.camera.model.CameraCorners`); this module keeps their result and prior
records (:class:`ReprojectionResult`, :class:`PoseRefinementResult`, :class:`TranslationPriors`), the
noise model's variance estimation (:func:`fit_variances`, :func:`reweighted_fit`,
:func:`block_whitening`: the core's fit of correlated residuals uses them) and
:func:`pose_mahalanobis`. ``handeye.solvers.refine.refine_pose`` and ``.refine_reprojection`` still
find them for one release.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from .._shared.moved import forward_names
from ..errors import InputMismatchError
from ..frames.setups import predicted_target2cam
from ..sensors.camera.poses import NOISE_TERMS, pose_jacobian, pose_noise_shapes, pose_residuals

__all__ = ["PoseRefinementResult", "ReprojectionResult", "Reweighted", "TranslationPriors", "VARIANCE_FLOOR", "block_whitening",
           "fit_variances", "pose_mahalanobis", "reweighted_fit", "predicted_target2cam"]

__getattr__ = forward_names(__name__)  # refine_pose, refine_reprojection: now the estimation core's (handeye.estimation.refinement)


@dataclass(frozen=True)
class ReprojectionResult:
    """X and Z refined on the pixel errors (:func:`handeye.estimation.refinement.refine_reprojection`), with their
    covariance and residuals."""

    X: NDArray[np.float64]
    Z: NDArray[np.float64]
    K: NDArray[np.float64]  #: the intrinsics used (refined when asked)
    dist: NDArray[np.float64]
    rms_px: float  #: RMS reprojection error over all points after refinement
    rms_px_before: float  #: the same for the closed-form start
    per_image_rms_px: NDArray[np.float64]
    n_points: int
    success: bool
    message: str
    cov_X: NDArray[np.float64] | None = None  #: 6x6 over [rotation vector (rad), translation (m)] of X
    sigma_px: float | None = None  #: pixel noise estimated from the residuals
    n_rejected: int = 0  #: points dropped as outliers (robust=True)
    flange2base: NDArray[np.float64] | None = None  #: the robot poses, corrected when robot_noise was given
    n_evaluations: int = 0  #: residual evaluations the solver made
    #: images whose every point the robust pass set aside (they keep no pixel residual)
    rejected_images: tuple[int, ...] = ()
    #: per image, the points the fit kept (robust=True; all points otherwise)
    kept: tuple[NDArray[np.bool_], ...] | None = None


@dataclass(frozen=True)
class TranslationPriors:
    """Linear measurements of the translations of X and Z for :func:`refine_pose`:
    ``G @ [t_X, t_Z] = values`` with standard deviations ``stds`` (metres).

    Attributes
    ----------
    G : ndarray (P, 6)
        One row per measurement over ``[t_X (3), t_Z (3)]`` (X's translation in the frame X maps
        into, Z's in Z's), e.g. ``[0, 0, 1, 0, 0, 0]`` for the z component of X's translation.
    values, stds : ndarray (P,)
    """

    G: NDArray[np.float64]
    values: NDArray[np.float64]
    stds: NDArray[np.float64]

    def rows(self, X0: NDArray[np.float64], Z0: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The whitened residual rows ``J @ x + f`` over the 12 increments of ``refine_pose``."""
        G = np.asarray(self.G, float) / np.asarray(self.stds, float)[:, None]
        J = np.zeros((len(G), 12))
        J[:, 3:6], J[:, 9:12] = G[:, :3], G[:, 3:]
        f = G @ np.concatenate([X0[:3, 3], Z0[:3, 3]]) - np.asarray(self.values, float) / np.asarray(self.stds, float)
        return J, f


@dataclass(frozen=True)
class PoseRefinementResult:
    """X and Z refined on the robot and camera poses (:func:`refine_pose`), with the noise estimates."""

    X: NDArray[np.float64]
    Z: NDArray[np.float64]
    cov_X: NDArray[np.float64]  #: 6x6 over [rotation vector (rad), translation (m)] of X
    cov_Z: NDArray[np.float64]  #: the same for Z
    cov: NDArray[np.float64]  #: 12x12 over [X rotation, X translation, Z rotation, Z translation]
    #: estimated noise standard deviations per axis (rad, m): 'robot_rotation', 'camera_rotation',
    #: 'translation' (robot and camera together), 'camera_depth' (the camera's, along its optical axis) for the
    #: noise model; 'rotation', 'translation' for 'strobl'
    noise: dict[str, float]
    residuals: NDArray[np.float64]  #: (N, 6) per pose: rotation vector (rad), translation (m), target frame
    rounds: int  #: weight re-estimation rounds
    converged: bool  #: whether the noise estimates were stable (to 0.1%) within ``max_rounds``
    weighting: str
    success: bool
    message: str


def _theta(noise: dict[str, float]) -> NDArray[np.float64]:
    """The variances of a noise model's standard deviations (``PoseRefinementResult.noise``)."""
    return np.maximum([noise.get(k, 0.0) ** 2 for k in NOISE_TERMS], VARIANCE_FLOOR)


def fit_variances(r: NDArray[np.float64], shapes: NDArray[np.float64], theta0: NDArray[np.float64]) -> NDArray[np.float64]:
    """Maximum-likelihood variances ``theta`` of ``r_i ~ N(0, sum_k theta_k shapes_k[i])``: ``r`` (N, c)
    the residuals, ``shapes`` (K, N, c, c) per term and residual its covariance for a unit variance.

    Fisher scoring over log theta (the expected Hessian of the variance-components problem) with
    step halving: every step lowers -2 log-likelihood. A quasi-Newton search (L-BFGS-B) took its
    first step by the gradient's size, summed over the poses, to the variances' floor, where the
    covariance is singular, and stopped there with the variances unchanged: on 40 poses with 0.1
    deg of robot rotation noise it returned its start (0.058 deg) in 38 of 40 sessions, and X was
    further from the truth (100 poses: 0.14 mm median against 0.094 mm now). A term whose share of
    the residuals' variance falls below :data:`NEGLIGIBLE_SHARE` is set to the floor: the data do
    not support it.
    """
    shapes = np.stack(shapes)  # (K, N, c, c)
    lo, hi = np.log(VARIANCE_FLOOR), 0.0

    def evaluate(log_t):
        t = np.exp(log_t)
        try:
            Ci = np.linalg.inv(np.einsum("k,knij->nij", t, shapes))
        except np.linalg.LinAlgError:  # an infinitely unlikely point: the step is halved
            return np.inf, None, None, None
        u = np.einsum("nij,nj->ni", Ci, r)
        A = np.einsum("nij,knjl->knil", Ci, shapes)  # C^-1 S_k
        share = t * np.einsum("knii->k", A)  # each term's part of the residuals' cN degrees of freedom
        grad = share - t * np.einsum("ni,knij,nj->k", u, shapes, u)
        fisher = np.outer(t, t) * np.einsum("knij,lnji->kl", A, A)
        value = float(-np.sum(np.linalg.slogdet(Ci)[1]) + np.einsum("ni,ni->", r, u))  # log det C = -log det C^-1
        return value, grad, fisher, share

    x = np.clip(np.log(theta0), lo, hi)
    f, g, F, share = evaluate(x)
    for _ in range(SCORING_STEPS):
        if g is None:
            break
        ridge = 1e-12 * max(np.trace(F), np.finfo(float).tiny)
        step = np.linalg.solve(F + ridge * np.eye(len(x)), -g)
        step *= min(1.0, MAX_LOG_STEP / max(np.abs(step).max(), np.finfo(float).tiny))  # the direction kept
        for _ in range(40):
            trial = np.clip(x + step, lo, hi)
            evaluated = evaluate(trial)
            if evaluated[0] < f:
                break
            step = step / 2.0
        else:
            break
        done = f - evaluated[0] <= 1e-12 * max(1.0, abs(f))
        x, (f, g, F, share) = trial, evaluated
        if done:
            break
    if share is not None:
        x = np.where(share < NEGLIGIBLE_SHARE * r.size, lo, x)
    return np.exp(x)


#: Most Fisher-scoring steps of :func:`fit_variances`, and the largest change of a log variance per step.
SCORING_STEPS = 100
MAX_LOG_STEP = 2.0
#: A noise term carrying less than this share of the residuals' variance is not supported by the
#: data and goes to the floor.
NEGLIGIBLE_SHARE = 1e-9


def block_whitening(theta: NDArray[np.float64], shapes: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per residual block the matrix (N, c, c) that whitens it when its covariance is
    ``sum_k theta_k shapes_k`` (``shapes`` (K, N, c, c)): the inverse of its Cholesky factor."""
    C = np.einsum("k,knij->nij", theta, np.stack(shapes))
    try:
        return np.linalg.inv(np.linalg.cholesky(C))  # whitening: L^-1 r has unit covariance
    except np.linalg.LinAlgError:
        # variances 1e13 apart (one at its floor while another is large: data far from the noise
        # model) leave C positive definite only on paper; a ridge 1e-12 of its scale keeps it so
        ridge = 1e-12 * np.trace(C, axis1=1, axis2=2).max() / C.shape[-1]
        return np.linalg.inv(np.linalg.cholesky(C + ridge * np.eye(C.shape[-1])))


@dataclass(frozen=True)
class Reweighted:
    """What :func:`reweighted_fit` found."""

    x: NDArray[np.float64]
    theta: NDArray[np.float64]  #: the noise variances, as the last round estimated them
    rounds: int
    converged: bool  #: whether the variances were stable (to 0.1%) within the rounds allowed
    success: bool  #: the last least squares'
    message: str


def reweighted_fit(functions: Callable, variances: Callable, theta0: NDArray[np.float64], x0: NDArray[np.float64], *,
                   x_scale: NDArray[np.float64], tol: float = 1e-10, max_rounds: int = 20) -> Reweighted:
    """Least squares with the noise variances estimated from the data (the "automatic weighting" of
    seed §2.2.4): the residuals whitened under the variances, fitted, the variances re-estimated from
    the new residuals, and so on until they are stable.

    ``functions(theta, x)`` gives the whitened residuals and their Jacobian (two functions of the
    unknowns) under the variances ``theta``, with weights that depend on the unknowns taken at ``x``
    (the round's start); ``variances(x, theta)`` the variances re-estimated at ``x`` from ``theta``.
    :func:`refine_pose` and the estimation core's fit of a sensor whose views' residuals are
    correlated (:mod:`handeye.estimation.core`) share it.
    """
    x, theta = np.asarray(x0, float), np.asarray(theta0, float)
    converged, res, rounds = False, None, 0
    for rounds in range(1, max_rounds + 1):
        fun, jac = functions(theta, x)
        res = least_squares(fun, x, jac=jac, method="trf", x_scale=x_scale, xtol=tol, ftol=tol, gtol=tol)
        x = res.x
        new = variances(x, theta)
        converged = bool(np.all(np.abs(np.log(new / theta)) < 1e-3))
        theta = new
        if converged:
            break
    return Reweighted(x, theta, rounds, converged, bool(res is not None and res.success), "" if res is None else str(res.message))


#: Smallest noise variance the pose refinement estimates (rad^2 or m^2): noise-free data stay exact.
VARIANCE_FLOOR = 1e-24


def pose_mahalanobis(
    result: PoseRefinementResult,
    flange2base: NDArray[np.float64],
    target2cam: NDArray[np.float64],
    setup: str,
    fitted: NDArray[np.bool_] | None = None,
) -> NDArray[np.float64]:
    """Squared Mahalanobis distance of every pose's residual under a noise-model refinement.

    The residual covariance is the noise model's ``C_i`` corrected for the fit: ``C_i - J_i S J_i^T``
    for the poses the refinement used (``fitted``; they pulled X and Z towards themselves) and
    ``C_i + J_i S J_i^T`` for the others (X and Z are uncertain too), with ``S`` the covariance of
    X and Z. Divided by 6, poses that fit the model follow roughly an F(6, 6 n - 12) distribution.
    """
    if result.weighting != "noise_model":
        raise InputMismatchError("pose_mahalanobis needs a 'noise_model' refinement")
    flange2base = np.asarray(flange2base, float)
    target2cam = np.asarray(target2cam, float)
    r, target2flange, _ = pose_residuals(result.X, result.Z, flange2base, target2cam, setup)
    C = np.einsum("k,knij->nij", _theta(result.noise), np.stack(pose_noise_shapes(target2flange, target2cam)))
    J = pose_jacobian(result.X, result.Z, flange2base, target2cam, setup, r)
    P = J @ result.cov @ np.swapaxes(J, 1, 2)
    sign = np.ones(len(r)) if fitted is None else np.where(fitted, -1.0, 1.0)
    V = C + sign[:, None, None] * P
    # a pose with (nearly) full leverage has no residual left to judge: keep a floor of C / 10
    V = np.where(np.linalg.eigvalsh(V)[:, :1, None] > 0, V, 0.1 * C)
    return np.einsum("ni,ni->n", r, np.linalg.solve(V, r[..., None])[..., 0])
