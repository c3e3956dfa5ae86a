"""The estimators a calibration chooses from, and the choice: by what predicts held-out views best.

Every closed form (AX = XB with Z the mean of the per-pose Z_i, and the robot-world ones), the pose
refinement (Strobl-Hirzinger's weighting with a noise model: the one estimation core's fit of the camera's
poses, :class:`~handeye.sensors.camera.poses.PoseDifferences` times :class:`~handeye.robot.models.ControllerPoses`,
:func:`poses_fit`; its folds and jackknife refits are the core's refits with the noise held), and with
images the pixel refinement: the one estimation core's fit of the camera's corners
(:mod:`handeye.estimation.core`, :class:`~handeye.sensors.camera.model.CameraCorners`) with the robot's
poses exact (:class:`~handeye.robot.models.ControllerPoses`), the intrinsics refined too when they were
estimated from the same images, or with each pose's error fitted under a prior the user gives
(:class:`~handeye.robot.models.PoseErrors`, which the core eliminates view by view); its folds and
jackknife refits are the core's downdates. Fitting the training data better is not the test: on real
captures a refinement can fit better and predict worse. :func:`choose` runs K-fold
cross-validation (:mod:`handeye.estimation.validation`) of each on the user's own data and keeps the one with
the smallest held-out error; the jackknife spread of X comes from refits of the chosen one without each pose
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Protocol, cast

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from .. import solvers
from ..errors import HandEyeError
from ..frames.motions import MotionSet, Pairs
from ..robot.models import ControllerPoses
from ..sensors.camera.model import CameraCorners
from ..sensors.camera.pnp import INTRINSICS, intrinsics_covariance, refine_pnp
from ..sensors.camera.poses import NOISE_TERMS, PoseDifferences
from ..solvers.refine import ReprojectionResult
from .core import Fitted, Problem, downdated
from .core import fit as core_fit
from .diagnostics import SCALE_TOLERANCE, board_scale, closed_form
from .refinement import corners_problem, fit_poses_shared, reprojection_result
from .validation import FAILED_FIT, CrossValidation, Fit, Views, cross_validate, default_folds, fold_indices, pnp_errors

__all__ = ["Choice", "PosesFit", "closed_fit", "pose_candidates", "pose_fit", "poses_fit", "pixel_candidates", "choose",
           "intrinsics_cov", "POSE", "PIXEL", "PIXEL_INTRINSICS", "PIXEL_ROBOT", "REFINE_INTRINSICS"]

#: Closed forms left out of the choice: horaud_nonlinear costs 4x the others per fit and lands between
#: horaud and the pose refinement, which are both candidates.
SLOW_CLOSED_FORMS = ("horaud_nonlinear",)
#: Tolerance of the refits on parts of the data (cross-validation, jackknife), which start at the
#: fit on all of it: their X moves by far more between folds than this leaves unconverged.
REFIT_TOL = 1e-8
#: Names of the refinements (the closed forms go by their solver names).
POSE = "pose"
PIXEL = "reprojection"
PIXEL_INTRINSICS = "reprojection+intrinsics"
PIXEL_ROBOT = "reprojection+robot"
#: The estimators that refine intrinsics estimated from the same images along with X (the others hold
#: them fixed: :func:`intrinsics_cov`).
REFINE_INTRINSICS = (PIXEL_INTRINSICS, PIXEL_ROBOT)


def closed_fit(method: str, pairs: Pairs = "auto", shared: dict | None = None) -> Fit:
    """The closed form ``method`` on the motions of ``pairs`` (for a subset: its own ``pairs``; an
    explicit list of index pairs does not survive leaving poses out, so it becomes 'auto').
    ``shared``: the closed forms fitted on the same poses share their motions through it (made and
    checked once per set of poses, :func:`_motions`)."""
    rule = pairs if isinstance(pairs, str) else "auto"

    def fit(flange2base, target2cam, setup, idx):
        motions = None  # a robot-world solver solves the poses, not their motions
        if shared is not None and solvers.get(method).kind != "robot_world":
            motions = _motions(shared, flange2base, target2cam, setup, rule)
        X, Z, _ = closed_form(flange2base, target2cam, setup, method, rule, motions)
        return X, Z
    return fit


def _motions(shared: dict, flange2base: NDArray[np.float64], target2cam: NDArray[np.float64], setup: str,
             rule: Pairs) -> MotionSet:
    """The motions of these poses, made and checked (:func:`~handeye.solvers.check_observability`) once
    for every closed form fitted on them (kept in ``shared`` by the poses' bytes; so is the error of
    motions that cannot determine X, raised again)."""
    key = (setup, str(rule), np.shape(flange2base), np.asarray(flange2base, float).tobytes(),
           np.asarray(target2cam, float).tobytes())
    if key not in shared:
        try:
            motions = MotionSet.from_poses(flange2base, target2cam, setup, rule)
            solvers.check_observability(motions)
            shared[key] = motions
        except FAILED_FIT as exc:
            shared[key] = exc
    found = shared[key]
    if isinstance(found, BaseException):
        raise found
    return found


class _Kept(Protocol):
    """A :data:`~handeye.estimation.validation.Fit` that keeps the fit on all the views once it made it
    (``full``: empty before)."""

    full: list

    def __call__(self, flange2base: NDArray[np.float64], target2cam: NDArray[np.float64], setup: str,
                 idx: NDArray[np.intp]) -> tuple: ...


class _KeptCorners(_Kept, Protocol):
    """The pixel refinement's: its :class:`CornersFit` too (``core``)."""

    core: list[CornersFit]


