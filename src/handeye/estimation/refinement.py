"""The pose refinement and the pixel refinement as functions of their inputs, fitted by the one
estimation core (:mod:`handeye.estimation.core`): no second engine.

``refine_pose``: X and Z refined on the poses alone, the optimal correction of Strobl and Hirzinger
(seed §2.2.4) with its noise model's variances estimated from the data: the core's fit of
:class:`~handeye.sensors.camera.poses.PoseDifferences` times
:class:`~handeye.robot.models.ControllerPoses` (:func:`~handeye.estimation.core.fit_poses`).

``refine_reprojection``: X and Z refined on the pixels, every target point projected onto its
detection in every image (the thesis's "future work", §6.1, and Horaud-Dornaika's lesson: estimate
everything together): the core's fit of :class:`~handeye.sensors.camera.model.CameraCorners` times
:class:`~handeye.robot.models.ControllerPoses`, or :class:`~handeye.robot.models.PoseErrors` with each
robot pose's error fitted under a prior.

Both once lived in :mod:`handeye.solvers.refine` as engines of their own; that path still finds
them for one release (with a DeprecationWarning).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import cast

import numpy as np
from numpy.typing import NDArray

from .._shared.threads import on_one_blas_thread
from ..errors import InputMismatchError
from ..frames.setups import check_setup
from ..robot.models import ControllerPoses, PoseErrors
from ..sensors.camera.model import CameraCorners
from ..sensors.camera.poses import NOISE_TERMS, pose_residuals
from ..solvers.refine import PoseRefinementResult, ReprojectionResult, TranslationPriors
from .core import Fitted, Problem, fit, fit_poses, view_rms_px

__all__ = ["PoseRefinementResult", "ReprojectionResult", "TranslationPriors", "corners_problem", "fit_poses_shared",
           "pose_fits_shared", "refine_pose", "refine_reprojection", "reprojection_result"]

_POSE_FITS: ContextVar[dict | None] = ContextVar("_POSE_FITS", default=None)


@contextmanager
def pose_fits_shared() -> Iterator[None]:
    """Within it, the pose refinement of the same poses from the same start is fitted once
    (:func:`fit_poses_shared`): the check's outlier refit on all the poses (:func:`refine_pose` from
    Daniilidis) is the pose candidate's fit on them (:func:`~handeye.estimation.estimators.poses_fit`
    from the same closed form) whenever the check leaves every pose in, the costliest fit of a
    calibration on poses (a 20-view session: ~0.2 s of ~0.8). Nested: the outermost one keeps them."""
    token = _POSE_FITS.set({}) if _POSE_FITS.get() is None else None
    try:
        yield
    finally:
        if token is not None:
            _POSE_FITS.reset(token)


def fit_poses_shared(flange2base: NDArray[np.float64], target2cam: NDArray[np.float64], setup: str, X0: NDArray[np.float64],
                     Z0: NDArray[np.float64], priors: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
                     ) -> tuple[Problem, Fitted]:
    """:func:`~handeye.estimation.core.fit_poses`, its answer kept within :func:`pose_fits_shared` (keyed by
    the inputs' bytes: the same inputs, the same fit)."""
    memo = _POSE_FITS.get()
    if memo is None:
        return fit_poses(flange2base, target2cam, setup, X0, Z0, priors=priors)
    arrays = (flange2base, target2cam, X0, Z0) + (() if priors is None else tuple(priors))
    key = (setup, priors is None) + tuple((np.shape(a), np.asarray(a, float).tobytes()) for a in arrays)
    if key not in memo:
        memo[key] = fit_poses(flange2base, target2cam, setup, X0, Z0, priors=priors)
    return memo[key]


def refine_pose(
    X0: NDArray[np.float64],
    Z0: NDArray[np.float64],
    flange2base: NDArray[np.float64],
    target2cam: NDArray[np.float64],
    setup: str,
    weighting: str = "noise_model",
    priors: TranslationPriors | None = None,
) -> PoseRefinementResult:
    """Refine X and Z on the poses: the optimal correction of Strobl and Hirzinger (seed §2.2.4),
    fitted by the estimation core (:func:`~handeye.estimation.core.fit_poses`).

    Every pose i says where the target is, ``Z_i`` (target2base for eye-in-hand, target2flange for
    eye-to-hand, through X); the residual is ``Z^-1 Z_i`` as a rotation vector and a translation, in
    the target frame. Poses, not motions, carry the residuals: each measurement enters once, so
    residuals are independent and the covariance is honest. The residual of pose i has the
    covariance ``s_rr M_i + s_rc P_rot + s_t P_tra (+ s_d P_depth)``: robot rotation noise (``M_i``:
    through the lever arm between flange and target), camera rotation noise, translation noise and,
    from 6 poses, the camera's depth noise; the variances are estimated by maximum likelihood from
    the residuals, the fit repeated with the new weights until they are stable.

    Parameters
    ----------
    X0, Z0 : (4, 4)
        Start, e.g. a closed-form solution and the mean of the ``Z_i``.
    flange2base, target2cam : (N, 4, 4)
    setup : {'eye_in_hand', 'eye_to_hand'}
    weighting : {'noise_model'}
        The noise model above (the only one: Strobl and Hirzinger's fixed two-variance metric,
        'strobl', went with the second engine).
    priors : TranslationPriors, optional
        Linear measurements of the translations of X and Z (``G @ [t_X, t_Z] = value +- std``),
        each one more residual: what fixes the directions the poses cannot see (a SCARA's camera
        height, :mod:`handeye.solvers.low_dof`).

    Returns
    -------
    PoseRefinementResult
        ``cov_X`` is scaled by the residual variance factor (chi-square over degrees of freedom).

    Examples
    --------
    >>> import numpy as np
    >>> from handeye.simulate import Noise, add_noise, random_scene
    >>> from handeye.solvers import closed_form
    >>> scene = random_scene(12, "eye_in_hand", rng=0)
    >>> target2cam = add_noise(scene.target2cam, Noise(rot_deg=0.02, trans_mm=0.2), np.random.default_rng(0))
    >>> X0, Z0, _ = closed_form(scene.flange2base, target2cam, "eye_in_hand", "daniilidis")
    >>> ref = refine_pose(X0, Z0, scene.flange2base, target2cam, "eye_in_hand")
    >>> bool(1e3 * np.linalg.norm(ref.X[:3, 3] - scene.X[:3, 3]) < 3e3 * np.sqrt(np.trace(ref.cov_X[3:, 3:])))
    True
    """
    setup = check_setup(setup)
    if weighting != "noise_model":
        raise InputMismatchError(f"weighting={weighting!r}; use 'noise_model' (the noise model's variances estimated "
                                 "from the data; the fixed 'strobl' metric is no longer offered)")
    flange2base = np.asarray(flange2base, dtype=float)
    target2cam = np.asarray(target2cam, dtype=float)
    if len(flange2base) < 3:
        raise InputMismatchError(f"pose refinement needs at least 3 poses, got {len(flange2base)}")
    X0, Z0 = np.asarray(X0, float), np.asarray(Z0, float)
    # the core's unknowns are X's left increment and the target's chart about Z0: the priors' own
    rows = priors.rows(X0, Z0) if priors is not None else None
    problem, fitted = fit_poses_shared(flange2base, target2cam, setup, X0, Z0, priors=rows)
    X = fitted.X
    Z = problem.sensor.Z(X, fitted.p)
    cov = problem.full_cov_xp(fitted.cov)
    found = dict(zip(NOISE_TERMS, map(float, fitted.sigma)))
    noise = {k: found.get(k, 0.0) for k in NOISE_TERMS}
    residuals, _, _ = pose_residuals(X, Z, flange2base, target2cam, setup)
    message = "the core's fit of the poses" + ("" if fitted.success else ": the noise estimates did not settle")
    return PoseRefinementResult(X, Z, cov[:6, :6], cov[6:, 6:], cov, noise, residuals, fitted.rounds, fitted.success,
                                weighting, fitted.success, message)


@on_one_blas_thread  # narrow matrices throughout: a second BLAS thread spins more than it works
def refine_reprojection(
    X0: NDArray[np.float64],
    Z0: NDArray[np.float64],
    flange2base: NDArray[np.float64],
    object_points: list[NDArray[np.float64]],
    image_points: list[NDArray[np.float64]],
    K: NDArray[np.float64],
    dist: NDArray[np.float64],
    setup: str,
    refine_intrinsics: bool = False,
    robust: bool = False,
    robot_noise: tuple[float, float] | None = None,
    tol: float = 1e-10,
) -> ReprojectionResult:
    """Refine X and Z by minimising the reprojection error of all target points in all images: the
    estimation core's fit of the corners (:func:`~handeye.estimation.core.fit`).

    The camera pose of image i is not a free unknown but follows from the robot pose (docs/guide.md,
    Conventions): eye-in-hand ``target2cam_i = inv(X) @ inv(flange2base_i) @ Z`` (X = cam2flange, Z =
    target2base); eye-to-hand ``target2cam_i = inv(X) @ flange2base_i @ Z`` (X = cam2base, Z =
    target2flange). Every corner's pixel error weighs alike; the pixel noise is estimated from the
    residuals and scales the covariance.

    Parameters
    ----------
    X0, Z0 : (4, 4)
        Start (a closed-form solution).
    flange2base : (N, 4, 4)
    object_points, image_points : lists of N arrays (M_i, 3) and (M_i, 2)
        Target points (target frame, metres) and their detections (pixels), image by image.
    K, dist
        Camera intrinsics (OpenCV's model, up to 8 distortion coefficients; held fixed unless refined).
    setup : {'eye_in_hand', 'eye_to_hand'}
    refine_intrinsics : bool
        Also refine fx, fy, cx, cy and five distortion terms (k1 k2 p1 p2 k3). The robot poses tie
        all views together, so this is far better conditioned than a camera calibration alone:
        use it when the intrinsics were estimated from the same images.
    robust : bool
        Wrong detections: the core's robust fit (a soft-L1 round, every corner beyond 5 of its std
        set aside, then plain least squares on the rest, so the covariance is that of a least-squares
        fit; with ``robot_noise``, a view whose pose the robust round bends far beyond its prior is
        set aside whole). Without: plain least squares on every corner.
    robot_noise : (rad, m), optional
        The robot poses are not exact: each gets its own error (rotation vector and translation, 6
        unknowns per image) with a Gaussian prior of these standard deviations per axis (e.g. the
        controller's repeatability), weighed against the pixel noise the fit estimates. X and Z then
        stop absorbing the robot's errors. The corrected robot poses are returned (``flange2base``).
    tol : float
        The least squares' tolerance.

    Returns
    -------
    ReprojectionResult
        ``cov_X`` over X's left rotation increment (rad) and translation (m).

    Examples
    --------
    >>> import numpy as np
    >>> from dataclasses import replace
    >>> from handeye.simulate import EXACT, realistic_scene
    >>> sc = realistic_scene(10, "eye_in_hand", 2, errors=replace(EXACT, pixel_px=0.2))  # exact robot, 0.2 px
    >>> obj = [sc.object_points] * len(sc.flange2base)
    >>> ref = refine_reprojection(sc.X, sc.Z, sc.flange2base, obj, list(sc.image_points), sc.K, sc.dist, "eye_in_hand")
    >>> bool(np.all(np.abs(ref.X[:3, 3] - sc.X[:3, 3]) < 3 * np.sqrt(np.diag(ref.cov_X))[3:]))
    True
    """
    problem = corners_problem(setup, [str(i) for i in range(len(flange2base))], flange2base, object_points, image_points, K,
                              dist, X0, Z0, refine_intrinsics, robot_noise)
    return reprojection_result(problem, fit(problem, tol=tol, robust=robust))


def corners_problem(setup: str, names: list[str], flange2base: NDArray[np.float64], object_points: list[NDArray[np.float64]],
                    image_points: list[NDArray[np.float64]], K: NDArray[np.float64], dist: NDArray[np.float64],
                    X0: NDArray[np.float64], Z0: NDArray[np.float64], refine_intrinsics: bool = False,
                    robot_noise: tuple[float, float] | None = None) -> Problem:
    """The core's problem of a camera's corners (the pixel refinement), started at ``X0``, ``Z0``: the robot's
    poses exact, or with ``robot_noise`` (rad, m) each pose's error an unknown under that prior."""
    setup = check_setup(setup)
    flange2base = np.asarray(flange2base, dtype=float)
    if not len(flange2base) == len(object_points) == len(image_points):
        raise InputMismatchError(f"{len(flange2base)} robot poses, {len(object_points)} point sets and {len(image_points)} "
                                 "detections: give one of each per image")
    sensor = CameraCorners(setup, names, list(image_points), list(object_points), K, dist, refine_intrinsics=refine_intrinsics)
    X_start, p_start = sensor.start(flange2base, np.asarray(X0, float), np.asarray(Z0, float))
    if robot_noise is None:
        robot: ControllerPoses = ControllerPoses(flange2base)
    else:
        sig_rot, sig_t = (float(v) for v in robot_noise)
        if not (sig_rot > 0 and sig_t > 0 and np.isfinite(sig_rot) and np.isfinite(sig_t)):
            raise InputMismatchError(f"robot_noise {robot_noise}: give positive standard deviations (rad, m) of each "
                                     "robot pose's error, e.g. (np.radians(0.05), 0.2e-3)")
        robot = PoseErrors(flange2base, (float(np.degrees(sig_rot)), 1e3 * sig_t))
    return Problem(sensor, robot, X_start, p_start)


def reprojection_result(problem: Problem, fitted: Fitted) -> ReprojectionResult:
    """The core's fit of a camera's corners (:class:`~handeye.sensors.camera.model.CameraCorners`) as a
    :class:`~handeye.solvers.refine.ReprojectionResult`."""
    sensor = cast(CameraCorners, problem.sensor)
    flange2base = problem.robot.flange2base(fitted.d)
    everything = np.arange(len(sensor.owner))

    def pixels(X, p, rows):
        return np.sum((sensor.residuals(X, p, flange2base, rows) / sensor.pixel_size(rows)[:, None]) ** 2, axis=1)

    rows = fitted.rows
    sq = pixels(fitted.X, fitted.p, rows)
    n_views = len(sensor.names)
    per_view = view_rms_px(problem, fitted, np.arange(n_views))
    before = pixels(problem.X0, problem.p0, everything)
    kept = tuple(fitted.kept[sensor.owner == v] for v in range(n_views))
    emptied = tuple(v for v, k in enumerate(kept) if len(k) and not k.any())
    return ReprojectionResult(
        fitted.X, sensor.Z(fitted.X, fitted.p), *sensor.intrinsics(fitted.p), float(np.sqrt(np.mean(sq))),
        float(np.sqrt(np.mean(before))), per_view, len(rows), fitted.success, "the core's fit of the corners",
        fitted.cov[:6, :6], float(fitted.sigma[0]), int(len(everything) - len(rows)), flange2base, 0, emptied, kept)
