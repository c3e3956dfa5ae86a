"""The sensor kinds, each one registration: what ``calibrate``, ``check``, a rig, ``simulate`` and ``plan``
look up instead of switching on a kind's names.

A kind of sensor is two folders: ``sensors/<kind>/`` holds its mathematics (what one view measures,
its sensor model), ``pipelines/<kind>/`` everything else (``session.py``: its session.yaml section read
and checked; ``pipeline.py``: each view measured, then the estimation core; ``simulate.py``: its captures
with ground truth; ``plan.py``: poses to capture, with the std they would give). Its one registration is
a :class:`SensorKind` made known by :func:`register_kind` (the built-in kinds' at the end of this module):
its section name in session.yaml, its name on the command line, its name for people, and its hooks,
named as ``"module:function"`` inside its folder and imported on first use (a camera's session does not
pay for the laser's imports; this module imports no kind's).

The camera (images, pose pairs, joint angles, streams) is the kind every other one builds on: its
pipelines are this folder's modules and ``simulate`` and ``plan`` take it by default; it is not registered.

Examples
--------
>>> from handeye.pipelines.kinds import kind_named, session_kind
>>> kind = kind_named("laser_line")
>>> kind.section, kind.display
('laser', 'laser line profiler')
>>> session_kind({"setup": "eye_in_hand", "laser": {"unit": "mm"}}) is kind
True
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ..errors import HandEyeError

if TYPE_CHECKING:  # the registry imports nothing heavy: the command line reads every kind's registration
    import numpy as np
    from numpy.typing import NDArray

    from ..result import Calibration

__all__ = ["SensorKind", "KindOption", "SimulateRequest", "PlanRequest", "SensorPlan", "register_kind", "unregister_kind",
           "sensor_kinds", "kind_named", "session_kind", "member_kind", "kind_of_model", "kinds_of_target", "joins_sensors",
           "importer_of"]


@dataclass(frozen=True)
class KindOption:
    """A command-line option of one kind's own (``plan --diameter``, ``simulate --cameras``), added to
    ``command``'s parser for it: ``type`` is ``"flag"`` (on or off), ``"number"`` (in ``[low, high]``,
    ``(low, high]`` when ``above``), ``"whole"`` (>= ``low``), ``"text"`` or ``"texts"`` (given once per
    value, a list); given with another ``--sensor``, the command refuses it, naming the kind it belongs
    to, unless it ``chooses`` its kind when no ``--sensor`` is given (``plan --rig-camera``: a rig)."""

    command: str
    flag: str
    help: str
    type: str = "text"
    low: float = 0.0
    high: float = float("inf")
    above: bool = False
    metavar: str | None = None
    chooses: bool = False

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
    imports : tuple of (str, str)
        ``(source, "module:function")``: ``handeye import <source>``, another tool's capture written as a
        session of this kind; ``function(folder, out, **options) -> ImportSummary`` (:func:`importer_of`).
    several : bool
        Its result is several sensors' one fit (a rig's), with the figures a rig's model gives them
        (:mod:`handeye.sensors.rig`: ``X_per_sensor``, ``relative``, ``alone``, ...): the report draws
        every sensor and writes their frames (``rig_static_tf.launch.py``), the terminal prints each
        one's X (:func:`joins_sensors`).
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
    imports: tuple[tuple[str, str], ...] = ()
    several: bool = False

    def hook(self, name: str) -> Callable[..., Any]:
        """The function of hook ``name`` (``"calibrate"``, ``"simulate"``, ...), imported on first use.

        Raises
        ------
        HandEyeError
            The kind has no such hook (a laser has no ``rig_extras``).
        """
        where = getattr(self, name, None)
        if not isinstance(where, str) or ":" not in where:
            raise HandEyeError(f"a {self.display} has no {name} (its registration names none)")
        return self._imported(where)

    def _imported(self, where: str) -> Callable[..., Any]:
        """The function ``"module:function"`` of this kind's folder, imported."""
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
    ``X`` and the target's ``Z`` (metres), the command's arguments (``intrinsics``: a camera's YAML,
    ``tilt_max_deg``, ``margin_px``: a board's views), its own options in ``options``."""

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
    intrinsics: str | None = None
    tilt_max_deg: float = 45.0
    margin_px: float = 20.0


@dataclass(frozen=True)
class SensorPlan:
    """A kind's plan as ``handeye plan`` writes and prints it: ``flange2base`` per row ``names`` (the
    table's first column ``id_column``), ``heading`` above them, then X's predicted std from ``plan``
    (its ``std_X``, ``std_data``, ``std_narrow`` and ``robot_accuracy``) in the words ``label`` (a
    row), ``accuracy`` (what the robot's accuracy is in it), ``per`` (the data alone), ``narrow`` (the
    narrow capture it is compared with), ``undetermined`` (said when that cannot determine X) and
    ``why`` (what the plan's spread buys); ``written``: what the file is, after its name. A plan with
    ``lines`` (a rig's: each camera's std) prints them instead of X's std."""

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
    lines: tuple[str, ...] = ()


_KINDS: dict[str, SensorKind] = {}


def register_kind(kind: SensorKind) -> SensorKind:
    """Make ``kind`` known to ``calibrate``, ``check``, rigs, ``simulate`` and ``plan``.

    Raises
    ------
    HandEyeError
        Its section, command-line or display name is another kind's.
    """
    for other in _KINDS.values():
        if other.package != kind.package and {other.section, other.cli, other.display} & {kind.section, kind.cli, kind.display}:
            raise HandEyeError(f"sensor kind {kind.package}: a name of it is {other.package}'s")
    _KINDS[kind.package] = kind
    return kind


def unregister_kind(kind: SensorKind) -> None:
    """Forget a kind registered by :func:`register_kind` (a plug-in's tests clean up with it)."""
    _KINDS.pop(kind.package, None)


def sensor_kinds() -> tuple[SensorKind, ...]:
    """Every registered kind, in the order they were registered (the order sessions are told apart in)."""
    return tuple(_KINDS.values())


def kind_named(cli: str) -> SensorKind:
    """The kind whose command-line name is ``cli``.

    Raises
    ------
    HandEyeError
        None is (the names there are listed).
    """
    for kind in _KINDS.values():
        if kind.cli == cli:
            return kind
    raise HandEyeError(f"--sensor {cli}: unknown; give one of camera, {', '.join(k.cli for k in _KINDS.values())}")


def session_kind(spec: dict[str, Any]) -> SensorKind | None:
    """The kind of a session from its session.yaml ``spec``: the first kind whose section it has (not
    null); None for a camera's session (images, with or without joint angles)."""
    return next((k for k in _KINDS.values() if spec.get(k.section) is not None), None)


def member_kind(block: dict[str, Any]) -> SensorKind | None:
    """The kind of a rig's sensor from its block under ``sensors:``: the first kind that can be a rig's
    sensor whose section the block has; None for a camera."""
    return next((k for k in _KINDS.values() if k.rig_member is not None and k.section in block), None)


def kind_of_model(display: str | None) -> SensorKind | None:
    """The kind whose sensor models call themselves ``display`` (a result's ``sensor.kind``); None for a camera's."""
    return next((k for k in _KINDS.values() if k.display == display), None)


def importer_of(source: str) -> Callable[..., Any] | None:
    """The function that writes another tool's capture ``source`` (``handeye import <source>``:
    ``robcalibrator``) as a session of the kind whose registration :attr:`~SensorKind.imports` it; None
    when no kind does (a camera's sources: :mod:`handeye.io.importers`)."""
    kind, where = next(((k, w) for k in _KINDS.values() for s, w in k.imports if s == source), (None, ""))
    return None if kind is None else kind._imported(where)


def joins_sensors(calibration: Calibration) -> bool:
    """Whether ``calibration`` is several sensors' one fit (a rig's): its sensor's kind (a result's
    ``sensor.kind``, the display name) is registered :attr:`~SensorKind.several`."""
    kind = None if calibration.sensor is None else kind_of_model(calibration.sensor.sensor)
    return kind is not None and kind.several


def kinds_of_target(target: str | None) -> tuple[SensorKind, ...]:
    """The kinds whose own ``--target`` name ``target`` is (``plane``: a laser's; ``sphere``: a depth
    camera's and a laser's); none for a board."""
    return tuple(k for k in _KINDS.values() if target in k.targets)


# The built-in kinds, in the order a session is told apart by its section (a depth camera's ``depth:``
# first). Each is its registration: its names, its hooks in its folder (pipelines/<kind>/), its options.
register_kind(SensorKind(
    section="depth", cli="depth", display="depth camera", package="handeye.pipelines.depth",
    calibrate="pipeline:calibrate_depth_session", extras="session:extras", rig_member="pipeline:rig_member",
    rig_extras="session:rig_extras", simulate="simulate:simulate_command",
    targets=("mesh", "sphere", "arm", "scene"),
    simulate_help="a depth camera's 640x480 clouds of a mesh (--target mesh, the default: a flange-sized disc on the "
    "flange), a ball (sphere), a board, the arm itself (arm: markerless, its joint angles, always eye_to_hand; --arm "
    "panda, the arm with meshes) or an irregular object (scene: no target and no mesh given, X from the clouds' agreement)",
))
register_kind(SensorKind(
    section="laser", cli="laser_line", display="laser line profiler", package="handeye.pipelines.laser",
    calibrate="pipeline:calibrate_laser_session", rig_member="pipeline:rig_member",
    simulate="simulate:simulate_command", plan="plan:plan_command", imports=(("robcalibrator", "importers:import_robcalibrator"),),
    targets=("sphere", "plane", "edge", "step", "spheres"), frame="laser_profiler_optical_frame",
    simulate_help="a laser line profiler's profiles of a ball, a plate, a block's edge, a step or a fixture of balls "
    "(--target; --poses of them; --arm for joint angles)",
    plan_help="a laser line profiler's profiles of a ball (--diameter), a plate, a block's edge, a step or a fixture of "
    "balls (--target); --target-in-base is then the ball's centre (a point of the plate, of the edge's line, the first "
    "ball's centre), its rotation by default 0,0,0: the profiler looks from above",
    plan_usage="the profiler's placement (--cam-in-flange or --camera-in-base), the target's and --target "
    "sphere|plane|edge|step|spheres",
    plan_target_rotation=(0.0, 0.0, 0.0),
    options=(KindOption("plan", "--diameter", "the ball's diameter (m, default 0.04)", "number", 0.0, 1.0, above=True),),
))
register_kind(SensorKind(
    section="linescan", cli="line_scan", display="line-scan camera", package="handeye.pipelines.linescan",
    calibrate="pipeline:calibrate_linescan_session", simulate="simulate:simulate_command", plan="plan:plan_command",
    simulate_help="a line-scan camera's scans of a chessboard swept by the robot (--poses of them; --arm for joint angles)",
    plan_help="a line-scan camera's straight scans across a chessboard (--line-camera, --standoff, --speed)",
    plan_takes=("--target-spec", "--standoff"),
    plan_usage="the camera (--line-camera WIDTH,FOCAL), its placement (--cam-in-flange or --camera-in-base), the "
    "target's, --target or --target-spec, --standoff (default 0.4 m; the scans at 0.75-1.25x it) and --speed",
    options=(KindOption("plan", "--line-camera", "pixels along the line and the focal length in pixels (default 2048,2400)",
                        metavar="WIDTH,FOCAL"),
             KindOption("plan", "--speed", "the scans' speed (m/s, default 0.2)", "number", 0.0, above=True)),
))
register_kind(SensorKind(
    section="silhouette", cli="silhouette", display="colour camera", package="handeye.pipelines.silhouette",
    calibrate="pipeline:calibrate_silhouette_session", extras="session:extras", simulate="simulate:simulate_command",
    imports=(("easyhec", "importers:import_easyhec"),),
    simulate_help="a fixed colour camera's masks of a Panda (markerless, its joint angles, eye_to_hand; --poses of them)",
))
register_kind(SensorKind(
    section="sensors", cli="rig", display="rig", package="handeye.pipelines.rig",
    calibrate="pipeline:calibrate_rig_session", extras="session:extras", members="pipeline:rig_members",
    simulate="simulate:simulate_command", plan="plan:plan_command", several=True,
    simulate_help="a stereo pair on the flange (eye_in_hand) or three fixed cameras (eye_to_hand)",
    plan_help="poses in which every camera of a rig sees the whole board (--intrinsics: the first camera's; a "
    "--rig-camera per other camera), each camera's predicted std",
    plan_takes=("--intrinsics", "--target-spec", "--standoff"),
    plan_usage="--intrinsics (the first camera's), a --rig-camera per other camera, the first camera's placement "
    "(--cam-in-flange or --camera-in-base), the target's, --target or --target-spec and --standoff",
    options=(KindOption("simulate", "--cameras", "the number of cameras (default 2 on the flange, 3 fixed around the cell)",
                        "whole", 2),
             KindOption("simulate", "--laser", "a camera beside a laser profiler (a small board and a 40 mm ball) instead "
                        "of cameras", "flag"),
             KindOption("plan", "--rig-camera", "another camera of the rig: its name, its intrinsics YAML and its rough "
                        "pose in the first camera's frame (m, rotation vector in deg); once per camera: poses every "
                        "camera can use (written with a first column view, as a rig session's poses.csv); without "
                        "--sensor, it plans for a rig", "texts", metavar="NAME,INTRINSICS,X,Y,Z[,RX,RY,RZ]", chooses=True),
             KindOption("simulate", "--depth", "a camera beside a depth camera (640x480 clouds and intensity images), both "
                        "seeing the board, instead of cameras", "flag")),
))
