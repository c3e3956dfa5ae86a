"""Camera intrinsics, per-image target poses (PnP), and the symmetric-target ambiguity."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..._shared.lazy import lazy_module
from ...errors import InputMismatchError
from ...frames.setups import robot_world_A, robot_world_A_inv
from ...geometry.se3 import PITCH_ANGLE, from_rotvec_translation, invert, screw_parameters, skew
from .targets import Detection

cv2 = lazy_module("cv2")  # OpenCV loads on first use: `import handeye` stays light

__all__ = ["symmetry_costs", "settled_symmetry_costs", "label_doubts", "solve_pnp",
           "refine_pnp", "calibrate_intrinsics", "intrinsics_covariance",
           "INTRINSICS", "resolve_symmetries", "reprojection_rms", "project_points", "project_points_many",
           "project_camera_points", "projection_jacobians", "LabelledViews", "labelled_by_robot", "relabel_points"]


def project_points(
    target2cam: NDArray[np.float64], points: NDArray[np.float64], K: NDArray[np.float64], dist: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Pixel positions (M, 2) of target-frame points (M, 3) seen from pose ``target2cam``."""
    if len(points) == 0:  # OpenCV returns None for no points
        return np.empty((0, 2))
    rvec, _ = cv2.Rodrigues(target2cam[:3, :3])
    px, _ = cv2.projectPoints(np.ascontiguousarray(points, dtype=np.float64), rvec, target2cam[:3, 3], K, dist)
    return px.reshape(-1, 2)


def project_points_many(target2cam: NDArray[np.float64], points: NDArray[np.float64], owner: NDArray[np.intp],
                        K: NDArray[np.float64], dist: NDArray[np.float64]) -> NDArray[np.float64]:
    """Pixel positions (M, 2) of target-frame points (M, 3), point ``m`` seen from pose
    ``target2cam[owner[m]]``: many images in one vectorised pass.

    OpenCV's camera model (``cv2.projectPoints``) with up to 8 distortion coefficients (k1 k2 p1
    p2 k3 k4 k5 k6, the rational model); longer models (thin prism, tilt) go through OpenCV
    image by image. Agrees with ``cv2.projectPoints`` to ~1e-10 px.
    """
    dist = np.asarray(dist, dtype=float).ravel()
    if len(dist) > 8:
        out = np.empty((len(points), 2))
        for i in np.unique(owner):
            sel = owner == i
            out[sel] = project_points(target2cam[i], points[sel], K, dist)
        return out
    R, t = target2cam[owner, :3, :3], target2cam[owner, :3, 3]
    return project_camera_points(np.einsum("mij,mj->mi", R, points) + t, K, dist)


def _rational_model(p: NDArray[np.float64], dist: NDArray[np.float64]) -> tuple:
    """OpenCV's distortion of camera-frame points ``(M, 3)`` with up to 8 coefficients (k1 k2 p1
    p2 k3 k4 k5 k6): ``(coefficients, x, y, r2, num, den, xd, yd)``, the normalised point, its
    squared radius, the radial factor's numerator and denominator and the distorted point."""
    dist = np.asarray(dist, dtype=float).ravel()
    if len(dist) > 8:
        raise InputMismatchError(f"{len(dist)} distortion coefficients: the vectorised camera model covers up to 8")
    d = np.zeros(8)
    d[: len(dist)] = dist
    k1, k2, p1, p2, k3, k4, k5, k6 = d
    x, y = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
    r2 = x * x + y * y
    num = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    den = 1 + r2 * (k4 + r2 * (k5 + r2 * k6))
    radial = num / den
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return d, x, y, r2, num, den, xd, yd


def project_camera_points(p: NDArray[np.float64], K: NDArray[np.float64], dist: NDArray[np.float64]) -> NDArray[np.float64]:
    """Pixel positions (M, 2) of camera-frame points (M, 3): OpenCV's camera model with up to 8
    distortion coefficients (see :func:`project_points_many`)."""
    *_, xd, yd = _rational_model(p, dist)
    return np.stack([K[0, 0] * xd + K[0, 2], K[1, 1] * yd + K[1, 2]], axis=1)  # OpenCV ignores a skew term


