"""Previews of the images a report shows: the part of each image around its target, grey and faded
(so that coloured marks drawn on it stand out), at the size a click on a report's thumbnail shows.

Reading the images again for the report's gallery took 2 s of a 14 s ``handeye calibrate`` on 200
images of 12 MP (60 thumbnails on 2 cores). While previews are kept (:func:`kept`, which the command
line opens when it writes a report), detection cuts them from the image it has decoded anyway, and
the report takes them (:func:`recall`) instead of reading the files again. A preview is recalled
only while its file is unchanged (the same path, size and modification time), and they are all
dropped when the ``kept`` block ends.
"""

from __future__ import annotations

import os
import threading
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np
from numpy.typing import NDArray

from ..._shared.lazy import lazy_module

cv2 = lazy_module("cv2")

__all__ = ["Preview", "crop_box", "cut", "kept", "wanted", "remember", "recall", "ZOOM_WIDTH"]

#: Previews are this wide (a report shows them smaller, and at this size when clicked).
ZOOM_WIDTH = 900
#: The crop around the target's points: this fraction of their extent added on every side.
CROP_MARGIN = 0.25
#: The image is blended with white by this much, so that coloured marks stand out.
FADE = 0.55


@dataclass(frozen=True)
class Preview:
    """A part of an image: ``box`` (x0, y0, x1, y1, in the image's pixels) of an image of ``size``
    (width, height), as ``image`` (grey, faded, ZOOM_WIDTH wide or less)."""

    box: tuple[int, int, int, int]
    size: tuple[int, int]
    image: NDArray[np.uint8]

    @property
    def scale(self) -> float:
        """Preview pixels per image pixel."""
        return self.image.shape[1] / (self.box[2] - self.box[0])

    def holds(self, points: NDArray[np.float64]) -> bool:
        """Whether every point of ``points`` (N, 2) that lies in the image lies in the box too."""
        w, h = self.size
        p = points[np.all(np.isfinite(points), axis=1)]
        p = p[(p[:, 0] >= 0) & (p[:, 0] <= w) & (p[:, 1] >= 0) & (p[:, 1] <= h)]
        x0, y0, x1, y1 = self.box
        return bool(np.all((p[:, 0] >= x0) & (p[:, 0] <= x1) & (p[:, 1] >= y0) & (p[:, 1] <= y1)))


def crop_box(points: NDArray[np.float64], shape: tuple[int, ...]) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1): the points' bounding box with CROP_MARGIN, grown to the image's aspect
    ratio and kept inside the image; the whole image when no point lies in it."""
    h, w = shape[:2]
    inside = points[np.all(np.isfinite(points), axis=1) & (points[:, 0] > -w) & (points[:, 0] < 2 * w)
                    & (points[:, 1] > -h) & (points[:, 1] < 2 * h)]
    if len(inside) == 0:
        return 0, 0, w, h
    lo, hi = np.clip(inside.min(axis=0), 0, [w, h]), np.clip(inside.max(axis=0), 0, [w, h])
    size = (hi - lo) * (1 + 2 * CROP_MARGIN) + 16
    cw = max(size[0], size[1] * w / h, 0.2 * w)  # the image's aspect ratio: the gallery's grid stays even
    cw = min(cw, w)
    ch = cw * h / w
    centre = 0.5 * (lo + hi)
    x0 = int(np.clip(centre[0] - cw / 2, 0, w - cw))
    y0 = int(np.clip(centre[1] - ch / 2, 0, h - ch))
    return x0, y0, min(w, x0 + int(round(cw))), min(h, y0 + int(round(ch)))


def cut(gray: NDArray[np.uint8], points: NDArray[np.float64], factor: int = 1) -> Preview:
    """The preview of ``gray`` around ``points`` (its pixels); ``gray`` may be the image decoded at
    1/``factor`` of its size, ``points`` and the box are in the whole image's pixels."""
    small = np.asarray(points, dtype=float).reshape(-1, 2) / factor
    x0, y0, x1, y1 = crop_box(small, gray.shape)
    k = (x1 - x0) // ZOOM_WIDTH
    if k >= 2:  # shrunk by an integer factor first (OpenCV's area average is several times faster for it)
        x1, y1 = x0 + (x1 - x0) // k * k, y0 + (y1 - y0) // k * k
    crop = gray[y0:y1, x0:x1]
    if k >= 2:
        crop = cv2.resize(crop, None, fx=1 / k, fy=1 / k, interpolation=cv2.INTER_AREA)
    s = ZOOM_WIDTH / crop.shape[1]
    image = cv2.resize(crop, (ZOOM_WIDTH, max(1, round(crop.shape[0] * s))),
                       interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR)
    image = cv2.addWeighted(image, 1 - FADE, np.full_like(image, 255), FADE, 0)
    return Preview((factor * x0, factor * y0, factor * x1, factor * y1),
                   (factor * gray.shape[1], factor * gray.shape[0]), image)


_lock = threading.Lock()
_kept: dict[tuple[str, int, int], Preview] = {}
_limit = 0


@contextmanager
def kept(count: int) -> Iterator[None]:
    """Inside the block, detection keeps the previews of the first ``count`` images it is given
    (0: none); they are dropped when the block ends."""
    global _limit
    with _lock:
        previous, _limit = _limit, max(0, int(count))
    try:
        yield
    finally:
        with _lock:
            _limit = previous
            if not previous:
                _kept.clear()


def wanted() -> int:
    """How many images' previews detection keeps now (0 outside :func:`kept`)."""
    return _limit


def _key(path: str | Path) -> tuple[str, int, int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return os.path.realpath(path), st.st_size, st.st_mtime_ns


def remember(path: str | Path, preview: Preview) -> None:
    """Keep ``preview`` of the image file ``path`` (inside :func:`kept`; at most its count, the oldest
    dropped first)."""
    key = _key(path)
    with _lock:
        if key is None or not _limit:
            return
        _kept.pop(key, None)
        _kept[key] = preview
        while len(_kept) > _limit:
            del _kept[next(iter(_kept))]


def recall(path: str | Path) -> Preview | None:
    """The preview kept of ``path`` while the file is as it was then, else None."""
    key = _key(path)
    with _lock:
        return None if key is None else _kept.get(key)
