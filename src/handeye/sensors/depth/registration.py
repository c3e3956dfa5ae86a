"""A known shape found in a depth cloud without any guess of its pose.

1. The cloud thinned to one point per voxel (a 30th of the shape's size); the background's large
   planes set aside (RANSAC; of a plane's points, the connected pieces larger than the shape could
   show: a wall, a table); seeds on what is left (each cluster, or points spread over it, moved to
   the middle of their neighbourhood).
2. From every seed, 60 evenly spread orientations (the icosahedral group) and the turns that put each
   of the shape's main faces towards the camera, each pulled in by trimmed point-to-plane ICP on
   coarse copies of both, all at once (:func:`icp`: only surfaces facing the camera are matched; a
   thin part's back face is as good a plane, and a trap).
3. The candidates scored by the shape's visible surface the cloud sees where it is, less twice what
   it sees through (:class:`_Rays`); the best distinct few refined on the full cloud, turned about
   the axis their points pin least (a disc's: only its holes and pin fix it) to the best of 24 turns,
   and the one that explains most points and is seen best kept.

A shape that is not in the cloud (too few points on its surface, or points on a strip of it only)
raises :class:`~handeye.errors.InputMismatchError` saying so: the pipeline skips the view, named.
:func:`refine_shape` finds it from a pose guess (where the other views put it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import label
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from ...errors import InputMismatchError
from ...geometry.se3 import make_transform, perpendicular_basis
from .clouds import depth_sigma
from .shape import Shape, dominant_normals, voxel_pick, weakest_rotation

__all__ = ["ShapeMatch", "find_shape", "refine_shape", "icp", "MIN_INLIERS", "MIN_COVER"]

#: Fewer points on the shape's surface than this: the shape is not found.
MIN_INLIERS = 60
#: The points on the surface must span this share of the shape's size along two of its axes (a
#: strip of points fits a wrong pose as well as the right one).
MIN_COVER = 0.4
#: The orientations the global search starts from (the icosahedral group's 60 rotations: none is
#: more than ~38 deg from any orientation, within trimmed ICP's reach).
_START_ROTATIONS = Rotation.create_group("I").as_matrix()


@dataclass(frozen=True)
class ShapeMatch:
    """A shape found in one cloud: its pose, the cloud's points on its surface (camera frame, m),
    their normals (the shape's frame), the point-to-plane RMS (m), the share of the points near the
    shape that lie on it, the pose's covariance (6x6 over a right increment: rotation rad, translation
    m, in the shape's frame) and the runner-up poses (k, 4, 4) with their scores (share of the best's)."""

    target2cam: NDArray[np.float64]
    points: NDArray[np.float64]
    normals: NDArray[np.float64]
    rms: float
    share: float
    cov: NDArray[np.float64]
    others: NDArray[np.float64]
    other_scores: NDArray[np.float64]


class _Rays:
    """A cloud's points by direction (x/z, y/z in a 2D KD-tree): what lies on the ray of any point,
    for telling whether a posed shape is seen, seen through, or hidden."""

    def __init__(self, q: NDArray[np.float64], around: NDArray[np.float64] | None = None, radius: float = 0.0) -> None:
        """The points ``q`` whose directions lie within ``radius`` (m, at their depth) of the
        directions of ``around`` (the places the shape may be), all when ``around`` is None."""
        uv = q[:, :2] / q[:, 2:3]
        if around is not None and len(around):
            a = around[:, :2] / around[:, 2:3]
            grow = radius / float(np.min(around[:, 2]))
            keep = np.all((uv >= a.min(axis=0) - grow) & (uv <= a.max(axis=0) + grow), axis=1)
            q, uv = q[keep], uv[keep]
        self.q = q
        self.tree = cKDTree(uv)
        probe = uv[:: max(1, len(uv) // 2000)]
        self.pitch = float(np.median(self.tree.query(probe, k=2)[0][:, 1]))

    def score(self, shape: Shape, T: NDArray[np.float64], every: int = 1, slack: float = 0.0, pixels: int = 4
              ) -> NDArray[np.float64]:
        """Per pose (H, 4, 4): the shape's samples (``every`` one of the coarse ones) facing the
        camera that the cloud sees where they are (within 3 of the depth noise and ``slack`` plus the
        samples' spacing), minus twice those it sees through (a point behind them on their ray), of
        the ``pixels`` nearest each sample's direction (4: a sample at an edge, with a pixel beside it
        that misses the shape, is not seen through)."""
        s = shape.points[shape.coarse[::every]]
        n = shape.normals[shape.coarse[::every]]
        T = np.asarray(T, float)
        R = np.swapaxes(T[:, :3, :3], 1, 2)
        x = s @ R + T[:, None, :3, 3]
        cos = np.sum((n @ R) * x, axis=2) / np.linalg.norm(x, axis=2)
        pose, m = np.nonzero((cos < -0.3) & (x[..., 2] > 0))  # facing the camera, not at a grazing angle
        x = x[pose, m]
        # the 4 pixels around each sample: seen where any of them is, seen through where all are behind
        # (a sample at an edge has a pixel beside it that misses the shape)
        dist, k = self.tree.query(x[:, :2] / x[:, 2:3], k=[1, 2, 3, 4][:pixels], distance_upper_bound=1.2 * self.pitch)
        hit = np.isfinite(dist)
        dz = np.where(hit, self.q[np.minimum(k, len(self.q) - 1), 2] - x[:, 2:3], np.nan)
        tol = (3.0 * depth_sigma(x[:, 2]) + shape.size / 60.0 + slack)[:, None]
        with np.errstate(invalid="ignore"):
            seen = np.any(np.abs(dz) < tol, axis=1)
            through = hit.any(axis=1) & np.all((dz > tol) | ~hit, axis=1)
        return np.asarray(np.bincount(pose, seen - 2.0 * through, minlength=len(T)), dtype=float)  # weighted: floats


def _to_shape(T: NDArray[np.float64], q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Points ``q`` (H, M, 3) or (M, 3) in the camera frame into the shape's frame under poses ``T`` (H, 4, 4)."""
    return (q - T[:, None, :3, 3]) @ T[:, :3, :3]


