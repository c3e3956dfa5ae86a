"""What the sensor models of a planar target seen in pixels share (:mod:`handeye.sensors.base`).

An area camera's (:class:`~handeye.sensors.camera.model.CameraCorners`) and a line-scan camera's
(:class:`~handeye.sensors.linescan.model.LineScanCorners`) unknowns begin with the target's pose:
a rotation vector about the pose the first start gave (the chart: smooth for every pose near it)
and the translation. Their residuals are pixels times each corner's pixel size at its depth, fixed
at that first start (so that the fit cannot shrink them by moving the target away), which also
turns the stated pixel noise into millimetres; the columns a model names in ``pixel_columns`` are
weighted by that size too (their ``shape``: an area camera's; a line-scan camera's are not).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..errors import HandEyeError
from ..frames.setups import predicted_target2cam
from ..geometry.se3 import make_transform

__all__ = ["ChartedTarget", "grid_curve", "SECTION_PLANE_IMAGE"]

#: What a camera's sections are drawn in (the report's picture of the fit on each view).
SECTION_PLANE_IMAGE = "the image (mm at the target)"


class ChartedTarget:
    """The target's pose as unknowns in a chart, and the pixel sizes (the module docstring). A model
    that uses it has ``setup``, ``points`` (M, 3: the target's points), ``owner`` (M,), ``noise_px``
    and its noise ``shape`` before the pixel sizes weight it, and calls :meth:`_first_start` from its
    ``start``.

    The chart and the pixel sizes are the model's anchor: set by the first start and never changed
    after it (a fold's start gives its unknowns in the same chart), since they need X and Z, which
    only the core's closed form on the views' poses gives. The noise ``shape`` is derived from them
    (the stated shape, its pixel columns weighted by the anchor's pixel sizes), not rewritten; before
    the first start the residuals, the noise and the target's pose are refused by name."""

    _chart: NDArray[np.float64] | None = None  #: the target's pose at the first start
    _mpp: NDArray[np.float64] | None = None  #: per point the pixel's size at its depth (m), fixed at the first start
    _stated_shape: NDArray[np.float64]
    noise_px: float
    setup: str
    kind: str
    target: str
    owner: NDArray[np.intp]
    points: NDArray[np.float64]
    #: the residual columns that are pixels times the pixel's size
    pixel_columns: tuple[int, ...] = (0, 1)

    @property
    def shape(self) -> NDArray[np.float64]:
        """The residuals' noise shape (M, c): the stated one, each pixel column weighted by the point's
        pixel size over the median's once the first start has fixed them (a corner's noise is pixels:
        its residual in metres is as large as its pixel at its depth, else the far corners count too much)."""
        if self._mpp is None or not self.pixel_columns:
            return self._stated_shape
        factor = np.ones(self._stated_shape.shape)
        factor[:, list(self.pixel_columns)] = (self._mpp / np.median(self._mpp))[:, None]
        return self._stated_shape * factor

    @shape.setter
    def shape(self, value: NDArray[np.float64]) -> None:
        self._stated_shape = np.asarray(value, dtype=float)

    def _first_start(self, X: NDArray[np.float64], Z: NDArray[np.float64], flange2base: NDArray[np.float64],
                     focal: float) -> None:
        """At the first start: the chart (``Z``) and each point's pixel size, its depth in the view's
        camera frame (X, Z and ``flange2base`` given) over the focal length (px); later starts keep them."""
        if self._chart is not None:
            return
        target2cam = predicted_target2cam(X, Z, np.asarray(flange2base, float), self.setup)[self.owner]
        depth = np.einsum("mj,mj->m", target2cam[:, 2, :3], self.points) + target2cam[:, 2, 3]
        self._chart, self._mpp = np.array(Z, dtype=float), np.abs(depth) / focal

    def _pixel_size(self, rows: NDArray[np.intp]) -> NDArray[np.float64]:
        """Per point of ``rows`` its pixel's size (m), fixed at the first start (refused before it)."""
        if self._mpp is None:
            raise HandEyeError(f"{self.kind} ({self.target}): no start yet; its pixel sizes and the target's chart are "
                               "fixed by the first start (the core's, from the closed form on the views' poses)")
        return self._mpp[rows]

    def _anchor(self) -> NDArray[np.float64]:
        """The target's pose at the first start (refused by name before it)."""
        if self._chart is None:
            raise HandEyeError(f"{self.kind} ({self.target}): no start yet; its pixel sizes and the target's chart are "
                               "fixed by the first start (the core's, from the closed form on the views' poses)")
        return self._chart

    def target_params(self, Z: NDArray[np.float64]) -> NDArray[np.float64]:
        """The unknowns of the target's pose ``Z`` (after the first start: in its chart)."""
        return np.r_[Rotation.from_matrix(Z[:3, :3] @ self._anchor()[:3, :3].T).as_rotvec(), Z[:3, 3]]

    def _target2world(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        return make_transform(Rotation.from_rotvec(p[:3]).as_matrix() @ self._anchor()[:3, :3], p[3:6])

    def Z(self, X: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.float64]:
        """The target's pose (target2base eye-in-hand, target2flange eye-to-hand)."""
        return self._target2world(p)

    def Z_std(self, p: NDArray[np.float64], cov_p: NDArray[np.float64]) -> NDArray[np.float64]:
        """The target pose's std (deg, mm)."""
        std = np.sqrt(np.clip(np.diag(cov_p)[:6], 0.0, None))
        return np.r_[np.degrees(std[:3]), 1e3 * std[3:6]]

    def noise_mm(self, rows: NDArray[np.intp]) -> NDArray[np.float64]:
        """The points' stated noise (px) at their pixel size (mm)."""
        return 1e3 * self.noise_px * self._pixel_size(rows)


def grid_curve(board_points: NDArray[np.float64], drawn: NDArray[np.float64]) -> NDArray[np.float64]:
    """A board's grid as the report draws it: ``drawn`` (n, d), where each of its points
    ``board_points`` (n, 3; the target frame, a grid's rows and columns) is drawn (in a picture, or in
    the camera's frame), joined along the board's rows and along its columns, NaN between the lines (m, d)."""
    board_points, drawn = np.asarray(board_points, float), np.asarray(drawn, float)
    lines = []
    for along, across in ((0, 1), (1, 0)):
        key = np.round(board_points[:, across], 6)
        for value in np.unique(key):
            at = np.flatnonzero(key == value)
            if len(at) > 1:
                lines += [drawn[at[np.argsort(board_points[at, along])]], np.full((1, drawn.shape[1]), np.nan)]
    return np.concatenate(lines) if lines else np.full((1, drawn.shape[1]), np.nan)

