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
asymmetric_circles     OpenCV's asymmetric grid, ``cols`` per row, ``rows`` rows, ``square`` =
                       the spacing of OpenCV's pattern unit (centres at ((2j + i % 2) s, i s))
apriltag               one tag (AprilTag 36h11 unless ``dictionary`` says otherwise), its four
                       corners; ``square`` = tag side (outer black border), ``id`` optional
aruco_grid             a grid of ``cols`` x ``rows`` markers (OpenCV's GridBoard: ids 0.. row by
                       row from the top left), their corners; ``square`` = marker side,
                       ``separation`` = the gap between markers, ``dictionary`` (an AprilTag
                       family makes an AprilTag grid); no symmetry: every marker is unique
=====================  ====================================================================

``detect`` returns a :class:`Detection` (feature ids, subpixel image points, object points) or
None when the target is not found. Works with OpenCV 4.x (>= 4.7, the aruco detector API) and 5.x.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from .._shared.lazy import lazy_module
from ..errors import TargetError

cv2 = lazy_module("cv2")  # OpenCV loads on first use: `import handeye` stays light

__all__ = ["Detection", "Target", "Chessboard", "Charuco", "CircleGrid", "AprilTag", "ArucoGrid", "target_from_spec",
           "target_origin", "ORIGINS", "TARGET_TYPES"]

TARGET_TYPES = ("chessboard", "charuco", "circles", "asymmetric_circles", "apriltag", "aruco_grid")
_SUBPIX_CRITERIA = (3, 50, 1e-4)  # cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER (2 + 1), 50 rounds, 1e-4 px


@dataclass(frozen=True)
class Detection:
    """Features of a target found in one image."""

    ids: NDArray[np.intp]
    image_points: NDArray[np.float64]  #: (M, 2) pixels
    object_points: NDArray[np.float64]  #: (M, 3) metres, target frame

    def __len__(self) -> int:
        return len(self.ids)


@dataclass(frozen=True)
class Target:
    """Base class: a planar target with known feature positions."""

    type: ClassVar[str] = ""
    #: where the target frame is (Z and every pose of the target are given in it), in words
    frame: ClassVar[str] = ""
    cols: int
    rows: int
    square: float

    def object_points(self) -> NDArray[np.float64]:
        """All feature positions (N, 3) in metres, in id order."""
        raise NotImplementedError

    def detect(self, gray: NDArray[np.uint8]) -> Detection | None:
        """Find the target in a grayscale image; None when it is not there."""
        raise NotImplementedError

    def symmetries(self) -> list[NDArray[np.float64]]:
        """In-plane transforms ``F`` (4x4) under which the pattern looks the same.

        A detector cannot tell these views apart, so the pose it yields is ``T`` or ``T @ F``;
        :func:`handeye.vision.pnp.resolve_symmetries` picks the one consistent with the robot.
        The identity comes first; unambiguous targets (ChArUco, AprilTag) have only it.
        """
        return [np.eye(4)]

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
            raise TargetError(f"{self.type}: square must be a length in metres between 0 and 1, got {self.square!r}"
                              + (" (millimetres? write 0.0236 for 23.6 mm)" if self.square >= 1.0 else ""))


def _grid(cols: int, rows: int, square: float) -> NDArray[np.float64]:
    j, i = np.mgrid[0:rows, 0:cols]
    return np.stack([i.ravel() * square, j.ravel() * square, np.zeros(cols * rows)], axis=1)


@dataclass(frozen=True)
class Chessboard(Target):
    """Inner corners of a chessboard, ``cols`` per row."""

    type: ClassVar[str] = "chessboard"
    frame: ClassVar[str] = ("origin at the first inner corner in OpenCV's order, x along its row of cols corners, "
                            "y along the rows, z into the board (away from the camera); a chessboard reads the same "
                            "turned by a half turn, so which end is first is settled from the robot motion")

    def __post_init__(self) -> None:
        self._check_size()

    def object_points(self) -> NDArray[np.float64]:
        return _grid(self.cols, self.rows, self.square)

    def symmetries(self) -> list[NDArray[np.float64]]:
        return self._grid_symmetries(self.object_points())

    def detect(self, gray: NDArray[np.uint8]) -> Detection | None:
        size = (self.cols, self.rows)
        corners = _chessboard_in_region(gray, size) if min(gray.shape[:2]) >= PYRAMID_MIN_SIDE else None
        ok = corners is not None
        if not ok:
            ok, corners = cv2.findChessboardCornersSB(gray, size, flags=cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY)
        if not ok:
            # the classic detector, then subpixel refinement (thesis §4.1.2)
            flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
            ok, corners = cv2.findChessboardCorners(gray, size, flags=flags)
            if not ok:
                return None
            corners = cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), _SUBPIX_CRITERIA)
        pts = corners.reshape(-1, 2).astype(float)
        ids = np.arange(len(pts))
        return Detection(ids, pts, self.object_points())


