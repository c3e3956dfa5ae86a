"""The sensor kinds, each one registration: what ``calibrate``, ``check``, a rig, ``simulate`` and ``plan``
look up instead of switching on a kind's names.

A kind of sensor is two folders: ``sensors/<kind>/`` holds its mathematics (what one view measures,
its sensor model), ``pipelines/<kind>/`` everything else (``session.py``: its session.yaml section read
and checked; ``pipeline.py``: each view measured, then the estimation core; ``simulate.py``: its captures
with ground truth; ``plan.py``: poses to capture, with the std they would give). Its one registration is
the :class:`SensorKind` named ``KIND`` in ``pipelines/<kind>/__init__.py``, made known by
:func:`register_kind` (the built-in kinds at the end of this module): its section name in session.yaml,
its name on the command line, its name for people, and its hooks, named as ``"module:function"`` inside
its folder and imported on first use (a camera's session does not pay for the laser's imports).

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

from typing import Any

from ..errors import HandEyeError
from . import depth, laser, linescan, rig, silhouette
from .sensor_kind import KindOption, PlanRequest, SensorKind, SensorPlan, SimulateRequest

__all__ = ["SensorKind", "KindOption", "SimulateRequest", "PlanRequest", "SensorPlan", "register_kind", "unregister_kind",
           "sensor_kinds", "kind_named", "session_kind", "member_kind", "kind_of_model", "kinds_of_target"]

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


def kinds_of_target(target: str | None) -> tuple[SensorKind, ...]:
    """The kinds whose own ``--target`` name ``target`` is (``plane``: a laser's; ``sphere``: a depth
    camera's and a laser's); none for a board."""
    return tuple(k for k in _KINDS.values() if target in k.targets)


# The built-in kinds, in the order a session is told apart by its section (a depth camera's ``depth:``
# first). Their records import nothing heavy: a kind's modules load when a hook is first called.
for _kind in (depth.KIND, laser.KIND, linescan.KIND, silhouette.KIND, rig.KIND):
    register_kind(_kind)
