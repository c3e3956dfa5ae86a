"""The pipelines: robot and camera poses (``calibrate_poses``), or a capture session of images and
robot poses (``calibrate``), to a :class:`~handeye.result.Calibration`.

``calibrate`` runs named steps, each returning a new result (``dataclasses.replace``), never
editing one: :func:`observe` (detection, intrinsics, PnP, symmetric targets), the closed form and
check of :func:`calibrate_poses`, then :func:`refine_on_pixels` or :func:`refine_on_poses`, and
last the image fields.
"""

from __future__ import annotations

from concurrent.futures import Future
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from .._shared.io import array_digest, files_digests_by_path, files_digests_soon
from .._shared.lazy import lazy_module
from .._shared.progress import Progress
from .._shared.text import sentences, summarize
from .._shared.threads import one_blas_thread
from ..errors import DegenerateMotionError, InputMismatchError
from ..estimation.diagnostics import closed_form, compare_solvers, diagnose, scale_is_off
from ..estimation.estimators import (
    PIXEL,
    PIXEL_INTRINSICS,
    PIXEL_ROBOT,
    POSE,
    REFINE_INTRINSICS,
    Choice,
    PosesFit,
    choose,
    closed_fit,
    intrinsics_cov,
    pixel_candidates,
    pixel_fit,
    pose_candidates,
    pose_fit,
    poses_fit,
)
from ..estimation.partial import calibrate_partial, known_on_complete, parse_known
from ..estimation.refinement import pose_fits_shared
from ..estimation.uncertainty import UNSEEN_FACTOR, robot_accuracy_cov, robot_accuracy_from_data, widened_uncertainty
from ..estimation.validation import Views, jackknife_covs, robot_error_seen
from ..estimation.verdict import judged, partial_pose_verdict, solver_spread
from ..frames.metrics import std_deg_mm
from ..frames.motions import MotionSet, Pairs, validate_poses
from ..frames.poses import RobotPoseInput
from ..frames.setups import Setup, check_setup
from ..geometry.se3 import invert, make_transform
from ..io.session import Session, SessionError, load_session
from ..options import ROBOT_ACCURACY, CalibrationOptions, options_from
from ..result import Calibration, Diagnostics, HeldOutErrors, StreamSync
from ..sensors.camera import (
    calibrate_intrinsics,
    detect_images,
    solve_pnp,
    target_from_spec,
    target_origin,
)
from ..sensors.camera.pnp import INTRINSICS, labelled_by_robot
from ..solvers.certifiable import certify
from ..solvers.low_dof import partial_kind
from ..solvers.refine import ReprojectionResult
from ._sensor import label_notes

_sync = lazy_module("handeye.estimation.sync")  # two clocks: loaded for a session with a robot stream only

__all__ = ["Calibration", "CalibrationOptions", "Observations", "ROBOT_ACCURACY", "apply_choice", "calibrate", "certify_calibration",
           "calibrate_observed", "calibrate_poses", "observe", "refine_on_pixels", "refine_on_poses",
           "robot_accuracy_cov", "robot_accuracy_from_data", "widened_uncertainty", "UNSEEN_FACTOR"]

#: Fewest usable poses for a calibration (two motions, as the solvers need).
MIN_POSES = 3
#: Above this RMS (px) of the intrinsic calibration, the result is flagged.
INTRINSICS_RMS_WARN = 1.0
#: refine='auto' keeps the pixel refinement only if its RMS stays within this factor of the
#: per-image PnP RMS (median), or below REFINE_RMS_FLOOR px: otherwise robot errors dominate.
REFINE_RMS_FACTOR = 3.0
REFINE_RMS_FLOOR = 1.0


#: calibrate_poses shows its steps from this many poses (a second or more).
PROGRESS_FROM_POSES = 200
#: calibrate shows its steps after detection from this many views (several seconds for large boards).
PROGRESS_FROM_IMAGES = 50


@dataclass(frozen=True)
class _PoseCall:
    """One call of :func:`calibrate_poses`, checked once at its entry, for the steps inside it: the
    setup, the options, the known values parsed against the setup, and what the poses were given as."""

    setup: Setup
    opts: CalibrationOptions
    given: dict
    robot_input: RobotPoseInput | None = None
    camera_input: RobotPoseInput | None = None
    symmetries: list | None = None
    names: list[str] | None = None
    uncertainty: bool = True
    camera_from_images: bool = False


def _checked_poses(flange2base, target2cam, call: _PoseCall, check: bool, strict: bool = False, camera_input=None):
    """The poses to calibrate on after :func:`handeye.diagnose` (outliers left out, explicit pairs
    renumbered): ``(flange2base, target2cam, pairs, keep, diagnostics, notes)``. Raises only when X
    cannot be determined, or (``strict``) when the data are inconsistent."""
    keep = np.arange(len(flange2base))
    pairs = call.opts.pairs
    if not check:
        return flange2base, target2cam, pairs, keep, None, []
    diag = diagnose(flange2base, target2cam, call.setup, robot_input=call.robot_input, camera_input=camera_input,
                    symmetries=call.symmetries, names=call.names, camera_from_images=call.camera_from_images)
    if diag.verdict == "degenerate":
        raise DegenerateMotionError(sentences(diag.advice), diagnostics=diag)
    if diag.verdict == "inconsistent" and strict:
        raise InputMismatchError(f"{diag.advice[0]} (strict=False returns the best estimate with this verdict)")
    if diag.outliers:
        n_input = len(flange2base)
        keep = _kept(diag)
        flange2base, target2cam = flange2base[keep], target2cam[keep]
        if not isinstance(pairs, str):  # explicit pairs: drop those with an outlier, renumber
            old_to_new = np.full(n_input, -1)
            old_to_new[keep] = np.arange(len(keep))
            p = old_to_new[np.asarray(pairs)]
            pairs = p[(p >= 0).all(axis=1)]
    return flange2base, target2cam, pairs, keep, diag, list(diag.advice)


