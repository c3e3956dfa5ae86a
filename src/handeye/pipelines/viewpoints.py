"""A camera's candidate viewpoints around a target and what each tells of X: what the camera's
planner (:mod:`handeye.planning.poses`), a rig's (:mod:`handeye.pipelines.rig.plan`), ``handeye
acquire`` and ``handeye live`` share.

A viewpoint is a camera pose about the target (``cam2target``); one the camera sees the whole target
from (:func:`visible_mask`) becomes a robot pose through a rough X and Z. Each pose's information
(:func:`reprojection_information`: ``J^T J`` of its corners' pixels over X's and Z's increments) adds
up over a capture; :func:`choose_views` picks the set that leaves X's predicted error smallest
(A-optimal), :func:`choose_next` the next one, and :func:`reported_std` adds the robot's accuracy as
``calibrate`` does.

Examples
--------
>>> import numpy as np
>>> from handeye.sensors.camera.targets.chessboard import Chessboard
>>> K = np.array([[800.0, 0, 320], [0, 800, 240], [0, 0, 1]])
>>> views = candidate_views(Chessboard(9, 6, 0.03).object_points(), K, (640, 480), standoff=0.6)
>>> views.shape[1:], bool(len(views) > 100)
((4, 4), True)
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import HandEyeError
from ..estimation.uncertainty import robot_accuracy_cov
from ..frames.metrics import std_deg_mm
from ..frames.setups import robot_world_A_inv
from ..geometry.se3 import invert, skew
from ..sensors.camera.pnp import project_points
from ..simulate import look_at

__all__ = ["TILTS_DEG", "AZIMUTHS", "ROLLS", "DISTANCE_FACTORS", "visible_mask", "reprojection_information", "predicted_cov",
           "choose_views", "choose_next", "viewpoints_around", "candidate_views", "reported_std"]

TILTS_DEG = (0.0, 10.0, 20.0, 30.0, 37.5, 45.0, 52.5, 60.0)
AZIMUTHS = 12
ROLLS = 8
DISTANCE_FACTORS = (0.8, 1.0, 1.25)


def visible_mask(target2cam: NDArray[np.float64], object_points: NDArray[np.float64], K: NDArray[np.float64],
                 dist: NDArray[np.float64], image_size: tuple[int, int], margin_px: float = 0.0) -> NDArray[np.bool_]:
    """Per pose, whether every target point is in front of the camera and ``margin_px`` inside the image."""
    w, h = image_size
    obj = np.ascontiguousarray(object_points, dtype=np.float64)
    out = np.zeros(len(target2cam), dtype=bool)
    for i, T in enumerate(target2cam):
        depth = obj @ T[:3, :3].T[:, 2] + T[2, 3]
        if np.any(depth <= 1e-3):
            continue
        px = project_points(T, obj, K, dist)
        out[i] = bool(np.all(px >= margin_px) and np.all(px[:, 0] <= w - 1 - margin_px)
                      and np.all(px[:, 1] <= h - 1 - margin_px))
    return out


def reprojection_information(flange2base: NDArray[np.float64], X: NDArray[np.float64], Z: NDArray[np.float64],
                             setup: str, object_points: NDArray[np.float64], K: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per pose, ``J^T J`` (N, 12, 12) of the pixel residuals of every target point with respect to
    the 12 unknowns of :func:`handeye.estimation.refinement.refine_reprojection` (left rotation-vector
    increments and translation increments of X, then of Z), for unit pixel noise (pinhole model:
    distortion changes the information little and is left out)."""
    robot = robot_world_A_inv(flange2base, setup)  # W: base->flange or flange->base
    R_X, t_X, R_Z, t_Z = X[:3, :3], X[:3, 3], Z[:3, :3], Z[:3, 3]
    p = np.asarray(object_points, dtype=float)  # (M, 3)
    Rp = p @ R_Z.T  # (M, 3)  R_Z p
    q = Rp + t_Z
    R_W, t_W = robot[:, :3, :3], robot[:, :3, 3]  # (N, 3, 3), (N, 3)
    s = np.einsum("nij,mj->nmi", R_W, q) + t_W[:, None, :]  # (N, M, 3) point in the X frame's parent
    pc = np.einsum("ji,nmj->nmi", R_X, s - t_X)  # R_X^T (s - t_X)
    fx, fy = K[0, 0], K[1, 1]
    x, y, z = pc[..., 0], pc[..., 1], pc[..., 2]
    Jp = np.zeros(pc.shape[:2] + (2, 3))
    Jp[..., 0, 0] = fx / z
    Jp[..., 0, 2] = -fx * x / z**2
    Jp[..., 1, 1] = fy / z
    Jp[..., 1, 2] = -fy * y / z**2
    RXt = R_X.T
    # d pc / d(omega_X) = R_X^T [s - t_X]x ; d pc / d(v_X) = -R_X^T
    dX_rot = np.einsum("ij,nmjk->nmik", RXt, skew(s - t_X))
    dX_tra = np.broadcast_to(-RXt, pc.shape[:2] + (3, 3))
    # d pc / d(omega_Z) = -R_X^T R_W [R_Z p]x ; d pc / d(v_Z) = R_X^T R_W
    RXW = np.einsum("ij,njk->nik", RXt, R_W)  # (N, 3, 3)
    dZ_rot = -np.einsum("nij,mjk->nmik", RXW, skew(Rp))
    dZ_tra = np.broadcast_to(RXW[:, None], pc.shape[:2] + (3, 3))
    D = np.concatenate([dX_rot, dX_tra, dZ_rot, dZ_tra], axis=3)  # (N, M, 3, 12)
    J = np.einsum("nmij,nmjk->nmik", Jp, D)  # (N, M, 2, 12)
    return np.einsum("nmai,nmaj->nij", J, J)