def icp(shape: Shape, T: NDArray[np.float64], q: NDArray[np.float64], sigma: NDArray[np.float64],
        thresholds: NDArray[np.float64], coarse: bool = False) -> NDArray[np.float64]:
    """Trimmed point-to-plane ICP of poses ``T`` (H, 4, 4, target2cam) against points ``q`` (H, M, 3)
    or (M, 3) with depth noise ``sigma`` (M,): per step, the points within that step's threshold of
    their nearest sample (m) whose normal faces the camera (a thin part's back face is as good a
    plane, and a trap), weighted by their noise, one damped Gauss-Newton step of a right increment;
    all poses at once."""
    T = np.array(T, dtype=float)
    H = len(T)
    qs = np.broadcast_to(q, (H,) + q.shape[-2:]) if q.ndim == 2 else q
    w0 = 1.0 / np.square(np.broadcast_to(sigma, qs.shape[:2]))
    for tau in thresholds:
        x = _to_shape(T, qs)
        d, dist, n = shape.surface(x.reshape(-1, 3), coarse)
        d, dist, n = d.reshape(H, -1), dist.reshape(H, -1), n.reshape(H, -1, 3)
        facing = np.sum((n @ np.swapaxes(T[:, :3, :3], 1, 2)) * qs, axis=2) < 0  # a camera sees no back face
        w = np.where((dist < tau) & facing, w0, 0.0)
        J = -np.concatenate([np.cross(x, n), n], axis=2)  # d(residual)/d(right increment)
        Jw = J * w[..., None]
        A = np.swapaxes(Jw, 1, 2) @ J
        b = -(np.swapaxes(Jw, 1, 2) @ d[..., None])[..., 0]
        A += (1e-6 * np.trace(A, axis1=1, axis2=2)[:, None, None] + 1e-12) * np.eye(6)
        step = np.linalg.solve(A, b[..., None])[..., 0]
        inc = make_transform(Rotation.from_rotvec(step[:, :3]).as_matrix(), step[:, 3:])
        T = T @ inc
    return T


