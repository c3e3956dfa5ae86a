"""Hand-eye calibration from a depth camera's organized point clouds (thesis §6.1: other camera types).

A depth camera (RGB-D, structured light) gives, per view, an organized cloud: one 3D point per
pixel of its intensity image, in that image's camera frame, NaN where there is no depth. The
board's corners are detected in the intensity image as for any camera and *lifted* to 3D from the
cloud at their subpixel positions (no PnP): the target's pose then comes from 3D points, which
fixes what PnP is weakest at, the distance along the optical axis.

Depth cameras are off in their own ways: a depth scale (a factor near 1: the projector-camera
baseline or the depth unit slightly wrong) and a depth bias (an offset along the rays). Both are
estimated with X and Z from the 3D residuals (metres):

    q_measured = (s + b / z) * p,    p = target2cam(X, Z, flange2base) @ P_target

(``p`` scaled along its own ray so that its depth becomes ``s z + b``), each residual weighted by the
depth noise at its distance (growing with the square of the distance, as triangulation's does).

Functions
---------
check_cloud
    A cloud's shape against its image, NaNs, and its unit (a cloud in mm given as m).
lift_points
    Corners' 3D points from an organized cloud (bilinear, refusing depth edges and holes).
board_pose
    A board's pose from its lifted corners (a weighted rigid fit) and its flatness.
calibrate_depth
    X, Z, the depth scale and bias, with their std, from lifted corners and robot poses.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from .calibration import calibrate_poses
from .errors import InputMismatchError
from .geometry.se3 import make_transform, perturb
from .setups import check_setup, predicted_target2cam

__all__ = ["DepthCalibration", "check_cloud", "lift_points", "board_pose", "calibrate_depth", "depth_sigma",
           "MAX_DEPTH_M", "EDGE_JUMP"]

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


@dataclass(frozen=True)
class DepthCalibration:
    """X and Z from 3D points, with the depth camera's scale and bias."""

    setup: str
    X: NDArray[np.float64]
    Z: NDArray[np.float64]
    std: NDArray[np.float64]  #: of X: rotation (deg, about the axes of X's reference frame), translation (mm)
    depth_scale: float  #: measured depth = depth_scale * true depth + depth_bias
    depth_scale_std: float
    depth_bias: float  #: metres
    depth_bias_std: float
    rms_mm: float  #: the depth noise (std along the rays) at the median depth, from the residuals, mm
    n_points: int
    notes: list[str] = field(default_factory=list)


#: Noise across the rays, per metre of depth, to start from (0.2 px at a focal length of ~700 px).
LATERAL = 3e-4


