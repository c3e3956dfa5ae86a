"""The arm itself as a depth camera's target (markerless, eye-to-hand): :class:`PosedArm` and
:class:`ArmSurface`.

A depth camera fixed in the cell (X = cam2base) sees the arm. At each view's joint angles the arm's
link meshes (:mod:`handeye.robot.meshes`), placed by its kinematic table, are a known surface in
the base frame: a different shape per view, but a known one, so each view's points carried into
the base frame by X must lie on that view's posed arm. No target, no pose of it to fit.

* :class:`PosedArm`: the links' surfaces sampled densely (every :data:`SPACING`) with their
  faces' normals, posed per view in the base frame, a KD-tree per view; a point's residual is its
  signed distance from the face of its nearest sample (exact on the face's plane);
  :meth:`PosedArm.shape` gives a view's posed arm as a rigid shape for the global registration
  (:func:`~handeye.sensors.depth.registration.find_shape`: X from one view without any guess).
* :func:`fit_cam2base`: trimmed point-to-plane ICP of X over every view's points at once;
  :func:`on_arm`: which of a cloud's points lie within a band of the posed arm at X (the
  segmentation of the arm from the table, the floor, cables and whatever else the cloud holds).
* :class:`ArmSurface`: those points as a sensor model (:mod:`handeye.sensors.base`): each point's
  signed distance from the posed arm's surface along its normal, the point moved back along its ray
  by the depth scale and bias as for the other depth targets; unknowns: X, the depth scale and
  bias. With the arm's joint angles (``joints``) the table's entries can be
  fitted too (:class:`~handeye.robot.models.JointAngles`): the core passes the corrected table
  (``residuals(..., table=)``), each point moves with the link it lies on (found at the start), and
  ``jacobian(..., table=)`` adds its derivatives by every entry from the links' twists
  (:meth:`~handeye.robot.meshes.ArmMeshes.table_twists`).

Examples
--------
>>> import numpy as np
>>> from handeye.robot.kinematics import load_arm
>>> from handeye.robot.meshes import arm_meshes
>>> from handeye.sensors.depth.arm import PosedArm
>>> panda, meshes = load_arm("panda"), arm_meshes("panda")
>>> arm = PosedArm(meshes, meshes.link2base(panda, np.radians([[0, -20, 0, -120, 0, 100, 45]])))
>>> d, dist, n = arm.surface(np.zeros(1, dtype=np.intp), np.array([[0.0, 0.0, 1.5]]))
>>> bool(d[0] > 0.3)            # 1.5 m above the base, well outside the arm
True
"""

from __future__ import annotations

import importlib
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from ...errors import InputMismatchError, SessionError
from ...frames.setups import check_setup, setup_info
from ...geometry.se3 import perturb
from ...robot.kinematics import Chain
from ...robot.meshes import ArmMeshes
from .clouds import depth_sigma
from .model import LATERAL, DepthRows, depth_figures
from .shape import NearestSamples, Shape, sample_surface, search_tree, shape_from_mesh, voxel_pick

__all__ = ["PosedArm", "ArmSurface", "fit_cam2base", "on_arm", "within", "to_base", "SPACING", "BAND_SIGMA", "BAND_M", "FACES",
           "COARSE_SPACING", "COARSE_TAU", "KEPT"]

#: The links' surfaces are sampled this densely (m between samples): a point's nearest sample is
#: on its own face but within ~1 mm of a face's edge.
SPACING = 0.0025
#: A point is on the arm when within this many of its depth noise of the posed surface, plus
#: :data:`BAND_M` (the depth scale and bias not fitted yet, the meshes' own error), and near a sample.
BAND_SIGMA = 4.0
BAND_M = 0.002
#: The fit's residual: of this many nearest samples, the one whose face's plane is nearest the
#: point (the nearest sample alone biased X by up to 3 of its std on the simulator: points near a
#: face's edge measured against the face beside theirs).
FACES = 4
#: The ICP's wide rounds (thresholds above :data:`COARSE_TAU`, m) search one sample per voxel of this
#: side (m) instead of every sample: a point far from the arm (the table, a wrong candidate's whole
#: cloud) costs a search of the dense samples up to the threshold, and a step pulled in from
#: centimetres away needs no millimetre surface.
COARSE_SPACING = 0.02
COARSE_TAU = 0.04
#: The fit remembers this many nearest samples per point (:class:`~handeye.sensors.depth.shape.NearestSamples`):
#: :data:`FACES` and two more (the core's fit of the simulated Panda's 15 clouds took 4.5x less CPU than
#: with a new search at every step; 8, about the same).
KEPT = 6