@pose_fits_shared()  # the check's refit on all the poses is the pose candidate's fit
def calibrate_poses(
    flange2base: ArrayLike,
    target2cam: ArrayLike,
    setup: str = "eye_in_hand",
    options: CalibrationOptions | None = None,
    *,
    robot_input: RobotPoseInput | None = None,
    camera_input: RobotPoseInput | None = None,
    symmetries: list | None = None,
    names: list[str] | None = None,
    progress: bool = True,
    uncertainty: bool = True,
    camera_from_images: bool = False,
    **changes,
) -> Calibration:
    """Hand-eye calibration from robot poses and camera-to-target poses.

    Parameters
    ----------
    flange2base : array_like, shape (N, 4, 4)
        Flange poses reported by the robot (metres); see :func:`handeye.parse_poses`.
    target2cam : array_like, shape (N, 4, 4)
        Target poses in the camera frame (``solvePnP``'s rvec/tvec), metres.
    setup : {'eye_in_hand', 'eye_to_hand'}
    options : CalibrationOptions, optional
        How to calibrate (:class:`handeye.CalibrationOptions`); any of its fields can be given as a
        keyword instead (``method='tsai_lenz'``) or on top of it. The fields:
    method : str
        A solver from ``handeye.solvers.available()``: an AX = XB solver (Z is then the mean of
        the per-pose Z_i), or a robot-world one (``shah``, ``li``), which estimates X and Z together.
    refine : {'auto', 'pose', 'none'}
        'auto' (default): the estimator that predicts held-out poses best, by ``folds``-fold
        cross-validation (:mod:`handeye.estimation.estimators`): the closed forms (all but ``horaud_nonlinear``)
        or the pose refinement. 'pose': X and Z refined jointly from the ``method`` solution:
        Strobl-Hirzinger's optimal correction with noise variances estimated from the data
        (``pose_noise``), as the estimation core fits it (:func:`handeye.estimation.estimators.poses_fit`,
        the same X as :func:`handeye.estimation.refinement.refine_pose`). 'none': the closed form as is. Each
        reports ``cov`` and ``std``: the noise model (none for a closed form), the jackknife spread
        and the robot's accuracy (``std_sources``).
    pairs : {'auto', 'all', 'consecutive'} or (K, 2) array
        The pose pairs of the motions (:func:`handeye.frames.motions.pair_indices`).
    check : bool
        Run :func:`handeye.diagnose` first (default): degenerate motions raise an error; outlier
        poses are left out, with a note; inconsistent data (with the convention that fixes them,
        when one does) and weak data are calibrated all the same, with the verdict and the advice
        (``verdict``, ``diagnostics``, ``notes``). ``check=False`` calibrates the poses as they are.
    strict : bool
        Raise :class:`InputMismatchError` instead of answering inconsistent data.
    folds : int, optional
        Cross-validation folds of ``refine='auto'`` (default: one per pose up to 10 poses, else 5).
    robot_accuracy : (deg, mm) or None
        The robot's absolute accuracy per axis, which X absorbs unseen (added to its covariance; None: exact).
    known : dict, optional
        What the data cannot determine (SCARA, Cartesian robots; :mod:`handeye.estimation.partial`), e.g.
        ``{'target2base.z': 0.012}`` or ``{'cam2flange.z': (0.085, 0.001)}``: translation components of
        X or Z in metres (exact, ``(value, std)`` or ``'value+-std'``); values the data determine are
        compared with them (a note), not used.
    robot_input, camera_input, symmetries, names, progress, uncertainty, camera_from_images
        Keyword-only: the robot (camera) poses as written (:class:`RobotPoseInput`); a symmetric target's
        symmetries (the check relabels the images under each); each pose's name (image file or row id);
        the steps on stderr; False skips the std's jackknife and robot accuracy (X alone, in a loop);
        ``target2cam`` is handeye's own PnP (the check then never advises inverting it).

    Returns
    -------
    Calibration
        With ``diagnostics`` (when checked) and ``pose_indices``, the input poses used; with
        'auto', ``estimator``, ``cross_validation`` and ``prediction_error``. Motions about one axis
        (or none): the pose refinement with the known values, ``unobservable`` naming the rest.

    Raises
    ------
    DegenerateMotionError
        The motions cannot determine X (advice in the message).
    InputMismatchError
        ``strict`` and the poses do not agree on one X; the message names the likely mistake.

    Examples
    --------
    >>> import handeye
    >>> from handeye.simulate import Noise, add_noise, random_scene
    >>> scene = random_scene(12, "eye_in_hand", rng=0)
    >>> target2cam = add_noise(scene.target2cam, Noise(rot_deg=0.02, trans_mm=0.2), np.random.default_rng(0))
    >>> cal = handeye.calibrate_poses(scene.flange2base, target2cam, setup="eye_in_hand", progress=False)
    >>> cal.verdict, cal.cam2flange.shape
    ('good', (4, 4))
    >>> bool(1e3 * np.linalg.norm(cal.X[:3, 3] - scene.X[:3, 3]) < 3 * np.linalg.norm(cal.std[3:]))   # within its std
    True
    """
    opts = options_from(options, changes).for_poses()
    setup = check_setup(setup)
    call = _PoseCall(setup, opts, parse_known(opts.known, setup), robot_input, camera_input, symmetries, names, uncertainty,
                     camera_from_images)
    flange2base_in, target2cam_in = validate_poses(flange2base, target2cam)
    bar = Progress(3, f"calibrating {len(flange2base_in)} poses: check, estimators, uncertainty",
                   progress and len(flange2base_in) >= PROGRESS_FROM_POSES)
    try:
        flange2base, target2cam, pairs, keep, diag, notes, scale = _checked_at_scale(flange2base_in, target2cam_in, call)
        bar.update()
        target_scale = 1.0 if scale is None else scale[0]
        digest = array_digest(flange2base_in, target2cam_in)
        if (kind := partial_kind(flange2base, target2cam, setup) if diag is None or diag.motion_kind != "general" else None):
            return replace(_partial(flange2base, target2cam, call, kind, pairs, diag, keep, digest), target_scale=target_scale)
        X, Z, motions = closed_form(flange2base, target2cam, setup, opts.method, pairs)
        cal = Calibration(
            X=X, Z=Z, setup=setup, method=opts.method, flange2base=flange2base, target2cam=target2cam, pairs=motions.pairs,
            motions=motions, diagnostics=diag, pose_indices=keep, notes=notes, robot_input=robot_input,
            inputs_sha256=digest, estimator=opts.method, target_scale=target_scale)
        cal = _refined(cal, call, pairs, bar)
        if scale is not None and cal.cov is not None:
            cal = _with_scale_error(cal, scale, opts.method)
        bar.update(bar.total - bar.done)
    finally:
        bar.close()
    return known_on_complete(cal, call.given)


def certify_calibration(cal: Calibration) -> Calibration:
    """``cal`` with ``certificate``: whether its X is the global minimum of the stated AX = XB cost of
    :mod:`handeye.solvers.certifiable` on its motions (the duality gap of the semidefinite
    relaxation), and a note saying so. Needs ``handeye[certifiable]``. The estimator that chose X
    may minimise another cost (the pose or pixel refinements do): a gap then says how far X is from
    that cost's minimum, not that X is wrong."""
    if cal.target2cam is None and cal.motions is None:
        raise InputMismatchError("certify: the certificate is of the AX = XB cost on the camera's motions; this "
                                 f"calibration ({cal.method}) has no camera poses: leave --certify out")
    if cal.motion_kind != "general":  # the relaxation needs motions that determine all of X
        return replace(cal, notes=list(cal.notes) + ["certificate: not computed (the motions determine only part of X)"])
    motions = cal.motions if cal.motions is not None else MotionSet.from_poses(cal.flange2base, cal.target2cam,
                                                                                cal.setup, cal.pairs)
    cert = certify(motions, None, cal.X)
    if cert.optimal:
        note = f"certificate: X is the global minimum of the stated motion cost (gap {cert.gap:.3g})"
    else:
        note = (f"certificate: X is not the global minimum of the stated motion cost (gap {cert.gap:.3g} of "
                f"{cert.cost:.3g}; {cal.estimator or cal.method} minimises "
                f"{'that cost' if cal.method == 'certifiable' else 'another'})")
    return replace(cal, certificate=cert, notes=list(cal.notes) + [note])


