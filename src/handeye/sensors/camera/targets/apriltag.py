"""One AprilTag (or any aruco marker): its four outer corners, found by OpenCV's aruco detector."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from ...._shared.lazy import lazy_module
from ...._shared.text import shown
from ....errors import TargetError
from .base import DARK, LIGHT, Detection, Target, Texture, aruco_dictionary, need, raster_rects

cv2 = lazy_module("cv2")

__all__ = ["AprilTag"]


@dataclass(frozen=True)
class AprilTag(Target):
    """One AprilTag; features are its four outer corners (ids 0..3, OpenCV's aruco order)."""

    type: ClassVar[str] = "apriltag"
    frame: ClassVar[str] = ("origin at the tag's first corner (the top-left of the printed tag, OpenCV's aruco "
                            "order), x towards the top-right corner, y towards the bottom-left, z into the tag (away "
                            "from the camera); ViSP and the AprilTag library put the origin at the tag's centre, "
                            "(side/2, side/2, 0) in this frame")
    size_name: ClassVar[str] = "tag side"
    print_kinds: ClassVar[dict] = {"apriltag": ("apriltag", dict(square=100.0, dictionary="DICT_APRILTAG_36h11", id=0))}
    dictionary: str = "DICT_APRILTAG_36h11"
    tag_id: int | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.square) and 0 < self.square < 1.0):
            raise TargetError(f"apriltag: square (the tag side) must be in metres between 0 and 1, got {shown(self.square)}")
        aruco_dictionary(self.dictionary)

    @classmethod
    def from_spec(cls, spec: dict[str, Any]) -> "AprilTag":
        tag_id = spec.get("id")
        return cls(0, 0, float(need(spec, "square")), dictionary=str(spec.get("dictionary", "DICT_APRILTAG_36h11")),
                   tag_id=None if tag_id is None else int(tag_id))

    def to_spec(self) -> dict[str, Any]:
        return {"type": self.type, "square": self.square, "dictionary": self.dictionary,
                **({} if self.tag_id is None else {"id": self.tag_id})}

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

    def texture(self, texels_per_m: float = 4000.0) -> Texture:
        side = int(round(self.square * texels_per_m))
        tag = cv2.aruco.generateImageMarker(aruco_dictionary(self.dictionary), self.tag_id or 0, side, borderBits=1)
        m = side // 3
        img = np.full((side + 2 * m, side + 2 * m), LIGHT, np.uint8)
        img[m : m + side, m : m + side] = np.where(tag > 127, LIGHT, DARK)
        return Texture(img, m - 0.5, m - 0.5, side / self.square)  # the tag's edge between texels (board_texture)

    def print_shapes(self) -> tuple[list[tuple], float, float]:
        d = aruco_dictionary(self.dictionary)
        bits = d.markerSize + 2
        cells = cv2.aruco.generateImageMarker(d, self.tag_id or 0, bits, borderBits=1)  # one pixel per bit
        cell = 1e3 * self.square / bits
        quiet = 2 * cell
        shapes = [(kind, x + quiet, y + quiet, w, h) for kind, x, y, w, h in raster_rects(cells, cell)]
        return shapes, self.square * 1e3 + 2 * quiet, self.square * 1e3 + 2 * quiet

    def describe(self) -> str:
        return f"tag {self.tag_id or 0} of {self.dictionary}, side {1e3 * self.square:.2f} mm"