def _trimesh():
    try:
        return importlib.import_module("trimesh")
    except ImportError:
        raise SessionError("the arm as the target needs trimesh and rtb-data: pip install 'handeye[markerless]'") from None


class PosedArm:
    """An arm's surface at every view's joint angles, in the base frame: per view its samples
    (``points``, ``normals``) and a KD-tree on them.

    Parameters
    ----------
    meshes : ArmMeshes
        The arm's links (:func:`~handeye.robot.meshes.arm_meshes`).
    link2base : ndarray (N, L, 4, 4)
        Each view's pose of each link (:meth:`~handeye.robot.meshes.ArmMeshes.link2base`).
    spacing : float
        The samples' spacing (m).
    """

    def __init__(self, meshes: ArmMeshes, link2base: NDArray[np.float64], spacing: float = SPACING) -> None:
        trimesh = _trimesh()
        self.meshes, self.link2base = meshes, np.asarray(link2base, float)
        if self.link2base.ndim != 4 or self.link2base.shape[1] != len(meshes.links):
            raise InputMismatchError(f"link poses of shape {self.link2base.shape}: give (views, {len(meshes.links)}, 4, 4)")
        local = []
        for link in meshes.links:
            mesh = trimesh.Trimesh(link.vertices, link.faces, process=False)
            p, face = sample_surface(mesh, max(200, int(mesh.area / spacing**2)))
            local.append((p, np.asarray(mesh.face_normals, float)[face]))
        #: per sample (the same in every view) its link's index in ``meshes.links``
        self.sample_link = np.repeat(np.arange(len(local)), [len(p) for p, _ in local])
        #: the samples the wide rounds search (:data:`COARSE_SPACING`): the same ones of each link in every view
        starts = np.cumsum([0] + [len(p) for p, _ in local])
        self.coarse = np.concatenate([start + voxel_pick(p, COARSE_SPACING) for (p, _), start in zip(local, starts)])
        self.points, self.normals, self.trees = [], [], []
        for T in self.link2base:
            pts = np.concatenate([p @ t[:3, :3].T + t[:3, 3] for (p, _), t in zip(local, T)])
            self.points.append(pts)
            self.normals.append(np.concatenate([n @ t[:3, :3].T for (_, n), t in zip(local, T)]))
            self.trees.append(search_tree(pts))
        #: per view the wide rounds' samples: their KD-tree, points and normals
        self.sparse = [(search_tree(p[self.coarse]), p[self.coarse], n[self.coarse]) for p, n in zip(self.points, self.normals)]

    def subset(self, views: list[int] | NDArray[np.intp]) -> PosedArm:
        """The arm at the views ``views`` only (their samples and trees shared, not made again)."""
        views = [int(v) for v in views]
        out = object.__new__(PosedArm)
        out.meshes, out.link2base, out.sample_link = self.meshes, self.link2base[views], self.sample_link
        out.coarse = self.coarse
        out.points, out.normals, out.trees, out.sparse = ([getattr(self, a)[v] for v in views]
                                                          for a in ("points", "normals", "trees", "sparse"))
        return out

    @property
    def n_views(self) -> int:
        """The views the arm is posed at."""
        return len(self.link2base)

    def surface(self, owner: NDArray[np.intp], y: NDArray[np.float64], bound: float = np.inf, faces: int = 1,
                coarse: bool = False) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """For points ``y`` (M, 3, base frame) of views ``owner`` (M,): the signed distance from the
        face of each one's nearest sample (along its normal; outside > 0), the distance to that
        sample, and the normal (M, 3, base frame); with ``faces`` > 1, of that many nearest samples
        the one whose face's plane is nearest (a point near an edge, whose nearest sample lies on the
        face beside its own); a point farther than ``bound`` (m) from every sample (a far point's
        search is slow) gets infinite distances and a zero normal. ``coarse``: of the samples one
        per :data:`COARSE_SPACING` (the ICP's wide rounds)."""
        d, dist, n = np.full(len(y), np.inf), np.full(len(y), np.inf), np.zeros((len(y), 3))
        for v in np.unique(owner):
            at = np.flatnonzero(owner == v)
            tree, points, normals = self.sparse[v] if coarse else (self.trees[v], self.points[v], self.normals[v])
            r, k = tree.query(y[at], k=[1] if faces == 1 else faces, distance_upper_bound=bound)
            hit = k[:, 0] < len(points)
            at, r, k = at[hit], r[hit], np.minimum(k[hit], len(points) - 1)
            normal = normals[k]  # (m, faces, 3)
            plane = np.where(np.isfinite(r), np.einsum("mki,mki->mk", y[at, None] - points[k], normal), np.inf)
            pick = np.argmin(np.abs(plane), axis=1)
            m = np.arange(len(at))
            d[at], dist[at], n[at] = plane[m, pick], r[m, pick], normal[m, pick]
        return d, dist, n

    def shape(self, view: int) -> Shape:
        """View ``view``'s posed arm as one rigid shape in the base frame (its target2cam is then
        base2cam), for :func:`~handeye.sensors.depth.registration.find_shape`."""
        vertices, faces, _ = self.meshes.merged()
        posed = self.meshes.posed_vertices(self.link2base[view:view + 1])[0]
        return shape_from_mesh(_trimesh().Trimesh(posed, faces, process=False), f"{self.meshes.arm} at view {view + 1}")


