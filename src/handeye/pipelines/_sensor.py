"""What the pipelines of sensor models share: the options they use and those they refuse, the robot model."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from .._shared.progress import Progress
from .._shared.text import summarize
from .._shared.threads import one_blas_thread
from ..errors import InputMismatchError
from ..estimation.core import estimate
from ..estimation.readings import Reading, check_readings
from ..frames.poses import RobotPoseInput
from ..frames.setups import setup_info
from ..options import CalibrationOptions, options_from
from ..result import Calibration
from ..robot.models import ControllerPoses, JointAngles, RobotModel
from ..sensors.base import SensorModel
from ..sensors.camera.pnp import LabelledViews

__all__ = ["sensor_options", "robot_model", "session_robot_input", "why_skipped", "held_and_freed", "estimate_checked",
           "measure_views"]

Measured = TypeVar("Measured")

#: The options of image and pose sessions that a sensor model's fit has no use for.
IMAGE_ONLY = ("method", "refine", "pairs", "known", "robot_noise", "compliance", "strict_images", "keyframes",
              "offset_range", "time_offset")
#: The options a sensor whose robot may be joint angles through the arm's table takes as well.
TABLE_OPTIONS = ("compliance",)


def why_skipped(exc: Exception, path: object) -> str:
    """Why a view is skipped, from the error its file gave, without the file's path in front (the
    skip names the view)."""
    text = str(exc)
    return text[len(str(path)) + 2:] if text.startswith(f"{path}: ") else text


def measure_views(measure: Callable[[int], Measured], names: Sequence[str], refused: tuple[type[Exception], ...], what: str,
                  progress: bool = False, jobs: int | None = None, *, views: Sequence[int] | None = None,
                  bar: Progress | None = None) -> tuple[list[int], list[Measured], list[tuple[str, str]]]:
    """Every view ``k`` of ``names`` (or of ``views``, those indices into it) measured by ``measure(k)``, ``jobs``
    views at a time (threads, default 2, each on one BLAS thread), in that order, with a progress bar saying
    ``what`` (or ``bar``, a bar of the caller's, updated and left open): the views measured (their indices) and what
    each gave, and the views skipped, each named with why (the message of an error of ``refused`` that its
    measurement raised; any other error propagates)."""
    def attempt(k: int) -> Measured | str:
        try:
            return measure(k)
        except refused as exc:
            return str(exc)

    order = list(range(len(names))) if views is None else [int(k) for k in views]
    index: list[int] = []
    measured: list[Measured] = []
    skipped: list[tuple[str, str]] = []
    shown = Progress(len(order), what, progress) if bar is None else bar
    with ThreadPoolExecutor(max_workers=max(1, jobs or 2)) as pool, one_blas_thread():
        for k, result in zip(order, pool.map(attempt, order)):
            shown.update()
            if isinstance(result, str):
                skipped.append((names[k], result))
            else:
                index.append(k)
                measured.append(result)
    if bar is None:
        shown.close()
    return index, measured, skipped


def _given(value: Any, default: Any) -> bool:
    """Whether an option was given other than its default (an empty mapping counts as none)."""
    if value is None or (isinstance(value, dict) and not value):
        return default is not None and not (isinstance(default, dict) and not default)
    if isinstance(value, (str, bool, int, float, tuple)):
        return value != default
    return True


def sensor_options(options: CalibrationOptions | None, changes: dict, what: str, table: bool = False) -> CalibrationOptions:
    """The options of a sensor model's calibration (``robot_accuracy``, ``folds``, ``arm``; with
    ``table``, a sensor whose joint angles fit the arm's table, ``compliance`` too), refusing by name
    those that only image and pose sessions use when they are given (``what``: the session in
    words, for the message)."""
    opts = options_from(options, changes)
    default = CalibrationOptions()
    unused = [name for name in IMAGE_ONLY if _given(getattr(opts, name), getattr(default, name))
              and not (table and name in TABLE_OPTIONS)]
    unused += [] if opts.check else ["check"]
    if unused:
        flags = ", ".join(f"{name} (--{name.replace('_', '-')})" for name in unused)
        raise InputMismatchError(f"{flags}: options of image and pose sessions; {what}'s fit has no use for them (leave "
                                 "them out)")
    return opts


def label_notes(target_type: str, n_symmetries: int, setup: str, names: list[str], labelled: LabelledViews) -> list[str]:
    """What the labelling of a symmetric target's views (``labelled``, :func:`~handeye.sensors.camera.pnp.labelled_by_robot`)
    leaves to say: that Z is fixed only up to the board's symmetry, and the views ``names`` whose labelling is
    in doubt or matches no robot motion."""
    notes = []
    if n_symmetries > 1:  # X is fixed by the labelling; Z only up to the board's symmetry (issue 60, item 8)
        notes.append(f"the {target_type} target looks the same turned a half turn about its centre: its corners are "
                     "labelled so that the camera's motion agrees with the robot's, which fixes X; Z "
                     f"({setup_info(setup).z_name}) is the board's frame so labelled, which may be the printed "
                     "board's turned a half turn about its normal (compare Z with a measured one up to that turn; a board "
                     "that cannot be read from the wrong end, such as ChArUco, fixes Z too)")
    if labelled.unmatched.any():  # flagged, not dropped: the check and the robust fits judge them
        notes.append(f"image(s) {summarize(names[k] for k in np.flatnonzero(labelled.unmatched))}: no "
                     f"labelling of the symmetric {target_type} target makes the camera's motion agree with the robot's "
                     "(a misdetected grid, or a wrong robot pose): check them; a board that cannot be read from the wrong "
                     "end avoids the first")
    if labelled.unsure.any():  # flagged, not dropped: the check and the robust fits judge them
        notes.append(f"image(s) {summarize(names[k] for k in np.flatnonzero(labelled.unsure))}: the "
                     f"symmetric {target_type} target reads almost as well turned about its centre, so which end is which was "
                     "decided by a thin margin from the robot motion; a board that cannot be read from the wrong end "
                     "(ChArUco, a marker grid, asymmetric circles: handeye target) removes the doubt")
    return notes


def robot_model(session: Any, index: list[int], options: CalibrationOptions) -> RobotModel:
    """The robot side of a sensor session's (depth, laser, rig: its ``flange2base``, ``joints``,
    ``arm``) views ``index``: joint angles through the arm's table when the session has them (each
    joint's compliance fitted too with ``options.compliance``), else the controller's poses with the
    robot's stated accuracy (``options.robot_accuracy``). Raises InputMismatchError for a compliance
    without joint angles."""
    if session.joints is not None:
        return JointAngles(session.arm, session.joints[index], compliance=options.compliance)
    if options.compliance:
        raise InputMismatchError(f"{session.folder}: compliance=True (--compliance) fits the joints' compliance from joint "
                                 "angles with the arm's table; the session has none (a joints: table in session.yaml): "
                                 "leave compliance out")
    return ControllerPoses(session.flange2base[index], options.robot_accuracy)


def held_and_freed(session: Any, options: CalibrationOptions) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The sensor's unknowns to hold and to free: session.yaml's ``unknowns:`` (``session.unknowns``),
    overridden by the options' ``hold`` and ``free`` (the command line's ``--hold``, ``--free``)."""
    modes = dict(getattr(session, "unknowns", {}) or {})
    modes |= {name: "hold" for name in options.hold} | {name: "free" for name in options.free}
    return (tuple(n for n, m in modes.items() if m == "hold"), tuple(n for n, m in modes.items() if m == "free"))


