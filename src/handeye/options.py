"""How to calibrate, as one record: :class:`CalibrationOptions`.

Every pipeline (:func:`handeye.calibrate`, :func:`handeye.calibrate_poses`,
:func:`handeye.calibrate_streams`, ``check``, ``fleet``, ``acquire``) takes its options from one
validated, keyword-only record, so that an option is spelled, defaulted and checked in one place,
and ``check`` judges the data with exactly the options ``calibrate`` would use.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .errors import InputMismatchError
from .solvers import get

__all__ = ["CalibrationOptions", "FIELDS", "KEYFRAMES", "PAIRS", "REFINES", "REFINES_POSES", "ROBOT_ACCURACY", "options_from"]

#: The robot's absolute accuracy assumed by default, per axis (deg, mm): a constant error of the robot
#: poses moves X by as much, and no data can see it (it is absorbed into X).
ROBOT_ACCURACY = (0.03, 0.3)
#: Keyframes calibrated by default from a camera stream: well spread, where the robot moves slowly.
KEYFRAMES = 80
#: ``refine`` on a session with images, and on poses alone (the pixel refinement needs detections).
REFINES = ("auto", "reprojection", "pose", "none")
REFINES_POSES = ("auto", "pose", "none")
#: ``pairs`` by name (an explicit (K, 2) array of pose indices is accepted too).
PAIRS = ("auto", "all", "consecutive")


def _pair(value, name: str, positive: bool) -> tuple[float, float] | None:
    """Two finite numbers (deg, mm), non-negative (or positive), or None."""
    if value is None:
        return None
    try:
        deg, mm = (float(v) for v in value)
    except (TypeError, ValueError):
        raise InputMismatchError(f"{name} {value!r}: give (degrees, millimetres)") from None
    ok = (deg > 0 and mm > 0) if positive else (deg >= 0 and mm >= 0)
    if not (ok and np.isfinite(deg) and np.isfinite(mm)):
        kind = "positive standard deviations" if positive else "non-negative accuracies"
        raise InputMismatchError(f"{name} ({deg:g}, {mm:g}): give {kind} (deg, mm)")
    return deg, mm


@dataclass(frozen=True, kw_only=True)
class CalibrationOptions:
    """The options of a calibration, checked once when the record is made.

    Attributes
    ----------
    method : str
        A solver from ``handeye.solvers.available()`` (the closed form the refinements start from).
    refine : {'auto', 'reprojection', 'pose', 'none'}
        The estimator (:func:`handeye.calibrate`); poses alone take 'auto', 'pose' or 'none'.
    pairs : {'auto', 'all', 'consecutive'} or (K, 2) array
        The pose pairs of the motions.
    check : bool
        Diagnose the data first (outliers left out, the verdict and its advice).
    strict : bool
        Raise instead of answering data the check calls inconsistent.
    folds : int, optional
        Cross-validation folds of ``refine='auto'`` (default: one per view up to 10, else 5).
    robot_accuracy : (deg, mm) or None
        The robot's absolute accuracy per axis, added to X's covariance; zeros or None: exact.
    robot_noise : (deg, mm), optional
        The robot's pose error std for the pixel refinement with robot pose corrections.
    known : dict, optional
        Translation components of X or Z the data cannot determine (:mod:`handeye.estimation.partial`).
    keyframes, offset_range, time_offset
        Streams on two clocks (:func:`handeye.calibrate_streams`).
    strict_images : bool
        A missing or unreadable image is an error; by default it is skipped with the reason.
    arm : str, optional
        The arm's kinematics for a session with a ``joints:`` table, instead of the one session.yaml
        names: a shipped arm's name, a DH table (``.yaml``) or a URDF (``.urdf``; its chain from
        ``base_link``/``world`` to ``tool0``/``flange``); files relative to the current folder. Joint
        angles only: poses alone, and sessions without joints, refuse it.
    compliance : bool
        With joint angles: fit each joint's compliance with the arm's table (its deflection per metre
        of the moment arm of the flange's load, :meth:`handeye.robot.kinematics.Chain.moment_arms`). Joint
        angles only, as ``arm``.
    hold, free : tuple of str
        A sensor's unknowns beside X, by name (``depth_scale``, ``depth_bias``, ``radius``, ``focal``,
        ...: :class:`~handeye.sensors.base.Nuisance`), to hold at their nominal or given value, or to
        fit whatever the capture; the others are fitted where the capture determines them. Sensor
        sessions only (not images or poses alone); over session.yaml's ``unknowns:``.
    """

    method: str = "daniilidis"
    refine: str = "auto"
    pairs: Any = "auto"
    check: bool = True
    strict: bool = False
    folds: int | None = None
    robot_accuracy: tuple[float, float] | None = ROBOT_ACCURACY
    robot_noise: tuple[float, float] | None = None
    known: dict | None = None
    keyframes: int = KEYFRAMES
    offset_range: tuple[float, float] | None = None
    time_offset: float | None = None
    strict_images: bool = False
    arm: str | None = None
    compliance: bool = False
    hold: tuple[str, ...] = ()
    free: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        get(self.method)  # an unknown name: the registry's error lists the valid ones
        if self.refine not in REFINES:
            raise InputMismatchError(f"refine={self.refine!r}; use {_either(REFINES)}")
        if isinstance(self.pairs, str) and self.pairs not in PAIRS:
            raise InputMismatchError(f"unknown pairs strategy {self.pairs!r}; use {', '.join(repr(p) for p in PAIRS)} "
                                     "or a (K, 2) array of pose indices")
        for name in ("check", "strict", "strict_images", "compliance"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise InputMismatchError(f"{name}={getattr(self, name)!r}; give True or False")
        if self.folds is not None and (not _whole(self.folds) or self.folds < 2):
            raise InputMismatchError(f"folds={self.folds!r}; give a whole number of at least 2 (or None)")
        if not _whole(self.keyframes) or self.keyframes < 3:
            raise InputMismatchError(f"keyframes={self.keyframes!r}; give a whole number of at least 3")
        accuracy = _pair(self.robot_accuracy, "robot_accuracy", positive=False)
        object.__setattr__(self, "robot_accuracy", None if accuracy is None or accuracy == (0.0, 0.0) else accuracy)
        object.__setattr__(self, "robot_noise", _pair(self.robot_noise, "robot_noise", positive=True))
        if self.robot_noise is not None and self.refine not in ("auto", "reprojection"):
            raise InputMismatchError(f"robot_noise is used by the pixel refinement; refine={self.refine!r} would "
                                     "ignore it (use refine='auto' or 'reprojection', or leave robot_noise out)")
        if self.arm is not None and (not isinstance(self.arm, str) or not self.arm.strip()):
            raise InputMismatchError(f"arm={self.arm!r}; give a shipped arm's name, a DH table (.yaml) or a URDF (.urdf)")
        for name in ("hold", "free"):
            value = getattr(self, name)
            names = (value,) if isinstance(value, str) else value
            if not isinstance(names, (tuple, list)) or not all(isinstance(n, str) and n for n in names):
                raise InputMismatchError(f"{name}={value!r}; give the unknowns' names, e.g. ('depth_scale', 'depth_bias')")
            object.__setattr__(self, name, tuple(names))
        if set(self.hold) & set(self.free):
            raise InputMismatchError(f"{', '.join(sorted(set(self.hold) & set(self.free)))}: both held and freed; say one")
        if self.known is not None and not isinstance(self.known, dict):
            raise InputMismatchError(f"known={self.known!r}; give a dict such as {{'target2base.z': 0.012}}")
        if self.offset_range is not None:
            try:
                lo, hi = (float(v) for v in self.offset_range)
            except (TypeError, ValueError):
                raise InputMismatchError(f"offset_range {self.offset_range!r}: give (low, high) seconds") from None
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise InputMismatchError(f"offset_range ({lo:g}, {hi:g}): give finite seconds with low < high")
            object.__setattr__(self, "offset_range", (lo, hi))
        if self.time_offset is not None:
            try:
                offset = float(self.time_offset)
            except (TypeError, ValueError):
                raise InputMismatchError(f"time_offset {self.time_offset!r}: give seconds") from None
            if not np.isfinite(offset):
                raise InputMismatchError(f"time_offset {offset!r}: give finite seconds")
            object.__setattr__(self, "time_offset", offset)

    def replace(self, **changes: Any) -> "CalibrationOptions":
        """A copy with ``changes``, checked again."""
        return replace(self, **changes)

    def for_images(self) -> "CalibrationOptions":
        """The options checked for a camera's images or poses: ``hold`` and ``free`` name a sensor's
        unknowns beside X, which a camera's fit does not have."""
        given = [f"{name}={getattr(self, name)!r}" for name in ("hold", "free") if getattr(self, name)]
        if given:
            raise InputMismatchError(f"{', '.join(given)}: a camera's images and poses have no unknowns beside X and the "
                                     "target to hold or free (depth cameras, laser profilers and line-scan cameras do); "
                                     "leave them out")
        return self

    def for_poses(self) -> "CalibrationOptions":
        """The options checked for poses alone (no images): 'reprojection' and ``robot_noise`` need
        the detections."""
        self.for_images()
        if self.refine not in REFINES_POSES:
            raise InputMismatchError(f"refine={self.refine!r}; use 'auto', 'pose' or 'none' (pixel refinement needs "
                                     "the detections: use handeye.calibrate on a session)")
        if self.arm is not None:
            raise InputMismatchError(f"arm={self.arm!r} gives the kinematics of joint angles; poses alone have none "
                                     "(give a session with a joints: table, or leave arm out)")
        if self.compliance:
            raise InputMismatchError("compliance=True fits the joints' compliance from joint angles; poses alone have "
                                     "none (give a session with a joints: table, or leave compliance out)")
        if self.robot_noise is not None:  # else dropped without a word
            raise InputMismatchError("robot_noise is used by the pixel refinement, which needs the detections: use "
                                     "handeye.calibrate on a session, or leave robot_noise out (the pose refinement "
                                     "estimates the robot's noise from the poses)")
        return self


def _either(names) -> str:
    """'a', 'b' or 'c'."""
    quoted = [repr(n) for n in names]
    return ", ".join(quoted[:-1]) + " or " + quoted[-1]


def _whole(value) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


#: The option names, for the errors that list them.
FIELDS = tuple(CalibrationOptions.__dataclass_fields__)


def options_from(options: CalibrationOptions | None = None, changes: dict[str, Any] | None = None) -> CalibrationOptions:
    """``options`` (default: :class:`CalibrationOptions()`) with the keyword ``changes`` a pipeline
    was called with; an unknown name or a record of another type is a clear error."""
    base = CalibrationOptions() if options is None else options
    if not isinstance(base, CalibrationOptions):
        raise InputMismatchError(f"options={options!r}: give a handeye.CalibrationOptions (or the options as "
                                 f"keywords: {', '.join(FIELDS)})")
    changes = changes or {}
    unknown = sorted(set(changes) - set(FIELDS))
    if unknown:
        raise InputMismatchError(f"unknown option(s) {', '.join(unknown)}; the options are: {', '.join(FIELDS)}")
    return replace(base, **changes) if changes else base