def to_base(X: NDArray[np.float64], q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Points ``q`` (M, 3, camera frame) in the base frame through ``X`` (cam2base)."""
    return q @ X[:3, :3].T + X[:3, 3]


def _facing(X: NDArray[np.float64], n: NDArray[np.float64], q: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Whether normals ``n`` (base frame) face the camera at points ``q`` (camera frame): a camera sees no back face."""
    return np.einsum("mi,mi->m", n @ X[:3, :3], q) < 0


def on_arm(arm: PosedArm, X: NDArray[np.float64], owner: NDArray[np.intp], q: NDArray[np.float64],
           band_sigma: float = BAND_SIGMA, band_m: float = BAND_M) -> NDArray[np.bool_]:
    """Per point ``q`` (M, 3, camera frame, of views ``owner``) whether it lies on the posed arm at
    X: within ``band_sigma`` of its depth noise plus ``band_m`` of the surface along the normal,
    within twice that of its nearest sample, on a face towards the camera."""
    band = band_sigma * depth_sigma(q[:, 2]) + band_m
    near = 2.0 * band + 2.0 * SPACING
    y = to_base(X, q)
    d, dist, n = np.full(len(q), np.inf), np.full(len(q), np.inf), np.zeros((len(q), 3))
    # a search costs little up to the point's own bound and much beyond it (a far point, the table's): the
    # points searched in groups of bounds within a factor 2, each to its group's largest (the same answers)
    group = np.floor(np.log2(near / near.min())) if len(q) else near
    for g in np.unique(group):
        at = np.flatnonzero(group == g)
        d[at], dist[at], n[at] = arm.surface(owner[at], y[at], float(near[at].max()))
    return (np.abs(d) < band) & (dist < near) & _facing(X, n, q)


def within(arm: PosedArm, X: NDArray[np.float64], owner: NDArray[np.intp], q: NDArray[np.float64], tau: float,
           coarse: bool = False) -> int:
    """How many of the points ``q`` (camera frame, of views ``owner``) lie within ``tau`` (m) of a
    sample of the posed arm at X on a face towards the camera: the ICP's points at that threshold
    (``coarse``: of the wide rounds' samples)."""
    d, dist, n = arm.surface(owner, to_base(X, q), float(tau), coarse=coarse)
    return int(np.count_nonzero((dist < tau) & _facing(X, n, q)))


def fit_cam2base(arm: PosedArm, X: NDArray[np.float64], owner: NDArray[np.intp], q: NDArray[np.float64],
                 thresholds: NDArray[np.float64]) -> NDArray[np.float64]:
    """X (cam2base) pulled in by trimmed point-to-plane ICP over every view's points at once: per
    threshold (m), the points ``q`` (M, 3, camera frame, of views ``owner``) within it of their
    nearest sample on a face towards the camera, weighted by their depth noise, one damped
    Gauss-Newton step of X's left increment; a threshold above :data:`COARSE_TAU` against the
    sparser samples (``PosedArm.surface(..., coarse=True)``)."""
    X = np.asarray(X, float)
    w0 = 1.0 / np.square(depth_sigma(q[:, 2]))
    for tau in thresholds:
        u = q @ X[:3, :3].T
        d, dist, n = arm.surface(owner, u + X[:3, 3], float(tau), coarse=bool(tau > COARSE_TAU))
        w = np.where((dist < tau) & _facing(X, n, q), w0, 0.0)
        d = np.where(w > 0, d, 0.0)
        J = np.concatenate([np.cross(u, n), n], axis=1)
        A = (J * w[:, None]).T @ J
        A += (1e-6 * np.trace(A) + 1e-12) * np.eye(6)
        step = np.linalg.solve(A, -(J * w[:, None]).T @ d)
        X = perturb(X, step[:3], step[3:])
    return X


class ArmSurface(DepthRows):
    """Every view's points on the arm (``points``: per view (m_i, 3), camera frame, m) against the
    arm posed at that view's joint angles (``arm``: :class:`PosedArm`), from the start ``X0``
    (cam2base, the global registration's and the views' ICP), with the depth scale and bias
    (``fit_depth``).

    The noise along a point's normal: the depth noise times the cosine between its ray and the
    normal, and the noise across the rays (:data:`~handeye.sensors.depth.model.LATERAL`) times its sine.
    Z, the target's pose, is none: the arm is posed by the joint angles; the result's Z is the
    identity (the target taken as the flange itself), not fitted.

    With ``joints`` (N, n; rad: those ``arm`` was posed at), the fit can correct the table it was
    posed by (the module docstring): each point is assigned the link nearest it at ``X0``.
    """

    target = "arm"
    groups: tuple[tuple[int, ...], ...] = ((0,),)

    def __init__(self, setup: str, names: list[str], arm: PosedArm, points: list[NDArray[np.float64]],
                 X0: NDArray[np.float64], fit_depth: bool = True, joints: NDArray[np.float64] | None = None) -> None:
        self.setup = check_setup(setup)
        if setup_info(self.setup).camera_on_flange:
            raise InputMismatchError("the arm as the target is seen by a camera fixed in the cell: setup eye_to_hand")
        if not len(names) == len(points) == arm.n_views:
            raise InputMismatchError(f"{len(names)} views, {len(points)} point sets and the arm posed at {arm.n_views}: "
                                     "give one of each per view")
        self.names, self.arm, self.fit_depth = list(names), arm, fit_depth
        self.X0 = np.asarray(X0, float)
        self._rays(np.concatenate([np.asarray(q, float).reshape(-1, 3) for q in points]))
        self.owner = np.repeat(np.arange(len(names)), [len(np.asarray(q).reshape(-1, 3)) for q in points])
        self._nearest = NearestSamples(len(self.owner), FACES, KEPT)
        _, n = self._surface(np.arange(len(self.owner)), to_base(self.X0, self.measured))
        cos = np.clip(np.abs(np.einsum("mi,mi->m", self.basis[:, 0], n @ self.X0[:3, :3])), 0.0, 1.0)
        z = self.measured[:, 2]
        self.shape = np.sqrt((depth_sigma(z) * cos) ** 2 + (LATERAL * z) ** 2 * (1.0 - cos**2))[:, None]
        self.param_names = ["depth.scale-1", "depth.bias"] if fit_depth else []
        self.param_scale = np.full(len(self.param_names), 1e-3)
        self.joints = None if joints is None else np.atleast_2d(np.asarray(joints, float))
        if self.joints is not None:
            if len(self.joints) != len(names):
                raise InputMismatchError(f"{len(names)} views and joint angles of shape {self.joints.shape}: give one row "
                                         "of joint angles per view")
            y0 = to_base(self.X0, self.measured)
            self.link = np.empty(len(self.owner), dtype=np.intp)
            for v in range(len(names)):
                at = self.owner == v
                self.link[at] = arm.meshes.nearest_link(arm.link2base[v], y0[at])

    @property
    def sees_links(self) -> bool:
        """Whether the fit can correct the arm's table (its joint angles given)."""
        return self.joints is not None

    def view_poses(self) -> None:
        """None: no view measures a target's pose (the model starts from its own ``X0``)."""
        return None

    def start(self, flange2base, X, Z, rows=None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``X0`` (the registration's), the depth scale 1 and bias 0."""
        return self.X0.copy(), np.zeros(len(self.param_names))

    def Z(self, X, p) -> NDArray[np.float64]:
        """The identity: the arm has no target of its own (its links are posed by the joint angles)."""
        return np.eye(4)

    def Z_std(self, p, cov_p) -> NDArray[np.float64]:
        """Zeros: Z is not fitted."""
        return np.zeros(6)

    def _search(self, rows: NDArray[np.intp], y: NDArray[np.float64]
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The rows' :data:`KEPT` nearest samples of their views' posed arms (distances, points, normals)."""
        r, points, normals = np.empty((len(rows), KEPT)), np.empty((len(rows), KEPT, 3)), np.empty((len(rows), KEPT, 3))
        owner = self.owner[rows]
        for v in np.unique(owner):
            at = np.flatnonzero(owner == v)
            r[at], k = self.arm.trees[v].query(y[at], k=KEPT)
            points[at], normals[at] = self.arm.points[v][k], self.arm.normals[v][k]
        return r, points, normals

    def _surface(self, rows: NDArray[np.intp], y: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """What ``arm.surface(owner[rows], y, faces=FACES)`` gives, its searches remembered
        (:class:`~handeye.sensors.depth.shape.NearestSamples`: the same answers): the signed distance and the normal."""
        points, normals = self._nearest.lookup(rows, y, self._search)
        plane = np.einsum("mki,mki->mk", y[:, None] - points, normals)
        pick = np.argmin(np.abs(plane), axis=1)
        m = np.arange(len(rows))
        return plane[m, pick], normals[m, pick]

    def _moved(self, p, rows) -> NDArray[np.float64]:
        """The rows' points moved back along their rays by the depth scale and bias."""
        q = self.measured[rows]
        if not self.fit_depth:
            return q
        s, b = 1.0 + p[-2], p[-1]
        return q * ((q[:, 2] - b) / (s * q[:, 2]))[:, None]

    def _on_nominal(self, y: NDArray[np.float64], rows: NDArray[np.intp], table: Chain | None
                    ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """Points ``y`` (base frame) of ``rows`` carried from their links posed by ``table`` to the same
        links posed by the nominal one (where the posed arm's samples are), and the rotation that did
        it (None without ``table``)."""
        if table is None:
            return y, None
        at = (self.owner[rows], self.link[rows])
        joints = cast(NDArray[np.float64], self.joints)  # a table comes with joint angles (sees_links)
        nominal, moved = self.arm.link2base[at], self.arm.meshes.link2base(table, joints)[at]
        R = nominal[:, :3, :3] @ np.swapaxes(moved[:, :3, :3], 1, 2)
        return np.einsum("mij,mj->mi", R, y - moved[:, :3, 3]) + nominal[:, :3, 3], R

    def residuals(self, X, p, flange2base, rows, table: Chain | None = None) -> NDArray[np.float64]:
        """Each row's signed distance (m) from its view's posed arm, along the surface's normal (the
        links posed by ``table`` when given, else by the table the arm was posed by)."""
        y, _ = self._on_nominal(to_base(X, self._moved(p, rows)), rows, table)
        return self._surface(np.asarray(rows), y)[0][:, None]

    def jacobian(self, X, p, flange2base, rows, table: Chain | None = None) -> NDArray[np.float64]:
        """The residuals' derivatives (M, 1, 6 + k): X's left increment, then the depth scale and bias;
        with ``table``, at it, then (M, 1, 6 + k + E) by every entry of it (natural units, row by row): a
        point's link moved by ``w x y + v`` (:meth:`~handeye.robot.meshes.ArmMeshes.table_twists`) moves
        the surface under it, and its distance from it by minus that along the normal."""
        q = self._moved(p, rows)
        u = q @ X[:3, :3].T
        y, R = self._on_nominal(u + X[:3, 3], rows, table)
        _, n = self._surface(np.asarray(rows), y)
        if R is not None:
            n = np.einsum("mji,mj->mi", R, n)
        cols = [np.cross(u, n), n]
        if self.fit_depth:
            s = 1.0 + p[-2]
            n_cam = n @ X[:3, :3]
            raw = self.measured[rows]
            cols += [(-np.einsum("mi,mi->m", n_cam, q) / s)[:, None],
                     (-np.einsum("mi,mi->m", n_cam, raw) / (s * raw[:, 2]))[:, None]]
        if table is not None:
            joints = cast(NDArray[np.float64], self.joints)  # a table comes with joint angles (sees_links)
            twist = self.arm.meshes.table_twists(table, joints)[:, self.owner[rows], self.link[rows]]  # (E, M, 6)
            moved = np.cross(twist[..., :3], u + X[:3, 3]) + twist[..., 3:]
            cols.append(-np.einsum("mi,emi->me", n, moved))
        return np.concatenate(cols, axis=1)[:, None, :]

    def figures(self, p, cov_p) -> dict[str, Any]:
        """The arm, its links, the points fitted, the depth scale and bias."""
        return {"arm": self.arm.meshes.arm, "links": [link.name for link in self.arm.meshes.links],
                "points": int(len(self.owner)), **depth_figures(p, cov_p, self.fit_depth)}

    def notes(self, p, cov_p) -> list[str]:
        """The depth notes, and how the arm's links were posed."""
        posed = ("through its table, fitted with X (joint angles)" if self.sees_links else
                 "through its nominal table (not fitted)")
        return super().notes(p, cov_p) + [
            f"the arm ({self.arm.meshes.arm}) is the target: its links posed by the joint angles {posed}; Z is the "
            "identity (no target of its own)"]

