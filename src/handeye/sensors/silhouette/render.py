"""An arm's silhouette in a camera image, on the CPU: projection, filling, outlines and distance fields.

:func:`render_silhouettes` projects each view's posed triangles through the camera matrix (and
OpenCV's distortion when given) and fills the ones that face the camera, each with
``cv2.fillConvexPoly`` (``cv2.fillPoly`` with many polygons fills their even-odd union, not their
union: two overlapping triangles leave a hole). A closed mesh's silhouette is the union of its
triangles that face the camera, half of them: ~30 ms for the Panda's 39,000 triangles at 640x480.
A triangle with a corner behind the camera (closer than :data:`NEAR` m) is left out.

:func:`signed_distance` is a mask's signed distance field (pixels, positive outside, zero on the
boundary between pixel centres), read at sub-pixel points by :func:`bilinear`; :func:`outline`
gives a mask's outer boundary pixels.

Examples
--------
>>> import numpy as np
>>> K = np.array([[100.0, 0, 32], [0, 100, 24], [0, 0, 1]])
>>> square = np.array([[[-0.1, -0.1, 1.0], [0.1, -0.1, 1.0], [0.1, 0.1, 1.0], [-0.1, 0.1, 1.0]]])
>>> faces = np.array([[0, 2, 1], [0, 3, 2]])         # facing the camera (-z)
>>> int(render_silhouettes(square, faces, K, (64, 48))[0].sum())   # 20 x 20 pixels, and half a pixel around
441
"""

from __future__ import annotations

from typing import Literal, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..._shared.lazy import lazy_module
from ...errors import InputMismatchError

cv2 = lazy_module("cv2")

__all__ = ["project", "projection_jacobian", "render_silhouettes", "signed_distance", "bilinear", "outline", "iou", "NEAR",
           "SUBPIXEL"]

#: Points closer to the camera than this (m), or behind it, are not drawn.
NEAR = 0.02
#: The renderer draws with this many fractional bits (cv2's ``shift``): 1/16 px.
SUBPIXEL = 4


