"""The ChArUco board: a chessboard with aruco markers in its light squares; every corner is named
by the markers around it, so a partly seen board still gives labelled corners."""

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

__all__ = ["Charuco"]

#: Pixels per square of the board image the printed page is traced from, per marker bit.
PRINT_PX_PER_BIT = 40
#: Images whose shorter side has at least this many pixels have their markers found at half size.
HALF_SIZE_FROM_PX = 2000
#: ... and from this many at a quarter size first (750 px a side at least, more than VGA's 480).
QUARTER_SIZE_FROM_PX = 3000
MARKER_SUBPIX_CRITERIA = (3, 30, 0.01)  # cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT: cv2 loads lazily
#: The reduced image's marker search thresholds it at these window sizes (px; OpenCV's default 3, 13 and 23): on
#: bench_large's first 40 images at a quarter of 12 MP, 7.8 ms an image against 12.9 ms, 2790 of the board's markers
#: found against 2791 (an image that misses one inside the board is searched again larger, as before).
REDUCED_THRESHOLD_WINDOWS = (3, 23, 20)  # min, max, step


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
            raise TargetError(f"charuco: marker side must be between 0 and the square side {self.square}, got {shown(self.marker)}")
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
        corners, ids = None, None
        if min(gray.shape[:2]) >= HALF_SIZE_FROM_PX:
            half = cv2.resize(gray, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
            if min(gray.shape[:2]) >= QUARTER_SIZE_FROM_PX:
                quarter = cv2.resize(half, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
                corners, ids = self._detect_from_reduced(detector, gray, (half, quarter))
            if ids is None:
                corners, ids = self._detect_from_reduced(detector, gray, (half,))
        if ids is None:
            corners, ids, _, _ = detector.detectBoard(gray)
        if ids is None or corners is None or len(ids) < 4:
            return None
        ids = ids.ravel().astype(np.intp)
        return Detection(ids, corners.reshape(-1, 2).astype(float), self.object_points()[ids])

    def _detect_from_reduced(self, detector, gray: NDArray[np.uint8], levels: tuple) -> tuple:
        """The board's corners, its markers found on the image reduced (``levels``: the image at half
        size, then at a quarter, ...; the last is searched): the markers only say where the corners
        are, their corners are refined on each larger level in turn, and the board's corners on the
        full image as always. On 12 MP images the half size is 2.5x faster than the whole image
        and as accurate (measured against the renderer's true corners on 30 images of 12 MP: RMS
        0.0341 px against 0.0346 px from the whole image; 0.0363 against 0.0375 on 5 MP); a
        quarter, ~1.9x faster again where it finds every marker (11 of 12 rendered images of 12 MP,
        RMS from the truth the same to 1e-4 px; 33 of bench_large's first 40). ``(None, None)`` when a marker of the board that
        lies inside the image was not found (small markers), or too few were: the next larger
        level, then the full image is searched, so no corner is lost to the shortcut."""
        params = cv2.aruco.DetectorParameters()
        params.adaptiveThreshWinSizeMin, params.adaptiveThreshWinSizeMax, params.adaptiveThreshWinSizeStep = \
            REDUCED_THRESHOLD_WINDOWS
        markers, marker_ids, _ = cv2.aruco.ArucoDetector(self._board.getDictionary(), params).detectMarkers(levels[-1])
        if marker_ids is None:
            return None, None
        ours = np.isin(marker_ids.ravel(), np.asarray(self._board.getIds()).ravel())  # not other markers in view
        if ours.sum() < 4:
            return None, None
        marker_ids = marker_ids[ours]
        markers = tuple(m for m, keep in zip(markers, ours) if keep)
        # pixel i of a level spans pixels 2i and 2i + 1 of the next larger one
        for larger in levels[-2::-1]:
            markers = tuple(cv2.cornerSubPix(larger, (2 * m + 0.5).reshape(-1, 1, 2).astype(np.float32), (3, 3), (-1, -1),
                                             MARKER_SUBPIX_CRITERIA).reshape(1, 4, 2) for m in markers)
        markers = tuple(2 * m + 0.5 for m in markers)
        if self._markers_missed(markers, marker_ids.ravel(), gray.shape):
            return None, None
        # the board's corners are found from the markers' corners: refined at full size, they give
        # corners as close to the truth as the whole-image search's, or closer (without: 24% further on 5 MP)
        markers = tuple(cv2.cornerSubPix(gray, m.reshape(-1, 1, 2).astype(np.float32), (3, 3), (-1, -1),
                                         MARKER_SUBPIX_CRITERIA).reshape(1, 4, 2) for m in markers)
        corners, ids, _, _ = detector.detectBoard(gray, markerCorners=markers, markerIds=marker_ids)
        return corners, ids

    def _markers_missed(self, markers: tuple, marker_ids: NDArray[np.int_], shape: tuple[int, ...]) -> bool:
        """Whether a marker not among ``marker_ids`` lies inside the image (at least 2% of its width
        from the border), where the board's plane, mapped through the markers found, puts it."""
        board_ids = np.asarray(self._board.getIds()).ravel()
        board_corners = [np.asarray(c, dtype=np.float64)[:, :2] for c in self._board.getObjPoints()]
        where = {int(i): k for k, i in enumerate(board_ids)}
        found_ids = set(marker_ids.tolist())
        missing = [k for k, i in enumerate(board_ids) if int(i) not in found_ids]
        if not missing:
            return False
        found = np.concatenate([board_corners[where[int(i)]] for i in marker_ids])
        H, _ = cv2.findHomography(found, np.concatenate([m.reshape(-1, 2) for m in markers]).astype(np.float64))
        if H is None:
            return True
        expected = cv2.perspectiveTransform(np.concatenate([board_corners[k] for k in missing])[None], H)[0]
        h, w = shape[:2]
        margin = 0.02 * w
        inside = ((expected[:, 0] > margin) & (expected[:, 0] < w - margin) & (expected[:, 1] > margin)
                  & (expected[:, 1] < h - margin)).reshape(-1, 4).all(axis=1)
        return bool(inside.any())

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