def _refined(cal: Calibration, call: _PoseCall, pairs: Pairs, bar: Progress) -> Calibration:
    """The closed form ``cal`` refined as ``call.opts.refine`` says (:func:`calibrate_poses`)."""
    refine, method, accuracy, uncertainty = call.opts.refine, call.opts.method, call.opts.robot_accuracy, call.uncertainty
    if refine == "pose" or (refine == "auto" and len(cal.flange2base) < 5):
        return _pose_refined(cal, method, accuracy, uncertainty)
    if refine == "auto":
        views = Views(cal.flange2base, cal.target2cam, cal.setup)
        choice = choose(views, pose_candidates(method, views), call.opts.folds)
        bar.update()
        return apply_choice(cal, choice, views, pairs, robot_accuracy=accuracy, uncertainty=uncertainty)
    if uncertainty:  # the closed form alone: no noise model, the jackknife and the robot's accuracy
        return _uncertain(cal, closed_fit(method, pairs), Views(cal.flange2base, cal.target2cam, cal.setup), accuracy)
    return cal


def _partial(flange2base, target2cam, call: _PoseCall, kind: str, pairs: Pairs, diag: Diagnostics | None, keep,
             digest: str) -> Calibration:
    """:func:`calibrate_poses` on motions that determine only part of X (:mod:`handeye.estimation.partial`)."""
    accuracy = call.opts.robot_accuracy
    cal = calibrate_partial(flange2base, target2cam, call.setup, kind, pairs, call.given, refine=call.opts.refine != "none")
    diag = partial_pose_verdict(diag, len(flange2base), complete=not cal.unobservable)
    # the check's advice beyond the partial verdict's own sentence (calibrate_partial's note says it): outliers
    cal = replace(cal, diagnostics=diag, pose_indices=keep, robot_input=call.robot_input, inputs_sha256=digest,
                  notes=cal.notes + list(diag.advice[1:]))
    if cal.cov is not None and accuracy is not None:
        cov = cal.cov + robot_accuracy_cov(cal.X, accuracy)
        std = np.where(np.isinf(cal.std), np.inf, _std(cov))
        cal = replace(cal, cov=cov, std=std, notes=cal.notes + [
            f"the std of X includes the robot's absolute accuracy, assumed {accuracy[0]:g} deg / {accuracy[1]:g} mm "
            "per axis (robot_accuracy=(deg, mm))"])
    return judged(cal)


def _std(cov_X: NDArray[np.float64]) -> NDArray[np.float64]:
    """Standard deviations of X's six parameters in degrees and millimetres."""
    return std_deg_mm(cov_X)


def refine_on_poses(cal: Calibration, ref: PosesFit | None = None) -> Calibration:
    """``cal`` with X and Z refined on its poses (:func:`~handeye.estimation.estimators.poses_fit`, or
    the refinement ``ref`` of them already made) and the uncertainty fields set."""
    if ref is None:
        ref = poses_fit(Views(cal.flange2base, cal.target2cam, cal.setup), cal.X, cal.Z)
    notes = list(cal.notes)
    if not ref.converged:
        notes.append(f"pose refinement: the noise estimates did not settle in {ref.rounds} rounds; "
                     "the reported uncertainty is approximate")
    return replace(
        cal, X=ref.X, Z=ref.Z, cov=ref.cov_X, std=_std(ref.cov_X), refinement="pose", method=f"{cal.method}+pose",
        notes=notes, estimator=POSE, pose_noise={
            "robot_rotation_deg": float(np.degrees(ref.noise["robot_rotation"])),
            "camera_rotation_deg": float(np.degrees(ref.noise["camera_rotation"])),
            "translation_mm": 1e3 * ref.noise["translation"],
            "camera_depth_mm": 1e3 * ref.noise["camera_depth"],
        },
    )


def apply_choice(cal: Calibration, choice: Choice, views: Views, pairs: Pairs = "auto", obs: "Observations | None" = None,
                 robot_noise: tuple[float, float] | None = None,
                 robot_accuracy: tuple[float, float] | None = ROBOT_ACCURACY, uncertainty: bool = True) -> Calibration:
    """``cal`` (a closed form on its poses) refitted by the estimator ``choice`` chose, on all of its
    poses, with the cross-validation table and (``uncertainty``) the widened uncertainty."""
    name = choice.name
    if name == POSE:
        done = getattr(choice.fits[POSE], "full", None)  # the refinement on these very poses, if made
        cal = refine_on_poses(cal, done[0] if done else None)
    elif name in (PIXEL, PIXEL_INTRINSICS, PIXEL_ROBOT):
        cal = _final_pixel_fit(cal, obs, name, robot_noise, pairs, choice.fits[name])
    elif name != cal.estimator:  # another closed form
        X, Z, motions = closed_form(cal.flange2base, cal.target2cam, cal.setup, name, pairs)
        cal = replace(cal, X=X, Z=Z, method=name, motions=motions, pairs=motions.pairs)
    cal = replace(cal, estimator=name, cross_validation=HeldOutErrors(choice.table(), choice.best.folds))
    if uncertainty:
        cal = _spread_judged(_uncertain(cal, choice.fits[name], views, robot_accuracy, obs), choice)
    notes = list(cal.notes) + [f"estimator {name}: chosen by {choice.best.folds}-fold cross-validation, held-out error "
                               + _cv_text(choice.table()[name])]
    return replace(cal, notes=notes)


def _uncertain(cal: Calibration, fit, views: Views, robot_accuracy: tuple[float, float] | None,
               obs: "Observations | None" = None) -> Calibration:
    """``cal``, fitted by the estimator ``fit`` on ``views``, with the std every estimator reports (the
    noise model widened by the jackknife spread of ``fit``, plus the robot's accuracy, plus the
    intrinsics' error when ``obs`` estimated them from these images) and its verdict weakened when
    that std is too wide: the same whether the estimator was chosen or named."""
    intrinsics = None
    if obs is not None and obs.intrinsics_source == "estimated" and cal.estimator not in REFINE_INTRINSICS:
        intrinsics = intrinsics_cov(cal.estimator, fit, views, cal.X, cal.Z)
        if intrinsics is None:
            cal = replace(cal, notes=list(cal.notes) + [
                "the error of the intrinsics estimated from these images could not be propagated to X (a refit "
                "failed): the std of X leaves it out; give K and dist in session.yaml"])
    cov_X, cov_Z = jackknife_covs(fit, views, cal.X, cal.Z)
    if cov_X is None and cal.cov is None:  # a closed form on too few poses to refit without one
        cal = replace(cal, notes=list(cal.notes) + [
            f"the std of X leaves out the poses' noise: {cal.estimator or cal.method} has no noise model and "
            f"{len(views)} poses are too few to refit it without each one; add poses, or refine='pose'"])
    seen = None if robot_accuracy is None else robot_error_seen(cal.X, cal.Z, views)
    cal = widened_uncertainty(cal, cov_X, robot_accuracy, intrinsics, seen, views.has_pixels)
    if cov_Z is not None:  # a constant robot error moves Z about as much as X
        accuracy = robot_accuracy_from_data(robot_accuracy, seen)
        robot_Z = np.zeros((6, 6)) if accuracy is None else robot_accuracy_cov(cal.Z, accuracy)
        cal = replace(cal, std_Z=_std(cov_Z + robot_Z))
    return judged(cal)