def projection_jacobians(points_cam: NDArray[np.float64], K: NDArray[np.float64], dist: NDArray[np.float64],
                         intrinsics: bool = True) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Pixel positions of camera-frame points ``(M, 3)`` and their derivatives under OpenCV's
    camera model (as :func:`project_camera_points`, up to 8 distortion coefficients).

    Returns
    -------
    pixels : ndarray (M, 2)
        :func:`project_camera_points` of the points (the same numbers).
    d_point : ndarray (M, 2, 3)
        d(u, v) / d(point in the camera frame).
    d_intrinsics : ndarray (M, 2, 9)
        d(u, v) / d(fx, fy, cx, cy, k1, k2, p1, p2, k3); (M, 2, 0) when ``intrinsics`` is False (not needed).
    """
    (k1, k2, p1, p2, k3, k4, k5, k6), x, y, r2, num, den, xd, yd = _rational_model(points_cam, dist)
    fx, fy = K[0, 0], K[1, 1]
    inv_z = 1.0 / points_cam[:, 2]
    radial = num / den
    d_radial = ((k1 + r2 * (2 * k2 + 3 * k3 * r2)) * den - num * (k4 + r2 * (2 * k5 + 3 * k6 * r2))) / (den * den)
    xy = x * y
    # the distorted normalised point (xd, yd) against the undistorted one (x, y)
    dxd_dx = radial + 2 * x * x * d_radial + 2 * p1 * y + 6 * p2 * x
    dxd_dy = 2 * xy * d_radial + 2 * p1 * x + 2 * p2 * y
    dyd_dy = radial + 2 * y * y * d_radial + 6 * p1 * y + 2 * p2 * x
    m = len(points_cam)
    d_point = np.empty((m, 2, 3))
    # (x, y) against the point: [[1/z, 0, -x/z], [0, 1/z, -y/z]]
    d_point[:, 0, 0] = fx * dxd_dx * inv_z
    d_point[:, 0, 1] = fx * dxd_dy * inv_z
    d_point[:, 0, 2] = -fx * (dxd_dx * x + dxd_dy * y) * inv_z
    d_point[:, 1, 0] = fy * dxd_dy * inv_z  # dyd/dx = dxd/dy
    d_point[:, 1, 1] = fy * dyd_dy * inv_z
    d_point[:, 1, 2] = -fy * (dxd_dy * x + dyd_dy * y) * inv_z
    pixels = np.stack([fx * xd + K[0, 2], fy * yd + K[1, 2]], axis=1)
    if not intrinsics:
        return pixels, d_point, np.zeros((m, 2, 0))
    d_intrinsics = np.zeros((m, 2, 9))
    d_intrinsics[:, 0, 0] = xd
    d_intrinsics[:, 1, 1] = yd
    d_intrinsics[:, 0, 2] = 1.0
    d_intrinsics[:, 1, 3] = 1.0
    for col, power in ((4, 1), (5, 2), (8, 3)):  # k1, k2, k3
        g = r2**power / den
        d_intrinsics[:, 0, col] = fx * x * g
        d_intrinsics[:, 1, col] = fy * y * g
    d_intrinsics[:, 0, 6] = fx * 2 * xy
    d_intrinsics[:, 1, 6] = fy * (r2 + 2 * y * y)
    d_intrinsics[:, 0, 7] = fx * (r2 + 2 * x * x)
    d_intrinsics[:, 1, 7] = fy * 2 * xy
    return pixels, d_point, d_intrinsics


def reprojection_rms(det: Detection, target2cam: NDArray[np.float64], K: NDArray[np.float64], dist: NDArray[np.float64]) -> float:
    """RMS distance (px) between detected and reprojected feature points."""
    proj = project_points(target2cam, det.object_points, K, dist)
    return float(np.sqrt(np.mean(np.sum((proj - det.image_points) ** 2, axis=1))))


def solve_pnp(det: Detection, K: NDArray[np.float64], dist: NDArray[np.float64]) -> tuple[NDArray[np.float64], float] | None:
    """``target2cam`` and its reprojection RMS (px) for one detection, or None (< 4 points).

    IPPE (the planar-target solver, which keeps the better of the two planar solutions), then
    Levenberg-Marquardt refinement of the reprojection error.
    """
    if len(det) < 4:
        return None
    obj = np.ascontiguousarray(det.object_points, dtype=np.float64)
    img = np.ascontiguousarray(det.image_points, dtype=np.float64)
    ok, rvec, tvec = cv2.solvePnP(obj, img, K, dist, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        return None
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, dist, rvec, tvec)
    T = from_rotvec_translation(rvec.ravel(), tvec.ravel())
    return T, reprojection_rms(det, T, K, dist)


def refine_pnp(target2cam: NDArray[np.float64], object_points: NDArray[np.float64], image_points: NDArray[np.float64],
               K: NDArray[np.float64], dist: NDArray[np.float64]) -> NDArray[np.float64]:
    """``target2cam`` refitted to its points under other intrinsics: Levenberg-Marquardt from the
    pose given, which keeps its planar solution (a fresh IPPE could take the other one)."""
    rvec = cv2.Rodrigues(np.ascontiguousarray(target2cam[:3, :3]))[0]
    tvec = np.ascontiguousarray(target2cam[:3, 3]).reshape(3, 1)
    rvec, tvec = cv2.solvePnPRefineLM(np.ascontiguousarray(object_points, dtype=np.float64),
                                      np.ascontiguousarray(image_points, dtype=np.float64), K, dist, rvec, tvec)
    return from_rotvec_translation(rvec.ravel(), tvec.ravel())


def calibrate_intrinsics(
    detections: list[Detection], image_size: tuple[int, int]
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """``K``, ``dist`` (k1 k2 p1 p2 k3) and the RMS reprojection error (px) from the same images.

    ``cv2.calibrateCamera`` on every detection; needs views with varied tilt, as a hand-eye capture has.
    """
    obj = [np.ascontiguousarray(d.object_points, dtype=np.float32) for d in detections]
    img = [np.ascontiguousarray(d.image_points, dtype=np.float32) for d in detections]
    rms, K, dist, _, _ = cv2.calibrateCamera(obj, img, image_size, None, None)
    return K, dist.ravel(), float(rms)


#: The intrinsics :func:`calibrate_intrinsics` estimates, in the order of :func:`projection_jacobians`.
INTRINSICS = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3")


def intrinsics_covariance(object_points: Sequence[NDArray[np.float64]], image_points: Sequence[NDArray[np.float64]],
                          target2cam: NDArray[np.float64], K: NDArray[np.float64],
                          dist: NDArray[np.float64]) -> NDArray[np.float64]:
    """Covariance (9, 9) of the intrinsics (:data:`INTRINSICS`) estimated from these views by
    :func:`calibrate_intrinsics`: the Gauss-Newton covariance of the reprojection fit over the
    intrinsics and every view's pose, the poses eliminated (Schur complement), scaled by the
    residual variance. Its diagonal is OpenCV's ``stdDeviationsIntrinsics`` squared; the
    correlations (fx with fy, the principal point with the tilt of the views) are what a
    propagation to X needs."""
    k = len(INTRINSICS)
    S = np.zeros((k, k))
    rss, residuals = 0.0, 0
    for P, uv, T in zip(object_points, image_points, target2cam):
        RP = np.asarray(P, dtype=float) @ T[:3, :3].T
        px, d_point, d_intr = projection_jacobians(RP + T[:3, 3], K, dist)
        r = np.asarray(uv, dtype=float) - px
        rss += float(np.sum(r * r))
        residuals += r.size
        # the view's pose: a left rotation increment w (d point = w x RP = -[RP]x w) and the translation
        d_pose = np.empty((len(RP), 3, 6))
        d_pose[:, :, :3] = -skew(RP)
        d_pose[:, :, 3:] = np.eye(3)
        A = d_intr.reshape(-1, k)
        B = (d_point @ d_pose).reshape(-1, 6)
        BA = B.T @ A
        S += A.T @ A - BA.T @ np.linalg.solve(B.T @ B, BA)
    dof = residuals - k - 6 * len(target2cam)
    if dof <= 0:
        raise InputMismatchError(f"{residuals} residuals cannot give the covariance of {k} intrinsics and {len(target2cam)} poses")
    return np.asarray(rss / dof * np.linalg.pinv(S), dtype=float)


def symmetry_costs(target2cam: NDArray[np.float64], flange2base: NDArray[np.float64], setup: str,
                   symmetries: list[NDArray[np.float64]], labels: NDArray[np.intp] | None = None) -> NDArray[np.float64]:
    """(S, N - 1): per symmetry and image after the first, how far that image's camera motions, so
    relabelled, are from the robot's in rotation angle and pitch (rad; 0.1 m of pitch ~ 1 rad).

    Without ``labels``, the motion from the first image alone; with them (the symmetry index chosen
    per image), the median over the motions from up to :data:`LABEL_REFERENCES` other images, each
    relabelled by its own label: one image's noise or a motion whose angle and pitch happen to match
    a wrong labelling's no longer decides. The pitch counts in full only where both motions turn by
    :data:`~handeye.geometry.se3.PITCH_ANGLE` or more, below it in proportion to the smaller angle:
    the axis of a motion that hardly turns, and with it the pitch, is set by the poses' noise. A pure
    translation of the robot (the camera moved without turning) is then judged by the angle alone,
    which tells the labellings apart by a quarter or half turn.
    """
    n = len(target2cam)
    robot, robot_inv = robot_world_A(flange2base, setup), robot_world_A_inv(flange2base, setup)
    if labels is None:
        refs, ref_poses = np.array([0]), target2cam[:1]
    else:
        refs = np.unique(np.linspace(0, n - 1, min(n, LABEL_REFERENCES)).round().astype(np.intp))
        ref_poses = target2cam[refs] @ np.asarray(symmetries)[np.asarray(labels)[refs]]
    # (R, N - 1) motions from reference j to image i: A_ij = inv(A_i) A_j, B_ij = (T_i F) inv(T_j F_j)
    _, _, th_a, d_a = screw_parameters(robot_inv[None, 1:] @ robot[refs][:, None])
    inv_refs = invert(ref_poses)[:, None]
    same = refs[:, None] == np.arange(1, n)[None]  # an image is not its own reference
    costs = []
    for F in symmetries:
        _, _, th_b, d_b = screw_parameters((target2cam[None, 1:] @ F) @ inv_refs)
        weight = np.minimum(1.0, np.minimum(th_a, th_b) / PITCH_ANGLE)
        cost = np.where(same, np.nan, np.abs(th_a - th_b) + weight * np.abs(d_a - d_b) / 0.1)
        costs.append(np.nanmedian(cost, axis=0))
    return np.stack(costs)


def settled_symmetry_costs(target2cam: NDArray[np.float64], flange2base: NDArray[np.float64], setup: str,
                           symmetries: list[NDArray[np.float64]], rounds: int = 3) -> NDArray[np.float64]:
    """:func:`symmetry_costs` against every image's label: the labels from the first image's motions,
    then the costs against all of them, and again until no label changes (at most ``rounds``)."""
    costs = symmetry_costs(target2cam, flange2base, setup, symmetries)
    labels = np.r_[0, np.argmin(costs, axis=0)]
    for _ in range(rounds):
        costs = symmetry_costs(target2cam, flange2base, setup, symmetries, labels)
        new = np.r_[0, np.argmin(costs, axis=0)]
        if np.array_equal(new, labels):
            break
        labels = new
    return costs


#: Most reference images :func:`symmetry_costs` compares each image with (spread over the capture):
#: enough for a steady median, linear in the images beyond.
LABEL_REFERENCES = 25


def label_doubts(costs: NDArray[np.float64], thin: float = 3.0, unmatched: float = 10.0,
                 floor_rad: float = 0.2) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Per image (the first, which defines the target frame, never), from :func:`symmetry_costs`:
    whether its labelling was chosen by a thin margin (another reading fits within ``thin`` times
    the typical best misfit), and whether even its best labelling leaves its motion far from the
    robot's (``unmatched`` times the typical best misfit, and over ``floor_rad``: a misdetected
    grid or a wrong robot pose, which no labels explain). An image is one or the other."""
    n = costs.shape[1] + 1
    unsure, off = np.zeros(n, bool), np.zeros(n, bool)
    if costs.shape[0] < 2 or n < 3:
        return unsure, off
    ranked = np.sort(costs, axis=0)
    typical = float(np.median(ranked[0]))
    off[1:] = ranked[0] > max(unmatched * typical, floor_rad)
    unsure[1:] = (ranked[1] - ranked[0] < thin * max(typical, 1e-3)) & ~off[1:]
    return unsure, off