def _ray_frames(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """(M, 3, 3): rows along each point's ray and two unit directions across it."""
    along = points / np.linalg.norm(points, axis=1, keepdims=True)
    helper = np.where(np.abs(along[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    first = np.cross(along, helper)
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    return np.stack([along, first, np.cross(along, first)], axis=1)


def _model(x: NDArray[np.float64], X0, Z0, F, setup, obj, owner, fit_depth: bool):
    """Predicted measured points (M, 3) for the unknowns ``x`` (X's and Z's steps, scale - 1, bias)."""
    X = perturb(X0, x[0:3], x[3:6])
    Z = perturb(Z0, x[6:9], x[9:12])
    T = predicted_target2cam(X, Z, F, setup)
    p = np.einsum("mij,mj->mi", T[owner, :3, :3], obj) + T[owner, :3, 3]
    if not fit_depth:
        return p
    return p * (1.0 + x[12] + x[13] / p[:, 2])[:, None]


def _jackknife(residuals, x: NDArray[np.float64], owner: NDArray[np.intp], n_views: int,
               noise: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per unknown, the leave-one-view-out jackknife std: what the noise model misses (the corner
    noise's share along tilted boards, errors that differ from view to view) widens X's std."""
    if n_views < 4:
        return np.zeros_like(x)
    rows = np.repeat(owner, 3)
    fits = []
    for k in range(n_views):
        keep = rows != k
        fit = least_squares(lambda y: residuals(y, noise)[keep], x, method="lm",
                            x_scale=np.full(len(x), 1e-3))
        fits.append(fit.x)
    fits = np.array(fits)
    return np.sqrt((n_views - 1) / n_views * np.sum(np.square(fits - fits.mean(axis=0)), axis=0))


def calibrate_depth(flange2base: NDArray[np.float64], object_points: list[NDArray[np.float64]],
                    points: list[NDArray[np.float64]], setup: str = "eye_in_hand",
                    fit_depth: bool = True) -> DepthCalibration:
    """X and Z from robot poses and the board's corners lifted to 3D, with the depth scale and bias.

    Parameters
    ----------
    flange2base : (N, 4, 4)
    object_points : list of N arrays (M_i, 3)
        The corners in the target's frame (metres).
    points : list of N arrays (M_i, 3)
        The same corners measured in the camera frame (:func:`lift_points`; NaN rows: no depth).
    setup : {'eye_in_hand', 'eye_to_hand'}
    fit_depth : bool
        Estimate the depth scale and bias (else taken as 1 and 0).

    Returns
    -------
    DepthCalibration
        Its notes say when the depth scale or bias differ from 1 / 0 beyond 3 std.
    """
    check_setup(setup)
    F = np.asarray(flange2base, dtype=float)
    if not (len(F) == len(object_points) == len(points)):
        raise InputMismatchError(f"{len(F)} robot poses, {len(object_points)} point sets and {len(points)} lifted sets: "
                                 "give one of each per view")
    keep = [np.isfinite(q).all(axis=1) for q in points]
    poses = [board_pose(o, q) for o, q in zip(object_points, points)]
    start = calibrate_poses(F, np.array([T for T, _ in poses]), setup, refine="pose", progress=False)
    obj = np.concatenate([np.asarray(o, float)[k] for o, k in zip(object_points, keep)])
    meas = np.concatenate([np.asarray(q, float)[k] for q, k in zip(points, keep)])
    owner = np.repeat(np.arange(len(F)), [int(k.sum()) for k in keep])
    z = meas[:, 2]
    basis = _ray_frames(meas)  # per point: along its ray, and two directions across it
    # the noise along the rays (depth; and a corner found off its place moves along the board, so
    # along the ray too, by tan(ray, normal)) and across them (the corner's pixel noise, times the
    # depth) differ; each is scaled to the data in a second pass
    normals = np.array([T[:3, 2] for T, _ in poses])[owner]
    cos = np.clip(np.abs(np.einsum("mi,mi->m", basis[:, 0], normals)), 0.2, 1.0)
    along = np.sqrt(depth_sigma(z) ** 2 + (LATERAL * z) ** 2 * (1.0 / cos**2 - 1.0))
    noise = np.stack([along, LATERAL * z, LATERAL * z], axis=1)
    n = 14 if fit_depth else 12
    x = np.zeros(n)
    for _ in range(2):
        def residuals(x, noise=noise):
            r = meas - _model(x, start.X, start.Z, F, setup, obj, owner, fit_depth)
            return (np.einsum("mij,mj->mi", basis, r) / noise).ravel()

        res = least_squares(residuals, x, method="lm", x_scale=np.full(n, 1e-3))
        x = res.x
        w = res.fun.reshape(-1, 3)
        dof = max(res.fun.size - n, 1) / res.fun.size
        along, across = np.sqrt(np.mean(w[:, 0] ** 2) / dof), np.sqrt(np.mean(w[:, 1:] ** 2) / dof)
        noise = noise * np.array([along, across, across])
    s2 = float(res.fun @ res.fun) / max(res.fun.size - n, 1)  # ~1 once the noise is scaled
    cov = s2 * np.linalg.pinv(res.jac.T @ res.jac)
    std = np.maximum(np.sqrt(np.clip(np.diag(cov), 0.0, None)), _jackknife(residuals, x, owner, len(F), noise))
    sigma = noise[:, :1]
    X = perturb(start.X, res.x[0:3], res.x[3:6])
    Z = perturb(start.Z, res.x[6:9], res.x[9:12])
    scale, bias = (1.0 + res.x[12], res.x[13]) if fit_depth else (1.0, 0.0)
    scale_std, bias_std = (std[12], std[13]) if fit_depth else (0.0, 0.0)
    notes = []
    if fit_depth and abs(scale - 1.0) > 3 * scale_std:
        notes.append(f"depth scale {scale:.5f} +- {scale_std:.5f}: the camera's depths are {1e2 * (scale - 1):+.3f}% off "
                     "(beyond 3 std); correct the depth unit or the camera's calibration, or keep this factor")
    if fit_depth and abs(bias) > 3 * bias_std:
        notes.append(f"depth bias {1e3 * bias:+.2f} +- {1e3 * bias_std:.2f} mm along the rays (beyond 3 std)")
    rms = float(np.median(sigma)) * 1e3
    return DepthCalibration(setup, X, Z, np.r_[np.degrees(std[0:3]), 1e3 * std[3:6]], float(scale), float(scale_std),
                            float(bias), float(bias_std), rms, len(meas), notes)
