"""X from a scene's clouds without any guess: where to start the registration of all views.

Two kinds of candidates, each then pulled in by a coarse registration of all views with X
(:func:`~handeye.sensors.depth.scene.register` on a few hundred points per view), the one whose
views agree best kept (:func:`scene_start`):

* the **closed form** on the clouds' centres (:func:`centroid_start`): a camera that looks at the
  object from every view sees it about one place, so ``A_i X c_i`` is one point for every view
  (``c_i`` the cloud's centroid in the camera, ``A_i`` the robot-world pose): linear in X, as for
  a ball's centres. Each view sees another side of the object, so the centroids are off by a share
  of its size and X by a few degrees and centimetres; the registration's reach covers that when
  the views fixate the object;
* a **search** over X's rotation (:func:`rotation_search`): every rotation of a grid (the 60 of the
  icosahedral group, each turned by 12 steps of ~19 deg about 6 axes and by none: 780, none more
  than ~20 deg from any rotation), X's translation for it from the same centres (linear), each
  scored by the share of the views' points that lie near another view's (voxels, all rotations at
  once); the best few distinct ones go to the registration. It needs no fixation of the views'
  rotation: it finds X where the closed form's rotation is far off (a view that sees mostly a
  table's plane, the cloud's centroid far from the object's).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ...errors import DegenerateMotionError
from ...geometry.se3 import make_transform
from .model import sphere_start
from .scene import SceneView, pair_spread, register
from .shape import voxel_pick

__all__ = ["centroid_start", "rotation_grid", "rotation_search", "scene_start", "StartCandidate", "agreement"]


def centroid_start(views: list[SceneView], A: NDArray[np.float64]) -> NDArray[np.float64]:
    """X from ``A_i X c_i = p`` with ``c_i`` each view's centroid (camera frame) and ``p`` one point
    (the object's centre in the common frame): linear, as a ball's centres (:func:`~handeye.sensors.depth.model.sphere_start`).

    Raises
    ------
    DegenerateMotionError
        The views' motions cannot determine X this way (fewer than 4 views, or turns about one axis).
    """
    c = np.array([v.centroid for v in views])
    X, _ = sphere_start(np.asarray(A, float), c, np.arange(len(views)), np.zeros(len(views), dtype=np.intp), 1)
    return X


def rotation_grid() -> NDArray[np.float64]:
    """Rotations (780, 3, 3) none more than ~20 deg from any rotation: the icosahedral group's 60,
    each also turned by 19 deg about the 6 axes of an icosahedron's vertices, both ways."""
    group = Rotation.create_group("I")
    phi = (1 + np.sqrt(5)) / 2
    axes = np.array([[0, 1, phi], [0, 1, -phi], [1, phi, 0], [1, -phi, 0], [phi, 0, 1], [-phi, 0, 1]], float)
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    turns = Rotation.from_rotvec(np.r_[np.zeros((1, 3)), np.radians(19.0) * axes, -np.radians(19.0) * axes])
    return np.concatenate([(group * t).as_matrix() for t in turns])


def _translations(views: list[SceneView], A: NDArray[np.float64], R: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per rotation of ``R`` (H, 3, 3) X's translation from ``A_i (R c_i + t) = p`` (the views'
    centroids one point): least squares in ``t`` and ``p``, all rotations at once."""
    c = np.array([v.centroid for v in views])
    RA, tA = A[:, :3, :3], A[:, :3, 3]
    n = len(views)
    M: NDArray[np.float64] = np.zeros((n, 3, 6))
    M[:, :, :3] = RA
    M[:, :, 3:] = -np.eye(3)
    M = M.reshape(3 * n, 6)
    pinv = np.linalg.pinv(M)
    rhs = -(np.einsum("nij,hjk,nk->hni", RA, R, c) + tA[None]).reshape(len(R), 3 * n)
    return (rhs @ pinv.T)[:, :3]


def agreement(views: list[SceneView], A: NDArray[np.float64], X: NDArray[np.float64], voxel: float,
              points: list[NDArray[np.intp]] | None = None) -> NDArray[np.float64]:
    """Per X of ``X`` (H, 4, 4): the share of the views' points (``points``: per view the indices;
    default each view's query points) whose voxel of side ``voxel`` (m, in the common frame; two
    grids half a voxel apart) holds a point of another view."""
    X = np.asarray(X, float)
    H = len(X)
    pts = [v.points[v.query if points is None else points[k]] for k, v in enumerate(views)]
    best = np.zeros(H)
    total = sum(len(p) for p in pts)
    for shift in (0.0, 0.5):
        hits = np.zeros(H)
        keys, bits = [], []
        for k, p in enumerate(pts):
            T = A[k][None] @ X  # (H, 4, 4) camera to common
            y = np.einsum("hij,mj->hmi", T[:, :3, :3], p) + T[:, None, :3, 3]
            cell = np.floor(y / voxel + shift).astype(np.int64)
            key = ((np.arange(H)[:, None] * 4096 + (cell[..., 0] & 4095)) * 4096 + (cell[..., 1] & 4095)) * 4096 + \
                (cell[..., 2] & 4095)
            keys.append(key.ravel())
            bits.append(np.full(key.size, 1 << k, dtype=np.int64))
        key, bit = np.concatenate(keys), np.concatenate(bits)
        order = np.argsort(key, kind="stable")
        key_s, bit_s = key[order], bit[order]
        start = np.r_[0, np.flatnonzero(np.diff(key_s)) + 1]
        mask = np.bitwise_or.reduceat(bit_s, start)
        group = np.repeat(np.arange(len(start)), np.diff(np.r_[start, len(key_s)]))
        others = (mask[group] & ~bit_s) != 0
        hits_s = np.zeros(len(key), bool)
        hits_s[order] = others
        offset = 0
        for p in pts:
            size = H * len(p)
            hits += hits_s[offset:offset + size].reshape(H, len(p)).sum(axis=1)
            offset += size
        best = np.maximum(best, hits / max(total, 1))
    return best


@dataclass(frozen=True)
class StartCandidate:
    """A start of the registration: where it came from, X before and after the coarse registration,
    and how well the views agree there (the share of their points near another view's, and the
    pairs' robust spread, m)."""

    source: str
    X0: NDArray[np.float64]
    X: NDArray[np.float64]
    share: float
    spread: float


def _coarse_points(views: list[SceneView], count: int) -> list[NDArray[np.intp]]:
    """Per view about ``count`` of its query points, spread evenly (one per voxel)."""
    out = []
    for v in views:
        q = v.query
        if len(q) <= count:
            out.append(q)
            continue
        extent = float(np.linalg.norm(np.ptp(v.points[q], axis=0)))
        voxel = extent / np.sqrt(count) * 1.2
        pick = q[voxel_pick(v.points[q], voxel)]
        out.append(pick[np.linspace(0, len(pick) - 1, min(count, len(pick))).astype(np.intp)])
    return out


def rotation_search(views: list[SceneView], A: NDArray[np.float64], size: float, keep: int = 4,
                    count: int = 150) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The best ``keep`` distinct X (more than 30 deg apart) of :func:`rotation_grid`'s rotations with
    their translations from the centroids (:func:`_translations`), by :func:`agreement` on ``count``
    points per view in voxels of a tenth of the scene's ``size`` (m); and their scores."""
    R = rotation_grid()
    t = _translations(views, A, R)
    X = make_transform(R, t)
    score = agreement(views, A, X, 0.1 * size, _coarse_points(views, count))
    chosen: list[int] = []
    for i in np.argsort(-score):
        if all(np.degrees(Rotation.from_matrix(R[i] @ R[j].T).magnitude()) > 30.0 for j in chosen):
            chosen.append(int(i))
        if len(chosen) == keep:
            break
    return X[chosen], score[chosen]


def scene_start(views: list[SceneView], A: NDArray[np.float64], *, search: bool = True
                ) -> tuple[StartCandidate, list[StartCandidate]]:
    """X to start the registration from, with no guess (the module's docstring): the closed form on
    the centroids and (``search``) the rotation search's best few, each pulled in by a coarse
    registration (thresholds from a fifth of the scene's size down to a fiftieth, a fifth of the
    query points), the one whose views agree best kept (the most points near another view's within
    a fiftieth of the size, then the smallest spread). Returns the one kept and every candidate.

    Raises
    ------
    DegenerateMotionError
        No candidate: the views' motions determine no X (fewer than 3 views, or turns about one axis).
    """
    size = float(np.median([2.0 * v.radius for v in views]))
    starts: list[tuple[str, NDArray[np.float64]]] = []
    try:
        starts.append(("closed form on the clouds' centroids", centroid_start(views, A)))
    except DegenerateMotionError:
        if not search:
            raise
    if search:
        found, _ = rotation_search(views, A, size)
        starts += [(f"rotation search ({k + 1})", X) for k, X in enumerate(found)]
    if not starts:
        raise DegenerateMotionError("the views' motions determine no X: at least 4 views with the flange turned about two "
                                    "different axes are needed")
    taus = np.geomspace(0.2 * size, 0.02 * size, 4)
    coarse = _coarse_points(views, 300)
    out = []
    for source, X0 in starts:
        X, _, pairs = register(views, A, X0, taus, coarse=max(1, int(np.median([len(v.query) for v in views]) // 120)),
                               steps=3, rounds=3, settle=0.05, full_last=False)
        share = float(agreement(views, A, X[None], 0.02 * size, coarse)[0])
        out.append(StartCandidate(source, X0, X, share, pair_spread(views, A, X, pairs) if len(pairs) >= 6 else np.inf))
    return max(out, key=lambda c: (round(c.share, 2), -c.spread)), out