def predicted_cov(information: NDArray[np.float64], noise_px: float) -> NDArray[np.float64]:
    """Covariance (6, 6) of X from the summed information of the poses and the pixel noise."""
    return noise_px**2 * np.linalg.inv(information)[:6, :6]


def _criterion(info_inv: NDArray[np.float64], weight: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.einsum("...ii,i->...", info_inv[..., :6, :6], weight)


def choose_views(infos: NDArray[np.float64], n: int, weight: NDArray[np.float64], max_passes: int = 8,
                 prior: NDArray[np.float64] | None = None) -> list[int]:
    """A-optimal selection of ``n`` of the candidate informations: greedy, then exchanges; ``prior``
    (12, 12) holds what no pose can determine (a SCARA's vertical) fixed."""
    ridge = 1e-9 * float(np.mean(np.trace(infos, axis1=1, axis2=2))) * np.eye(infos.shape[-1])
    if prior is not None:
        ridge = ridge + prior
    chosen: list[int] = []
    total = ridge.copy()
    for _ in range(n):
        scores = _criterion(np.linalg.inv(total + infos), weight)
        scores[chosen] = np.inf
        k = int(np.argmin(scores))
        chosen.append(k)
        total = total + infos[k]
    best = float(_criterion(np.linalg.inv(total), weight))
    for _ in range(max_passes):
        improved = False
        for slot in range(n):
            rest = total - infos[chosen[slot]]
            scores = _criterion(np.linalg.inv(rest + infos), weight)
            scores[chosen] = np.inf
            k = int(np.argmin(scores))
            if scores[k] < best * (1 - 1e-9):
                chosen[slot], total, best, improved = k, rest + infos[k], float(scores[k]), True
        if not improved:
            break
    return chosen




def viewpoints_around(standoff: float, tilt_max_deg: float, centre: NDArray[np.float64]) -> NDArray[np.float64]:
    """Every viewpoint of the grid (``cam2target``, (C, 4, 4)): on the target's printed side within
    ``tilt_max_deg`` of its normal (:data:`TILTS_DEG`), :data:`AZIMUTHS` around it, :data:`ROLLS` rolls,
    at :data:`DISTANCE_FACTORS` times ``standoff`` from ``centre``, looking at it."""
    tilts = np.radians([t for t in TILTS_DEG if t <= tilt_max_deg + 1e-9])
    az = np.linspace(0, 2 * np.pi, AZIMUTHS, endpoint=False)
    rolls = np.linspace(-np.pi, np.pi, ROLLS, endpoint=False)
    T, A, Rl, D = np.meshgrid(tilts, az, rolls, DISTANCE_FACTORS, indexing="ij")
    keep = ~((T == 0) & (A > 0))  # at zero tilt every azimuth is the same view
    T, A, Rl, D = T[keep], A[keep], Rl[keep], D[keep]
    # the camera on the printed side of the target (target -z), as the renderer and detectors expect
    direction = np.stack([np.sin(T) * np.cos(A), np.sin(T) * np.sin(A), -np.cos(T)], axis=1)
    position = centre + direction * (standoff * D)[:, None]
    return look_at(position, np.broadcast_to(centre, position.shape), Rl + A)




def reported_std(std: NDArray[np.float64], cov: NDArray[np.float64], X: NDArray[np.float64],
                 accuracy: tuple[float, float] | None) -> NDArray[np.float64]:
    """The std calibrate reports (deg, mm): the pixels' covariance ``cov`` of X (its std ``std``, inf
    where undetermined) plus the robot's absolute accuracy, which X takes whole."""
    if accuracy is None:
        return std
    return np.where(np.isinf(std), np.inf, std_deg_mm(cov + robot_accuracy_cov(X, accuracy)))


def candidate_views(object_points: ArrayLike, K: ArrayLike, image_size: tuple[int, int], dist: ArrayLike | None = None,
                    standoff: float = 0.5, tilt_max_deg: float = 45.0, margin_px: float = 20.0) -> NDArray[np.float64]:
    """The candidate viewpoints of :func:`~handeye.planning.poses.plan_poses` that keep the whole target ``margin_px`` inside
    the image, as ``cam2target`` (C, 4, 4): they do not depend on X and Z, so a capture that learns
    X and Z as it goes turns them into robot poses anew (:func:`handeye.frames.setups.flange_poses`)."""
    obj = np.asarray(object_points, dtype=float).reshape(-1, 3)
    K = np.asarray(K, dtype=float)
    dist = np.zeros(5) if dist is None else np.asarray(dist, dtype=float).ravel()
    centre = 0.5 * (obj.min(axis=0) + obj.max(axis=0))
    cam2target = viewpoints_around(standoff, tilt_max_deg, centre)
    keep = visible_mask(invert(cam2target), obj, K, dist, image_size, margin_px)
    if not keep.any():
        raise HandEyeError(f"no candidate view keeps the whole target {margin_px:g} px inside the image at a standoff "
                           f"of {standoff:g} m; increase the standoff or use a smaller target")
    return cam2target[keep]


def choose_next(information: NDArray[np.float64], candidates: NDArray[np.float64], weight: NDArray[np.float64],
                exclude: NDArray[np.bool_] | None = None) -> int | None:
    """The candidate (index into ``candidates``, (C, 12, 12) informations) whose view, added to the
    views of ``information`` (12, 12), leaves the smallest predicted error of X (the A-optimal
    criterion of :func:`~handeye.planning.poses.plan_poses`, ``weight`` over X's six parameters); None when all are excluded."""
    ridge = 1e-9 * max(float(np.mean(np.trace(candidates, axis1=1, axis2=2))), 1e-12) * np.eye(12)
    scores = _criterion(np.linalg.inv(information + ridge + candidates), weight)
    if exclude is not None:
        scores = np.where(exclude, np.inf, scores)
    k = int(np.argmin(scores))
    return None if not np.isfinite(scores[k]) else k
