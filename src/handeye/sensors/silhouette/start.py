"""A fixed camera's pose found from an arm's silhouettes without any guess: :func:`coarse_cam2base`.

The camera is somewhere around the arm, looking at it. For each of a set of orientations (viewing
directions spread evenly over the sphere, :func:`fibonacci_sphere`, each turned about itself in
:data:`ROLLS` steps) the camera's position follows in closed form from the masks: in every view the
arm's centre (of its surface, sampled evenly) must project to the mask's centroid, at the depth where
the arm's spread across the image (orthographically, metres) matches the mask's (pixels) through the
focal length; the views' positions are averaged. Each candidate is scored by the masks' agreement
(intersection over union, averaged over the views) with the arm's surface points splatted into
downscaled masks (1/8 of the image's side), and the best are returned for the contour fit to finish.

Examples
--------
>>> fibonacci_sphere(4).shape
(4, 3)
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..._shared.lazy import lazy_module
from ...geometry.se3 import make_transform

cv2 = lazy_module("cv2")

__all__ = ["fibonacci_sphere", "surface_samples", "coarse_cam2base", "DIRECTIONS", "ROLLS", "SCALE"]

#: Viewing directions tried (evenly over the sphere).
DIRECTIONS = 300
#: Turns of the camera about its viewing direction tried per direction.
ROLLS = 12
#: The coarse score splats at most this many of each view's surface points.
SPLAT = 600
#: The coarse score's masks are this many times smaller than the image along each side.
SCALE = 8


def fibonacci_sphere(n: int) -> NDArray[np.float64]:
    """``n`` unit vectors (n, 3) spread evenly over the sphere."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    phi = np.pi * (3 - np.sqrt(5)) * k
    r = np.sqrt(1 - z**2)
    return np.c_[r * np.cos(phi), r * np.sin(phi), z]


def surface_samples(vertices: NDArray[np.float64], faces: NDArray[np.intp], n: int, rng: int = 0
                    ) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """``n`` points spread evenly (by area) over a mesh's surface: each one's triangle and its
    barycentric weights (n, 3), so that posed vertices give the posed points."""
    tri = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    gen = np.random.default_rng(rng)
    face = gen.choice(len(faces), size=n, p=area / area.sum())
    a, b = gen.random(n), gen.random(n)
    flip = a + b > 1
    a[flip], b[flip] = 1 - a[flip], 1 - b[flip]
    return face, np.c_[1 - a - b, a, b]


