"""Calibration targets: their object points (metres) and how each finds itself in an image.

Target frame (OpenCV's convention): origin at the first feature, x along a row (``cols``), y along
a column (``rows``), z = x cross y, pointing away from the side the pattern is printed on (a camera
that sees the pattern looks along +z).

=====================  ====================================================================
type                   features
=====================  ====================================================================
chessboard             inner corners, ``cols`` x ``rows``; ``square`` = square side
charuco                chessboard corners between markers; ``cols`` x ``rows`` squares,
                       ``square``, ``marker``, ``dictionary``
circles                symmetric circle grid, ``cols`` x ``rows`` centres, ``square`` = spacing
modified_circles       ROS-Industrial's modified circle grid: ``circles`` with the corner circle
                       drawn large, the origin (one reading, no symmetry)
asymmetric_circles     OpenCV's asymmetric grid, ``cols`` per row, ``rows`` rows, ``square`` =
                       the spacing of OpenCV's pattern unit (centres at ((2j + i % 2) s, i s))
apriltag               one tag (AprilTag 36h11 unless ``dictionary`` says otherwise), its four
                       corners; ``square`` = tag side (outer black border), ``id`` optional
aruco_grid             a grid of ``cols`` x ``rows`` markers (OpenCV's GridBoard: ids 0.. row by
                       row from the top left), their corners; ``square`` = marker side,
                       ``separation`` = the gap between markers, ``dictionary`` (an AprilTag
                       family makes an AprilTag grid); no symmetry: every marker is unique
=====================  ====================================================================

Each type is one class in its own module implementing the :class:`~handeye.sensors.camera.targets.base.Target`
protocol (spec, detect, render, print, frame); :func:`register_target` makes it known to
session.yaml, the simulator, the renderer and ``handeye target``. A new type is one new module and
one call of :func:`register_target`.

``detect`` returns a :class:`Detection` (feature ids, subpixel image points, object points) or
None when the target is not found. Works with OpenCV 4.x (>= 4.7, the aruco detector API) and 5.x.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...._shared.text import shown
from ....errors import TargetError
from .apriltag import AprilTag
from .aruco_grid import ArucoGrid
from .base import Detection, Target, Texture, aruco_dictionary
from .charuco import Charuco
from .chessboard import PYRAMID_MIN_SIDE, Chessboard
from .circles import CircleGrid
from .modified_circles import ModifiedCircleGrid

__all__ = ["Detection", "Target", "Texture", "Chessboard", "Charuco", "CircleGrid", "ModifiedCircleGrid", "AprilTag", "ArucoGrid",
           "target_from_spec", "target_origin", "register_target", "unregister_target", "target_types", "print_kinds",
           "aruco_dictionary",
           "ORIGINS", "PYRAMID_MIN_SIDE", "TargetError"]

#: session.yaml type -> the class that reads it
_REGISTRY: dict[str, type[Target]] = {}


def register_target(cls: type[Target]) -> type[Target]:
    """Make a :class:`Target` class known by its ``spec_types()`` (usable as a class decorator).

    Raises
    ------
    TargetError
        The class does not implement the protocol, or one of its types is taken by another class.
    """
    missing = [m for m in ("object_points", "detect", "texture", "print_shapes")
               if getattr(cls, m, None) is getattr(Target, m)]
    if not (isinstance(cls, type) and issubclass(cls, Target)) or missing or not cls.type or not cls.frame:
        raise TargetError(f"{getattr(cls, '__name__', cls)!r} is not a target type: subclass Target, set type and frame, "
                          f"and implement {', '.join(missing) or 'its methods'}")
    for kind in cls.spec_types():
        if _REGISTRY.get(kind, cls) is not cls:
            raise TargetError(f"target type {shown(kind)} is taken by {_REGISTRY[kind].__name__}")
        _REGISTRY[kind] = cls
    return cls


def unregister_target(cls: type[Target]) -> None:
    """Forget a class registered by :func:`register_target` (a plug-in's tests clean up with it)."""
    for kind in cls.spec_types():
        if _REGISTRY.get(kind) is cls:
            del _REGISTRY[kind]


for _cls in (Chessboard, Charuco, CircleGrid, ModifiedCircleGrid, AprilTag, ArucoGrid):
    register_target(_cls)


def target_types() -> tuple[str, ...]:
    """The session.yaml target types known now, in the order they were registered."""
    return tuple(_REGISTRY)


def print_kinds() -> dict[str, tuple[str, dict[str, Any]]]:
    """``handeye target --type`` name -> (session.yaml type, default sizes in mm and counts), of
    every registered class."""
    out: dict[str, tuple[str, dict[str, Any]]] = {}
    for cls in dict.fromkeys(_REGISTRY.values()):
        out.update(cls.print_kinds)
    return out


#: Where a target frame's origin can be: handeye's (each type's ``frame``), or the target's centre
#: (ViSP's and the AprilTag library's convention), the same axes.
ORIGINS = ("corner", "centre")


def target_origin(spec: dict[str, Any], where: str = "target") -> NDArray[np.float64]:
    """The origin of the target frame that ``spec`` asks for (``origin: corner``, the default, or
    ``origin: centre``), as a point of the type's own frame (:attr:`Target.frame`): zeros, or the
    centre of the features' bounding box (of the board, for every type handeye prints)."""
    pts = target_from_spec(spec, where).object_points()  # checks the origin's name too
    if spec.get("origin", "corner") == "corner":
        return np.zeros(3)
    return 0.5 * (pts.min(axis=0) + pts.max(axis=0))


def target_from_spec(spec: dict[str, Any], where: str = "target") -> Target:
    """A :class:`Target` from the ``target:`` mapping of session.yaml (the session format in docs/guide.md); ``origin`` is
    checked and left to :func:`target_origin` (the target classes stay in their own frame)."""
    if not isinstance(spec, dict):
        raise TargetError(f"{where}: expected a mapping with type, cols, rows, square")
    if spec.get("origin", "corner") not in ORIGINS + ("center",):
        raise TargetError(f"{where}: origin {shown(spec.get('origin'))}; use 'corner' (the default) or 'centre'")
    cls = _REGISTRY.get(str(spec.get("type")))
    if cls is None:
        raise TargetError(f"{where}: unknown target type {shown(spec.get('type'))}; use one of {', '.join(_REGISTRY)}")
    try:
        return cls.from_spec(spec)
    except (TypeError, ValueError, TargetError) as exc:  # the size checks of the target classes: say where
        raise TargetError(f"{where}: {exc}") from None
