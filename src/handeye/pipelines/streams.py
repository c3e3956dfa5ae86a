"""Calibration from continuous recordings: a robot stream and a camera stream, each on its own clock.

:func:`calibrate_streams` estimates the clock offset (:func:`handeye.estimation.sync.synchronise`: coarse
from the angular velocities, refined jointly with X and Z on the camera samples), picks
well-spread keyframes where the robot moves slowly, interpolates the robot at their camera times
corrected by the offset, and calibrates them as :func:`handeye.calibrate_poses` does (check,
estimator by cross-validation, honest std). The offset's own uncertainty is added to X's.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike

from .._shared.text import summarize
from ..estimation.sync import KEYFRAMES, check_stream, keyframes_at, offset_cov, synchronise
from ..estimation.verdict import judged
from ..frames.metrics import std_deg_mm
from ..frames.poses import RobotPoseInput
from ..frames.setups import check_setup
from ..options import CalibrationOptions, options_from
from ..result import Calibration, StreamSync
from ..robot.kinematics import Chain, joints_at, load_arm
from .calibration import calibrate_poses
from .joints import calibrate_joints, joint_angles

__all__ = ["calibrate_streams", "calibrate_joint_streams", "paired_delay_note", "KEYFRAMES"]


def calibrate_streams(
    t_robot: ArrayLike,
    flange2base: ArrayLike,
    t_cam: ArrayLike,
    target2cam: ArrayLike,
    setup: str = "eye_in_hand",
    options: CalibrationOptions | None = None,
    *,
    robot_input: RobotPoseInput | None = None,
    **changes,
) -> Calibration:
    """Hand-eye calibration from a robot stream and a camera stream with separate clocks.

    Parameters
    ----------
    t_robot : array_like, shape (N,)
        Stamps of the robot poses, seconds on the robot's clock, strictly increasing.
    flange2base : array_like, shape (N, 4, 4)
        The robot poses (metres), e.g. 100-500 Hz from the controller.
    t_cam : array_like, shape (M,)
        Stamps of the camera poses, seconds on the camera's clock, strictly increasing.
    target2cam : array_like, shape (M, 4, 4)
        The target's pose in the camera frame per camera sample (PnP), metres.
    setup : {'eye_in_hand', 'eye_to_hand'}
    options : CalibrationOptions, optional
        How to calibrate (:class:`handeye.CalibrationOptions`), or its fields as keywords:
    method, refine, pairs, check, robot_accuracy, strict, folds, known
        As :func:`handeye.calibrate_poses`, for the keyframes.
    keyframes : int
        How many camera samples to calibrate on (well spread, where the robot moves slowly).
    offset_range : (lo, hi), optional
        Offsets (s, camera clock minus robot clock) to search; default +-1 s, or around the
        difference of the streams' middles when their stamps do not overlap.
    time_offset : float, optional
        The offset, when known: no estimate (``time_offset_std`` is then 0).
    robot_input : RobotPoseInput, optional
        The robot stream as written (format and units): the result files give X in its convention,
        and the check tries its other readings on the keyframes.

    Returns
    -------
    Calibration
        As :func:`handeye.calibrate_poses` on the keyframes (the robot interpolated at their camera
        times minus the offset), with ``time_offset`` (s), ``time_offset_std`` and ``streams``; X's
        covariance includes the offset's uncertainty.

    Raises
    ------
    InputMismatchError
        Streams that are too short, unordered, do not overlap in time, or whose angular
        velocities align best at the end of the searched range.
    DegenerateMotionError
        The keyframes cannot determine X.

    Examples
    --------
    A robot stream at 100 Hz and a camera stream at 30 Hz on two clocks, 40 ms apart:

    >>> import handeye
    >>> from handeye.simulate import stream_scene
    >>> sc = stream_scene(duration=12.0, setup="eye_in_hand", time_offset=0.040, rng=1)
    >>> cal = handeye.calibrate_streams(sc.robot_times, sc.flange2base, sc.camera_times, sc.target2cam, "eye_in_hand")
    >>> bool(abs(cal.time_offset - 0.040) < 0.005)
    True
    """
    opts = options_from(options, changes).for_poses()
    setup = check_setup(setup)
    robot = check_stream(t_robot, flange2base, "robot stream")
    camera = check_stream(t_cam, target2cam, "camera stream")
    sync = synchronise(robot, camera, setup, opts.offset_range, opts.time_offset, opts.keyframes)
    kf, f2b, n_candidates = keyframes_at(robot, camera, sync.offset, opts.keyframes, setup, sync.fit)
    if robot_input is not None:  # the interpolated poses as the robot would write them (the check re-reads them)
        robot_input = robot_input.rewritten(f2b)
    cal = calibrate_poses(f2b, camera.poses[kf], setup, opts, progress=False, robot_input=robot_input,
                          names=[f"t={t:.3f}" for t in camera.times[kf]])
    return _with_sync(cal, sync, robot, camera, kf, setup,
                      f"{len(kf)} keyframes calibrated, chosen among {n_candidates} camera samples where the robot "
                      "moves slowly")


def calibrate_joint_streams(
    t_robot: ArrayLike,
    joints: ArrayLike,
    t_cam: ArrayLike,
    target2cam: ArrayLike,
    setup: str = "eye_in_hand",
    arm: str | Chain = "ur5",
    options: CalibrationOptions | None = None,
    *,
    joint_unit: str = "rad",
    **changes,
) -> Calibration:
    """:func:`calibrate_streams` with the robot recorded as joint angles: X, Z and the arm's table
    (:func:`handeye.calibrate_joints`) from a joint stream and a camera stream on separate clocks.

    The clock offset is estimated on the nominal table's flange poses (:func:`handeye.estimation.sync.synchronise`:
    an arm a few millimetres off its table does not move the offset), the keyframes are chosen
    where the arm moves slowly, the joint angles are interpolated (linearly, per joint) at their
    camera times minus the offset, and X, Z and the table are fitted to the keyframes' camera
    poses (across the viewing rays). The offset's uncertainty is added to X's covariance.

    Parameters
    ----------
    t_robot : array_like (N,)
        Stamps of the joint angles, seconds on the robot's clock, strictly increasing.
    joints : array_like (N, n)
        The joint angles the controller recorded (``joint_unit``), e.g. ``/joint_states``.
    t_cam, target2cam
        As :func:`calibrate_streams`.
    setup : {'eye_in_hand', 'eye_to_hand'}
    arm : str or Chain
        A shipped arm's name or a chain (:func:`handeye.robot.kinematics.load_arm`).
    options : CalibrationOptions, optional
        As :func:`calibrate_streams` (``keyframes``: the kinematic fit wants 30 or more; the default
        80 is fine), plus ``compliance``.
    joint_unit : {'rad', 'deg'}

    Returns
    -------
    Calibration
        As :func:`handeye.calibrate_joints` on the keyframes, with ``sync`` (the offset and its std).
    """
    opts = options_from(options, changes)
    setup = check_setup(setup)
    chain = load_arm(arm) if isinstance(arm, str) else arm
    q = joint_angles(joints, chain, joint_unit)
    robot = check_stream(t_robot, chain.forward(q), "robot stream (the nominal table's flange poses)")
    camera = check_stream(t_cam, target2cam, "camera stream")
    sync = synchronise(robot, camera, setup, opts.offset_range, opts.time_offset, opts.keyframes)
    kf, _, n_candidates = keyframes_at(robot, camera, sync.offset, opts.keyframes, setup, sync.fit)
    at = camera.times[kf] - sync.offset
    q_kf = joints_at(robot.times, q, at)
    cal = calibrate_joints(q_kf, camera.poses[kf], setup, chain, opts.replace(offset_range=None, time_offset=None))
    return _with_sync(cal, sync, robot, camera, kf, setup,
                      f"{len(kf)} keyframes calibrated with the arm's table, chosen among {n_candidates} camera samples "
                      "where the arm moves slowly; their joint angles interpolated at the camera times minus the offset")


def _with_sync(cal: Calibration, sync, robot, camera, kf, setup: str, done: str) -> Calibration:
    """``cal`` (on the keyframes ``kf`` of ``camera``) judged with the clock offset ``sync``: its std
    added to X's, the synchronisation's notes, ``done``, and the keyframes left out as outliers."""
    notes = list(sync.notes) + [done]
    if cal.diagnostics is not None and cal.diagnostics.outliers:
        left = [f"{camera.times[kf][i]:.3f} s" for i in cal.diagnostics.outliers]
        notes.append(f"keyframes left out as outliers (camera times): {summarize(left)}")
    if sync.offset_std > 0 and cal.cov is not None and np.isfinite(cal.cov).all():
        used = kf[cal.pose_indices]
        cov = cal.cov + offset_cov(cal.X, cal.Z, setup, robot, camera.times[used], camera.poses[used], sync.offset,
                                   sync.offset_std)
        cal = replace(cal, cov=cov, std=std_deg_mm(cov))
    return judged(replace(cal, sync=StreamSync(sync.offset, sync.offset_std, sync.info(robot, camera, camera.times[kf])),
                          notes=notes + list(cal.notes)))


def paired_delay_note(paired_delays: ArrayLike | None, offset: float, offset_std: float) -> str | None:
    """A warning when rows paired by id (``paired_delays``: per pair, camera time minus robot time)
    disagree with the clock offset the data show: each pair then matches a view with where the
    robot was ``offset - delay`` earlier or later. None when they agree (within 3 std, or 1 ms)."""
    if paired_delays is None or len(paired_delays) == 0:
        return None
    delay = float(np.median(paired_delays))
    miss = offset - delay
    if abs(miss) <= max(3.0 * offset_std, 1e-3):
        return None
    return (f"the ids pair camera and robot rows {delay * 1e3:.1f} ms apart (median), but the streams show the camera "
            f"clock {offset * 1e3:.1f} +- {offset_std * 1e3:.1f} ms ahead of the robot's: paired by id, each view would "
            f"get the robot pose {abs(miss) * 1e3:.1f} ms {'after' if miss > 0 else 'before'} the one it shows; handeye "
            "paired the streams by time at the estimated offset instead")