def _pose_refined(cal: Calibration, method: str, robot_accuracy: tuple[float, float] | None,
                  uncertainty: bool = True, obs: "Observations | None" = None) -> Calibration:
    """``cal`` (the closed form ``method`` on its poses) refined on its poses, as named (``refine='pose'``)
    or with too few poses to choose (fewer than 5): its std as :func:`_uncertain` (with 4 poses the
    jackknife refits 3). The noise model alone, its three variances estimated from few residuals,
    covered X's error within 3 std on 80-94% of the axes of realistic 4-pose sessions, and on 30-90%
    of them between the halves of ViSP's 8-view 2022 capture."""
    views = Views(cal.flange2base, cal.target2cam, cal.setup) if obs is None else obs.views(np.asarray(cal.pose_indices))
    ref = poses_fit(views, cal.X, cal.Z)
    cal = refine_on_poses(cal, ref)
    if not uncertainty:
        return cal
    return _uncertain(cal, pose_fit(method, views, ref), views, robot_accuracy, obs)


def _final_pixel_fit(cal: Calibration, obs: Observations, name: str, robot_noise, pairs: Pairs,
                     fit=None) -> Calibration:
    """The pixel refinement ``name`` on every used image, the check's pose outliers back in: a pose
    can look off because its PnP is weak (a far or fronto-parallel view) while its pixels fit, and
    the robust pixel fit judges every point (an image whose points all disagree is named)."""
    everything = np.arange(len(obs.used))
    outliers = sorted(set(everything.tolist()) - set(cal.pose_indices.tolist()))
    notes = list(cal.notes)
    if outliers:
        notes = [n for n in notes if "left out" not in n]
        notes.append(f"image(s) {summarize(obs.session.image_names[obs.used[k]] for k in outliers)} looked like "
                     f"outliers by their PnP poses but are kept: the robust pixel refinement judges their points")
        motions = MotionSet.from_poses(obs.flange2base, obs.target2cam, cal.setup, pairs)
        cal = replace(cal, flange2base=obs.flange2base, target2cam=obs.target2cam, pairs=motions.pairs,
                      motions=motions, pose_indices=everything, notes=notes)
    done = getattr(fit, "full", None)
    if done and not outliers:  # the candidate's robust fit on these very images
        ref = done[0]
    else:
        sigma = _robot_sigma(robot_noise) if name == PIXEL_ROBOT else None
        ref = pixel_fit(obs.views(everything), everything, cal.X, cal.Z,
                        name != PIXEL and obs.intrinsics_source == "estimated", sigma)
    return replace(refine_on_pixels(cal, obs, ref, robot_noise if name == PIXEL_ROBOT else None), estimator=name)


def _spread_judged(cal: Calibration, choice: Choice) -> Calibration:
    """``cal`` judged with the spread of the closed forms about X (each a fair estimate on these
    poses: when they typically land further from X than 3 std, the std promises more than the data
    support). The solver comparison it computes is kept (``solver_comparison``: the report draws it)."""
    if cal.std is None or cal.diagnostics is None or cal.diagnostics.verdict != "good":
        return cal
    f2b, t2c, pairs = cal.flange2base, cal.target2cam, cal.pairs
    diag = cal.diagnostics
    if diag.outliers and len(f2b) == diag.n_poses:  # the pixel refinement put the check's outliers back: not these
        keep = _kept(diag)
        f2b, t2c, pairs = f2b[keep], t2c[keep], "auto"
    rows = compare_solvers(f2b, t2c, cal.setup, cal.X, pairs)
    # fair estimates only: a closed form that predicts held-out views far worse than the estimator chosen (noisy
    # PnP poses, which the pixel refinement does not use) lands far from X without the std promising too much
    own = choice.results[choice.name].score
    fair = [m for m, r in choice.results.items() if np.isfinite(r.score) and r.score <= SPREAD_FAIR * own]
    closed = {r["method"] for r in rows}
    unfair = [m for m in choice.results if m in closed and m not in fair]
    spread = solver_spread(rows, unfair)
    factor = min((choice.results[m].score for m in unfair), default=np.inf) / own if own > 0 else np.inf
    return judged(replace(cal, solver_comparison=rows), solver_spread(rows, fair),
                  None if spread is None else (*spread, factor))


#: The closed forms whose held-out error is within this factor of the chosen estimator's are fair
#: estimates of X: their spread about X is held against its std. Rendered ChArUco sessions (15 views,
#: 640x480): the closed forms landed 2.2-3.7 mm from a pixel-refined X that was 0.1-0.2 mm from the truth
#: (3 std: 1.8 mm), predicting held-out views several times worse.
SPREAD_FAIR = 1.5


def _cv_text(row: dict[str, float | None]) -> str:
    return (f"{row['px']:.3f} px, " if row.get("px") is not None else "") + f"{row['mm']:.3f} mm at the target"


@dataclass(frozen=True)
class Observations:
    """What the images of a session say, before any hand-eye solve (:func:`observe`).

    ``used`` indexes the session's images that gave a target pose; the per-image fields follow it.
    """

    session: Session
    used: list[int]
    flange2base: NDArray[np.float64]  #: robot poses of the used images
    target2cam: NDArray[np.float64]  #: PnP poses, symmetric targets relabelled to agree with the robot
    pnp_rms: list[float]  #: PnP reprojection RMS per used image (px)
    object_points: list[NDArray[np.float64]]  #: per used image, in the (relabelled) target frame (m)
    image_points: list[NDArray[np.float64]]  #: per used image, detections (px)
    K: NDArray[np.float64]
    dist: NDArray[np.float64]
    intrinsics_source: str  #: "session.yaml" or "estimated"
    intrinsics_rms: float | None
    skipped: list[tuple[str, str]]  #: (image, reason)
    notes: list[str]
    robot_input: RobotPoseInput | None  #: the robot poses of the used images as written
    #: the input files' digests and each one's by path (:func:`~handeye._shared.io.files_digests_soon`)
    input_digests: Future | None = field(default=None, compare=False, repr=False)

    def views(self, idx=None) -> Views:
        """The used images ``idx`` (indices into ``used``; default all) as cross-validation views."""
        idx = np.arange(len(self.used)) if idx is None else np.asarray(idx)
        return Views(self.flange2base[idx], self.target2cam[idx], self.session.setup,
                     [self.object_points[i] for i in idx], [self.image_points[i] for i in idx], self.K, self.dist)

    def subset(self, idx) -> "Observations":
        """The same observations restricted to the used images ``idx`` (indices into ``used``)."""
        idx = [int(i) for i in idx]
        ri = self.robot_input
        return replace(self, used=[self.used[i] for i in idx], flange2base=self.flange2base[idx],
                       target2cam=self.target2cam[idx], pnp_rms=[self.pnp_rms[i] for i in idx],
                       object_points=[self.object_points[i] for i in idx], image_points=[self.image_points[i] for i in idx],
                       robot_input=None if ri is None else replace(ri, values=ri.values[idx]))

    def scaled(self, scale: float) -> "Observations":
        """The same observations with the target ``scale`` times as large: its points, and the PnP
        poses' translations (PnP on points scaled by s gives the same rotation, the translation times s)."""
        target2cam = self.target2cam.copy()
        target2cam[:, :3, 3] *= scale
        return replace(self, target2cam=target2cam, object_points=[scale * np.asarray(p) for p in self.object_points])