def _background_planes(p: NDArray[np.float64], shape: Shape, tol: float, voxel: float, rng: np.random.Generator
                       ) -> NDArray[np.bool_]:
    """Per point of ``p`` (one per voxel of side ``voxel``) whether it lies on a plane larger than
    the shape could show (a wall, a table): RANSAC, up to 4 planes within ``tol``; of each plane's
    points, the connected pieces (joined within 2.5 voxels) with more points than twice the shape's
    size squared holds voxels (a shape's face in the wall's plane but apart from it stays)."""
    background = np.zeros(len(p), bool)
    link = 2.5 * voxel
    most = 2.0 * shape.size**2 / voxel**2
    for _ in range(4):
        rest = np.flatnonzero(~background)
        if len(rest) < most:
            break
        tri = p[rest[rng.integers(0, len(rest), (300, 3))]]
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        ok = np.linalg.norm(normal, axis=1) > 1e-12
        normal = normal[ok] / np.linalg.norm(normal[ok], axis=1, keepdims=True)
        probe = p[rest[rng.integers(0, len(rest), min(len(rest), 4000))]]
        counts = (np.abs(probe @ normal.T - np.einsum("hi,hi->h", tri[ok, 0], normal)) < tol).sum(axis=0)
        k = int(np.argmax(counts))
        on = rest[np.abs(p[rest] @ normal[k] - tri[ok][k, 0] @ normal[k]) < tol]
        if len(on) < most:
            break
        piece = _plane_components(p[on], normal[k], link)
        sizes = np.bincount(piece)
        big = sizes[piece] >= most
        if not big.any():
            break
        background[on[big]] = True
    return background


def _plane_components(p: NDArray[np.float64], normal: NDArray[np.float64], link: float) -> NDArray[np.intp]:
    """Per point of ``p`` (on a plane of ``normal``) its connected piece's label: the points
    rasterised in the plane at ``link``, 8-connected cells one piece."""
    u, w = perpendicular_basis(normal)
    uv = np.c_[p @ u, p @ w]
    cell = np.floor((uv - uv.min(axis=0)) / link).astype(np.int64)
    size = cell.max(axis=0) + 1
    if np.prod(size) > 4_000_000:  # a plane that reaches far (grazing rays): its occupied cells joined in a graph
        cells, back = np.unique(cell, axis=0, return_inverse=True)
        return _components(cells.astype(float), 1.5)[back.ravel()]
    grid = np.zeros(size, bool)
    grid[cell[:, 0], cell[:, 1]] = True
    labels, _ = label(grid, structure=np.ones((3, 3)))
    return labels[cell[:, 0], cell[:, 1]]


def _components(p: NDArray[np.float64], link: float) -> NDArray[np.intp]:
    """Per point its connected piece's label (points joined within ``link``)."""
    pairs = cKDTree(p).query_pairs(link, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(p), len(p)))
    return connected_components(graph, directed=False)[1]


def _seeds(p: NDArray[np.float64], shape: Shape, link: float) -> list[NDArray[np.float64]]:
    """Where the shape may be: over each of the 4 largest clusters of ``p`` (points joined within
    ``link``), the cluster's centroid when it is as small as the shape, else points spread half a
    radius apart (farthest-point sampling from the nearest point, at most 12); each moved to the
    middle of the points within 0.8 radius of it (mean shift), those that meet merged; at most 8."""
    if len(p) < 2:
        return []
    piece = _components(p, link)
    sizes = np.bincount(piece)
    seeds: list[NDArray[np.float64]] = []
    for c in np.argsort(-sizes)[:4]:
        if sizes[c] < 20:
            break
        members = p[piece == c]
        if np.linalg.norm(members.max(axis=0) - members.min(axis=0)) <= 1.5 * shape.size:
            seeds.append(members.mean(axis=0))
            continue
        chosen = [members[np.argmin(members[:, 2])]]
        gap = np.linalg.norm(members - chosen[0], axis=1)
        while len(chosen) < 12 and gap.max() > 0.5 * shape.radius:
            chosen.append(members[int(np.argmax(gap))])
            gap = np.minimum(gap, np.linalg.norm(members - chosen[-1], axis=1))
        seeds += chosen
    seeds = seeds[:12]
    return _distinct_points(_shifted(p, seeds, 0.8 * shape.radius), 0.2 * shape.radius)[:8]


