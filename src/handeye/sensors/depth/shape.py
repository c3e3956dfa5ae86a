"""A known shape as a calibration target: a mesh (STL, OBJ, PLY) or a template cloud, read in its
stated unit, sampled densely with normals, and what of a pose it leaves undetermined.

A shape determines a pose only up to the motions that slide its surface along itself: a disc
without features turns about its axis unseen, a plate slides in its plane. Those motions are the
twists ``(w, v)`` with ``n . (w x p + v) = 0`` at every surface point ``p`` of normal ``n``
(:func:`free_twists`): the null space of the surface's ``[p x n, n]`` rows, up to
:data:`SYMMETRY_SHARE` of the best determined motion (a tessellated cylinder's facets do not
pin its rotation in a camera's noise).

Examples
--------
>>> import numpy as np
>>> from handeye.sensors.depth.shape import free_twists
>>> angle = np.linspace(0, 2 * np.pi, 400, endpoint=False)
>>> ring = np.c_[np.cos(angle), np.sin(angle), np.zeros_like(angle)]   # a cylinder's wall at z = 0 ...
>>> wall = np.vstack([ring + [0, 0, z] for z in (-0.5, 0.0, 0.5)])
>>> free = free_twists(wall, np.vstack([ring] * 3))
>>> len(free)                         # ... slides along and turns about its axis
2
"""

from __future__ import annotations

import importlib
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import distance_transform_edt
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from ..._shared.text import shown
from ...errors import SessionError
from ...geometry.se3 import perpendicular_basis
from .clouds import read_points

__all__ = ["Shape", "load_shape", "shape_from_mesh", "shape_from_points", "free_twists", "twist_axis", "describe_twist", "weakest_rotation",
           "dominant_normals", "NearestSamples", "search_tree", "voxel_pick", "sample_surface",
           "MESH_SUFFIXES", "TEMPLATE_SUFFIXES", "MAX_SIZE_M", "MIN_SIZE_M", "SYMMETRY_SHARE",
           "SPIN_SHARE", "MAX_SAMPLES"]

#: Files read as meshes (with trimesh) and as template clouds (a PLY without faces is a template).
MESH_SUFFIXES = (".stl", ".obj", ".ply", ".off")
TEMPLATE_SUFFIXES = (".ply", ".pcd", ".npy")
#: A shape larger than this across (m) is no target a depth camera sees whole: a mesh in mm declared m.
MAX_SIZE_M = 3.0
#: A shape smaller than this across (m) is no target a depth camera resolves: a mesh in m declared mm.
MIN_SIZE_M = 0.005
#: A motion that moves the surface along its normals less than this share of the best determined
#: motion (rotations at the shape's radius) leaves the shape where it was: the shape does not determine it.
SYMMETRY_SHARE = 0.05
#: A rotation a surface pins less than this share as well as its best pinned rotation is searched
#: over whole turns when the shape is found in a cloud (a disc's own axis: its holes and pin pin it).
SPIN_SHARE = 0.25
#: The surface is sampled this densely at most (points); a sample every ~1/600 of the shape's size.
MAX_SAMPLES = 100_000


