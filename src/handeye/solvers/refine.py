"""What the pose and pixel refinements share, and the pixel refinement's own engine.

``refine_pose`` moved to :mod:`handeye.estimation.refinement`: the estimation core fits it
(:class:`~handeye.sensors.camera.poses.PoseDifferences`); this module keeps its result and prior
records, the noise model's variance estimation (:func:`fit_variances`, :func:`reweighted_fit`,
:func:`block_whitening`: the core's fit of correlated residuals uses them) and
:func:`pose_mahalanobis`. ``handeye.solvers.refine.refine_pose`` still finds it for one release.

``refine_reprojection``: the thesis's "future work" (§6.1) and Horaud-Dornaika's lesson (estimate
everything together): with target detections available, X and Z are refined jointly so that every
target point projects onto its detection in every image. The camera pose of image i is not a
free unknown but follows from the robot pose (docs/guide.md, Conventions):

* eye-in-hand: ``target2cam_i = inv(X) @ inv(flange2base_i) @ Z`` (X = cam2flange, Z = target2base);
* eye-to-hand: ``target2cam_i = inv(X) @ flange2base_i @ Z`` (X = cam2base, Z = target2flange).

12 unknowns (rotation-vector increments and translations of X and Z), two residuals per point;
``scipy.optimize.least_squares`` with an optional robust loss (``soft_l1``, ``huber``...). With 12
unknowns shared by every residual the Jacobian is dense. With ``robot_noise`` each robot pose also
gets a 6-unknown correction under a Gaussian prior (the robot is not exact); image i's residuals
then depend on X, Z and its own correction only, and the Jacobian is differenced by groups of
columns with disjoint rows (12 + 6 residual evaluations instead of 12 + 6N).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix

from .._shared.moved import forward_names
from ..errors import InputMismatchError
from ..frames.setups import predicted_target2cam, robot_world_A_inv, setup_info
from ..geometry.se3 import perturb, rotation_of_valid, skew, so3_left_jacobian
from ..sensors.camera.pnp import project_points, project_points_many, projection_jacobians, solve_pnp
from ..sensors.camera.poses import NOISE_TERMS, pose_jacobian, pose_noise_shapes, pose_residuals
from ..sensors.camera.targets import Detection
from ._common import _xz_increment

__all__ = ["PoseRefinementResult", "ReprojectionResult", "Reweighted", "TranslationPriors", "VARIANCE_FLOOR", "block_whitening",
           "fit_variances", "pose_mahalanobis", "refine_reprojection", "reweighted_fit", "predicted_target2cam"]

__getattr__ = forward_names(__name__)  # refine_pose: now the estimation core's (handeye.estimation.refinement)


@dataclass(frozen=True)
class ReprojectionResult:
    """X and Z refined on the pixel errors (:func:`refine_reprojection`), with their covariance and residuals."""

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


def refine_reprojection(
    X0: NDArray[np.float64],
    Z0: NDArray[np.float64],
    flange2base: NDArray[np.float64],
    object_points: list[NDArray[np.float64]],
    image_points: list[NDArray[np.float64]],
    K: NDArray[np.float64],
    dist: NDArray[np.float64],
    setup: str,
    loss: str = "linear",
    f_scale: float = 1.0,
    refine_intrinsics: bool = False,
    robust: bool = False,
    robot_noise: tuple[float, float] | None = None,
    sparse: bool = True,
    tol: float = 1e-12,
) -> ReprojectionResult:
    """Refine X and Z by minimising the reprojection error of all target points in all images.

    Parameters
    ----------
    X0, Z0 : (4, 4)
        Start (a closed-form solution).
    flange2base : (N, 4, 4)
    object_points, image_points : lists of N arrays (M_i, 3) and (M_i, 2)
        Target points (target frame, metres) and their detections (pixels), image by image.
    K, dist
        Camera intrinsics (held fixed).
    setup : {'eye_in_hand', 'eye_to_hand'}
    loss, f_scale
        As ``scipy.optimize.least_squares`` (``f_scale`` in pixels): ``soft_l1`` or ``huber``
        limit the pull of wrong detections.
    refine_intrinsics : bool
        Also refine fx, fy, cx, cy and five distortion terms (k1 k2 p1 p2 k3). The robot poses tie
        all views together, so this is far better conditioned than a camera calibration alone:
        use it when the intrinsics were estimated from the same images.
    robust : bool
        Wrong detections: a first pass with the ``soft_l1`` loss (``f_scale`` px), then every point
        whose residual exceeds 5 sigma (sigma from the median residual) is dropped and the inliers
        are refitted by plain least squares, so the covariance stays that of a least-squares fit.
        Measured (15 poses, 0.3 px, 10% of points moved by 20 px): translation error 1.11x the
        clean case, against 15x without.
    robot_noise : (rad, m), optional
        The robot poses are not exact: each gets its own small correction (rotation vector and
        translation, 6 unknowns per image) with a Gaussian prior of these standard deviations per
        axis (e.g. the controller's repeatability), weighed against the pixel noise, which is
        estimated from free per-image PnP fits. X and Z then stop absorbing the robot's errors.
        The corrected robot poses are returned (``flange2base``).
    sparse : bool
        Analytic Jacobians, corrections eliminated (beyond 8 distortion terms: differences grouped
        by image); ``False``: scipy's plain differences (with ``robot_noise``, on the joint problem),
        the reference the fast path is measured against.
    tol : float
        ``least_squares``' xtol, ftol and gtol (refits from a nearby start, as in cross-validation,
        need far less than the default).
    """
    if robust:
        return _robust_reprojection(X0, Z0, flange2base, object_points, image_points, K, dist, setup, f_scale,
                                    refine_intrinsics, robot_noise, sparse)
    obj = [np.ascontiguousarray(o, dtype=np.float64) for o in object_points]
    img = [np.asarray(i, dtype=np.float64) for i in image_points]
    K0 = np.asarray(K, dtype=float)
    d0 = np.zeros(5)
    dist = np.asarray(dist, dtype=float).ravel()
    d0[: min(5, len(dist))] = dist[:5]
    extra_dist = dist[5:]  # higher-order terms, if any, are kept fixed

    n_img = len(obj)
    n_glob = 21 if refine_intrinsics else 12
    counts = np.cumsum([0] + [len(o) for o in obj])
    if robot_noise is not None:
        (sig_rot, sig_t), prior_w = _robot_prior(robot_noise, obj, img, K0, dist)
    analytic = len(extra_dist) <= 3  # up to 8 coefficients: OpenCV's rational model
    if robot_noise is not None and sparse and analytic:
        return _refine_with_corrections(X0, Z0, K0, d0, extra_dist, flange2base, obj, img, setup, n_glob, counts,
                                        prior_w, loss, f_scale, tol)
    unpack = _reprojection_unpacker(X0, Z0, K0, d0, extra_dist, flange2base, refine_intrinsics,
                                    robot_noise is not None, n_glob)

    calls = [0]
    # least_squares evaluates at x0 again, and a Jacobian needs the value where it is taken, which
    # the solver has just computed: both come from the memo
    residuals = _remember_last(_reprojection_residuals(unpack, obj, img, setup, n_glob,
                                                       prior_w if robot_noise is not None else None, calls))
    n = n_glob + (6 * n_img if robot_noise is not None else 0)
    x0 = np.zeros(n)
    r0 = residuals(x0)
    # increments of ~1 mrad and ~1 mm move the pixels about as much as ~1 px of focal length or
    # ~1e-3 of distortion
    scale = np.r_[np.full(12, 1e-3), np.ones(4), np.full(5, 1e-3)][:n_glob]
    kw = {"method": "trf"}
    if robot_noise is not None:
        scale = np.r_[scale, np.tile(np.r_[np.full(3, sig_rot), np.full(3, sig_t)], n_img)]
        if sparse:
            kw["jac"] = _grouped_jacobian(residuals, _robot_groups(counts, n_glob))
    res = (_analytic_least_squares(residuals, _reprojection_jacobian(unpack, obj, setup, n_glob), x0, r0.size, loss,
                                   f_scale, scale, tol) if robot_noise is None and analytic and sparse else
           least_squares(residuals, x0, loss=loss, f_scale=f_scale, x_scale=scale, xtol=tol, ftol=tol, gtol=tol, **kw))
    return _reprojection_result(res, unpack, r0, counts, n, loss, calls[0])


def _analytic_least_squares(residuals, jac, x0, m: int, loss: str, f_scale: float, scale, tol: float):
    """``least_squares`` of ``residuals`` with the analytic Jacobian ``jac``: soft-L1 as plain least
    squares (:func:`_soft_l1_as_plain`), then MINPACK's Levenberg-Marquardt where it applies
    (:func:`_method`); ``fun`` of the result is the residuals themselves either way."""
    n = x0.size
    if loss == "soft_l1" and m >= n:
        fun, jac_plain = _soft_l1_as_plain(residuals, jac, f_scale)
        res = least_squares(fun, x0, jac=jac_plain, method="lm", x_scale=scale, xtol=tol, ftol=tol, gtol=tol)
        res.fun = residuals(res.x)  # the pixel residuals, not their soft-L1 form
        return res
    return least_squares(residuals, x0, jac=jac, method=_method(loss, m, n), loss=loss, f_scale=f_scale,
                         x_scale=scale, xtol=tol, ftol=tol, gtol=tol)


def _soft_l1_as_plain(residuals, jac, f_scale: float):
    """``residuals`` and ``jac`` for which plain least squares minimises the soft-L1 cost of
    ``residuals`` (scaled by ``f_scale``): each residual ``r`` becomes ``r g`` with ``g =
    sqrt(2 / (s + 1))``, ``s = sqrt(1 + (r / f_scale)^2)``, whose square is ``f_scale^2 rho(z)``,
    ``rho(z) = 2 (sqrt(1 + z) - 1)``; its derivative is ``1 / (s g)``. The same cost, so the same
    minimum, but MINPACK's Levenberg-Marquardt (a QR per iteration) can take it where scipy's
    robust losses need trf (an SVD of the whole Jacobian per iteration)."""

    def parts(r):
        s = np.sqrt(1.0 + (r / f_scale) ** 2)
        g = np.sqrt(2.0 / (s + 1.0))
        return s, g

    def fun(x):
        r = residuals(x)
        return r * parts(r)[1]

    def jac_plain(x):
        s, g = parts(residuals(x))
        return jac(x) * (1.0 / (s * g))[:, None]

    return fun, jac_plain


def _method(loss: str, m: int, n: int) -> str:
    """``least_squares``' method for an analytic, dense Jacobian: MINPACK's Levenberg-Marquardt (a QR
    of the Jacobian per iteration) where it applies (plain least squares, no fewer residuals than
    unknowns; soft-L1 too, by :func:`_soft_l1_as_plain`), as trf's SVD of the whole Jacobian every
    iteration dominates large boards (30 images of a 28 x 17 board with the intrinsics: 0.09 s
    against 0.45 s, the same optimum to 1e-9)."""
    return "lm" if loss == "linear" and m >= n else "trf"


def _robot_prior(robot_noise, obj, img, K, dist) -> tuple[tuple[float, float], NDArray[np.float64]]:
    """The robot pose corrections' prior: their stds (rad, m), checked, and the weights of their
    residual rows in pixel units, the pixel noise taken from free per-image pose fits (which absorb
    any robot error)."""
    sig_rot, sig_t = (float(v) for v in robot_noise)
    if not (sig_rot > 0 and sig_t > 0 and np.isfinite(sig_rot) and np.isfinite(sig_t)):
        raise InputMismatchError(f"robot_noise {robot_noise}: give positive standard deviations (rad, m)")
    sigma_px = _pixel_noise(obj, img, K, dist)
    return (sig_rot, sig_t), np.tile(np.r_[np.full(3, sigma_px / sig_rot), np.full(3, sigma_px / sig_t)], len(obj))


def _reprojection_unpacker(X0, Z0, K0, d0, extra_dist, flange2base, refine_intrinsics: bool, robot_corrections: bool,
                           n_glob: int):
    """``unpack(x) -> (X, Z, K, dist, flange2base)`` for the unknowns of :func:`refine_reprojection`:
    rotation-vector (left) and translation increments of X and Z, then the intrinsics (fx, fy, cx,
    cy, k1 k2 p1 p2 k3) when refined, then a 6-vector correction per robot pose when allowed."""
    n_img = len(flange2base)

    def unpack(x):
        X, Z = _xz_increment(x, X0, Z0)
        Kx, dx = K0, np.concatenate([d0, extra_dist])
        if refine_intrinsics:
            Kx = K0.copy()
            Kx[0, 0] += x[12]
            Kx[1, 1] += x[13]
            Kx[0, 2] += x[14]
            Kx[1, 2] += x[15]
            dx = np.concatenate([d0 + x[16:21], extra_dist])
        F = flange2base
        if robot_corrections:
            d = x[n_glob:].reshape(n_img, 6)
            F = perturb(flange2base, d[:, :3], d[:, 3:])
        return X, Z, Kx, dx, F

    return unpack


def _reprojection_residuals(unpack, obj, img, setup: str, n_glob: int, prior_w, calls: list[int]):
    """The residual function of :func:`refine_reprojection`: pixel errors of every point of every
    image, then (``prior_w`` given) the prior on each robot pose correction in pixel units.
    ``calls[0]`` counts the evaluations."""

    # every point of every image in one array, with the image it belongs to (an image without
    # points projects nothing)
    points = np.concatenate([np.reshape(o, (-1, 3)) for o in obj])
    detected = np.concatenate([np.reshape(i, (-1, 2)) for i in img]).ravel()
    owner = np.repeat(np.arange(len(obj)), [len(o) for o in obj])

    def residuals(x):
        calls[0] += 1
        X, Z, Kx, dx, F = unpack(x)
        T = predicted_target2cam(X, Z, F, setup)
        px = project_points_many(T, points, owner, Kx, dx).ravel() - detected
        if prior_w is not None:
            return np.concatenate([px, x[n_glob:] * prior_w])
        return px

    return residuals


def _cross_rows(a: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.float64]:
    """``a[m, r] x p[m]`` for rows ``a (M, R, 3)`` and points ``p (M, 3)``: ``a^T [p]x`` row by row."""
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    px, py, pz = p[:, None, 0], p[:, None, 1], p[:, None, 2]
    return np.stack([ay * pz - az * py, az * px - ax * pz, ax * py - ay * px], axis=-1)


def _pixel_blocks(X, Z, Kx, dx, F, points, owner, setup: str, n_glob: int, x_rot, c_rot=None):
    """Pixels ``(M, 2)`` of the target points and their derivatives: ``(M, 2, n_glob)`` against
    the global unknowns (X, Z, the intrinsics) and, with robot corrections ``c_rot`` (their rotation
    vectors, ``(N, 3)``), ``(M, 2, 6)`` against each point's image's correction (else None).

    With ``H_i = inv(A_i)`` (:func:`~handeye.frames.setups.robot_world_A_inv`) a target point ``P`` is seen
    at ``p = R_X^T (H_i Z P - t_X)``. For the left rotation increments and added translations of
    the unknowns: ``dp/dw_X = [p]x R_X^T``, ``dp/dv_X = -R_X^T``, ``dp/dw_Z = -G_i [R_Z P]x``,
    ``dp/dv_Z = G_i`` with ``G_i = R_X^T R_Hi``; a robot correction of ``flange2base_i`` (rotation
    ``w``, translation ``v``, ``q = Z P``) moves ``H_i q`` by ``-[R_F q]x w + v`` (eye-to-hand,
    ``H = F``) or ``R_F^T [q - t_F]x w - R_F^T v`` (eye-in-hand, ``H = inv(F)``). The unknowns are
    rotation vectors composed on the left (``exp(w) R_0``), so each rotation block is the left
    increment's times the left Jacobian at ``w`` (``x_rot``: X's and Z's, ``(2, 3)``). The pixels
    follow by :func:`~handeye.sensors.camera.pnp.projection_jacobians`."""
    m = len(points)
    R_Xt = X[:3, :3].T
    H = robot_world_A_inv(F, setup)
    G = (R_Xt @ H[:, :3, :3])[owner]  # (M, 3, 3)
    zp = points @ Z[:3, :3].T  # R_Z P
    q = zp + Z[:3, 3]  # Z P
    p = np.einsum("mij,mj->mi", G, q) + (R_Xt @ (H[:, :3, 3] - X[:3, 3]).T).T[owner]
    pixels, d_point, d_intr = projection_jacobians(p, Kx, dx)
    J_lx, J_lz = so3_left_jacobian(x_rot)
    d_G = d_point @ G
    J_glob = np.empty((m, 2, n_glob))
    # rows a^T [p]x = (a x p)^T: cross products, then one product with a 3x3 for all rows
    J_glob[:, :, 0:3] = (_cross_rows(d_point, p).reshape(-1, 3) @ (R_Xt @ J_lx)).reshape(m, 2, 3)
    J_glob[:, :, 3:6] = -(d_point.reshape(-1, 3) @ R_Xt).reshape(m, 2, 3)
    J_glob[:, :, 6:9] = -(_cross_rows(d_G, zp).reshape(-1, 3) @ J_lz).reshape(m, 2, 3)
    J_glob[:, :, 9:12] = d_G
    if n_glob > 12:
        J_glob[:, :, 12:] = d_intr
    if c_rot is None:
        return pixels, J_glob, None
    R_F, t_F = F[owner, :3, :3], F[owner, :3, 3]
    if setup_info(setup).camera_on_flange:  # H = inv(F)
        R_Ft = np.swapaxes(R_F, -1, -2)
        dh = np.concatenate([R_Ft @ skew(q - t_F), -R_Ft], axis=2)
    else:  # H = F: R_F q, with q in the flange frame
        dh = np.concatenate([-skew(np.einsum("mij,mj->mi", R_F, q)), np.broadcast_to(np.eye(3), (m, 3, 3))], axis=2)
    dh[:, :, :3] = dh[:, :, :3] @ so3_left_jacobian(c_rot)[owner]
    return pixels, J_glob, (d_point.reshape(-1, 3) @ R_Xt).reshape(m, 2, 3) @ dh


def _reprojection_jacobian(unpack, obj, setup: str, n_glob: int):
    """The analytic Jacobian of :func:`_reprojection_residuals` without robot corrections (dense),
    for ``least_squares`` (see :func:`_pixel_blocks`): one pass over the points instead of one
    residual evaluation per unknown."""
    points = np.concatenate([np.reshape(o, (-1, 3)) for o in obj])
    owner = np.repeat(np.arange(len(obj)), [len(o) for o in obj])

    def jac(x):
        X, Z, Kx, dx, F = unpack(x)
        return _pixel_blocks(X, Z, Kx, dx, F, points, owner, setup, n_glob, np.stack([x[0:3], x[6:9]]))[1].reshape(
            2 * len(points), n_glob)

    return jac


#: ``rho'(z)`` of scipy's robust losses (``least_squares``' definitions).
_LOSS_WEIGHTS = {
    "soft_l1": lambda z: 1.0 / np.sqrt(1.0 + z),
    "huber": lambda z: np.where(z <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z, 1.0))),
    "cauchy": lambda z: 1.0 / (1.0 + z),
    "arctan": lambda z: 1.0 / (1.0 + z * z),
}

#: Gauss-Newton steps for the robot corrections per evaluation, and when they have settled (the
#: step against the prior's std).
_INNER_STEPS = 12
_INNER_TOL = 1e-10


def _refine_with_corrections(X0, Z0, K0, d0, extra_dist, flange2base, obj, img, setup, n_glob, counts, prior_w,
                             loss, f_scale, tol) -> ReprojectionResult:
    """:func:`refine_reprojection` with robot pose corrections, the corrections eliminated.

    For given X, Z (and intrinsics) each image's correction is a 6-unknown problem of its own
    (its pixels and its prior), solved by Gauss-Newton, batched over the images and warm-started
    from the last solution; ``least_squares`` then sees the global unknowns only (variable
    projection), with the Jacobian of the residuals along the corrections' optimum:
    ``J_g - A (A^T A + P)^-1 A^T J_g`` per image (``A``: the pixels against its correction, ``P``:
    the prior's weights squared). Memory and time grow with the points, not with the square of the
    images: the joint Jacobian over 12 + 6N unknowns took 1.3 GB and 13 s at 60 images of 476
    points. With a robust loss the corrections are solved with the same loss's weights.
    """
    n_img = len(obj)
    points = np.concatenate([np.reshape(o, (-1, 3)) for o in obj])
    detected = np.concatenate([np.reshape(i, (-1, 2)) for i in img])
    owner = np.repeat(np.arange(n_img), [len(o) for o in obj])
    m = len(points)
    glob = _reprojection_unpacker(X0, Z0, K0, d0, extra_dist, flange2base, n_glob == 21, False, n_glob)
    w2 = prior_w.reshape(n_img, 6) ** 2
    by_image = csr_matrix((np.ones(m), (owner, np.arange(m))), shape=(n_img, m))  # sums per image
    state = {"c": np.zeros((n_img, 6)), "x": None, "A": None, "J": None, "W": None}
    calls = [0]

    def robust_weights(r):  # rho'(z), z = (r / f_scale)^2: the loss's weights of the squared residuals
        if loss == "linear":
            return None
        z = (r / f_scale) ** 2
        return _LOSS_WEIGHTS[loss](z)

    def weighted_normal(A, W):
        """The loss-weighted rows ``A W`` and each image's 6x6 normal matrix ``A^T W A + P``."""
        Aw = A if W is None else A * W[:, :, None]
        normal = (by_image @ np.einsum("mri,mrj->mij", Aw, A).reshape(m, 36)).reshape(n_img, 6, 6)
        normal[:, np.arange(6), np.arange(6)] += w2
        return Aw, normal

    def evaluate(x):
        if state["x"] is not None and np.array_equal(x, state["x"]):
            return
        calls[0] += 1
        X, Z, Kx, dx, _ = glob(x)
        x_rot = np.stack([x[0:3], x[6:9]])
        c = state["c"].copy()
        for _ in range(_INNER_STEPS):
            F = perturb(flange2base, c[:, :3], c[:, 3:])
            px, J_glob, A = _pixel_blocks(X, Z, Kx, dx, F, points, owner, setup, n_glob, x_rot, c[:, :3])
            r = px - detected
            Aw, normal = weighted_normal(A, robust_weights(r))
            grad = by_image @ np.einsum("mri,mr->mi", Aw, r) + w2 * c
            step = np.linalg.solve(normal, grad[..., None])[..., 0]
            c -= step
            if np.max(np.abs(step) * np.sqrt(w2)) <= _INNER_TOL * max(1.0, float(np.abs(r).max(initial=0.0))):
                break
        F = perturb(flange2base, c[:, :3], c[:, 3:])
        px, J_glob, A = _pixel_blocks(X, Z, Kx, dx, F, points, owner, setup, n_glob, x_rot, c[:, :3])
        state.update(x=np.array(x, copy=True), c=c, px=px, J=J_glob, A=A, W=robust_weights(px - detected), F=F)

    def residuals(x):
        evaluate(x)
        return np.concatenate([(state["px"] - detected).ravel(), (state["c"] * prior_w.reshape(n_img, 6)).ravel()])

    def jac(x):
        evaluate(x)
        A, J_glob = state["A"], state["J"]
        Aw, normal = weighted_normal(A, state["W"])
        cross = (by_image @ np.einsum("mri,mrj->mij", Aw, J_glob).reshape(m, 6 * n_glob)).reshape(n_img, 6, n_glob)
        dc = -np.linalg.solve(normal, cross)  # d(correction)/d(globals) along the optimum
        J = np.empty((2 * m + 6 * n_img, n_glob))
        J[:2 * m] = (J_glob + A @ dc[owner]).reshape(2 * m, n_glob)
        J[2 * m:] = (prior_w.reshape(n_img, 6)[:, :, None] * dc).reshape(6 * n_img, n_glob)
        return J

    x0 = np.zeros(n_glob)
    r0 = residuals(x0)
    scale = np.r_[np.full(12, 1e-3), np.ones(4), np.full(5, 1e-3)][:n_glob]
    res = least_squares(residuals, x0, jac=jac, loss=loss, f_scale=f_scale, x_scale=scale, method="trf",
                        xtol=tol, ftol=tol, gtol=tol)
    evaluate(res.x)

    def unpack(x):
        X, Z, Kx, dx, _ = glob(x)
        return X, Z, Kx, dx, state["F"]

    # the degrees of freedom count the corrections too
    return _reprojection_result(res, unpack, r0, counts, n_glob + 6 * n_img, loss, calls[0])


def _reprojection_result(res, unpack, r0, counts, n: int, loss: str, n_calls: int) -> ReprojectionResult:
    """The :class:`ReprojectionResult` of a finished ``least_squares`` run (``r0``: residuals at the
    start; ``n``: the unknowns, for the residual variance's degrees of freedom)."""
    m_px = 2 * int(counts[-1])
    X, Z, K_out, d_out, F_out = unpack(res.x)
    cov_X, sigma2 = _gauss_newton_cov_X(res, n, loss)
    r = res.fun[:m_px].reshape(-1, 2)
    per_image = np.array([np.sqrt(np.mean(np.sum(r[a:b] ** 2, axis=1))) if b > a else np.nan
                          for a, b in zip(counts[:-1], counts[1:])])
    return ReprojectionResult(
        X, Z, K_out, d_out, float(np.sqrt(np.mean(np.sum(r**2, axis=1)))),
        float(np.sqrt(np.mean(r0[:m_px].reshape(-1, 2) ** 2) * 2)),
        per_image, int(counts[-1]), bool(res.success), str(res.message), cov_X, float(np.sqrt(sigma2)), 0,
        F_out, n_calls,
    )


def _gauss_newton_cov_X(res, n: int, loss: str):
    """Covariance of X's six parameters from the Jacobian at the optimum, scaled by the residual
    variance (Gauss-Newton: sigma^2 (J^T J)^-1), and that variance. The rotation increments are
    global (left) perturbations, so the first block is the covariance of X's rotation vector error
    in the flange/base frame. None for a robust loss (no least-squares covariance)."""
    m = res.fun.size
    sigma2 = float(res.fun @ res.fun) / max(m - n, 1)
    if loss != "linear":
        return None, sigma2
    J = res.jac.toarray() if hasattr(res.jac, "toarray") else res.jac
    try:
        return (sigma2 * np.linalg.inv(J.T @ J))[:6, :6], sigma2
    except np.linalg.LinAlgError:
        return None, sigma2


def _robust_reprojection(X0, Z0, flange2base, object_points, image_points, K, dist, setup, f_scale,
                         refine_intrinsics, robot_noise, sparse) -> ReprojectionResult:
    """``refine_reprojection(robust=True)``: a ``soft_l1`` pass, every point beyond 5 sigma dropped,
    then a least-squares refit of the inliers (so the covariance is that of a least-squares fit)."""
    first = refine_reprojection(X0, Z0, flange2base, object_points, image_points, K, dist, setup,
                                loss="soft_l1", f_scale=f_scale, refine_intrinsics=refine_intrinsics,
                                robot_noise=robot_noise, sparse=sparse)
    T = predicted_target2cam(first.X, first.Z, first.flange2base, setup)
    norms = [np.linalg.norm(project_points(Ti, np.ascontiguousarray(o, dtype=np.float64), first.K, first.dist)
                            - np.asarray(im, dtype=np.float64), axis=1)
             for Ti, o, im in zip(T, object_points, image_points)]
    sigma = 1.4826 * float(np.median(np.concatenate(norms)))
    keep = [nm <= 5.0 * sigma for nm in norms]
    if robot_noise is not None:
        # a view its robot pose contradicts (a wrong pose, a swapped image): the soft-L1 pass bends
        # that pose far beyond its prior rather than give up the view's points, and pulls X with
        # it (measured: a view shifted by 200 px moved X 14 mm). Such views go whole.
        moved = _corrections_in_sigmas(first.flange2base, flange2base, robot_noise)
        contradicted = (moved > CORRECTION_SIGMAS) & (moved > 3.0 * np.median(moved))
        keep = [k & ~bad for k, bad in zip(keep, contradicted)]
    second = refine_reprojection(first.X, first.Z, flange2base,
                                 [np.asarray(o)[k] for o, k in zip(object_points, keep)],
                                 [np.asarray(im)[k] for im, k in zip(image_points, keep)],
                                 first.K, first.dist, setup, refine_intrinsics=refine_intrinsics,
                                 robot_noise=robot_noise, sparse=sparse)
    rejected = int(sum(int((~k).sum()) for k in keep))
    emptied = tuple(i for i, k in enumerate(keep) if len(k) and not k.any())
    return ReprojectionResult(
        second.X, second.Z, second.K, second.dist, second.rms_px, first.rms_px_before, second.per_image_rms_px,
        second.n_points, second.success, second.message, second.cov_X, second.sigma_px, rejected,
        second.flange2base, second.n_evaluations, emptied, tuple(keep),
    )


#: A robot pose the robust pass corrects by more than this many prior stds (on some axis), and by
#: more than 3x the median pose's, marks its view as contradicting it (see _robust_reprojection).
CORRECTION_SIGMAS = 6.0


def _corrections_in_sigmas(corrected, given, robot_noise) -> NDArray[np.float64]:
    """Per robot pose, the largest component of its correction (left rotation vector, translation)
    in units of the prior's std ``robot_noise = (rad, m)``."""
    rot = rotation_of_valid(corrected[:, :3, :3] @ np.swapaxes(given[:, :3, :3], 1, 2)).as_rotvec() / robot_noise[0]
    return np.abs(np.c_[rot, (corrected[:, :3, 3] - given[:, :3, 3]) / robot_noise[1]]).max(axis=1)


def _pixel_noise(obj, img, K, dist) -> float:
    """Per-axis pixel noise from free PnP fits of every image (6 unknowns each)."""
    ss, dof = 0.0, 0
    for o, im in zip(obj, img):
        fit = solve_pnp(Detection(np.arange(len(o)), im, o), K, dist)
        if fit is None:
            continue
        ss += fit[1] ** 2 * len(o)  # fit[1]: RMS over points of the 2D distance
        dof += 2 * len(o) - 6
    return float(np.sqrt(ss / dof)) if dof > 0 and ss > 0 else 0.1


def _robot_groups(counts: NDArray[np.intp], n_glob: int) -> list[tuple[NDArray[np.intp], list[NDArray[np.intp]] | None]]:
    """Columns that can be differenced together, with the rows each one touches.

    Image i's pixel residuals depend on the globals (X, Z, intrinsics) and on its own 6 robot
    pose corrections only; prior row k on correction k only. So the j-th correction of every
    image touches disjoint rows: 6 groups cover the 6N correction columns.
    """
    n_img = len(counts) - 1
    m_px = 2 * int(counts[-1])
    groups: list = [(np.array([k]), None) for k in range(n_glob)]
    for j in range(6):
        cols = n_glob + j + 6 * np.arange(n_img)
        rows = [np.r_[np.arange(2 * counts[i], 2 * counts[i + 1]), m_px + 6 * i + j] for i in range(n_img)]
        groups.append((cols, rows))
    return groups


def _remember_last(fun):
    """``fun`` that returns its previous value when called again at the same ``x``."""
    last_x, last_f = None, None

    def remembered(x):
        nonlocal last_x, last_f
        if last_x is None or not np.array_equal(x, last_x):
            last_f = fun(x)
            last_x = np.array(x, copy=True)
        return last_f

    return remembered


def _grouped_jacobian(fun, groups):
    """A ``jac`` callable for ``least_squares``: forward differences that exploit the sparsity
    (one residual evaluation per group of columns with disjoint rows, instead of one per column),
    returned dense so that the exact trust-region solver still applies. (scipy's own
    ``jac_sparsity`` switches to the inexact LSMR solver, which needed ~50x more evaluations
    on this problem.) Step as scipy's '2-point': sqrt(eps) max(1, |x|)."""
    h0 = np.sqrt(np.finfo(float).eps)

    def jac(x):
        f0 = fun(x)  # with _remember_last, the value the solver computed at x
        J = np.zeros((f0.size, x.size))
        for cols, rows in groups:
            h = h0 * np.maximum(1.0, np.abs(x[cols]))
            xp = x.copy()
            xp[cols] += h
            df = fun(xp) - f0
            if rows is None:
                J[:, cols[0]] = df / h[0]
            else:
                for c, hc, r in zip(cols, h, rows):
                    J[r, c] = df[r] / hc
        return J

    return jac


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
