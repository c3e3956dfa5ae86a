"""X and Z from 3D measurements of a depth camera, with its depth scale and bias as unknowns.

Two kinds of measurement, one fit: a board's corners lifted to 3D from the cloud
(:func:`calibrate_depth`), or the centres of spheres found in the cloud (:func:`calibrate_spheres`,
no board at all). Depth cameras are off in their own ways: a depth scale (a factor near 1: the
projector-camera baseline or the depth unit slightly wrong) and a depth bias (an offset along the
rays). Both are estimated with X and Z from the 3D residuals (metres):

    q_measured = (s + b / z) * p,    p = target2cam(X, Z, flange2base) @ P_target

(``p`` scaled along its own ray so that its depth becomes ``s z + b``), each residual weighted by
its noise (the depth noise grows with the square of the distance), that noise scaled to the data,
and the std widened to a leave-one-view-out jackknife where the noise model misses something.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from ..errors import DegenerateMotionError, InputMismatchError
from ..frames.setups import check_setup, predicted_target2cam, robot_world_A
from ..geometry.se3 import make_transform, perturb
from ..options import ROBOT_ACCURACY
from ..sensors.depth.clouds import board_pose, depth_sigma
from .calibration import calibrate_poses, robot_accuracy_cov

__all__ = ["DepthCalibration", "calibrate_depth", "calibrate_spheres", "predict_points", "LATERAL"]

#: Noise across the rays, per metre of depth, to start from (0.2 px at a focal length of ~700 px).
LATERAL = 3e-4


@dataclass(frozen=True)
class DepthCalibration:
    """X and Z from 3D points, with the depth camera's scale and bias."""

    setup: str
    X: NDArray[np.float64]
    Z: NDArray[np.float64]  #: spheres: the first sphere's centre (the rotation is the identity: a sphere has none)
    #: of X: rotation (deg, about the axes of X's reference frame), translation (mm); the data's and
    #: the robot's stated accuracy (which X absorbs unseen)
    std: NDArray[np.float64]
    depth_scale: float  #: measured depth = depth_scale * true depth + depth_bias
    depth_scale_std: float
    depth_bias: float  #: metres
    depth_bias_std: float
    rms_mm: float  #: the noise along the rays (std) at the median depth, from the residuals, mm
    n_points: int
    notes: list[str] = field(default_factory=list)
    #: spheres: (K, 3) centres in Z's frame (base for eye-in-hand, flange for eye-to-hand), metres
    centres: NDArray[np.float64] | None = None
    centres_std: NDArray[np.float64] | None = None  #: (K, 3), mm
    residuals_mm: NDArray[np.float64] | None = None  #: (N,): per view, the RMS 3D residual, mm
    radii: NDArray[np.float64] | None = None  #: spheres: the radii the centres were fitted with, m
    std_data: NDArray[np.float64] | None = None  #: as ``std``, the data's share alone (an exact robot)


