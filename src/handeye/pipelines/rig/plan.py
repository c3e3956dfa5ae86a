"""Planning a rig's capture (``handeye plan --sensor rig``, or ``plan --rig-camera``: the rig's
registration's ``plan`` hook): robot poses in which every camera of the rig sees the whole target.

A rig's cameras share the robot's poses, so a view only one of them can use is half wasted.
:func:`plan_rig` draws each camera's candidate viewpoints (as :func:`handeye.planning.poses.plan_poses`
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
from scipy.spatial.transform import Rotation

from ...errors import HandEyeError
from ...frames.metrics import std_deg_mm
from ...frames.motions import order_path
from ...frames.setups import check_setup, flange_poses, predicted_target2cam
from ...geometry.se3 import make_transform, skew
from ...io.session import read_intrinsics
from ...options import ROBOT_ACCURACY, CalibrationOptions
from ...sensors.camera.targets import target_from_spec
from ...simulate import DEFAULT_TARGETS
from ..kinds import PlanRequest, SensorPlan
from ..viewpoints import candidate_views, choose_views, reported_std, reprojection_information, visible_mask

__all__ = ["RigPlanCamera", "RigPlan", "plan_rig", "plan_command"]


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
        The first camera's rough X and the target's rough pose, as for :func:`handeye.planning.poses.plan_poses`.
    object_points : (M, 3)
        The target's points (metres, target frame).
    cameras : list of RigPlanCamera
        The first is the camera X is; each other one's ``cam2first`` places it.
    n_poses, standoff, tilt_max_deg, margin_px, noise_px, robot_accuracy
        As for :func:`handeye.planning.poses.plan_poses`.

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


def _intrinsics(path: str, flag: str) -> tuple[NDArray[np.float64], NDArray[np.float64], tuple[int, int]]:
    """K, dist and image size of a camera's intrinsics YAML, an error naming ``flag``."""
    try:
        return read_intrinsics(path)
    except HandEyeError as exc:
        raise HandEyeError(f"{flag} {exc}") from None


def _pose(text: str, name: str) -> NDArray[np.float64]:
    """x,y,z[,rx,ry,rz] (metres, a rotation vector in degrees) as a 4x4."""
    try:
        v = np.array([float(t) for t in text.replace(" ", "").split(",")])
    except ValueError:
        raise HandEyeError(f"{name} {text!r}: give comma-separated numbers") from None
    if v.size not in (3, 6) or not np.all(np.isfinite(v)):
        raise HandEyeError(f"{name} {text!r}: give 3 or 6 finite comma-separated numbers")
    return make_transform(Rotation.from_rotvec(v[3:] if v.size == 6 else np.zeros(3), degrees=True).as_matrix(), v[:3])


def rig_cameras(intrinsics: str, others: list[str]) -> list[RigPlanCamera]:
    """The first camera (its intrinsics YAML, ``--intrinsics``) and each other one, ``--rig-camera``'s
    NAME,INTRINSICS,X,Y,Z[,RX,RY,RZ] (its pose in the first camera's frame: metres and a rotation vector
    in degrees)."""
    K, dist, size = _intrinsics(intrinsics, "--intrinsics")
    cameras = [RigPlanCamera("cam0", np.eye(4), K, size, dist)]
    for text in others:
        parts = text.split(",")
        if len(parts) not in (5, 8) or not parts[0] or not parts[1]:
            raise HandEyeError(f"--rig-camera {text!r}: give NAME,INTRINSICS,X,Y,Z[,RX,RY,RZ]: the camera's name, its "
                               "intrinsics YAML and its pose in the first camera's frame (m; rotation vector, deg)")
        if parts[0] in [c.name for c in cameras]:
            raise HandEyeError(f"--rig-camera {text!r}: the name {parts[0]!r} is taken (the first camera is cam0): each "
                               "camera needs its own name")
        K_k, dist_k, size_k = _intrinsics(parts[1], "--intrinsics")
        cameras.append(RigPlanCamera(parts[0], _pose(",".join(parts[2:]), f"--rig-camera {parts[0]}"), K_k, size_k, dist_k))
    return cameras


def plan_command(request: PlanRequest) -> SensorPlan:
    """``handeye plan --sensor rig`` (or ``plan --rig-camera``; the rig's registration's ``plan`` hook):
    poses in which every camera of the rig sees the whole board (``target`` or ``target_spec``; default
    a chessboard), each camera's X's predicted std; ``intrinsics`` is the first camera's, ``options``'
    ``rig_camera`` the others'.

    Raises
    ------
    HandEyeError
        No ``intrinsics``, ``standoff`` or other camera, a camera badly given, or too few poses every
        camera can use.
    """
    others = list(request.options.get("rig_camera") or [])
    if request.intrinsics is None or request.standoff is None or not others:
        raise HandEyeError("plan --sensor rig needs --intrinsics (the first camera's), --standoff and a --rig-camera per "
                           "other camera")
    spec = request.target_spec if request.target_spec is not None else DEFAULT_TARGETS[request.target or "chessboard"]
    obj = target_from_spec(spec).object_points()
    plan = plan_rig(request.setup, request.X, request.Z, obj, rig_cameras(request.intrinsics, others),
                    n_poses=request.poses or 15, standoff=request.standoff, tilt_max_deg=request.tilt_max_deg,
                    margin_px=request.margin_px, noise_px=request.noise_px, robot_accuracy=request.robot_accuracy)
    acc = plan.robot_accuracy
    lines = ["", f"predicted std of each camera's X as the rig's calibration would report it ({plan.noise_px:g} px of corner "
             "noise" + (f", the robot's absolute accuracy {acc[0]:g} deg / {acc[1]:g} mm per axis in it" if acc else "") + "):"]
    lines += [f"  {name:8s} rotation {_vector(s[:3], 4)} deg, translation {_vector(s[3:], 3)} mm"
              for name, s in plan.std_per_camera.items()]
    return SensorPlan(
        [f"v{k + 1:02d}" for k in range(len(plan.flange2base))], plan.flange2base, "view", plan,
        f"{len(plan.flange2base)} poses chosen from {plan.n_candidates} in which every camera ({', '.join(plan.names)}) keeps "
        f"the whole target {request.margin_px:g} px inside its image; in path order:", "view", "", "", "", "", "",
        "flange2base per view; it is the poses.csv of the rig session to capture (first column view; replace each row "
        "by the pose the robot reports)", lines=tuple(lines))


def _vector(v: NDArray[np.float64], digits: int) -> str:
    return "[" + ", ".join(f"{x: .{digits}f}" for x in v) + "]"