@dataclass(frozen=True)
class LabelledViews:
    """A symmetric target's views labelled against the robot (:func:`labelled_by_robot`)."""

    target2cam: NDArray[np.float64]  #: (N, 4, 4) the poses, each in the labelling chosen
    object_points: list[NDArray[np.float64]]  #: per view its points in that labelling's target frame
    choice: NDArray[np.intp]  #: per view the symmetry chosen (0: as detected)
    unsure: NDArray[np.bool_]  #: per view: chosen by a thin margin (:func:`label_doubts`)
    unmatched: NDArray[np.bool_]  #: per view: no labelling agrees with the robot (:func:`label_doubts`)


def relabel_points(points: NDArray[np.float64], F: NDArray[np.float64]) -> NDArray[np.float64]:
    """Target points (M, 3) in the frame of the labelling ``T @ F`` (new = F^-1 old): the same corners,
    named from the other end."""
    F_inv = invert(np.asarray(F, float))
    return np.asarray(points, float) @ F_inv[:3, :3].T + F_inv[:3, 3]


def labelled_by_robot(target2cam: NDArray[np.float64], object_points: Sequence[NDArray[np.float64]],
                      flange2base: NDArray[np.float64], setup: str, symmetries: list[NDArray[np.float64]]) -> LabelledViews:
    """Views of a symmetric target (``symmetries``, the target's :meth:`symmetries`) relabelled so that
    the camera's motion agrees with the robot's (:func:`resolve_symmetries`), with the doubts of
    :func:`label_doubts`: every path that fits a board's corners takes them so (a detector names a
    chessboard's corners from either end, view by view: one view named from the other end is a pose
    half a turn away, which no X explains). An unambiguous target's views come back as given.

    Parameters
    ----------
    target2cam : (N, 4, 4) array
        Per view the target's pose by PnP (or from its points in a cloud).
    object_points : list of (n_i, 3) arrays
        Per view its points in the detector's target frame.
    flange2base : (N, 4, 4) array
        The robot's poses of the views.
    setup : str
    symmetries : list of (4, 4) arrays
        The identity first.
    """
    target2cam = np.asarray(target2cam, float)
    n = len(target2cam)
    unsure = unmatched = np.zeros(n, bool)
    costs = None
    if len(symmetries) > 1 and n > 1:
        costs = settled_symmetry_costs(target2cam, flange2base, setup, symmetries)
        unsure, unmatched = label_doubts(costs)
    fixed, choice = resolve_symmetries(target2cam, flange2base, setup, symmetries, costs)
    points = [np.asarray(p, float) if c == 0 else relabel_points(p, symmetries[c]) for p, c in zip(object_points, choice)]
    return LabelledViews(fixed, points, choice, unsure, unmatched)