#: Images whose shorter side has at least this many pixels look for a chessboard on the half-size
#: level of the image pyramid first (see :func:`_chessboard_in_region`).
PYRAMID_MIN_SIDE = 800


def _chessboard_in_region(gray: NDArray[np.uint8], size: tuple[int, int]) -> NDArray[np.float32] | None:
    """Chessboard corners by findChessboardCornersSB (EXHAUSTIVE | ACCURACY) on the full-size image,
    searched only in the region where the half-size image shows the board; None if not found.

    The detector's cost grows with the pixel count (1280x1024: ~0.7 s an image on one thread, most
    of it the ACCURACY refinement). The half-size search (a pyrDown level, where pixel x covers 2x -
    0.5 to 2x + 1.5 of the full image) is cheap and only locates the board; the corners are then
    found by the same call as on the whole image, in the bounding box of the board grown by one
    square, so they are as accurate (measured on rendered 1280x1024 images with 0.2 px noise: 0.1785
    px RMS from the true corners against 0.1782 px on the whole image, ~5x faster).
    """
    ok, corners = cv2.findChessboardCornersSB(cv2.pyrDown(gray), size, flags=cv2.CALIB_CB_EXHAUSTIVE)
    if not ok:
        return None
    pts = corners.reshape(size[1], size[0], 2).astype(np.float64) * 2.0 + 0.5
    spacing = max(np.linalg.norm(np.diff(pts, axis=0), axis=2).max(), np.linalg.norm(np.diff(pts, axis=1), axis=2).max())
    pts = pts.reshape(-1, 2)
    x0, y0 = np.maximum(np.floor(pts.min(axis=0) - spacing).astype(int), 0)
    x1, y1 = np.minimum(np.ceil(pts.max(axis=0) + spacing).astype(int), [gray.shape[1], gray.shape[0]])
    region = np.ascontiguousarray(gray[y0:y1, x0:x1])
    ok, corners = cv2.findChessboardCornersSB(region, size, flags=cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY)
    if not ok:
        return None
    return corners + np.array([x0, y0], dtype=np.float32)


def aruco_dictionary(name: str) -> Any:
    if not isinstance(name, str) or not name.startswith("DICT_") or not hasattr(cv2.aruco, name):
        raise TargetError(f"unknown aruco dictionary {name!r}; use an OpenCV name such as DICT_6X6_250 or DICT_APRILTAG_36h11")
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


class _OpenCVBoard:
    """A target backed by an OpenCV board object (``_board``, built in ``__post_init__``)."""

    def __reduce__(self):  # the cv2 board does not pickle: rebuild it from the public fields (worker processes)
        return (type(self), tuple(getattr(self, f.name) for f in fields(self) if not f.name.startswith("_")))

    @property
    def board(self) -> Any:
        """The OpenCV board (``cv2.aruco.CharucoBoard`` or ``cv2.aruco.GridBoard``)."""
        return self._board


@dataclass(frozen=True)
class Charuco(_OpenCVBoard, Target):
    """A ChArUco board of ``cols`` x ``rows`` squares; features are its inner chessboard corners."""

    type: ClassVar[str] = "charuco"
    frame: ClassVar[str] = ("origin at the board's outer corner next to its first inner corner (that corner is at "
                            "x = y = one square), x along the cols squares, y along the rows, z into the board (away "
                            "from the camera): OpenCV's CharucoBoard frame")
    marker: float = 0.0
    dictionary: str = "DICT_6X6_250"
    _board: Any = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        self._check_size(3, 3)
        if not (0 < self.marker < self.square):
            raise TargetError(f"charuco: marker side must be between 0 and the square side {self.square}, got {self.marker!r}")
        board = cv2.aruco.CharucoBoard((int(self.cols), int(self.rows)), float(self.square), float(self.marker),
                                        aruco_dictionary(self.dictionary))
        object.__setattr__(self, "_board", board)

    def object_points(self) -> NDArray[np.float64]:
        return np.asarray(self._board.getChessboardCorners(), dtype=float).reshape(-1, 3)

    def detect(self, gray: NDArray[np.uint8]) -> Detection | None:
        detector = cv2.aruco.CharucoDetector(self._board)
        corners, ids, _, _ = detector.detectBoard(gray)
        if ids is None or len(ids) < 4:
            return None
        ids = ids.ravel().astype(np.intp)
        return Detection(ids, corners.reshape(-1, 2).astype(float), self.object_points()[ids])


