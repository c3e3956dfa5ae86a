"""Planning a rig's capture: robot poses in which every camera of the rig sees the whole target.

A rig's cameras share the robot's poses, so a view only one of them can use is half wasted.
:func:`plan_rig` draws each camera's candidate viewpoints (as :func:`~handeye.planning.poses.plan_poses`
does for one camera: around the target, within a tilt of its normal, at 0.8, 1 and 1.25 times the
standoff), turns them into flange poses through the rough mounting, keeps those in which every
camera sees the whole target, and chooses the set that determines X best (A-optimal, as for one
camera) with every camera's corners, as the rig's joint fit uses them: the unknowns are the first
camera's X, the target's pose and every other camera's pose in the first camera's frame (each
camera's X is the first's times it), and each camera's X and its std follow from them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import HandEyeError
from ..frames.metrics import std_deg_mm
from ..frames.setups import check_setup, flange_poses, predicted_target2cam
from ..geometry.se3 import skew
from ..options import ROBOT_ACCURACY, CalibrationOptions
from .poses import candidate_views, choose_views, order_path, reported_std, reprojection_information, visible_mask

__all__ = ["RigPlanCamera", "RigPlan", "plan_rig"]


@dataclass(frozen=True)
class RigPlanCamera:
    """One camera of the rig to plan for: its name, rough pose in the first camera's frame
    (``cam2first``, 4x4; the identity for the first camera), intrinsics and image size."""

    name: str
    cam2first: NDArray[np.float64]
    K: NDArray[np.float64]
    image_size: tuple[int, int]
    dist: NDArray[np.float64] = field(default_factory=lambda: np.zeros(5))


@dataclass(frozen=True)
class RigPlan:
    """Planned robot poses for a rig and what they promise.

    Attributes
    ----------
    setup : str
    names : list of str
        The cameras.
    flange2base : ndarray (N, 4, 4)
        The poses, in path order.
    std_X : ndarray (6,)
        The std of the first camera's X (deg, mm) the rig's joint fit would report: every camera's
        corners, the robot's accuracy added.
    std_per_camera : dict
        The same for every camera's X.
    n_candidates : int
        Candidate poses in which every camera sees the whole target.
    robot_accuracy : (deg, mm) or None
    """

    setup: str
    names: list[str]
    flange2base: NDArray[np.float64]
    std_X: NDArray[np.float64]
    std_per_camera: dict[str, NDArray[np.float64]]
    n_candidates: int
    noise_px: float
    robot_accuracy: tuple[float, float] | None


def _candidate_poses(setup: str, X: NDArray[np.float64], Z: NDArray[np.float64], obj: NDArray[np.float64],
                     cameras: list[RigPlanCamera], standoff: float, tilt_max_deg: float, margin_px: float
                     ) -> NDArray[np.float64]:
    """Every camera's candidate viewpoints as flange poses, kept where every camera sees the whole target."""
    poses = []
    for cam in cameras:  # each camera's own candidates, centred for it: a rig's middle view suits neither end
        cam2target = candidate_views(obj, cam.K, cam.image_size, cam.dist, standoff, tilt_max_deg, margin_px)
        poses.append(flange_poses(cam2target, X @ cam.cam2first, Z, setup))
    F = np.concatenate(poses)
    keep = np.ones(len(F), dtype=bool)
    for cam in cameras:
        keep &= visible_mask(predicted_target2cam(X @ cam.cam2first, Z, F, setup), obj, cam.K, cam.dist, cam.image_size,
                             margin_px)
    return F[keep]


