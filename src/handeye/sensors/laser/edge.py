"""Profiles of a block's edge or of a step: two flat faces as laser targets (:mod:`handeye.sensors.base`).

A profile across an edge (a block's top and side: two planes meeting at a line, at an angle that
is fitted, not assumed) or a step (two parallel faces at different heights) is two straight pieces;
mapped through the flange pose and X (``q = A_i X p``, :func:`~handeye.frames.setups.robot_world_A`)
every point must lie on the face it belongs to: its residual is its signed distance from the nearer
face at the current estimate (smooth wherever a point is nearer one face by more than the noise:
everywhere but within the noise of the edge line, or, for a step, never, the faces being apart).

* :class:`EdgeProfiles`: the unknowns are the two faces' normals (each in a chart about its first
  start's, as :class:`~handeye.sensors.laser.plane.PlaneProfiles` has it) and their distances from
  the origin of the frame they are fixed in: 6. A profile gives four equations (two lines' offsets
  and slopes), twice a plate's.
* :class:`StepProfiles`: one normal for both faces and two distances: 4. A step's riser (the face
  between the levels) is no part of the model: its points are set aside as stray.

The start (:func:`faces_start`): each profile split into its two straight pieces (the breakpoint of
the best two-line fit along the profile, each line refitted without its stray points); then from
each of :data:`~handeye.sensors.laser.plane.SEARCH_ROTATIONS` rotations of X the pieces' directions
mapped into the target's frame are fitted to two planes through the origin (their product, which
needs no labels, for an edge; one plane for a step), which labels each piece with its face (a
step's by its distance from the sensor: the upper face is the nearer); X's translation and the
faces' distances are then linear, and all of it is polished on the labelled points. The best
polish is the start; fits as good as it with X's rotation more than
:data:`~handeye.sensors.laser.plane.AMBIGUOUS_DEG` apart are refused as ambiguous.

Examples
--------
>>> from handeye.pipelines.laser.simulate import laser_scene
>>> sc = laser_scene(20, "eye_in_hand", rng=3, target="edge")
>>> model = EdgeProfiles("eye_in_hand", [f"p{k}" for k in range(20)], sc.profiles)
>>> X0, p0 = model.start(sc.flange2base, None, None)   # the searched start, which the fit refines
>>> bool(np.degrees(np.arccos((np.trace(X0[:3, :3].T @ sc.X[:3, :3]) - 1) / 2)) < 1.0)
True
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ...errors import DegenerateMotionError
from ...frames.setups import robot_world_A
from ...geometry.se3 import make_transform, perpendicular_basis
from .model import LASER_NOISE_M, Profiles
from .plane import AMBIGUOUS_DEG, SEARCH_GIVE_UP_M, SEARCH_POINTS, SEARCH_ROTATIONS

__all__ = ["EdgeProfiles", "StepProfiles", "faces_start", "profile_pieces"]

#: A straight piece of a profile needs this many points (and :data:`PIECE_M` of length) to give a direction.
PIECE_POINTS, PIECE_M = 15, 2e-3
#: A profile is two pieces when one line leaves this many times the two lines' RMS (else one piece).
TWO_PIECES = 3.0
#: The search scores this many rotations of X by how well the pieces' directions fit, polishes the
#: SEARCH_POLISHED best, and fits the points from the POLISHED best of those (twins included).
SEARCH_SAMPLES, SEARCH_POLISHED, POLISHED = 20000, 40, 8


def _line_sse(n, sx, sz, sxx, szz, sxz) -> NDArray[np.float64]:
    """The orthogonal regression's sum of squares of ``n`` points with these sums (vectorised): the
    smallest eigenvalue of their scatter matrix."""
    n = np.maximum(n, 1.0)
    cxx, czz, cxz = sxx - sx * sx / n, szz - sz * sz / n, sxz - sx * sz / n
    return np.maximum(0.5 * (cxx + czz) - np.sqrt(0.25 * (cxx - czz) ** 2 + cxz**2), 0.0)


def _line(p: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The orthogonal regression line of (n, 2) points: its centroid, unit direction, and each point's distance."""
    c = p.mean(axis=0)
    u = np.linalg.svd(p - c, full_matrices=False)[2][0]
    return c, u, (p - c) @ np.array([-u[1], u[0]])


