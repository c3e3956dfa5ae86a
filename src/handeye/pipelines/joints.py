"""Calibration from joint angles: X and Z together with the arm's kinematic table.

The controller's flange poses carry the arm's absolute error (0.5-3 mm uncalibrated), which no
black-box calibration can remove: it only widens X's std by it. Given the joint angles of each
view and the arm's nominal kinematics (:mod:`handeye.robot.kinematics`), :func:`calibrate_joints` starts
from the black-box calibration on the nominal chain's flange poses (its check, target scale,
outliers and verdict) and fits X, Z and the table's corrections to what the camera saw in the
estimation core (:func:`handeye.estimation.core.estimate` with the robot model
:class:`~handeye.robot.models.JointAngles`): the corners' pixels with detections
(:class:`~handeye.sensors.camera.model.CameraCorners`), the viewing rays of the target's poses
without (:class:`~handeye.sensors.camera.poses.TargetPoses`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._shared.threads import on_one_blas_thread
from ..errors import InputMismatchError
from ..estimation.core import estimate
from ..estimation.verdict import judged
from ..io.session import Session
from ..options import CalibrationOptions, options_from
from ..result import Calibration, HeldOutErrors
from ..robot.kinematics import Chain, load_arm
from ..robot.models import ANGLE_PRIOR_RAD, LENGTH_PRIOR_M, JointAngles
from ..sensors.camera.model import CameraCorners
from ..sensors.camera.poses import TargetPoses
from .calibration import calibrate_poses, drop_pose_outliers, observe, with_images

__all__ = ["calibrate_joints", "calibrate_joint_session", "joint_angles", "KINEMATIC"]

#: The estimator's name in the result (and its row of the held-out errors).
KINEMATIC = "kinematic"


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
    # the black-box start on the nominal flange poses (its check, target scale and outliers): poses alone
    # have no joints (arm, compliance)
    opts = opts.replace(refine="none", robot_noise=None, arm=None, compliance=False)
    start = calibrate_poses(chain.forward(q), target2cam, setup, opts, progress=False, uncertainty=False)
    if start.observability is not None and start.observability.unobservable:
        raise InputMismatchError(f"the motions determine only part of X ({start.observability.motion_kind}): the arm's "
                                 "table cannot be fitted with it; calibrate the flange poses with handeye.calibrate_poses")
    keep = np.asarray(start.pose_indices)
    target2cam = start.target2cam  # the views kept, at the target's scale the robot's motions give
    names = [str(int(k)) for k in keep]
    if image_points is not None:
        if object_points is None or K is None or dist is None or len(image_points) != len(q):
            raise InputMismatchError("pixel residuals need object_points and image_points (one per view), K and dist")
        sensor = CameraCorners(setup, names, [image_points[i] for i in keep],
                               [start.target_scale * np.asarray(object_points[i]) for i in keep], K, dist)
    else:
        sensor = TargetPoses(setup, names, target2cam)
    robot = JointAngles(chain, q[keep], length_prior=1e-3 * length_prior_mm, angle_prior=np.radians(angle_prior_deg),
                        compliance=compliance)
    fit = estimate(sensor, robot, opts.folds, method=f"kinematic({chain.name})")
    return _joint_calibration(start, fit, sensor, keep, ignored)


def _joint_calibration(start: Calibration, fit: Calibration, sensor: CameraCorners | TargetPoses, keep: NDArray[np.intp],
                       ignored: list[str]) -> Calibration:
    """The black-box ``start`` (its check, notes and camera poses) with the joint fit's X, Z, std, arm
    table and held-out errors; ``keep`` the views the start kept (the fit's views index it)."""
    used = np.asarray(fit.pose_indices)  # of the views kept: those the joint fit explains
    held = None if fit.cross_validation is None else HeldOutErrors(
        {KINEMATIC if k == fit.estimator else k: v for k, v in fit.cross_validation.errors.items()},
        fit.cross_validation.folds)
    pixels = isinstance(sensor, CameraCorners)
    notes = list(start.notes) + [
        f"X, Z and the arm's table fitted to the {'pixels' if pixels else 'viewing rays of the target poses'} "
        f"({fit.sensor.fit_rms_mm:.3g} mm RMS at the target)"]
    # the core's views are named by their index in the input, so its notes and skipped views name them as given
    notes += [n for n in fit.notes if not n.startswith(f"{sensor.kind} (")]
    notes += [f"{' and '.join(ignored)} not used: the fit of X, Z and the arm's table replaces the estimators"] if ignored else []
    diag, observability = start.diagnostics, start.observability
    if fit.diagnostics.verdict in ("inconsistent", "partial"):  # the joint fit's own finding ('weak' is judged below)
        diag = replace(diag, verdict=fit.diagnostics.verdict, advice=list(fit.diagnostics.advice))
        observability = fit.observability
    camera = {} if not pixels else dict(
        object_points=[sensor.points[sensor.owner == v] for v in used], image_points=[sensor.uv[sensor.owner == v] for v in used],
        camera_matrix=sensor.K, dist_coeffs=sensor.dist, intrinsics_source="given")
    cal = replace(start, X=fit.X, Z=fit.Z, cov=fit.cov, std=fit.std, method=fit.method, estimator=KINEMATIC,
                  refinement="kinematic", flange2base=fit.flange2base, target2cam=start.target2cam[used],
                  pose_indices=keep[used], motions=None, notes=notes, kinematic=fit.kinematic, cross_validation=held,
                  diagnostics=diag, observability=observability, skipped=list(fit.skipped),
                  std_sources=fit.std_sources, **camera)
    return cal if diag.verdict in ("inconsistent", "partial") else judged(cal)


@on_one_blas_thread  # narrow matrices throughout: a second BLAS thread spins more than it works
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
    kept, outliers = drop_pose_outliers(cal, obs, {int(k): why for k, why in cal.skipped})
    cal = with_images(cal, obs, kept, outliers, list(obs.notes))
    return judged(replace(cal, intrinsics_source=obs.intrinsics_source))


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