def _detect(session: Session, jobs: int | None, progress: bool, strict_images: bool = False):
    """Detections per image, the image size and the images skipped with why (missing, unreadable,
    target not found); ``strict_images``: a missing or unreadable image is an error."""
    target = target_from_spec(session.target_spec)
    present = [k for k, p in enumerate(session.image_paths) if Path(p).is_file()]
    found_results = (detect_images([session.image_paths[k] for k in present], target, jobs=jobs, progress=progress)
                     if present else [])
    results: list = [None] * len(session.image_paths)
    for k, r in zip(present, found_results):
        results[k] = r
    unreadable = [session.image_names[k] for k, r in enumerate(results) if r is None or r.image_size is None]
    if unreadable and strict_images:
        raise SessionError(f"{session.folder / 'images'}: cannot read image(s) {summarize(unreadable)} (missing, corrupt "
                           "or not an image); without --strict-images (strict_images=False) they are skipped")
    skipped = [(name, "missing from images/" if r is None else r.error)
               for name, r in zip(session.image_names, results) if r is None or r.detection is None]
    found = [k for k, r in enumerate(results) if r is not None and r.detection is not None]
    sizes = {results[k].image_size for k in found}  # the images that count: those with the target
    if len(sizes) > 1:
        by_size = {sz: [session.image_names[k] for k in found if results[k].image_size == sz] for sz in sorted(sizes)}
        raise SessionError(f"{session.folder / 'images'}: images differ in size ("
                           + "; ".join(f"{w}x{h}: {', '.join(n[:3])}{' ...' if len(n) > 3 else ''}" for (w, h), n in by_size.items())
                           + "); one camera and resolution per session")
    if len(found) < MIN_POSES:
        raise SessionError(
            f"the {target.type} target was found in only {len(found)} of {len(results)} images "
            f"(at least {MIN_POSES} are needed); " + (_counted_squares(session, results) or
                                                       "check the target description in session.yaml"))
    return target, {k: results[k].detection for k in found}, (sizes.pop() if sizes else None), skipped


#: Unknowns of the intrinsics estimate beside the view poses (:data:`handeye.sensors.camera.pnp.INTRINSICS`).
INTRINSIC_UNKNOWNS = len(INTRINSICS)


def _intrinsics_counts(detections: dict) -> tuple[int, int]:
    """Points detected, and unknowns of estimating the intrinsics from them (with the view poses)."""
    return sum(len(d) for d in detections.values()), INTRINSIC_UNKNOWNS + 6 * len(detections)


def _check_intrinsics_data(points: int, unknowns: int, images: int, target: str) -> None:
    """Raise :class:`SessionError` when the detections hold fewer equations (two per point) than
    the intrinsics estimate has unknowns (nine, and six per view; :func:`_intrinsics_counts`):
    OpenCV would stop with a bare 'less vars to optimize' error (a few images of one AprilTag)."""
    if 2 * points <= unknowns:
        raise SessionError(
            f"session.yaml gives no camera intrinsics, and the {images} images with the {target} found hold "
            f"{points} points: {2 * points} equations for the {unknowns} unknowns of estimating them (9, and 6 per "
            f"image). Give the camera's K and dist in session.yaml (camera:), or take more images (or a target with "
            f"more points, e.g. a chessboard or ChArUco board)")


def _counted_squares(session: Session, results: list) -> str | None:
    """For a target not found: whether it was miscounted (:meth:`Target.miscounted`: a chessboard's
    squares counted instead of its inner corners), tried on up to 3 of the images."""
    slip = target_from_spec(session.target_spec).miscounted()
    if slip is None:
        return None
    meant, hint = slip
    tried = [session.image_paths[k] for k, r in enumerate(results) if r is not None and r.image_size is not None][:3]
    if not any(r.detection is not None for r in detect_images(tried, meant, jobs=1, progress=False)):
        return None
    return hint


def observe(session: Session, jobs: int | None = None, progress: bool = True,
            strict_images: bool = False, digests: bool = False) -> Observations:
    """Detect the target in every image of ``session`` (in parallel), take the intrinsics from
    session.yaml or estimate them from the same images, solve PnP per image and relabel symmetric
    targets so that every camera motion agrees with its robot motion. Missing and unreadable images
    are skipped with the reason (``skipped``), or (``strict_images``) an error. ``digests``: hash the
    input files in the background from when the detection ends (``input_digests``, for the result).

    Raises
    ------
    SessionError
        (``strict_images``) a missing or unreadable image; images of different sizes; fewer than 3 images with the target found;
        no intrinsics in session.yaml and too few points to estimate them.
    """
    target, detections, image_size, skipped = _detect(session, jobs, progress, strict_images)
    hashed = files_digests_soon(session.input_files, session.folder) if digests else None
    notes = list(session.notes)
    if session.camera_matrix is not None:
        K, dist, source, k_rms = session.camera_matrix, session.dist_coeffs, "session.yaml", None
    else:
        points, unknowns = _intrinsics_counts(detections)
        _check_intrinsics_data(points, unknowns, len(detections), session.target_spec.get("type", "target"))
        K, dist, k_rms = calibrate_intrinsics(list(detections.values()), image_size)
        source = "estimated"
        if 2 * points < 3 * unknowns:  # fewer than 3 equations per unknown: the fit follows the noise
            notes.append(f"intrinsics estimated from {points} points ({2 * points} equations for {unknowns} unknowns): "
                         "poorly determined, and X with them; calibrate the camera separately and put K and dist in "
                         "session.yaml, or take more images")
        if k_rms > INTRINSICS_RMS_WARN:
            notes.append(f"intrinsics estimated from the images have an RMS reprojection error of {k_rms:.2f} px "
                         f"(> {INTRINSICS_RMS_WARN} px): calibrate the camera separately and put K and dist in session.yaml")
    used, poses, rms = [], [], []
    for k, det in detections.items():
        sol = solve_pnp(det, K, dist)
        if sol is None:
            skipped.append((session.image_names[k], "pose could not be estimated (fewer than 4 features)"))
            continue
        used.append(k)
        poses.append(sol[0])
        rms.append(sol[1])
    if len(used) < MIN_POSES:
        raise SessionError(f"only {len(used)} usable images (at least {MIN_POSES} are needed)")
    used_arr = np.array(used)
    flange2base = session.flange2base[used_arr]
    symmetries = target.symmetries()
    labelled = labelled_by_robot(np.array(poses), [detections[k].object_points for k in used], flange2base,
                                 session.setup, symmetries)
    target2cam, obj = labelled.target2cam, labelled.object_points  # the target frame relabelled (new = F^-1 old)
    img = [detections[k].image_points for k in used]
    notes += label_notes(target.type, len(symmetries), session.setup, [session.image_names[k] for k in used], labelled)
    robot_input = session.robot_input
    if robot_input is not None:
        robot_input = replace(robot_input, values=robot_input.values[used_arr])
    origin = target_origin(session.target_spec)
    if origin.any():  # origin: centre: the same axes, the origin moved (X is unchanged, Z moves with it)
        target2cam = target2cam @ make_transform(np.eye(3), origin)
        obj = [p - origin for p in obj]
    return Observations(session, used, flange2base, target2cam, rms, obj, img, K, dist, source, k_rms, skipped,
                        notes, robot_input, hashed)


def _robot_sigma(robot_noise: tuple[float, float] | None) -> tuple[float, float] | None:
    """``robot_noise`` (deg, mm; checked by :class:`CalibrationOptions`) in (rad, m)."""
    return None if robot_noise is None else (np.radians(robot_noise[0]), 1e-3 * robot_noise[1])


