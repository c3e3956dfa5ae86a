"""The ChArUco board: a chessboard with aruco markers in its light squares; every corner is named
by the markers around it, so a partly seen board still gives labelled corners."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from ..._shared.lazy import lazy_module
from ...errors import TargetError
from .base import Detection, OpenCVBoard, Target, Texture, aruco_dictionary, need, raster_rects

cv2 = lazy_module("cv2")

__all__ = ["Charuco"]

#: Pixels per square of the board image the printed page is traced from, per marker bit.
PRINT_PX_PER_BIT = 40


@dataclass(frozen=True)
class Charuco(OpenCVBoard, Target):
    """A ChArUco board of ``cols`` x ``rows`` squares; features are its inner chessboard corners."""

    type: ClassVar[str] = "charuco"
    frame: ClassVar[str] = ("origin at the board's outer corner next to its first inner corner (that corner is at "
                            "x = y = one square), x along the cols squares, y along the rows, z into the board (away "
                            "from the camera): OpenCV's CharucoBoard frame")
    size_keys: ClassVar[tuple[str, ...]] = ("square", "marker")
    print_kinds: ClassVar[dict] = {
        "charuco": ("charuco", dict(cols=7, rows=5, square=25.0, marker=18.0, dictionary="DICT_5X5_100"))}
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

    @classmethod
    def from_spec(cls, spec: dict[str, Any]) -> "Charuco":
        return cls(need(spec, "cols"), need(spec, "rows"), float(need(spec, "square")), marker=float(need(spec, "marker")),
                   dictionary=str(need(spec, "dictionary")))

    def to_spec(self) -> dict[str, Any]:
        return {**super().to_spec(), "marker": self.marker, "dictionary": self.dictionary}

    def object_points(self) -> NDArray[np.float64]:
        return np.asarray(self._board.getChessboardCorners(), dtype=float).reshape(-1, 3)

    def detect(self, gray: NDArray[np.uint8]) -> Detection | None:
        detector = cv2.aruco.CharucoDetector(self._board)
        corners, ids, _, _ = detector.detectBoard(gray)
        if ids is None or len(ids) < 4:
            return None
        ids = ids.ravel().astype(np.intp)
        return Detection(ids, corners.reshape(-1, 2).astype(float), self.object_points()[ids])

    def texture(self, texels_per_m: float = 4000.0) -> Texture:
        return self.board_texture(self.square, self.cols * self.square, self.rows * self.square, texels_per_m)

    def print_shapes(self) -> tuple[list[tuple], float, float]:
        # OpenCV's own layout, traced at a resolution where every square spans whole pixels
        px = PRINT_PX_PER_BIT * (aruco_dictionary(self.dictionary).markerSize + 2)  # pixels per square
        mm_per_px = 1e3 * self.square / px
        img = self.board.generateImage((self.cols * px, self.rows * px), marginSize=0, borderBits=1)
        return raster_rects(img, mm_per_px), img.shape[1] * mm_per_px, img.shape[0] * mm_per_px

    def describe(self) -> str:
        return (f"ChArUco board of {self.cols} x {self.rows} squares, squares {1e3 * self.square:.2f} mm, markers "
                f"{1e3 * self.marker:.2f} mm, {self.dictionary}")