def _rotations(directions: int, rolls: int) -> NDArray[np.float64]:
    """Camera orientations (n, 3, 3; columns: the camera's x, y, z in the base frame)."""
    z = fibonacci_sphere(directions)
    helper = np.where(np.abs(z[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    x0 = np.cross(helper, z)
    x0 /= np.linalg.norm(x0, axis=1, keepdims=True)
    y0 = np.cross(z, x0)
    out = []
    for a in np.arange(rolls) * 2 * np.pi / rolls:
        x = np.cos(a) * x0 + np.sin(a) * y0
        out.append(np.stack([x, np.cross(z, x), z], axis=2))
    return np.concatenate(out)


def _mask_moments(masks: NDArray[np.bool_]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per mask its centroid (N, 2, pixels) and spread (N,: RMS distance from the centroid)."""
    c, s = np.zeros((len(masks), 2)), np.zeros(len(masks))
    for k, m in enumerate(masks):
        v, u = np.nonzero(m)
        c[k] = u.mean(), v.mean()
        s[k] = np.sqrt(u.var() + v.var())
    return c, s


def _small(masks: NDArray[np.bool_], scale: int) -> NDArray[np.bool_]:
    h, w = masks.shape[1:]
    size = (max(1, w // scale), max(1, h // scale))
    return np.array([cv2.resize(m.astype(np.float32), size, interpolation=cv2.INTER_AREA) > 0.5 for m in masks])


def _scores(R: NDArray[np.float64], C: NDArray[np.float64], points: NDArray[np.float64], K: NDArray[np.float64],
            small: NDArray[np.bool_], scale: int, chunk: int = 64) -> NDArray[np.float64]:
    """Per candidate (R, C: its orientation and centre) the mean IoU over the views of the points
    (N, S, 3, base frame) splatted into the small masks (N, h, w), dilated by one cell; ``chunk``
    candidates at a time."""
    n_views, h, w = small.shape
    out = np.zeros(len(R))
    for start in range(0, len(R), chunk):
        Rc, Cc = R[start:start + chunk], C[start:start + chunk]
        p = np.matmul((points[None] - Cc[:, None, None]).reshape(len(Rc), -1, 3), Rc).reshape((len(Rc),) + points.shape)
        z = p[..., 2]
        ok = z > 0.05
        with np.errstate(divide="ignore", invalid="ignore"):
            u = (K[0, 0] * p[..., 0] / z + K[0, 2]) / scale
            v = (K[1, 1] * p[..., 1] / z + K[1, 2]) / scale
        ok &= (u >= 0) & (u < w) & (v >= 0) & (v < h)
        cand, view, _ = np.nonzero(ok)
        cells = np.zeros((len(Rc), n_views, h + 2, w + 2), bool)
        cells[cand, view, v[ok].astype(np.intp) + 1, u[ok].astype(np.intp) + 1] = True
        drawn = np.zeros((len(Rc), n_views, h, w), bool)
        for di in range(3):
            for dj in range(3):
                drawn |= cells[:, :, di:di + h, dj:dj + w]
        inter = np.count_nonzero(drawn & small, axis=(2, 3))
        union = np.count_nonzero(drawn | small, axis=(2, 3))
        out[start:start + chunk] = np.mean(inter / np.maximum(union, 1), axis=1)
    return out


def coarse_cam2base(points: NDArray[np.float64], masks: NDArray[np.bool_], K: NDArray[np.float64], keep: int = 8,
                    directions: int = DIRECTIONS, rolls: int = ROLLS, scale: int = SCALE
                    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The camera's best poses (keep, 4, 4: cam2base) and their coarse scores (mean IoU), best first.

    Parameters
    ----------
    points : ndarray (N, S, 3)
        Per view, points spread evenly over the arm's surface at that view's joint angles, base frame (m).
    masks : ndarray of bool (N, height, width)
        The arm's silhouette in each view.
    K : ndarray (3, 3)
    keep : int
        How many candidates to return.
    """
    R = _rotations(directions, rolls)
    centroid, spread = _mask_moments(masks)
    f = float(np.sqrt(K[0, 0] * K[1, 1]))
    centre = points.mean(axis=1)  # (N, 3)
    rel = points - centre[:, None]
    cov = np.einsum("nsi,nsj->nij", rel, rel) / points.shape[1]
    # per candidate and view: the arm's spread across the image plane (orthographic, m)
    model_spread = np.sqrt(np.einsum("cik,nij,cjk->cn", R[:, :, :2], cov, R[:, :, :2], optimize=True))  # (c, N)
    depth = f * model_spread / np.maximum(spread, 1.0)  # (c, N)
    rays = np.c_[(centroid[:, 0] - K[0, 2]) / K[0, 0], (centroid[:, 1] - K[1, 2]) / K[1, 1], np.ones(len(masks))]
    # the camera's centre: C = centre_i - R (z_i ray_i), averaged over the views
    C = np.mean(centre[None] - np.einsum("cjk,cnk->cnj", R, depth[..., None] * rays[None]), axis=1)
    small = _small(masks, scale)
    sub = points[:, ::max(1, points.shape[1] // SPLAT)]
    score = _scores(R, C, sub, K, small, scale)
    best = np.argsort(-score)[:keep]
    return make_transform(R[best], C[best]), score[best]