@dataclass(frozen=True)
class CircleGrid(Target):
    """A grid of circles: symmetric (``cols`` x ``rows``) or OpenCV's asymmetric layout."""

    type: ClassVar[str] = "circles"
    frame: ClassVar[str] = ("origin at the first circle's centre in OpenCV's order, x along its row, y along the "
                            "rows, z into the board (away from the camera); a symmetric grid reads the same turned by a "
                            "half turn, so which end is first is settled from the robot motion (an asymmetric grid has "
                            "one reading)")
    asymmetric: bool = False

    def __post_init__(self) -> None:
        self._check_size(3, 3)

    def object_points(self) -> NDArray[np.float64]:
        if not self.asymmetric:
            return _grid(self.cols, self.rows, self.square)
        i, j = np.divmod(np.arange(self.cols * self.rows), self.cols)
        return np.stack([(2 * j + i % 2) * self.square, i * self.square, np.zeros(len(i))], axis=1)

    def symmetries(self) -> list[NDArray[np.float64]]:
        return [np.eye(4)] if self.asymmetric else self._grid_symmetries(self.object_points())

    def detect(self, gray: NDArray[np.uint8]) -> Detection | None:
        flags = cv2.CALIB_CB_ASYMMETRIC_GRID if self.asymmetric else cv2.CALIB_CB_SYMMETRIC_GRID
        params = cv2.SimpleBlobDetector_Params()
        params.maxArea = float(gray.shape[0] * gray.shape[1]) / 20.0
        params.minArea = 10.0
        blob = cv2.SimpleBlobDetector_create(params)
        ok, centres = cv2.findCirclesGrid(gray, (self.cols, self.rows), flags=flags, blobDetector=blob)
        if not ok:
            return None
        pts = centres.reshape(-1, 2).astype(float)
        return Detection(np.arange(len(pts)), pts, self.object_points())


@dataclass(frozen=True)
class AprilTag(Target):
    """One AprilTag; features are its four outer corners (ids 0..3, OpenCV's aruco order)."""

    type: ClassVar[str] = "apriltag"
    frame: ClassVar[str] = ("origin at the tag's first corner (the top-left of the printed tag, OpenCV's aruco "
                            "order), x towards the top-right corner, y towards the bottom-left, z into the tag (away "
                            "from the camera); ViSP and the AprilTag library put the origin at the tag's centre, "
                            "(side/2, side/2, 0) in this frame")
    dictionary: str = "DICT_APRILTAG_36h11"
    tag_id: int | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.square) and 0 < self.square < 1.0):
            raise TargetError(f"apriltag: square (the tag side) must be in metres between 0 and 1, got {self.square!r}")
        aruco_dictionary(self.dictionary)

    def object_points(self) -> NDArray[np.float64]:
        s = self.square
        # aruco corner order: top-left, top-right, bottom-right, bottom-left; origin at the first
        return np.array([[0.0, 0.0, 0.0], [s, 0.0, 0.0], [s, s, 0.0], [0.0, s, 0.0]])

    def detect(self, gray: NDArray[np.uint8]) -> Detection | None:
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
        detector = cv2.aruco.ArucoDetector(aruco_dictionary(self.dictionary), params)
        corners, ids, _ = detector.detectMarkers(gray)
        if ids is None:
            return None
        ids = ids.ravel()
        if self.tag_id is not None:
            keep = np.flatnonzero(ids == self.tag_id)
        else:
            keep = np.arange(len(ids)) if len(ids) == 1 else np.array([], dtype=int)
        if len(keep) != 1:
            return None  # the tag is absent, or several tags and no id to choose
        pts = corners[int(keep[0])].reshape(-1, 2).astype(float)
        return Detection(np.arange(4), pts, self.object_points())


