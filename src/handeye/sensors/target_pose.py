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

from ..frames.setups import predicted_target2cam
from ..geometry.se3 import make_transform

__all__ = ["ChartedTarget", "grid_curve", "SECTION_PLANE_IMAGE"]

#: What a camera's sections are drawn in (the report's picture of the fit on each view).
SECTION_PLANE_IMAGE = "the image (mm at the target)"


class ChartedTarget:
    """The target's pose as unknowns in a chart, and the pixel sizes (the module docstring). A model
    that uses it has ``setup``, ``points`` (M, 3: the target's points), ``owner`` (M,) and
    ``noise_px``, and calls :meth:`_first_start` from its ``start``."""

    #: the target's pose at the first start (None before it)
    _chart: NDArray[np.float64] = None  # type: ignore[assignment]
    #: per point the pixel's size at its depth (m), fixed at the first start (None before it)
    _mpp: NDArray[np.float64] = None  # type: ignore[assignment]
    noise_px: float
    shape: NDArray[np.float64]
    setup: str
    owner: NDArray[np.intp]
    points: NDArray[np.float64]
    #: the residual columns that are pixels times the pixel's size
    pixel_columns: tuple[int, ...] = (0, 1)

    def _first_start(self, X: NDArray[np.float64], Z: NDArray[np.float64], flange2base: NDArray[np.float64],
                     focal: float) -> None:
        """At the first start: the chart (``Z``) and each point's pixel size, its depth in the view's
        camera frame (X, Z and ``flange2base`` given) over the focal length (px)."""
        if self._chart is not None:
            return
        self._chart = np.array(Z, dtype=float)
        target2cam = predicted_target2cam(X, Z, np.asarray(flange2base, float), self.setup)[self.owner]
        depth = np.einsum("mj,mj->m", target2cam[:, 2, :3], self.points) + target2cam[:, 2, 3]
        self._mpp = np.abs(depth) / focal
        # a corner's noise is pixels: its residual in metres is as large as its pixel at its depth, so
        # each pixel column's rows are weighted by that size (else the far corners count too much)
        factor = np.ones(np.shape(self.shape))
        factor[:, list(self.pixel_columns)] = (self._mpp / np.median(self._mpp))[:, None]
        self.shape = np.asarray(self.shape, float) * factor

    def target_params(self, Z: NDArray[np.float64]) -> NDArray[np.float64]:
        """The unknowns of the target's pose ``Z`` (after the first start: in its chart)."""
        return np.r_[Rotation.from_matrix(Z[:3, :3] @ self._chart[:3, :3].T).as_rotvec(), Z[:3, 3]]

    def _target2world(self, p: NDArray[np.float64]) -> NDArray[np.float64]:
        return make_transform(Rotation.from_rotvec(p[:3]).as_matrix() @ self._chart[:3, :3], p[3:6])

    def Z(self, X: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.float64]:
        """The target's pose (target2base eye-in-hand, target2flange eye-to-hand)."""
        return self._target2world(p)

    def Z_std(self, p: NDArray[np.float64], cov_p: NDArray[np.float64]) -> NDArray[np.float64]:
        """The target pose's std (deg, mm)."""
        std = np.sqrt(np.clip(np.diag(cov_p)[:6], 0.0, None))
        return np.r_[np.degrees(std[:3]), 1e3 * std[3:6]]

    def noise_mm(self, rows: NDArray[np.intp]) -> NDArray[np.float64]:
        """The points' stated noise (px) at their pixel size (mm)."""
        mpp = self._mpp[rows] if self._mpp is not None else np.full(len(rows), np.nan)
        return 1e3 * self.noise_px * mpp


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

