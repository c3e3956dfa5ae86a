"""The chessboard: its inner corners, found by OpenCV's sector-based detector (the classic one and
cornerSubPix as the fallback, thesis §4.1.2)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from ...._shared.lazy import lazy_module
from .base import DARK, LIGHT, SUBPIX_CRITERIA, Detection, Target, Texture, grid_points

cv2 = lazy_module("cv2")

__all__ = ["Chessboard", "PYRAMID_MIN_SIDE"]

#: Images whose shorter side has at least this many pixels (VGA and up) look for a chessboard on the
#: half-size level of the image pyramid first (see :func:`_chessboard_in_region`); below it the
#: half-size image is too small to show most boards.
PYRAMID_MIN_SIDE = 400


@dataclass(frozen=True)
class Chessboard(Target):
    """Inner corners of a chessboard, ``cols`` per row."""

    type: ClassVar[str] = "chessboard"
    frame: ClassVar[str] = ("origin at the first inner corner in OpenCV's order, x along its row of cols corners, "
                            "y along the rows, z into the board (away from the camera); a chessboard reads the same "
                            "turned by a half turn, so which end is first is settled from the robot motion")
    print_kinds: ClassVar[dict] = {"chessboard": ("chessboard", dict(cols=9, rows=6, square=20.0))}

    def __post_init__(self) -> None:
        self._check_size()

    def object_points(self) -> NDArray[np.float64]:
        return grid_points(self.cols, self.rows, self.square)

    def symmetries(self) -> list[NDArray[np.float64]]:
        return self._grid_symmetries(self.object_points())

    def miscounted(self) -> tuple["Chessboard", str] | None:
        if min(self.cols, self.rows) < 4:
            return None
        inner = Chessboard(self.cols - 1, self.rows - 1, self.square)
        return inner, (f"did you count squares? This board has {inner.cols} x {inner.rows} inner corners (a board of "
                       f"{self.cols} x {self.rows} squares): set cols: {inner.cols} and rows: {inner.rows} in "
                       "session.yaml (cols and rows count the inner corners)")

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
            corners = cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), SUBPIX_CRITERIA)
        if corners is None:
            return None
        pts = corners.reshape(-1, 2).astype(float)
        ids = np.arange(len(pts))
        return Detection(ids, pts, self.object_points())

    def texture(self, texels_per_m: float = 4000.0) -> Texture:
        s, sq = texels_per_m, self.square
        nx, ny = self.cols + 1, self.rows + 1  # squares
        margin = sq
        w, h = int(round((nx * sq + 2 * margin) * s)), int(round((ny * sq + 2 * margin) * s))
        img = np.full((h, w), LIGHT, np.uint8)
        u0 = v0 = (margin + sq) * s  # the first inner corner is one square in from the board's corner
        for b in range(ny):
            for a in range(nx):
                if (a + b) % 2 == 0:  # the board's corner square is dark
                    x0, y0 = (a - 1) * sq, (b - 1) * sq
                    pts = np.array([[x0, y0], [x0 + sq, y0], [x0 + sq, y0 + sq], [x0, y0 + sq]]) * s + [u0, v0]
                    cv2.fillConvexPoly(img, np.round(pts * 16).astype(np.int32), DARK, cv2.LINE_AA, 4)
        return Texture(img, u0, v0, s)

    def print_shapes(self) -> tuple[list[tuple], float, float]:
        sq = 1e3 * self.square
        nx, ny = self.cols + 1, self.rows + 1
        shapes = [("rect", a * sq, b * sq, sq, sq) for b in range(ny) for a in range(nx) if (a + b) % 2 == 0]
        return shapes, nx * sq, ny * sq

    def describe(self) -> str:
        return f"chessboard of {self.cols} x {self.rows} inner corners, squares {1e3 * self.square:.2f} mm"


def _chessboard_in_region(gray: NDArray[np.uint8], size: tuple[int, int]) -> NDArray[np.float32] | None:
    """Chessboard corners by findChessboardCornersSB (EXHAUSTIVE | ACCURACY) on the full-size image,
    searched only in the region where the half-size image shows the board; None if not found.

    The detector's cost grows with the pixel count (640x480: ~125 ms an image on one thread;
    1280x1024: ~0.7 s; most of it the ACCURACY refinement). The half-size search (a pyrDown level,
    where pixel x covers 2x - 0.5 to 2x + 1.5 of the full image) only locates the board: by the
    classic detector (~2 ms at 320x240), else by the sector-based one (~16 ms). The corners are then
    found by the same call as on the whole image, in the bounding box of the board grown by one
    square. They are not the same corners (the call's result depends on the whole image it is
    given: up to ~0.4 px apart at 640x480) but as accurate, measured on rendered images with 0.2 px
    noise (RMS from the true corners): at 640x480, 0.2181 px on 120 images located by the classic
    detector, 0.2182 by the sector-based one (28 and 44 ms an image), 0.2190 on the whole image
    (126 ms); at 1280x1024, 0.1835 against 0.1833 px on the whole image (30 images,
    benchmarks/bench_images.py); at 4000x3000, 0.1924 px both. A board the half-size image does not
    show is searched for on the whole image. An image without a board pays the failed half-size
    searches before that (at 640x480: 9 ms flat, 37 ms noisy; at 1280x1024: ~160 ms), an image
    whose board has another size than the session says ~210 ms (1280x1024: ~320 ms); the
    whole-image search then fails too (~290 ms at 640x480).
    """
    half = cv2.pyrDown(gray)
    ok, corners = cv2.findChessboardCorners(half, size, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not ok:
        ok, corners = cv2.findChessboardCornersSB(half, size, flags=cv2.CALIB_CB_EXHAUSTIVE)
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
