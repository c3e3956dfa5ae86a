"""Organized point clouds of depth cameras: reading, checking, and 3D points of image features.

A depth camera (RGB-D, structured light) gives, per view, an organized cloud: one 3D point per
pixel of its intensity image, in that image's optical frame, NaN (or 0) where there is no depth.

Functions
---------
read_cloud
    An organized cloud from a .npy (H x W x 3), .ply or .pcd file, in metres.
check_cloud
    A cloud's shape against its image, NaNs, and its unit (a cloud in mm given as m).
cloud_pinhole
    The pinhole an organized cloud is registered to (fx, fy, cx, cy), from the cloud alone.
check_frame
    Whether a cloud is in the frame of the image whose intrinsics are given (depth vs colour frame).
lift_points
    Image points' 3D points from an organized cloud (bilinear, refusing depth edges and holes).
plane_points
    A flat target's points where their rays meet its plane, fitted to the cloud (noise averaged).
board_pose
    A board's pose from its lifted corners (a weighted rigid fit) and its flatness.
depth_sigma
    The depth noise model: growing with the square of the distance.
"""

from __future__ import annotations

import importlib
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..._shared.lazy import lazy_module
from ..._shared.text import cut, shown
from ...errors import InputMismatchError, SessionError, UnusableViewError
from ...geometry.se3 import make_transform
from ..camera.pnp import project_points

cv2 = lazy_module("cv2")

__all__ = ["plane_points", "read_cloud", "read_points", "check_cloud", "cloud_pinhole", "check_frame", "lift_points",
           "board_pose", "depth_sigma", "MAX_DEPTH_M", "EDGE_JUMP", "FRAME_TOLERANCE_PX", "CLOUD_SUFFIXES"]

#: A depth beyond this many metres is no depth camera's working range: a cloud whose median depth
#: is larger is taken to be in millimetres.
MAX_DEPTH_M = 20.0
#: Neighbouring pixels whose depths differ by more than this share of the depth straddle an edge
#: (or a flying pixel): a corner interpolated between them is not lifted.
EDGE_JUMP = 0.01


def depth_sigma(z: NDArray[np.float64], at_1m: float = 5e-4, floor: float = 1e-4) -> NDArray[np.float64]:
    """A depth camera's depth noise (m) at depth ``z`` (m): ``floor + at_1m z^2`` (triangulation's
    error grows with the square of the distance); the weights of the 3D residuals."""
    return floor + at_1m * np.square(z)


def check_cloud(cloud: NDArray, image_size: tuple[int, int] | None = None, where: str = "cloud") -> NDArray[np.float64]:
    """``cloud`` as an (H, W, 3) float array in metres, or :class:`InputMismatchError` naming ``where``.

    Refused: another shape, or another size than the intensity image's ``image_size`` (width,
    height); no finite point; a median depth beyond :data:`MAX_DEPTH_M` (a cloud in mm read as m);
    most depths negative (a cloud in a frame whose z does not point into the scene).
    """
    cloud = np.asarray(cloud, dtype=float)
    if cloud.ndim != 3 or cloud.shape[2] != 3:
        raise InputMismatchError(f"{where}: an organized cloud is an H x W x 3 array (x, y, z per pixel); got shape "
                                 f"{cloud.shape}")
    if image_size is not None and (cloud.shape[1], cloud.shape[0]) != tuple(image_size):
        raise InputMismatchError(f"{where}: the cloud is {cloud.shape[1]}x{cloud.shape[0]} and its image "
                                 f"{image_size[0]}x{image_size[1]}: give the cloud registered to the image (one point per "
                                 "pixel of the image the target is detected in, e.g. the depth aligned to colour)")
    z = cloud[..., 2]
    finite = np.isfinite(cloud).all(axis=2) & (z != 0)
    if not finite.any():
        raise InputMismatchError(f"{where}: no point has a depth (all NaN or zero): an empty capture, or the depth "
                                 "stream was not enabled")
    median = float(np.median(z[finite]))
    if median > MAX_DEPTH_M:
        raise InputMismatchError(f"{where}: median depth {median:g} m: the cloud looks like millimetres; give it in "
                                 "metres (divide by 1000) or say its unit")
    if median < 0:
        raise InputMismatchError(f"{where}: median depth {median:g} m is negative: the cloud is not in the camera's "
                                 "optical frame (z forward); give it in the frame of the image it is registered to")
    return cloud


