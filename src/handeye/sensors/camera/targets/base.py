"""What every calibration target is: the :class:`Target` protocol, and what the types share.

A target type is one class in its own module, registered in :mod:`handeye.sensors.camera.targets`. It
answers five questions, each with one method or attribute:

==================  ===========================================================================
spec                ``from_spec(spec)`` builds it from session.yaml's ``target:`` mapping,
                    ``to_spec()`` gives the mapping back; ``size_keys`` are the lengths that scale
                    with the board, ``print_kinds`` the ``handeye target --type`` names it prints as
detect              ``detect(gray)``: a :class:`Detection` or None, ``object_points()``,
                    ``symmetries()``
render              ``texture(texels_per_m)``: the printed pattern as a :class:`Texture`, for the
                    simulator's renderer
print               ``print_shapes()``: the board as vector shapes in millimetres, and
                    ``describe()``: one line of words for the printed page
frame               ``frame``: where the target frame is, in words (Z and every target pose are
                    given in it)
==================  ===========================================================================
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from ...._shared.lazy import lazy_module
from ...._shared.text import shown
from ....errors import TargetError

cv2 = lazy_module("cv2")  # OpenCV loads on first use: `import handeye` stays light

__all__ = ["Detection", "Target", "Texture", "OpenCVBoard", "aruco_dictionary", "grid_points", "raster_rects", "need",
           "DARK", "LIGHT", "SUBPIX_CRITERIA"]

#: The grey levels of a rendered pattern's dark and light parts.
DARK, LIGHT = 25, 225
#: cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER (2 + 1), 50 rounds, 1e-4 px
SUBPIX_CRITERIA = (3, 50, 1e-4)


@dataclass(frozen=True)
class Detection:
    """Features of a target found in one image."""

    ids: NDArray[np.intp]
    image_points: NDArray[np.float64]  #: (M, 2) pixels
    object_points: NDArray[np.float64]  #: (M, 3) metres, target frame

    def __len__(self) -> int:
        return len(self.ids)


@dataclass(frozen=True)
class Texture:
    """A target's printed pattern: ``u = u0 + x * scale``, ``v = v0 + y * scale`` (x, y in metres),
    texel ``(i, j)`` centred at ``u = i, v = j`` (OpenCV's drawing and ``remap`` convention)."""

    image: NDArray[np.uint8]
    u0: float
    v0: float
    scale: float  #: texels per metre

    def outline(self) -> NDArray[np.float64]:
        """The sheet's four corners in the target frame (metres, z = 0)."""
        h, w = self.image.shape
        us = np.array([0, w, w, 0], dtype=float) - 0.5  # texel centres at integers: the sheet spans [-0.5, w - 0.5]
        vs = np.array([0, 0, h, h], dtype=float) - 0.5
        return np.stack([(us - self.u0) / self.scale, (vs - self.v0) / self.scale, np.zeros(4)], axis=1)


def need(spec: dict[str, Any], key: str) -> Any:
    """``spec[key]``, or a TargetError naming the key and the target type."""
    if spec.get(key) is None:
        raise TargetError(f"missing key '{key}' for a {spec.get('type')} target")
    return spec[key]


@dataclass(frozen=True)
class Target:
    """Base class: a planar target with known feature positions (the protocol in this module's text)."""

    #: the session.yaml ``type`` of the class (a class may read more than one: ``spec_types``)
    type: ClassVar[str] = ""
    #: where the target frame is (Z and every pose of the target are given in it), in words
    frame: ClassVar[str] = ""
    #: the spec's lengths (metres) that scale with the board when it is fitted to the paper
    size_keys: ClassVar[tuple[str, ...]] = ("square",)
    #: what ``square`` measures, in words ("squares", "tag side", ...)
    size_name: ClassVar[str] = "squares"
    #: ``handeye target --type`` name -> (session.yaml type, default sizes in mm and counts)
    print_kinds: ClassVar[dict[str, tuple[str, dict[str, Any]]]] = {}
    cols: int
    rows: int
    square: float

    # spec ---------------------------------------------------------------------------------------
    @classmethod
    def spec_types(cls) -> tuple[str, ...]:
        """The session.yaml types this class reads."""
        return (cls.type,)

    @classmethod
    def from_spec(cls, spec: dict[str, Any]) -> "Target":
        """The target of a session.yaml ``target:`` mapping (its ``type`` one of :meth:`spec_types`)."""
        return cls(need(spec, "cols"), need(spec, "rows"), float(need(spec, "square")))

    def to_spec(self) -> dict[str, Any]:
        """The session.yaml ``target:`` mapping of this target (``from_spec(to_spec())`` equals it)."""
        return {"type": self.type, "cols": self.cols, "rows": self.rows, "square": self.square}

    # detect -------------------------------------------------------------------------------------
    def object_points(self) -> NDArray[np.float64]:
        """All feature positions (N, 3) in metres, in id order."""
        raise NotImplementedError

    def detect(self, gray: NDArray[np.uint8]) -> Detection | None:
        """Find the target in a grayscale image; None when it is not there."""
        raise NotImplementedError

    def symmetries(self) -> list[NDArray[np.float64]]:
        """In-plane transforms ``F`` (4x4) under which the pattern looks the same.

        A detector cannot tell these views apart, so the pose it yields is ``T`` or ``T @ F``;
        :func:`handeye.sensors.camera.pnp.resolve_symmetries` picks the one consistent with the robot.
        The identity comes first; unambiguous targets (ChArUco, AprilTag) have only it.
        """
        return [np.eye(4)]

    def miscounted(self) -> tuple["Target", str] | None:
        """The target a user who miscounted this one probably has, and the hint to give when it is
        found where this one is not (a chessboard's squares counted instead of its inner corners);
        None when no such slip is common."""
        return None

    # render and print ---------------------------------------------------------------------------
    def texture(self, texels_per_m: float = 4000.0) -> Texture:
        """The printed pattern (with a white quiet zone around it), for the renderer."""
        raise NotImplementedError

    def print_shapes(self) -> tuple[list[tuple], float, float]:
        """The board's shapes (mm, y down, origin at its top-left: ``('rect', x, y, w, h)``,
        ``('circle', cx, cy, r)``) and its width and height (mm, quiet zones included)."""
        raise NotImplementedError

    def describe(self) -> str:
        """The target in one line of words (sizes in mm), for the printed page."""
        return f"{self.type} of {self.cols} x {self.rows}, {self.size_name} {1e3 * self.square:.2f} mm"

    # shared checks ------------------------------------------------------------------------------
    def _grid_symmetries(self, pts: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """The grid's symmetry group about its centre: half turns about the normal and about the
        two in-plane axes (a labelling "from behind" fits PnP as well as the true one), and for a
        square grid the quarter turns too (dihedral group D2, or D4)."""
        c = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
        step = 90 if self.cols == self.rows else 180
        flip = np.diag([1.0, -1.0, -1.0])  # half turn about the in-plane x axis
        out = []
        for back in (np.eye(3), flip):
            for k in range(0, 360, step):
                a = np.radians(k)
                Rz = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
                F = np.eye(4)
                F[:3, :3] = np.round(Rz @ back)
                F[:3, 3] = c - F[:3, :3] @ c
                out.append(F)
        return out

    def _check_size(self, min_cols: int = 2, min_rows: int = 2) -> None:
        if int(self.cols) != self.cols or int(self.rows) != self.rows or self.cols < min_cols or self.rows < min_rows:
            raise TargetError(f"{self.type}: cols and rows must be integers >= {min_cols}, {min_rows}; got {self.cols} x {self.rows}")
        if not (np.isfinite(self.square) and 0 < self.square < 1.0):
            raise TargetError(f"{self.type}: square must be a length in metres between 0 and 1, got {shown(self.square)}"
                              + (" (millimetres? write 0.0236 for 23.6 mm)" if self.square >= 1.0 else ""))


def grid_points(cols: int, rows: int, square: float) -> NDArray[np.float64]:
    """A ``cols`` x ``rows`` grid of points ``square`` apart (metres), row by row, z = 0."""
    j, i = np.mgrid[0:rows, 0:cols]
    return np.stack([i.ravel() * square, j.ravel() * square, np.zeros(cols * rows)], axis=1)


def aruco_dictionary(name: str) -> Any:
    """OpenCV's predefined aruco dictionary ``name`` (``DICT_6X6_250``, ``DICT_APRILTAG_36h11``, ...)."""
    if not isinstance(name, str) or not name.startswith("DICT_") or not hasattr(cv2.aruco, name):
        raise TargetError(f"unknown aruco dictionary {shown(name)}; use an OpenCV name such as DICT_6X6_250 or DICT_APRILTAG_36h11")
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


class OpenCVBoard:
    """A target backed by an OpenCV board object (``_board``, built in ``__post_init__``)."""

    _board: Any

    def __reduce__(self):  # the cv2 board does not pickle: rebuild it from the public fields (worker processes)
        return (type(self), tuple(getattr(self, f.name) for f in fields(self) if not f.name.startswith("_")))

    @property
    def board(self) -> Any:
        """The OpenCV board (``cv2.aruco.CharucoBoard`` or ``cv2.aruco.GridBoard``)."""
        return self._board

    def board_texture(self, margin: float, width: float, height: float, texels_per_m: float) -> Texture:
        """OpenCV's own image of the board, ``margin`` metres of white around it."""
        s = texels_per_m
        w, h = int(round((width + 2 * margin) * s)), int(round((height + 2 * margin) * s))
        m = int(round(margin * s))
        img = self.board.generateImage((w, h), marginSize=m, borderBits=1)
        img = np.where(img > 127, LIGHT, DARK).astype(np.uint8)
        # texel i spans [i - 0.5, i + 0.5] where the renderer samples (pixel centres at integers):
        # the board's edge, between texels m - 1 and m, is at m - 0.5
        return Texture(img, m - 0.5, m - 0.5, (w - 2 * m) / width)


def raster_rects(img: NDArray[np.uint8], mm_per_px: float) -> list[tuple]:
    """The dark pixels of a binary image as rectangles (mm): runs along each row, merged down the
    rows while they stay the same."""
    dark = img < 128
    shapes: list[tuple] = []
    open_runs: dict[tuple[int, int], int] = {}  # (x0, x1) -> first row
    for y in range(dark.shape[0] + 1):
        runs = set()
        if y < dark.shape[0]:
            row = np.r_[False, dark[y], False].astype(np.int8)
            edges = np.flatnonzero(np.diff(row))
            runs = {(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])}
        for run in list(open_runs):
            if run not in runs:
                y0 = open_runs.pop(run)
                shapes.append(("rect", run[0] * mm_per_px, y0 * mm_per_px, (run[1] - run[0]) * mm_per_px,
                               (y - y0) * mm_per_px))
        for run in runs:
            open_runs.setdefault(run, y)
    return shapes
