"""Line-scan camera sessions calibrated: each scan's target found, then the estimation core.

A line-scan session (:mod:`handeye.pipelines.linescan.session`: ``linescan:`` in session.yaml, ``images/``
of pushbroom scans, the robot's trajectory with times) gives per scan the rows the camera exposed
while the robot swept it (or the target) across its view plane. :func:`calibrate_linescan_session`
finds the target's corners in each scan (a scan without the whole target is skipped, named), makes
them a sensor model (:class:`~handeye.sensors.linescan.model.LineScanCorners`: each corner's distance
from the view plane at its row's time and its pixel error along the line), and the estimation core
(:func:`handeye.estimation.core.estimate`) fits X with the target's pose, the focal length,
principal point and distortion along the line and the clocks' offset (and the arm's table when the
trajectory is joint angles: :func:`linescan_joints`); cross-validates on held-out scans (their
corners' errors at the target, mm), says what the capture leaves undetermined and gives the
verdict: one :class:`~handeye.result.Calibration`, as for images.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..._shared.threads import on_one_blas_thread
from ...errors import DegenerateMotionError, InputMismatchError
from ...estimation.readings import Reading
from ...frames.setups import predicted_target2cam
from ...geometry.se3 import invert
from ...options import CalibrationOptions
from ...result import Calibration
from ...robot.kinematics import Chain, joints_at
from ...robot.models import ControllerPoses, JointTrajectory, PoseErrors, RobotModel
from ...sensors.camera.detect import detect_images
from ...sensors.camera.targets import target_from_spec
from ...sensors.linescan.model import LineScanCorners, Trajectory
from .._sensor import estimate_checked, sensor_options, session_robot_input
from .session import LineScanSession, load_linescan_session

__all__ = ["calibrate_linescan_session", "grid_orderings", "linescan_robot", "linescan_joints", "readings_note"]


def linescan_robot(flange2base_ref: NDArray[np.float64], accuracy: tuple[float, float] | None
                   ) -> ControllerPoses | PoseErrors:
    """The robot model of a line-scan capture: each scan's reference pose with its own error fitted,
    the robot's stated ``accuracy`` its prior (:class:`~handeye.robot.models.PoseErrors`); the poses
    as given when no accuracy is stated, or (0, 0) (an exact robot).

    A scan is a short straight move, over which the arm's error is one rigid error; fitted, it no
    longer bends the focal length and X (the focal length trades with the distance). Measured
    (``benchmarks/bench_linescan.py``, 20 sessions of 12 scans, a calibrated arm's error of 0.01 deg
    / 0.05 mm stated): X 0.80 -> 0.10 mm eye-in-hand and 0.44 -> 0.18 mm eye-to-hand (median), the
    focal length within 0.02%. With an exact robot and the default accuracy stated, it costs
    precision the data would have given (0.03 -> 0.15 mm on 6 sessions): no real arm is exact.
    """
    exact = accuracy is None or not any(accuracy)  # (0, 0): the robot stated exact, as the options take it
    return ControllerPoses(flange2base_ref, None) if exact else PoseErrors(flange2base_ref, accuracy)


def linescan_joints(chain: Chain, times: NDArray[np.float64], joints: NDArray[np.float64], model: LineScanCorners,
                    compliance: bool = False) -> JointTrajectory:
    """The robot model of a line-scan capture whose trajectory is joint angles (``joints`` at the
    robot's ``times``): every row's flange pose through the arm's table, whose entries are fitted
    with X (:class:`~handeye.robot.models.JointTrajectory`); each scan's own pose, for the start and
    the arm's accuracy, at its reference time (:attr:`LineScanCorners.t_ref`).

    Examples
    --------
    >>> from handeye.pipelines.linescan.simulate import linescan_scene
    >>> sc = linescan_scene(4, "eye_in_hand", rng=0, arm="ur5")
    >>> model = LineScanCorners("eye_in_hand", sc.names, sc.corners, sc.target_points, sc.starts, sc.line_rate,
    ...                         sc.trajectory, sc.focal, sc.width)
    >>> linescan_joints(sc.chain, sc.trajectory.times, sc.joints, model).joints.shape
    (4, 6)
    """
    return JointTrajectory(chain, joints_at(times, joints, model.t_ref), compliance=compliance, times=times,
                           trajectory=joints)


def grid_orderings(points: NDArray[np.float64]) -> list[NDArray[np.intp]]:
    """The orders in which a detector may read a target's ``points`` (n, 3): as printed, and each
    half turn or mirror image about the points' middle that maps them onto themselves (a scan
    moving the other way is a mirror image; a square grid is also read transposed)."""
    xy = np.asarray(points, float)[:, :2]
    middle = xy.mean(axis=0)
    out = []
    for T in ([[1, 0], [0, 1]], [[-1, 0], [0, -1]], [[-1, 0], [0, 1]], [[1, 0], [0, -1]],
              [[0, 1], [1, 0]], [[0, -1], [-1, 0]], [[0, -1], [1, 0]], [[0, 1], [-1, 0]]):
        moved = (xy - middle) @ np.asarray(T, float).T + middle
        gap = np.linalg.norm(moved[:, None] - xy[None], axis=2)
        order = np.argmin(gap, axis=1)
        if np.all(gap[np.arange(len(xy)), order] < 1e-9) and len(set(order.tolist())) == len(xy):
            out.append(order.astype(np.intp))
    return out


def readings_note(cal: Calibration, points: NDArray[np.float64], orderings: list[NDArray[np.intp]] | None) -> list[str]:
    """What a symmetric target's readings leave open of Z, in a note: the grid of ``points`` (its
    target frame) maps onto itself turned a half turn about its normal (and, read mirrored, about its
    x or y axis through its middle, which turns z out of the board), so Z is the reading the scans and
    the robot's motion settled, and may be so turned from another tool's or a simulator's; X is the
    same for every reading. Says which way Z's z axis points (into the board, away from the camera,
    as handeye's target frame of images has it; or towards the camera, and the turn that gives the
    other). No note for a target read one way (``orderings``: one, or None)."""
    if orderings is None or len(orderings) < 2:
        return []
    middle = 1e3 * np.asarray(points, float)[:, :2].mean(axis=0)
    cam_z = invert(predicted_target2cam(cal.X, cal.Z, cal.flange2base, cal.setup))[:, 2, 3]
    towards = float(np.median(cam_z)) > 0
    turns = "a half turn (a square grid: a quarter turn)" if len(orderings) > 4 else "a half turn"
    return [f"the {cal.sensor.target} reads the same turned {turns} about its normal, or a half turn about its x or y axis, through "
            f"its middle ({middle[0]:.1f}, {middle[1]:.1f}) mm in its frame (a scan moving the other way is a mirror image): "
            "Z is the reading the scans and the robot's motion settled, and may be so turned from another tool's or a "
            "simulator's (X is the same for every reading); "
            + ("here Z's z axis points towards the camera: Z turned a half turn about its x axis through that middle has "
               "it into the board, as handeye's target frame of images has it" if towards else
               "here Z's z axis points into the board, away from the camera, as handeye's target frame of images has it")]


def _detected(s: LineScanSession, progress: bool):
    """Each scan's corners (u, row) and target points, or why it was skipped (a scan of another
    width than the session's is skipped whatever was found in it)."""
    target = target_from_spec(s.target_spec, where="target")
    found = []
    for r in detect_images(s.image_paths, target, progress=progress):
        if r.image_size is not None and r.image_size[0] != s.width:
            found.append((None, f"{r.image_size[0]} pixels along the line, the session says width: {s.width}"))
        else:
            found.append((r.detection, r.error))
    return target, found


