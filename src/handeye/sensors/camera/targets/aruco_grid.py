"""A grid of aruco (or AprilTag) markers, OpenCV's GridBoard: every marker's four corners, each
marker named by its id, so any part of the grid gives labelled points."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from ...._shared.lazy import lazy_module
from ...._shared.text import shown
from ....errors import TargetError
from .base import Detection, OpenCVBoard, Target, Texture, aruco_dictionary, need, raster_rects

cv2 = lazy_module("cv2")

__all__ = ["ArucoGrid"]


@dataclass(frozen=True)
class ArucoGrid(OpenCVBoard, Target):
    """A grid of ``cols`` x ``rows`` markers (OpenCV's GridBoard); features are the corners of every
    marker (id ``4 * marker + corner``)."""

    type: ClassVar[str] = "aruco_grid"
    frame: ClassVar[str] = ("origin at the top-left corner of the board's first marker, x along the cols markers, "
                            "y along the rows, z into the board (away from the camera): OpenCV's GridBoard frame")
    size_keys: ClassVar[tuple[str, ...]] = ("square", "separation")
    size_name: ClassVar[str] = "markers"
    print_kinds: ClassVar[dict] = {
        "aruco-grid": ("aruco_grid", dict(cols=5, rows=7, square=25.0, separation=5.0, dictionary="DICT_5X5_100")),
        "apriltag-grid": ("aruco_grid", dict(cols=4, rows=5, square=35.0, separation=7.0, dictionary="DICT_APRILTAG_36h11"))}
    separation: float = 0.0
    dictionary: str = "DICT_6X6_250"
    _board: Any = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (int(self.cols) >= 1 and int(self.rows) >= 1 and int(self.cols) * int(self.rows) >= 2):
            raise TargetError(f"aruco_grid: cols and rows count markers; give at least 2 markers, got {self.cols} x {self.rows}")
        if not (np.isfinite(self.square) and 0 < self.square < 1.0):
            raise TargetError(f"aruco_grid: square (the marker side) must be in metres between 0 and 1, got {shown(self.square)}")
        if not (np.isfinite(self.separation) and 0 < self.separation < 1.0):
            raise TargetError(f"aruco_grid: separation (the gap between markers) must be in metres between 0 and 1, "
                              f"got {shown(self.separation)}")
        d = aruco_dictionary(self.dictionary)
        if int(self.cols) * int(self.rows) > len(d.bytesList):
            raise TargetError(f"aruco_grid: {self.cols * self.rows} markers, but {self.dictionary} has {len(d.bytesList)}")
        board = cv2.aruco.GridBoard((int(self.cols), int(self.rows)), float(self.square), float(self.separation), d)
        object.__setattr__(self, "_board", board)

    @classmethod
    def from_spec(cls, spec: dict[str, Any]) -> "ArucoGrid":
        return cls(int(need(spec, "cols")), int(need(spec, "rows")), float(need(spec, "square")),
                   separation=float(need(spec, "separation")), dictionary=str(need(spec, "dictionary")))

    def to_spec(self) -> dict[str, Any]:
        return {**super().to_spec(), "separation": self.separation, "dictionary": self.dictionary}

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

    def texture(self, texels_per_m: float = 4000.0) -> Texture:
        return self.board_texture(self.square / 2, self.width, self.height, texels_per_m)

    def print_shapes(self) -> tuple[list[tuple], float, float]:
        # OpenCV's own layout, traced with whole pixels per marker bit and the gap as near whole pixels as can be
        bits = aruco_dictionary(self.dictionary).markerSize + 2
        k = min(range(12, 61), key=lambda k: abs((v := self.separation / self.square * bits * k) - round(v)))
        mm_per_px = 1e3 * self.square / (bits * k)
        size = (int(round(1e3 * self.width / mm_per_px)), int(round(1e3 * self.height / mm_per_px)))
        img = self.board.generateImage(size, marginSize=0, borderBits=1)
        return raster_rects(img, mm_per_px), img.shape[1] * mm_per_px, img.shape[0] * mm_per_px

    def describe(self) -> str:
        return (f"grid of {self.cols} x {self.rows} markers, markers {1e3 * self.square:.2f} mm, gaps "
                f"{1e3 * self.separation:.2f} mm, {self.dictionary}")
