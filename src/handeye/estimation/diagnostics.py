"""Trust the data: observability, convention mix-ups, outlier poses (``handeye.diagnose``).

The failures users report again and again ("more samples made it worse", "every run differs by
2 cm", "the eye-to-hand result is wrong") nearly always come from one of: motions that cannot
determine X (parallel rotation axes, tiny rotations), robot poses read with the wrong convention
(Euler sequence, quaternion order, inverted poses, mm read as m, degrees as radians), or a few bad
samples. :func:`diagnose` tells which.

* Observability (thesis §4.1.2: large rotations about varied axes): the scatter of the camera
  motions' rotation axes, rotation-angle statistics, the singular values of the Daniilidis system
  (two near zero expected, §2.2.3) and the condition of the translation system.
* Outliers: RANSAC over poses (minimal sets of 3 poses, least-median scoring), then the pose
  refinement on the consensus set, whose noise model gives every pose a Mahalanobis distance; a
  pose is an outlier when that distance exceeds the 99.99% point of its F distribution.
* Consistency: how well one X makes all poses agree on where the target is (unit-free score,
  below). When the data are inconsistent, the usual mistakes are tried and the one that makes the
  data consistent is named (``convention_hint``).
* Leave-one-out: how much X moves when each pose is left out.
"""

from __future__ import annotations

import time
from collections.abc import Sized
from contextvars import ContextVar
from itertools import combinations
from math import comb
from typing import Any, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import fdtri

from .. import solvers
from .._shared.text import summarize
from ..errors import DegenerateMotionError, HandEyeError, InputMismatchError
from ..frames.metrics import rotation_error, translation_error
from ..frames.motions import MotionSet, Pairs, validate_poses
from ..frames.poses import RobotPoseInput, parse_poses
from ..frames.setups import SETUPS, check_setup, constant_transforms, robot_world_inputs, setup_info
from ..geometry.se3 import invert, mean_transform
from ..result import Diagnostics
from ..sensors.camera import resolve_symmetries
from ..solvers import closed_form
from ..solvers.daniilidis import motion_groups, singular_values, solve_leave_one_out
from ..solvers.low_dof import ONE_AXIS, gauge_priors, partial_kind, solve_low_dof
from ..solvers.observability import check_observability, observable_leave_one_out, rotation_spread
from ..solvers.refine import pose_mahalanobis
from .refinement import refine_pose
from .validation import fold_indices
from .verdict import (
    CONSISTENT,
    MANY_OUTLIERS,
    MIN_POSES,
    SCALE_TOLERANCE,
    SMALL_ROTATION_DEG,
    agreement_verdict,
    count_verdict,
    many_outliers,
    motion_verdict,
    reading_verdict,
    scale_is_off,
    scale_verdict,
    weak_motions,
    weakened,
)

__all__ = ["Diagnostics", "RobotPoseInput", "diagnose", "find_outliers", "consistency_score", "closed_form",
           "compare_solvers", "board_scale", "scale_is_off", "pose_alternatives"]

#: Per-pose median rotation residual (deg) and translation residual relative to the camera's motion
#: scale that count as one unit of the consistency score.
ROT_UNIT_DEG = 1.0
TRANS_UNIT = 0.02
#: Outlier test level: a pose that fits the noise model is called an outlier with this probability.
OUTLIER_P = 1e-4
#: ... and its residual (rotation or translation) must exceed this many times the median one.
GROSS = 4.0
# The thresholds that decide (CONSISTENT, SMALL_ROTATION_DEG, AXIS_SHARE_WEAK, FEW_POSES, FAR_TARGET_M,
# SCALE_TOLERANCE, SCALE_SIGMAS) are handeye.estimation.verdict's: this module measures, that one decides.


def _solve(flange2base, target2cam, setup, kind: str | None = None) -> NDArray[np.float64]:
    """Daniilidis on the pose pairs of ``pairs='auto'`` (raises DegenerateMotionError when X is
    undetermined); ``kind`` ('one_axis', 'translation_only'): the low-DOF solver's part of X.

    Within :func:`diagnose`, whose checks ask for X on the same poses several times (the
    consistency score, the outlier refit, the board scale, the leave-one-out), each answer is
    computed once (keyed by the poses' bytes)."""
    memo = _SOLVE_MEMO.get()
    key = None
    if memo is not None:
        key = (np.asarray(flange2base, float).tobytes(), np.asarray(target2cam, float).tobytes(), setup, kind)
        if key in memo:
            return memo[key].copy()
    motions = MotionSet.from_poses(flange2base, target2cam, setup, "auto")
    X = solve_low_dof(motions, kind).X if kind is not None else solvers.solve_motions(motions, "daniilidis")
    if memo is not None and key is not None:
        memo[key] = X.copy()
    return X


#: The answers of :func:`_solve` during one :func:`diagnose` call (None outside).
_SOLVE_MEMO: ContextVar[dict | None] = ContextVar("_SOLVE_MEMO", default=None)


def _motion_scale(target2cam: NDArray[np.float64]) -> float:
    """RMS distance between camera positions relative to the target: the scale of the data."""
    cam_in_target = invert(target2cam)[:, :3, 3]
    return float(np.sqrt(np.mean(np.sum((cam_in_target - cam_in_target.mean(axis=0)) ** 2, axis=1)))) + 1e-12