@on_one_blas_thread  # narrow matrices throughout: a second BLAS thread spins more than it works
def calibrate_linescan_session(folder: str | Path | LineScanSession, options: CalibrationOptions | None = None, *,
                               progress: bool = False, jobs: int | None = None,
                               **changes) -> Calibration:
    """Calibrate a line-scan camera session (the module docstring).

    Parameters
    ----------
    folder : path or LineScanSession
    options : CalibrationOptions, optional
        ``robot_accuracy`` (the controller's poses' stated accuracy: each scan's pose error fitted
        with it as the prior), ``folds``, and for a trajectory of joint angles ``arm`` (instead of
        the ``joints:`` table's) and ``compliance``; the options of image sessions are refused when
        changed.
    progress : bool
        A progress bar over the scans' detection.
    jobs : int, optional
        Unused (the scans are detected in one process); accepted as every pipeline does.

    Returns
    -------
    Calibration
        X (``cam2flange`` eye-in-hand, ``cam2base`` eye-to-hand), Z the target's pose, the std, the
        verdict; ``sensor`` holds the fitted focal length, principal point, distortion and clock
        offset with their std; ``skipped`` the scans not used, with why; with joint angles
        ``kinematic``, the arm's table fitted and its accuracy before and after.

    Raises
    ------
    SessionError
        A bad session, naming the file or key (:func:`~handeye.pipelines.linescan.session.load_linescan_session`).
    DegenerateMotionError
        Fewer than 3 scans with the target, or scans whose poses cannot determine X.

    Examples
    --------
    >>> import tempfile
    >>> from handeye.pipelines.linescan.simulate import linescan_scene, write_linescan_session
    >>> folder = write_linescan_session(tempfile.mkdtemp() + "/s", linescan_scene(8, "eye_in_hand", rng=1), rng=1)
    >>> cal = calibrate_linescan_session(folder)
    >>> cal.verdict, abs(cal.sensor.figures["focal_px"]["value"] / 2400 - 1) < 1e-3
    ('good', True)
    """
    opts = sensor_options(options, changes, "a line-scan session", table=True)
    s = folder if isinstance(folder, LineScanSession) else load_linescan_session(folder, arm=opts.arm)
    target, found = _detected(s, progress)
    kept = [k for k, (det, _) in enumerate(found) if det is not None]
    skipped = list(s.skipped) + [(s.names[k], why) for k, (det, why) in enumerate(found) if det is None]
    if len(kept) < 3:
        why = f" ({'; '.join(f'{n}: {r}' for n, r in skipped[:5])})" if skipped else ""
        raise DegenerateMotionError(f"{len(kept)} of {len(s.names) + len(s.skipped)} scans show the target{why}: at least 3 "
                                    "are needed, 10-15 with the flange turned 10 deg or more about two or three axes to "
                                    "trust X")

    def rebuild(reading: Reading) -> tuple[LineScanCorners, RobotModel]:
        """The scans as another reading of the trajectory's poses would place them."""
        other = _scans_model(replace(s, setup=reading.setup, flange2base=reading.flange2base), kept, found, target)
        return other, ControllerPoses(other.flange2base_ref, opts.robot_accuracy)

    model = _scans_model(s, kept, found, target)
    cal = estimate_checked(model, _robot(s, model, opts), s, opts, rebuild=None if s.joints is not None else rebuild)
    notes = list(s.notes) + list(cal.notes) + readings_note(cal, target.object_points(), model.orderings)
    return replace(cal, skipped=skipped + list(cal.skipped), notes=notes, input_folder=s.folder,
                   robot_input=session_robot_input(s, cal.flange2base))