@dataclass(frozen=True)
class ArucoGrid(_OpenCVBoard, Target):
    """A grid of ``cols`` x ``rows`` markers (OpenCV's GridBoard); features are the corners of every
    marker (id ``4 * marker + corner``)."""

    type: ClassVar[str] = "aruco_grid"
    frame: ClassVar[str] = ("origin at the top-left corner of the board's first marker, x along the cols markers, "
                            "y along the rows, z into the board (away from the camera): OpenCV's GridBoard frame")
    separation: float = 0.0
    dictionary: str = "DICT_6X6_250"
    _board: Any = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (int(self.cols) >= 1 and int(self.rows) >= 1 and int(self.cols) * int(self.rows) >= 2):
            raise TargetError(f"aruco_grid: cols and rows count markers; give at least 2 markers, got {self.cols} x {self.rows}")
        if not (np.isfinite(self.square) and 0 < self.square < 1.0):
            raise TargetError(f"aruco_grid: square (the marker side) must be in metres between 0 and 1, got {self.square!r}")
        if not (np.isfinite(self.separation) and 0 < self.separation < 1.0):
            raise TargetError(f"aruco_grid: separation (the gap between markers) must be in metres between 0 and 1, "
                              f"got {self.separation!r}")
        d = aruco_dictionary(self.dictionary)
        if int(self.cols) * int(self.rows) > len(d.bytesList):
            raise TargetError(f"aruco_grid: {self.cols * self.rows} markers, but {self.dictionary} has {len(d.bytesList)}")
        board = cv2.aruco.GridBoard((int(self.cols), int(self.rows)), float(self.square), float(self.separation), d)
        object.__setattr__(self, "_board", board)

    @property
    def width(self) -> float:
        return self.cols * self.square + (self.cols - 1) * self.separation

    @property
    def height(self) -> float:
        return self.rows * self.square + (self.rows - 1) * self.separation

    def object_points(self) -> NDArray[np.float64]:
        return np.asarray(self._board.getObjPoints(), dtype=float).reshape(-1, 3)

    def detect(self, gray: NDArray[np.uint8]) -> Detection | None:
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
        corners, ids, _ = cv2.aruco.ArucoDetector(aruco_dictionary(self.dictionary), params).detectMarkers(gray)
        if ids is None:
            return None
        ids = ids.ravel()
        keep = [k for k in np.argsort(ids) if 0 <= ids[k] < self.cols * self.rows]
        if not keep:
            return None
        feature = np.concatenate([4 * int(ids[k]) + np.arange(4) for k in keep])
        pts = np.concatenate([corners[k].reshape(4, 2) for k in keep]).astype(float)
        return Detection(feature.astype(np.intp), pts, self.object_points()[feature])


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
        raise TargetError(f"{where}: origin {spec.get('origin')!r}; use 'corner' (the default) or 'centre'")
    kind = spec.get("type")
    if kind not in TARGET_TYPES:
        raise TargetError(f"{where}: unknown target type {kind!r}; use one of {', '.join(TARGET_TYPES)}")

    def need(key: str) -> Any:
        if spec.get(key) is None:
            raise TargetError(f"{where}: missing key '{key}' for a {kind} target")
        return spec[key]

    try:
        if kind == "apriltag":
            tag_id = spec.get("id")
            return AprilTag(0, 0, float(need("square")), dictionary=str(spec.get("dictionary", "DICT_APRILTAG_36h11")),
                            tag_id=None if tag_id is None else int(tag_id))
        cols, rows, square = need("cols"), need("rows"), float(need("square"))
        if kind == "aruco_grid":
            return ArucoGrid(int(cols), int(rows), square, separation=float(need("separation")),
                             dictionary=str(need("dictionary")))
        if kind == "chessboard":
            return Chessboard(cols, rows, square)
        if kind == "charuco":
            return Charuco(cols, rows, square, marker=float(need("marker")), dictionary=str(need("dictionary")))
        return CircleGrid(cols, rows, square, asymmetric=(kind == "asymmetric_circles"))
    except (TypeError, ValueError, TargetError) as exc:  # the size checks of the target classes: say where
        raise TargetError(f"{where}: {exc}") from None