def consistency_score(flange2base, target2cam, setup: str, kind: str | None = None) -> float:
    """Unit-free consistency of poses (see :class:`Diagnostics`); ``inf`` when unsolvable. ``kind``
    ('one_axis', 'translation_only'): X from the low-DOF solver; the part of X it cannot determine
    moves every pose's target pose alike, so the score does not depend on it."""
    try:
        X = _solve(flange2base, target2cam, setup, kind)
    except (HandEyeError, np.linalg.LinAlgError, ValueError):
        return float("inf")
    Zi = constant_transforms(X, flange2base, target2cam, setup)
    try:
        Z = mean_transform(Zi)
    except ValueError:
        return float("inf")
    rot = np.degrees(np.median(rotation_error(Zi, Z)))
    tra = float(np.median(translation_error(Zi, Z))) / _motion_scale(target2cam)
    return float(max(rot / ROT_UNIT_DEG, tra / TRANS_UNIT))


def pose_alternatives(pose_input: RobotPoseInput) -> list[tuple[str, dict]]:
    """The usual mistakes in declaring poses as written: the other length unit, angle unit,
    quaternion order and Euler sequences: (hint, the changed declaration)."""
    fmt, lu, au = pose_input.format, pose_input.length_unit, pose_input.angle_unit
    alternatives = [(f"length_unit:{u}", dict(length_unit=u)) for u in ("m", "mm") if u != lu]
    if fmt == "rotvec" or fmt.startswith("euler:"):
        alternatives += [(f"angle_unit:{u}", dict(angle_unit=u)) for u in ("rad", "deg") if u != au]
    if fmt in ("quat_wxyz", "quat_xyzw"):
        other = "quat_xyzw" if fmt == "quat_wxyz" else "quat_wxyz"
        alternatives.append((other, dict(format=other)))
    if fmt.startswith("euler:"):
        for a in "xyz":
            for b in "xyz":
                for c in "xyz":
                    if a != b and b != c:
                        for seq in (a + b + c, (a + b + c).upper()):
                            if f"euler:{seq}" != fmt:
                                alternatives.append((f"euler:{seq}", dict(format=f"euler:{seq}")))
    return alternatives


def _reread(pose_input: RobotPoseInput, change: dict) -> NDArray[np.float64] | None:
    """The poses as written, read with the declaration changed; None when impossible (e.g.
    quaternions of the wrong norm)."""
    kw = dict(format=pose_input.format, length_unit=pose_input.length_unit, angle_unit=pose_input.angle_unit) | change
    try:
        T = parse_poses(pose_input.values, kw["format"], kw["length_unit"], kw["angle_unit"])
    except HandEyeError:
        return None
    return invert(T) if pose_input.inverted else T


def _readings(flange2base, target2cam, robot_input: RobotPoseInput | None, camera_input: RobotPoseInput | None = None,
              setup: str = "eye_in_hand", symmetries: list | None = None, camera_from_images: bool = False
              ) -> dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """Other readings of the inputs: hint -> (flange2base, target2cam). Camera hints start with
    ``camera:``; camera poses handeye computed from images are never read inverted (a user cannot
    invert them). With the ``symmetries`` of a symmetric target, each robot reading relabels the
    images anew (:func:`handeye.sensors.camera.resolve_symmetries`): the labels chosen against the robot
    poses as declared are wrong under another reading."""
    def relabelled(f):
        return target2cam if not symmetries or len(symmetries) < 2 else resolve_symmetries(target2cam, f, setup,
                                                                                            symmetries)[0]

    inverted = invert(flange2base)
    out = {"invert_robot_poses": (inverted, relabelled(inverted))}
    if not camera_from_images:
        out["invert_camera_poses"] = (flange2base, invert(target2cam))
    if robot_input is None:
        for hint, s in (("length_unit:mm", 1e-3), ("length_unit:m", 1e3)):
            f = flange2base.copy()
            f[:, :3, 3] *= s
            out[hint] = (f, relabelled(f))
    else:
        for hint, change in pose_alternatives(robot_input):
            f = _reread(robot_input, change)
            if f is not None:
                out[hint] = (f, relabelled(f))
    if camera_input is not None:
        for hint, change in pose_alternatives(camera_input):
            t = _reread(camera_input, change)
            if t is not None:
                out[f"camera:{hint}"] = (flange2base, t)
    return out


def _refit_test(flange2base, target2cam, setup, inliers, kind: str | None = None):
    """Pose refinement on ``inliers``; per pose its studentized distance test and residuals."""
    if kind is None:
        X, priors = _solve(flange2base[inliers], target2cam[inliers], setup), None
    else:  # low-DOF data: X's undetermined part held (the residuals do not depend on it)
        sol = solve_low_dof(MotionSet.from_poses(flange2base[inliers], target2cam[inliers], setup, "auto"), kind)
        X, priors = sol.X, gauge_priors(sol.null_space, sol.X)
    Z = mean_transform(constant_transforms(X, flange2base[inliers], target2cam[inliers], setup))
    ref = refine_pose(X, Z, flange2base[inliers], target2cam[inliers], setup, priors=priors)
    d2 = pose_mahalanobis(ref, flange2base, target2cam, setup, fitted=inliers)
    Zi = constant_transforms(ref.X, flange2base, target2cam, setup)
    resid = np.c_[np.degrees(rotation_error(Zi, ref.Z)), 1e3 * translation_error(Zi, ref.Z)]
    # the noise was estimated from few poses: F rather than chi-square
    limit = 6.0 * fdtri(6, 6 * int(inliers.sum()) - 12, 1.0 - OUTLIER_P)  # the F quantile (scipy.stats is slow to import)
    # Real camera noise is not the model's (PnP errors are larger in depth than across, and couple
    # rotation with translation), so the test alone would flag clean poses: an outlier must also
    # be gross, beyond GROSS times the median residual of the consensus poses.
    med = np.median(resid[inliers], axis=0) + 1e-12
    gross = (resid > GROSS * med).any(axis=1)
    return (d2 <= limit) | ~gross, resid


