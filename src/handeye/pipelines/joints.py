"""Calibration from joint angles: X and Z together with the arm's kinematic table.

The controller's flange poses carry the arm's absolute error (0.5-3 mm uncalibrated), which no
black-box calibration can remove: it only widens X's std by it. Given the joint angles of each
view and the arm's nominal kinematics (:mod:`handeye.robot.kinematics`), :func:`calibrate_joints` starts
from the black-box calibration on the nominal chain's flange poses (its check, outliers and
verdict) and fits X, Z and the table's corrections to what the camera saw
(:func:`handeye.solvers.kinematic.refine_kinematic`): pixels with detections, viewing rays with
poses alone.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import HandEyeError, InputMismatchError
from ..estimation.estimators import pose_fit
from ..estimation.validation import Views, cross_validate, default_folds, fold_indices, jackknife_covs, view_errors
from ..estimation.verdict import judged
from ..frames.metrics import std_deg_mm
from ..io.session import Session
from ..options import CalibrationOptions, options_from
from ..result import Calibration, HeldOutErrors, KinematicModel
from ..robot.kinematics import Chain, load_arm
from ..solvers.kinematic import ANGLE_PRIOR_RAD, COMPLIANCE_PRIOR, LENGTH_PRIOR_M, KinematicRefinement, refine_kinematic
from .calibration import calibrate_poses, drop_pose_outliers, observe, with_images

__all__ = ["calibrate_joints", "calibrate_joint_session", "joint_angles"]

#: The jackknife refits' tolerance: they start at the fit on all views, and move by far more than this.
REFIT_TOL = 1e-8


def calibrate_joints(
    joints: ArrayLike,
    target2cam: ArrayLike,
    setup: str = "eye_in_hand",
    arm: str | Chain = "ur5",
    options: CalibrationOptions | None = None,
    *,
    object_points: list[NDArray[np.float64]] | None = None,
    image_points: list[NDArray[np.float64]] | None = None,
    K: ArrayLike | None = None,
    dist: ArrayLike | None = None,
    joint_unit: str = "rad",
    length_prior_mm: float = 1e3 * LENGTH_PRIOR_M,
    angle_prior_deg: float = float(np.degrees(ANGLE_PRIOR_RAD)),
    **changes,
) -> Calibration:
    """Hand-eye calibration from joint angles, with the arm's kinematic table as unknowns too.

    Parameters
    ----------
    joints : array_like (N, n)
        The joint angles the controller reports for each view.
    target2cam : array_like (N, 4, 4)
        The camera's poses of the target (PnP's).
    setup : {'eye_in_hand', 'eye_to_hand'}
    arm : str or Chain
        A name of :func:`handeye.robot.kinematics.arm_names` or the arm's own chain.
    options : CalibrationOptions, optional
        The black-box calibration's options for the start and the check (``check``, ``strict``,
        ``method``), also as keywords.
    object_points, image_points, K, dist
        Per view the target's points and their detections, and the intrinsics: the fit in pixels
        (else across the viewing rays of the poses).
    joint_unit : {'rad', 'deg'}
    length_prior_mm, angle_prior_deg : float
        The std of the table's lengths and angles about their nominal values (the arm's
        tolerances): what holds the entries the capture cannot determine.

    Returns
    -------
    Calibration
        ``X``, ``Z``, ``cov`` and ``std`` from the joint fit (the entries' uncertainty included),
        ``flange2base`` from the corrected chain, the check of the black-box start, and
        ``kinematic`` (:class:`handeye.result.KinematicModel`): the corrected table with each
        entry's std and whether the capture determines it.

    Raises
    ------
    InputMismatchError
        Joint angles of the wrong shape, count or unit, an unknown arm or unit.

    Examples
    --------
    Joint angles of an arm whose table is off by ~1 mm, and the camera's poses of the target:

    >>> import handeye
    >>> from handeye.simulate import kinematic_scene
    >>> scene = kinematic_scene(12, "eye_in_hand", rng=3, arm="ur5")
    >>> cal = handeye.calibrate_joints(scene.joints, scene.target2cam, "eye_in_hand", arm="ur5")
    >>> cal.kinematic.nominal.name, cal.estimator
    ('UR5', 'kinematic')
    """
    chain = load_arm(arm) if isinstance(arm, str) else arm
    q = joint_angles(joints, chain, joint_unit)
    target2cam = np.asarray(target2cam, dtype=float)
    if target2cam.shape != (len(q), 4, 4):
        raise InputMismatchError(f"{len(q)} joint rows but target2cam has shape {target2cam.shape}: give one camera pose "
                                 "per row of joint angles")
    opts = options_from(options, changes)
    ignored = [f"refine={opts.refine!r}"] if opts.refine != "auto" else []
    ignored += ["robot_noise (the arm's error is fitted)"] if opts.robot_noise is not None else []
    compliance = opts.compliance
    # the black-box start on the nominal flange poses: poses alone have no joints (arm, compliance)
    opts = opts.replace(refine="none", robot_noise=None, arm=None, compliance=False)
    start = calibrate_poses(chain.forward(q), target2cam, setup, opts, progress=False, uncertainty=False)
    if start.observability is not None and start.observability.unobservable:
        raise InputMismatchError(f"the motions determine only part of X ({start.observability.motion_kind}): the arm's "
                                 "table cannot be fitted with it; calibrate the flange poses with handeye.calibrate_poses")
    keep = np.asarray(start.pose_indices)
    target2cam = start.target2cam  # the views kept, at the target's scale the robot's motions give
    pixels = {}
    if image_points is not None:
        if object_points is None or K is None or dist is None or len(image_points) != len(q):
            raise InputMismatchError("pixel residuals need object_points and image_points (one per view), K and dist")
        pixels = dict(object_points=[start.target_scale * np.asarray(object_points[i]) for i in keep],
                      image_points=[image_points[i] for i in keep],
                      K=np.asarray(K, dtype=float), dist=np.asarray(dist, dtype=float).ravel())
    priors = dict(length_prior=1e-3 * length_prior_mm, angle_prior=np.radians(angle_prior_deg),
                  compliance=compliance)
    ref = refine_kinematic(start.X, start.Z, chain, q[keep], setup, target2cam=target2cam, **priors, **pixels)
    cov_X, cov_entries, widened = _widened(ref, chain, q[keep], target2cam, setup, priors, pixels)
    held_out = _held_out(ref, chain, q[keep], target2cam, setup, priors, pixels, opts.folds)
    model = _kinematic_model(chain, ref, cov_entries, q[keep])
    notes = list(start.notes) + _fit_notes(ref, model, bool(pixels), ignored, widened, length_prior_mm, angle_prior_deg)
    cal = replace(start, X=ref.X, Z=ref.Z, cov=cov_X, std=std_deg_mm(cov_X), method=f"kinematic({chain.name})",
                  estimator="kinematic", refinement="kinematic", flange2base=model.chain.forward(q[keep]),
                  target2cam=target2cam, pose_indices=keep, motions=None, notes=notes, kinematic=model,
                  cross_validation=held_out,
                  **({} if not pixels else dict(object_points=pixels["object_points"], image_points=pixels["image_points"],
                                                camera_matrix=pixels["K"], dist_coeffs=pixels["dist"],
                                                intrinsics_source="given")),
                  std_sources={"model": std_deg_mm(ref.cov_X), "jackknife": None if cov_X is ref.cov_X else
                               std_deg_mm(cov_X), "robot_accuracy": None})
    return judged(cal)


def _kinematic_model(chain: Chain, ref: KinematicRefinement, cov_entries, q) -> KinematicModel:
    """The arm's kinematics the fit found: the corrected chain, each entry's correction and std (the
    jackknife-widened ``cov_entries``), how far it moves the flange, and the accuracy before/after."""
    corrected = chain.corrected(ref.deltas)
    if ref.compliance is not None:
        corrected = replace(corrected, compliance=ref.compliance)
    index = _positions(chain, ref.names)
    p = _vector(chain, ref)
    shift = 1e3 * np.linalg.norm(corrected.forward(q)[:, :3, 3] - chain.forward(q)[:, :3, 3], axis=1)
    return KinematicModel(chain, corrected, ref.names, p[index], np.sqrt(np.diag(cov_entries)), ref.prior_std,
                          ref.determined, (float(np.median(shift)), float(shift.max())),
                          _accuracy(chain, p, index, cov_entries, q), q)


def _fit_notes(ref: KinematicRefinement, model: KinematicModel, pixels: bool, ignored: list[str], widened: float,
               length_prior_mm: float, angle_prior_deg: float) -> list[str]:
    """What the joint fit did, for people: its residual, the options it does not use, the jackknife's
    widening, and the entries the capture does not determine with what would."""
    chain = model.nominal
    notes = [f"X, Z and {len(ref.names)} entries of {chain.name}'s kinematic table fitted to the "
             + ("pixels" if pixels else "camera's viewing rays") + f" ({ref.rms:.3g} {'px' if pixels else 'm'} RMS); "
             f"{int(ref.determined.sum())} determined by the capture"]
    if ignored:
        notes.append(f"{' and '.join(ignored)} not used: the fit of X, Z and the arm's table replaces the estimators")
    if widened > 1.5:
        notes.append(f"the std of X is widened up to {widened:.1f}x the fit's model: X moves more without some views than "
                     "pixel noise explains (errors of a whole view: joint encoder noise or backlash, timing, a view "
                     "that does not fit)")
    if model.undetermined:
        parallel = [n for n in model.undetermined if n in along_parallel_axes(chain)]
        sagging = [n for n in model.undetermined if n.endswith(".compliance")]
        moved = [n for n in model.undetermined if n not in parallel and n not in sagging]
        prior = f"{length_prior_mm:g} mm, {angle_prior_deg:g} deg" + (
            f", {np.degrees(COMPLIANCE_PRIOR):g} deg/m" if any(n.endswith(".compliance") for n in model.names) else "")
        notes.append(f"the capture does not determine {', '.join(model.undetermined)}: held near nominal by their prior "
                     f"({prior}), whose uncertainty X's std includes"
                     + (f"; {', '.join(parallel)} lie along parallel joint axes, where only their sum shows whatever the "
                        "capture" if parallel else "")
                     + (f"; move joint{'s' if len(_joints_of(moved)) > 1 else ''} {_joints_of(moved)} further between "
                        "views (over a wider range, and together with the others) to determine them" if moved else "")
                     + (f"; for the compliance of joint{'s' if len(_joints_of(sagging)) > 1 else ''} {_joints_of(sagging)}, "
                        "vary how far the flange reaches out from those joints' axes between views (the load's "
                        "moment arm)" if sagging else ""))
    return notes


def _joints_of(entries: list[str]) -> str:
    """'3, 5 and 7' for entries of joints 3, 5 and 7 (``joint<k>.<parameter>``)."""
    ks = sorted({int(e.split(".")[0].removeprefix("joint")) for e in entries})
    words = [str(k) for k in ks]
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]


def calibrate_joint_session(session: Session, options: CalibrationOptions | None = None, *, jobs: int | None = None,
                            progress: bool = True, **changes) -> Calibration:
    """:func:`calibrate_joints` on a capture session whose ``session.yaml`` has a ``joints:``
    table (:func:`handeye.io.session.load_session`): the images detected and PnP solved as
    :func:`handeye.calibrate` does, then X, Z and the arm's table fitted to the pixels."""
    opts = options_from(options, changes)
    if session.joints is None or session.arm is None:
        raise InputMismatchError(f"{session.folder}: no joints: table in session.yaml")
    obs = observe(session, jobs=jobs, progress=progress, strict_images=opts.strict_images, digests=True)
    cal = calibrate_joints(session.joints[obs.used], obs.target2cam, session.setup, session.arm, opts,
                           object_points=obs.object_points, image_points=obs.image_points, K=obs.K, dist=obs.dist)
    kept, outliers = drop_pose_outliers(cal, obs)
    cal = with_images(cal, obs, kept, outliers, list(obs.notes))
    return judged(replace(cal, intrinsics_source=obs.intrinsics_source))


def _views_of(pixels: dict, idx) -> dict:
    """The pixel data of the views ``idx`` (per-view points and detections; the intrinsics whole)."""
    return {k: ([v[i] for i in idx] if k in ("object_points", "image_points") else v) for k, v in pixels.items()}


def _widened(ref: KinematicRefinement, chain: Chain, q, target2cam, setup, priors: dict,
             pixels: dict) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """X's covariance and the table entries': the fit's model, each axis (each entry) widened to the
    jackknife's spread (the fit repeated without each of up to 10 groups of views, started at the
    fit on all, the noise held) when that is larger, as every handeye estimator does; and X's largest
    widening factor. The model takes the pixel errors of a view's points as independent: an error
    of the whole view (joint encoder noise of 0.002 deg on rendered UR5 sessions) left X within 3 of
    its std on 76% of the axes."""
    index = _positions(chain, ref.names)
    refitted = []

    def fit(flange2base, t2c, setup, idx):
        part = _views_of(pixels, idx)
        r = refine_kinematic(ref.X, ref.Z, chain, q[idx], setup, target2cam=t2c, sigma=ref.sigma,
                             deltas0=ref.deltas, compliance0=ref.compliance, tol=REFIT_TOL, **priors, **part)
        refitted.append(_vector(chain, r)[index])
        return r.X, r.Z
    jack, _ = jackknife_covs(fit, Views(chain.forward(q), target2cam, setup), ref.X, None)
    cov_entries = ref.cov[12:, 12:]
    if jack is None:
        return ref.cov_X, cov_entries, 1.0
    d = np.array(refitted) - np.mean(refitted, axis=0)
    jack_entries = (len(d) - 1) / len(d) * d.T @ d
    cov_X, factor = _wider(ref.cov_X, jack)
    return cov_X, _wider(cov_entries, jack_entries)[0], factor


def _wider(cov: NDArray[np.float64], jack: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """``cov`` with each axis widened to the jackknife's ``jack`` where that is larger; the largest factor."""
    ratio = np.sqrt(np.maximum(np.diag(jack), 1e-300) / np.maximum(np.diag(cov), 1e-300))
    D = np.diag(np.maximum(ratio, 1.0))
    return D @ cov @ D, float(ratio.max())


#: Joint configurations the arm's accuracy is predicted over (drawn within the capture's joint ranges).
ACCURACY_SAMPLES = 500


def _accuracy(chain: Chain, p, index: list[int], cov_entries, q) -> dict[str, float]:
    """The arm's absolute accuracy at the flange before and after the fit, over joint angles drawn
    uniformly within the capture's range of each joint (where the fit has seen the arm) and, when
    the chain knows its joints' limits, over the whole workspace (``workspace_`` keys): before, how
    far the nominal table puts the flange from the corrected one; after, the corrected table's
    position std from its entries' covariance (first order, a finite-difference Jacobian). Outside
    the capture's ranges 'before' is the corrected table extrapolated, and 'after' grows with the
    entries the capture left to their prior."""
    rng = np.random.default_rng(0)
    within = rng.uniform(q.min(axis=0), q.max(axis=0), (ACCURACY_SAMPLES, q.shape[1]))
    out = _accuracy_over(chain, p, index, cov_entries, within)
    if chain.limits is not None:
        whole = _accuracy_over(chain, p, index, cov_entries,
                               rng.uniform(chain.limits[:, 0], chain.limits[:, 1], (ACCURACY_SAMPLES, q.shape[1])))
        out |= {f"workspace_{k}": v for k, v in whole.items() if k != "samples"}
    return out


def _accuracy_over(chain: Chain, p, index: list[int], cov_entries, samples) -> dict[str, float]:
    """:func:`_accuracy` at the joint angles ``samples`` (S, n)."""
    corrected = chain.forward_with(samples, p)[:, :3, 3]
    before = 1e3 * np.linalg.norm(chain.forward(samples)[:, :3, 3] - corrected, axis=1)
    J = np.empty((len(samples), 3, len(index)))
    step = 1e-7
    for j, k in enumerate(index):
        d = np.array(p, dtype=float)
        d[k] += step
        J[:, :, j] = (chain.forward_with(samples, d)[:, :3, 3] - corrected) / step
    after = 1e3 * np.sqrt(np.einsum("nij,jk,nik->n", J, cov_entries, J))
    return {"before_median": float(np.median(before)), "before_max": float(before.max()),
            "after_median": float(np.median(after)), "after_max": float(after.max()), "samples": len(samples)}


def _positions(chain: Chain, names: list[str]) -> list[int]:
    """Where the fitted entries ``names`` sit in ``chain.forward_with``'s parameter vector."""
    every = chain.parameter_names(any(n.endswith(".compliance") for n in names))
    return [every.index(n) for n in names]


def _vector(chain: Chain, r: KinematicRefinement) -> NDArray[np.float64]:
    """The fit's parameter vector of ``chain.forward_with``: the table's corrections, then (when
    fitted) the compliance's."""
    if r.compliance is None:
        return r.deltas.ravel().copy()
    return np.r_[r.deltas.ravel(), r.compliance - (0.0 if chain.compliance is None else chain.compliance)]


def _held_out(ref: KinematicRefinement, chain: Chain, q, target2cam, setup, priors: dict, pixels: dict,
              folds: int | None) -> HeldOutErrors | None:
    """Each view predicted from its joint angles alone by the fit without its fold (X, Z and the
    table refitted from the fit on all, the noise held), beside the black-box pose refinement on
    the nominal chain's flange poses on the same folds: what the table's fit buys on views it did
    not see. None with fewer than 5 views."""
    n = len(q)
    if n < 5:
        return None
    views = Views(chain.forward(q), target2cam, setup, pixels.get("object_points"), pixels.get("image_points"),
                  pixels.get("K"), pixels.get("dist"))
    held = fold_indices(n, default_folds(n) if folds is None else min(folds, n))
    px = np.full(n, np.inf) if views.has_pixels else None
    mm = np.full(n, np.inf)
    for test in held:
        train = np.setdiff1d(np.arange(n), test)
        part = _views_of(pixels, train)
        try:
            r = refine_kinematic(ref.X, ref.Z, chain, q[train], setup, target2cam=target2cam[train], sigma=ref.sigma,
                                 deltas0=ref.deltas, compliance0=ref.compliance, tol=REFIT_TOL, **priors, **part)
        except (HandEyeError, np.linalg.LinAlgError, ValueError):
            continue
        f2b = views.flange2base.copy()
        f2b[test] = chain.forward_with(q[test], _vector(chain, r))
        e_px, mm[test] = view_errors(r.X, r.Z, replace(views, flange2base=f2b), test)
        if px is not None:
            px[test] = e_px

    nominal = cross_validate(pose_fit("daniilidis", None), views, held)  # the black box, refitted per fold

    def row(p, m) -> dict[str, float | None]:
        return {"px": None if p is None else float(np.sqrt(np.mean(p**2))), "mm": float(np.sqrt(np.mean(m**2)))}
    return HeldOutErrors({"kinematic": row(px, mm), "pose (nominal flange poses)": row(nominal.px, nominal.mm)},
                         len(held))


def along_parallel_axes(chain: Chain) -> set[str]:
    """The offsets along joint axes parallel to the next or the previous one: a shift along two
    parallel axes moves the flange the same way, so only the offsets' sum can be determined."""
    alpha = chain.table[:, 1]
    n = chain.n_joints
    # standard DH: joint k's alpha is between axes k and k+1; modified: row k's alpha is between k-1 and k
    between = [abs(np.sin(alpha[k])) < 1e-9 for k in range(n - 1)] if chain.convention == "dh" else \
        [abs(np.sin(alpha[k + 1])) < 1e-9 for k in range(n - 1)]
    out = set()
    for k, parallel in enumerate(between):
        if parallel:
            out |= {f"joint{k + 1}.d", f"joint{k + 2}.d"}
    return out


def joint_angles(joints: ArrayLike, chain: Chain, unit: str) -> NDArray[np.float64]:
    """Joint angles (N, n) in radians, checked against the chain and the unit."""
    if unit not in ("rad", "deg"):
        raise InputMismatchError(f"joint_unit {unit!r}; use 'rad' or 'deg'")
    q = np.asarray(joints, dtype=float)
    if q.ndim != 2 or q.shape[1] != chain.n_joints:
        raise InputMismatchError(f"{chain.name} has {chain.n_joints} joints; the joint angles have shape {q.shape} "
                                 f"(one row of {chain.n_joints} per view)")
    if not np.isfinite(q).all():
        row = int(np.argmin(np.isfinite(q).all(axis=1)))
        raise InputMismatchError(f"joint angles: row {row} holds NaN or infinite values")
    if unit == "rad" and np.abs(q).max() > 2.5 * np.pi:
        raise InputMismatchError(f"joint angles up to {np.abs(q).max():.1f} rad: they look like degrees; "
                                 "give joint_unit='deg'")
    return np.radians(q) if unit == "deg" else q