def resolve_symmetries(
    target2cam: NDArray[np.float64],
    flange2base: NDArray[np.float64],
    setup: str,
    symmetries: list[NDArray[np.float64]],
    costs: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Choose, per image, which symmetric variant ``T @ F`` of a pose the robot motion agrees with
    (``costs``: :func:`settled_symmetry_costs` of these poses, when already computed).

    A symmetric pattern (chessboard, symmetric circle grid) looks the same after a half turn, so a
    detector may label it from either end: the PnP pose is ``T`` or ``T @ F``. The rotation angle
    and the pitch of a motion do not depend on the hand-eye transform (thesis §2.2.3), so for each
    image the variant whose camera motions from the other images have the robot motions' angles and
    pitches is the right one. The first image keeps its labelling (it defines the target frame).

    Returns the corrected poses and the index of the symmetry chosen per image.
    """
    n = len(target2cam)
    choice = np.zeros(n, dtype=np.intp)
    if len(symmetries) == 1 or n < 2:
        return target2cam, choice
    if costs is None:
        costs = settled_symmetry_costs(target2cam, flange2base, setup, symmetries)
    choice[1:] = np.argmin(costs, axis=0)
    fixed = target2cam.copy()
    for k, F in enumerate(symmetries):
        sel = choice == k
        fixed[sel] = target2cam[sel] @ F
    return fixed, choice