def find_outliers(
    flange2base: NDArray[np.float64],
    target2cam: NDArray[np.float64],
    setup: str,
    rng: np.random.Generator | int | None = 0,
    hypotheses: int = 40,
    kind: str | None = None,
) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
    """Outlier poses: a noise-model test after a fit on all poses, and, when that fit finds any,
    RANSAC over minimal sets of 3 poses (least-median scoring) followed by the same test on the
    consensus set, repeated until the set is stable. ``kind``: motions about one axis or none
    (:mod:`handeye.solvers.low_dof`): the same with the low-DOF solver (the poses' residuals do
    not depend on the undetermined part of X).

    Returns
    -------
    inliers : ndarray (N,) of bool
    residuals : ndarray (N, 2)
        Per pose: rotation (deg) and translation (mm) of its target pose from the consensus one.
    """
    n = len(flange2base)
    rng = np.random.default_rng(rng)
    if n < 5:  # a minimal set and too few others to vote
        return np.ones(n, bool), np.zeros((n, 2))
    everything = np.ones(n, bool)
    # Inconsistent poses go to RANSAC whatever the refit says: test the cheap score first (a refit
    # on poses with gross outliers is the slowest step: its noise weights barely settle).
    # (low-DOF data have no consistency score: straight to RANSAC, whose minimal sets are cheap)
    if kind is None and consistency_score(flange2base, target2cam, setup) <= CONSISTENT:
        try:
            ok, resid = _refit_test(flange2base, target2cam, setup, everything, kind)
            if ok.all():
                return everything, resid
        except (HandEyeError, np.linalg.LinAlgError):
            pass
    # minimal sets: all triplets when few, else random distinct ones (40 draws miss an all-inlier
    # set with probability 5e-8 at 30% outliers)
    if comb(n, 3) <= hypotheses:
        sets = np.array(list(combinations(range(n), 3)))
    else:
        sets = np.array([rng.choice(n, 3, replace=False) for _ in range(hypotheses)])
    rots, tras = [], []
    for s in sets:
        try:
            X = _solve(flange2base[s], target2cam[s], setup, kind)
        except (HandEyeError, np.linalg.LinAlgError):
            continue
        Zi = constant_transforms(X, flange2base, target2cam, setup)
        Z = mean_transform(Zi[s])
        rots.append(rotation_error(Zi, Z))
        tras.append(translation_error(Zi, Z))
    if not rots:
        return everything, np.zeros((n, 2))
    rot, tra = np.array(rots), np.array(tras)
    # least median of the (scale-free) larger residual
    s_r, s_t = np.median(rot) + 1e-15, np.median(tra) + 1e-15
    best = int(np.argmin(np.median(np.maximum(rot / s_r, tra / s_t), axis=1)))
    r, t = rot[best], tra[best]
    inliers = cast(NDArray[np.bool_], (r <= 3.0 * np.median(r) + 1e-12) & (t <= 3.0 * np.median(t) + 1e-12))
    resid = np.c_[np.degrees(r), 1e3 * t]
    for _ in range(5):
        if inliers.sum() < 4:
            break
        try:
            new, resid = _refit_test(flange2base, target2cam, setup, inliers, kind)
        except (HandEyeError, np.linalg.LinAlgError):
            break
        if np.array_equal(new, inliers):
            break
        inliers = new
    return inliers, resid


def _observability(motions: MotionSet) -> dict:
    v = motions.dq_b[:, 1:4]  # sin(theta/2) * axis of the camera motions
    S = v.T @ v
    total = float(np.trace(S)) + 1e-300
    lam, vec = np.linalg.eigh(S / total)
    angles = np.degrees(2 * np.arctan2(np.linalg.norm(v, axis=1), np.abs(motions.dq_b[:, 0])))
    R_A = motions.R_A
    M = np.einsum("kji,kjl->il", np.eye(3) - R_A, np.eye(3) - R_A)
    ev = np.linalg.eigvalsh(M)
    return {
        "axis_shares": lam[::-1].copy(),
        "weakest_axis": vec[:, 0].copy(),
        "rotation_angles_deg": angles,
        "singular_values": singular_values(motions),
        "translation_condition": float(ev[-1] / max(ev[0], 1e-300)),
    }


def _axis_name(axis: NDArray[np.float64]) -> str:
    k = int(np.argmax(np.abs(axis)))
    if abs(axis[k]) > 0.9:
        return f"the camera's {'xyz'[k]} axis"
    return f"the camera-frame direction {np.array2string(axis, precision=2, suppress_small=True)}"