def _pixels(views: Views) -> tuple[Sequence[NDArray[np.float64]], Sequence[NDArray[np.float64]], NDArray[np.float64],
                                   NDArray[np.float64]]:
    """The object points, image points, K and dist of views with images (:attr:`Views.has_pixels`)."""
    return cast(tuple[Sequence[NDArray[np.float64]], Sequence[NDArray[np.float64]], NDArray[np.float64], NDArray[np.float64]],
                (views.object_points, views.image_points, views.K, views.dist))


@dataclass(frozen=True)
class PosesFit:
    """The pose refinement as the one estimation core fits it (:func:`poses_fit`): its problem and
    fit, which refit on any subset of its views, or on other poses of the same views, with the noise
    held."""

    problem: Problem
    fitted: Fitted

    @property
    def sensor(self) -> PoseDifferences:
        """The camera's poses (the problem's sensor)."""
        return cast(PoseDifferences, self.problem.sensor)

    @property
    def X(self) -> NDArray[np.float64]:  # noqa: D102
        return self.fitted.X

    @property
    def Z(self) -> NDArray[np.float64]:  # noqa: D102
        return self.problem.sensor.Z(self.fitted.X, self.fitted.p)

    @property
    def cov_X(self) -> NDArray[np.float64]:
        """X's covariance (rotation vector rad, translation m): the noise model's."""
        return self.fitted.cov[:6, :6]

    @property
    def noise(self) -> dict[str, float]:
        """The noise found, per term of :data:`~handeye.sensors.camera.poses.NOISE_TERMS` (rad, m;
        the camera's depth 0 with fewer views than it needs)."""
        found = dict(zip(self.sensor.noise_terms, map(float, self.fitted.sigma)))
        return {k: found.get(k, 0.0) for k in NOISE_TERMS}

    @property
    def converged(self) -> bool:
        """Whether the fit and its noise estimates settled."""
        return self.fitted.success

    @property
    def rounds(self) -> int:
        """The rounds of the noise estimation."""
        return self.fitted.rounds

    def on(self, idx: NDArray[np.intp]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """X and Z refitted on the views ``idx`` (of those fitted), the noise held."""
        sub = core_fit(self.problem, np.asarray(idx), start=self.fitted, tol=REFIT_TOL)
        return sub.X, self.problem.sensor.Z(sub.X, sub.p)

    def refit(self, flange2base: NDArray[np.float64], target2cam: NDArray[np.float64]
              ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """X and Z refitted on other poses (e.g. the same views' PnP with other intrinsics), the noise held."""
        sensor = PoseDifferences(self.sensor.setup, [str(i) for i in range(len(target2cam))], target2cam,
                                 terms=len(self.sensor.noise_terms))
        problem = Problem(sensor, ControllerPoses(np.asarray(flange2base, float)), *sensor.start(flange2base, self.X, self.Z))
        sub = core_fit(problem, start=replace(self.fitted, x=np.zeros(len(self.fitted.x))), tol=REFIT_TOL)
        return sub.X, sensor.Z(sub.X, sub.p)


def poses_fit(views: Views, X0: NDArray[np.float64], Z0: NDArray[np.float64]) -> PosesFit:
    """The pose refinement of X and Z on the poses of ``views`` from ``X0``, ``Z0`` (a closed form),
    by the one estimation core (:mod:`handeye.estimation.core`): the camera's poses of the target,
    each view's residual whitened by the pose refinement's noise model, its variances estimated from
    the data (:class:`~handeye.sensors.camera.poses.PoseDifferences`), with the robot's poses as the
    controller gave them (:func:`~handeye.estimation.core.fit_poses`, as :func:`~handeye.estimation.refinement.refine_pose`)."""
    return PosesFit(*fit_poses_shared(views.flange2base, views.target2cam, views.setup, X0, Z0))


def pose_fit(method: str, views: Views | None, start: PosesFit | None = None) -> Fit:
    """The pose refinement (:func:`poses_fit`) from the closed form ``method``. With ``views`` (all
    the poses), it is fitted on them once (kept as ``fit.full``; ``start``: that fit, already made),
    and each fit on a subset of them is refitted from it with the noise held (a cross-validation
    fold differs from the whole by a few poses); on other poses of the same views (the intrinsics'
    refits), likewise."""
    full: list = [] if start is None else [start]

    def fit(flange2base, target2cam, setup, idx):
        if views is None:
            X, Z, _ = closed_form(flange2base, target2cam, setup, method)
            whole = poses_fit(Views(flange2base, target2cam, setup), X, Z)
            return whole.X, whole.Z
        if not full:
            X, Z, _ = closed_form(views.flange2base, views.target2cam, setup, method)
            full.append(poses_fit(views, X, Z))
        idx = np.asarray(idx)
        if np.array_equal(flange2base, views.flange2base[idx]) and np.array_equal(target2cam, views.target2cam[idx]):
            return full[0].on(idx)
        return full[0].refit(flange2base, target2cam)

    kept = cast(_Kept, fit)
    kept.full = full
    return kept


def pose_candidates(method: str = "daniilidis", views: Views | None = None) -> dict[str, Fit]:
    """Every registered closed form, and the pose refinement started from ``method`` (warm-started
    from the refinement on all of ``views`` when given)."""
    shared: dict = {}  # each training set's motions, for every closed form
    out = {name: closed_fit(name, shared=shared) for name in solvers.available(closed_forms=True) if name not in SLOW_CLOSED_FORMS}
    out[POSE] = pose_fit(method, views)
    return out


@dataclass(frozen=True)
class CornersFit:
    """The core's fit of a camera's corners with the robot's poses exact (:mod:`handeye.estimation.core`,
    :class:`~handeye.sensors.camera.model.CameraCorners` times :class:`~handeye.robot.models.ControllerPoses`):
    its problem and fit, which downdate to any subset of its views, and the same fit as the pixel
    refinement's result (what the calibration reports)."""

    problem: Problem
    fitted: Fitted
    result: ReprojectionResult

    @property
    def sensor(self) -> CameraCorners:
        """The camera's corners (the problem's sensor)."""
        return cast(CameraCorners, self.problem.sensor)

    def on(self, idx: NDArray[np.intp]) -> tuple[NDArray[np.float64], ...]:
        """X and Z fitted on the views ``idx`` (of those fitted), and K and dist when they are
        refined: one Gauss-Newton downdate."""
        sensor = self.sensor
        sub = downdated(self.problem, self.fitted, np.asarray(idx), guard=False)
        XZ = (sub.X, sensor.Z(sub.X, sub.p))
        return XZ + sensor.intrinsics(sub.p) if sensor.refine_intrinsics else XZ

    def with_intrinsics(self, K: NDArray[np.float64], dist: NDArray[np.float64]) -> NDArray[np.float64]:
        """X refitted on the same points with the intrinsics ``K``, ``dist`` (a plain least squares
        from this fit, its noise scale kept)."""
        sensor = copy.copy(self.sensor)
        sensor.K, sensor.dist = np.asarray(K, float), np.asarray(dist, float).ravel()
        return core_fit(replace(self.problem, sensor=sensor), start=self.fitted, tol=REFIT_TOL).X


def corners_fit(views: Views, idx: NDArray[np.intp], X0: NDArray[np.float64], Z0: NDArray[np.float64],
                refine_intrinsics: bool = False, robot_sigma: tuple[float, float] | None = None) -> CornersFit:
    """The robust pixel fit of X and the target (and the intrinsics) on the views ``idx``, started at
    ``X0``, ``Z0``, by the one estimation core (every corner weighted by its pixel; points beyond 5 of
    their std set aside): with the robot's poses exact, or with ``robot_sigma`` (rad, m) each pose's
    error fitted under that prior (:class:`~handeye.robot.models.PoseErrors`; a view whose pose the
    robust fit bends far beyond it is set aside whole)."""
    idx = np.asarray(idx)
    object_points, image_points, K, dist = _pixels(views)
    problem = corners_problem(views.setup, [str(i) for i in idx], views.flange2base[idx], [object_points[i] for i in idx],
                              [image_points[i] for i in idx], K, dist, X0, Z0, refine_intrinsics, robot_sigma)
    fitted = core_fit(problem)
    return CornersFit(problem, fitted, reprojection_result(problem, fitted))


def pixel_fit(views: Views, idx: NDArray[np.intp], X0: NDArray[np.float64], Z0: NDArray[np.float64],
              refine_intrinsics: bool = False, robot_sigma: tuple[float, float] | None = None) -> ReprojectionResult:
    """The robust pixel refinement of X0, Z0 on the views ``idx``: the core's fit of the corners
    (:func:`corners_fit`), with the robot exact or each pose corrected under the prior ``robot_sigma``
    (rad, m)."""
    return corners_fit(views, idx, X0, Z0, refine_intrinsics, robot_sigma).result


def _corners(views: Views, method: str, refine_intrinsics: bool = False, robot_sigma: tuple[float, float] | None = None
             ) -> Fit:
    """The pixel refinement: the core's fit of the corners (and the intrinsics; ``robot_sigma``: and
    each robot pose's error under that prior) on all of ``views`` (kept as ``fit.full``, its
    :class:`CornersFit` as ``fit.core``), from the closed form ``method``; each fit on a subset is one
    Gauss-Newton downdate of it."""
    full: list = []
    core: list[CornersFit] = []

    def fit(flange2base, target2cam, setup, idx):
        if not core:
            X, Z, _ = closed_form(views.flange2base, views.target2cam, setup, method)
            core.append(corners_fit(views, np.arange(len(views)), X, Z, refine_intrinsics, robot_sigma))
            full.append(core[0].result)
        return core[0].on(idx)

    kept = cast(_KeptCorners, fit)
    kept.full, kept.core = full, core
    return kept


def pixel_candidates(views: Views, method: str = "daniilidis", intrinsics_estimated: bool = False,
                     robot_sigma: tuple[float, float] | None = None) -> dict[str, Fit]:
    """The pixel refinements for ``views`` (which must have images): robot poses exact; with the
    intrinsics refined too when they were estimated from these images; with robot pose corrections
    when ``robot_sigma`` (rad, m) is given."""
    out = {PIXEL: _corners(views, method)}
    if intrinsics_estimated:
        out[PIXEL_INTRINSICS] = _corners(views, method, True)
    if robot_sigma is not None:
        out[PIXEL_ROBOT] = _corners(views, method, intrinsics_estimated, robot_sigma)
    return out


@dataclass(frozen=True)
class Choice:
    """What :func:`choose` found: the estimator chosen, and every candidate's held-out errors."""

    name: str
    results: dict[str, CrossValidation]
    fits: dict[str, Fit]  #: the candidates, by name
    prefer: str | None = None  #: the estimator the others had to beat by one standard error
    robot_error_ratio: float | None = None  #: :func:`robot_error_ratio` of these views

    @property
    def best(self) -> CrossValidation:
        return self.results[self.name]

    def table(self) -> dict[str, dict[str, float | None]]:
        """Per estimator its held-out RMS error: ``px`` (None without images) and ``mm``."""
        return {name: {"px": r.rms_px, "mm": r.rms_mm} for name, r in self.results.items()}


def choose(views: Views, candidates: dict[str, Fit], folds: int | None = None, seed: int = 0,
           prefer: str | None = None) -> Choice:
    """Cross-validate every candidate on the same folds and keep the best (smallest RMS held-out
    error: pixels with images, millimetres at the target's distance without).

    With few views the held-out errors are noisy, and the smallest can win by chance: the
    candidate with the smallest error replaces ``prefer`` only when it is better by more than one
    standard error of the per-view differences (the "one standard error" rule of model selection).
    By default ``prefer`` is the pixel refinement while its model holds (the robot's poses exact
    up to the camera's noise: :func:`robot_error_ratio` at most :data:`ROBOT_DOMINATES`), else the
    pose refinement, which models the noise of both robot and camera. Held-out pixels alone do not
    see a bias of X that every held-out view shares (a robot error smooth over the capture moves
    them all alike), so the default is chosen by the model that fits the errors; beyond
    :data:`ROBOT_EXCLUDES` the exact-robot pixel refinement cannot win at all. Raises
    :class:`HandEyeError` when no candidate solves every fold.
    """
    held = fold_indices(len(views), default_folds(len(views)) if folds is None else folds, seed)
    results = {name: cross_validate(fit, views, held, name) for name, fit in candidates.items()}
    finite = {name: r.score for name, r in results.items() if np.isfinite(r.score)}
    if not finite:
        raise HandEyeError("no estimator could be fitted on every cross-validation fold (too few or degenerate poses)")
    ratio = robot_error_ratio(views, candidates)
    scale_off = None if ratio is None or ratio <= ROBOT_DOMINATES else _scale_off(views)
    if ratio is not None and ratio > ROBOT_EXCLUDES and not scale_off and POSE in finite:
        # the exact-robot model is plainly wrong here: a modest held-out gain is no evidence for its X
        finite = {name: v for name, v in finite.items()
                  if name not in (PIXEL, PIXEL_INTRINSICS) or v < PIXEL_MARGIN * finite[POSE]}
    best = min(finite, key=lambda name: finite[name])
    if prefer is None:
        pixel = _pixel_name(candidates)
        robot_dominates = ratio is not None and ratio > ROBOT_DOMINATES and not scale_off
        prefer = pixel if pixel is not None and not robot_dominates else POSE
    if prefer in finite and best != prefer:
        d = _errors(results[best]) ** 2 - _errors(results[prefer]) ** 2
        if d.mean() + d.std(ddof=1) / np.sqrt(len(d)) >= 0:
            best = prefer
    return Choice(best, results, dict(candidates), prefer, ratio)


#: The pixel refinement holds the robot's poses exact. When its residual std is more than this many
#: times the PnP residual's on the same points (each view's pose free; both per degree of freedom),
#: the robot's errors, not the pixels', make much of it: the pixel fit then weighs views by how far
#: the robot's error moves their pixels, and lands further from X than the pose refinement, which
#: models robot and camera noise (rendered realistic sessions of 12 eye-in-hand views at ~0.9 mm
#: robot error: 1.25 mm against 0.64 mm median). Exact robot poses give ~1.0-1.1; an arm with
#: 0.2-3 mm of kinematic error 1.3-8.
ROBOT_DOMINATES = 1.2
#: Beyond this ratio the exact-robot pixel refinement may not win at all (unless the board scale is
#: off): its held-out pixels can beat the pose refinement's while its X is further from the truth.
#: Rendered sessions (24 per cell, 12 views, robot error 0.2-3 mm): the default's median X error
#: against OpenCV's best method went from 0.94/1.06 to 0.94/0.98 (rotation/translation) at ~0.9 mm
#: eye-to-hand, 1.00/0.96 to 0.97/0.83 at ~2.7 mm eye-in-hand and 1.44/1.17 to 1.35/0.96 eye-to-hand;
#: unchanged below the threshold (at 1.2 instead, the 0.2 mm eye-to-hand cell lost: 0.90/1.11 to 1.12/1.18).
ROBOT_EXCLUDES = 1.5
#: ... unless its held-out error is below this fraction of the pose refinement's: bending X to the
#: robot's smooth errors gained the pixel fit 13-32% in held-out pixels on those sessions (one of 24
#: at ~2.7 mm eye-to-hand: 32%), while on ROS-Industrial's ChArUco capture (ratio above 1.5) it predicts
#: held-out views 34% better on all 16 views (2.8x better in 5-fold cross-validation).
PIXEL_MARGIN = 0.7


def robot_error_ratio(views: Views, candidates: dict[str, Fit]) -> float | None:
    """The pixel refinement's residual std over the PnP poses' on the same points, each per degree
    of freedom (the hand-eye fit has 12 unknowns, and the intrinsics when it refines them; PnP 6 per view):
    ~1 when the robot's poses are exact up to the camera's noise. None without a pixel refinement
    among ``candidates``, before it was fitted, or with too few points (the pixel refinement then
    stays preferred)."""
    name = _pixel_name(candidates)
    done = getattr(candidates.get(name), "full", None) if name is not None else None
    if not done or not views.has_pixels:
        return None
    points = np.array([len(p) for p in _pixels(views)[0]])
    px = cast(NDArray[np.float64], pnp_errors(views)[0])  # views with images: their errors in pixels
    sq, count = float(np.sum(px ** 2 * points)), int(2 * points.sum())
    unknowns = 12 + (len(INTRINSICS) if name == PIXEL_INTRINSICS else 0)
    dof_pnp, dof_pixel = count - 6 * len(views), count - unknowns
    if dof_pnp <= 0 or dof_pixel <= 0 or sq <= 0:
        return None
    pixel_sq = done[0].rms_px ** 2 * (count // 2)  # rms_px is per point (x and y together)
    return float(np.sqrt((pixel_sq / dof_pixel) / (sq / dof_pnp)))


def _pixel_name(candidates: dict[str, Fit]) -> str | None:
    """The pixel refinement among ``candidates`` that holds the robot exact (intrinsics refined first)."""
    return next((p for p in (PIXEL_INTRINSICS, PIXEL) if p in candidates), None)


def _scale_off(views: Views) -> bool:
    """The board's scale is off by more than 3 of its std and more than 1%
    (:func:`~handeye.estimation.diagnostics.board_scale`): then a wrong square size, not the robot, makes the
    pixel fit's excess residual. An arm's link-length errors also move the scale, by 0.05-0.7% on
    rendered sessions with 0.2-3 mm of kinematic error, beyond 3 std in 5 of 24 at 3 mm."""
    scale = board_scale(views.flange2base, views.target2cam, views.setup)
    return scale is not None and abs(scale[0] - 1.0) > max(3.0 * scale[1], SCALE_TOLERANCE)


def _errors(r: CrossValidation) -> NDArray[np.float64]:
    return r.px if r.px is not None else r.mm


#: :func:`intrinsics_cov` steps this many standard deviations along each principal direction of
#: the intrinsics' covariance (a poorly determined k3 moves by tens); 1.0 gives the same std.
INTRINSICS_STEP = 0.25


def intrinsics_cov(name: str, fit: Fit, views: Views, X: NDArray[np.float64],
                   Z: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """Covariance of X (6x6, as ``Calibration.cov``) from the error of intrinsics estimated from
    these very views, for the estimator ``name`` (fitted by ``fit``) when it holds them fixed: the
    pose refinement, the closed forms and the pixel refinement without intrinsics. The intrinsics'
    error is common to every view, so neither a noise model nor the jackknife sees it. X is refitted
    with the intrinsics moved along each principal direction of their covariance
    (:func:`~handeye.sensors.camera.pnp.intrinsics_covariance`) and every view's PnP pose refitted to them;
    the differences, scaled to one standard deviation, give the covariance (10 refits; the pixel
    refinement's warm-started and on every point: 0.6 s for 30 images of a 28x17 board). None for the
    estimators that refine the intrinsics themselves, for views without pixels or with other than
    the 5 coefficients :func:`~handeye.sensors.camera.pnp.calibrate_intrinsics` estimates, and when a refit
    fails.

    Measured on rendered sessions of 8 images: X's change from the true intrinsics to the
    estimated ones is within 3 of these std on 97% of the axes (median ratio 0.84 where a Gaussian
    gives 0.67: detection errors correlated within an image make the intrinsics' covariance, as
    OpenCV's, ~1.15x too small); added to the jackknife and the robot's accuracy, X's whole error
    is within 3 std on 87-100% of the axes at 8, 12 and 20 images (60-100% without it)."""
    if name in REFINE_INTRINSICS or not views.has_pixels or len(np.ravel(_pixels(views)[3])) != 5:
        return None
    try:
        object_points, image_points, K, dist = _pixels(views)
        cov_K = intrinsics_covariance(object_points, image_points, views.target2cam, K, dist)
        lam, V = np.linalg.eigh(cov_K)
        # differences from X refitted the same way at the intrinsics as estimated (not the given X,
        # which a robust fit or another start may have put a hair away)
        X0 = _fit_with_intrinsics(name, fit, views, X, Z, np.zeros(9))
        diffs = []
        for lam_j, v in zip(lam, V.T):
            if lam_j > 0:
                Xj = _fit_with_intrinsics(name, fit, views, X, Z, INTRINSICS_STEP * np.sqrt(lam_j) * v)
                d_rot = Rotation.from_matrix(Xj[:3, :3] @ X0[:3, :3].T).as_rotvec()
                diffs.append(np.r_[d_rot, Xj[:3, 3] - X0[:3, 3]] / INTRINSICS_STEP)
    except (HandEyeError, np.linalg.LinAlgError, ValueError):
        return None  # a refit that fails: the caller says the term is missing
    if not diffs:
        return None
    D = np.array(diffs)
    return D.T @ D


def _fit_with_intrinsics(name: str, fit: Fit, views: Views, X: NDArray[np.float64], Z: NDArray[np.float64],
                         step: NDArray[np.float64]) -> NDArray[np.float64]:
    """X fitted by ``name`` to the views with the intrinsics (fx fy cx cy k1 k2 p1 p2 k3) moved by ``step``."""
    object_points, image_points, K_given, dist_given = _pixels(views)
    K = K_given.copy()
    K[0, 0] += step[0]
    K[1, 1] += step[1]
    K[0, 2] += step[2]
    K[1, 2] += step[3]
    dist = np.ravel(dist_given) + step[4:]
    if name == PIXEL:  # the pixel refinement reads the intrinsics, not the PnP poses: refitted from its fit
        corners = cast(_KeptCorners, fit)  # the pixel refinement's (:func:`_corners`)
        if not corners.core:
            fit(views.flange2base, views.target2cam, views.setup, np.arange(len(views)))
        return corners.core[0].with_intrinsics(K, dist)
    target2cam = np.array([refine_pnp(T, P, uv, K, dist)
                           for T, P, uv in zip(views.target2cam, object_points, image_points)])
    return fit(views.flange2base, target2cam, views.setup, np.arange(len(views)))[0]