def refine_on_pixels(cal: Calibration, obs: Observations, ref: ReprojectionResult,
                     robot_noise: tuple[float, float] | None = None) -> Calibration:
    """``cal`` with the pixel refinement ``ref`` of its images applied (:func:`handeye.estimation.estimators.pixel_fit`):
    X, Z, the intrinsics and the uncertainty from it."""
    names = [obs.session.image_names[obs.used[k]] for k in cal.pose_indices]
    extra: list[str] = []
    if ref.n_rejected:
        extra.append(f"reprojection refinement set aside {ref.n_rejected} of {ref.n_points + ref.n_rejected} "
                     f"detected points as outliers (beyond 5 sigma)")
    if ref.rejected_images:
        extra.append(f"image(s) {summarize(names[k] for k in ref.rejected_images)}: every point set aside by the "
                     "robust pixel fit (the robot pose and the image disagree): check or retake them")
    pnp_median = float(np.median(obs.pnp_rms))
    if ref.rms_px > max(REFINE_RMS_FACTOR * pnp_median, REFINE_RMS_FLOOR):
        extra.append(f"the robot poses and the images disagree: with the robot poses taken as exact the best fit "
                     f"leaves {ref.rms_px:.2f} px RMS, while each image alone fits to {pnp_median:.2f} px; the robot "
                     "pose errors dominate")
    fields = dict(cov=ref.cov_X, std=_std(ref.cov_X)) if ref.cov_X is not None else {}
    method = cal.method + "+reprojection" + (
        f" (robot poses corrected, prior {robot_noise[0]:g} deg / {robot_noise[1]:g} mm)" if robot_noise else "")
    source = obs.intrinsics_source
    if source == "estimated" and not np.array_equal(ref.K, obs.K):
        source = "estimated, refined with the robot poses"
    return replace(cal, X=ref.X, Z=ref.Z, refinement="reprojection", refined_rms=ref.rms_px, method=method,
                   notes=list(cal.notes) + extra, camera_matrix=np.asarray(ref.K, dtype=float),
                   dist_coeffs=np.asarray(ref.dist, dtype=float).ravel(), intrinsics_source=source,
                   estimator=PIXEL_ROBOT if robot_noise else PIXEL, **fields)


def drop_pose_outliers(cal: Calibration, obs: Observations, left_out: dict[int, str] | None = None
                       ) -> tuple[list[int], list[tuple[str, str]]]:
    """When the poses decide: the used images without the outlier poses, and the outliers' images
    as skipped (with why: ``left_out``'s, per index of ``obs.used``, for views a later fit left out)."""
    skipped = []
    for k in sorted(set(range(len(obs.used))) - set(cal.pose_indices.tolist())):
        if left_out and k in left_out:
            skipped.append((obs.session.image_names[obs.used[k]], left_out[k]))
            continue
        r, t = cal.diagnostics.outlier_residuals[k]
        skipped.append((obs.session.image_names[obs.used[k]], f"outlier: its robot pose and target pose disagree "
                        f"with the others by {r:.2f} deg / {t:.1f} mm"))
    return [int(k) for k in cal.pose_indices], skipped


def with_images(cal: Calibration, obs: Observations, kept: list[int], skipped: list[tuple[str, str]],
                 notes: list[str]) -> Calibration:
    """``cal`` with the fields of the images it used (``kept`` indexes ``obs.used``)."""
    names = obs.session.image_names
    skipped = sorted(obs.skipped + skipped, key=lambda item: names.index(item[0]))
    # every input file read once (on a background thread since the detection ended: observe(digests=True))
    inputs_sha256, by_path = (obs.input_digests.result() if obs.input_digests is not None else
                              files_digests_by_path(obs.session.input_files, obs.session.folder))
    intrinsics = {}
    if cal.camera_matrix is None:  # not refined with X and Z: as observed
        intrinsics = dict(camera_matrix=np.asarray(obs.K, dtype=float), dist_coeffs=np.asarray(obs.dist, dtype=float).ravel(),
                          intrinsics_source=obs.intrinsics_source)
    return replace(
        cal, image_names=[names[obs.used[k]] for k in kept], reprojection_rms=np.array([obs.pnp_rms[k] for k in kept]),
        skipped=skipped, intrinsics_rms=obs.intrinsics_rms,
        image_paths=[obs.session.image_paths[obs.used[k]] for k in kept], input_folder=obs.session.folder,
        object_points=[obs.object_points[k] for k in kept], image_points=[obs.image_points[k] for k in kept],
        inputs_sha256=inputs_sha256, image_sha256=[by_path[str(obs.session.image_paths[obs.used[k]])] for k in kept],
        notes=list(cal.notes) + notes,
        **intrinsics,
    )


def calibrate(
    session_dir: str | Path,
    options: CalibrationOptions | None = None,
    *,
    jobs: int | None = None,
    progress: bool = True,
    **changes,
) -> Calibration:
    """Hand-eye calibration from a capture session folder (images + robot poses, the session format in docs/guide.md).

    Detects the target in every image (in parallel), takes the intrinsics from session.yaml or
    estimates them from the same images, solves PnP per image, and calibrates.

    Parameters
    ----------
    session_dir : path
    options : CalibrationOptions, optional
        How to calibrate (:class:`handeye.CalibrationOptions`); any of its fields can be given as a
        keyword instead (``refine='pose'``) or on top of it. The fields:
    method, pairs, check, strict, folds, robot_accuracy, known
        As :func:`calibrate_poses` (outlier poses' images are listed in ``skipped``). On motions
        that determine only part of X (SCARA, Cartesian robots), X comes from the PnP poses by the
        pose refinement with the ``known`` values (the pixel refinement does not run there yet).
    refine : {'auto', 'reprojection', 'pose', 'none'}
        'reprojection': X and Z (and the intrinsics, when estimated) refined jointly on the pixel
        errors of every target point (the estimation core's fit of the corners,
        :func:`handeye.estimation.estimators.corners_fit`), starting from ``method``, with the robot
        poses taken as exact (with ``robot_noise``: each pose's error fitted under that prior). 'pose': refined on the robot and PnP
        poses (:func:`handeye.estimation.estimators.poses_fit`), which allows for robot pose errors.
        'auto' (default): whichever of these, the closed forms and (with ``robot_noise``) the pixel
        refinement with robot pose corrections predicts held-out images best, by ``folds``-fold
        cross-validation (:mod:`handeye.estimation.estimators`); the std covers the spread of those fits too.
    robot_noise : (deg, mm), optional
        Standard deviation per axis of the robot's pose errors (its accuracy where the images were
        taken; the data sheet's repeatability is a lower bound). The reprojection refinement then
        gives every robot pose a small correction with that prior instead of taking the poses as
        exact, so robot errors no longer bias X and the uncertainty accounts for them.
    jobs : int, optional
        Detection workers (default: the available cores).
    progress : bool
        Progress bar on stderr.
    keyframes, offset_range, time_offset
        For a session whose poses are a robot stream (poses.csv with a time column, the images'
        times in an ``images:`` table): as :func:`handeye.calibrate_streams`; the images are the
        camera stream (the clock offset is estimated from 20 or more images of a video; a few
        scattered images meet the robot at their own times, or at ``time_offset``).

    Returns
    -------
    Calibration
        With ``image_names`` (the images used), ``skipped`` (image, reason), per-image PnP
        ``reprojection_rms``, ``refined_rms`` (all points, after refinement), the intrinsics used
        (refined together with X and Z when they were estimated) and ``notes`` (warnings).

    Raises
    ------
    SessionError
        Bad session folder; (``strict_images``) a missing or unreadable image; fewer than 3 images
        with the target found.

    Examples
    --------
    The bundled sample session (12 rendered chessboard images, KUKA poses):

    >>> import handeye
    >>> from importlib.resources import files
    >>> cal = handeye.calibrate(files("handeye") / "data" / "sample_session", progress=False)
    >>> cal.verdict, len(cal.image_names), cal.estimator is not None
    ('good', 12, True)
    """
    opts = options_from(options, changes).for_images()  # bad options fail before any image work
    session = load_session(session_dir, strict_images=opts.strict_images, arm=opts.arm)
    if opts.compliance:
        raise InputMismatchError(f"{session.folder}: compliance=True fits the joints' compliance from joint angles with "
                                 "the arm's table: " + (_JOINT_FIT if session.joints is not None else
                                                        "the session has none (a joints: table in session.yaml); leave "
                                                        "compliance out"))
    if session.joints is not None:  # said, not silently dropped
        poses = "the arm's nominal table gives" if session.pose_format == "joints" else "the controller reported"
        session = replace(session, notes=list(session.notes) + [
            f"session.yaml has joint angles: this calibration took the flange poses {poses} as a black box; {_JOINT_FIT}"])
    parse_known(opts.known, session.setup)
    obs = observe(session, jobs=jobs, progress=progress, strict_images=opts.strict_images, digests=True)
    sync = None
    if session.robot_stream is not None:  # a robot stream: the images meet the robot at the clock offset
        obs, sync, robot, camera = _synchronised(obs, opts.offset_range, opts.time_offset, opts.keyframes)
    with one_blas_thread():
        cal = calibrate_observed(obs, opts, progress=progress)
    return cal if sync is None else judged(_with_sync(cal, sync, robot, camera, obs))