def _shifted(p: NDArray[np.float64], seeds: list[NDArray[np.float64]], radius: float) -> list[NDArray[np.float64]]:
    """Each seed moved to the centroid of the points within ``radius`` of it, three times (mean
    shift: onto the middle of the densest part nearby)."""
    tree = cKDTree(p)
    out = []
    for seed in seeds:
        for _ in range(3):
            near = tree.query_ball_point(seed, radius)
            if not near:
                break
            seed = p[near].mean(axis=0)
        out.append(seed)
    return out


def _distinct_points(points: list[NDArray[np.float64]], gap: float) -> list[NDArray[np.float64]]:
    out: list[NDArray[np.float64]] = []
    for x in points:
        if all(np.linalg.norm(x - o) > gap for o in out):
            out.append(x)
    return out


def _global(shape: Shape, p: NDArray[np.float64], seeds: list[NDArray[np.float64]], tau: float,
            rng: np.random.Generator) -> NDArray[np.float64]:
    """Candidate poses (K, 4, 4) from every seed and start orientation, each pulled in by trimmed
    ICP on the seed's neighbourhood (coarse copies of both)."""
    poses = []
    tree = cKDTree(p)
    for seed in seeds:
        crop = p[tree.query_ball_point(seed, 1.2 * shape.radius)]
        if len(crop) < 20:
            continue
        crop = crop[rng.permutation(len(crop))[:100]]
        centre = crop.mean(axis=0)
        ray = centre / np.linalg.norm(centre)
        R = np.concatenate([_START_ROTATIONS, _facing(shape, crop)])
        # each orientation's visible side (its 90th percentile towards the camera) on the points' centroid
        front = np.percentile((shape.points[shape.coarse] - shape.centre) @ np.swapaxes(R, 1, 2) @ -ray, 90, axis=1)
        T = make_transform(R, centre + front[:, None] * ray - R @ shape.centre)
        steps = np.geomspace(0.6 * shape.radius, tau, 7)
        poses.append(icp(shape, T, crop, depth_sigma(crop[:, 2]), np.r_[steps, tau, tau], coarse=True))
    return np.concatenate(poses) if poses else np.zeros((0, 4, 4))


def _facing(shape: Shape, crop: NDArray[np.float64], turns: int = 12) -> NDArray[np.float64]:
    """Orientations (K, 3, 3) that turn each of the shape's main face directions onto the direction
    most of the points ``crop`` face (their local planes' normals, towards the camera), each at
    ``turns`` turns about it: starts near a flat part's true orientation, which the evenly spread
    ones may miss by 37 deg."""
    if len(crop) < 10 or not len(shape.faces):
        return np.zeros((0, 3, 3))
    _, nb = cKDTree(crop).query(crop, k=min(10, len(crop)))
    local = crop[nb] - crop[nb].mean(axis=1, keepdims=True)
    normal = np.linalg.svd(local, full_matrices=False)[2][:, 2]
    normal *= -np.sign(np.sum(normal * crop, axis=1))[:, None]  # towards the camera
    seen = dominant_normals(normal, k=1, share=0.0)[0]
    out = []
    spin = Rotation.from_rotvec(np.outer(np.arange(turns) * 2 * np.pi / turns, seen))
    for face in shape.faces:
        align, _ = Rotation.align_vectors(seen[None], face[None])
        out.append((spin * align).as_matrix())
    return np.concatenate(out)