def lift_points(cloud: NDArray[np.float64], image_points: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """The 3D points of ``image_points`` (M, 2; pixels, subpixel) in an organized ``cloud``
    (:func:`check_cloud`): bilinear in the four pixels around each, and ``valid`` False where one
    of them has no depth or their depths differ by more than :data:`EDGE_JUMP` of it (an edge or a
    flying pixel, where interpolating would invent a point between two surfaces)."""
    h, w = cloud.shape[:2]
    uv = np.asarray(image_points, dtype=float).reshape(-1, 2)
    u0 = np.floor(uv[:, 0]).astype(int)
    v0 = np.floor(uv[:, 1]).astype(int)
    inside = (u0 >= 0) & (v0 >= 0) & (u0 + 1 < w) & (v0 + 1 < h)
    u0, v0 = np.clip(u0, 0, w - 2), np.clip(v0, 0, h - 2)
    fu, fv = (uv[:, 0] - u0)[:, None], (uv[:, 1] - v0)[:, None]
    corners = np.stack([cloud[v0, u0], cloud[v0, u0 + 1], cloud[v0 + 1, u0], cloud[v0 + 1, u0 + 1]], axis=1)
    z = corners[..., 2]
    with np.errstate(invalid="ignore"):
        ok = inside & np.isfinite(corners).all(axis=(1, 2)) & (z > 0).all(axis=1)
        ok &= (np.nanmax(z, axis=1) - np.nanmin(z, axis=1)) <= EDGE_JUMP * np.nanmin(np.abs(z), axis=1)
    points = ((1 - fu) * (1 - fv) * corners[:, 0] + fu * (1 - fv) * corners[:, 1]
              + (1 - fu) * fv * corners[:, 2] + fu * fv * corners[:, 3])
    return np.where(ok[:, None], points, np.nan), ok


def _directions(cloud: NDArray[np.float64], image_points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit rays (M, 3) of ``image_points`` from the cloud itself: a point's direction does not
    depend on its depth (noise along the ray, flying pixels), so the four pixels around each give
    it bilinearly, lens distortion included; where one of them has no depth, the cloud's pinhole."""
    h, w = cloud.shape[:2]
    uv = np.asarray(image_points, dtype=float).reshape(-1, 2)
    u0 = np.clip(np.floor(uv[:, 0]).astype(int), 0, w - 2)
    v0 = np.clip(np.floor(uv[:, 1]).astype(int), 0, h - 2)
    fu, fv = (uv[:, 0] - u0)[:, None], (uv[:, 1] - v0)[:, None]
    four = np.stack([cloud[v0, u0], cloud[v0, u0 + 1], cloud[v0 + 1, u0], cloud[v0 + 1, u0 + 1]], axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        four = four / np.linalg.norm(four, axis=2, keepdims=True)
    d = ((1 - fu) * (1 - fv) * four[:, 0] + fu * (1 - fv) * four[:, 1] + (1 - fu) * fv * four[:, 2]
         + fu * fv * four[:, 3])
    bad = ~np.isfinite(d).all(axis=1)
    if bad.any():
        (fx, fy, cx, cy), _ = cloud_pinhole(cloud)
        d[bad] = np.c_[(uv[bad, 0] - cx) / fx, (uv[bad, 1] - cy) / fy, np.ones(int(bad.sum()))]
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def plane_points(cloud: NDArray[np.float64], image_points: NDArray[np.float64], where: str = "cloud"
                 ) -> tuple[NDArray[np.float64], float, int]:
    """The 3D points of a flat target's ``image_points``: where their rays meet the target's plane,
    fitted to every point of the cloud inside the points' outline (thousands of points against
    four per corner for :func:`lift_points`: the depth noise averages out).

    The plane is fitted by weighted total least squares (weights from :func:`depth_sigma`), points
    beyond 3.5 robust std of it left out and the fit repeated. Returns the points (M, 3), the RMS
    distance of the cloud from the plane (m) and the number of points fitted.
    """
    h, w = cloud.shape[:2]
    uv = np.asarray(image_points, dtype=np.float64).reshape(-1, 2)
    hull = cv2.convexHull(uv.astype(np.float32)).reshape(-1, 2)
    mask = np.zeros((h, w), dtype=np.uint8)
    cv2.fillConvexPoly(mask, np.rint(hull).astype(np.int32), 1)
    inside = mask.astype(bool) & np.isfinite(cloud).all(axis=2) & (cloud[..., 2] > 0)
    q = cloud[inside]
    if len(q) < 20:
        raise InputMismatchError(f"{where}: only {len(q)} points with depth on the target: the cloud has no depth there")
    keep = np.ones(len(q), dtype=bool)
    for _ in range(3):
        wgt = 1.0 / np.square(depth_sigma(q[keep, 2]))
        centre = (wgt @ q[keep]) / wgt.sum()
        normal = np.linalg.svd((q[keep] - centre) * np.sqrt(wgt)[:, None], full_matrices=False)[2][2]
        dist = (q - centre) @ normal
        scale = 1.4826 * np.median(np.abs(dist[keep] / depth_sigma(q[keep, 2])))
        keep = np.abs(dist) <= np.maximum(3.5 * scale * depth_sigma(q[:, 2]), 1e-9)
        if keep.sum() < 20:
            raise InputMismatchError(f"{where}: the points on the target do not lie on a plane (fewer than 20 within "
                                     "3.5 std of the best one): is the target flat and in view?")
    rays = _directions(cloud, uv)
    with np.errstate(divide="ignore"):
        t = (centre @ normal) / (rays @ normal)
    rms = float(np.sqrt(np.mean(dist[keep] ** 2)))
    return rays * t[:, None], rms, int(keep.sum())


def board_pose(object_points: NDArray[np.float64], points: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """``target2cam`` from a board's points in its own frame and their lifted 3D points (rows with
    NaN left out): the rigid fit weighted by the depth noise (:func:`depth_sigma`), and the RMS
    distance (m) of the lifted points from their best plane (a board that is not flat, or depth
    that is not, shows there)."""
    keep = np.isfinite(points).all(axis=1)
    P, Q = np.asarray(object_points, float)[keep], np.asarray(points, float)[keep]
    if len(P) < 4:
        raise InputMismatchError(f"only {len(P)} corners have a depth: at least 4 are needed for the board's pose")
    wgt = 1.0 / np.square(depth_sigma(Q[:, 2]))
    wgt = wgt / wgt.sum()
    cp, cq = wgt @ P, wgt @ Q
    H = ((P - cp) * wgt[:, None]).T @ (Q - cq)
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    normal = np.linalg.svd(Q - Q.mean(axis=0))[2][2]
    flatness = float(np.sqrt(np.mean(np.square((Q - Q.mean(axis=0)) @ normal))))
    return make_transform(R, cq - R @ cp), flatness


#: A cloud whose points project with the image's intrinsics more than this many pixels (RMS) from
#: their own pixels is not in that image's frame.
FRAME_TOLERANCE_PX = 2.0
CLOUD_SUFFIXES = (".npy", ".ply", ".pcd")


def _optional(module: str, extra: str, path: Path):
    try:
        return importlib.import_module(module)
    except ImportError:
        raise SessionError(f"{path}: reading {path.suffix} clouds needs {module}: pip install 'handeye[{extra}]' "
                           "(or save the cloud as a .npy of H x W x 3)") from None


def _load(path: Path) -> NDArray:
    """The array a cloud file holds (organized (H, W, 3) or (N, 3)), in its own unit; SessionError naming the file."""
    if not path.is_file():
        raise SessionError(f"{path}: no such cloud file")
    suffix = path.suffix.lower()
    try:
        if suffix == ".npy":
            cloud = np.load(path, allow_pickle=False)
        elif suffix == ".ply":
            vertex = _optional("plyfile", "depth", path).PlyData.read(str(path))["vertex"]
            cloud = np.stack([np.asarray(vertex[c], dtype=float) for c in "xyz"], axis=-1)
        elif suffix == ".pcd":
            pc = _optional("pypcd4", "depth", path).PointCloud.from_path(path)
            cloud = np.asarray(pc.numpy(("x", "y", "z")), dtype=float)
            if pc.metadata.height > 1:
                cloud = cloud.reshape(pc.metadata.height, pc.metadata.width, 3)
        else:
            raise SessionError(f"{path}: a cloud is a {', '.join(CLOUD_SUFFIXES)} file")
    except SessionError:
        raise
    except Exception as exc:  # a damaged file: whatever the reader raises, say which file
        raise UnusableViewError(f"{path}: cannot read the cloud ({type(exc).__name__}: {cut(str(exc), 200)})") from None
    return cloud


def read_cloud(path: str | Path, image_size: tuple[int, int] | None = None, unit: str = "m") -> NDArray[np.float64]:
    """An organized cloud (H, W, 3), metres, NaN where there is no depth, from ``path``.

    Parameters
    ----------
    path : str or Path
        ``.npy`` (an H x W x 3 array), ``.ply`` (its vertex x, y, z, one per pixel in row-major order;
        read with plyfile) or ``.pcd`` (PCL's format, organized: HEIGHT > 1, or one point per pixel;
        read with pypcd4). Points at (0, 0, 0) are missing depth, as most cameras write it.
    image_size : (width, height), optional
        The registered intensity image's size: an unorganized PLY/PCD of that many points is
        reshaped to it, and any other size refused (:func:`check_cloud`).
    unit : {'m', 'mm'}
        The unit the file is in.
    """
    path = Path(path)
    cloud = _load(path)
    if cloud.ndim == 2 and cloud.shape[1] == 3 and image_size is not None:
        if len(cloud) != image_size[0] * image_size[1]:
            raise InputMismatchError(f"{path}: {len(cloud)} points, and its image is {image_size[0]}x{image_size[1]} "
                                     f"= {image_size[0] * image_size[1]} pixels: give the organized cloud (one point "
                                     "per pixel, NaN or 0 where there is no depth), registered to the image")
        cloud = cloud.reshape(image_size[1], image_size[0], 3)
    if unit not in ("m", "mm"):
        raise SessionError(f"{path}: the cloud's unit is m or mm, not {shown(unit)}")
    cloud = np.array(cloud, dtype=float) * (1e-3 if unit == "mm" else 1.0)
    if cloud.ndim != 3 or cloud.shape[2] != 3:  # no cloud at all: the view's file is unusable, not the session
        raise UnusableViewError(f"{path}: an organized cloud is an H x W x 3 array (x, y, z per pixel); got shape "
                                f"{cloud.shape}")
    cloud[(cloud == 0).all(axis=2)] = np.nan
    if not (np.isfinite(cloud).all(axis=2) & (cloud[..., 2] != 0)).any():
        raise UnusableViewError(f"{path}: no point has a depth (all NaN or zero): an empty capture, or the depth "
                                "stream was not enabled")
    return check_cloud(cloud, image_size, where=str(path))


def read_points(path: str | Path, unit: str = "m") -> NDArray[np.float64]:
    """The points (N, 3, metres) of a cloud file, organized or not (a scan cropped to a part, as 3D
    scanners export it, has no image grid): ``.npy`` (H x W x 3 or N x 3), ``.ply`` or ``.pcd``, the
    points without depth (NaN, or all three coordinates 0) left out. Nothing is checked of the depths
    (a template cloud of a shape has none); :class:`SessionError` naming a file that cannot be read."""
    path = Path(path)
    if unit not in ("m", "mm"):
        raise SessionError(f"{path}: the cloud's unit is m or mm, not {shown(unit)}")
    cloud = np.asarray(_load(path), dtype=float)
    if cloud.shape[-1:] != (3,) or cloud.ndim not in (2, 3):
        raise UnusableViewError(f"{path}: a cloud is an H x W x 3 or N x 3 array of points, got shape {cloud.shape}")
    p = cloud.reshape(-1, 3) * (1e-3 if unit == "mm" else 1.0)
    return p[np.isfinite(p).all(axis=1) & (p != 0).any(axis=1)]


def cloud_pinhole(cloud: NDArray[np.float64], sample: int = 20000,
                  rng: np.random.Generator | int | None = 0) -> tuple[NDArray[np.float64], float]:
    """The pinhole ``(fx, fy, cx, cy)`` an organized cloud is registered to, and the RMS pixel
    residual of that fit: each point projects onto its own pixel, ``u = fx x/z + cx``. Noise along
    the rays (depth noise, flying pixels) does not move a projection, so the residual is ~0 for a
    cloud that is what it says it is."""
    h, w = cloud.shape[:2]
    v, u = np.nonzero(np.isfinite(cloud).all(axis=2) & (cloud[..., 2] > 0))
    if len(u) < 10:
        raise InputMismatchError("too few points with depth to tell the cloud's pinhole")
    pick = np.random.default_rng(rng).choice(len(u), min(sample, len(u)), replace=False)
    u, v = u[pick].astype(float), v[pick].astype(float)
    p = cloud[v.astype(int), u.astype(int)]
    a, b = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
    (fx, cx), res_u = np.linalg.lstsq(np.c_[a, np.ones_like(a)], u, rcond=None)[:2]
    (fy, cy), res_v = np.linalg.lstsq(np.c_[b, np.ones_like(b)], v, rcond=None)[:2]
    rms = float(np.sqrt((np.sum(res_u) + np.sum(res_v)) / (2 * len(u)))) if len(res_u) and len(res_v) else 0.0
    return np.array([fx, fy, cx, cy]), rms


def check_frame(cloud: NDArray[np.float64], K: NDArray[np.float64], dist: NDArray[np.float64] | None = None,
                where: str = "cloud") -> float:
    """The RMS distance (px) between where the cloud's points project with the image's intrinsics
    ``K`` and their own pixels; :class:`InputMismatchError` beyond :data:`FRAME_TOLERANCE_PX`,
    naming what the cloud's own pinhole says (the depth sensor's frame, not the colour image's)."""
    K = np.asarray(K, dtype=float)
    h, w = cloud.shape[:2]
    v, u = np.mgrid[0:h, 0:w]
    ok = np.isfinite(cloud).all(axis=2) & (cloud[..., 2] > 0)
    ok &= np.random.default_rng(0).random(ok.shape) < min(1.0, 50000 / max(int(ok.sum()), 1))  # enough to tell
    uv = project_points(np.eye(4), cloud[ok], K, np.zeros(5) if dist is None else np.asarray(dist, float))
    du, dv = uv[:, 0] - u[ok], uv[:, 1] - v[ok]
    rms = float(np.sqrt(np.mean(du**2 + dv**2)))
    if rms > FRAME_TOLERANCE_PX:
        own, _ = cloud_pinhole(cloud)
        raise InputMismatchError(
            f"{where}: its points project {rms:.1f} px (RMS, {np.median(du):+.1f} px in u, {np.median(dv):+.1f} in v) "
            f"from their pixels with the image's intrinsics (fx {K[0, 0]:.1f}, cx {K[0, 2]:.1f}); the cloud's own pinhole "
            f"is fx {own[0]:.1f}, fy {own[1]:.1f}, cx {own[2]:.1f}, cy {own[3]:.1f}: the cloud is in another frame than "
            "the image (the depth sensor's, not the colour camera's?); give the depth aligned to the colour image "
            "(e.g. RealSense align_to colour, Zivid's point cloud with its colour image), or the intrinsics of the "
            "image the cloud is registered to")
    return rms
