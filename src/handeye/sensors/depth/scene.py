"""Whatever a depth camera sees as the target: the views' clouds must agree through X and the robot.

No target, no mesh: the object's model is the views themselves, each view's cloud a piece of its
surface. Each cloud is thinned, each point given its neighbourhood's surface (:func:`prepare_view`:
a quadric over the plane through its 40 nearest neighbours in its own view, which gives its normal
and its place on the surface with most of its noise averaged out) and its noise along the normal,
and split in two sets that never overlap: a few thousand **query** points spread evenly, whose
residuals the fit takes, and the rest, the **reference** surface the other views' query points are
matched to. A query point's residual is its signed distance from the tangent plane of its
reference, a point of another view's surface, both carried into the common frame (the robot base
eye-in-hand, the flange eye-to-hand) by their own flange pose and X:

    r = n_j . (A_i X p - A_j X q),    n_j = rot(A_j X) n_q

so the residual moves with X on both sides. Each point is in one role only (no query point is a
reference), so no measurement's noise enters two residuals: the rows are independent and the noise
model is the measurements'. Of the other views, the reference is taken from the one whose surface
passes nearest the query point *across* the normal (:func:`match`): the nearest in 3D would pick,
of several overlapping views, the one whose errors happen to put it closest along the normal, and
the residuals would come out small and the fit's curvature flat (on a real capture 0.27 mm RMS
where the views disagree by 0.76 mm). The pairs are found again between rounds of the fit
(:func:`register`: robust point-to-plane ICP of all views at once, X the only unknown) and held
during the core's fit (:class:`SceneSurface`), whose residuals are then smooth in X.

The depth scale and bias can be unknowns too (``fit_depth``): every point moved along its ray to
depth ``(z - b) / s``, in both roles. They are held at 1 and 0 by default: an unknown object's
size is what a depth scale changes, and only the robot's translations between views tell it.

Examples
--------
>>> import numpy as np
>>> from handeye.sensors.depth.scene import prepare_view
>>> u, v = np.meshgrid(np.linspace(-0.05, 0.05, 80), np.linspace(-0.05, 0.05, 80))
>>> wave = np.c_[u.ravel(), v.ravel(), 0.4 + 0.01 * np.sin(60 * u.ravel()) * np.cos(40 * v.ravel())]
>>> view = prepare_view(wave, "v1", queries=500)
>>> len(view.query) <= 500, len(np.intersect1d(view.query, view.reference))
(True, 0)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal, overload

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from ...errors import InputMismatchError
from ...frames.setups import check_setup, robot_world_A, setup_info
from ...geometry.se3 import invert, perturb
from ..base import Nuisance
from .clouds import depth_sigma
from .model import DEPTH_BIAS_TOLERANCE_M, DEPTH_SCALE_TOLERANCE, LATERAL, depth_figures
from .shape import free_twists

__all__ = ["SceneView", "Pairs", "SceneSurface", "prepare_view", "match", "register", "pair_terms", "pair_spread",
           "view_overlap", "scene_free", "describe_free", "common_frame", "point_sigma", "gather", "DRAWN", "MIN_POINTS",
           "QUERIES", "MAX_POINTS", "NEIGHBOURS", "FLATNESS", "LINE", "GRAZING_COS", "NORMAL_COS"]

#: A view with fewer usable points than this (with depth, on a smooth surface) cannot register.
MIN_POINTS = 300
#: Query points per view (evenly spread): the rows of the fit.
QUERIES = 2000
#: A view is thinned to at most this many points (one per voxel) before its normals are taken.
MAX_POINTS = 25000
#: Neighbours of a point whose surface (a plane, then a quadric over it) gives its normal and its place.
NEIGHBOURS = 40
#: A point whose neighbours' smallest spread exceeds this share of their total (an edge, a corner,
#: a flying pixel) has no tangent plane to trust: it is neither a query nor a reference.
FLATNESS = 0.04
#: A point whose neighbours' middle spread is below this share of their largest lies on a line (flying pixels
#: along an outline, a thin wire), not on a surface: it is left out too.
LINE = 0.1
#: A point seen at more than ~75 deg from its normal (a grazing ray: its depth the least accurate) is left out.
GRAZING_COS = 0.26
#: A query point and its reference must face within ~35 deg of one another (the same side of the surface).
NORMAL_COS = 0.82


@dataclass(eq=False)
class SceneView:
    """One view's cloud prepared for registration: its points (camera frame, m), their unit normals
    (towards the camera), each point's noise along its normal (m), the query and reference points
    (indices, disjoint), a KD-tree on the references, their typical spacing (m) and the cloud's
    centroid."""

    name: str
    points: NDArray[np.float64]
    normals: NDArray[np.float64]
    sigma: NDArray[np.float64]
    surface: NDArray[np.float64]  #: each point moved onto its neighbours' quadric (the reference surface), m
    surface_sigma: NDArray[np.float64]  #: the noise along the normal left in ``surface``, m
    query: NDArray[np.intp]
    reference: NDArray[np.intp]
    spacing: float
    tree: cKDTree = field(repr=False)
    centroid: NDArray[np.float64] = field(repr=False)
    radius: float = 0.0  #: the largest distance of a point from the centroid, m
    box: NDArray[np.float64] = field(default_factory=lambda: np.zeros((2, 3)), repr=False)  #: the references' bounding box, m


def _surfaces(p: NDArray[np.float64], k: int) -> tuple[NDArray[np.float64], ...]:
    """Per point the surface through its ``k`` nearest neighbours: a plane (its normal turned towards
    the camera at the origin; its flatness, the smallest spread over the total), then a quadric over
    it, ``w = a u^2 + b u v + c v^2 + d u + e v + f`` in the plane's frame about the point: the point
    moved onto the quadric (a plane through the neighbours' mean would pull it inside a curved
    surface by a quarter of the neighbourhood's sagitta, the same in every view), the normal
    tilted by its slope, and the share of the point's own noise left in its height ``f``. Also
    the nearest neighbour's distance."""
    d, nb = cKDTree(p).query(p, k=k)
    local = p[nb] - p[nb].mean(axis=1, keepdims=True)
    lam, vec = np.linalg.eigh(np.einsum("mki,mkj->mij", local, local))
    n = vec[:, :, 0]
    n *= np.where(np.einsum("mi,mi->m", n, p) > 0, -1.0, 1.0)[:, None]
    e1 = vec[:, :, 2]
    e2 = np.cross(n, e1)
    rel = p[nb] - p[:, None, :]
    u, v, w = (np.einsum("mki,mi->mk", rel, e) for e in (e1, e2, n))
    D = np.stack([u * u, u * v, v * v, u, v, np.ones_like(u)], axis=2)
    scale = np.maximum(np.sqrt(np.mean(u * u + v * v, axis=1)), 1e-9)[:, None]
    Ds = D / np.stack([scale**2] * 3 + [scale] * 2 + [np.ones_like(scale)], axis=2)  # well conditioned
    N = np.einsum("mki,mkj->mij", Ds, Ds) + 1e-9 * np.eye(6)
    coef = np.linalg.solve(N, np.einsum("mki,mk->mi", Ds, w)[..., None])[..., 0]
    share = np.sqrt(np.clip(np.linalg.inv(N)[:, 5, 5], 0.0, 1.0))
    slope = coef[:, 3:5] / scale
    normal = n - slope[:, :1] * e1 - slope[:, 1:] * e2
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    # a plane's neighbours spread two ways: the smallest spread small against the total, and the middle
    # one not (a line of points, as flying pixels along an outline, is "flat" but has no plane)
    flat = np.maximum(lam[:, 0] / np.maximum(lam.sum(axis=1), 1e-30), np.where(lam[:, 1] < LINE * lam[:, 2], 1.0, 0.0))
    return normal, p + coef[:, 5:6] * n, share, flat, d[:, 1]


def common_frame(setup: str) -> str:
    """The frame the views' clouds agree in, in words: the robot base eye-in-hand (the object is
    fixed in the cell), the flange eye-to-hand (it moves with the flange)."""
    return "robot base" if setup_info(setup).camera_on_flange else "flange"


def point_sigma(points: NDArray[np.float64], normals: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each point's noise along its normal (m): the depth noise times the cosine between its ray and
    the normal, the noise across the rays (:data:`~handeye.sensors.depth.model.LATERAL`) times its sine."""
    z = points[:, 2]
    cos = np.abs(np.einsum("mi,mi->m", points, normals)) / np.linalg.norm(points, axis=1)
    return np.sqrt((depth_sigma(z) * cos) ** 2 + (LATERAL * z) ** 2 * (1.0 - cos**2))


def prepare_view(points: NDArray[np.float64], name: str, *, queries: int = QUERIES, max_points: int = MAX_POINTS,
                 rng: np.random.Generator | int | None = 0) -> SceneView:
    """One view's cloud (N, 3, camera frame, m; organized clouds flattened) prepared for
    registration (the module's docstring): thinned to ``max_points`` (one per voxel), normals, the
    points without a trustworthy tangent plane or seen at a grazing angle left out, at most
    ``queries`` query points one per voxel, the rest the reference.

    Raises
    ------
    InputMismatchError
        Fewer than :data:`MIN_POINTS` usable points, naming the view.
    """
    rng = np.random.default_rng(rng)
    p = np.asarray(points, float).reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1) & (p[:, 2] > 0)]
    if len(p) < MIN_POINTS:
        raise InputMismatchError(f"{name}: {len(p)} points with depth: too few to register (at least {MIN_POINTS} on the "
                                 "object's surface are needed); is the object in view and within the camera's range?")
    if len(p) > max_points:
        p = p[_thinned(p, max_points)]
    k = min(NEIGHBOURS, len(p))
    n, on_surface, _, flat, gap = _surfaces(p, k)
    cos = np.abs(np.einsum("mi,mi->m", p, n)) / np.linalg.norm(p, axis=1)
    spacing = float(np.median(gap))
    good = (flat < FLATNESS) & (cos > GRAZING_COS) & (gap < 5.0 * spacing)
    usable = np.flatnonzero(good)
    if len(usable) < MIN_POINTS:
        raise InputMismatchError(f"{name}: {len(usable)} points on a smooth surface (of {len(p)} with depth): too few to "
                                 f"register (at least {MIN_POINTS} are needed); is the cloud mostly noise or edges?")
    share = min(0.5, queries / len(usable))
    query = usable[_thinned(p[usable], max(int(share * len(usable)), 1))]
    if len(query) > queries:
        query = np.sort(rng.choice(query, queries, replace=False))
    reference = np.setdiff1d(usable, query)
    centroid = p.mean(axis=0)
    sigma = point_sigma(p, n)
    box = np.array([on_surface[reference].min(axis=0), on_surface[reference].max(axis=0)]) if len(reference) else np.zeros((2, 3))
    return SceneView(name, p, n, sigma, on_surface, sigma * share, query, reference, spacing,
                     cKDTree(on_surface[reference], leafsize=32), centroid, float(np.linalg.norm(p - centroid, axis=1).max()), box)


def _thinned(p: NDArray[np.float64], count: int) -> NDArray[np.intp]:
    """About ``count`` of the points ``p`` (indices, camera frame), one per cell of their directions
    from the camera (``x/z``, ``y/z``: a coarser pixel grid), the cell shrunk until enough are
    occupied. By direction, not by voxel: a depth error moves a point along its ray, never to
    another direction, where one point per voxel keeps the points that noise pushed into a voxel of
    their own, the surface's outliers (on a plane seen at an angle a bias of a tenth of the noise)."""
    uv = p[:, :2] / p[:, 2:3]
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    cell = float(np.sqrt(max(float(np.prod(hi - lo)), 1e-12) / count))
    for _ in range(30):
        key = np.floor((uv - lo) / cell).astype(np.int64)
        flat = key[:, 0] * (int(key[:, 1].max()) + 1) + key[:, 1]
        pick = np.sort(np.unique(flat, return_index=True)[1])
        if len(pick) >= 0.8 * count:
            return pick
        cell *= 0.8
    return pick


@dataclass(frozen=True)
class Pairs:
    """Query points matched to other views' reference points: per pair the query's view and index
    (into its view's points), the reference's view and index, and their distance across the
    reference's normal at the matching (m)."""

    view: NDArray[np.intp]
    point: NDArray[np.intp]
    ref_view: NDArray[np.intp]
    ref_point: NDArray[np.intp]
    distance: NDArray[np.float64]

    def __len__(self) -> int:
        return len(self.view)

    def take(self, keep: NDArray[np.bool_] | NDArray[np.intp]) -> Pairs:
        """The pairs ``keep`` (a mask or indices)."""
        return Pairs(self.view[keep], self.point[keep], self.ref_view[keep], self.ref_point[keep], self.distance[keep])


def _no_pairs() -> Pairs:
    """No pairs at all."""
    return Pairs(np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp),
                 np.zeros(0, dtype=np.intp), np.zeros(0))


def match(views: list[SceneView], A: NDArray[np.float64], X: NDArray[np.float64], tau: float,
          normal_cos: float = NORMAL_COS, use: NDArray[np.bool_] | None = None, every: int = 1) -> Pairs:
    """Each query point of each view (``use``: of these views only; the references of all views
    ``use`` allows) matched to the nearest reference point of another view, within ``tau`` (m) in
    the common frame and facing the same way (normals within ``normal_cos``): ``A`` the robot-world
    poses (:func:`~handeye.frames.setups.robot_world_A`), X the sensor's; ``every``: one query point
    in so many (a coarse round). The references' KD-trees are in their own camera frames: the query
    points are carried there (``inv(A_j X) A_i X``)."""
    n = len(views)
    use = np.ones(n, bool) if use is None else np.asarray(use, bool)
    T = A @ X
    centre = np.array([T[k, :3, :3] @ v.centroid + T[k, :3, 3] for k, v in enumerate(views)])
    out = []
    for i, vi in enumerate(views):
        query = vi.query[::every]
        if not use[i] or not len(query):
            continue
        best = np.full(len(query), np.inf)
        ref_view = np.full(len(query), -1)
        ref_point = np.zeros(len(query), dtype=np.intp)
        for j, vj in enumerate(views):
            if j == i or not use[j] or not len(vj.reference) or \
                    np.linalg.norm(centre[i] - centre[j]) > vi.radius + vj.radius + tau:
                continue
            M = invert(T[j]) @ T[i]
            q = vi.points[query] @ M[:3, :3].T + M[:3, 3]
            near = np.flatnonzero(np.all((q > vj.box[0] - tau) & (q < vj.box[1] + tau), axis=1))  # within reach of j's box
            d, k = vj.tree.query(q[near], distance_upper_bound=tau)
            ok = np.isfinite(d)
            hit, d, k = near[ok], d[ok], k[ok]
            k_hit = vj.reference[k]
            # the view whose surface lies nearest across the normal, not along it: the nearest in 3D
            # would pick, of overlapping views, the one whose noise put it closest along the normal
            # (residuals biased small, the fit's curvature flattened)
            along = np.einsum("mi,mi->m", q[hit] - vj.surface[k_hit], vj.normals[k_hit])
            lateral = np.sqrt(np.maximum(d**2 - along**2, 0.0))
            facing = np.einsum("mi,mi->m", vi.normals[query[hit]] @ M[:3, :3].T, vj.normals[k_hit]) > normal_cos
            better = facing & (lateral < best[hit])
            at = hit[better]
            best[at], ref_view[at], ref_point[at] = lateral[better], j, k_hit[better]
        found = ref_view >= 0
        out.append((np.full(int(found.sum()), i), query[found], ref_view[found], ref_point[found], best[found]))
    if not out:
        return _no_pairs()
    cols = [np.concatenate([o[c] for o in out]) for c in range(5)]
    return Pairs(cols[0].astype(np.intp), cols[1].astype(np.intp), cols[2].astype(np.intp), cols[3].astype(np.intp), cols[4])


@dataclass(frozen=True)
class _Gathered:
    """The pairs' points, normals and noise gathered per pair (camera frames, m)."""

    p: NDArray[np.float64]  #: query points (M, 3), their own camera's frame
    q: NDArray[np.float64]  #: reference points (M, 3), theirs
    n: NDArray[np.float64]  #: reference normals (M, 3), theirs
    sigma: NDArray[np.float64]  #: each pair's noise along the normal, both points' (M,)


def gather(views: list[SceneView], pairs: Pairs) -> _Gathered:
    """The pairs' points, normals and noise (:class:`_Gathered`)."""
    m = len(pairs)
    p, q, n, s = np.zeros((m, 3)), np.zeros((m, 3)), np.zeros((m, 3)), np.zeros(m)
    for k, v in enumerate(views):
        at = pairs.view == k
        p[at] = v.points[pairs.point[at]]
        s[at] += v.sigma[pairs.point[at]] ** 2
        at = pairs.ref_view == k
        q[at], n[at] = v.surface[pairs.ref_point[at]], v.normals[pairs.ref_point[at]]
        s[at] += v.surface_sigma[pairs.ref_point[at]] ** 2
    return _Gathered(p, q, n, np.sqrt(s))


def _corrected(x: NDArray[np.float64], depth: NDArray[np.float64] | None) -> NDArray[np.float64]:
    """Points moved along their rays from the measured depth ``s z + b`` back to ``z`` (``depth``: s - 1, b)."""
    if depth is None:
        return x
    s, b = 1.0 + depth[0], depth[1]
    return x * ((x[:, 2] - b) / (s * x[:, 2]))[:, None]


@overload
def pair_terms(g: _Gathered, A_i: NDArray[np.float64], A_j: NDArray[np.float64], X: NDArray[np.float64],
               depth: NDArray[np.float64] | None = None, jacobian: Literal[True] = True
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...


@overload
def pair_terms(g: _Gathered, A_i: NDArray[np.float64], A_j: NDArray[np.float64], X: NDArray[np.float64],
               depth: NDArray[np.float64] | None = None, *, jacobian: Literal[False]
               ) -> tuple[NDArray[np.float64], None]: ...


def pair_terms(g: _Gathered, A_i: NDArray[np.float64], A_j: NDArray[np.float64], X: NDArray[np.float64],
               depth: NDArray[np.float64] | None = None, jacobian: bool = True
               ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """The pairs' residuals (M,): ``n_j . (A_i X p - A_j X q)`` with ``n_j`` the reference's normal
    carried to the common frame, ``A_i``, ``A_j`` (M, 4, 4) each pair's query's and reference's
    robot-world pose; and (``jacobian``) their derivatives (M, 6 [+ 2]) by a left increment of X
    (rotation vector, translation; :func:`~handeye.geometry.se3.perturb`) and the depth's scale and
    bias when ``depth`` is given."""
    R = X[:3, :3]
    p, q = _corrected(g.p, depth), _corrected(g.q, depth)
    u_i, u_j, m_j = p @ R.T, q @ R.T, g.n @ R.T  # in X's parent frame (the flange eye-in-hand), before X's translation
    RA_i, RA_j = A_i[:, :3, :3], A_j[:, :3, :3]
    n_b = np.einsum("mij,mj->mi", RA_j, m_j)
    y_i = np.einsum("mij,mj->mi", RA_i, u_i + X[:3, 3]) + A_i[:, :3, 3]
    y_j = np.einsum("mij,mj->mi", RA_j, u_j + X[:3, 3]) + A_j[:, :3, 3]
    d = y_i - y_j
    r = np.einsum("mi,mi->m", n_b, d)
    if not jacobian:
        return r, None
    a_i = np.einsum("mji,mj->mi", RA_i, n_b)
    d_j = np.einsum("mji,mj->mi", RA_j, d)
    cols = [np.cross(u_i, a_i) - np.cross(u_j, m_j) + np.cross(m_j, d_j), a_i - m_j]
    if depth is not None:
        s = 1.0 + depth[0]
        n_i_cam, n_j_cam = a_i @ R, g.n  # the normal in each camera's frame
        cols.append((-np.einsum("mi,mi->m", n_i_cam, p) / s + np.einsum("mi,mi->m", n_j_cam, q) / s)[:, None])
        cols.append((-np.einsum("mi,mi->m", n_i_cam, g.p) / (s * g.p[:, 2])
                     + np.einsum("mi,mi->m", n_j_cam, g.q) / (s * g.q[:, 2]))[:, None])
    return r, np.concatenate(cols, axis=1)


#: The robust registration's loss scale, in the residuals' robust spread (Cauchy weights).
CAUCHY = 2.5


def _solve_step(r: NDArray[np.float64], J: NDArray[np.float64], sigma: NDArray[np.float64]) -> NDArray[np.float64]:
    """One robust Gauss-Newton step (Cauchy weights at :data:`CAUCHY` robust spreads of the
    residuals over their noise), damped a little."""
    w = r / sigma
    scale = 1.4826 * float(np.median(np.abs(w))) or 1.0
    weight = 1.0 / (1.0 + (w / (CAUCHY * scale)) ** 2) / sigma**2
    H = (J * weight[:, None]).T @ J
    g = (J * weight[:, None]).T @ r
    H += 1e-9 * np.trace(H) / len(H) * np.eye(len(H))
    return np.asarray(-np.linalg.solve(H, g), dtype=float)


def register(views: list[SceneView], A: NDArray[np.float64], X: NDArray[np.float64], taus: NDArray[np.float64], *,
             depth: NDArray[np.float64] | None = None, use: NDArray[np.bool_] | None = None, steps: int = 4,
             rounds: int = 3, settle: float = 0.02, coarse: int = 4, full_last: bool = True
             ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None, Pairs]:
    """Robust point-to-plane ICP of all views at once with X (and the depth's scale and bias when
    ``depth`` is given) the unknowns: for each threshold of ``taus`` (m, from wide to tight), up to
    ``rounds`` times the pairs found again (:func:`match`; one query point in ``coarse``, but all at
    the last threshold with ``full_last``) and up to ``steps`` robust Gauss-Newton steps on them,
    until a round moves the scene's points by less than ``settle`` times the threshold (at the
    views' distance: X's turn times it, plus its shift). Returns X, the depth's unknowns and the
    last pairs."""
    depth = None if depth is None else np.asarray(depth, float).copy()
    pairs = _no_pairs()
    lever = float(np.median([np.linalg.norm(v.centroid) for v in views])) + float(np.linalg.norm(X[:3, 3]))
    for k, tau in enumerate(taus):
        for _ in range(rounds):
            pairs = match(views, A, X, float(tau), use=use, every=1 if full_last and k == len(taus) - 1 else coarse)
            if len(pairs) < 6:
                return X, depth, pairs
            g = gather(views, pairs)
            moved = 0.0
            for _ in range(steps):
                r, J = pair_terms(g, A[pairs.view], A[pairs.ref_view], X, depth)
                step = _solve_step(r, J, g.sigma)
                X = perturb(X, step[:3], step[3:6])
                if depth is not None:
                    depth = depth + step[6:]
                size = float(np.linalg.norm(step[:3])) * lever + float(np.linalg.norm(step[3:6]))
                moved += size
                if size < 1e-3 * settle * tau:
                    break
            if moved < settle * tau:
                break
    return X, depth, pairs


def pair_spread(views: list[SceneView], A: NDArray[np.float64], X: NDArray[np.float64], pairs: Pairs,
                depth: NDArray[np.float64] | None = None) -> float:
    """The pairs' robust spread (m): 1.4826 times their median absolute residual (inf without pairs)."""
    if not len(pairs):
        return np.inf
    r, _ = pair_terms(gather(views, pairs), A[pairs.view], A[pairs.ref_view], X, depth, jacobian=False)
    return float(1.4826 * np.median(np.abs(r)))


def view_overlap(views: list[SceneView], pairs: Pairs) -> NDArray[np.float64]:
    """Per view the share of its query points matched to another view's surface."""
    counts = np.bincount(pairs.view, minlength=len(views))
    return counts / np.maximum([len(v.query) for v in views], 1)


class SceneSurface:
    """The views' query points against the other views' surfaces as a sensor model
    (:mod:`handeye.sensors.base`): one row per pair (:class:`Pairs`, held), its residual the
    signed distance of :func:`pair_terms` (m), its noise both points' noise along the normal. The
    unknowns: X alone, or with the depth's scale and bias (``fit_depth``). ``X_registered``: the
    registration's X, the start of a fit on every view; a fit on fewer views (cross-validation's
    closed-form start) starts from the clouds' centroids (:func:`~handeye.sensors.depth.scene_start.centroid_start`).
    The target's pose Z is the identity: the object is wherever the views put it, in the common frame."""

    kind = "depth camera"
    target = "scene"
    groups: tuple[tuple[int, ...], ...] = ((0,),)

    def __init__(self, setup: str, views: list[SceneView], pairs: Pairs, X_registered: NDArray[np.float64], *,
                 fit_depth: bool = False, depth: NDArray[np.float64] | None = None, start=None,
                 free: NDArray[np.float64] | None = None) -> None:
        self.setup = check_setup(setup)
        order = np.argsort(pairs.view, kind="stable")
        self.views, self.pairs = views, pairs.take(order)
        self.names = [v.name for v in views]
        self.g = gather(views, self.pairs)
        self.owner = self.pairs.view
        self.shape = self.g.sigma[:, None]
        self.fit_depth = fit_depth
        self.depth0 = np.zeros(2) if depth is None else np.asarray(depth, float)
        self.param_names = ["depth.scale-1", "depth.bias"] if fit_depth else []
        self.param_scale = np.full(2, 1e-3) if fit_depth else np.zeros(0)
        self.X_registered = np.asarray(X_registered, float)
        self._start = start
        self.free = np.zeros((0, 6)) if free is None else np.asarray(free, float)

    @property
    def nuisances(self) -> tuple[Nuisance, ...]:
        """The depth scale and bias (when they are unknowns): nominal 1 and 0, fitted where the capture
        determines them (an unknown object's size is what a scale changes: only the robot's translations
        between views tell it)."""
        if not self.fit_depth:
            return ()
        return (Nuisance("depth_scale", 0, 0.0, DEPTH_SCALE_TOLERANCE, offset=1.0),
                Nuisance("depth_bias", 1, 0.0, DEPTH_BIAS_TOLERANCE_M, unit="mm", scale=1e3))

    def view_poses(self) -> None:
        """No view measures a whole pose: the start is the registration's."""
        return None

    def start(self, flange2base, X, Z, rows=None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The registration's X on every view; on fewer (a fold of cross-validation), the closed form
        on those views' clouds (``start``: a function of the views and their robot-world poses)."""
        rows = np.arange(len(self.owner)) if rows is None else np.asarray(rows)
        p0 = self.depth0.copy() if self.fit_depth else np.zeros(0)
        seen = np.unique(self.owner[rows])
        if self._start is None or len(seen) == len(np.unique(self.owner)):
            return self.X_registered.copy(), p0
        A = robot_world_A(np.asarray(flange2base, float), self.setup)
        return self._start([self.views[v] for v in seen], A[seen]), p0

    def _depth(self, p) -> NDArray[np.float64] | None:
        return np.asarray(p[-2:], float) if self.fit_depth else None

    def residuals(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """Each row's signed distance (m) from its reference's tangent plane, in the common frame."""
        A = robot_world_A(np.asarray(flange2base, float), self.setup)
        g = _Gathered(self.g.p[rows], self.g.q[rows], self.g.n[rows], self.g.sigma[rows])
        r, _ = pair_terms(g, A[self.pairs.view[rows]], A[self.pairs.ref_view[rows]], X, self._depth(p), jacobian=False)
        return r[:, None]

    def jacobian(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """The residuals' derivatives (M, 1, 6 [+ 2]): X's left increment, the depth's scale and bias."""
        A = robot_world_A(np.asarray(flange2base, float), self.setup)
        g = _Gathered(self.g.p[rows], self.g.q[rows], self.g.n[rows], self.g.sigma[rows])
        _, J = pair_terms(g, A[self.pairs.view[rows]], A[self.pairs.ref_view[rows]], X, self._depth(p))
        return J[:, None, :]

    def noise_mm(self, rows) -> NDArray[np.float64]:
        """Each row's stated noise (mm): both points' noise along the normal."""
        return 1e3 * self.g.sigma[np.asarray(rows)]

    def Z(self, X, p) -> NDArray[np.float64]:
        """The identity: the object is where the views put it (the common frame is its frame)."""
        return np.eye(4)

    def Z_std(self, p, cov_p) -> NDArray[np.float64]:
        """Zero: nothing of the object's pose is fitted."""
        return np.zeros(6)

    def figures(self, p, cov_p) -> dict[str, Any]:
        """The pairs fitted, what the scene leaves free, the depth's scale and bias."""
        return {"pairs": int(len(self.owner)), "free": describe_free(self.free),
                **depth_figures(p, cov_p, self.fit_depth)}

    def notes(self, p, cov_p) -> list[str]:
        """The depth held (or fitted), and what of its own pose the scene leaves free."""
        out = []
        f = depth_figures(p, cov_p, self.fit_depth)
        if not self.fit_depth:
            out.append("the depth scale and bias are held at 1 and 0 (nominal): an unknown object's size is what a depth "
                       "scale changes, and only the robot's translations between views would tell it; a scale error of "
                       "the camera moves X's translation by about as much times the object's distance")
        else:
            scale = f["depth_scale"]
            if abs(scale["value"] - 1.0) > 3 * scale["std"]:
                out.append(f"depth scale {scale['value']:.5f} +- {scale['std']:.5f} (beyond 3 std of 1)")
        if len(self.free):
            out.append("the scene moves along itself unseen (" + "; ".join(describe_free(self.free)) + ", in the "
                       f"{common_frame(self.setup)} frame): no view tells that motion from another, so X is fitted "
                       "in what the rest of the shape determines through the robot's motions (a ball's centre, an axis, a "
                       "plane's normal and distance; the core names any direction of X that is then left undetermined)")
        return out

    def sections(self, X, p, flange2base, views) -> list[dict[str, NDArray[np.float64]]]:
        """Per view of ``views`` its registered cloud as the report draws it: at most
        :data:`DRAWN` of its matched query points in the common frame (``cloud_mm``, mm, through
        X and its flange pose; ``frame``: that frame in words) and their residuals (``residual_mm``)."""
        A = robot_world_A(np.asarray(flange2base, float), self.setup)
        out = []
        for v in views:
            rows = np.flatnonzero(self.owner == v)
            rows = rows[np.linspace(0, len(rows) - 1, min(len(rows), DRAWN)).astype(np.intp)] if len(rows) else rows
            T = A[v] @ X
            x = _corrected(self.g.p[rows], self._depth(p))
            out.append({"cloud_mm": 1e3 * (x @ T[:3, :3].T + T[:3, 3]), "frame": common_frame(self.setup),
                        "residual_mm": 1e3 * self.residuals(X, p, flange2base, rows)[:, 0]})
        return out


#: The report draws at most this many points of each view's registered cloud.
DRAWN = 800


def describe_free(free: NDArray[np.float64]) -> list[str]:
    """What the twists ``free`` (k, 6: rotation rad, translation m, about the common frame's origin)
    let a scene do unseen, in words (mm): a ball's turns about its centre, a turn about an axis
    (and a slide along it), slides along a direction or in a plane."""
    free = np.asarray(free, float).reshape(-1, 6)
    if not len(free):
        return []
    W = free[:, :3]
    _, sv, Vt = np.linalg.svd(W.T, full_matrices=True)  # coefficient vectors c with c W = 0: pure slides
    # turns the twists share: a real scene's free twists each carry a little of the others' turns
    rank = int(np.sum(sv > 0.1 * max(float(sv.max(initial=0.0)), 1e-300))) if sv.size else 0
    slides = Vt[rank:] @ free if rank < len(free) else np.zeros((0, 6))
    out = []
    if rank == 1 and len(slides) == 2:  # a plane: its in-plane slides, and a turn about its normal anywhere
        n = np.cross(slides[0, 3:], slides[1, 3:])
        n /= np.linalg.norm(n)
        return [f"it slides in its plane and turns about its normal ({n[0]:+.2f}, {n[1]:+.2f}, {n[2]:+.2f}) (a plane)"]
    if rank == 3:  # a point no motion moves: v = c x w for every twist
        M = np.concatenate([-_skew(w) for w in W])
        c = np.linalg.lstsq(M, free[:, 3:].reshape(-1), rcond=None)[0]
        out.append(f"it turns about its centre ({1e3 * c[0]:.1f}, {1e3 * c[1]:.1f}, {1e3 * c[2]:.1f}) mm (a ball)")
    elif rank >= 1:
        turn = Vt[:rank] @ free
        for u in turn[:1] if rank == 1 else turn:
            w, v = u[:3], u[3:]
            a = w / np.linalg.norm(w)
            point = np.cross(w, v) / float(w @ w)
            out.append(f"it turns about the axis ({a[0]:+.2f}, {a[1]:+.2f}, {a[2]:+.2f}) through ({1e3 * point[0]:.1f}, "
                       f"{1e3 * point[1]:.1f}, {1e3 * point[2]:.1f}) mm")
    t = slides[:, 3:]
    if len(t) == 1:
        d = t[0] / np.linalg.norm(t[0])
        out.append(f"it slides along ({d[0]:+.2f}, {d[1]:+.2f}, {d[2]:+.2f})")
    elif len(t) == 2:
        n = np.cross(t[0], t[1])
        n /= np.linalg.norm(n)
        out.append(f"it slides in the plane normal to ({n[0]:+.2f}, {n[1]:+.2f}, {n[2]:+.2f}) (a plane)")
    elif len(t) >= 3:
        out.append("it moves freely (nothing in it pins a position)")
    return out


def _skew(w: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def scene_free(views: list[SceneView], pairs: Pairs, A: NDArray[np.float64], X: NDArray[np.float64]) -> NDArray[np.float64]:
    """The motions (k, 6; about the common frame's origin) that slide the registered scene along
    itself (:func:`~handeye.sensors.depth.shape.free_twists` of the matched query points with their
    normals, in the common frame): a ball's turns, a cylinder's turn and slide, a plane's slides."""
    T = A @ X
    pts, nrm = [], []
    for k, v in enumerate(views):
        at = pairs.point[pairs.view == k]
        pts.append(v.points[at] @ T[k, :3, :3].T + T[k, :3, 3])
        nrm.append(v.normals[at] @ T[k, :3, :3].T)
    p, n = np.concatenate(pts), np.concatenate(nrm)
    if len(p) < 10:
        return np.zeros((0, 6))
    return free_twists(p, n)