def _distinct(T: NDArray[np.float64], score: NDArray[np.float64], k: int, shape: Shape) -> NDArray[np.intp]:
    """The ``k`` best poses of ``T`` by ``score``, each more than 10 deg or a fifth of the shape's
    radius from the others; for a shape with an axis it pins least (:attr:`Shape.spin`), turns about
    that axis count as the same pose (the refinement tries them all)."""
    if shape.spin is None:
        direction = T[:, :3, :3].reshape(len(T), 9) / np.sqrt(3.0)
        where = T[:, :3, :3] @ shape.centre + T[:, :3, 3]
    else:
        direction = T[:, :3, :3] @ shape.spin[0]
        where = T[:, :3, :3] @ shape.spin[1] + T[:, :3, 3]
    out: list[int] = []
    for i in np.argsort(-score):
        near = [np.linalg.norm(where[i] - where[j]) < 0.2 * shape.radius and direction[i] @ direction[j] > np.cos(np.radians(10))
                for j in out]
        if not any(near):
            out.append(int(i))
        if len(out) == k:
            break
    return np.array(out, dtype=np.intp)


def _near(shape: Shape, T: NDArray[np.float64], q: NDArray[np.float64], limit: int, rng: np.random.Generator
          ) -> NDArray[np.float64]:
    """The points of ``q`` within the shape's bounding ball (10% larger) under pose ``T``, at most ``limit``."""
    centre = T[:3, :3] @ shape.centre + T[:3, 3]
    near = q[np.sum((q - centre) ** 2, axis=1) < (1.1 * shape.radius) ** 2]
    return near if len(near) <= limit else near[rng.choice(len(near), limit, replace=False)]


def _inliers(shape: Shape, T: NDArray[np.float64], q: NDArray[np.float64]) -> tuple[NDArray[np.bool_], NDArray[np.float64],
                                                                                     NDArray[np.float64], NDArray[np.float64]]:
    """Which points of ``q`` lie on the surface under ``T`` (within 3.5 of their depth noise along
    the normal, and near a sample), their signed distances, normals (shape frame) and shape-frame points."""
    x = _to_shape(T[None], q)[0]
    d, dist, n = shape.surface(x, exact=True)
    on = _on_surface(shape, d, dist, depth_sigma(q[:, 2])) & (np.sum((n @ T[:3, :3].T) * q, axis=1) < 0)
    return on, d, n, x


def _on_surface(shape: Shape, d: NDArray[np.float64], dist: NDArray[np.float64], sigma: NDArray[np.float64]
                ) -> NDArray[np.bool_]:
    """Whether points at signed distance ``d`` along the normal and ``dist`` from their nearest sample,
    of depth noise ``sigma``, lie on the surface: within 3.5 of their noise along the normal and near a sample."""
    return (np.abs(d) < 3.5 * sigma + 0.5 * shape.spacing) & (dist < 4.0 * sigma + 3.0 * shape.spacing)


def _covered(x: NDArray[np.float64], shape: Shape) -> bool:
    """Whether points ``x`` (shape frame) span :data:`MIN_COVER` of the shape along two of its box's axes."""
    span = np.ptp(x, axis=0) / np.maximum(np.ptp(shape.points, axis=0), 1e-9)
    return int(np.sum(span >= MIN_COVER)) >= 2


