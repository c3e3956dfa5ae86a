"""Circle grids, symmetric and OpenCV's asymmetric layout: the circles' centres, found by
findCirclesGrid with a blob detector sized to the image."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from ...._shared.lazy import lazy_module
from .base import DARK, LIGHT, Detection, Target, Texture, grid_points, need

cv2 = lazy_module("cv2")

__all__ = ["CircleGrid"]

#: Circle radius as a fraction of the spacing (rendered and printed alike).
RADIUS = 0.3


@dataclass(frozen=True)
class CircleGrid(Target):
    """A grid of circles: symmetric (``cols`` x ``rows``) or OpenCV's asymmetric layout."""

    type: ClassVar[str] = "circles"
    frame: ClassVar[str] = ("origin at the first circle's centre in OpenCV's order, x along its row, y along the "
                            "rows, z into the board (away from the camera); a symmetric grid reads the same turned by a "
                            "half turn, so which end is first is settled from the robot motion (an asymmetric grid has "
                            "one reading)")
    size_name: ClassVar[str] = "circle spacing"
    print_kinds: ClassVar[dict] = {"circles": ("circles", dict(cols=7, rows=6, square=20.0)),
                                   "asymmetric-circles": ("asymmetric_circles", dict(cols=4, rows=11, square=20.0))}
    asymmetric: bool = False

    def __post_init__(self) -> None:
        self._check_size(3, 3)

    @classmethod
    def spec_types(cls) -> tuple[str, ...]:
        return ("circles", "asymmetric_circles")

    @classmethod
    def from_spec(cls, spec: dict[str, Any]) -> "CircleGrid":
        return cls(need(spec, "cols"), need(spec, "rows"), float(need(spec, "square")),
                   asymmetric=(spec["type"] == "asymmetric_circles"))

    def to_spec(self) -> dict[str, Any]:
        return {**super().to_spec(), "type": "asymmetric_circles" if self.asymmetric else self.type}

    def object_points(self) -> NDArray[np.float64]:
        if not self.asymmetric:
            return grid_points(self.cols, self.rows, self.square)
        i, j = np.divmod(np.arange(self.cols * self.rows), self.cols)
        return np.stack([(2 * j + i % 2) * self.square, i * self.square, np.zeros(len(i))], axis=1)

    def symmetries(self) -> list[NDArray[np.float64]]:
        return [np.eye(4)] if self.asymmetric else self._grid_symmetries(self.object_points())

    def detect(self, gray: NDArray[np.uint8]) -> Detection | None:
        found = self._find(gray)
        if found is None:
            return None
        pts = found[0].reshape(-1, 2).astype(float)
        return Detection(np.arange(len(pts)), pts, self.object_points())

    def _find(self, gray: NDArray[np.uint8]) -> tuple[NDArray[np.float32], Any] | None:
        """findCirclesGrid's centres (OpenCV's order) and the blob detector it used, or None."""
        flags = cv2.CALIB_CB_ASYMMETRIC_GRID if self.asymmetric else cv2.CALIB_CB_SYMMETRIC_GRID
        params = cv2.SimpleBlobDetector_Params()
        params.maxArea = float(gray.shape[0] * gray.shape[1]) / 20.0
        params.minArea = 10.0
        blob = cv2.SimpleBlobDetector_create(params)
        ok, centres = cv2.findCirclesGrid(gray, (self.cols, self.rows), flags=flags, blobDetector=blob)
        return (centres, blob) if ok else None

    def texture(self, texels_per_m: float = 4000.0) -> Texture:
        s = texels_per_m
        pts = self.object_points()[:, :2]
        margin = 1.5 * self.square
        lo = pts.min(axis=0) - margin
        hi = pts.max(axis=0) + margin
        w, h = (np.round((hi - lo) * s)).astype(int)
        img = np.full((h, w), LIGHT, np.uint8)
        for (x, y), radius in zip(pts, self._radii()):
            c = np.round(((np.array([x, y]) - lo) * s) * 16).astype(int)
            cv2.circle(img, (int(c[0]), int(c[1])), int(round(radius * self.square * s * 16)), DARK, -1, cv2.LINE_AA, 4)
        return Texture(img, -lo[0] * s, -lo[1] * s, s)

    def print_shapes(self) -> tuple[list[tuple], float, float]:
        pts = 1e3 * self.object_points()[:, :2]
        s = 1e3 * self.square
        margin = s  # a quiet zone of one spacing around the outer circles
        shapes = [("circle", x + margin, y + margin, radius * s) for (x, y), radius in zip(pts, self._radii())]
        return shapes, pts[:, 0].max() + 2 * margin, pts[:, 1].max() + 2 * margin

    def _radii(self) -> NDArray[np.float64]:
        """Each circle's radius as a fraction of the spacing, in id order."""
        return np.full(self.cols * self.rows, RADIUS)

    def describe(self) -> str:
        kind = "asymmetric circles" if self.asymmetric else "circles"
        return f"{kind} grid of {self.cols} x {self.rows}, spacing {1e3 * self.square:.2f} mm"
