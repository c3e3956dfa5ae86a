"""A line-scan camera's pose from one scan of a planar target, in closed form (the fit's start).

During a scan the robot moves the camera (or the target) along a straight line at a steady speed.
Then (Gupta and Hartley's linear pushbroom camera) a target point ``P`` (x, y, 0 in the target
frame) crosses the view plane (``y = 0`` of the camera frame) at the time ``s = a . (x, y, 1)``,
affine in the point, and at the crossing its camera coordinates ``(x_c, 0, z_c)`` are affine in it
too: ``u = cx + f x_c / z_c``. With the camera's pose at ``s = 0`` (``target2cam``: ``R P + T``) and
its velocity ``V`` in its own frame, ``R P + T = (x_c, 0, z_c) + s V``: the rows of ``[r1 r2 T]`` are
``lambda b + V_x a``, ``V_y a`` and ``lambda c + V_z a``, where ``a``, and ``b``, ``c`` up to the scale
``lambda``, are linear least squares from the corners, and ``lambda`` and ``V`` follow from ``r1``,
``r2`` orthonormal and ``|V|`` the robot's speed.

One scan cannot tell the scene from its mirror image in the view plane with the motion reversed
(``V_y`` of either sign fits the same image): :func:`pushbroom_resection` returns both, and
:func:`resolve_mirrors` picks per scan the one that agrees with the robot, from the rotations between
scans (their angles and axes, as ``A X = X B`` has them) and the direction each scan moved.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ...errors import DegenerateMotionError
from ...geometry.se3 import make_transform

__all__ = ["pushbroom_resection", "resolve_mirrors"]

#: Pairs of scans whose flange turned less than this (rad) between them say nothing of the mirrors.
MIN_TURN = np.radians(1.0)


def pushbroom_resection(target_xy: NDArray[np.float64], u: NDArray[np.float64], s: NDArray[np.float64], focal: float,
                        cx: float, speed: float) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """The camera's pose at ``s = 0`` and its velocity from one scan (the module docstring).

    Parameters
    ----------
    target_xy : (n, 2) array
        The corners in the target's plane (m).
    u : (n,) array
        Their pixel along the line.
    s : (n,) array
        The time each was seen (s, relative to the scan's reference time).
    focal, cx : float
        The intrinsics along the line (px): nominal values serve.
    speed : float
        The robot's speed during the scan (m/s).

    Returns
    -------
    target2cam : (2, 4, 4) array
        The pose and its mirror.
    velocity : (2, 3) array
        The camera's velocity relative to the target in the camera frame (m/s), for each.
    rms : float
        How far the linear model leaves the corners (px along the line).

    Raises
    ------
    DegenerateMotionError
        Fewer than 6 corners, or corners that do not determine the pose (a target seen edge-on, a
        scan that did not move).
    """
    xy = np.asarray(target_xy, dtype=float)
    n = len(xy)
    if n < 6 or speed <= 0:
        raise DegenerateMotionError(f"a scan with {n} corners and speed {speed:g} m/s: a pose needs 6 corners or more "
                                    "and a robot that moves during the scan")
    m = np.c_[xy, np.ones(n)]
    a = np.linalg.lstsq(m, s, rcond=None)[0]
    xn = (np.asarray(u, float) - cx) / focal
    _, sv, Vt = np.linalg.svd(np.c_[-m, xn[:, None] * m], full_matrices=False)
    b, c = Vt[-1, :3], Vt[-1, 3:]
    if sv[-2] < 1e-9 * sv[0]:
        raise DegenerateMotionError("the scan's corners do not determine its pose (the target seen edge-on?)")

    def rows(v):
        lam, V = v[0], v[1:]
        return np.array([lam * b + V[0] * a, V[1] * a, lam * c + V[2] * a])  # rows of [r1 r2 T]

    def equations(v):
        M = rows(v)
        r1, r2 = M[:, 0], M[:, 1]
        return np.array([r1 @ r1 - 1.0, r2 @ r2 - 1.0, r1 @ r2, (v[1:] @ v[1:]) / speed**2 - 1.0])

    lam0 = 1.0 / np.sqrt(0.5 * (b[0] ** 2 + c[0] ** 2 + b[1] ** 2 + c[1] ** 2))
    lam0 *= np.sign(np.median(m @ c)) or 1.0  # in front of the camera: z_c = lambda c . m > 0
    best = min((least_squares(equations, np.r_[lam0, 0.0, sign * speed, 0.0], method="lm", xtol=1e-15, ftol=1e-15)
                for sign in (1.0, -1.0)), key=lambda r: r.cost)
    poses, velocities = [], []
    for flip in (1.0, -1.0):
        v = best.x * np.r_[1.0, 1.0, flip, 1.0]
        M = rows(v)
        U, _, Wt = np.linalg.svd(np.c_[M[:, 0], M[:, 1], np.cross(M[:, 0], M[:, 1])])
        poses.append(make_transform(U @ np.diag([1.0, 1.0, np.linalg.det(U @ Wt)]) @ Wt, M[:, 2]))
        velocities.append(v[1:])
    depth = best.x[0] * (m @ c)
    if np.any(depth <= 0):
        raise DegenerateMotionError("the scan's corners fit no pose with the target in front of the camera")
    x_c = best.x[0] * (m @ b)
    rms = float(np.sqrt(np.mean((focal * x_c / depth + cx - u) ** 2)))
    return np.array(poses), np.array(velocities), rms


def _angle(R: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.arccos(np.clip((np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0))


def resolve_mirrors(target2cam: NDArray[np.float64], velocity: NDArray[np.float64], A: NDArray[np.float64],
                    w: NDArray[np.float64]) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """Per scan which of its candidate poses agrees with the robot: the pushbroom's two mirror images
    (:func:`pushbroom_resection`), each for every ordering of the target's corners a symmetric target
    allows (a detector reads a mirrored scan's grid in mirrored order).

    The flange's turn from a reference scan (the one turned most from the others) to each scan must
    have the camera's angle: for each candidate of the reference, that picks each scan's candidate;
    the turn axes and the scans' directions then give X's rotation (``axis(A_jr) = R_X axis(B_jr)``,
    ``w_j = R_X V_j``, scipy's ``align_vectors``), and each scan takes the candidate whose target pose
    in the robot's world (``R_A R_X R_B``) is the reference's and whose direction is its own. The
    reference's candidate whose choice agrees best wins.

    Parameters
    ----------
    target2cam : (N, K, 4, 4) array
        Each scan's candidate poses.
    velocity : (N, K, 3) array
        The camera's velocity relative to the target (camera frame) with each.
    A : (N, 4, 4) array
        :func:`~handeye.frames.setups.robot_world_A` of each scan's reference flange pose.
    w : (N, 3) array
        The sensor's velocity relative to the target in ``A``'s frame (``R_A^T dt_A/dt``, m/s).

    Returns
    -------
    choice : (N,) int array
        The candidate per scan.
    R_X : (3, 3) array
        X's rotation the choice implies.

    Raises
    ------
    DegenerateMotionError
        The flange did not turn between scans.
    """
    n, k = target2cam.shape[:2]
    RA, RB = A[:, :3, :3], target2cam[:, :, :3, :3]
    turn = _angle(np.swapaxes(RA[:, None], 2, 3) @ RA[None, :])  # (N, N): the flange's turn between scans
    if not (turn > MIN_TURN).any():
        raise DegenerateMotionError("the flange did not turn between scans: turn it 10 deg or more about two or three axes "
                                    "between scans (X's rotation and the scans' mirror images need it)")
    r = int(np.argmax(np.median(turn, axis=1)))
    others = np.flatnonzero(turn[r] > MIN_TURN)
    RA_jr = np.swapaxes(RA[others], 1, 2) @ RA[r]
    axes_A = Rotation.from_matrix(RA_jr).as_rotvec()
    unit_w = w / np.linalg.norm(w, axis=1, keepdims=True)
    unit_V = velocity / np.linalg.norm(velocity, axis=2, keepdims=True)
    best: tuple[float, NDArray[np.intp], NDArray[np.float64]] | None = None
    for c_r in range(k):
        RB_jr = RB[others] @ RB[r, c_r].T  # (m, K, 3, 3)
        pick = np.argmin(np.abs(_angle(RB_jr) - turn[r, others, None]), axis=1)
        a = np.r_[axes_A, unit_w[[r]]]
        b = np.r_[Rotation.from_matrix(RB_jr[np.arange(len(others)), pick]).as_rotvec(), unit_V[[r], c_r]]
        R_X = Rotation.align_vectors(a, b)[0].as_matrix()
        R_Z = RA[r] @ R_X @ RB[r, c_r]
        # each scan's candidate: its target pose in the robot's world as the reference's, its direction its own
        off = _angle(np.swapaxes(R_Z, 0, 1)[None, None] @ (RA[:, None] @ R_X @ RB))
        along = np.einsum("nkj,nj->nk", unit_V, unit_w @ R_X)
        cost = off + np.where(along > 0, 0.0, np.pi)
        choice = np.argmin(cost, axis=1)
        total = float(np.sum(cost[np.arange(n), choice]))
        if best is None or total < best[0]:
            best = (total, choice.astype(np.intp), R_X)
    if best is None:
        raise DegenerateMotionError("no candidate pose of the target in the scans: the resection found none")
    return best[1], best[2]