def plan_rig(setup: str, X: ArrayLike, Z: ArrayLike, object_points: ArrayLike, cameras: list[RigPlanCamera],
             n_poses: int = 12, standoff: float = 0.5, tilt_max_deg: float = 45.0, margin_px: float = 20.0,
             noise_px: float = 0.3, robot_accuracy: tuple[float, float] | None = ROBOT_ACCURACY) -> RigPlan:
    """Plan ``n_poses`` robot poses for a rig of cameras (the module docstring).

    Parameters
    ----------
    setup : {'eye_in_hand', 'eye_to_hand'}
    X, Z : (4, 4)
        The first camera's rough X and the target's rough pose, as for :func:`~handeye.planning.poses.plan_poses`.
    object_points : (M, 3)
        The target's points (metres, target frame).
    cameras : list of RigPlanCamera
        The first is the camera X is; each other one's ``cam2first`` places it.
    n_poses, standoff, tilt_max_deg, margin_px, noise_px, robot_accuracy
        As for :func:`~handeye.planning.poses.plan_poses`.

    Raises
    ------
    HandEyeError
        Fewer than two cameras, the first not at the identity, or fewer candidate poses than asked in
        which every camera sees the whole target (with what to change).

    Examples
    --------
    >>> import numpy as np
    >>> from handeye.geometry.se3 import make_transform
    >>> from handeye.sensors.camera.targets.chessboard import Chessboard
    >>> K = np.array([[1400.0, 0, 640], [0, 1400, 512], [0, 0, 1]])
    >>> left = RigPlanCamera("left", np.eye(4), K, (1280, 1024))
    >>> right = RigPlanCamera("right", make_transform(np.eye(3), [0.12, 0, 0]), K, (1280, 1024))
    >>> X = make_transform(np.eye(3), [0, 0, 0.05])
    >>> Z = make_transform(np.diag([1.0, -1, -1]), [0.6, 0, 0])
    >>> plan = plan_rig("eye_in_hand", X, Z, Chessboard(9, 6, 0.03).object_points(), [left, right], n_poses=10, standoff=0.7)
    >>> len(plan.flange2base), sorted(plan.std_per_camera)
    (10, ['left', 'right'])
    """
    setup = check_setup(setup)
    X, Z = np.asarray(X, float), np.asarray(Z, float)
    obj = np.asarray(object_points, float).reshape(-1, 3)
    if len(cameras) < 2 or not np.allclose(cameras[0].cam2first, np.eye(4)):
        raise HandEyeError("a rig plan needs two cameras or more, the first at the identity (X is its pose)")
    if n_poses < 3:
        raise HandEyeError(f"--poses {n_poses}: at least 3 poses are needed; 12 to 20 are usual")
    F = _candidate_poses(setup, X, Z, obj, cameras, standoff, tilt_max_deg, margin_px)
    if len(F) < n_poses:
        raise HandEyeError(f"only {len(F)} candidate poses keep the whole target {margin_px:g} px inside every camera's "
                           f"image at a standoff of {standoff:g} m (fewer than the {n_poses} asked): increase the standoff, "
                           "use a smaller target, or check the cameras' poses in the first camera's frame")
    maps = [_to_rig(X, cam.cam2first, k, len(cameras)) for k, cam in enumerate(cameras)]
    infos = np.sum([np.einsum("ai,nab,bj->nij", M, reprojection_information(F, X @ cam.cam2first, Z, setup, obj, cam.K), M)
                    for M, cam in zip(maps, cameras)], axis=0)  # (N, u, u) over the rig's unknowns
    weight = np.r_[np.full(3, standoff**2), np.ones(3)]
    chosen = np.asarray(choose_views(infos, n_poses, weight))
    chosen = chosen[order_path(F[chosen])]
    accuracy = CalibrationOptions(robot_accuracy=robot_accuracy).robot_accuracy
    cov = noise_px**2 * np.linalg.inv(infos[chosen].sum(axis=0))
    per = {}
    for M, cam in zip(maps, cameras):
        cov_cam = (M @ cov @ M.T)[:6, :6]
        per[cam.name] = reported_std(std_deg_mm(cov_cam), cov_cam, X @ cam.cam2first, accuracy)
    return RigPlan(setup, [c.name for c in cameras], F[chosen], per[cameras[0].name], per, len(F), float(noise_px), accuracy)


def _to_rig(X: NDArray[np.float64], cam2first: NDArray[np.float64], k: int, n: int) -> NDArray[np.float64]:
    """(12, 12 + 6 (n - 1)): camera ``k``'s X and Z increments (rotation left, translation added) from
    the rig's unknowns: the first X's, Z's and each other camera's pose in the first camera's frame
    (``X_k = X @ cam2first``: X's increment (a, b) moves X_k by (a, b - [R t]x a), R t the
    camera's offset in X's parent frame; its own pose's (c, e) by (R c, R e))."""
    R = X[:3, :3]
    M = np.zeros((12, 12 + 6 * (n - 1)))
    M[:6, :6] = np.eye(6)
    M[3:6, :3] = -skew(R @ cam2first[:3, 3])
    M[6:12, 6:12] = np.eye(6)
    if k > 0:
        c = 12 + 6 * (k - 1)
        M[:3, c:c + 3] = R
        M[3:6, c + 3:c + 6] = R
    return M

