"""A depth camera's measurements as sensor models (:mod:`handeye.sensors.base`).

Depth cameras are off in their own ways: a depth scale (a factor near 1: the projector-camera
baseline or the depth unit slightly wrong) and a depth bias (an offset along the rays). Both are
unknowns of the model beside the target's pose (a board) or centres (spheres):

    q_measured = (s + b / z) * p,    p = the target's point predicted in the camera frame

(``p`` scaled along its own ray so that its depth becomes ``s z + b``). Residuals are metres, in
each point's ray frame (along the ray, two directions across), so that the depth noise (growing
with the square of the distance, :func:`~handeye.sensors.depth.clouds.depth_sigma`) and the noise
across the rays each get their own scale.

* :class:`BoardPoints`: a board's corners lifted to 3D (p: Z's increment (6), then s - 1 and b);
* :class:`SphereCentres`: the centres of one or more balls found in the clouds (p: each centre in
  Z's frame (3 per ball), then s - 1 and b); Z is the first ball's centre.

Examples
--------
>>> import numpy as np
>>> from handeye.sensors.depth.model import SphereCentres
>>> model = SphereCentres("eye_to_hand", ["a", "b", "c"], np.array([[0.0, 0.0, 0.8], [0.1, 0.0, 0.7], [0.0, 0.1, 0.9]]))
>>> model.param_names
['centre1.x', 'centre1.y', 'centre1.z', 'depth.scale-1', 'depth.bias']
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ...errors import DegenerateMotionError, HandEyeError, InputMismatchError
from ...frames.setups import check_setup, predicted_target2cam, robot_world_A
from ...geometry.se3 import make_transform, perturb
from ..base import Nuisance
from ..camera.pnp import relabel_points
from ..target_pose import grid_curve
from .clouds import board_pose, depth_sigma

__all__ = ["BoardPoints", "SphereCentres", "LATERAL", "SECTION_POINTS", "ray_frames", "DEPTH_SCALE_TOLERANCE",
           "DEPTH_BIAS_TOLERANCE_M"]

#: How far a depth camera's scale and bias may be off their nominal 1 and 0 (one std): a
#: structured-light or stereo camera's depth trueness, a few tenths of a percent and a millimetre or
#: two (what the core holds them at, with this in X's std, when a capture does not determine them).
DEPTH_SCALE_TOLERANCE, DEPTH_BIAS_TOLERANCE_M = 0.005, 0.002

#: Noise across the rays, per metre of depth, to start from (0.2 px at a focal length of ~700 px).
LATERAL = 3e-4
#: Most points of a view the report draws (:meth:`DepthRows.sections`).
SECTION_POINTS = 1500


def ray_frames(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """(M, 3, 3): rows along each point's ray and two unit directions across it."""
    along = points / np.linalg.norm(points, axis=1, keepdims=True)
    helper = np.where(np.abs(along[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    first = np.cross(along, helper)
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    return np.stack([along, first, np.cross(along, first)], axis=1)


def as_measured(p: NDArray[np.float64], scale_step: float, bias: float,
                radius: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """Points ``p`` (M, 3) as the camera measures them: scaled along their rays to depth ``s z + b``
    (``scale_step`` = s - 1); with ``radius`` (M,), centres of spheres fitted with that radius to a
    cap whose depths are so scaled, which lie ``(s - 1) r`` short along their rays."""
    q = p * (1.0 + scale_step + bias / p[:, 2])[:, None]
    if radius is None:
        return q
    return q - (scale_step * radius)[:, None] * p / np.linalg.norm(p, axis=1, keepdims=True)


def depth_figures(p: NDArray[np.float64], cov_p: NDArray[np.float64], fit_depth: bool) -> dict[str, Any]:
    """The depth scale and bias with their std (the last two of ``p``), as the result's figures."""
    if not fit_depth:
        return {"depth_scale": {"value": 1.0, "std": 0.0, "fitted": False},
                "depth_bias_mm": {"value": 0.0, "std": 0.0, "fitted": False}}
    std = np.sqrt(np.clip(np.diag(cov_p)[-2:], 0.0, None))
    return {"depth_scale": {"value": float(1.0 + p[-2]), "std": float(std[0]), "fitted": True},
            "depth_bias_mm": {"value": float(1e3 * p[-1]), "std": float(1e3 * std[1]), "fitted": True}}


class DepthRows:
    """What the depth models share: rows of 3D points in their ray frames, weighted by depth (the
    mesh's too, :class:`~handeye.sensors.depth.mesh.MeshSurface`)."""

    kind = "depth camera"
    groups: tuple[tuple[int, ...], ...] = ((0,), (1, 2))
    fit_depth = True
    # the members of the model it is part of (:class:`~handeye.sensors.base.SensorModel`)
    param_names: list[str]
    owner: NDArray[np.intp]
    residuals: Callable[..., NDArray[np.float64]]

    @property
    def nuisances(self) -> tuple[Nuisance, ...]:
        """The depth scale and bias (the last two of ``p``, when fitted): nominal 1 and 0."""
        if not self.fit_depth:
            return ()
        k = len(self.param_names) - 2
        return (Nuisance("depth_scale", k, 0.0, DEPTH_SCALE_TOLERANCE, offset=1.0),
                Nuisance("depth_bias", k + 1, 0.0, DEPTH_BIAS_TOLERANCE_M, unit="mm", scale=1e3))

    def notes(self, p, cov_p) -> list[str]:
        """The depth scale and bias when they differ from 1 and 0 beyond 3 std."""
        f = depth_figures(p, cov_p, self.fit_depth)
        scale, bias = f["depth_scale"], f["depth_bias_mm"]
        out = []
        if self.fit_depth and abs(scale["value"] - 1.0) > 3 * scale["std"]:
            out.append(f"depth scale {scale['value']:.5f} +- {scale['std']:.5f}: the camera's depths are "
                       f"{1e2 * (scale['value'] - 1):+.3f}% off (beyond 3 std); correct the depth unit or the camera's "
                       "calibration, or keep this factor")
        if self.fit_depth and abs(bias["value"]) > 3 * bias["std"]:
            out.append(f"depth bias {bias['value']:+.2f} +- {bias['std']:.2f} mm along the rays (beyond 3 std)")
        return out

    def _rays(self, measured: NDArray[np.float64]) -> None:
        self.measured = measured
        self.basis = ray_frames(measured)

    def _residual(self, predicted: NDArray[np.float64], rows: NDArray[np.intp]) -> NDArray[np.float64]:
        return np.einsum("mij,mj->mi", self.basis[rows], self.measured[rows] - predicted)

    def noise_mm(self, rows: NDArray[np.intp]) -> NDArray[np.float64]:
        """The depth noise at each row's depth (mm)."""
        return 1e3 * depth_sigma(self.measured[rows, 2])

    def sections(self, X, p, flange2base, views, max_points: int = SECTION_POINTS) -> list[dict[str, Any]]:
        """Per view of ``views`` what the report draws of it (:class:`~handeye.result.SensorFit`'s
        ``sections``): in its image, mm at the target (each point's ``x / z`` and ``y / z`` times the
        view's median depth), at most ``max_points`` of its points (evenly taken) with their residual
        (a surface's signed distance, or the size of a point's error; mm), and the target drawn where
        the fit puts it (:meth:`_section_curve`)."""
        F = np.asarray(flange2base, float)
        out = []
        for v in views:
            rows = np.flatnonzero(self.owner == v)
            rows = rows[np.linspace(0, len(rows) - 1, min(len(rows), max_points)).astype(np.intp)] if len(rows) else rows
            r = self.residuals(X, p, F, rows) if len(rows) else np.zeros((0, 1))
            q = self.measured[rows]
            depth = float(np.median(q[:, 2])) if len(rows) else 1.0
            curve = self._section_curve(X, p, F, v, rows, r)
            out.append({"points_mm": 1e3 * depth * q[:, :2] / q[:, 2:],
                        "residual_mm": 1e3 * (r[:, 0] if r.shape[1] == 1 else np.linalg.norm(r, axis=1)),
                        "curve_mm": 1e3 * depth * curve[:, :2] / curve[:, 2:], "plane": "its image (mm at the target)"})
        return out

    def _section_curve(self, X, p, flange2base, view: int, rows: NDArray[np.intp], r: NDArray[np.float64]
                       ) -> NDArray[np.float64]:
        """The target as the report draws it in view ``view``'s camera frame (m; NaN rows between lines):
        nothing by default (the points' residuals show the fit)."""
        return np.full((1, 3), np.nan)

    def _predicted(self, rows: NDArray[np.intp], r: NDArray[np.float64]) -> NDArray[np.float64]:
        """Where the fit puts the points of ``rows`` (camera frame, m), from their residuals ``r`` in
        their ray frames: the measured point less the residual turned back out of its frame."""
        return self.measured[rows] - np.einsum("mji,mj->mi", self.basis[rows], r)


class BoardPoints(DepthRows):
    """A board's corners (in its own frame, ``object_points`` per view) measured in 3D (``points``
    per view, NaN rows: no depth), with the depth scale and bias (``fit_depth``).

    The noise along a ray is the depth noise and a corner found off its place along the board
    (which moves along the ray by tan(ray, normal)); across, the corner's pixel noise times the depth.
    """

    target = "board"

    def __init__(self, setup: str, names: list[str], object_points: list[NDArray[np.float64]],
                 points: list[NDArray[np.float64]], fit_depth: bool = True) -> None:
        self.setup = check_setup(setup)
        if not len(names) == len(object_points) == len(points):
            raise InputMismatchError(f"{len(names)} views, {len(object_points)} point sets and {len(points)} lifted sets: "
                                     "give one of each per view")
        self.names, self.fit_depth = list(names), fit_depth
        # a view with fewer than 4 corners in depth has no pose and no rows (a rig's sensor that missed it)
        keep = [np.isfinite(np.asarray(q, float).reshape(-1, 3)).all(axis=1) for q in points]
        keep = [k if k.sum() >= 4 else np.zeros_like(k) for k in keep]
        self.poses = np.array([board_pose(o, q)[0] if k.any() else np.full((4, 4), np.nan)
                               for o, q, k in zip(object_points, points, keep)])
        self.obj = np.concatenate([np.asarray(o, float).reshape(-1, 3)[k] for o, k in zip(object_points, keep)])
        self._rays(np.concatenate([np.asarray(q, float).reshape(-1, 3)[k] for q, k in zip(points, keep)]))
        self.owner = np.repeat(np.arange(len(names)), [int(k.sum()) for k in keep])
        z = self.measured[:, 2]
        normals = self.poses[self.owner, :3, 2]
        cos = np.clip(np.abs(np.einsum("mi,mi->m", self.basis[:, 0], normals)), 0.2, 1.0)
        along = np.sqrt(depth_sigma(z) ** 2 + (LATERAL * z) ** 2 * (1.0 / cos**2 - 1.0))
        self.shape = np.stack([along, LATERAL * z, LATERAL * z], axis=1)
        self.param_names = [f"Z.{k}" for k in ("rx", "ry", "rz", "x", "y", "z")] + (
            ["depth.scale-1", "depth.bias"] if fit_depth else [])
        self.param_scale = np.r_[np.full(6, 1e-3), [1e-3, 1e-3] if fit_depth else []]
        self._Zref: NDArray[np.float64] = None  # type: ignore[assignment]  # the board's pose the unknowns move it from (first start)

    def view_poses(self) -> NDArray[np.float64]:
        """The board's pose in each view, a rigid fit to its lifted corners."""
        return self.poses

    def relabelled(self, F: NDArray[np.float64]) -> "BoardPoints":
        """The same views with the board's corners named in the frame of the labelling ``T @ F`` (a
        symmetric board read from the other end: its points ``F^-1 p``, its poses ``T F``), before any start."""
        if self._Zref is not None:
            raise HandEyeError("a board's labelling is turned before its first start, not after (its unknowns are anchored)")
        out = copy.copy(self)
        out.obj = relabel_points(self.obj, F)
        out.poses = self.poses @ F
        return out

    def start(self, flange2base, X, Z, rows=None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The closed form's X and Z; the depth exact. The first start's Z is the reference the
        board's unknowns move it from (a rotation vector on the left, a translation)."""
        Z = np.asarray(Z, dtype=float)
        if self._Zref is None:  # the anchor: kept by every later start (a fold's unknowns in the same terms)
            self._Zref = Z
        return np.asarray(X, dtype=float), np.r_[self.target_params(Z), np.zeros(len(self.param_names) - 6)]

    def target_params(self, Z: NDArray[np.float64]) -> NDArray[np.float64]:
        """The unknowns that move the reference pose to the board's pose ``Z`` (after the first start;
        a rig's other sensors map a shared board into them)."""
        self._reference()
        return np.r_[Rotation.from_matrix(Z[:3, :3] @ self._Zref[:3, :3].T).as_rotvec(), Z[:3, 3] - self._Zref[:3, 3]]

    def Z(self, X, p) -> NDArray[np.float64]:
        """The board's pose: the reference moved by ``p[:6]``."""
        return perturb(self._reference(), p[0:3], p[3:6])

    def _reference(self) -> NDArray[np.float64]:
        """The board's pose its unknowns move it from: the first start's (refused before it)."""
        if self._Zref is None:
            raise DegenerateMotionError("the board's pose has no start yet: its unknowns are moves from the first start's")
        return self._Zref

    def residuals(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """Measured minus predicted corners, in their ray frames (m)."""
        owner = self.owner[rows]
        views = np.unique(owner)
        T = np.zeros((len(flange2base), 4, 4))
        T[views] = predicted_target2cam(X, self.Z(X, p), flange2base[views], self.setup)
        q = np.einsum("mij,mj->mi", T[owner, :3, :3], self.obj[rows]) + T[owner, :3, 3]
        if self.fit_depth:
            q = as_measured(q, p[6], p[7])
        return self._residual(q, rows)

    def Z_std(self, p, cov_p) -> NDArray[np.float64]:
        """The board pose's std (deg, mm) from ``p``'s covariance."""
        s = np.sqrt(np.clip(np.diag(cov_p)[:6], 0.0, None))
        return np.r_[np.degrees(s[:3]), 1e3 * s[3:]]

    def figures(self, p, cov_p) -> dict[str, Any]:
        """The depth scale and bias."""
        return depth_figures(p, cov_p, self.fit_depth)

    def _section_curve(self, X, p, flange2base, view, rows, r) -> NDArray[np.float64]:
        """The board's grid through its corners where the fit puts them."""
        return grid_curve(self.obj[rows], self._predicted(rows, r))


class SphereCentres(DepthRows):
    """The centres of ``K`` balls measured in each view (``centres`` (N, 3) or (N, K, 3), NaN: not
    seen), with their covariances (``covariances``, their shape weights each centre: the cap a
    camera sees pins a ball least along the ray; default the depth noise along the ray, a third of
    it across), the balls' radii (a centre fitted with the true radius to a cap whose depths are
    scaled by ``s`` lies ``(s - 1) r`` short along its ray) and the depth scale and bias."""

    target = "spheres"

    def __init__(self, setup: str, names: list[str], centres: NDArray[np.float64],
                 covariances: NDArray[np.float64] | None = None, radii: NDArray[np.float64] | None = None,
                 fit_depth: bool = True) -> None:
        self.setup = check_setup(setup)
        C = np.asarray(centres, dtype=float)
        C = C[:, None] if C.ndim == 2 else C
        if C.ndim != 3 or C.shape[2] != 3 or len(C) != len(names):
            raise InputMismatchError(f"{len(names)} views and centres of shape {np.shape(centres)}: give one centre "
                                     "(3,) per view and sphere, (N, 3) or (N, K, 3)")
        self.names, self.fit_depth = list(names), fit_depth
        self.n_spheres = C.shape[1]
        view, sphere = np.nonzero(np.isfinite(C).all(axis=2))
        self.owner, self.sphere = view, sphere
        self._rays(C[view, sphere])
        if covariances is None:
            self.shape = depth_sigma(self.measured[:, 2])[:, None] * np.array([1.0, 1 / 3, 1 / 3])
            self.groups = ((0, 1, 2),)
        else:  # each centre's covariance: residuals along its principal axes (metric), its std there the shape
            cov = np.asarray(covariances, dtype=float)
            cov = (cov[:, None] if cov.ndim == 3 else cov)[view, sphere]
            lam, V = np.linalg.eigh(0.5 * (cov + np.swapaxes(cov, 1, 2)))
            self.basis = np.swapaxes(V, 1, 2)
            self.shape = np.sqrt(np.maximum(lam, 1e-18))
            self.groups = ((0, 1, 2),)
        self.radius = None if radii is None else np.asarray(radii, float)[sphere]
        self.param_names = [f"centre{k + 1}.{a}" for k in range(self.n_spheres) for a in "xyz"] + (
            ["depth.scale-1", "depth.bias"] if fit_depth else [])
        self.param_scale = np.r_[np.full(3 * self.n_spheres, 1e-3), [1e-3, 1e-3] if fit_depth else []]

    def view_poses(self) -> None:
        """A ball has no orientation: no per-view pose."""
        return None

    def start(self, flange2base, X, Z, rows=None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """X and the centres from ``A_i X c = p_k`` on ``rows`` (default all; linear in R_X, t_X and
        the p_k; R_X then made a rotation and the rest solved again), or DegenerateMotionError."""
        A = robot_world_A(np.asarray(flange2base, dtype=float), self.setup)
        rows = np.arange(len(self.owner)) if rows is None else np.asarray(rows)
        X0, p0 = sphere_start(A, self.measured[rows], self.owner[rows], self.sphere[rows], self.n_spheres)
        return X0, np.r_[p0.ravel(), [0.0, 0.0] if self.fit_depth else []]

    def centres(self, p) -> NDArray[np.float64]:
        """(K, 3): each ball's centre in Z's frame (m)."""
        return np.asarray(p[:3 * self.n_spheres]).reshape(self.n_spheres, 3)

    def Z(self, X, p) -> NDArray[np.float64]:
        """The first ball's centre (a translation: a ball has no orientation)."""
        return make_transform(np.eye(3), self.centres(p)[0])

    def residuals(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """Measured minus predicted centres, in their ray frames (or whitened by their covariance)."""
        owner = self.owner[rows]
        c = self.centres(p)[self.sphere[rows]]
        Z = np.broadcast_to(np.eye(4), (len(rows), 4, 4)).copy()
        Z[:, :3, 3] = c
        q = predicted_target2cam(X, Z, flange2base[owner], self.setup)[:, :3, 3]
        if self.fit_depth:
            q = as_measured(q, p[-2], p[-1], None if self.radius is None else self.radius[rows])
        return self._residual(q, rows)

    def Z_std(self, p, cov_p) -> NDArray[np.float64]:
        """The first centre's std (mm); a ball's orientation is not defined (NaN)."""
        return np.r_[np.full(3, np.nan), 1e3 * np.sqrt(np.clip(np.diag(cov_p)[:3], 0.0, None))]

    def figures(self, p, cov_p) -> dict[str, Any]:
        """The balls' centres (m, and their std in mm) and the depth scale and bias."""
        std = 1e3 * np.sqrt(np.clip(np.diag(cov_p)[:3 * self.n_spheres], 0.0, None)).reshape(self.n_spheres, 3)
        return {"centres_m": self.centres(p).tolist(), "centres_std_mm": std.tolist(),
                "radii_m": None if self.radius is None else sorted({float(r) for r in self.radius}),
                **depth_figures(p, cov_p, self.fit_depth)}

    def _section_curve(self, X, p, flange2base, view, rows, r) -> NDArray[np.float64]:
        """Each ball's outline where the fit puts its centre (a circle of its radius across the ray; a
        cross of 5 mm when the radius is not known)."""
        centres = self._predicted(rows, r)
        out = []
        for k, c in zip(rows, centres):
            ray = ray_frames(c[None])[0]
            if self.radius is None:
                out += [c - 0.005 * ray[1], c + 0.005 * ray[1], [np.nan] * 3, c - 0.005 * ray[2], c + 0.005 * ray[2]]
            else:
                t = np.linspace(0, 2 * np.pi, 73)[:, None]
                out += list(c + self.radius[k] * (np.cos(t) * ray[1] + np.sin(t) * ray[2]))
            out.append([np.nan] * 3)
        return np.array(out, float).reshape(-1, 3) if out else np.full((1, 3), np.nan)


def sphere_start(A: NDArray[np.float64], centres: NDArray[np.float64], view: NDArray[np.intp],
                 sphere: NDArray[np.intp], n_spheres: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """X and the spheres' centres from ``A_i X c = p_k`` with ``A_i`` the robot-world poses
    (:func:`~handeye.frames.setups.robot_world_A`) and ``c`` the centres measured in the sensor frame
    (linear in R_X, t_X and the p_k; R_X then made a rotation and the rest solved again), or
    DegenerateMotionError."""
    m = len(centres)
    R_A, t_A = A[view, :3, :3], A[view, :3, 3]
    cols = 12 + 3 * n_spheres
    M: NDArray[np.float64] = np.zeros((m, 3, cols))
    M[:, :, :9] = np.einsum("mij,mk->mijk", R_A, centres).reshape(m, 3, 9)  # R_A (R_X c), R_X row-major
    M[:, :, 9:12] = R_A
    for axis in range(3):
        M[np.arange(m), axis, 12 + 3 * sphere + axis] = -1.0
    M = M.reshape(3 * m, cols)
    rhs = -t_A.reshape(-1)
    sv = np.linalg.svd(M, compute_uv=False)
    if 3 * m < cols or sv[-1] < 1e-6 * sv[0]:
        raise DegenerateMotionError(
            f"the sphere's centres in {len(np.unique(view))} views do not determine X ({3 * m} equations for {cols} "
            "unknowns, or the robot turned about one axis only): capture more views, turning the flange about "
            "at least two different axes by 30 deg or more, with the sphere in different parts of the image")
    sol = np.linalg.lstsq(M, rhs, rcond=None)[0]
    U, _, Vt = np.linalg.svd(sol[:9].reshape(3, 3))
    R_X = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    rest = np.linalg.lstsq(M[:, 9:], rhs - M[:, :9] @ R_X.ravel(), rcond=None)[0]
    return make_transform(R_X, rest[:3]), rest[3:].reshape(n_spheres, 3)
