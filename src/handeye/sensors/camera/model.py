"""An area camera's target corners in pixels as a sensor model (:mod:`handeye.sensors.base`).

Each view's corners are predicted through X, the target's pose and the flange pose: the target's
points mapped into the camera frame (``inv(A_i X) Z P``) and projected with the camera's intrinsics
(OpenCV's model, known: ``K``, ``dist``). The residuals (metres, at the target): the pixel error
times the pixel's size at the corner's depth (fixed at the start, so that the fit cannot shrink it
by moving away), each weighted by that size (``shape``: a corner's noise is pixels, so a far corner's
residual in metres is larger for the same pixel error; weighting the metres alike had put 14% more
error in a stereo pair's relative pose, bench_rig.py). The unknowns besides X: the target's pose (a
chart about its start). The start: each view's pose by PnP, then the closed form.

This is the model a rig's cameras share (:mod:`handeye.sensors.rig`); a single camera's images go
through :mod:`handeye.pipelines.calibration`, which also estimates the intrinsics.

Examples
--------
>>> import numpy as np
>>> from handeye.estimation.core import estimate
>>> from handeye.robot.models import ControllerPoses
>>> from handeye.pipelines.rig.simulate import rig_scene
>>> sc = rig_scene(12, "eye_in_hand", rng=0, cameras=1)
>>> cam = sc.cameras[0]
>>> model = CameraCorners("eye_in_hand", sc.names, cam.image_points, cam.object_points, cam.K, cam.dist)
>>> cal = estimate(model, ControllerPoses(sc.flange2base))
>>> bool(1e3 * np.abs(cal.X[:3, 3] - cam.X[:3, 3]).max() < 0.5)
True
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...errors import DegenerateMotionError, InputMismatchError
from ...frames.setups import check_setup, predicted_target2cam, robot_world_A_inv
from ...geometry.se3 import so3_left_jacobian
from ..target_pose import SECTION_PLANE_IMAGE, ChartedTarget, grid_curve
from .pnp import INTRINSICS, project_camera_points, projection_jacobians, solve_pnp
from .targets.base import Detection

__all__ = ["CameraCorners", "CAMERA_NOISE_PX"]

#: A corner's noise to state before any fit (px).
CAMERA_NOISE_PX = 0.3


class CameraCorners(ChartedTarget):
    """An area camera's views of a target (the module docstring).

    Parameters
    ----------
    setup : str
    names : list of str
        Per view its name (the image file).
    image_points : list of (n_i, 2) arrays
        Per view the corners found (px); a view may have none (the target not seen).
    object_points : list of (n_i, 3) arrays
        Their points in the target frame (m).
    K, dist : arrays
        The camera's intrinsics (OpenCV's model, up to 8 distortion coefficients; a longer model's
        terms beyond them must be zero).
    noise_px : float
        The corners' noise to state (px).
    refine_intrinsics : bool
        Also fit the intrinsics (fx, fy, cx, cy and OpenCV's five distortion terms k1 k2 p1 p2 k3,
        as increments of ``K``, ``dist``): for intrinsics estimated from the same images, which the
        robot's poses tie together far better than a camera calibration alone.
    """

    kind = "camera"
    target = "board"
    groups: tuple[tuple[int, ...], ...] = ((0, 1),)
    param_names = ["target.rx", "target.ry", "target.rz", "target.x", "target.y", "target.z"]

    def __init__(self, setup: str, names: list[str], image_points: list[NDArray[np.float64]],
                 object_points: list[NDArray[np.float64]], K: NDArray[np.float64], dist: NDArray[np.float64],
                 noise_px: float = CAMERA_NOISE_PX, refine_intrinsics: bool = False) -> None:
        self.setup = check_setup(setup)
        if not len(names) == len(image_points) == len(object_points):
            raise InputMismatchError(f"{len(names)} views, {len(image_points)} corner sets and {len(object_points)} point "
                                     "sets: give one of each per view (an empty one where the target was not seen)")
        self.names = list(names)
        self.uv = np.concatenate([np.asarray(c, float).reshape(-1, 2) for c in image_points])
        self.points = np.concatenate([np.asarray(p, float).reshape(-1, 3) for p in object_points])
        self.owner = np.concatenate([np.full(len(np.asarray(c).reshape(-1, 2)), k) for k, c in enumerate(image_points)]
                                    ).astype(np.intp)
        if len(self.points) != len(self.uv):
            raise InputMismatchError("each view needs one target point per corner")
        self.K, self.dist = np.asarray(K, float), np.asarray(dist, float).ravel()
        if len(self.dist) > 8:  # OpenCV's 12- and 14-term models: their thin prism and tilt terms are not modelled here
            if np.any(self.dist[8:]):
                raise InputMismatchError(f"{len(self.dist)} distortion coefficients with thin-prism or tilt terms: the pixel "
                                         "refinement models OpenCV's first 8 (k1 k2 p1 p2 k3 k4 k5 k6); calibrate the "
                                         "camera with the rational model (8 terms) or fewer")
            self.dist = self.dist[:8]
        self.refine_intrinsics = bool(refine_intrinsics)
        self.noise_px = float(noise_px)
        self.shape = np.ones((len(self.uv), 2))
        self.param_scale = np.full(6, 1e-3)
        if self.refine_intrinsics:
            if len(self.dist) > 5 and np.any(self.dist[5:]):
                raise InputMismatchError(f"{len(self.dist)} distortion coefficients: refining the intrinsics takes OpenCV's "
                                         "five (k1 k2 p1 p2 k3); give the intrinsics as known, or estimate them with five")
            self.param_names = CameraCorners.param_names + list(INTRINSICS)
            # ~1 mrad and ~1 mm of the pose move the pixels about as much as ~1 px of focal length or ~1e-3 of distortion
            self.param_scale = np.r_[self.param_scale, np.ones(4), np.full(5, 1e-3)]
        self._poses: NDArray[np.float64] | None = None

    @property
    def seen(self) -> NDArray[np.bool_]:
        """Per view whether it has corners."""
        return np.bincount(self.owner, minlength=len(self.names)) > 0

    def view_poses(self) -> NDArray[np.float64]:
        """Per view the target's pose in the camera frame by PnP (NaN for a view without corners)."""
        if self._poses is None:
            out = np.full((len(self.names), 4, 4), np.nan)
            for v in np.flatnonzero(self.seen):
                rows = self.owner == v
                got = solve_pnp(Detection(np.arange(int(rows.sum())), self.uv[rows], self.points[rows]), self.K, self.dist)
                if got is not None:
                    out[v] = got[0]
            self._poses = out
        return self._poses

    def start(self, flange2base, X, Z, rows=None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """X and the target from the closed form; the first start fixes the target's chart and each
        corner's pixel size."""
        if X is None or Z is None:
            raise DegenerateMotionError("a camera's start needs the views' poses (PnP on 3 views or more)")
        self._first_start(X, Z, flange2base, float(np.sqrt(self.K[0, 0] * self.K[1, 1])))
        return X, np.r_[self.target_params(Z), np.zeros(len(INTRINSICS) if self.refine_intrinsics else 0)]

    def intrinsics(self, p: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``K`` and ``dist`` at the unknowns ``p`` (as given unless they are refined)."""
        if not self.refine_intrinsics:
            return self.K, self.dist
        K = self.K.copy()
        K[[0, 1, 0, 1], [0, 1, 2, 2]] += p[6:10]
        dist = np.zeros(5)
        dist[:min(5, len(self.dist))] = self.dist[:5]
        return K, dist + p[10:15]

    def _in_camera(self, X, Z, flange2base, rows) -> NDArray[np.float64]:
        target2cam = predicted_target2cam(X, Z, np.asarray(flange2base, float), self.setup)[self.owner[rows]]
        return np.einsum("mij,mj->mi", target2cam[:, :3, :3], self.points[rows]) + target2cam[:, :3, 3]

    def residuals(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """Per corner (m): its pixel error times the pixel's size at its depth."""
        cam = self._in_camera(X, self._target2world(p), flange2base, rows)
        return (project_camera_points(cam, *self.intrinsics(p)) - self.uv[rows]) * self._pixel_size(rows)[:, None]

    def jacobian(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """The residuals' derivatives (M, 2, 12; 21 with the intrinsics) for a left increment of X (rotation ``a``, translation
        ``b``: ``R_X -> exp(a) R_X``, ``t_X -> t_X + b``) and the target's unknowns (its chart's
        rotation vector ``r`` and its translation): a corner in the camera frame is
        ``c = R_X^T (q - t_X)`` with ``q = inv(A_i) Z P``, so ``dc/da = R_X^T [q - t_X]x``,
        ``dc/db = -R_X^T``, and through ``Z P = exp(r) R_chart P + t``, ``dc/dr = -R_X^T R_W [exp(r)
        R_chart P]x J_l(r)`` (SO(3)'s left Jacobian), ``dc/dt = R_X^T R_W``; times the projection's
        derivatives (:func:`~handeye.sensors.camera.pnp.projection_jacobians`) and the pixel's size;
        then the projection's own derivatives by the intrinsics when they are refined."""
        owner = self.owner[rows]
        W = robot_world_A_inv(np.asarray(flange2base, float), self.setup)  # per view, indexed per corner below
        Z = self._target2world(p)
        u = self.points[rows] @ Z[:3, :3].T  # the points turned into the world, before Z's translation
        q = np.einsum("mij,mj->mi", W[owner, :3, :3], u + Z[:3, 3]) + W[owner, :3, 3]
        v = q - X[:3, 3]
        R_t = X[:3, :3].T
        _, d_point, d_intrinsics = projection_jacobians(v @ X[:3, :3], *self.intrinsics(p), intrinsics=self.refine_intrinsics)
        m = len(rows)
        # rows a^T [w]x = (a x w)^T: the pixel's derivative by the camera point, times R_X^T (a) or R_X^T R_W (b)
        a = (d_point.reshape(-1, 3) @ R_t).reshape(m, 2, 3)
        b = np.matmul(d_point, (R_t @ W[:, :3, :3])[owner])
        jac = np.empty((m, 2, 12))
        _cross_rows(a, v, out=jac[:, :, 0:3])
        np.negative(a, out=jac[:, :, 3:6])
        jac[:, :, 6:9] = -(_cross_rows(b, u).reshape(-1, 3) @ so3_left_jacobian(p[:3])).reshape(m, 2, 3)
        jac[:, :, 9:12] = b
        if self.refine_intrinsics:
            jac = np.concatenate([jac, d_intrinsics], axis=2)
        jac *= self._pixel_size(rows)[:, None, None]
        return jac

    def pixel_size(self, rows: NDArray[np.intp]) -> NDArray[np.float64]:
        """Per corner of ``rows`` its pixel's size (m) at its depth: its residual over it is pixels."""
        return self._pixel_size(rows)

    def figures(self, p, cov_p) -> dict[str, Any]:
        """The intrinsics used (known, or refined with their std)."""
        K, dist = self.intrinsics(p)
        out: dict[str, Any] = {"K": K.tolist(), "dist": np.asarray(dist).tolist()}
        if self.refine_intrinsics:
            out["intrinsics_std"] = dict(zip(INTRINSICS, np.sqrt(np.clip(np.diag(cov_p)[6:15], 0.0, None)).tolist()))
        return out

    def notes(self, p, cov_p) -> list[str]:
        """Nothing beyond the core's own notes."""
        return []

    def sections(self, X, p, flange2base, views) -> list[dict[str, Any]]:
        """Per view of ``views`` what the report draws of it (:class:`~handeye.result.SensorFit`'s
        ``sections``): its image in mm at the target (pixels times the view's median pixel size), the
        corners as found with their error's size (mm), and the target's grid through the corners
        projected through X (none where the view saw nothing)."""
        out = []
        for v in views:
            rows = np.flatnonzero(self.owner == v)
            r = self.residuals(X, p, flange2base, rows) if len(rows) else np.zeros((0, 2))
            mpp = float(np.median(self._pixel_size(rows))) if len(rows) else 1.0
            fitted = (self.uv[rows] + r / self._pixel_size(rows)[:, None]) * mpp
            out.append({"points_mm": 1e3 * self.uv[rows] * mpp, "residual_mm": 1e3 * np.linalg.norm(r, axis=1),
                        "curve_mm": 1e3 * grid_curve(self.points[rows], fitted), "plane": SECTION_PLANE_IMAGE})
        return out


def _cross_rows(a: NDArray[np.float64], w: NDArray[np.float64], out: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """``a[m, r] x w[m]`` for rows ``a`` (M, R, 3) and vectors ``w`` (M, 3): ``a^T [w]x`` row by row (into ``out``)."""
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    wx, wy, wz = w[:, None, 0], w[:, None, 1], w[:, None, 2]
    out = np.empty(a.shape) if out is None else out
    out[..., 0] = ay * wz - az * wy
    out[..., 1] = az * wx - ax * wz
    out[..., 2] = ax * wy - ay * wx
    return out