def _robust_line(p: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """The line of (n, 2) points refitted twice without those beyond 5 of the robust spread (spikes,
    a step's riser): centroid, direction, the points kept."""
    keep = np.ones(len(p), bool)
    for _ in range(3):
        c, u, dist = _line(p[keep])
        all_dist = np.abs((p - c) @ np.array([-u[1], u[0]]))
        keep = all_dist <= max(5 * 1.4826 * float(np.median(np.abs(dist))), 5e-6)
        if keep.sum() < 2:
            keep[:] = True
            break
    return c, u, keep


def _split(xz: NDArray[np.float64]) -> int | None:
    """The breakpoint (an index into ``xz``, sorted along x) of the best two-line fit, or None when one
    line fits nearly as well (the profile crossed one face only)."""
    n = len(xz)
    x, z = xz[:, 0], xz[:, 1]
    sums = [np.r_[0.0, np.cumsum(v)] for v in (np.ones(n), x, z, x * x, z * z, x * z)]
    k = np.arange(PIECE_POINTS, n - PIECE_POINTS + 1)
    if not len(k):
        return None
    left = _line_sse(*(s[k] for s in sums))
    right = _line_sse(*(s[n] - s[k] for s in sums))
    best = int(np.argmin(left + right))
    one = float(_line_sse(*(s[n] for s in sums)))
    two = float(left[best] + right[best])
    return int(k[best]) if one > TWO_PIECES**2 * max(two, n * 1e-12) else None


def profile_pieces(points: NDArray[np.float64], owner: NDArray[np.intp]
                   ) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64], NDArray[np.float64]]:
    """Each profile's straight pieces: per point its piece (-1: none, a stray point), and per piece its
    view, its unit direction (x, 0, z) in the sensor frame and its distance from the sensor's origin
    (in the laser plane). A profile is split at the best two-line fit's breakpoint
    (:func:`_split`); each piece's line is refitted without its stray points."""
    piece = np.full(len(points), -1, dtype=np.intp)
    views: list[Any] = []
    directions: list[Any] = []
    distances: list[Any] = []
    for v in np.unique(owner):
        rows = np.flatnonzero(owner == v)
        rows = rows[np.argsort(points[rows, 0], kind="stable")]
        xz = points[rows][:, [0, 2]]
        k = _split(xz)
        for part in ([rows] if k is None else [rows[:k], rows[k:]]):
            p = points[part][:, [0, 2]]
            c, u, keep = _robust_line(p)
            if keep.sum() < PIECE_POINTS or np.ptp(p[keep] @ u) < PIECE_M:
                continue
            piece[part[keep]] = len(views)
            views.append(v)
            directions.append([u[0], 0.0, u[1]])
            distances.append(abs(c @ np.array([-u[1], u[0]])))
    return (piece, np.array(views, dtype=np.intp), np.array(directions).reshape(-1, 3), np.array(distances))