#: Where a session's joint angles are used.
_JOINT_FIT = ("handeye.pipelines.folders.calibrate_folder (which `handeye calibrate` runs) fits the arm's table with X from "
              "them")


#: Images with times count as a stream (the clock offset estimated) from this many, at most this far apart (s).
STREAM_MIN_IMAGES, STREAM_MAX_PERIOD = 20, 0.5


def _synchronised(obs: Observations, offset_range, time_offset, keyframes: int):
    """The observations of a session with a robot stream, paired with the robot at the clock offset.

    Images of a video (:data:`STREAM_MIN_IMAGES` or more, :data:`STREAM_MAX_PERIOD` apart at
    most): the offset is estimated (:func:`handeye.estimation.sync.synchronise`) and ``keyframes`` of them
    kept. A few scattered images (a stop-and-go capture) cannot show the offset: the robot is
    interpolated at their times (offset 0, or ``time_offset``) and a note says how fast it moved
    there. Returns the observations, the synchronisation, and both streams."""
    session = obs.session
    setup = session.setup
    robot = _sync.check_stream(session.robot_times, session.robot_stream, "robot stream")
    times = session.image_times[np.asarray(obs.used)]
    order = np.argsort(times, kind="stable")
    obs, times = obs.subset(order), times[order]
    if len(times) >= max(STREAM_MIN_IMAGES, _sync.MIN_SAMPLES) and np.median(np.diff(times)) <= STREAM_MAX_PERIOD:
        camera = _sync.check_stream(times, obs.target2cam, "images")
        sync = _sync.synchronise(robot, camera, setup, offset_range, time_offset, keyframes)
        kf, f2b, _ = _sync.keyframes_at(robot, camera, sync.offset, keyframes, setup, sync.fit)
        obs = obs.subset(kf)
    else:
        camera = _sync.PoseStream(times, obs.target2cam, "images")
        offset = 0.0 if time_offset is None else float(time_offset)
        f2b, inside = _sync.interpolate(robot, times - offset)
        if not inside.all():
            raise SessionError(f"image(s) {summarize(np.asarray(session.image_names)[np.asarray(obs.used)][~inside])} "
                               "were taken outside the robot stream's time span (or in a gap of it)")
        cost = _sync.timing_cost(robot, times - offset)
        note = (f"{len(times)} images are too few or too far apart to estimate the clock offset: the robot was "
                f"interpolated at their times{'' if time_offset is None else f' minus the given {offset * 1e3:.1f} ms'}"
                f"; it moved up to {np.nanmax(cost):.2f} deg/s + cm/s there, so each 10 ms of offset costs up to "
                f"{np.nanmax(cost) / 100:.3f} deg + mm")
        sync = _sync.Synchronisation(offset, 0.0, (offset, offset), None, None, [note])
    ri = obs.robot_input
    return replace(obs, flange2base=f2b, robot_input=None if ri is None else ri.rewritten(f2b)), sync, robot, camera


def _with_sync(cal: Calibration, sync: _sync.Synchronisation, robot: _sync.PoseStream, camera: _sync.PoseStream,
               obs: Observations) -> Calibration:
    """``cal`` (from the synchronised images ``obs``) with the clock offset, its uncertainty in X's
    and the stream fields."""
    session = obs.session
    name_to_time = dict(zip(session.image_names, session.image_times))
    used_times = np.array([name_to_time[n] for n in cal.image_names])
    if sync.offset_std > 0 and cal.cov is not None and np.isfinite(cal.cov).all():
        cov = cal.cov + _sync.offset_cov(cal.X, cal.Z, cal.setup, robot, used_times, cal.target2cam, sync.offset,
                                   sync.offset_std)
        cal = replace(cal, cov=cov, std=_std(cov))
    return replace(cal, sync=StreamSync(sync.offset, sync.offset_std, sync.info(robot, camera, used_times)),
                   notes=list(sync.notes) + list(cal.notes))


@pose_fits_shared()  # the check's refit on all the poses is the pose candidate's fit
def calibrate_observed(
    obs: Observations,
    options: CalibrationOptions | None = None,
    *,
    uncertainty: bool = True,
    progress: bool = False,
    **changes,
) -> Calibration:
    """:func:`calibrate` from what :func:`observe` made of a session's images (the same options).

    ``uncertainty=False`` skips the jackknife refits that the reported std needs, and the robot's
    accuracy with them: the std is the noise model's (for repeated calibrations on parts of the same
    data, e.g. cross-validation);
    ``progress``: show the steps after detection on stderr (from :data:`PROGRESS_FROM_IMAGES` views).
    """
    bar = Progress(3, f"calibrating {len(obs.flange2base)} views: check, estimators, uncertainty",
                   progress and len(obs.flange2base) >= PROGRESS_FROM_IMAGES)
    try:
        return _calibrate_observed(obs, options_from(options, changes), uncertainty, bar)
    finally:
        bar.close()


