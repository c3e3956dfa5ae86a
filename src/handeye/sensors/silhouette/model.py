"""An arm's silhouette in a fixed colour camera's images as a sensor model (:mod:`handeye.sensors.base`).

No target: the camera (eye-to-hand, X = cam2base) sees the robot, whose shape in every view is its
links' meshes placed by the joint angles (:class:`~handeye.robot.meshes.ArmMeshes`). What a view
measured is the arm's mask (a segmentation of the image); what X predicts is the meshes' silhouette.

:class:`ArmViews` holds the posed meshes and the masks' signed distance fields and finds, at a
given X, each view's *outline points*: points of the meshes' occluding contours (the edges between a
triangle that faces the camera and one that does not) whose projection lies on the outer boundary
of the rendered silhouette (:func:`~handeye.sensors.silhouette.render.render_silhouettes`), at most
one per pixel of that boundary. They are fixed points of the arm (base frame).

:class:`SilhouetteContours` is the model the core fits: each outline point is a measurement row,
its residual the mask's signed distance (pixels, read with sub-pixel bilinear interpolation,
positive outside the mask) at the point's projection through X, times the point's depth over the
focal length: millimetres at the arm, the unit every other sensor's residuals are in (the figures
give pixels too). The outline points are found again between rounds by the pipeline
(:mod:`handeye.pipelines.silhouette.pipeline`) as X moves; within a fit they stay.

Neighbouring outline points share their errors (a boundary off by a pixel along a stretch, a mesh
that differs from the real link): the noise model alone would claim too small a std, and the core's
leave-views-out jackknife widens it.

Examples
--------
>>> import numpy as np
>>> from handeye.sensors.silhouette.model import SilhouetteContours
>>> K = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
>>> sdf = np.zeros((1, 480, 640), np.float32)
>>> m = SilhouetteContours(["v0"], np.array([[0.0, 0.0, 1.0]]), np.array([0]), K, None, sdf, np.eye(4))
>>> m.residuals(np.eye(4), np.zeros(0), np.eye(4)[None], np.array([0])).shape
(1, 1)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._shared.lazy import lazy_module
from ...errors import InputMismatchError
from ...frames.setups import setup_info
from .render import NEAR, bilinear, project, projection_jacobian, render_silhouettes, signed_distance

cv2 = lazy_module("cv2")

__all__ = ["ArmViews", "SilhouetteContours", "mesh_edges", "NOISE_PX", "ON_OUTLINE_PX", "BORDER_PX"]

#: A mask's boundary is placed to about this (pixels) by a good segmentation (its RMS, blobs and ragged
#: stretches included): the noise stated before any fit.
NOISE_PX = 2.0
#: An occluding contour's point is on the rendered silhouette's outline when its projection is this
#: close (pixels) to the boundary.
ON_OUTLINE_PX = 0.5
#: The renderer's silhouette reaches this far (pixels) beyond the projected outline (OpenCV fills
#: every pixel whose centre is within about half a pixel of the polygon; 0.46 measured on turned squares).
FILL_PX = 0.46
#: Outline points this close to the image's border (pixels) are left out: the mask ends there, not the arm.
BORDER_PX = 3.0
#: The report draws at most this many outline points of a view.
SECTION_POINTS = 1500
#: The masks' distance fields are computed with the image padded by this many pixels (copies of
#: its border): the image's edge is not the arm's.
PAD = 64


def mesh_edges(faces: NDArray[np.intp]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """A mesh's edges (E, 2: vertex indices) and the faces on each side (E, 2; both the same face
    for an edge on a hole's border). Edges of more than two faces are paired in order."""
    f = np.asarray(faces, dtype=np.intp)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    face = np.tile(np.arange(len(f)), 3)
    e.sort(axis=1)
    key = e[:, 0] * (int(f.max()) + 1) + e[:, 1]
    order = np.argsort(key, kind="stable")
    key, e, face = key[order], e[order], face[order]
    first = np.r_[True, key[1:] != key[:-1]]
    start = np.flatnonzero(first)
    count = np.diff(np.r_[start, len(key)])
    second = np.where(count >= 2, start + 1, start)
    return e[start], np.c_[face[start], face[second]]


