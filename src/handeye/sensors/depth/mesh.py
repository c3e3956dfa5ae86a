"""A known shape's surface in depth clouds as a sensor model (:mod:`handeye.sensors.base`):
:class:`MeshSurface`.

Every point a view's cloud has on the shape's surface (:func:`~handeye.sensors.depth.registration.find_shape`)
is a measurement row; its residual is its signed distance from the surface along the surface's
normal (the nearest of the shape's dense samples, found again at every evaluation), after the
point is moved back along its ray by the depth scale and bias (as for spheres and boards:
``depth_measured = s z + b``) and carried into the shape's frame through X, the shape's pose Z and
the flange pose. The unknowns: X, Z (target2flange eye-to-hand, target2base eye-in-hand; none when
the session gives the shape's placement, ``pose_in_flange`` / ``pose_in_base``) and the depth scale
and bias.

A shape that slides along itself (:func:`~handeye.sensors.depth.shape.free_twists`: a plain
disc's rotation about its axis, a plate's in-plane motion) leaves those directions of Z
undetermined: Z's unknowns are the others only (held, named in the notes, their std NaN). With the
placement given, what it leaves undetermined of X is what the capture cannot tell, and the core
names it (a disc seen along one direction only, translations alone: X's rotation about that axis).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ...errors import DegenerateMotionError, InputMismatchError
from ...frames.setups import check_setup, predicted_target2cam, robot_world_A, setup_info
from ...geometry.se3 import invert, make_transform, so3_left_jacobian
from .clouds import depth_sigma
from .model import LATERAL, DepthRows, depth_figures, sphere_start
from .shape import NearestSamples, Shape, twist_axis

__all__ = ["MeshSurface", "twist", "KEPT"]

#: The fit remembers this many nearest samples of the shape per point
#: (:class:`~handeye.sensors.depth.shape.NearestSamples`; the nearest one is the point's): the core's fit
#: of the simulator's disc on a UR5's joint angles (15 clouds) took 2.6x less CPU than with a new search
#: at every step (5 kept: 2.3x).
KEPT = 3


def twist(xi: NDArray[np.float64]) -> NDArray[np.float64]:
    """The transform of a twist ``xi`` (6: rotation vector rad, translation m; (..., 6) batched)."""
    xi = np.asarray(xi, float)
    return make_transform(Rotation.from_rotvec(xi[..., :3].reshape(-1, 3)).as_matrix().reshape(xi.shape[:-1] + (3, 3)),
                          xi[..., 3:])


class MeshSurface(DepthRows):
    """The points of a known shape's surface in each view (``points``: per view (m_i, 3), camera
    frame, m; ``normals``: the surface's normal at each, shape frame, for their noise) against the
    shape (:class:`~handeye.sensors.depth.shape.Shape`), with each view's pose of the shape
    (``poses``: target2cam (N, 4, 4), NaN where not known; the start's closed form), the shape's
    placement when known (``placement``: Z) and the depth scale and bias (``fit_depth``).

    The noise along a point's normal: the depth noise times the cosine between its ray and the
    normal, and the noise across the rays (:data:`~handeye.sensors.depth.model.LATERAL`) times its sine.
    """

    target = "mesh"
    groups: tuple[tuple[int, ...], ...] = ((0,),)
    #: what fixes a direction of X the capture leaves free (pure translations: X's translation)
    undetermined_fix = ("give the shape's placement (pose_in_flange eye-to-hand, pose_in_base eye-in-hand, in session.yaml's "
                        "target:), which makes each view give X whole; or turn the flange 30 deg or more about two axes "
                        "between views")

    def __init__(self, setup: str, names: list[str], shape: Shape, points: list[NDArray[np.float64]],
                 normals: list[NDArray[np.float64]], poses: NDArray[np.float64], placement: NDArray[np.float64] | None = None,
                 fit_depth: bool = True) -> None:
        self.setup = check_setup(setup)
        if not len(names) == len(points) == len(normals) == len(poses):
            raise InputMismatchError(f"{len(names)} views, {len(points)} point sets, {len(normals)} normal sets and "
                                     f"{len(poses)} poses: give one of each per view")
        self.names, self.shape_model, self.fit_depth = list(names), shape, fit_depth
        self.poses = np.asarray(poses, float)
        self.placement = None if placement is None else np.asarray(placement, float)
        self._rays(np.concatenate([np.asarray(q, float).reshape(-1, 3) for q in points]))
        self.owner = np.repeat(np.arange(len(names)), [len(q) for q in points])
        n_shape = np.concatenate([np.asarray(n, float).reshape(-1, 3) for n in normals])
        safe = np.where(np.isfinite(self.poses), self.poses, np.eye(4))
        n_cam = np.einsum("mij,mj->mi", safe[self.owner, :3, :3], n_shape)
        cos = np.clip(np.abs(np.einsum("mi,mi->m", self.basis[:, 0], n_cam)), 0.0, 1.0)
        z = self.measured[:, 2]
        self.shape = np.sqrt((depth_sigma(z) * cos) ** 2 + (LATERAL * z) ** 2 * (1.0 - cos**2))[:, None]
        self.free = shape.free
        self.basis_Z = _complement(shape.free, shape.radius) if placement is None else np.zeros((6, 0))
        k = self.basis_Z.shape[1]
        self.param_names = [f"Z.d{i + 1}" for i in range(k)] + (["depth.scale-1", "depth.bias"] if fit_depth else [])
        self.param_scale = np.r_[np.full(k, 1e-3), [1e-3, 1e-3] if fit_depth else []]
        self._Zref: NDArray[np.float64] = self.placement  # type: ignore[assignment]  # None until the first start without one
        self._nearest = NearestSamples(len(self.owner), 1, KEPT)

    @property
    def n_z(self) -> int:
        """Z's unknowns (6 less what the shape leaves free; 0 with the placement given)."""
        return self.basis_Z.shape[1]

    def view_poses(self) -> NDArray[np.float64] | None:
        """Each view's pose of the shape, when the core's closed form can use them (the placement
        unknown and the shape determining a whole pose); else None (the model's own start)."""
        return self.poses if self.placement is None and not len(self.free) else None

    def start(self, flange2base, X, Z, rows=None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The core's closed form X and Z (the first start's Z the reference Z's unknowns move it
        from); without them the model's own: with the placement known, each view's X from it and
        its pose, averaged; for a shape that turns into itself, X and a point on its axis from the
        points' positions (as spheres' centres), Z's axis from the views' poses."""
        F = np.asarray(flange2base, float)
        rows = np.arange(len(self.owner)) if rows is None else np.asarray(rows)
        views = np.unique(self.owner[rows])
        views = views[np.isfinite(self.poses[views]).all(axis=(1, 2))]
        depth = np.zeros(2 if self.fit_depth else 0)
        if X is not None:
            self._anchor(np.asarray(Z, float))
            return np.asarray(X, float), np.r_[self._z_coordinates(np.asarray(Z, float)), depth]
        if len(views) < 2:
            raise DegenerateMotionError(f"{len(views)} views with the shape's pose: at least 2 are needed to start")
        A = robot_world_A(F[views], self.setup)
        if self.placement is not None:  # each view's points of the shape in both frames: X maps one onto the other
            return _rigid(self.poses[views] @ self._anchors(), invert(A) @ self.placement @ self._anchors()), depth
        axis_point = self.shape_model.centre if len(self.free) else np.zeros(3)
        c = self.poses[views, :3, :3] @ axis_point + self.poses[views, :3, 3]
        X0, centre = sphere_start(A, c, np.arange(len(views)), np.zeros(len(views), dtype=np.intp), 1)
        Z_i = A @ X0 @ self.poses[views]
        Z0 = Z_i[0].copy()
        Z0[:3, 3] = centre[0] - Z0[:3, :3] @ axis_point
        # Z's unknowns from the reference the first start fixed (a fold's start had moved the reference the
        # whole fit's unknowns are from: its Z 9 um off after cross-validation on a plain disc's capture)
        first = self._Zref is None
        self._anchor(Z0)
        return X0, np.r_[np.zeros(self.n_z) if first else self._z_coordinates(Z0), depth]

    def _anchor(self, Z: NDArray[np.float64]) -> None:
        """The reference Z's unknowns move it from: the first start's Z (or the placement given), kept."""
        if self._Zref is None:
            self._Zref = np.array(Z, dtype=float)

    def _anchors(self) -> NDArray[np.float64]:
        """Points of the shape (4, k, homogeneous) that no free motion of it moves: the corners of a
        tetrahedron about its centre; on its axis when it turns into itself; its centre alone for a ball."""
        shape = self.shape_model
        rot = self.free[np.linalg.norm(self.free[:, :3], axis=1) > 1e-9]
        if len(rot) == 1:
            a, c = twist_axis(rot[0])
            c = c + a * float((shape.centre - c) @ a)
            pts = [c - 0.5 * shape.radius * a, c + 0.5 * shape.radius * a]
        elif len(rot) >= 3:
            pts = [shape.centre]
        else:
            pts = [shape.centre + 0.5 * shape.radius * d for d in np.eye(3)] + [shape.centre]
        return np.r_[np.array(pts).T, np.ones((1, len(pts)))]

    def _z_coordinates(self, Z: NDArray[np.float64]) -> NDArray[np.float64]:
        """Z's unknowns that move the reference to ``Z`` (least squares in the shape's metric)."""
        if not self.n_z:
            return np.zeros(0)
        D = invert(self._Zref) @ Z
        xi = np.r_[Rotation.from_matrix(D[:3, :3]).as_rotvec(), D[:3, 3]]
        return np.asarray(np.linalg.lstsq(self.basis_Z, xi, rcond=None)[0], dtype=float)

    def Z(self, X, p) -> NDArray[np.float64]:
        """The shape's pose: its placement, or the reference moved by Z's unknowns."""
        if self._Zref is None:
            raise DegenerateMotionError("the shape's pose has no start yet")
        return self._Zref @ twist(self.basis_Z @ np.asarray(p[:self.n_z], float)) if self.n_z else self._Zref

    def _points(self, X, p, flange2base, rows):
        """The rows' points moved back along their rays by the depth scale and bias, the views'
        target2cam per row (M, 4, 4), and the points in the shape's frame."""
        owner = self.owner[rows]
        views = np.unique(owner)
        T = np.zeros((len(flange2base), 4, 4))
        T[views] = predicted_target2cam(X, self.Z(X, p), flange2base[views], self.setup)
        q = self.measured[rows]
        if self.fit_depth:
            s, b = 1.0 + p[-2], p[-1]
            q = q * ((q[:, 2] - b) / (s * q[:, 2]))[:, None]
        Tm = T[owner]
        x = np.einsum("mji,mj->mi", Tm[:, :3, :3], q - Tm[:, :3, 3])
        return q, Tm, x

    def _search(self, rows: NDArray[np.intp], x: NDArray[np.float64]
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The :data:`KEPT` samples of the shape nearest points ``x`` (shape frame): distances, points, normals."""
        r, k = self.shape_model.tree.query(x, k=KEPT)
        return r, self.shape_model.points[k], self.shape_model.normals[k]

    def _nearest_sample(self, x: NDArray[np.float64], rows: NDArray[np.intp]
                        ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``shape.surface(x, exact=True)``'s signed distance and normal, its searches remembered
        (:class:`~handeye.sensors.depth.shape.NearestSamples`: the same answers)."""
        points, normals = self._nearest.lookup(rows, x, self._search)
        return np.einsum("mi,mi->m", x - points[:, 0], normals[:, 0]), normals[:, 0]

    def _surface(self, x: NDArray[np.float64], rows: NDArray[np.intp]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Signed distances and their gradients (shape frame) of points ``x`` (of ``rows``), exactly blind to
        what the shape leaves free (:meth:`~handeye.sensors.depth.shape.Shape.canonical`): the nearest
        sample's normal, less its part along every free motion (not made unit again: the distance's
        derivative is the projection itself; renormalised, the Jacobian was 1.5e-4 off on a plain disc)."""
        if not len(self.free):
            return self._nearest_sample(x, rows)
        xc, R = self.shape_model.canonical(x)
        d, n = self._nearest_sample(xc, rows)
        n = np.einsum("mji,mj->mi", R, n)
        for u in self.free:  # the normal across every free motion (a facet's tilt would pin it a little)
            t = np.cross(u[:3], x) + u[3:]
            t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)
            n = n - np.einsum("mi,mi->m", n, t)[:, None] * t
        return d, n

    def residuals(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """Each row's signed distance (m) from the shape's surface along its normal."""
        _, _, x = self._points(X, p, flange2base, rows)
        return self._surface(x, np.asarray(rows))[0][:, None]

    def jacobian(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """The residuals' derivatives (M, 1, 6 + k): X's left increment, Z's unknowns, the depth's."""
        q, Tm, x = self._points(X, p, flange2base, rows)
        _, n = self._surface(x, np.asarray(rows))
        u = q @ X[:3, :3].T  # the points in X's parent frame, before X's translation
        # x = inv(Z) A X q: a change of X q moves x by M = rot(inv(target2cam) inv(X)) = rot(inv(Z) A)
        M = np.einsum("mji,jk->mik", Tm[:, :3, :3], X[:3, :3].T)
        m = np.einsum("mji,mj->mi", M, n)
        cols = [np.cross(u, m), m]
        if self.n_z:
            # Z = Zref T(xi), xi = basis_Z p: x = R(w)^T (y - v) moves by [x]x J_l(-w) with the rotation w
            # and by -R(w)^T with the translation v (R(w) and J_l(-w) the identity at the reference only)
            xi = self.basis_Z @ np.asarray(p[:self.n_z], float)
            R = Rotation.from_rotvec(xi[:3]).as_matrix()
            cols.append(-np.concatenate([np.cross(x, n) @ so3_left_jacobian(-xi[:3]), n @ R.T], axis=1) @ self.basis_Z)
        if self.fit_depth:
            s = 1.0 + p[-2]
            n_cam = np.einsum("mij,mj->mi", Tm[:, :3, :3], n)
            raw = self.measured[rows]
            cols += [(-np.einsum("mi,mi->m", n_cam, q) / s)[:, None],
                     (-np.einsum("mi,mi->m", n_cam, raw) / (s * raw[:, 2]))[:, None]]
        return np.concatenate(cols, axis=1)[:, None, :]

    def Z_std(self, p, cov_p) -> NDArray[np.float64]:
        """Z's std (deg, mm, in its own frame): 0 with the placement given, NaN on every axis the
        shape leaves free."""
        if not self.n_z:
            return np.zeros(6)
        cov = self.basis_Z @ cov_p[:self.n_z, :self.n_z] @ self.basis_Z.T
        s = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        out = np.r_[np.degrees(s[:3]), 1e3 * s[3:]]
        for u in self.free:
            out = np.where(np.abs(u / np.linalg.norm(u)) > 0.05, np.nan, out)
        return out

    def figures(self, p, cov_p) -> dict[str, Any]:
        """The depth scale and bias, the shape's size and what of its pose it leaves free."""
        return {"shape": self.shape_model.name, "shape_size_mm": 1e3 * self.shape_model.size,
                "placement_given": self.placement is not None, "free": self.shape_model.describe_free(),
                "points": int(len(self.owner)), **depth_figures(p, cov_p, self.fit_depth)}

    def notes(self, p, cov_p) -> list[str]:
        """The depth notes, and what the shape leaves undetermined of its own pose."""
        out = super().notes(p, cov_p)
        free = self.shape_model.describe_free()
        if free:
            name = setup_info(self.setup).z_name
            held = ("the placement given holds it; what the capture then leaves undetermined of X is named "
                    "below" if self.placement is not None else f"{name} is fitted without it (held; its std NaN there)")
            out.append(f"the shape {self.shape_model.name} does not determine {'; '.join(free)}: {held}")
        return out

    def _section_curve(self, X, p, flange2base, view, rows, r) -> NDArray[np.float64]:
        """The shape's edges (a mesh's sharp and open edges; none for a template cloud) posed where the
        fit puts it."""
        T = predicted_target2cam(X, self.Z(X, p), np.asarray(flange2base, float)[view:view + 1], self.setup)[0]
        edges = _sharp_edges(self.shape_model.mesh) @ T[:3, :3].T + T[:3, 3]
        edges[2::3] = np.nan  # each edge's third point: the break between lines
        return edges if len(edges) else np.full((1, 3), np.nan)


#: A mesh's edge is drawn when its faces meet at more than this angle (rad): a rim, a hole, a pin.
SHARP_EDGE = np.radians(25.0)


def _sharp_edges(mesh: Any) -> NDArray[np.float64]:
    """A mesh's sharp edges (faces meeting at more than :data:`SHARP_EDGE`) and open ones, as
    (3k, 3) points in its frame: each edge's two ends and a third row (the report's break between
    lines); none (0, 3) for a template cloud (no mesh)."""
    if mesh is None:
        return np.zeros((0, 3))
    sharp = np.asarray(mesh.face_adjacency_edges)[np.asarray(mesh.face_adjacency_angles) > SHARP_EDGE]
    edges = np.sort(np.asarray(mesh.edges), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    pairs = np.concatenate([sharp.reshape(-1, 2), unique[counts == 1]])
    vertices = np.asarray(mesh.vertices, float)
    return np.concatenate([vertices[pairs], vertices[pairs[:, :1]]], axis=1).reshape(-1, 3) if len(pairs) else np.zeros((0, 3))


def _complement(free: NDArray[np.float64], radius: float) -> NDArray[np.float64]:
    """An orthonormal basis (6, 6 - k) of the twists the shape determines (rotations at ``radius``)."""
    if not len(free):
        return np.eye(6)
    scaled = np.c_[free[:, :3] * radius, free[:, 3:]]
    _, _, Vt = np.linalg.svd(scaled, full_matrices=True)
    basis = Vt[len(free):].T
    return np.r_[basis[:3] * radius, basis[3:]] / np.linalg.norm(np.r_[basis[:3] * radius, basis[3:]], axis=0)


def _rigid(source: NDArray[np.float64], target: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rigid transform that maps the points ``source`` onto ``target`` best (both (N, 4, k),
    homogeneous: each view's k points; Kabsch)."""
    P = np.swapaxes(source[:, :3], 1, 2).reshape(-1, 3)
    Q = np.swapaxes(target[:, :3], 1, 2).reshape(-1, 3)
    cp, cq = P.mean(axis=0), Q.mean(axis=0)
    R = Rotation.align_vectors(Q - cq, P - cp)[0].as_matrix()
    return make_transform(R, cq - R @ cp)