@dataclass(frozen=True, eq=False)
class Shape:
    """A target's surface in its own frame (metres): dense samples with unit normals, a KD-tree on
    them, a coarse copy for the global search, and the twists (k, 6: rotation in rad, translation in
    m, about the frame's origin) that slide the surface along itself (:func:`free_twists`)."""

    name: str
    points: NDArray[np.float64]
    normals: NDArray[np.float64]
    spacing: float  #: the samples' typical distance, m
    free: NDArray[np.float64]
    mesh: Any = field(default=None, repr=False)  #: the trimesh.Trimesh (metres), None for a template cloud
    tree: cKDTree = field(init=False, repr=False)
    coarse: NDArray[np.intp] = field(init=False, repr=False)  #: samples of the global search
    centre: NDArray[np.float64] = field(init=False, repr=False)  #: the samples' bounding box's centre, m
    size: float = field(init=False, repr=False)  #: the bounding box's diagonal, m
    radius: float = field(init=False, repr=False)  #: the smallest ball about ``centre`` that holds the shape, m
    #: the axis (unit, shape frame) of the rotation the surface pins least and a point on it, when it
    #: is pinned less than :data:`SPIN_SHARE` as well as the best rotation (a disc's, a cylinder's); else None
    spin: tuple[NDArray[np.float64], NDArray[np.float64]] | None = field(init=False, repr=False)
    #: the directions most of the surface faces (k, 3; unit, shape frame): a disc's two faces
    faces: NDArray[np.float64] = field(init=False, repr=False)
    _grids: dict[bool, _Grid] = field(init=False, repr=False)  #: the lookup grids, built on first use

    def __post_init__(self) -> None:
        lo, hi = self.points.min(axis=0), self.points.max(axis=0)
        object.__setattr__(self, "centre", 0.5 * (lo + hi))
        object.__setattr__(self, "size", float(np.linalg.norm(hi - lo)))
        object.__setattr__(self, "radius", float(np.linalg.norm(self.points - self.centre, axis=1).max()))
        object.__setattr__(self, "tree", search_tree(self.points))
        object.__setattr__(self, "coarse", voxel_pick(self.points, self.size / 60.0))
        object.__setattr__(self, "faces", dominant_normals(self.normals[self.coarse]))
        object.__setattr__(self, "spin", weakest_rotation(self.points[self.coarse], self.normals[self.coarse], share=SPIN_SHARE))
        object.__setattr__(self, "_grids", {})

    def surface(self, x: NDArray[np.float64], coarse: bool = False, exact: bool = False
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """For points ``x`` (M, 3) in the shape's frame: the signed distance along the nearest
        sample's normal, the distance to that sample, and the normal (M, 3). The nearest sample is
        looked up in a grid around the shape (the one nearest the point's cell's centre; the cell a
        100th of the shape's size, ``coarse``: a 40th; inf distance beyond the grid), or with
        ``exact`` in the KD-tree."""
        if exact:
            dist, k = self.tree.query(x)
        else:
            k = self._grid(coarse).lookup(x)
            dist = np.where(k >= 0, np.linalg.norm(x - self.points[k], axis=1), np.inf)
        n = self.normals[k]
        return np.einsum("mi,mi->m", x - self.points[k], n), dist, n

    def _grid(self, coarse: bool) -> _Grid:
        if coarse not in self._grids:  # built on first use: the fine one takes ~1 s
            h = self.size / (40.0 if coarse else 100.0)
            self._grids[coarse] = _Grid(self.points, h, 0.6 * self.radius if coarse else 0.12 * self.size)
        return self._grids[coarse]

    def canonical(self, x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Points ``x`` (M, 3) moved along what the shape leaves free to one place (a slide taken
        out; a turn about an axis to the half-plane at angle 0; about a centre, onto one ray), and
        the rotation (M, 3, 3) that did it: the distance to the surface of the moved point does not
        change with any free motion, exactly (a faceted mesh's facets would pin it a little)."""
        x = np.asarray(x, float)
        R = np.broadcast_to(np.eye(3), (len(x), 3, 3)).copy()
        rot = self.free[np.linalg.norm(self.free[:, :3], axis=1) > 1e-9]
        for u in self.free[np.linalg.norm(self.free[:, :3], axis=1) <= 1e-9]:
            d = u[3:] / np.linalg.norm(u[3:])
            x = x - np.outer((x - self.centre) @ d, d)
        if len(rot) == 1:
            a, c = twist_axis(rot[0])
            e1, e2 = perpendicular_basis(a)
            y = x - c
            angle = np.arctan2(y @ e2, y @ e1)
            R = Rotation.from_rotvec(np.outer(-angle, a)).as_matrix()
            x = c + np.einsum("mij,mj->mi", R, y)
        elif len(rot) >= 3:
            c = self.centre
            y = x - c
            R = Rotation.align_vectors(np.broadcast_to([0.0, 0.0, 1.0], y.shape), y)[0].as_matrix() if len(y) == 1 else \
                _onto_z(y)
            x = c + np.einsum("mij,mj->mi", R, y)
        return x, R

    def describe_free(self) -> list[str]:
        """What the shape leaves undetermined of its own pose, in words."""
        return [describe_twist(u, self.centre) for u in self.free]


def _onto_z(y: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per vector (M, 3) the rotation (M, 3, 3) that turns it onto +z (about their cross product)."""
    n = np.linalg.norm(y, axis=1, keepdims=True)
    u = y / np.where(n > 0, n, 1.0)
    axis = np.cross(u, [0.0, 0.0, 1.0])
    s = np.linalg.norm(axis, axis=1, keepdims=True)
    angle = np.arctan2(s[:, 0], u[:, 2])
    axis = np.where(s > 1e-12, axis / np.where(s > 0, s, 1.0), [[1.0, 0.0, 0.0]])
    return Rotation.from_rotvec(axis * angle[:, None]).as_matrix()


class _Grid:
    """A lookup table of a shape's nearest sample: per cell of side ``h`` over the samples' box grown
    by ``margin``, a sample of the occupied cell nearest to it (a Euclidean distance transform),
    none (-1) for cells farther than ``margin``."""

    def __init__(self, points: NDArray[np.float64], h: float, margin: float) -> None:
        self.lo = points.min(axis=0) - margin
        self.h = h
        self.n = np.ceil((points.max(axis=0) + margin - self.lo) / h).astype(np.int64) + 1
        cell = np.floor((points - self.lo) / h).astype(np.int64)
        owner = np.full(int(np.prod(self.n)), -1, dtype=np.int64)
        owner[np.ravel_multi_index(cell.T, self.n)] = np.arange(len(points))
        empty = (owner < 0).reshape(self.n)
        dist, nearest = distance_transform_edt(empty, return_indices=True)
        table = owner[np.ravel_multi_index(nearest.reshape(3, -1), self.n)]
        table[dist.ravel() * h > margin] = -1
        self.table = np.r_[table.astype(np.int32), -1]

    def lookup(self, x: NDArray[np.float64]) -> NDArray[np.intp]:
        """Per point (M, 3) its sample's index, -1 outside the grid."""
        c = np.floor((x - self.lo) / self.h).astype(np.int64)
        inside = np.all((c >= 0) & (c < self.n), axis=1)
        flat = np.where(inside, (c[:, 0] * self.n[1] + c[:, 1]) * self.n[2] + c[:, 2], len(self.table) - 1)
        return self.table[flat]


def search_tree(points: NDArray[np.float64]) -> cKDTree:
    """A KD-tree for nearest-sample searches of a surface's samples: split at sliding midpoints
    instead of medians, its nodes' boxes not shrunk to their points (scipy's ``balanced_tree`` and
    ``compact_nodes`` off): on the Panda's 146,000 samples 2x faster to build and ~1.8x to search,
    the same neighbours."""
    return cKDTree(points, balanced_tree=False, compact_nodes=False)


class NearestSamples:
    """A fit's searches of a surface's samples, remembered: per measurement row the ``kept`` samples
    nearest it at its last search (their points and normals). A row that has moved by less than half
    the gap between the distances of its ``nearest``-th and its last kept sample since then has the
    same ``nearest`` samples among the kept ones (every other sample was at least as far as the last
    kept one, and is at most the move nearer now): they are found among those few instead of by a new
    search, with the same answer. A fit moves its points by far less than that between its steps.

    Parameters
    ----------
    rows : int
        The measurement rows.
    nearest : int
        The samples each lookup gives per row, nearest first.
    kept : int
        The samples kept per row (more than ``nearest``).
    """

    def __init__(self, rows: int, nearest: int, kept: int) -> None:
        self.nearest, self.kept = nearest, kept
        self.at = np.full((rows, 3), np.nan)  #: where each row was searched from
        self.points = np.zeros((rows, kept, 3))  #: its nearest samples there, nearest first
        self.normals = np.zeros((rows, kept, 3))  #: and their normals
        self.slack = np.full(rows, -np.inf)  #: half the gap between the nearest-th and the last one's distance
        self.lock = threading.Lock()

    def lookup(self, rows: NDArray[np.intp], y: NDArray[np.float64], search: Callable[..., Any]
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The ``nearest`` samples of points ``y`` (M, 3) of ``rows`` (M,): their points and normals
        (M, nearest, 3), nearest first, as a search gives them. ``search(rows, y)`` searches the rows
        not answered from what is kept: per row the ``kept`` nearest samples' distances (m, kept),
        points and normals (m, kept, 3), nearest first."""
        with self.lock:
            fresh = ~(np.linalg.norm(y - self.at[rows], axis=1) < self.slack[rows])  # NaN (never searched): fresh
            if fresh.any():
                r, points, normals = search(rows[fresh], y[fresh])
                at = rows[fresh]
                self.at[at], self.points[at], self.normals[at] = y[fresh], points, normals
                self.slack[at] = 0.5 * (r[:, -1] - r[:, self.nearest - 1])
            points = self.points[rows]
            gap = y[:, None] - points  # (M, kept, 3)
            d2 = np.einsum("mki,mki->mk", gap, gap)
            if self.nearest == 1:  # the first nearest, as the stable sort's first (a third of a mesh fit's evaluation)
                k = np.argmin(d2, axis=1)
                return points[np.arange(len(k)), k][:, None], self.normals[rows, k][:, None]
            order = np.argsort(d2, axis=1, kind="stable")[:, :self.nearest, None]
            return np.take_along_axis(points, order, axis=1), np.take_along_axis(self.normals[rows], order, axis=1)


def voxel_pick(points: NDArray[np.float64], voxel: float) -> NDArray[np.intp]:
    """One point (its index) per occupied voxel of side ``voxel``."""
    key = np.floor((points - points.min(axis=0)) / voxel).astype(np.int64)
    span = key.max(axis=0) + 1
    flat = (key[:, 0] * span[1] + key[:, 1]) * span[2] + key[:, 2]
    return np.sort(np.unique(flat, return_index=True)[1])


def free_twists(points: NDArray[np.float64], normals: NDArray[np.float64]) -> NDArray[np.float64]:
    """The twists (k, 6; rotation rad, translation m, about the frame's origin; orthonormal in the
    metric with rotations at the shape's RMS radius) that move no surface point along its normal
    by more than :data:`SYMMETRY_SHARE` of the best determined twist: what the shape leaves
    undetermined of its pose."""
    p = np.asarray(points, float)
    n = np.asarray(normals, float)
    c = p.mean(axis=0)
    L = float(np.sqrt(np.mean(np.sum((p - c) ** 2, axis=1)))) or 1.0
    rows = np.c_[np.cross(p - c, n) / L, n] / np.sqrt(len(p))
    _, s, Vt = np.linalg.svd(rows, full_matrices=False)
    u = Vt[s < SYMMETRY_SHARE * s[0]]
    w, v_c = u[:, :3] / L, u[:, 3:]
    return np.c_[w, v_c - np.cross(w, c)]  # about the origin: w x (x - c) + v_c = w x x + (v_c - w x c)


def dominant_normals(normals: NDArray[np.float64], k: int = 6, share: float = 0.05, angle_deg: float = 15.0
                     ) -> NDArray[np.float64]:
    """The directions (at most ``k``, (m, 3)) that at least ``share`` of the unit ``normals`` lie
    within ``angle_deg`` of, most first: greedily, the normal with the most others near it, the
    mean of those, then the rest."""
    n = np.asarray(normals, float)
    n = n[np.random.default_rng(0).permutation(len(n))[:3000]]
    cos = np.cos(np.radians(angle_deg))
    left = np.ones(len(n), bool)
    out = []
    for _ in range(k):
        near = (n @ n[left].T > cos) & left[:, None]
        counts = near.sum(axis=0)
        if not len(counts) or counts.max() < share * len(n):
            break
        members = near[:, int(np.argmax(counts))]
        mean = n[members].mean(axis=0)
        out.append(mean / np.linalg.norm(mean))
        left &= ~members
    return np.array(out).reshape(-1, 3)


def weakest_rotation(points: NDArray[np.float64], normals: NDArray[np.float64], weights: NDArray[np.float64] | None = None,
                     share: float = SPIN_SHARE) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """The rotation a surface (``points`` with ``normals``, ``weights`` per point) pins least, the
    translations taken out of its information (a Schur complement): its axis (unit) and the point
    on it that goes with it; None when it is pinned at least ``share`` as well as the best rotation."""
    w = np.ones(len(points)) if weights is None else weights
    J = np.concatenate([np.cross(points, normals), normals], axis=1)
    A = (J * w[:, None]).T @ J
    coupling = np.linalg.pinv(A[3:, 3:], rcond=1e-10) @ A[3:, :3]
    lam, V = np.linalg.eigh(A[:3, :3] - A[:3, 3:] @ coupling)
    if lam[0] > share * lam[-1]:
        return None
    axis = V[:, 0]
    return axis, np.cross(axis, -coupling @ axis)  # the translation that goes with the turn fixes the axis's point


def twist_axis(u: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A rotating twist's axis ``(w, v)`` (6): its unit direction and its point nearest the origin."""
    w, v = u[:3], u[3:]
    return w / np.linalg.norm(w), np.cross(w, v) / float(w @ w)


def describe_twist(u: NDArray[np.float64], centre: NDArray[np.float64]) -> str:
    """A free twist of a shape in words: a rotation about an axis (through a point) or a slide."""
    w, v = u[:3], u[3:]
    if np.linalg.norm(w) < 1e-9 * max(float(np.linalg.norm(v)), 1e-300):
        d = v / np.linalg.norm(v)
        return f"its translation along ({d[0]:+.2f}, {d[1]:+.2f}, {d[2]:+.2f}) (the shape slides along itself)"
    a, point = twist_axis(u)
    return (f"its rotation about the axis ({a[0]:+.2f}, {a[1]:+.2f}, {a[2]:+.2f}) through ({1e3 * point[0]:.1f}, "
            f"{1e3 * point[1]:.1f}, {1e3 * point[2]:.1f}) mm (the shape turns into itself)")


def _trimesh(path: Path):
    try:
        return importlib.import_module("trimesh")
    except ImportError:
        raise SessionError(f"{path}: reading a mesh needs trimesh: pip install 'handeye[mesh]'") from None


def _checked_size(size_m: float, unit: str, where: str) -> None:
    if size_m > MAX_SIZE_M:
        raise SessionError(f"{where}: the shape is {size_m:g} m across in the unit declared ({unit}): no depth camera "
                           f"sees a target that large whole; is the file in millimetres? declare unit: mm")
    if size_m < MIN_SIZE_M:
        raise SessionError(f"{where}: the shape is {1e3 * size_m:g} mm across in the unit declared ({unit}): too small "
                           f"for a depth camera to resolve; is the file in metres? declare unit: m")


def load_shape(path: str | Path, unit: str = "mm", *, samples: int | None = None) -> Shape:
    """A target's shape from a mesh file (STL, OBJ, PLY with faces, OFF; read with trimesh) or a
    template cloud of its surface (PLY without faces, PCD, NPY of (N, 3)), in ``unit`` (m | mm).

    Raises
    ------
    SessionError
        Naming the file: it does not exist, is not a mesh (or a cloud) trimesh can read, has no
        surface, or its size in the declared unit is implausible (a mesh in mm declared m is tens of
        metres across: the error says to declare mm).
    """
    path = Path(path)
    if unit not in ("m", "mm"):
        raise SessionError(f"{path}: the shape's unit is m or mm, not {shown(unit)}")
    if not path.is_file():
        raise SessionError(f"{path}: no such mesh file")
    factor = 1e-3 if unit == "mm" else 1.0
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES + TEMPLATE_SUFFIXES:
        raise SessionError(f"{path}: a target's shape is a mesh ({', '.join(MESH_SUFFIXES)}) or a template cloud "
                           f"({', '.join(TEMPLATE_SUFFIXES)})")
    if suffix in (".pcd", ".npy"):
        return _template(read_points(path, unit), path, unit)
    trimesh = _trimesh(path)
    try:
        loaded = trimesh.load(str(path), force="mesh", process=True)
    except Exception as exc:  # whatever the reader raises on a damaged or foreign file: say which file
        raise SessionError(f"{path}: not a mesh trimesh can read ({type(exc).__name__}: {exc}); give an STL, OBJ or "
                           "PLY of the target's surface") from None
    faces = getattr(loaded, "faces", None)
    vertices = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))), float)
    if faces is None or len(faces) == 0:
        if suffix == ".ply":  # a PLY of points: a template cloud
            return _template(read_points(path, unit), path, unit)
        raise SessionError(f"{path}: no surface in the file ({len(vertices)} vertices, no faces): not a mesh; give an "
                           "STL, OBJ or PLY of the target's surface, or a template cloud of it (PCD, PLY)")
    mesh = loaded.copy()
    mesh.apply_scale(factor)
    _checked_size(float(np.linalg.norm(mesh.extents)), unit, str(path))
    _checked_surface(mesh, unit, str(path))
    return shape_from_mesh(mesh, path.name, samples)


#: A mesh thinner than this share of its size across its thinnest direction is flat (a surface, not a part).
FLAT_SHARE = 1e-4


def _checked_surface(mesh, unit: str, where: str) -> None:
    """Refuse a mesh with no surface to find (its vertices on one line: no area to sample) or a flat
    one whose faces point both ways (a part flattened to a plane, front and back on one another):
    the clouds then fit it from either side, the views disagree, and the fit would blame the robot."""
    f = 1e3 if unit == "mm" else 1.0
    v = np.asarray(mesh.vertices, float)
    size = float(np.linalg.norm(mesh.extents))
    _, s, Vt = np.linalg.svd(v - v.mean(axis=0), full_matrices=False)
    if float(mesh.area) <= (FLAT_SHARE * size) ** 2 or (len(s) > 1 and s[1] <= FLAT_SHARE * s[0]):
        raise SessionError(f"{where}: the mesh has no area: its vertices lie on one line ({f * size:.4g} {unit} long); "
                           "give an STL, OBJ or PLY of the target's surface")
    across = (v - v.mean(axis=0)) @ Vt[-1]
    if float(np.ptp(across)) <= FLAT_SHARE * size:
        normals = np.asarray(mesh.face_normals, float) @ Vt[-1]
        weights = np.asarray(mesh.area_faces, float)
        if weights[normals > 0.5].sum() > 0.1 * weights.sum() and weights[normals < -0.5].sum() > 0.1 * weights.sum():
            raise SessionError(f"{where}: the mesh is flat: its vertices lie in one plane ({f * float(np.ptp(across)):.2g} "
                               f"{unit} thick across {f * size:.4g} {unit}) and its faces point both ways, front and back "
                               "on one another: a cloud fits it from either side, and the part's relief (its walls, "
                               "bores, edges) is what pins its pose; give the part's solid mesh (or one side of it)")


def shape_from_mesh(mesh, name: str = "mesh", samples: int | None = None) -> Shape:
    """A :class:`Shape` from a trimesh.Trimesh in metres: its surface sampled evenly by area (seed
    0), each sample with its face's normal."""
    size = float(np.linalg.norm(mesh.extents))
    spacing = size / 600.0
    count = samples or int(np.clip(mesh.area / spacing**2, 2000, MAX_SAMPLES))
    points, face = sample_surface(mesh, count)
    normals = np.asarray(mesh.face_normals, float)[face]
    spacing = float(np.sqrt(mesh.area / count))
    return Shape(name, points, normals, spacing, free_twists(points, normals), mesh)


def sample_surface(mesh, count: int) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """``count`` points uniform over ``mesh``'s area (a trimesh.Trimesh; deterministic, seed 0) and
    the index of each one's face."""
    rng = np.random.default_rng(0)
    area = np.asarray(mesh.area_faces, float)
    face = rng.choice(len(area), count, p=area / area.sum())
    tri = np.asarray(mesh.triangles, float)[face]
    r = rng.random((count, 2))
    flip = r.sum(axis=1) > 1
    r[flip] = 1 - r[flip]
    points = tri[:, 0] + r[:, :1] * (tri[:, 1] - tri[:, 0]) + r[:, 1:] * (tri[:, 2] - tri[:, 0])
    return points, face


def shape_from_points(points: NDArray[np.float64], name: str = "template") -> Shape:
    """A :class:`Shape` from a template cloud of the surface (metres): each point's normal from its
    12 nearest neighbours (a plane fitted to them), turned away from the cloud's centroid (outwards,
    for a shape without deep hollows: a camera sees the side a normal points to)."""
    p = np.asarray(points, float)
    p = p[np.isfinite(p).all(axis=1)]
    d, nb = cKDTree(p).query(p, k=min(12, len(p)))
    local = p[nb] - p[nb].mean(axis=1, keepdims=True)
    _, _, Vt = np.linalg.svd(local, full_matrices=False)
    normals = Vt[:, 2]
    normals *= np.where(np.einsum("mi,mi->m", normals, p - p.mean(axis=0)) < 0, -1.0, 1.0)[:, None]
    return Shape(name, p, normals, float(np.median(d[:, 1])), free_twists(p, normals))


def _template(points: NDArray[np.float64], path: Path, unit: str) -> Shape:
    p = np.asarray(points, float).reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)]
    if len(p) < 100:
        raise SessionError(f"{path}: a template cloud needs at least 100 points of the target's surface; it has {len(p)}")
    _checked_size(float(np.linalg.norm(p.max(axis=0) - p.min(axis=0))), unit, str(path))
    return shape_from_points(p, path.name)