@dataclass(frozen=True)
class ArmViews:
    """The arm's meshes posed in every view, the camera, and the masks.

    Attributes
    ----------
    vertices : ndarray (N, V, 3)
        Per view the merged meshes' vertices in the base frame (m).
    faces : ndarray (F, 3)
    K : ndarray (3, 3)
    dist : ndarray or None
    masks : ndarray of bool (N, height, width)
    """

    vertices: NDArray[np.float64]
    faces: NDArray[np.intp]
    K: NDArray[np.float64]
    dist: NDArray[np.float64] | None
    masks: NDArray[np.bool_]
    edges: NDArray[np.intp] = field(init=False, repr=False)  #: the meshes' edges (E, 2), :func:`mesh_edges`
    sides: NDArray[np.intp] = field(init=False, repr=False)  #: the faces on each side of each edge (E, 2)
    sdf: NDArray[np.float32] = field(init=False, repr=False)  #: per view the mask's signed distance field (pixels)
    _drawn: dict[tuple[bytes, bytes], Any] = field(init=False, repr=False, compare=False)  #: the last rendering

    def __post_init__(self) -> None:
        if len(self.vertices) != len(self.masks):
            raise InputMismatchError(f"{len(self.vertices)} posed arms and {len(self.masks)} masks: give one mask per view")
        edges, sides = mesh_edges(self.faces)
        object.__setattr__(self, "edges", edges)  # frozen: set once here
        object.__setattr__(self, "sides", sides)
        object.__setattr__(self, "sdf", np.array([_padded_sdf(m) for m in self.masks]))
        object.__setattr__(self, "_drawn", {})  # the last rendering, by cam2base and views: asked twice in a row

    @property
    def size(self) -> tuple[int, int]:
        """The images' width and height."""
        return int(self.masks.shape[2]), int(self.masks.shape[1])

    def in_camera(self, cam2base: NDArray[np.float64], views: NDArray[np.intp] | None = None) -> NDArray[np.float64]:
        """The views' vertices (n, V, 3) in the camera frame."""
        V = self.vertices if views is None else self.vertices[views]
        return (V - cam2base[:3, 3]) @ cam2base[:3, :3]

    def render(self, cam2base: NDArray[np.float64], views: NDArray[np.intp] | None = None) -> NDArray[np.bool_]:
        """The meshes' silhouettes (n, height, width) through ``cam2base`` (the last one kept: the
        pipeline asks for the same one twice, the IoU and the outline of a pose, or the IoU and the
        pairing check of the result)."""
        views = np.arange(len(self.masks)) if views is None else np.asarray(views, dtype=np.intp)
        key = (np.asarray(cam2base, float).tobytes(), views.tobytes())
        if key not in self._drawn:
            self._drawn.clear()
            self._drawn[key] = render_silhouettes(self.in_camera(cam2base, views), self.faces, self.K, self.size, self.dist)
        return self._drawn[key].copy()

    def ious(self, cam2base: NDArray[np.float64], views: NDArray[np.intp] | None = None) -> NDArray[np.float64]:
        """Per view the IoU of the rendered silhouette with the mask."""
        views = np.arange(len(self.masks)) if views is None else np.asarray(views)
        drawn = self.render(cam2base, views)
        inter = np.count_nonzero(drawn & self.masks[views], axis=(1, 2))
        union = np.count_nonzero(drawn | self.masks[views], axis=(1, 2))
        return inter / np.maximum(union, 1)

    def outline_points(self, cam2base: NDArray[np.float64], views: NDArray[np.intp] | None = None, spacing: float = 1.0
                       ) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
        """The views' outline points at ``cam2base`` (the module's docstring): (M, 3) in the base
        frame and each one's view (M,), at most one per ``spacing`` pixels of the outline."""
        views = np.arange(len(self.masks)) if views is None else np.asarray(views)
        Vc = self.in_camera(cam2base, views)
        drawn = self.render(cam2base, views)
        points, owner = [], []
        for k, v in enumerate(views):
            p = self._view_outline(Vc[k], self.vertices[v], drawn[k], spacing)
            points.append(p)
            owner.append(np.full(len(p), v, dtype=np.intp))
        return np.concatenate(points), np.concatenate(owner)

    def _view_outline(self, Vc: NDArray[np.float64], Vb: NDArray[np.float64], drawn: NDArray[np.bool_], spacing: float
                      ) -> NDArray[np.float64]:
        tri = Vc[self.faces]
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        front = np.einsum("fi,fi->f", normal, tri[:, 0]) < 0
        a, b = front[self.sides[:, 0]], front[self.sides[:, 1]]
        rim = (a != b) | ((self.sides[:, 0] == self.sides[:, 1]) & a)
        e = self.edges[rim]
        if not len(e):
            return np.zeros((0, 3))
        uv, z = project(Vc[e], self.K, self.dist)  # (E, 2, 2)
        length = np.linalg.norm(uv[:, 1] - uv[:, 0], axis=1)
        ok = np.isfinite(length) & (z.min(axis=1) > NEAR)
        e, length = e[ok], length[ok]
        n = np.clip(np.ceil(length / (0.5 * spacing)).astype(np.intp), 1, 200)
        edge = np.repeat(np.arange(len(e)), n)
        t = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n) + 0.5) / np.repeat(n, n)
        P = Vb[e[edge, 0]] * (1 - t)[:, None] + Vb[e[edge, 1]] * t[:, None]
        Pc = Vc[e[edge, 0]] * (1 - t)[:, None] + Vc[e[edge, 1]] * t[:, None]
        uv, _ = project(Pc, self.K, self.dist)
        w, h = self.size
        inside = (uv[:, 0] >= BORDER_PX) & (uv[:, 0] <= w - 1 - BORDER_PX) & (uv[:, 1] >= BORDER_PX) & \
            (uv[:, 1] <= h - 1 - BORDER_PX)
        P, uv = P[inside], uv[inside]
        field = signed_distance(drawn)
        on = np.abs(bilinear(field, uv) + FILL_PX) < ON_OUTLINE_PX
        P, uv = P[on], uv[on]
        cell = np.floor(uv / spacing).astype(np.intp)
        _, first = np.unique(cell[:, 1] * (w + 1) + cell[:, 0], return_index=True)
        return P[np.sort(first)]