def _calibrate_observed(obs: Observations, opts: CalibrationOptions, uncertainty: bool, bar: Progress) -> Calibration:
    method, refine, pairs, robot_noise, accuracy = opts.method, opts.refine, opts.pairs, opts.robot_noise, opts.robot_accuracy
    robot_sigma = _robot_sigma(robot_noise)
    cal = calibrate_poses(obs.flange2base, obs.target2cam, obs.session.setup, opts.replace(refine="none", robot_noise=None),
                          robot_input=obs.robot_input, symmetries=_symmetries(obs), names=_used_names(obs),
                          progress=False, uncertainty=False, camera_from_images=True)  # the caller's bar counts this step
    scale = None if cal.target_scale == 1.0 else (cal.target_scale, cal.diagnostics.scale_std)
    if scale is not None:  # the check found the target's size wrong: its points too at the scale the robot's motions give
        obs = obs.scaled(cal.target_scale)
        if obs.intrinsics_source == "estimated":
            cal = _focal_or_size(cal)
    bar.update()
    kept, outlier_images = drop_pose_outliers(cal, obs)
    if cal.motion_kind != "general":  # part of X undetermined: the pose refinement with the known values
        if refine != "none":
            cal = calibrate_poses(obs.flange2base, obs.target2cam, obs.session.setup,
                                  opts.replace(refine="pose", strict=False, robot_noise=None),
                                  robot_input=obs.robot_input, names=_used_names(obs), progress=False,
                                  camera_from_images=True)
            cal = replace(cal, notes=cal.notes + ["the pixel refinement does not run on motions that determine only "
                                                  "part of X: X is refined on the PnP poses"])
        return with_images(cal, obs, kept, outlier_images, list(obs.notes))
    idx = np.asarray(cal.pose_indices)
    estimated = obs.intrinsics_source == "estimated"
    if refine == "auto" and len(idx) >= 5:
        views = obs.views(idx)
        candidates = pose_candidates(method, views) | pixel_candidates(views, method, estimated, robot_sigma)
        choice = choose(views, candidates, opts.folds)
        bar.update()
        cal = apply_choice(cal, choice, views, pairs, obs, robot_noise, accuracy, uncertainty)
        bar.update()
    elif refine in ("auto", "pose"):
        cal = _pose_refined(cal, method, accuracy, uncertainty, obs)
    elif refine == "reprojection":
        name = PIXEL_ROBOT if robot_sigma is not None else (PIXEL_INTRINSICS if estimated else PIXEL)
        views = obs.views(idx)
        fit = pixel_candidates(views, method, estimated, robot_sigma)[name]
        cal = _final_pixel_fit(cal, obs, name, robot_noise, pairs, fit)
        if uncertainty:
            cal = _uncertain(cal, fit, views, accuracy, obs)
    elif uncertainty:  # refine='none': the closed form's std from its jackknife and the robot's accuracy
        cal = _uncertain(cal, closed_fit(method, pairs), obs.views(idx), accuracy, obs)
    if cal.refinement == "reprojection":  # every image back in (see _final_pixel_fit)
        kept, outlier_images = list(range(len(obs.used))), []
    if scale is not None and uncertainty and cal.cov is not None:
        cal = _with_scale_error(cal, scale, method)
    return with_images(cal, obs, kept, outlier_images, list(obs.notes))


def _focal_or_size(cal: Calibration) -> Calibration:
    """``cal`` whose check found the target's size wrong, with the intrinsics estimated from the same
    images: a focal length off by the same factor scales the camera's translations alike (seen on
    rendered 640x480 ChArUco sessions: 1.1% with the size right), and the advice says so."""
    diag = cal.diagnostics
    extra = ("the intrinsics were estimated from these same images, and a focal length off by that factor scales the "
             "camera's translations alike (few views, little tilt or depth): if the target's size is right, give K from "
             "a separate intrinsic calibration (camera: in session.yaml)")
    return replace(cal, diagnostics=replace(diag, advice=list(diag.advice) + [extra]))


def _wrong_scale(diag: Diagnostics | None) -> tuple[float, float] | None:
    """The board scale (and its std) when the check names the target's size as wrong, else None."""
    if diag is None or diag.verdict != "inconsistent" or diag.scale is None or not scale_is_off(diag.scale, diag.scale_std):
        return None
    return diag.scale, diag.scale_std


def _checked_at_scale(flange2base, target2cam, call: _PoseCall):
    """:func:`_checked_poses`, and the board scale when the check found the target's size wrong (else
    None): then the poses to calibrate on are the camera's at the scale the robot's motions give
    (checked again for outliers), under the verdict and advice of the check as given, with a note."""
    checked = _checked_poses(flange2base, target2cam, call, call.opts.check, call.opts.strict, call.camera_input)
    scale = _wrong_scale(checked[4])
    if scale is None:
        return (*checked, None)
    target2cam = target2cam.copy()
    target2cam[:, :3, 3] *= scale[0]
    f2b, t2c, pairs, keep, diag, more = _checked_poses(flange2base, target2cam, call, True)
    notes = checked[5] + [n for n in more if n not in checked[5]] + [
        f"X is estimated with the target {scale[0]:.4f} times the size given (+- {scale[1]:.4f}, the scale the robot's "
        "motions give: the given size is wrong, see the advice); its std includes that scale's error"]
    return f2b, t2c, pairs, keep, _scale_diagnostics(checked[4], diag), notes, scale


def _scale_diagnostics(checked: Diagnostics, rescaled: Diagnostics) -> Diagnostics:
    """The check of the rescaled poses (outliers, rotation coverage) under the verdict and advice of
    the check as given: the size is still wrong, and the user must hear it."""
    advice = list(checked.advice) + [a for a in rescaled.advice if a not in checked.advice]
    return replace(rescaled, verdict=checked.verdict, advice=advice, scale=checked.scale, scale_std=checked.scale_std)


def _with_scale_error(cal: Calibration, scale: tuple[float, float], method: str) -> Calibration:
    """``cal`` (fitted on the target rescaled to ``scale``) with the scale's error in X's covariance: how
    X moves with the camera's translations scaled by one std of the scale (the closed form's change,
    ``method``, a derivative every estimator shares: rotations do not depend on the scale)."""
    step = scale[1] / scale[0]
    bigger = cal.target2cam.copy()
    bigger[:, :3, 3] *= 1.0 + step
    X0 = closed_form(cal.flange2base, cal.target2cam, cal.setup, method, cal.pairs)[0]
    X1 = closed_form(cal.flange2base, bigger, cal.setup, method, cal.pairs)[0]
    d = np.r_[Rotation.from_matrix(X1[:3, :3] @ X0[:3, :3].T).as_rotvec(), X1[:3, 3] - X0[:3, 3]]
    cov = cal.cov + np.outer(d, d)
    sources = dict(cal.std_sources or {}, board_scale=_std(np.outer(d, d)))
    return judged(replace(cal, cov=cov, std=_std(cov), std_sources=sources))


def _symmetries(obs: Observations) -> list[NDArray[np.float64]]:
    """The symmetries of the session's target (the images were labelled against the declared robot
    poses), in the frame ``obs`` uses (moved to the centre when the spec says ``origin: centre``)."""
    spec = obs.session.target_spec
    shift = make_transform(np.eye(3), target_origin(spec))
    return [invert(shift) @ S @ shift for S in target_from_spec(spec).symmetries()]


def _used_names(obs: Observations) -> list[str]:
    """The image file of each pose ``obs`` holds."""
    return [obs.session.image_names[k] for k in obs.used]


def _kept(diag: Diagnostics) -> NDArray[np.intp]:
    return np.setdiff1d(np.arange(diag.n_poses), diag.outliers)