def diagnose(
    flange2base: ArrayLike,
    target2cam: ArrayLike,
    setup: str = "eye_in_hand",
    *,
    robot_input: RobotPoseInput | None = None,
    camera_input: RobotPoseInput | None = None,
    outliers: bool = True,
    leave_one_out: bool = True,
    rng: np.random.Generator | int | None = 0,
    symmetries: list | None = None,
    names: list[str] | None = None,
    camera_from_images: bool = False,
) -> Diagnostics:
    """Check whether poses can give a good hand-eye calibration, and say why not.

    Parameters
    ----------
    flange2base, target2cam : array_like (N, 4, 4)
    setup : {'eye_in_hand', 'eye_to_hand'}
    robot_input, camera_input : RobotPoseInput, optional
        The robot (camera) poses as written: lets the check try other Euler sequences, quaternion
        orders and units. Without them, inverted poses (and mm/m for the robot) are tried.
    outliers, leave_one_out : bool
        Run the outlier search and the leave-one-out check.
    rng
        Seed of the RANSAC sampling (results are reproducible).
    symmetries : list of (4, 4), optional
        A symmetric target's symmetries (``target.symmetries()``; images labelled against the robot
        poses as declared): each other reading of the robot poses relabels the images anew.
    names : list of str, optional
        Each pose's name (its image file, or its row id in a pose table): the advice and the
        summary name poses by it (``Diagnostics.names``).
    camera_from_images : bool
        ``target2cam`` is handeye's own PnP of images: reading it inverted is no advice a user can
        follow, so it is not tried.

    Returns
    -------
    Diagnostics

    Examples
    --------
    Robot poses given inverted (base2flange where flange2base was meant) are found, with the fix:

    >>> import handeye
    >>> from handeye.geometry.se3 import invert
    >>> from handeye.simulate import random_scene
    >>> scene = random_scene(10, "eye_in_hand", rng=2)
    >>> handeye.diagnose(scene.flange2base, scene.target2cam).verdict
    'good'
    >>> d = handeye.diagnose(invert(scene.flange2base), scene.target2cam)
    >>> d.verdict, d.convention_hint
    ('inconsistent', 'invert_robot_poses')
    """
    token = _SOLVE_MEMO.set({})
    try:
        diag = _diagnose(flange2base, target2cam, setup, robot_input, camera_input, outliers, leave_one_out, rng,
                         symmetries, _names(names, len(cast(Sized, flange2base))), camera_from_images)
    finally:
        _SOLVE_MEMO.reset(token)
    return diag


def _names(names: list[str] | None, n: int) -> list[str] | None:
    """The poses' names checked against their count."""
    if names is None:
        return None
    names = [str(v) for v in names]
    if len(names) != n:
        raise InputMismatchError(f"{len(names)} pose names for {n} poses: give one name per pose")
    return names


def _diagnose(flange2base, target2cam, setup, robot_input, camera_input, outliers, leave_one_out, rng,
              symmetries, names, camera_from_images=False) -> Diagnostics:
    setup = check_setup(setup)
    flange2base, target2cam = validate_poses(flange2base, target2cam)
    n = len(flange2base)
    start = count_verdict(n)
    if start != "good":  # one motion at most: nothing to observe
        return Diagnostics(verdict=start, n_poses=n, consistency_limit=CONSISTENT, names=names, advice=[
            f"only {n} pose(s): hand-eye calibration needs at least {MIN_POSES} (two motions with different rotation axes); "
            "take 10-20 from varied viewpoints, turning the flange by 30 deg or more about different axes"])
    motions = MotionSet.from_poses(flange2base, target2cam, setup, "auto")
    diag = Diagnostics(verdict=start, n_poses=n, consistency_limit=CONSISTENT, names=names, **_observability(motions))
    try:
        check_observability(motions)
    except DegenerateMotionError as exc:
        return _undetermined(diag, motions, exc, flange2base, target2cam, setup, outliers, rng)

    given = consistency_score(flange2base, target2cam, setup)
    diag.consistency = given
    unstable = None
    if given > CONSISTENT:  # not consistent as given
        # systematic trouble: try the usual mistakes
        found = _convention(flange2base, target2cam, setup, given, robot_input, camera_input, symmetries,
                            camera_from_images)
        if found is not None:
            diag.convention_hint, advice = found
            diag.verdict = reading_verdict(diag.convention_hint)
            diag.advice.append(advice)
            return diag
        scale = board_scale(flange2base, target2cam, setup)  # a wrong target size is the other usual mistake
        if scale is not None and scale_is_off(*scale) and _scale_explains(flange2base, target2cam, setup, scale[0]):
            held, _, folds = _scale_subsets(flange2base, target2cam, setup, scale[0], explains=True)
            found_scale = scale_verdict(True, held, folds)  # off: scale_is_off above
            if found_scale is not None:
                diag.scale, diag.scale_std = scale
                diag.verdict = found_scale
                diag.advice.append(_scale_advice(*scale))
                return diag
            unstable = _unstable_scale_advice(*scale, held, folds)  # said, not acted on (the size as given)
            diag.advice.append(unstable)
    inliers = np.ones(n, bool)
    if outliers:
        inliers, resid = find_outliers(flange2base, target2cam, setup, rng=rng)
        diag.pose_residuals = resid
        diag.consistency = consistency_score(flange2base[inliers], target2cam[inliers], setup)
    if _disagree(diag, given, inliers):
        return diag
    if outliers and not inliers.all():
        _name_outliers(diag, inliers, resid)
        if many_outliers(len(diag.outliers), n):
            diag.verdict = weakened(diag.verdict, True)
            diag.advice.append(f"{len(diag.outliers)} of {n} poses are outliers (more than {100 * MANY_OUTLIERS:g}%): the rest may share "
                               "the same fault; check how the robot poses are paired with the images before relying "
                               "on X")
    if leave_one_out:
        diag.leave_one_out = _leave_one_out(flange2base, target2cam, setup, inliers)
    scale = board_scale(flange2base[inliers], target2cam[inliers], setup)
    if scale is not None and unstable is None:
        diag.scale, diag.scale_std = scale
        beyond, significant, folds = _scale_subsets(flange2base[inliers], target2cam[inliers], setup, scale[0], False)
        found_scale = scale_verdict(scale_is_off(*scale), beyond, folds)
        if found_scale is not None:
            diag.verdict = found_scale
            diag.advice.append(_scale_advice(*scale))
            return diag
        if scale_is_off(*scale) or significant:  # the call turns on which poses are in: said, not acted on
            unstable = _unstable_scale_advice(*scale, beyond if scale_is_off(*scale) else significant, folds)
            diag.advice.append(unstable)
    diag.verdict = weakened(diag.verdict, unstable is not None)  # a possible wrong size not ruled out: not good
    weak = _weak_advice(diag, target2cam[inliers], int(inliers.sum()))
    diag.verdict = weakened(diag.verdict, bool(weak))
    diag.advice.extend(weak)
    return diag