def estimate_checked(model: SensorModel, robot: RobotModel, session: Any, options: CalibrationOptions,
                     index: list[int] | NDArray[np.intp] | None = None,
                     rebuild: Callable[[Reading], tuple[SensorModel, RobotModel]] | None = None, **kw: Any) -> Calibration:
    """The core's fit of a sensor session (:func:`~handeye.estimation.core.estimate`), after the robot
    poses as declared are checked against the other readings of them on a cheap start
    (:func:`~handeye.estimation.readings.check_readings`: a wrong Euler sequence, quaternion order, unit,
    inversion or setup is named before any fit), with the unknowns held and freed as the session and
    the options say (:func:`held_and_freed`). ``index``: the session's views (rows of its pose table)
    the model's views are (default all)."""
    start = check_readings(model, robot, session.pose_input, session.flange2base, None if index is None else np.asarray(index),
                           rebuild)
    hold, free = held_and_freed(session, options)
    return estimate(model, robot, options.folds, hold=hold, free=free, start=start, **kw)


def session_robot_input(session: Any, flange2base: NDArray[np.float64]) -> RobotPoseInput | None:
    """The flange poses a sensor's fit used (``flange2base``) as the session's pose table writes them:
    the format and units its ``poses:`` block declares (``session.pose_input``). A sensor's
    calibration carries it as an image session's does, so that result.json gives X and Z in the
    robot's own format (``robot_format``: a FANUC's x, y, z, w, p, r) for every sensor. None when the
    session gives joint angles alone (no pose format declared)."""
    pose_input = getattr(session, "pose_input", None)
    return None if pose_input is None else pose_input.rewritten(flange2base)