def _chart(n0: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    return (n0, *perpendicular_basis(n0))


def _unit(chart, a, b) -> NDArray[np.float64]:
    m = chart[0] + a * chart[1] + b * chart[2]
    return m / np.linalg.norm(m)


def _lifted(W: NDArray[np.float64], shared: bool) -> NDArray[np.float64]:
    """The rows (..., P, c) whose null vector fits the pieces' directions ``W`` (..., P, 3): a step's
    normal (``n . w = 0``), or an edge's two planes through the origin as one quadric, ``w^T Q w = 0``
    with ``Q = (n1 n2^T + n2 n1^T) / 2`` (generalised PCA: no labels needed)."""
    if shared:
        return W
    x, y, z = W[..., 0], W[..., 1], W[..., 2]
    return np.stack([x * x, y * y, z * z, 2 * x * y, 2 * x * z, 2 * y * z], axis=-1)


def _normals_of(W: NDArray[np.float64], shared: bool) -> NDArray[np.float64]:
    """The faces' normals (2, 3) that the directions ``W`` fit best (:func:`_lifted`'s null vector;
    an edge's ``Q`` factored: ``n1, n2 ~ sqrt(l+) v+ +- sqrt(-l-) v-``)."""
    v = np.linalg.svd(_lifted(W, shared), full_matrices=False)[2][-1]
    if shared:
        return np.array([v, v])
    Q = np.array([[v[0], v[3], v[4]], [v[3], v[1], v[5]], [v[4], v[5], v[2]]])
    lam, V = np.linalg.eigh(Q)
    a, b = np.sqrt(max(lam[2], 1e-12)) * V[:, 2], np.sqrt(max(-lam[0], 1e-12)) * V[:, 0]
    return np.array([(a + b) / np.linalg.norm(a + b), (a - b) / np.linalg.norm(a - b)])


def _rotations(R_piece: NDArray[np.float64], u: NDArray[np.float64], shared: bool) -> list[tuple[float, NDArray[np.float64]]]:
    """X's rotations that fit the pieces' directions (``R_piece R u`` on the faces' planes), best first:
    :data:`SEARCH_SAMPLES` rotations scored at once (:func:`_lifted`'s smallest singular value), the
    :data:`SEARCH_POLISHED` best polished (the null vector solved again at each step), duplicates
    dropped. A turn of 180 deg about the sensor's y axis reverses every direction and fits as well:
    each comes with that twin (the points' positions tell them apart)."""
    Rs = Rotation.random(SEARCH_SAMPLES, random_state=0).as_matrix()
    chunk = max(1, 200000 // len(u))  # rotations scored at once: memory bounded by many profiles
    score = np.concatenate([np.linalg.svd(_lifted(np.einsum("pij,njk,pk->npi", R_piece, Rs[k:k + chunk], u), shared),
                                          compute_uv=False)[:, -1] for k in range(0, len(Rs), chunk)])

    def fun(x, R0):
        V = _lifted(np.einsum("pij,pj->pi", R_piece, u @ (Rotation.from_rotvec(x).as_matrix() @ R0).T), shared)
        return V @ np.linalg.svd(V, full_matrices=False)[2][-1]

    polished = []
    for R0 in Rs[np.argsort(score)[:SEARCH_POLISHED]]:
        res = least_squares(fun, np.zeros(3), method="lm", args=(R0,), max_nfev=200)
        polished.append((float(np.sum(res.fun**2)), Rotation.from_rotvec(res.x).as_matrix() @ R0))
    polished.sort(key=lambda c: c[0])
    twin = np.diag([-1.0, 1.0, -1.0])  # 180 deg about the sensor's y axis
    out: list[tuple[float, NDArray[np.float64]]] = []
    for cost, R in polished:
        for Rc in (R, R @ twin):
            if all(np.linalg.norm(Rotation.from_matrix(Rc @ R_o.T).as_rotvec()) > np.radians(2.0) for _, R_o in out):
                out.append((cost, Rc))
    return out


def _polished(A, points, labels, R0, normals, shared: bool, max_nfev: int = 60
              ) -> tuple[float, NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """From X's rotation ``R0`` and the faces' ``normals``: X's translation and the distances (linear),
    then all of them polished on the points labelled with their face (soft L1 of 1 mm): (robust RMS
    in m of every point's distance from its nearer face, X, normals (2, 3), distances (2,))."""
    R, tA = A[:, :3, :3], A[:, :3, 3]
    n_pt = normals[labels]
    base = np.einsum("mij,mj->mi", R, points @ R0.T) + tA
    M = np.c_[np.einsum("mji,mj->mi", R, n_pt), -(labels[:, None] == np.arange(2)).astype(float)]
    sol = np.linalg.lstsq(M, -np.einsum("mi,mi->m", n_pt, base), rcond=None)[0]
    charts = [_chart(n) for n in (normals[:1] if shared else normals)]
    k = len(charts)

    def unpack(u):
        Rx = Rotation.from_rotvec(u[:3]).as_matrix() @ R0
        n = np.array([_unit(c, u[6 + 2 * j], u[7 + 2 * j]) for j, c in enumerate(charts)])
        return Rx, u[3:6], n[[0, 0]] if shared else n, u[6 + 2 * k:]

    def fun(u):
        Rx, t, n, d = unpack(u)
        q = np.einsum("mij,mj->mi", R, points @ Rx.T + t) + tA
        return np.einsum("mi,mi->m", q, n[labels]) - d[labels]

    def jac(u):  # X's columns for a left increment (the fit's own stationary points, fewer evaluations)
        Rx, t, n, d = unpack(u)
        v = points @ Rx.T
        w = np.einsum("mji,mj->mi", R, n[labels])  # R_A^T n
        q = np.einsum("mij,mj->mi", R, v + t) + tA
        cols = [np.cross(v, w), w]
        for j, c in enumerate(charts):
            m = c[0] + u[6 + 2 * j] * c[1] + u[7 + 2 * j] * c[2]
            project = (np.eye(3) - np.outer(n[j], n[j])) / np.linalg.norm(m)
            on = ((labels == j) | shared)[:, None]
            cols.append(np.c_[q @ (project @ c[1]), q @ (project @ c[2])] * on)
        cols.append(-(labels[:, None] == np.arange(2)).astype(float))
        return np.concatenate(cols, axis=1)

    u0 = np.r_[np.zeros(3), sol[:3], np.zeros(2 * k), sol[3:]]
    res = least_squares(fun, u0, jac, loss="soft_l1", f_scale=1e-3, x_scale=1e-3, max_nfev=max_nfev)
    Rx, t, n, d = unpack(res.x)
    q = np.einsum("mij,mj->mi", R, points @ Rx.T + t) + tA
    nearest = np.min(np.abs(q @ n.T - d), axis=1)
    return float(np.sqrt(np.median(nearest**2))), make_transform(Rx, t), n, d


def _piece_labels(W: NDArray[np.float64], normals: NDArray[np.float64], shared: bool,
                  distances: NDArray[np.float64], views: NDArray[np.intp]) -> NDArray[np.intp]:
    """Each piece's face: an edge's the plane its direction lies in, a profile's two pieces on the two
    faces (the pairing that fits better); a step's by its distance from the sensor in its profile
    (the upper face, 0, is the nearer; a profile's lone piece: left out, -1)."""
    out = np.full(len(views), -1, dtype=np.intp)
    off = np.abs(W @ normals.T)  # (P, 2): each piece's direction off each face's plane
    for v in np.unique(views):
        idx = np.flatnonzero(views == v)
        if len(idx) == 2:
            swap = (off[idx[0], 1] + off[idx[1], 0] < off[idx[0], 0] + off[idx[1], 1]) if not shared else (
                distances[idx[0]] > distances[idx[1]])
            out[idx] = [1, 0] if swap else [0, 1]
        elif not shared:
            out[idx] = np.argmin(off[idx], axis=1)
    return out


def faces_start(A: NDArray[np.float64], points: NDArray[np.float64], owner: NDArray[np.intp], pieces: tuple,
                shared: bool, good_m: float, rotation: NDArray[np.float64] | None = None, fallback: bool = False
                ) -> tuple[float, NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """X, both faces' normals (2, 3) and distances (2,) from points ``p`` (point ``m`` seen from the
    robot-world pose ``A[owner[m]]``) with their ``pieces`` (:func:`profile_pieces`), searched from
    :data:`~handeye.sensors.laser.plane.SEARCH_ROTATIONS` rotations of X (or only from ``rotation``):
    the module docstring's steps. Returns (the robust RMS, m, X, normals, distances).

    Raises DegenerateMotionError when no profile has two pieces, when the best fit is worse than
    :data:`~handeye.sensors.laser.plane.SEARCH_GIVE_UP_M`, or when fits within ``good_m`` RMS of the
    best put X's rotation more than :data:`~handeye.sensors.laser.plane.AMBIGUOUS_DEG` apart."""
    piece, views, u, dist = pieces
    what = "a step" if shared else "an edge"
    turns = "turned 10 deg or more about two or three axes between them"
    if len(np.unique(views)) == len(views) or len(views) < (4 if shared else 7):
        raise DegenerateMotionError(
            f"the profiles of {what} have {len(views)} straight pieces in {len(np.unique(views))} profiles: capture 10 "
            f"or more profiles that cross the {'step' if shared else 'edge'}, each showing both faces (a laser line "
            "across the edge line, not along it)")
    R_piece = A[views, :3, :3]
    sample = np.flatnonzero(piece >= 0)
    sample = sample[np.linspace(0, len(sample) - 1, min(len(sample), SEARCH_POINTS)).astype(np.intp)]
    if rotation is not None:
        candidates = [rotation]
    elif fallback:  # the directions leave X's rotation open (few turns): start from rotations spread over all
        candidates = list(Rotation.random(SEARCH_ROTATIONS, random_state=0).as_matrix())
    else:
        candidates = [R for _, R in _rotations(R_piece, u, shared)[:POLISHED]]
    found, inputs = [], []
    for R0 in candidates:
        W = np.einsum("pij,pj->pi", R_piece, u @ R0.T)
        normals = _normals_of(W, shared)
        labels = _piece_labels(W, normals, shared, dist, views)
        rows = sample[labels[piece[sample]] >= 0]
        inputs.append((A[owner[rows]], points[rows], labels[piece[rows]]))
        found.append(_polished(*inputs[-1], R0, normals, shared))

    def apart(f, g) -> float:
        return float(np.degrees(np.linalg.norm(Rotation.from_matrix(f[1][:3, :3] @ g[1][:3, :3].T).as_rotvec())))

    k = int(np.argmin([f[0] for f in found]))
    best = found[k] = _polished(*inputs[k], found[k][1][:3, :3], found[k][2], shared, max_nfev=300)
    if best[0] > SEARCH_GIVE_UP_M:
        raise DegenerateMotionError(
            f"the profiles of {what} fit no sensor rotation ({1e3 * best[0]:.2f} mm RMS at best): check that each "
            f"profile crosses the {'step' if shared else 'edge'} and that the poses are the profiles' (their order, "
            f"format and unit); capture 10 or more profiles with the flange {turns}")
    for j, f in enumerate(found):  # a rival apart is polished to its end: one that was on its way to the best is none
        if f[0] <= best[0] + good_m and apart(f, best) > AMBIGUOUS_DEG:
            found[j] = _polished(*inputs[j], f[1][:3, :3], f[2], shared, max_nfev=300)
    rivals = [f for f in found if f[0] <= best[0] + good_m]
    spread = max(apart(f, best) for f in rivals)
    if spread > AMBIGUOUS_DEG:
        raise DegenerateMotionError(
            f"the profiles of {what} fit sensor rotations {spread:.0f} deg apart equally well ({best[0] * 1e3:.3f} mm RMS): "
            f"X is ambiguous; capture profiles with the flange {turns}")
    return best


class EdgeProfiles(Profiles):
    """Profiles across a block's edge: per view (``names``) the profile's points (n_i, 3) in the sensor
    frame (NaN rows: no return), metres. The unknowns: each face's normal (two, in a chart about its
    first start's) and distance from the origin of the frame it is fixed in."""

    target = "edge"
    #: both faces' own normals (a step shares one)
    shared = False

    def __init__(self, setup: str, names: list[str], profiles: list[NDArray[np.float64]],
                 noise_m: float = LASER_NOISE_M) -> None:
        super().__init__(setup, names, profiles, noise_m)
        faces = range(1 if self.shared else 2)
        self.param_names = [f"face{k + 1}.normal.{c}" for k in faces for c in "ab"] + ["face1.distance", "face2.distance"]
        self.param_scale = np.full(len(self.param_names), 1e-3)
        self.pieces = profile_pieces(self.points, self.owner)
        #: the anchor, from the whole capture's start (the first poses started on), kept: the faces' charts
        #: (and order), and whether their solid is the intersection of their half-spaces (a block), not their union
        self._charts: list | None = None
        self.convex = True

    def _charted(self) -> list:
        """The faces' charts, fixed by the first start (refused by name before it)."""
        if self._charts is None:
            raise DegenerateMotionError(f"the {self.target}'s faces have no start yet: their unknowns are in charts the "
                                        "first start fixes")
        return self._charts

    def _normals(self, p) -> NDArray[np.float64]:
        """Both faces' unit normals (2, 3)."""
        charts = self._charted()
        if self.shared:
            n = _unit(charts[0], p[0], p[1])
            return np.array([n, n])
        return np.array([_unit(c, p[2 * k], p[2 * k + 1]) for k, c in enumerate(charts)])

    def _distances(self, p) -> NDArray[np.float64]:
        return np.asarray(p[-2:], dtype=float)

    def start(self, flange2base, X, Z, rows=None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """:func:`faces_start` on ``rows`` (default all; at most :data:`START_POINTS`); a part of the
        profiles (a fold of cross-validation) from the whole capture's rotation when that fits them.
        The faces' normals point to the sensor's side; their order and charts are the whole capture's."""
        A = robot_world_A(np.asarray(flange2base, dtype=float), self.setup)
        whole = self._remembered(A, lambda: self._faces(A, self._start_rows(), None))
        self._anchor(A, whole)
        if rows is None or len(rows) == len(self.points):
            X0, normals, d, _ = whole
        else:
            X0, normals, d, _ = self._faces(A, self._start_rows(rows), whole[0][:3, :3])
        return X0, self._in_charts(normals, d)

    def _faces(self, A, rows, near) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.intp]]:
        """:func:`faces_start` on ``rows`` (from the rotation ``near`` first, when given and it fits),
        the normals turned to the sensor's side: X, the normals, the distances and the rows."""
        piece, views, u, dist = self.pieces
        seen = np.isin(views, np.unique(self.owner[rows]))
        renumber = np.cumsum(seen) - 1
        pieces = (np.where(piece[rows] >= 0, np.where(seen[piece[rows]], renumber[piece[rows]], -1), -1),
                  views[seen], u[seen], dist[seen])
        found = None
        if near is not None:
            try:
                found = faces_start(A, self.points[rows], self.owner[rows], pieces, self.shared, 5 * self.noise_m, near)
            except DegenerateMotionError:
                found = None
            if found is not None and found[0] > 5 * self.noise_m:
                found = None
        if found is None:
            args = (A, self.points[rows], self.owner[rows], pieces, self.shared, 5 * self.noise_m)
            try:
                found = faces_start(*args)
            except DegenerateMotionError:  # the directions leave the rotation open: search it on the points
                found = faces_start(*args, fallback=True)
        _, X0, normals, d = found
        M = A @ X0
        sensors = M[np.unique(self.owner[rows]), :3, 3]
        side = np.mean(sensors @ normals.T - d, axis=0) < 0  # the sensor's side of each face
        return X0, np.where(side[:, None], -normals, normals), np.where(side, -d, d), rows

    def _anchor(self, A, whole) -> None:
        """The charts, the faces' order (a step's upper face first: the larger distance) and, for an
        edge, whether the faces make a block, from the whole capture's start; kept once set."""
        if self._charts is not None:
            return
        X0, normals, d, rows = whole
        if not self.shared:  # a block: each point lies behind the face it is not on
            r = self._mapped(X0, A, rows) @ normals.T - d
            self.convex = bool(np.median(np.max(r, axis=1) ** 2) <= np.median(np.min(r, axis=1) ** 2))
        if self.shared and d[0] < d[1]:
            normals = normals[::-1]
        self._charts = [_chart(n) for n in normals[:1 if self.shared else 2]]

    def _in_charts(self, normals, d) -> NDArray[np.float64]:
        """The faces' normals and distances as ``p`` in the charts (a step's upper face first: the
        larger distance; an edge's faces in the charts' order)."""
        if self.shared and d[0] < d[1]:
            normals, d = normals[::-1], d[::-1]
        elif not self.shared and normals[0] @ self._charted()[1][0] > normals[0] @ self._charted()[0][0]:
            normals, d = normals[::-1], d[::-1]
        out = []
        for n, c in zip(normals[:1 if self.shared else 2], self._charted()):
            k = n / (n @ c[0])  # c0 + a c1 + b c2, proportional to n
            out += [k @ c[1], k @ c[2]]
        return np.r_[out, d]

    def _nearer(self, X, p, A, rows) -> tuple[NDArray[np.float64], NDArray[np.intp], NDArray[np.float64]]:
        """The points of ``rows`` mapped (q), each one's nearer face, the normals."""
        n, d = self._normals(p), self._distances(p)
        q = self._mapped(X, A, rows)
        r = q @ n.T - d
        return q, np.argmin(np.abs(r), axis=1).astype(np.intp), n

    def residuals(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """Each point's signed distance (m) from its nearer face."""
        A = robot_world_A(flange2base, self.setup)
        n, d = self._normals(p), self._distances(p)
        r = self._mapped(X, A, rows) @ n.T - d
        return np.take_along_axis(r, np.argmin(np.abs(r), axis=1)[:, None], axis=1)

    def jacobian(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """The residuals' derivatives (M, 1, 6 + k): X's as the plane's with the point's face's normal;
        that face's chart ``(I - n n^T) e_k / |m| . q`` and ``-1`` with its distance, nothing with the
        other face's unknowns."""
        A = robot_world_A(flange2base, self.setup)
        q, face, n = self._nearer(X, p, A, rows)
        cols = [self._x_jacobian(X, A, rows, n[face])]
        for k, c in enumerate(self._charted()):
            m = c[0] + p[2 * k] * c[1] + p[2 * k + 1] * c[2]
            project = (np.eye(3) - np.outer(n[k], n[k])) / np.linalg.norm(m)
            on = (face == k) | self.shared
            cols.append(np.c_[q @ (project @ c[1]), q @ (project @ c[2])] * on[:, None])
        cols.append(-(face[:, None] == np.arange(2)).astype(float))
        return np.concatenate(cols, axis=1)[:, None, :]

    def _section(self, sensor2target, p, x) -> NDArray[np.float64]:
        """Both faces' lines in the laser plane at ``x`` (z, m), the one the sensor sees: a block's the
        farther of the two (the other runs in the air beyond the edge), an inside corner's the nearer."""
        n, d = self._normals(p), self._distances(p)
        R, t = sensor2target[:3, :3], sensor2target[:3, 3]
        n_s, d_s = n @ R, d - n @ t
        with np.errstate(divide="ignore", invalid="ignore"):
            z = (d_s[:, None] - n_s[:, :1] * x) / n_s[:, 2:]
        z[np.abs(n_s[:, 2]) < 1e-9] = np.nan
        if self.shared:  # a step: the face whose level the point is on, the upper (nearer) where both are
            return np.nanmin(z, axis=0)
        return np.nanmax(z, axis=0) if self.convex else np.nanmin(z, axis=0)

    def edge_line(self, p) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The edge line: its point nearest the frame's origin and its unit direction (``n1 x n2``)."""
        n, d = self._normals(p), self._distances(p)
        e = np.cross(n[0], n[1])
        return n.T @ np.linalg.solve(n @ n.T, d), e / np.linalg.norm(e)

    def Z(self, X, p) -> NDArray[np.float64]:
        """The edge as a frame: x along the edge line, z the normals' bisector (to the sensor's side),
        its origin the edge's point nearest the frame's origin."""
        origin, e = self.edge_line(p)
        n = self._normals(p)
        z = n[0] + n[1] - e * (e @ (n[0] + n[1]))
        z /= np.linalg.norm(z)
        return make_transform(np.column_stack([e, np.cross(z, e), z]), origin)

    def Z_std(self, p, cov_p) -> NDArray[np.float64]:
        """The edge frame's std about its own axes (deg) and along them (mm; along the edge NaN: the
        edge's points are alike), propagated from ``cov_p`` by finite differences."""
        T0 = self.Z(None, p)
        J = np.zeros((6, len(p)))
        for k in range(len(p)):
            h = np.zeros(len(p))
            h[k] = 1e-7
            T = self.Z(None, p + h)
            J[:3, k] = Rotation.from_matrix(T0[:3, :3].T @ T[:3, :3]).as_rotvec() / 1e-7
            J[3:, k] = T0[:3, :3].T @ (T[:3, 3] - T0[:3, 3]) / 1e-7
        std = np.sqrt(np.clip(np.diag(J @ cov_p @ J.T), 0.0, None))
        return np.r_[np.degrees(std[:3]), np.nan, 1e3 * std[4:]]

    def _angle(self, p, cov_p) -> tuple[float, float]:
        """The angle between the faces (deg; 180 less the normals', both to the sensor's side: a square
        block's edge is 90) and its std."""
        def angle(v):
            n = self._normals(v)
            return 180.0 - np.degrees(np.arccos(np.clip(n[0] @ n[1], -1.0, 1.0)))
        g = np.array([(angle(p + h) - angle(p - h)) / 2e-7 for h in 1e-7 * np.eye(len(p))])
        return float(angle(p)), float(np.sqrt(max(g @ cov_p @ g, 0.0)))

    def figures(self, p, cov_p) -> dict[str, Any]:
        """Both faces' unit normals and distances, the edge line and the angle between the faces."""
        n, d = self._normals(p), self._distances(p)
        std = np.sqrt(np.clip(np.diag(cov_p), 0.0, None))
        origin, e = self.edge_line(p)
        angle, angle_std = self._angle(p, cov_p)
        return {"normals": [[float(v) for v in row] for row in n], "distances_m": [float(v) for v in d],
                "distances_std_mm": [float(1e3 * v) for v in std[-2:]], "edge_point_m": [float(v) for v in origin],
                "edge_direction": [float(v) for v in e], "angle_deg": {"value": angle, "std": angle_std},
                "convex": self.convex}

    def notes(self, p, cov_p) -> list[str]:
        """The angle between the faces found."""
        angle, s = self._angle(p, cov_p)
        kind = "a block's edge" if self.convex else "an inside corner"
        return [f"the faces meet at {angle:.3f} +- {s:.3f} deg ({kind})"]


class StepProfiles(EdgeProfiles):
    """Profiles across a step: two parallel faces at different heights (HandEyeSync's edge artefact).
    The unknowns: the faces' one normal (two, in a chart) and each face's distance from the origin of
    the frame it is fixed in (the upper face's first: the nearer to the sensor)."""

    target = "step"
    shared = True

    def __init__(self, setup: str, names: list[str], profiles: list[NDArray[np.float64]],
                 noise_m: float = LASER_NOISE_M) -> None:
        super().__init__(setup, names, profiles, noise_m)
        self.param_names = ["normal.a", "normal.b", "upper.distance", "lower.distance"]

    def Z(self, X, p) -> NDArray[np.float64]:
        """The upper face as a frame: z its normal (to the sensor's side), its origin the face's point
        nearest the frame's origin (the faces have no in-plane position nor turn)."""
        n = self._normals(p)[0]
        e1, e2 = perpendicular_basis(n)
        return make_transform(np.column_stack([e1, e2, n]), p[2] * n)

    def Z_std(self, p, cov_p) -> NDArray[np.float64]:
        """The normal's tilt (deg, two axes; about it NaN) and the upper face's distance (mm; in the
        face NaN)."""
        chart = self._charted()[0]
        m = chart[0] + p[0] * chart[1] + p[1] * chart[2]
        tilt = np.degrees(np.sqrt(np.clip(np.diag(cov_p)[:2], 0.0, None)) / np.linalg.norm(m))
        return np.r_[tilt, np.nan, np.nan, np.nan, 1e3 * np.sqrt(max(cov_p[2, 2], 0.0))]

    def _height(self, p, cov_p) -> tuple[float, float]:
        """The step's height (mm) and its std."""
        g = np.array([0.0, 0.0, 1.0, -1.0])
        return float(1e3 * (p[2] - p[3])), float(1e3 * np.sqrt(max(g @ cov_p @ g, 0.0)))

    def figures(self, p, cov_p) -> dict[str, Any]:
        """The faces' unit normal, both distances and the step's height."""
        std = np.sqrt(np.clip(np.diag(cov_p), 0.0, None))
        height, s = self._height(p, cov_p)
        return {"normal": [float(v) for v in self._normals(p)[0]], "distances_m": [float(v) for v in p[2:]],
                "distances_std_mm": [float(1e3 * v) for v in std[2:]], "height_mm": {"value": height, "std": s}}

    def notes(self, p, cov_p) -> list[str]:
        """The step's height found."""
        height, s = self._height(p, cov_p)
        return [f"the step is {height:.3f} +- {s:.3f} mm high"]