def board_scale(flange2base: NDArray[np.float64], target2cam: NDArray[np.float64],
                setup: str) -> tuple[float, float] | None:
    """The factor ``s`` that maps the camera's translations onto the robot's, with its std.

    Rotations do not depend on the target's size, translations do: a wrong square size (or units)
    scales every camera translation. With X's and Z's rotations from Daniilidis (scale-free), the
    robot-world form ``A_i X = Z inv(target2cam_i)`` is linear in ``t_X``, ``t_Z`` and ``s``
    (``R_Ai t_X - t_Z + s R_Ai R_X t_Ci = -t_Ai``, ``t_Ci`` the target's position in the camera):
    least squares, one residual block per pose (poses 4x beyond the median residual left out once);
    the std is the larger of the residual-variance one and the jackknife's. None when the poses
    cannot determine it (fewer than 4, or a singular system).
    """
    n = len(flange2base)
    if n < 4:
        return None
    try:
        X = _solve(flange2base, target2cam, setup)
    except (HandEyeError, np.linalg.LinAlgError):
        return None
    A = robot_world_inputs(flange2base, target2cam, setup)[0]
    R_A, t_A = A[:, :3, :3], A[:, :3, 3]
    M = np.zeros((n, 3, 7))
    M[:, :, :3] = R_A
    M[:, :, 3:6] = -np.eye(3)
    M[:, :, 6] = (R_A @ (X[:3, :3] @ target2cam[:, :3, 3, None]))[..., 0]
    sol, *_ = np.linalg.lstsq(M.reshape(-1, 7), -t_A.reshape(-1), rcond=None)
    # a grossly wrong pose (a flipped planar pose, a swapped image) would carry the fit: left out
    per_pose = np.linalg.norm((M @ sol) + t_A, axis=1)
    good = per_pose <= 4.0 * np.median(per_pose) + 1e-12
    if good.sum() >= 4 and not good.all():
        M, t_A, n = M[good], t_A[good], int(good.sum())
        sol, *_ = np.linalg.lstsq(M.reshape(-1, 7), -t_A.reshape(-1), rcond=None)
    J, y = M.reshape(-1, 7), -t_A.reshape(-1)
    r = J @ sol - y
    dof = len(y) - 7
    JtJ = J.T @ J
    if dof <= 0 or np.linalg.cond(JtJ) > 1e12:
        return None
    var = float(r @ r) / dof * np.linalg.inv(JtJ)[6, 6]
    # robot errors that depend on the pose are not independent noise: the jackknife (the scale
    # refitted without each pose) measures the spread whatever the errors are; the larger counts
    # (all refits at once: the normal equations without pose k's 3 rows, a downdate of J^T J;
    # one by one when a pose's absence leaves them singular)
    Mt = np.swapaxes(M, 1, 2)
    try:
        loo = np.linalg.solve(JtJ - Mt @ M, (J.T @ y + (Mt @ t_A[..., None])[..., 0])[..., None])[:, 6, 0]
    except np.linalg.LinAlgError:
        loo = np.array([np.linalg.lstsq(np.delete(M, k, axis=0).reshape(-1, 7), np.delete(-t_A, k, axis=0).reshape(-1),
                                        rcond=None)[0][6] for k in range(n)])
    var_jack = (n - 1) / n * float(np.sum((loo - loo.mean()) ** 2))
    return float(sol[6]), float(np.sqrt(max(var, var_jack)))


def _scale_explains(flange2base, target2cam, setup: str, scale: float) -> bool:
    """Whether the camera translations rescaled by ``scale`` make inconsistent poses consistent: a
    wrong target size does, a few wrong poses (whose scale fit is garbage, even negative) do not."""
    if not scale > 0:
        return False
    scaled = target2cam.copy()
    scaled[:, :3, 3] *= scale
    return consistency_score(flange2base, scaled, setup) <= CONSISTENT


#: The board-scale call is made again on subsets of the poses, each without one of this many folds,
#: and acted on only when every subset puts the scale beyond :data:`SCALE_TOLERANCE` on the same side
#: (the full set's std says whether it is beyond its noise; a subset of fewer poses has a larger
#: one): on a real 28-view capture the call named the board 0.935-0.940x its size in 3 of 5
#: cross-validation folds and nothing in the other 2.
SCALE_FOLDS = 5