def _ray_frames(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """(M, 3, 3): rows along each point's ray and two unit directions across it."""
    along = points / np.linalg.norm(points, axis=1, keepdims=True)
    helper = np.where(np.abs(along[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    first = np.cross(along, helper)
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    return np.stack([along, first, np.cross(along, first)], axis=1)


def _as_measured(p: NDArray[np.float64], scale_step: float, bias: float,
                 radius: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """Points ``p`` (M, 3) as the camera measures them: scaled along their rays to depth ``s z + b``
    (``scale_step`` = s - 1); with ``radius`` (M,), centres of spheres fitted with that radius to a
    cap whose depths are so scaled, which lie ``(s - 1) r`` short along their rays."""
    q = p * (1.0 + scale_step + bias / p[:, 2])[:, None]
    if radius is None:
        return q
    return q - (scale_step * radius)[:, None] * p / np.linalg.norm(p, axis=1, keepdims=True)


@dataclass
class _Problem:
    """A weighted 3D fit: ``predict(x)`` (M, 3) against ``meas``, residuals whitened by ``basis``
    (M, 3, 3) and divided by ``noise`` (M, 3), whose column ``groups`` are scaled to the data."""

    predict: Callable[[NDArray[np.float64]], NDArray[np.float64]]
    meas: NDArray[np.float64]
    basis: NDArray[np.float64]
    noise: NDArray[np.float64]
    owner: NDArray[np.intp]
    n_views: int
    groups: tuple[tuple[int, ...], ...]

    def residuals(self, x: NDArray[np.float64], noise: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        r = self.meas - self.predict(x)
        return (np.einsum("mij,mj->mi", self.basis, r) / (self.noise if noise is None else noise)).ravel()


def _solve(problem: _Problem, n: int, jackknife: bool = True
           ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The unknowns, their std (the larger of the fit's and the jackknife's) and the per-point
    residuals (M, 3) in metres, after the noise is scaled to the data."""
    x = np.zeros(n)
    for _ in range(2):
        res = least_squares(problem.residuals, x, method="lm", x_scale=np.full(n, 1e-3))
        x = res.x
        w = res.fun.reshape(-1, 3)
        dof = max(res.fun.size - n, 1) / res.fun.size
        factor = np.ones(3)
        for group in problem.groups:
            factor[list(group)] = np.sqrt(np.mean(w[:, list(group)] ** 2) / dof)
        problem.noise = problem.noise * factor
    s2 = float(res.fun @ res.fun) / max(res.fun.size - n, 1)  # ~1 once the noise is scaled
    std = np.sqrt(np.clip(np.diag(s2 * np.linalg.pinv(res.jac.T @ res.jac)), 0.0, None))
    if jackknife:
        std = np.maximum(std, _jackknife(problem, x))
    return x, std, problem.meas - problem.predict(x)


def _jackknife(problem: _Problem, x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per unknown, the leave-one-view-out jackknife std: what the noise model misses (the corner
    noise's share along tilted boards, errors that differ from view to view) widens X's std."""
    n_views = problem.n_views
    if n_views < 4:
        return np.zeros_like(x)
    rows = np.repeat(problem.owner, 3)
    fits = []
    for k in range(n_views):
        keep = rows != k
        fit = least_squares(lambda y: problem.residuals(y)[keep], x, method="lm", x_scale=np.full(len(x), 1e-3))
        fits.append(fit.x)
    fits = np.array(fits)
    return np.sqrt((n_views - 1) / n_views * np.sum(np.square(fits - fits.mean(axis=0)), axis=0))


def _depth_notes(scale, scale_std, bias, bias_std) -> list[str]:
    notes = []
    if abs(scale - 1.0) > 3 * scale_std:
        notes.append(f"depth scale {scale:.5f} +- {scale_std:.5f}: the camera's depths are {1e2 * (scale - 1):+.3f}% off "
                     "(beyond 3 std); correct the depth unit or the camera's calibration, or keep this factor")
    if abs(bias) > 3 * bias_std:
        notes.append(f"depth bias {1e3 * bias:+.2f} +- {1e3 * bias_std:.2f} mm along the rays (beyond 3 std)")
    return notes


def _x_std(X: NDArray[np.float64], std: NDArray[np.float64],
           robot_accuracy: tuple[float, float] | None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """X's std (deg, mm) with the robot's accuracy, and the data's alone, from the fit's std (rad, m)."""
    data = np.square(std[:6])
    total = data + (np.diag(robot_accuracy_cov(X, robot_accuracy)) if robot_accuracy is not None else 0.0)
    scale = np.r_[np.full(3, np.degrees(1.0)), np.full(3, 1e3)]
    return np.sqrt(total) * scale, np.sqrt(data) * scale


def _per_view_rms(residual: NDArray[np.float64], owner: NDArray[np.intp], n_views: int) -> NDArray[np.float64]:
    sq = np.bincount(owner, np.sum(residual**2, axis=1), minlength=n_views)
    count = np.maximum(np.bincount(owner, minlength=n_views), 1)
    return 1e3 * np.sqrt(sq / count)


def calibrate_depth(flange2base: NDArray[np.float64], object_points: list[NDArray[np.float64]],
                    points: list[NDArray[np.float64]], setup: str = "eye_in_hand",
                    fit_depth: bool = True, robot_accuracy: tuple[float, float] | None = ROBOT_ACCURACY,
                    uncertainty: bool = True) -> DepthCalibration:
    """X and Z from robot poses and the board's corners lifted to 3D, with the depth scale and bias.

    Parameters
    ----------
    flange2base : (N, 4, 4)
    object_points : list of N arrays (M_i, 3)
        The corners in the target's frame (metres).
    points : list of N arrays (M_i, 3)
        The same corners measured in the camera frame (:func:`~handeye.sensors.depth.plane_points` for a
        flat target, :func:`~handeye.sensors.depth.lift_points` for any; NaN rows: no depth).
    setup : {'eye_in_hand', 'eye_to_hand'}
    fit_depth : bool
        Estimate the depth scale and bias (else taken as 1 and 0).
    robot_accuracy : (deg, mm) or None
        The robot's absolute accuracy per axis, added to X's std (None: an exact robot).
    uncertainty : bool
        Widen the std to the leave-one-view-out jackknife (False: the fit's std alone; faster).

    Returns
    -------
    DepthCalibration
        Its notes say when the depth scale or bias differ from 1 / 0 beyond 3 std.
    """
    check_setup(setup)
    F = np.asarray(flange2base, dtype=float)
    if not (len(F) == len(object_points) == len(points)):
        raise InputMismatchError(f"{len(F)} robot poses, {len(object_points)} point sets and {len(points)} lifted sets: "
                                 "give one of each per view")
    keep = [np.isfinite(q).all(axis=1) for q in points]
    poses = [board_pose(o, q) for o, q in zip(object_points, points)]
    start = calibrate_poses(F, np.array([T for T, _ in poses]), setup, refine="pose", progress=False)
    obj = np.concatenate([np.asarray(o, float)[k] for o, k in zip(object_points, keep)])
    meas = np.concatenate([np.asarray(q, float)[k] for q, k in zip(points, keep)])
    owner = np.repeat(np.arange(len(F)), [int(k.sum()) for k in keep])
    z = meas[:, 2]
    basis = _ray_frames(meas)  # per point: along its ray, and two directions across it
    # the noise along the rays (depth; and a corner found off its place moves along the board, so
    # along the ray too, by tan(ray, normal)) and across them (the corner's pixel noise, times the
    # depth) differ; each is scaled to the data
    normals = np.array([T[:3, 2] for T, _ in poses])[owner]
    cos = np.clip(np.abs(np.einsum("mi,mi->m", basis[:, 0], normals)), 0.2, 1.0)
    along = np.sqrt(depth_sigma(z) ** 2 + (LATERAL * z) ** 2 * (1.0 / cos**2 - 1.0))
    n = 14 if fit_depth else 12

    def predict(x):
        T = predicted_target2cam(perturb(start.X, x[0:3], x[3:6]), perturb(start.Z, x[6:9], x[9:12]), F, setup)
        p = np.einsum("mij,mj->mi", T[owner, :3, :3], obj) + T[owner, :3, 3]
        return _as_measured(p, x[12], x[13]) if fit_depth else p

    problem = _Problem(predict, meas, basis, np.stack([along, LATERAL * z, LATERAL * z], axis=1), owner, len(F),
                       ((0,), (1, 2)))
    x, std, residual = _solve(problem, n, uncertainty)
    scale, bias = (1.0 + x[12], x[13]) if fit_depth else (1.0, 0.0)
    scale_std, bias_std = (std[12], std[13]) if fit_depth else (0.0, 0.0)
    notes = _depth_notes(scale, scale_std, bias, bias_std) if fit_depth else []
    X = perturb(start.X, x[0:3], x[3:6])
    x_std, x_std_data = _x_std(X, std, robot_accuracy)
    return DepthCalibration(setup, X, perturb(start.Z, x[6:9], x[9:12]), x_std, float(scale), float(scale_std),
                            float(bias), float(bias_std), float(np.median(problem.noise[:, 0])) * 1e3, len(meas), notes,
                            residuals_mm=_per_view_rms(residual, owner, len(F)), std_data=x_std_data)


def _sphere_start(A, centres, view, sphere, n_spheres):
    """X and the spheres' centres from ``A_i X c = p_k`` (linear in R_X, t_X and the p_k; R_X
    then made a rotation and the rest solved again), or DegenerateMotionError."""
    m = len(centres)
    R_A, t_A = A[view, :3, :3], A[view, :3, 3]
    cols = 12 + 3 * n_spheres
    M = np.zeros((m, 3, cols))
    M[:, :, :9] = np.einsum("mij,mk->mijk", R_A, centres).reshape(m, 3, 9)  # R_A (R_X c), R_X row-major
    M[:, :, 9:12] = R_A
    for axis in range(3):
        M[np.arange(m), axis, 12 + 3 * sphere + axis] = -1.0
    M = M.reshape(3 * m, cols)
    rhs = -t_A.reshape(-1)
    sv = np.linalg.svd(M, compute_uv=False)
    if 3 * m < cols or sv[-1] < 1e-6 * sv[0]:
        raise DegenerateMotionError(
            f"the sphere's centres in {len(np.unique(view))} views do not determine X ({3 * m} equations for {cols} "
            "unknowns, or the robot turned about one axis only): capture more views, turning the flange about "
            "at least two different axes by 30 deg or more, with the sphere in different parts of the image")
    sol = np.linalg.lstsq(M, rhs, rcond=None)[0]
    U, _, Vt = np.linalg.svd(sol[:9].reshape(3, 3))
    R_X = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    rest = np.linalg.lstsq(M[:, 9:], rhs - M[:, :9] @ R_X.ravel(), rcond=None)[0]
    return make_transform(R_X, rest[:3]), rest[3:].reshape(n_spheres, 3)


def calibrate_spheres(flange2base: NDArray[np.float64], centres: NDArray[np.float64], setup: str = "eye_to_hand",
                      covariances: NDArray[np.float64] | None = None, fit_depth: bool = True,
                      robot_accuracy: tuple[float, float] | None = ROBOT_ACCURACY,
                      uncertainty: bool = True, radii: NDArray[np.float64] | None = None) -> DepthCalibration:
    """X from the centres of spheres measured by a depth camera, without any board.

    Eye-to-hand: a sphere on the flange, seen by the fixed camera (``Z`` is its centre in the
    flange frame). Eye-in-hand: one or more spheres fixed in the cell, seen by the camera on the
    flange (``Z``: the first one's centre in the base frame).

    Parameters
    ----------
    flange2base : (N, 4, 4)
    centres : (N, 3) or (N, K, 3)
        Per view, the centre of each of K spheres in the camera frame (metres; NaN: not seen), e.g.
        from :func:`~handeye.sensors.depth.find_spheres`.
    setup : {'eye_in_hand', 'eye_to_hand'}
    covariances : (N, 3, 3) or (N, K, 3, 3), optional
        The centres' covariances (:class:`~handeye.sensors.depth.Sphere`'s ``cov``): their shape weights each
        centre (the cap a camera sees pins a sphere least along the ray); their size is scaled to the
        data. Default: the depth noise along the ray, a third of it across.
    fit_depth : bool
        Estimate the depth scale and bias (else taken as 1 and 0).
    robot_accuracy : (deg, mm) or None
        The robot's absolute accuracy per axis, added to X's std (None: an exact robot).
    uncertainty : bool
        Widen the std to the leave-one-view-out jackknife (False: the fit's std alone; faster).
    radii : (K,), optional
        The spheres' radii (m): a centre fitted with the true radius to a cap whose depths are
        scaled by ``s`` lies ``(s - 1) r`` short along its ray; modelled, so the bias is the camera's.
    """
    check_setup(setup)
    F = np.asarray(flange2base, dtype=float)
    C = np.asarray(centres, dtype=float)
    C = C[:, None] if C.ndim == 2 else C
    if C.ndim != 3 or C.shape[2] != 3 or len(C) != len(F):
        raise InputMismatchError(f"{len(F)} robot poses and centres of shape {np.shape(centres)}: give one centre "
                                 "(3,) per view and sphere, (N, 3) or (N, K, 3)")
    n_views, n_spheres = C.shape[:2]
    view, sphere = np.nonzero(np.isfinite(C).all(axis=2))
    meas = C[view, sphere]
    if covariances is None:
        basis = _ray_frames(meas)
        noise = depth_sigma(meas[:, 2])[:, None] * np.array([1.0, 1 / 3, 1 / 3])
    else:
        cov = np.asarray(covariances, dtype=float)
        cov = (cov[:, None] if cov.ndim == 3 else cov)[view, sphere]
        basis = np.linalg.inv(np.linalg.cholesky(cov))  # whitens each centre's residual
        noise = np.ones((len(meas), 3))
    A = robot_world_A(F, setup)
    X0, p0 = _sphere_start(A, meas, view, sphere, n_spheres)
    radius = None if radii is None else np.asarray(radii, float)[sphere]
    depth = 2 if fit_depth else 0
    n = 6 + 3 * n_spheres + depth

    def predict(x):
        X = perturb(X0, x[0:3], x[3:6])
        p = p0 + x[6:6 + 3 * n_spheres].reshape(n_spheres, 3)
        Z = np.broadcast_to(np.eye(4), (len(meas), 4, 4)).copy()
        Z[:, :3, 3] = p[sphere]
        c = predicted_target2cam(X, Z, F[view], setup)[:, :3, 3]
        return _as_measured(c, x[-2], x[-1], radius) if fit_depth else c

    problem = _Problem(predict, meas, basis, noise, view, n_views, ((0, 1, 2),))
    x, std, residual = _solve(problem, n, uncertainty)
    X = perturb(X0, x[0:3], x[3:6])
    p = p0 + x[6:6 + 3 * n_spheres].reshape(n_spheres, 3)
    scale, bias = (1.0 + x[-2], x[-1]) if fit_depth else (1.0, 0.0)
    scale_std, bias_std = (std[-2], std[-1]) if fit_depth else (0.0, 0.0)
    notes = _depth_notes(scale, scale_std, bias, bias_std) if fit_depth else []
    along = np.einsum("mi,mi->m", residual, meas / np.linalg.norm(meas, axis=1, keepdims=True))
    x_std, x_std_data = _x_std(X, std, robot_accuracy)
    return DepthCalibration(setup, X, make_transform(np.eye(3), p[0]), x_std, float(scale), float(scale_std), float(bias),
                            float(bias_std), float(np.sqrt(np.mean(along**2))) * 1e3, len(meas), notes, centres=p,
                            centres_std=1e3 * std[6:6 + 3 * n_spheres].reshape(n_spheres, 3),
                            residuals_mm=_per_view_rms(residual, view, n_views), std_data=x_std_data,
                            radii=None if radii is None else np.asarray(radii, float))


def predict_points(cal: DepthCalibration, flange2base: NDArray[np.float64],
                   object_points: list[NDArray[np.float64]] | None = None) -> list[NDArray[np.float64]]:
    """Per view, where the camera measures the target's points (a board's ``object_points``) or
    the spheres' centres (``object_points`` None: (K, 3) per view), predicted from the robot pose
    alone with X, Z, the depth scale and bias of ``cal`` (the model the fit used)."""
    F = np.asarray(flange2base, dtype=float)
    step = cal.depth_scale - 1.0
    if cal.centres is not None:
        Z = np.broadcast_to(np.eye(4), (len(cal.centres), 4, 4)).copy()
        Z[:, :3, 3] = cal.centres
        c = predicted_target2cam(cal.X, Z, F[:, None], cal.setup)[..., :3, 3]  # (N, K, 3)
        return [_as_measured(q, step, cal.depth_bias, cal.radii) for q in c]
    T = predicted_target2cam(cal.X, cal.Z, F, cal.setup)
    return [_as_measured(o @ t[:3, :3].T + t[:3, 3], step, cal.depth_bias) for o, t in zip(object_points or [], T)]
