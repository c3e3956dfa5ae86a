"""What a sensor kind declares: its registration (:class:`SensorKind`), its own command-line options
(:class:`KindOption`), and what ``simulate`` and ``plan`` ask of it and get back (:class:`SimulateRequest`,
:class:`PlanRequest`, :class:`SensorPlan`). The registry is :mod:`handeye.pipelines.kinds`."""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ..errors import HandEyeError

if TYPE_CHECKING:  # a registration imports nothing heavy: the command line reads every kind's
    import numpy as np
    from numpy.typing import NDArray

__all__ = ["SensorKind", "KindOption", "SimulateRequest", "PlanRequest", "SensorPlan"]


@dataclass(frozen=True)
class KindOption:
    """A command-line option of one kind's own (``plan --diameter``, ``simulate --cameras``), added to
    ``command``'s parser for it: ``type`` is ``"flag"`` (on or off), ``"number"`` (in ``[low, high]``,
    ``(low, high]`` when ``above``), ``"whole"`` (>= ``low``) or ``"text"``; given with another
    ``--sensor``, the command refuses it, naming the kind it belongs to."""

    command: str
    flag: str
    help: str
    type: str = "text"
    low: float = 0.0
    high: float = float("inf")
    above: bool = False
    metavar: str | None = None

    @property
    def dest(self) -> str:
        """Its name in the parsed arguments (``--line-camera``: ``line_camera``)."""
        return self.flag.lstrip("-").replace("-", "_")


@dataclass(frozen=True)
class SensorKind:
    """One kind of sensor's registration.

    Attributes
    ----------
    section : str
        Its section in session.yaml (``laser:``): a session with it is of this kind, and so is a rig's
        sensor whose block has it.
    cli : str
        Its name on the command line (``simulate --sensor laser_line``).
    display : str
        Its name for people, the same as its sensor models' ``kind`` (``"laser line profiler"``).
    package : str
        Its folder's package (``handeye.pipelines.laser``); the hooks are named inside it.
    calibrate : str
        ``"module:function"``: ``function(folder, options, *, progress, jobs) -> Calibration``, a
        session folder of this kind calibrated (``calibrate``, ``check``, fleets).
    extras : str or None
        ``function(spec, folder, needs)``: adds to ``needs`` (extra -> {module: why}) the optional
        extras a session of this kind needs, from its session.yaml ``spec`` (:func:`handeye.pipelines.folders.session_extras`).
    rig_member : str or None
        ``function(folder, setup, names, flange2base, block, name, target, where)``: a rig's sensor of this
        kind read over the rig's views, an object with ``seen`` (per view), ``files``, ``missing`` (what a
        view it missed lacks, "profile"), ``board_images`` (intensity images of the session's board, found
        with the cameras') and ``model(names, notes, progress, detected) -> SensorModel``.
    rig_extras : str or None
        ``function(block, name, folder, needs)``: :attr:`extras` for a rig's sensor of this kind.
    members : str or None
        ``function(calibration) -> dict[str, Calibration]``: each of its sensors' own result, by name (a
        rig's), that the report writes beside the whole one (``sensors/<name>/``).
    simulate : str or None
        ``function(request: SimulateRequest) -> str``: ``handeye simulate --sensor <cli>``; returns what it wrote.
    plan : str or None
        ``function(request: PlanRequest) -> SensorPlan``: ``handeye plan --sensor <cli>``.
    targets : tuple of str
        Its own ``--target`` names (``sphere``, ``plane``, ...; the first the default), beside the boards.
    frame : str or None
        The ROS frame of its X in the exports (``laser_profiler_optical_frame``); None: a camera's.
    simulate_help, plan_help : str
        What ``--sensor <cli>`` simulates or plans, for ``--help``.
    plan_takes : tuple of str
        The options of a camera's plan it takes too (``--standoff``); ``plan_usage`` says in words what it
        takes, for the error when another is given.
    plan_target_rotation : tuple of float
        The target's rotation (a rotation vector, degrees) when ``--target-in-base`` gives none.
    options : tuple of KindOption
        Its own options.
    """

    section: str
    cli: str
    display: str
    package: str
    calibrate: str
    extras: str | None = None
    rig_member: str | None = None
    rig_extras: str | None = None
    members: str | None = None
    simulate: str | None = None
    plan: str | None = None
    targets: tuple[str, ...] = ()
    frame: str | None = None
    simulate_help: str = ""
    plan_help: str = ""
    plan_takes: tuple[str, ...] = ()
    plan_usage: str = ""
    plan_target_rotation: tuple[float, float, float] = (180.0, 0.0, 0.0)
    options: tuple[KindOption, ...] = ()

    def hook(self, name: str) -> Callable[..., Any]:
        """The function of hook ``name`` (``"calibrate"``, ``"simulate"``, ...), imported on first use.

        Raises
        ------
        HandEyeError
            The kind has no such hook (a laser has no ``rig_extras``).
        """
        where = getattr(self, name, None)
        if not isinstance(where, str) or ":" not in where:
            raise HandEyeError(f"a {self.display} has no {name} (its registration, {self.package}.KIND, names none)")
        module, _, function = where.partition(":")
        return getattr(importlib.import_module(f"{self.package}.{module}"), function)

    def options_of(self, command: str) -> tuple[KindOption, ...]:
        """Its own options of ``command`` (``"simulate"`` or ``"plan"``)."""
        return tuple(o for o in self.options if o.command == command)


@dataclass(frozen=True)
class SimulateRequest:
    """What ``handeye simulate --sensor <cli>`` asks a kind's ``simulate`` hook for: the command's
    arguments, its own options by name (:attr:`KindOption.dest`) in ``options``."""

    out: str
    setup: str
    poses: int
    seed: int | None
    target: str | None = None
    arm: str | None = None
    robot: str = "arm"
    image_size: tuple[int, int] = (640, 480)
    noise_px: float = 0.2
    options: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class PlanRequest:
    """What ``handeye plan --sensor <cli>`` asks a kind's ``plan`` hook for: the sensor's rough pose
    ``X`` and the target's ``Z`` (metres), the command's arguments, its own options in ``options``."""

    setup: str
    X: NDArray[np.float64]
    Z: NDArray[np.float64]
    poses: int | None
    seed: int
    target: str | None = None
    target_spec: dict[str, Any] | None = None
    standoff: float | None = None
    noise_px: float = 0.3
    robot_accuracy: tuple[float, float] | None = None
    options: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class SensorPlan:
    """A kind's plan as ``handeye plan`` writes and prints it: ``flange2base`` per row ``names`` (the
    table's first column ``id_column``), ``heading`` above them, then X's predicted std from ``plan``
    (its ``std_X``, ``std_data``, ``std_narrow`` and ``robot_accuracy``) in the words ``label`` (a
    row), ``accuracy`` (what the robot's accuracy is in it), ``per`` (the data alone), ``narrow`` (the
    narrow capture it is compared with), ``undetermined`` (said when that cannot determine X) and
    ``why`` (what the plan's spread buys); ``written``: what the file is, after its name."""

    names: list[str]
    flange2base: NDArray[np.float64]
    id_column: str
    plan: Any
    heading: str
    label: str
    accuracy: str
    per: str
    narrow: str
    undetermined: str
    why: str
    written: str