def _scale_subsets(flange2base, target2cam, setup: str, scale: float, explains: bool) -> tuple[int, int, int]:
    """Over the subsets without one fold each (:data:`SCALE_FOLDS`; each pose once with fewer than 10):
    in how many the board scale is beyond :data:`SCALE_TOLERANCE` on ``scale``'s side of 1
    (``explains``: and rescaling by it makes the poses consistent, as for inconsistent poses), in how
    many it names the size as wrong by its own std (:func:`scale_is_off`), and how many subsets."""
    n = len(flange2base)
    beyond = significant = 0
    folds = fold_indices(n, min(SCALE_FOLDS, n)) if n >= 5 else []
    for fold in folds:
        keep = np.setdiff1d(np.arange(n), fold)
        found = board_scale(flange2base[keep], target2cam[keep], setup)
        if found is None:
            continue
        significant += scale_is_off(*found)
        if abs(found[0] - 1.0) > SCALE_TOLERANCE and (found[0] - 1.0) * (scale - 1.0) > 0 and (
                not explains or _scale_explains(flange2base[keep], target2cam[keep], setup, found[0])):
            beyond += 1
    return beyond, significant, len(folds)


def _unstable_scale_advice(scale: float, std: float, held: int, folds: int) -> str:
    return (f"the target's size may be wrong: the robot's motions put the camera's translations at {1 / scale:.3f}x "
            f"theirs (scale {scale:.4f} +- {std:.4f}), and whether that is beyond a right size's turns on which poses are "
            f"in: {held} of {folds} subsets of them (each without a fifth) say so: X is estimated with the size as given; "
            "measure the square (or the printed target) and give its size, or add views (turns of 30 deg or more, at "
            "several distances)")


def _scale_advice(scale: float, std: float) -> str:
    return (f"the camera's translations are {1 / scale:.3f}x what the robot's motions say (scale {scale:.4f} +- "
            f"{std:.4f}, 1 when right): the target's size (square, or the spacing of circles) is likely wrong by "
            f"that factor: multiply it by {scale:.4f} (or check the robot's length unit)")


def _undetermined(diag: Diagnostics, motions: MotionSet, exc: DegenerateMotionError, flange2base, target2cam,
                  setup: str, outliers: bool, rng) -> Diagnostics:
    """The verdict on motions the general solvers cannot use: 'partial' when the low-DOF solver
    determines part of X (with its own outlier search), else 'degenerate' with what to capture."""
    reasons: list[str] = []
    kind = partial_kind(flange2base, target2cam, setup, reasons)
    diag.verdict = motion_verdict(kind)
    diag.advice.extend([_partial_advice(kind, setup)] if kind else _degenerate_advice(motions, exc) + reasons)
    if kind:
        diag.motion_kind = kind
        _partial_checks(diag, flange2base, target2cam, setup, kind, outliers, rng)
    return diag


def _partial_checks(diag: Diagnostics, flange2base, target2cam, setup: str, kind: str, outliers: bool, rng) -> None:
    """The outlier search and the consistency score on low-DOF data (its own solver), into
    ``diag``, judged as general data are: robot poses paired with another scene's camera poses are
    'inconsistent', not a partial answer. A score that cannot be computed (a minimal set that
    determines nothing, 3 poses on a line) leaves the verdict to the solver."""
    given = consistency_score(flange2base, target2cam, setup, kind)
    diag.consistency = given
    inliers = np.ones(len(flange2base), bool)
    if outliers:
        inliers, diag.pose_residuals = find_outliers(flange2base, target2cam, setup, rng=rng, kind=kind)
        if not inliers.all():
            diag.consistency = consistency_score(flange2base[inliers], target2cam[inliers], setup, kind)
    if np.isfinite(diag.consistency) and _disagree(diag, given, inliers):
        return
    if not inliers.all():  # found with the outliers: their residuals with them
        _name_outliers(diag, inliers, cast(NDArray[np.float64], diag.pose_residuals))


def _disagree(diag: Diagnostics, given: float, inliers: NDArray[np.bool_]) -> bool:
    """Whether the poses (the inliers) disagree beyond their noise, or too many are outliers: then
    the verdict 'inconsistent' and what to check, first (``strict`` quotes it)."""
    found = agreement_verdict(diag.consistency, int(inliers.sum()), len(inliers))
    if found is None:
        return False
    diag.verdict = found
    diag.advice.insert(0, f"the poses do not agree on one camera mounting (consistency {given:.1f}, up to "
                          f"{CONSISTENT:g} is consistent) and no usual mistake explains it: check that each robot pose "
                          "belongs to its image, that the robot reports the flange (not a tool) pose, the pose format "
                          "and units, and the target description")
    return True


def _name_outliers(diag: Diagnostics, inliers: NDArray[np.bool_], resid: NDArray[np.float64]) -> None:
    """The outliers, their residuals and the advice to check them, into ``diag``."""
    diag.outliers = [int(i) for i in np.flatnonzero(~inliers)]
    diag.outlier_residuals = {i: (float(resid[i, 0]), float(resid[i, 1])) for i in diag.outliers}
    which = diag.pose_names(diag.outliers) if diag.names else f"pose(s) {summarize(diag.outliers)}"
    verb = "disagrees" if len(diag.outliers) == 1 and diag.names else "disagree"
    diag.advice.append(f"{which} {verb} with the others far beyond their noise "
                       "(a wrong robot pose, a mislabelled image or a misdetected target): they are left out; check or "
                       "retake them")


