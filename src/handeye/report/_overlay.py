"""Image thumbnails with the detected target points (green rings) and the points predicted through
X, Z and the robot pose (red crosses), for report.html and verify.html.

A whole 640x480 image shown 360 px wide makes a 9x6 board's marks a few pixels each, and rings and
crosses cannot be told apart. So a thumbnail shows the part of the image around the target, grey and
faded so that the coloured marks stand out, with marks sized to the spacing of the points as
displayed. The part is the one detection cut while it had the image decoded
(:mod:`handeye.sensors.camera.preview`), or read from the file again.
"""

from __future__ import annotations

import base64
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .._shared.lazy import lazy_module
from ..sensors.camera.preview import CROP_MARGIN, ZOOM_WIDTH, Preview, cut, recall

cv2 = lazy_module("cv2")

#: Thumbnails are shown this wide (and stored ZOOM_WIDTH wide: a click shows them at that size).
THUMB_WIDTH = 360
DETECTED_BGR, PREDICTED_BGR = (0, 170, 0), (0, 0, 220)
#: Mark radius as a fraction of the median spacing of the detected points, and its bounds in
#: displayed pixels.
MARK_FRACTION, MARK_MIN_PX, MARK_MAX_PX = 0.35, 3.0, 9.0


def jpeg(img: NDArray[np.uint8]) -> str:
    """``img`` as a JPEG data URI ('' when it cannot be encoded)."""
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 80])
    return "data:image/jpeg;base64," + base64.b64encode(buf.tobytes()).decode("ascii") if ok else ""


def zoom_size(img: NDArray[np.uint8]) -> tuple[NDArray[np.uint8], float]:
    """The image at most ZOOM_WIDTH wide (the size a click shows), and the scale applied."""
    s = min(1.0, ZOOM_WIDTH / img.shape[1])
    return cv2.resize(img, (max(1, round(img.shape[1] * s)), max(1, round(img.shape[0] * s))),
                      interpolation=cv2.INTER_AREA), s


def _spacing(points: NDArray[np.float64]) -> float:
    """Median distance from each point to its nearest neighbour (px); 0 for fewer than 2 points."""
    if len(points) < 2:
        return 0.0
    pts = points[:400]  # enough for a median; the pairwise table stays small
    d = np.linalg.norm(pts[:, None, :] - pts[None, :, :], axis=2)
    np.fill_diagonal(d, np.inf)
    return float(np.median(d.min(axis=1)))


def _from_file(image_path: str | Path, detected: NDArray[np.float64],
               predicted: NDArray[np.float64]) -> Preview | None:
    """The preview of the image file around the detected and predicted points; None when it cannot
    be read."""
    # a large image is decoded at 1/2, 1/4 or 1/8 of its size (JPEG decodes that directly, several
    # times faster) when the target's crop still spans ZOOM_WIDTH pixels there
    finite = detected[np.all(np.isfinite(detected), axis=1)]
    span = float(np.ptp(finite[:, 0])) * (1 + 2 * CROP_MARGIN) if len(finite) else 0.0
    factor = next((f for f in (8, 4, 2) if span / f >= ZOOM_WIDTH), 1)
    flags = {1: cv2.IMREAD_GRAYSCALE, 2: cv2.IMREAD_REDUCED_GRAYSCALE_2, 4: cv2.IMREAD_REDUCED_GRAYSCALE_4,
             8: cv2.IMREAD_REDUCED_GRAYSCALE_8}[factor]
    img = cv2.imread(str(image_path), flags)
    if img is None or img.shape[0] < 2 or img.shape[1] < 2:
        return None
    return cut(img, np.vstack([detected, predicted]), factor)


def overlay_thumbnail(image_path: str | Path, detected: NDArray[np.float64],
                      predicted: NDArray[np.float64] | None) -> str | None:
    """The image around its target, grey and faded, with ``detected`` points as green rings and
    ``predicted`` ones as red crosses, as a JPEG data URI ZOOM_WIDTH wide; None when the image
    cannot be read.

    The preview detection kept of the image (:mod:`handeye.sensors.camera.preview`) is used when every
    predicted point in the image lies in it; else the file is read. Predicted points far off the
    image (or NaN) are not drawn.
    """
    detected = np.asarray(detected, dtype=float).reshape(-1, 2)
    predicted = np.empty((0, 2)) if predicted is None else np.asarray(predicted, dtype=float).reshape(-1, 2)
    view = recall(image_path)
    if view is None or not view.holds(predicted):
        view = _from_file(image_path, detected, predicted)
    if view is None:
        return None
    thumb = cv2.cvtColor(view.image, cv2.COLOR_GRAY2BGR)
    s = view.scale
    shown = THUMB_WIDTH / ZOOM_WIDTH  # displayed pixels per stored pixel
    r = float(np.clip(MARK_FRACTION * _spacing(detected) * s, MARK_MIN_PX / shown, MARK_MAX_PX / shown))
    thick = max(2, round(1.4 / shown))
    offset = np.array(view.box[:2], dtype=float)
    for p in (detected - offset) * s:
        if np.all(np.isfinite(p)):
            cv2.circle(thumb, (int(round(p[0])), int(round(p[1]))), int(round(r)), DETECTED_BGR, thick, cv2.LINE_AA)
    for p in (predicted - offset) * s:
        # OpenCV takes int positions, and a bad prediction's 1e20 is not one
        if np.all(np.abs(p) < 1e5):
            cv2.drawMarker(thumb, (int(round(p[0])), int(round(p[1]))), PREDICTED_BGR, cv2.MARKER_CROSS,
                           int(round(2 * r)), thick, cv2.LINE_AA)
    return jpeg(thumb)