def _distort(xn: NDArray[np.float64], yn: NDArray[np.float64], dist: NDArray[np.float64]
             ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Normalised coordinates distorted by OpenCV's model (k1, k2, p1, p2[, k3[, k4, k5, k6]])."""
    d = np.zeros(8)
    d[:min(len(dist), 8)] = dist[:8]
    k1, k2, p1, p2, k3, k4, k5, k6 = d
    r2 = xn**2 + yn**2
    radial = (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
    return (xn * radial + 2 * p1 * xn * yn + p2 * (r2 + 2 * xn**2),
            yn * radial + p1 * (r2 + 2 * yn**2) + 2 * p2 * xn * yn)


def project(points: ArrayLike, K: ArrayLike, dist: ArrayLike | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Pixel coordinates (..., 2) of camera-frame points (..., 3) and their depth (...,): NaN pixels
    for points closer than :data:`NEAR`."""
    p = np.asarray(points, float)
    K = np.asarray(K, float)
    z = p[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        zs = np.where(z > NEAR, z, np.nan)
        xn, yn = p[..., 0] / zs, p[..., 1] / zs
    if dist is not None and np.any(np.asarray(dist, float) != 0):
        xn, yn = _distort(xn, yn, np.asarray(dist, float).ravel())
    uv = np.stack([K[0, 0] * xn + K[0, 1] * yn + K[0, 2], K[1, 1] * yn + K[1, 2]], axis=-1)
    return uv, z


def projection_jacobian(points: NDArray[np.float64], K: NDArray[np.float64], dist: NDArray[np.float64] | None = None
                        ) -> NDArray[np.float64]:
    """The derivative (M, 2, 3) of :func:`project`'s pixels with respect to camera-frame points (M, 3)
    (the distortion's part by central differences in normalised coordinates)."""
    x, y, z = points[:, 0], points[:, 1], points[:, 2]
    dn = np.zeros((len(points), 2, 3))  # normalised coordinates over the point
    dn[:, 0, 0] = 1 / z
    dn[:, 0, 2] = -x / z**2
    dn[:, 1, 1] = 1 / z
    dn[:, 1, 2] = -y / z**2
    D = np.broadcast_to(np.eye(2), (len(points), 2, 2)).copy()
    if dist is not None and np.any(np.asarray(dist, float) != 0):
        d = np.asarray(dist, float).ravel()
        xn, yn, h = x / z, y / z, 1e-6
        for j, (ex, ey) in enumerate(((h, 0.0), (0.0, h))):
            plus, minus = _distort(xn + ex, yn + ey, d), _distort(xn - ex, yn - ey, d)
            D[:, 0, j] = (plus[0] - minus[0]) / (2 * h)
            D[:, 1, j] = (plus[1] - minus[1]) / (2 * h)
    A = np.array([[K[0, 0], K[0, 1]], [0.0, K[1, 1]]])
    # A @ D @ dn written out: 3x faster than einsum with three operands (the same sums without distortion)
    AD = A[None, :, 0, None] * D[:, None, 0, :] + A[None, :, 1, None] * D[:, None, 1, :]
    return AD[:, :, 0, None] * dn[:, None, 0, :] + AD[:, :, 1, None] * dn[:, None, 1, :]


def render_silhouettes(vertices: ArrayLike, faces: ArrayLike, K: ArrayLike, size: tuple[int, int],
                       dist: ArrayLike | None = None) -> NDArray[np.bool_]:
    """Each view's silhouette (N, height, width) of a mesh posed in the camera frame.

    Parameters
    ----------
    vertices : array_like (N, V, 3)
        Per view the mesh's vertices in the camera frame, metres.
    faces : array_like (F, 3)
        Vertex indices of each triangle (any winding: a triangle is drawn when it faces the camera
        either way round as long as the mesh's windings agree; a closed mesh's outward normals).
    K : array_like (3, 3)
    size : (int, int)
        The image's width and height, pixels.
    dist : array_like, optional
        OpenCV's distortion coefficients.

    Returns
    -------
    ndarray of bool (N, height, width)
    """
    V = np.asarray(vertices, float)
    V = V[None] if V.ndim == 2 else V
    faces = np.asarray(faces, dtype=np.intp)
    width, height = int(size[0]), int(size[1])
    if width <= 0 or height <= 0:
        raise InputMismatchError(f"image size {size}: give (width, height) in pixels")
    out = np.zeros((len(V), height, width), np.uint8)
    uv, _ = project(V, K, dist)
    fill, line = cv2.fillConvexPoly, cv2.LINE_8  # looked up once: the loop below runs once per triangle
    for n in range(len(V)):
        tri = uv[n][faces]  # (F, 3, 2)
        e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        area = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        ok = np.isfinite(tri).all(axis=(1, 2)) & (area < 0)  # facing the camera (y down)
        ok &= (tri[..., 0].max(axis=1) >= -0.5) & (tri[..., 0].min(axis=1) < width - 0.5)
        ok &= (tri[..., 1].max(axis=1) >= -0.5) & (tri[..., 1].min(axis=1) < height - 0.5)
        ok &= np.abs(tri).max(axis=(1, 2)) < 1e5
        fixed = np.round(tri[ok] * (1 << SUBPIXEL)).astype(np.int32)
        image = out[n]
        for t in fixed:
            fill(image, t, 1, line, SUBPIXEL)
    return out.astype(bool)


def signed_distance(mask: ArrayLike) -> NDArray[np.float32]:
    """The signed distance (pixels) of every pixel centre from a mask's boundary: positive outside,
    negative inside, zero halfway between an inside and an outside pixel (Euclidean,
    ``cv2.distanceTransform``'s precise mask). A mask without any pixel set (or all set) gives
    +inf (or -inf) everywhere."""
    m = np.asarray(mask).astype(bool)
    if not m.any():
        return np.full(m.shape, np.inf, np.float32)
    if m.all():
        return np.full(m.shape, -np.inf, np.float32)
    inside = cv2.distanceTransform(m.astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    outside = cv2.distanceTransform((~m).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return np.where(m, 0.5 - inside, outside - 0.5).astype(np.float32)


@overload
def bilinear(field: NDArray[np.floating], uv: NDArray[np.float64], gradient: Literal[False] = False,
             views: NDArray[np.intp] | None = None) -> NDArray[np.float64]: ...


@overload
def bilinear(field: NDArray[np.floating], uv: NDArray[np.float64], gradient: Literal[True],
             views: NDArray[np.intp] | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...


def bilinear(field: NDArray[np.floating], uv: NDArray[np.float64], gradient: bool = False,
             views: NDArray[np.intp] | None = None) -> NDArray[np.float64] | tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``field`` (H, W) read at sub-pixel points ``uv`` (M, 2: column, row; pixel centres at
    integers), clamped to the image; with ``gradient`` also its derivative (M, 2) along u and v
    (of the bilinear surface: the cell's own slope). ``field`` (N, H, W) with ``views`` (M,): each
    point reads its view's field (every view's points at once)."""
    h, w = field.shape[-2:]
    u = np.clip(uv[:, 0], 0.0, w - 1.0 - 1e-9)
    v = np.clip(uv[:, 1], 0.0, h - 1.0 - 1e-9)
    i0, j0 = np.floor(v).astype(np.intp), np.floor(u).astype(np.intp)
    fu, fv = u - j0, v - i0
    if views is not None:  # one flat index into the stacked fields
        field = field.reshape(-1, w)
        i0 = i0 + np.asarray(views, dtype=np.intp) * h
    f00, f01 = field[i0, j0], field[i0, j0 + 1]
    f10, f11 = field[i0 + 1, j0], field[i0 + 1, j0 + 1]
    value = (f00 * (1 - fu) + f01 * fu) * (1 - fv) + (f10 * (1 - fu) + f11 * fu) * fv
    if not gradient:
        return value.astype(float)
    du = (f01 - f00) * (1 - fv) + (f11 - f10) * fv
    dv = (f10 - f00) * (1 - fu) + (f11 - f01) * fu
    return value.astype(float), np.stack([du, dv], axis=1).astype(float)


def outline(mask: ArrayLike) -> NDArray[np.bool_]:
    """A mask's boundary pixels (set pixels with an unset 4-neighbour; the image's own border does
    not count as a boundary)."""
    m = np.asarray(mask).astype(np.uint8)
    eroded = cv2.erode(m, np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8), borderType=cv2.BORDER_REPLICATE)
    return (m > 0) & (eroded == 0)


def iou(a: ArrayLike, b: ArrayLike) -> float:
    """The intersection over union of two masks (0 when both are empty)."""
    a, b = np.asarray(a, bool), np.asarray(b, bool)
    union = int(np.count_nonzero(a | b))
    return float(np.count_nonzero(a & b) / union) if union else 0.0