def _partial_advice(kind: str, setup: str) -> str:
    """What one-axis or translation-only motions determine, and how to complete X."""
    info = setup_info(setup)
    if kind == ONE_AXIS:
        return (f"every rotation is about one axis (a SCARA, planar or 4-axis robot): X's rotation and its translation "
                f"across that axis are determined, its translation along the axis is not; give known={{'{info.x_name}.z': "
                f"metres}} or {{'{info.z_name}.z': metres}} (--known {info.z_name}.z=VALUE), or add rotations of >= 30 deg "
                f"about a second axis")
    return (f"the robot only translates (a Cartesian robot): X's rotation is determined, its translation is not; give "
            f"known= values for {info.x_name}.x, .y and .z (or {info.z_name}'s), or add rotations of >= 30 deg about "
            f"two axes")


def _degenerate_advice(motions: MotionSet, exc: DegenerateMotionError) -> list[str]:
    """What to capture when the motions cannot determine X."""
    advice = []
    if "parallel" in str(exc):
        axis = rotation_spread(motions.dq_b)[2]
        axis = axis * np.sign(axis[np.argmax(np.abs(axis))])
        others = " and ".join(f"the camera's {c} axis" for k, c in enumerate("xyz") if abs(axis[k]) < 0.9)
        advice.append(
            f"all rotations are about one axis, {_axis_name(axis)} ({np.array2string(axis, precision=3, suppress_small=True)} "
            f"in the camera frame): the camera's rotation about it and its position along it are undetermined; "
            f"add rotations of >= 30 deg about {others or 'a second axis'}")
    advice.append(str(exc))
    return advice


def _weak_advice(diag: Diagnostics, target2cam: NDArray[np.float64], n_used: int) -> list[str]:
    """Sentences for data that determine X, but poorly (small or one-sided rotations, few poses,
    a far target)."""
    weak = []
    angles = cast(NDArray[np.float64], diag.rotation_angles_deg)  # the checks measured them before
    shares = cast(NDArray[np.float64], diag.axis_shares)
    dist = np.median(np.linalg.norm(target2cam[:, :3, 3], axis=1))
    broken = weak_motions(float(np.median(angles)), float(shares[-1]), n_used, float(dist))
    if "small_rotations" in broken:
        weak.append(
            f"most motions rotate less than {SMALL_ROTATION_DEG:g} deg (median {np.median(angles):.1f} deg): rotation "
            "errors then dominate; turn the flange by 20-45 deg between poses (thesis §4.1.2: large rotations)")
    if "weak_axis" in broken:
        weak.append(
            f"little rotation about {_axis_name(cast(NDArray[np.float64], diag.weakest_axis))} ({100 * shares[-1]:.1f}% of the "
            "rotation): add rotations of >= 30 deg about it")
    if "few_poses" in broken:
        weak.append(f"only {n_used} usable poses: take 10-20 from varied viewpoints")
    if "far_target" in broken:
        weak.append(f"the target is {dist:.2f} m from the camera (median): move closer, so that it fills the image "
                    "(camera rotation errors grow with the distance)")
    return weak


def _convention(flange2base, target2cam, setup: str, given: float, robot_input, camera_input, symmetries,
                camera_from_images: bool = False) -> tuple[str, str] | None:
    """The reading of the inputs that makes them consistent (a third of the score as given, and
    consistent), as (hint, advice); None when no usual mistake explains the data."""
    readings = _readings(flange2base, target2cam, robot_input, camera_input, setup, symmetries, camera_from_images)
    scores = {h: consistency_score(f, t, setup) for h, (f, t) in readings.items()}
    hint = min(scores, key=lambda h: scores[h]) if scores else None
    if hint is None or scores[hint] > CONSISTENT or scores[hint] >= given / 3:
        return None
    # readings that fit about as well (inverted robot and inverted camera poses can both fit exactly) are all
    # named, ranked by where each puts the camera and the target, then by their fit
    fits = sorted((h for h in scores if _ties(scores[h], scores[hint])),
                  key=lambda h: (_implausibility(*readings[h], setup), scores[h]))
    hint = fits[0]
    if hint == "invert_robot_poses":  # the same equations as the other setup: rank the two readings
        hint, advice = _setup_or_inverted(*readings[hint], setup, given, scores["invert_robot_poses"])
    else:
        advice = _hint_advice(hint, given, scores[hint])
    for h in fits[1:]:
        advice += f"; or, fitting as well: {_hint_advice(h, given, scores[h])}"
    return hint, advice


def _implausibility(flange2base, target2cam, setup: str) -> int:
    """How many placements of the camera and the target a reading makes implausible (:func:`_plausibility`)."""
    try:
        X = _solve(flange2base, target2cam, setup)
    except (HandEyeError, np.linalg.LinAlgError):
        return 99
    return _plausibility(X, mean_transform(constant_transforms(X, flange2base, target2cam, setup)), setup)[0]


def _ties(score: float, best: float) -> bool:
    """Whether a reading's consistency score fits about as well as the best one's."""
    return score <= CONSISTENT and score <= max(1.5 * best, best + 0.1)


#: Where cameras and targets plausibly are (m): a camera on the flange within this of it, a target on the
#: flange within this of it; a fixed camera, or a target beside the robot, at least MIN_FAR from the base.
NEAR_FLANGE_M, MIN_FAR_M = 0.35, 0.15


def _plausibility(X: NDArray[np.float64], Z: NDArray[np.float64], setup: str) -> tuple[int, str]:
    """How many of a reading's placements are implausible (a camera 2 m from the flange it rides
    on...), and the placements in words."""
    info = setup_info(setup)
    x, z = float(np.linalg.norm(X[:3, 3])), float(np.linalg.norm(Z[:3, 3]))
    if info.camera_on_flange:  # X: camera on the flange; Z: the target beside the robot
        bad = int(x > NEAR_FLANGE_M) + int(z < MIN_FAR_M)
        words = f"the camera {x:.2f} m from the flange, the target {z:.2f} m from the robot base"
    else:  # X: a camera beside the robot; Z: the target on the flange
        bad = int(x < MIN_FAR_M) + int(z > NEAR_FLANGE_M)
        words = f"the camera {x:.2f} m from the robot base, the target {z:.2f} m from the flange"
    return bad, words


