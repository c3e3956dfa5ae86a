"""ROS-Industrial's modified circle grid: a symmetric grid of circles whose corner circle is drawn
larger, so that every image has one reading. The big circle is found among the grid's blobs by its
size; the grid is then read from it, along the two edges that meet there, in the order that keeps
the target frame right-handed with z into the board."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from ...._shared.lazy import lazy_module
from .base import Detection, grid_points
from .circles import RADIUS, CircleGrid

cv2 = lazy_module("cv2")

__all__ = ["ModifiedCircleGrid"]

#: The big circle's radius as a fraction of the spacing, 1.67x the others' (on ROS-Industrial's
#: printed targets about 2x).
ORIGIN_RADIUS = 0.5
#: The big circle's blob is this many times the median blob's size or more (its diameter), and
#: :data:`ORIGIN_MARGIN` times the next largest: on ROS-Industrial's 10x10 captures the big one is
#: 1.76-2.3x the median and 1.44x the next or more; rendered at :data:`ORIGIN_RADIUS` (1.67x the
#: others' radius), seen at 45 deg, 1.42-1.90x the median, 1.20x the next or more.
ORIGIN_SIZE_RATIO = 1.3
ORIGIN_MARGIN = 1.12


@dataclass(frozen=True)
class ModifiedCircleGrid(CircleGrid):
    """A ``cols`` x ``rows`` grid of circles with a big circle at one corner (ROS-Industrial's
    ``ModifiedCircleGridTarget``): no symmetry left to settle from the robot motion."""

    type: ClassVar[str] = "modified_circles"
    frame: ClassVar[str] = ("origin at the big circle's centre, x and y along the grid's two edges that meet there, in "
                            "the order that puts z into the board (away from the camera): with the big circle at the "
                            "bottom left and the rows of `cols` circles across, x runs up the big circle's column and y "
                            "along its row (ROS-Industrial's frame, whose x runs along that row, y up that column and z "
                            "out of the board, turned a half turn about the line halfway between their x and y)")
    print_kinds: ClassVar[dict] = {"modified-circles": ("modified_circles", dict(cols=7, rows=6, square=20.0))}

    @classmethod
    def spec_types(cls) -> tuple[str, ...]:
        return (cls.type,)

    def object_points(self) -> NDArray[np.float64]:
        """The circles up the big circle's column (x, ``rows`` of them), then along its row (y): the
        symmetric grid's points with x and y swapped, in the same order."""
        return grid_points(self.cols, self.rows, self.square)[:, [1, 0, 2]]

    def symmetries(self) -> list[NDArray[np.float64]]:
        return [np.eye(4)]

    def detect(self, gray: NDArray[np.uint8]) -> Detection | None:
        found = self._find(gray)
        if found is None:
            return None
        centres, blobs = found
        grid = centres.reshape(self.rows, self.cols, 2)
        corner = _big_corner(grid, blobs.detect(gray))
        if corner is None:  # no circle stands out at a corner: an image without one reading
            return None
        order = _reading(grid, corner)
        if order is None:
            return None
        flat = centres.reshape(-1, 2)[order.ravel()].astype(float)
        return Detection(np.arange(len(flat)), flat, self.object_points())

    def _radii(self) -> NDArray[np.float64]:
        return np.r_[ORIGIN_RADIUS, np.full(self.cols * self.rows - 1, RADIUS)]

    def describe(self) -> str:
        return (f"modified circle grid of {self.cols} x {self.rows} (the big circle at the origin), "
                f"spacing {1e3 * self.square:.2f} mm")


def _big_corner(grid: NDArray[np.floating], keypoints) -> tuple[int, int] | None:
    """(row, column) of the grid's largest blob when it stands out (:data:`ORIGIN_SIZE_RATIO` times
    the median blob, :data:`ORIGIN_MARGIN` times the next) and sits at a corner; else None."""
    if not keypoints:
        return None
    where = np.array([k.pt for k in keypoints])
    size = np.array([k.size for k in keypoints])
    near = np.linalg.norm(grid.reshape(-1, 2)[:, None] - where[None], axis=2).argmin(axis=1)
    sizes = size[near]
    first, second = np.sort(sizes)[::-1][:2]
    if first < ORIGIN_SIZE_RATIO * np.median(sizes) or first < ORIGIN_MARGIN * second:
        return None
    rows, cols = grid.shape[:2]
    r, c = divmod(int(np.argmax(sizes)), cols)
    return (r, c) if r in (0, rows - 1) and c in (0, cols - 1) else None


def _reading(grid: NDArray[np.floating], corner: tuple[int, int]) -> NDArray[np.intp] | None:
    """The detector's indices in the target's order: from ``corner``, along its column then its row
    (``x`` first), or the other way round for a square grid, whichever turns the image's x axis onto
    its y axis the way the image's own axes turn (z into the board); None when neither does (a
    rectangular board seen in a mirror, or printed with its rows and columns swapped)."""
    rows, cols = grid.shape[:2]
    index = np.arange(rows * cols).reshape(rows, cols)
    index = index[:: 1 if corner[0] == 0 else -1, :: 1 if corner[1] == 0 else -1]  # the big circle first
    for order in (index, index.T) if rows == cols else (index,):
        p = grid.reshape(-1, 2)[order]
        x, y = p[1, 0] - p[0, 0], p[0, 1] - p[0, 0]
        if x[0] * y[1] - x[1] * y[0] > 0:
            return order
    return None
