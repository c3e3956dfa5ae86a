"""Pose planning: robot poses that make a good calibration, and how good it will be, before the robot moves.

The thesis asks for "the path the robot should follow to get data that guarantee precision" (§3.1)
and gives rules of thumb (§4.1.2: large rotations about axes that differ, the target always in
view). We plan for the estimator handeye actually runs on images, the joint reprojection
refinement of X and Z (:func:`handeye.estimation.refinement.refine_reprojection`): its covariance for
pixel noise sigma is ``sigma^2 (J^T J)^-1`` and J is known before any image is taken. So:

1. Candidate camera viewpoints look at the target centre from the ``standoff`` distance (and
   0.8x / 1.25x of it), tilted 0 to ``tilt_max`` from the target normal in 12 directions, with 8
   rolls about the optical axis; those that keep every target point ``margin_px`` inside the image
   (OpenCV's projection, with distortion) and, when a reach box is given, whose flange position
   lies in it, stay.
2. From these, N poses are chosen to minimise the predicted error of X (A-optimal design: the
   trace of X's covariance, rotation weighted by the standoff so both are in metres): greedy
   additions, then exchanges until no swap helps. Large rotations about spread axes — the
   thesis's rules — come out of this criterion rather than being imposed.
3. The poses are ordered to shorten the robot path (nearest neighbour, then 2-opt).

:func:`easy_handeye_poses` builds the fixed 17-pose pattern of easy_handeye's automatic mover
(rotations of +-25 and +-12.5 deg about the flange axes, moves of +-0.05 / +-0.1 / +0.033 m) for
comparison; :func:`simulate_errors` measures either plan by Monte-Carlo through the real pipeline.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from ..errors import HandEyeError
from ..estimation.refinement import refine_reprojection
from ..frames.metrics import rotation_error, std_deg_mm, translation_error
from ..frames.motions import order_path
from ..frames.setups import check_setup, flange_poses, predicted_target2cam, setup_info
from ..geometry.se3 import invert, make_transform
from ..io.session import write_pose_table
from ..options import ROBOT_ACCURACY, CalibrationOptions
from ..pipelines.calibration import calibrate_poses
from ..pipelines.viewpoints import (
    DISTANCE_FACTORS,
    candidate_views,
    choose_next,
    choose_views,
    predicted_cov,
    reported_std,
    reprojection_information,
    viewpoints_around,
    visible_mask,
)
from ..sensors.camera.pnp import project_points, solve_pnp
from ..sensors.camera.targets import Detection
from ..simulate import look_at

__all__ = ["Plan", "ROBOTS", "plan_poses", "easy_handeye_poses", "reprojection_information", "predicted_cov",
           "visible_mask", "simulate_errors", "write_plan", "order_path", "candidate_views", "choose_next", "choose_views",
           "reported_std"]



@dataclass
class Plan:
    """Planned robot poses and the accuracy they promise.

    Attributes
    ----------
    flange2base : (N, 4, 4)
        The poses to send the robot to, in order.
    target2cam : (N, 4, 4)
        What the camera should then see (from the assumed X and Z).
    cov_X : (6, 6)
        Predicted covariance of X (rotation vector rad, translation m) for ``noise_px``.
    std_X : (6,)
        Its standard deviations in degrees and millimetres.
    std_reported : (6,)
        The std ``calibrate`` would report for this capture: ``cov_X`` plus the robot's absolute
        accuracy (``robot_accuracy``), which no capture removes.
    noise_px : float
    n_candidates : int
        Viewpoints that passed the visibility and reach checks.
    """

    setup: str
    X: NDArray[np.float64]
    Z: NDArray[np.float64]
    flange2base: NDArray[np.float64]
    target2cam: NDArray[np.float64]
    cov_X: NDArray[np.float64]
    std_X: NDArray[np.float64]
    noise_px: float
    n_candidates: int
    robot: str = "arm"
    #: what the chosen robot cannot determine (the std there is inf), in words
    unobservable: list[str] | None = None
    #: the std calibrate would report: cov_X plus the robot's absolute accuracy
    std_reported: NDArray[np.float64] | None = None
    #: the robot's absolute accuracy assumed (deg, mm per axis), None for an exact robot
    robot_accuracy: tuple[float, float] | None = None


#: Robots ``plan_poses`` plans for: a 6-axis arm (views all around), a SCARA (the flange turns about
#: the vertical only) and a Cartesian gantry (translations only).
ROBOTS = ("arm", "scara", "cartesian")
#: SCARA candidates: yaws of the flange (deg) and lateral offsets (fractions of the standoff).
SCARA_YAWS_DEG = np.arange(-165.0, 180.0, 15.0)
LATERAL = np.linspace(-0.3, 0.3, 5)


def _low_dof_candidates(robot: str, setup: str, X: NDArray[np.float64], Z: NDArray[np.float64],
                        centre: NDArray[np.float64], standoff: float) -> NDArray[np.float64]:
    """Flange poses of a robot whose flange points down (base -z) and turns about the vertical
    (SCARA) or not at all (Cartesian): eye-in-hand, the camera above the target centre; eye-to-hand,
    the target centre above the camera. Lateral offsets and three heights around ``standoff``."""
    yaws = np.radians(SCARA_YAWS_DEG) if robot == "scara" else np.zeros(1)
    Y, dx, dy, h = np.meshgrid(yaws, LATERAL * standoff, LATERAL * standoff, standoff * np.asarray(DISTANCE_FACTORS),
                               indexing="ij")
    down = Rotation.from_euler("x", 180, degrees=True).as_matrix()
    R_f = Rotation.from_euler("z", Y.ravel()[:, None]).as_matrix() @ down
    offset = np.stack([dx.ravel(), dy.ravel(), h.ravel()], axis=1)
    if setup_info(setup).camera_on_flange:
        p = (Z[:3, :3] @ centre + Z[:3, 3]) + offset - R_f @ X[:3, 3]
    else:
        p = X[:3, 3] + offset - R_f @ (Z[:3, :3] @ centre + Z[:3, 3])
    return make_transform(R_f, p)


def _gauge(robot: str, setup: str, scale: float) -> tuple[NDArray[np.float64], list[str]]:
    """A prior (12, 12) on what ``robot`` cannot determine (X's translation along the vertical, or all
    of it), so that the information can be inverted, and those parameters in words."""
    info = setup_info(setup)
    prior = np.zeros((12, 12))
    if robot == "arm":
        return prior, []
    frame = "flange" if info.camera_on_flange else "base"
    axes = [2] if robot == "scara" else [0, 1, 2]  # the flange z axis is the vertical (pointing down)
    for k in axes:
        prior[3 + k, 3 + k] = 1e6 * scale
    return prior, [f"translation of {info.x_name} along the {frame} {'xyz'[k]} axis" for k in axes]


def _reachable(flange2base: NDArray[np.float64], keep: NDArray[np.bool_], n_poses: int, z_range, reach_box) -> NDArray[np.bool_]:
    """The candidates whose flange lies in ``z_range`` and ``reach_box`` (each optional); raises when
    fewer than ``n_poses`` of the visible ones (``keep``) are left."""
    keep = keep.copy()
    if z_range is not None:
        lo, hi = (float(v) for v in z_range)
        if not lo < hi:
            raise HandEyeError(f"z range {lo:g}, {hi:g}: give zmin,zmax (m) with zmin below zmax")
        keep &= (flange2base[:, 2, 3] >= lo) & (flange2base[:, 2, 3] <= hi)
        if keep.sum() < n_poses:
            raise HandEyeError(f"only {int(keep.sum())} views that see the whole target put the flange within z "
                               f"{lo:g}..{hi:g} m; widen the range or change the standoff")
    if reach_box is not None:
        box = np.asarray(reach_box, dtype=float).ravel()
        if box.size != 6 or np.any(box[:3] >= box[3:]):
            raise HandEyeError("reach box: give xmin,ymin,zmin,xmax,ymax,zmax (m) with each min below its max")
        t = flange2base[:, :3, 3]
        inside = np.all((t >= box[:3]) & (t <= box[3:]), axis=1)
        if (keep & inside).sum() < n_poses:
            raise HandEyeError(
                f"only {int((keep & inside).sum())} views that see the whole target put the flange inside the reach "
                f"box; enlarge the box, move the target, or change the standoff")
        keep &= inside
    return keep


def plan_poses(
    setup: str,
    X: ArrayLike,
    Z: ArrayLike,
    object_points: ArrayLike,
    K: ArrayLike,
    image_size: tuple[int, int],
    dist: ArrayLike | None = None,
    n_poses: int = 12,
    standoff: float = 0.5,
    tilt_max_deg: float = 45.0,
    margin_px: float = 20.0,
    reach_box: ArrayLike | None = None,
    noise_px: float = 0.3,
    robot: str = "arm",
    z_range: tuple[float, float] | None = None,
    robot_accuracy: tuple[float, float] | None = ROBOT_ACCURACY,
) -> Plan:
    """Plan ``n_poses`` robot poses for a calibration (see the module docstring).

    Parameters
    ----------
    setup : {'eye_in_hand', 'eye_to_hand'}
    X, Z : (4, 4)
        The assumed (rough, e.g. from CAD) camera mounting and target placement: eye-in-hand
        ``cam2flange`` and ``target2base``; eye-to-hand ``cam2base`` and ``target2flange``.
        Errors of a few centimetres or degrees are absorbed by ``margin_px``.
    object_points : (M, 3)
        The target's points (metres, target frame; the camera sees the target from its -z side).
    K, image_size, dist
        The camera (``dist`` in OpenCV's order; default none).
    n_poses : int
        At least 3.
    standoff : float
        Camera-to-target distance (m) of the middle candidates (0.8x and 1.25x are tried too).
    tilt_max_deg : float
        Largest angle between the optical axis and the target normal.
    margin_px : float
        Every target point stays this far inside the image.
    reach_box : (6,) array, optional
        ``xmin, ymin, zmin, xmax, ymax, zmax`` (m, base frame): where the flange may go.
    noise_px : float
        Pixel noise assumed for the predicted uncertainty.
    robot : {'arm', 'scara', 'cartesian'}
        'arm': views all around the target. 'scara': the flange points down and turns about the
        vertical only (yaws every 15 deg, the camera above the target or the target above the
        camera, lateral offsets, three heights); 'cartesian': the same without the turn. Neither
        determines all of X (``Plan.unobservable``, std inf there): the calibration needs
        ``known=`` values.
    z_range : (zmin, zmax), optional
        The heights (m, base frame) the flange can reach (a SCARA's z stroke).
    robot_accuracy : (deg, mm) or None
        The robot's absolute accuracy per axis, added as calibrate adds it (``Plan.std_reported``).

    Raises
    ------
    HandEyeError
        Bad arguments, or too few viewpoints see the whole target (with what to change).
    """
    setup = check_setup(setup)
    X = np.asarray(X, dtype=float)
    Z = np.asarray(Z, dtype=float)
    obj = np.asarray(object_points, dtype=float).reshape(-1, 3)
    K = np.asarray(K, dtype=float)
    dist = np.zeros(5) if dist is None else np.asarray(dist, dtype=float).ravel()
    if n_poses < 3:
        raise HandEyeError(f"--poses {n_poses}: at least 3 poses are needed (two motions); 10 to 20 are usual")
    if not standoff > 0 or not np.isfinite(standoff):
        raise HandEyeError(f"standoff {standoff}: give the camera-to-target distance in metres (> 0)")
    if not 0 < tilt_max_deg <= 70:
        raise HandEyeError(f"tilt_max {tilt_max_deg} deg: use a value in (0, 70]; detectors fail at grazing views")
    if robot not in ROBOTS:
        raise HandEyeError(f"robot {robot!r}; use one of {', '.join(ROBOTS)}")
    centre = 0.5 * (obj.min(axis=0) + obj.max(axis=0))
    if robot == "arm":
        cam2target = viewpoints_around(standoff, tilt_max_deg, centre)
        flange2base, target2cam = flange_poses(cam2target, X, Z, setup), invert(cam2target)
    else:
        flange2base = _low_dof_candidates(robot, setup, X, Z, centre, standoff)
        target2cam = predicted_target2cam(X, Z, flange2base, setup)
    keep = visible_mask(target2cam, obj, K, dist, image_size, margin_px)
    if keep.sum() < n_poses:
        raise HandEyeError(
            f"only {int(keep.sum())} of {len(keep)} candidate views keep the whole target {margin_px:g} px inside the "
            f"image at a standoff of {standoff:g} m; increase the standoff or use a smaller target")
    keep = _reachable(flange2base, keep, n_poses, z_range, reach_box)
    idx = np.flatnonzero(keep)
    infos = reprojection_information(flange2base[idx], X, Z, setup, obj, K)
    weight = np.r_[np.full(3, standoff**2), np.ones(3)]  # rotation error seen at the standoff, in metres
    prior, unobservable = _gauge(robot, setup, float(np.mean(np.trace(infos, axis1=1, axis2=2))))
    chosen = idx[choose_views(infos, n_poses, weight, prior=prior)]
    order = order_path(flange2base[chosen])
    chosen = chosen[order]
    info = reprojection_information(flange2base[chosen], X, Z, setup, obj, K).sum(axis=0)
    cov = predicted_cov(info + prior, noise_px)
    std = std_deg_mm(cov)
    std[3:][np.diag(prior)[3:6] > 0] = np.inf
    accuracy = CalibrationOptions(robot_accuracy=robot_accuracy).robot_accuracy
    return Plan(setup, X, Z, flange2base[chosen], target2cam[chosen], cov, std, float(noise_px), int(keep.sum()),
                robot, unobservable, reported_std(std, cov, X, accuracy), accuracy)


def easy_handeye_poses(start_flange2base: ArrayLike, angle_deg: float = 25.0, translation: float = 0.1) -> NDArray[np.float64]:
    """easy_handeye's automatic movement pattern around a start pose (17 poses).

    Its default parameters (``rotation_delta_degrees`` 25, ``translation_delta_meters`` 0.1): the
    start orientation turned by +-angle and by +-angle/2 about each of the flange's own x, y, z
    axes (12 poses), and the start position moved by +-translation/2 along base x, +-translation
    along base y and +translation/3 along base z (5 poses).
    """
    T0 = np.asarray(start_flange2base, dtype=float)
    out = []
    for scale in (1.0, 0.5):
        for k in range(3):
            for sign in (1.0, -1.0):
                rv = np.zeros(3)
                rv[k] = sign * scale * np.radians(angle_deg)
                out.append(T0 @ make_transform(Rotation.from_rotvec(rv).as_matrix(), np.zeros(3)))
    for k, d in ((0, translation / 2), (0, -translation / 2), (1, translation), (1, -translation), (2, translation / 3)):
        T = T0.copy()
        T[k, 3] += d
        out.append(T)
    return np.array(out)


def fronto_parallel_start(X: ArrayLike, Z: ArrayLike, object_points: ArrayLike, standoff: float, setup: str) -> NDArray[np.float64]:
    """The flange pose from which the camera looks straight at the target centre from ``standoff``."""
    obj = np.asarray(object_points, dtype=float).reshape(-1, 3)
    centre = 0.5 * (obj.min(axis=0) + obj.max(axis=0))
    cam2target = look_at(centre - [0.0, 0.0, standoff], centre, np.zeros(1))
    return flange_poses(cam2target, np.asarray(X, float), np.asarray(Z, float), setup)[0]


def simulate_errors(
    flange2base: NDArray[np.float64],
    X: NDArray[np.float64],
    Z: NDArray[np.float64],
    setup: str,
    object_points: NDArray[np.float64],
    K: NDArray[np.float64],
    dist: NDArray[np.float64],
    image_size: tuple[int, int],
    noise_px: float,
    runs: int,
    rng: np.random.Generator | int | None = None,
    method: str = "daniilidis",
) -> tuple[NDArray[np.float64], int]:
    """Errors of X (runs, 2: deg, mm) through the real pipeline, and how many poses could be used.

    Per run: every target point projected (OpenCV, with distortion) and moved by Gaussian noise
    of ``noise_px`` per axis; poses that do not keep every point inside the image are dropped (a
    detector would not find the target); PnP per image; ``method``; then the joint reprojection
    refinement, as ``handeye.calibrate`` runs it on a session with known intrinsics.
    """
    rng = np.random.default_rng(rng)
    obj = np.ascontiguousarray(object_points, dtype=np.float64)
    ids = np.arange(len(obj))
    T_true = predicted_target2cam(X, Z, flange2base, setup)
    usable = visible_mask(T_true, obj, K, dist, image_size, 0.0)
    if usable.sum() < 3:
        raise HandEyeError(f"only {int(usable.sum())} poses see the whole target; no calibration possible")
    f2b = flange2base[usable]
    clean = [project_points(T, obj, K, dist) for T in T_true[usable]]
    errors = np.empty((runs, 2))
    for r in range(runs):
        img = [c + rng.normal(0.0, noise_px, c.shape) for c in clean]
        t2c = np.array([solve_pnp(Detection(ids, im, obj), K, dist)[0] for im in img])
        cal = calibrate_poses(f2b, t2c, setup=setup, method=method, refine="none", check=False, uncertainty=False)
        ref = refine_reprojection(cal.X, cal.Z, f2b, [obj] * len(img), img, K, dist, setup)
        errors[r] = np.degrees(rotation_error(ref.X, X)), 1e3 * translation_error(ref.X, X)
    return errors, int(usable.sum())


def write_plan(plan: Plan, path: str | Path, format: str = "quat_wxyz", length_unit: str = "m",
               angle_unit: str = "rad", protect=()) -> Path:
    """Write the planned flange poses as a session ``poses.csv`` (``image`` column first: the names the
    images should get), in the robot's own pose format and units; atomically."""
    names = [f"{k:03d}.png" for k in range(len(plan.flange2base))]
    return write_pose_table(path, names, plan.flange2base, format, length_unit, angle_unit, protect)