def _setup_or_inverted(flange2base_inverted, target2cam, setup: str, given: float, fixed: float) -> tuple[str, str]:
    """Inverted robot poses in ``setup`` and the poses as given in the other setup are the same
    equations: both readings fit. The hint and a sentence that names both, ranked by where each
    puts the camera and the target."""
    other = next(s for s in SETUPS if s != setup)
    try:
        X = _solve(flange2base_inverted, target2cam, setup)
    except (HandEyeError, np.linalg.LinAlgError):
        return "invert_robot_poses", _hint_advice("invert_robot_poses", given, fixed)
    Z = mean_transform(constant_transforms(X, flange2base_inverted, target2cam, setup))
    bad_inv, words_inv = _plausibility(X, Z, setup)
    bad_other, words_other = _plausibility(X, Z, other)  # the same numbers, the other frames
    first = other if bad_other <= bad_inv else setup
    readings = {other: f"the setup is {other}, not {setup}, with the robot poses as given ({words_other}: "
                       f"{'plausible' if not bad_other else 'unlikely'})",
                setup: f"the robot poses are inverted, base2flange given where flange2base is expected, in {setup} "
                       f"({words_inv}: {'plausible' if not bad_inv else 'unlikely'})"}
    ranked = [readings[first], readings[other if first == setup else setup]]
    fix = (f"declare setup: {other}" if first == other else "invert the robot poses")
    return (f"setup:{other}" if first == other else "invert_robot_poses",
            f"two readings make the poses consistent (consistency {given:.1f} as given, {fixed:.2f} so read): "
            f"most likely {ranked[0]}; else {ranked[1]}: {fix}")


def _hint_advice(hint: str, given: float, fixed: float) -> str:
    what = {
        "invert_robot_poses": "the robot poses are inverted (base2flange given where flange2base is expected): invert them",
        "invert_camera_poses": "the camera poses are inverted (cam2target given where target2cam is expected): invert them",
    }.get(hint)
    if what is None:
        camera = hint.startswith("camera:")
        who, where = ("camera", " for camera_poses") if camera else ("robot", "")
        key, _, value = hint.removeprefix("camera:").partition(":")
        what = {
            "length_unit": f"the {who} positions are in {value}: declare length_unit {value}{where}",
            "angle_unit": f"the {who} angles are in {value}: declare angle_unit {value}{where}",
            "euler": f"the {who} angles follow the Euler sequence {value} "
                     f"({'intrinsic' if value.isupper() else 'extrinsic'}): declare format euler:{value}{where}",
        }.get(key, f"the {who} quaternions are in {hint.removeprefix('camera:')} order: declare format "
                   f"{hint.removeprefix('camera:')}{where}")
    return f"{what} (consistency {given:.1f} as given, {fixed:.2f} so read)"


def _leave_one_out(flange2base, target2cam, setup, inliers) -> NDArray[np.float64]:
    idx = np.flatnonzero(inliers)
    out = np.full((len(flange2base), 2), np.nan)
    if len(idx) < 4:
        return out
    # as _solve on the inliers, then every pose left out in one batch: a run that check_observability
    # would refuse, or that Daniilidis cannot solve, moves X infinitely far
    motions = MotionSet.from_poses(flange2base[idx], target2cam[idx], setup, "auto")
    X = solvers.solve_motions(motions, "daniilidis")
    groups = motion_groups(cast(NDArray[np.intp], motions.pairs), len(idx))
    Xk = solve_leave_one_out(motions, groups)
    ok = observable_leave_one_out(motions, groups) & np.isfinite(Xk).all(axis=(1, 2))
    Xk[~ok] = X
    moves = np.stack([np.degrees(rotation_error(Xk, X)), 1e3 * translation_error(Xk, X)], axis=1)
    out[idx] = np.where(ok[:, None], moves, np.inf)
    return out


def compare_solvers(flange2base: NDArray[np.float64], target2cam: NDArray[np.float64], setup: str,
                    X_ref: NDArray[np.float64], pairs: Pairs = "auto") -> list[dict]:
    """Every registered solver's closed form on the same poses (no refinement, no check).

    Per solver: how far its X is from ``X_ref`` (deg, mm), the median per-pose consistency of Z
    (deg, mm) and the time taken (ms); ``error`` instead when it cannot solve these data.
    """
    rows: list[dict[str, Any]] = []
    for name in solvers.available(closed_forms=True):
        start = time.perf_counter()
        try:
            X, Z, _ = closed_form(flange2base, target2cam, setup, name, pairs)
        except HandEyeError as exc:
            rows.append({"method": name, "error": str(exc)})
            continue
        Zi = constant_transforms(X, flange2base, target2cam, setup)
        ms = 1e3 * (time.perf_counter() - start)
        rows.append({
            "method": name,
            "dX_deg": float(np.degrees(rotation_error(X, X_ref))),
            "dX_mm": float(1e3 * translation_error(X, X_ref)),
            "median_pose_deg": float(np.median(np.degrees(rotation_error(Zi, Z)))),
            "median_pose_mm": float(np.median(1e3 * translation_error(Zi, Z))),
            "ms": ms,
        })
    return rows