def find_shape(shape: Shape, points: NDArray[np.float64], *, where: str = "cloud", max_points: int = 1200,
               rng: np.random.Generator | int | None = 0) -> ShapeMatch:
    """``shape`` found in a cloud's ``points`` (N, 3, camera frame, m; organized clouds flattened),
    without any guess of its pose (the module's docstring): its pose and the points on its surface
    (at most ``max_points``, evenly drawn).

    Raises
    ------
    InputMismatchError
        Naming ``where``: the shape is not in the cloud (too few points on its surface, or they
        span a strip of it only), or the cloud has too few points.
    """
    rng = np.random.default_rng(rng)
    q = np.asarray(points, float).reshape(-1, 3)
    q = q[np.isfinite(q).all(axis=1) & (q[:, 2] > 0)]
    if len(q) < MIN_INLIERS:
        raise InputMismatchError(f"{where}: {len(q)} points with depth: the shape cannot be in it")
    voxel = shape.size / 30.0
    p = q[voxel_pick(q, voxel)]
    tol = max(0.5 * voxel, 3.0 * float(np.median(depth_sigma(p[:, 2]))))
    rest = p[~_background_planes(p, shape, tol, voxel, rng)]
    tau = 3.0 * float(np.median(depth_sigma(rest[:, 2]))) + shape.size / 60.0 if len(rest) else 0.0
    seeds = _seeds(rest, shape, 2.5 * voxel)
    T = _global(shape, rest, seeds, tau, rng)
    if not len(T):
        raise InputMismatchError(f"{where}: the shape is not in the cloud (no group of points off the background's "
                                 "planes is near its size)")
    rays = _Rays(q, np.array(seeds), 2.5 * shape.radius)
    seen = rays.score(shape, T, every=8, slack=shape.size / 15.0, pixels=1)
    ranked = [_refined(shape, q, T0, rays, rng) for T0 in T[_distinct(T, seen, 3, shape)]]
    return _match(shape, q, sorted([r for r in ranked if r is not None], key=lambda r: -r[0]), max_points, rng, where)


def refine_shape(shape: Shape, points: NDArray[np.float64], target2cam: NDArray[np.float64], *, where: str = "cloud",
                 max_points: int = 1200, rng: np.random.Generator | int | None = 0) -> ShapeMatch:
    """``shape`` found in a cloud's ``points`` from a pose guess ``target2cam`` (the pose the other
    views predict): robust point-to-plane ICP from it, no global search; as :func:`find_shape`
    returns and raises."""
    rng = np.random.default_rng(rng)
    q = np.asarray(points, float).reshape(-1, 3)
    q = q[np.isfinite(q).all(axis=1) & (q[:, 2] > 0)]
    pulled = _pulled_in(shape, np.asarray(target2cam, float), q, rng)
    if pulled is None:
        raise InputMismatchError(f"{where}: fewer than {MIN_INLIERS} points where the other views put the shape: it is "
                                 "not there")
    T, _, tight = pulled
    near = _near(shape, T, q, 3000, rng)
    T = icp(shape, T[None], near, depth_sigma(near[:, 2]), np.full(5, tight))[0]
    return _match(shape, q, [(1.0, T)], max_points, rng, where)


def _refined(shape: Shape, q: NDArray[np.float64], T: NDArray[np.float64], rays: _Rays, rng: np.random.Generator
             ) -> tuple[float, NDArray[np.float64]] | None:
    """A candidate pose refined on the full cloud's points near it, turned about the axis the
    surface pins least (a disc's own, where holes or a pin fix it) to the best of 24 turns, and
    refined again: (score, pose) (the score: :meth:`_Rays.score`), None when no point is near."""
    pulled = _pulled_in(shape, T, q, rng)
    if pulled is None:
        return None
    T, near, tight = pulled
    turns = _turns(shape, T, near, tight)
    if len(turns) > 1:  # the best three turns, each refined: a turn a few degrees off its best scores low
        few = near[rng.permutation(len(near))[:500]]
        turns = icp(shape, turns, few, depth_sigma(few[:, 2]), np.full(5, 2.0 * tight), coarse=True)
        turns = turns[np.argsort(-_score(shape, turns, few, rays, every=2))[:3]]
    turns = icp(shape, turns, near, depth_sigma(near[:, 2]), np.r_[2.0 * tight, np.full(5, tight)])
    score = _score(shape, turns, _near(shape, turns[0], q, len(q), rng), rays)
    return float(score.max()), turns[int(np.argmax(score))]


def _pulled_in(shape: Shape, T: NDArray[np.float64], q: NDArray[np.float64], rng: np.random.Generator
               ) -> tuple[NDArray[np.float64], NDArray[np.float64], float] | None:
    """Pose ``T`` pulled in by trimmed ICP on the cloud's points ``q`` near it (thresholds from 4x down
    to the tight one, 3 of the depth noise and 3 sample spacings): (pose, those points, the tight
    threshold), None when fewer than :data:`MIN_INLIERS` are near."""
    near = _near(shape, T, q, 3000, rng)
    if len(near) < MIN_INLIERS:
        return None
    sigma = depth_sigma(near[:, 2])
    tight = 3.0 * float(np.median(sigma)) + 3.0 * shape.spacing
    return icp(shape, T[None], near, sigma, np.geomspace(4.0 * tight, tight, 8))[0], near, tight