def _scans_model(s: LineScanSession, kept: list[int], found: list, target) -> LineScanCorners:
    """The scans ``kept`` of ``s`` (their detections ``found``) as a sensor model on the session's trajectory."""
    return LineScanCorners(s.setup, [s.names[k] for k in kept], [found[k][0].image_points for k in kept],
                           [found[k][0].object_points for k in kept], s.starts[kept], s.line_rate,
                           Trajectory(s.times, s.flange2base), s.focal, s.width, s.noise_px, str(s.target_spec["type"]),
                           # a grid found whole may be read in a mirrored order; a coded target's ids are its own
                           grid_orderings(target.object_points()) if all(len(found[k][0]) == len(target.object_points())
                                                                         for k in kept) else None)


def _robot(s: LineScanSession, model: LineScanCorners, opts: CalibrationOptions) -> RobotModel:
    """The session's robot model: its joint angles through the arm's table when it has them, else the
    controller's poses (:func:`linescan_robot`)."""
    if s.joints is not None:
        return linescan_joints(s.arm, s.times, s.joints, model, opts.compliance)
    if opts.compliance:
        raise InputMismatchError(f"{s.folder}: compliance=True (--compliance) fits the joints' compliance from joint "
                                 "angles with the arm's table; the session's trajectory is poses (give it as a joints: "
                                 "table) or leave compliance out")
    return linescan_robot(model.flange2base_ref, opts.robot_accuracy)