def _padded_sdf(mask: NDArray[np.bool_]) -> NDArray[np.float32]:
    """The mask's signed distance field, the image's border not a boundary (padded with copies of it)."""
    m = np.pad(np.asarray(mask, bool), PAD, mode="edge")
    return signed_distance(m)[PAD:-PAD, PAD:-PAD]


class SilhouetteContours:
    """The outline points of an arm's silhouette against the masks (module docstring).

    Parameters
    ----------
    names : list of str
        Per view its name.
    points : ndarray (M, 3)
        The outline points in the base frame (m), each a measurement row.
    owner : ndarray (M,)
        Each point's view.
    K, dist
        The camera.
    sdf : ndarray (N, height, width)
        Per view the mask's signed distance field (pixels).
    start_X : ndarray (4, 4)
        cam2base to start the fit from.
    """

    kind = "colour camera"
    target = "arm silhouette"
    setup = "eye_to_hand"
    groups: tuple[tuple[int, ...], ...] = ((0,),)
    param_names: list[str] = []
    param_scale = np.zeros(0)

    def __init__(self, names: list[str], points: NDArray[np.float64], owner: NDArray[np.intp], K: NDArray[np.float64],
                 dist: NDArray[np.float64] | None, sdf: NDArray[np.float32], start_X: NDArray[np.float64]) -> None:
        self.names, self.points = list(names), np.asarray(points, float)
        self.owner = np.asarray(owner, dtype=np.intp)
        self.K, self.dist, self.sdf = np.asarray(K, float), dist, sdf
        self.start_X = np.asarray(start_X, float)
        z = (self.points - self.start_X[:3, 3]) @ self.start_X[:3, 2]
        #: metres per pixel at each point (its depth over the focal length): pixels to millimetres at the arm
        self.scale = np.maximum(z, NEAR) / float(np.sqrt(self.K[0, 0] * self.K[1, 1]))
        self.shape = self.scale[:, None]

    def view_poses(self) -> None:
        """None: a view measures no whole pose."""
        return None

    def start(self, flange2base, X, Z, rows=None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The pose the pipeline found (the global search refined by the outline rounds)."""
        return self.start_X.copy(), np.zeros(0)

    def _camera_points(self, X: NDArray[np.float64], rows: NDArray[np.intp]) -> NDArray[np.float64]:
        return (self.points[rows] - X[:3, 3]) @ X[:3, :3]

    def residuals_px(self, X: NDArray[np.float64], rows: NDArray[np.intp]) -> NDArray[np.float64]:
        """The rows' signed distances (pixels) from their mask's boundary, positive outside."""
        uv, _ = project(self._camera_points(X, rows), self.K, self.dist)
        uv = np.nan_to_num(uv, nan=-1e6)
        return bilinear(self.sdf, uv, views=self.owner[rows])

    def residuals(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """The rows' distances from their mask's boundary at their depth (m; (len(rows), 1))."""
        rows = np.asarray(rows, dtype=np.intp)
        return (self.residuals_px(X, rows) * self.scale[rows])[:, None]

    def jacobian(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """The residuals' derivatives (M, 1, 6) for a left increment of X (rotation, translation)."""
        rows = np.asarray(rows, dtype=np.intp)
        pc = self._camera_points(X, rows)
        uv, _ = project(pc, self.K, self.dist)
        uv = np.nan_to_num(uv, nan=-1e6)
        grad = bilinear(self.sdf, uv, gradient=True, views=self.owner[rows])[1]
        Jp = projection_jacobian(pc, self.K, self.dist)  # (M, 2, 3)
        g = np.einsum("mi,mij->mj", grad, Jp)  # over the camera-frame point
        a = g @ X[:3, :3].T  # over the point in the base frame
        rel = self.points[rows] - X[:3, 3]
        # p_cam = R^T (P - t) under R' = exp(w) R, t' = t + s: moved by R^T (rel x w - s), so
        # a . (rel x w) = w . (a x rel) and -a . s
        d_rot = np.cross(a, rel)
        d_trans = -a
        return (np.c_[d_rot, d_trans] * self.scale[rows, None])[:, None, :]

    def sections(self, X, p, flange2base, views) -> list[dict[str, Any]]:
        """Per view of ``views`` the image as the report draws it, in millimetres at the arm (pixels
        times the view's median depth over the focal length; x right, y down): the outline points
        through X with their residuals (at most :data:`SECTION_POINTS`), and the mask's boundary
        (its contours, NaN between them)."""
        out = []
        for v in views:
            rows = np.flatnonzero(self.owner == v)
            rows = rows[np.linspace(0, len(rows) - 1, min(len(rows), SECTION_POINTS)).astype(np.intp)] if len(rows) else rows
            mm = 1e3 * float(np.median(self.scale[rows])) if len(rows) else 1.0
            uv, _ = project(self._camera_points(X, rows), self.K, self.dist)
            contours, _ = cv2.findContours((self.sdf[v] < 0).astype(np.uint8), cv2.RETR_LIST, cv2.CHAIN_APPROX_SIMPLE)
            curve = np.concatenate([np.r_[c.reshape(-1, 2), c.reshape(-1, 2)[:1], [[np.nan, np.nan]]] for c in contours]) \
                if contours else np.full((1, 2), np.nan)
            out.append({"points_mm": uv * mm, "residual_mm": 1e3 * self.residuals(X, p, flange2base, rows)[:, 0],
                        "curve_mm": curve * mm, "plane": "its image (mm at the arm: the outline points, the mask's boundary)"})
        return out

    def Z(self, X, p) -> NDArray[np.float64]:
        """The identity: the target is the arm itself, placed by its joint angles (no target2flange to find)."""
        return np.eye(4)

    def Z_std(self, p, cov_p) -> NDArray[np.float64]:
        """Zero: nothing of the target is fitted."""
        return np.zeros(6)

    def figures(self, p, cov_p) -> dict[str, Any]:
        """The outline points and the pixels they are measured in."""
        return {"outline_points": int(len(self.owner)), "residual_unit": "mm at the arm (pixels times depth over focal length)",
                "mm_per_px_median": float(1e3 * np.median(self.scale)) if len(self.scale) else None}

    def notes(self, p, cov_p) -> list[str]:
        """What the target is."""
        return [f"no target: the arm's own silhouette; {setup_info(self.setup).z_name} is the identity (the arm is placed "
                "by its joint angles)"]

    def noise_mm(self, rows) -> NDArray[np.float64]:
        """The segmentation's stated noise (:data:`NOISE_PX`) at each row's depth (mm)."""
        return 1e3 * NOISE_PX * self.scale[np.asarray(rows, dtype=np.intp)]