def _score(shape: Shape, T: NDArray[np.float64], q: NDArray[np.float64], rays: _Rays, every: int = 1) -> NDArray[np.float64]:
    """Per pose (H, 4, 4): the cloud's points ``q`` on the shape's surface, plus :meth:`_Rays.score`
    (the shape's samples seen where they are, less twice those seen through; ``every`` one of them)
    in proportion."""
    x = _to_shape(T, np.broadcast_to(q, (len(T),) + q.shape))
    d, dist, n = shape.surface(x.reshape(-1, 3))
    on = _on_surface(shape, d, dist, np.tile(depth_sigma(q[:, 2]), len(T)))
    on &= np.sum(n.reshape(x.shape) @ np.swapaxes(T[:, :3, :3], 1, 2) * q, axis=2).ravel() < 0
    return on.reshape(len(T), -1).sum(axis=1) + every * rays.score(shape, T, every=every)


def _turns(shape: Shape, T: NDArray[np.float64], q: NDArray[np.float64], tight: float, n: int = 24) -> NDArray[np.float64]:
    """Pose ``T`` turned ``n`` times about the axis the cloud's points ``q`` on it pin least
    (:func:`~handeye.sensors.depth.shape.weakest_rotation`: a disc's own axis, which only its holes
    or a pin fix), when that rotation is pinned less than
    :data:`~handeye.sensors.depth.shape.SPIN_SHARE` as well as the best one; else ``T`` alone (1, 4, 4)."""
    x = _to_shape(T[None], q)[0]
    _, dist, nrm = shape.surface(x)
    weak = weakest_rotation(x, nrm, (dist < tight) / np.square(depth_sigma(q[:, 2])))
    if weak is None:
        return T[None]
    axis, c = weak
    R = Rotation.from_rotvec(np.outer(np.arange(n) * 2 * np.pi / n, axis)).as_matrix()
    return T @ make_transform(R, c - R @ c)


def _match(shape: Shape, q: NDArray[np.float64], ranked: list[tuple[float, NDArray[np.float64]]], max_points: int,
           rng: np.random.Generator, where: str) -> ShapeMatch:
    if not ranked:
        raise InputMismatchError(f"{where}: the shape is not in the cloud (no candidate pose has points near it)")
    score, T = ranked[0]
    near = _near(shape, T, q, len(q), rng)
    on, d, n, x = _inliers(shape, T, near)
    if on.sum() < MIN_INLIERS or not _covered(x[on], shape):
        raise InputMismatchError(f"{where}: the shape is not in the cloud: its best pose has {int(on.sum())} points on its "
                                 f"surface{'' if on.sum() < MIN_INLIERS else ', on a strip of it only'} (at least "
                                 f"{MIN_INLIERS}, spanning {100 * MIN_COVER:.0f}% of it two ways, are needed); is it in view, "
                                 "within the camera's range, and the mesh the part that was scanned?")
    keep = np.flatnonzero(on)
    keep = keep if len(keep) <= max_points else np.sort(rng.choice(keep, max_points, replace=False))
    sigma = depth_sigma(near[keep, 2])
    J = -np.concatenate([np.cross(x[keep], n[keep]), n[keep]], axis=1) / sigma[:, None]
    cov = np.asarray(np.linalg.pinv(J.T @ J, rcond=1e-12), dtype=float)
    others = np.array([t for _, t in ranked[1:]]).reshape(-1, 4, 4)
    return ShapeMatch(T, near[keep], n[keep], float(np.sqrt(np.mean(d[keep] ** 2))), float(on.mean()), cov, others,
                      np.array([s / max(score, 1.0) for s, _ in ranked[1:]]))
