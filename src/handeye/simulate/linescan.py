"""Line-scan cameras' captures: scans of a chessboard swept by the robot, with its errors and the clocks'.

:func:`linescan_scene` draws scans as a line-scan cell makes them: per scan the robot turns the
camera (eye-in-hand) or the board on its flange (eye-to-hand) to a new orientation within a cone
about the board's normal, then moves it in a straight line at a steady speed across the camera's
view plane, back and forth between scans. Each board corner is seen in the row exposed when it
crossed the view plane, at the pixel along the line its position there projects to (the focal
length, principal point and radial distortion along the line). The robot's trajectory is sampled on
its own clock, which reads ``clock_offset`` after the camera's; what the controller reports is off by
the robot's error (one rigid error per scan: the arm's pose error over a short straight move); the
rows' times jitter; the corners have pixel noise.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from .._shared.io import atomic_write, check_output_folder, write_png
from .._shared.lazy import lazy_module
from ..errors import HandEyeError, InputMismatchError
from ..frames.setups import check_setup, flange_poses, setup_info
from ..geometry.se3 import invert, make_transform
from ..io.session import write_pose_table
from ..sensors.camera.targets.chessboard import Chessboard
from ..sensors.linescan.model import Trajectory
from ._common import _reported
from .scenes import scene_from_viewpoints

cv2 = lazy_module("cv2")

__all__ = ["LineScanScene", "linescan_scene", "render_scan", "write_linescan_session", "LINESCAN_CAMERA"]

#: The simulated camera: pixels along the line, focal length (px), principal point off the middle
#: (px), radial distortion along the line, and the board (inner corners per row and column, square, m).
LINESCAN_CAMERA = {"width": 2048, "focal": 2400.0, "cx_offset": 7.3, "k1": -0.03, "board": (9, 6, 0.02)}
#: The robot's trajectory is sampled at this rate (Hz), from this long (s) before each scan to after it.
TRAJECTORY_HZ, LEAD_S = 250.0, 0.6


@dataclass(frozen=True)
class LineScanScene:
    """A simulated line-scan capture: per scan (``names``) the corners found (``corners``: u, row) and
    their board points, the time of row 0 on the camera's clock (``starts``), the robot's reported
    trajectory (its clock), and the truth: X, Z (the board's pose), the intrinsics and the clock
    offset (the robot's clock minus the camera's)."""

    setup: str
    X: NDArray[np.float64]
    Z: NDArray[np.float64]
    names: list[str]
    corners: list[NDArray[np.float64]]
    target_points: list[NDArray[np.float64]]
    starts: NDArray[np.float64]
    lines: NDArray[np.intp]  #: rows per scan
    line_rate: float
    trajectory: Trajectory  #: as the controller reports it
    trajectory_true: Trajectory
    focal: float
    cx: float
    k1: float
    width: int
    clock_offset: float
    board: tuple[int, int, float]
    #: the truth of each scan's motion: the camera's pose in the board frame at ``t_mid`` (the robot's
    #: clock) and its velocity there (m/s, board frame)
    cam2target_mid: NDArray[np.float64] | None = None
    velocity: NDArray[np.float64] | None = None
    t_mid: NDArray[np.float64] | None = None

    @property
    def target_spec(self) -> dict:
        """The board as session.yaml's ``target:`` mapping."""
        cols, rows, square = self.board
        return {"type": "chessboard", "cols": cols, "rows": rows, "square": square}


def linescan_scene(n_scans: int = 12, setup: str = "eye_in_hand", rng: np.random.Generator | int | None = None, *,
                   distance: float = 0.4, speed: float = 0.2, cone_deg: float = 30.0, noise_px: float = 0.1,
                   jitter_s: float = 2e-5, robot_error: tuple[float, float] | None = None, clock_offset: float = 0.012,
                   focal: float | None = None, k1: float | None = None, depth_spread: float = 0.25) -> LineScanScene:
    """A line-scan camera's capture of a chessboard (the module docstring).

    ``n_scans`` scans (:data:`LINESCAN_CAMERA`: 2,048 pixels, f = 2,400 px; a 9 x 6 board of 20 mm
    squares), each from ``distance`` (m; each scan's within ``depth_spread`` of it: the robot's known
    change of distance is what tells the focal length from the distance) within ``cone_deg`` of the
    board's normal, any roll, the
    motion at ``speed`` (m/s) along the camera's y axis, forth and back in turn; the line rate gives
    square pixels at that distance. ``noise_px``: the corners' noise (px, along the line and across);
    ``jitter_s``: the rows' timing jitter (s); ``robot_error`` (deg, mm): the controller's poses off by
    a constant and a heavy-tailed error per scan of that size per axis; ``clock_offset`` (s).

    Examples
    --------
    >>> sc = linescan_scene(4, "eye_in_hand", rng=0)
    >>> len(sc.corners), sc.corners[0].shape
    (4, (54, 2))
    """
    setup = check_setup(setup)
    if n_scans < 1:
        raise InputMismatchError(f"n_scans={n_scans}: at least 1")
    rng = np.random.default_rng(rng)
    cam = LINESCAN_CAMERA
    f = float(cam["focal"] if focal is None else focal)
    k = float(cam["k1"] if k1 is None else k1)
    width = int(cam["width"])
    cx = 0.5 * width + float(cam["cx_offset"])
    cols, rows, square = cam["board"]
    board = Chessboard(cols, rows, square).object_points()
    aim = board.mean(axis=0)
    line_rate = speed * f / distance
    half_path = 0.5 * np.hypot(cols, rows) * square + 0.04  # the board's half diagonal and a margin
    R_cam = np.empty((n_scans, 3, 3))
    centre = np.empty((n_scans, 3))
    for i in range(n_scans):  # the camera's orientation and its position at the scan's middle, board frame
        tilt = np.radians(cone_deg) * np.sqrt(rng.uniform())
        axis = rng.normal(size=2)
        axis /= np.linalg.norm(axis)
        R_cam[i] = (Rotation.from_rotvec(tilt * np.r_[axis, 0.0]) * Rotation.from_euler("x", 180, degrees=True)
                    * Rotation.from_euler("z", rng.uniform(-180, 180), degrees=True)).as_matrix()
        hit = aim + np.r_[rng.uniform(-0.02, 0.02, 2), 0.0]
        centre[i] = hit - R_cam[i][:, 2] * distance * rng.uniform(1 - depth_spread, 1 + depth_spread)
    mid = make_transform(R_cam, centre)  # cam2target at each scan's middle
    scene = scene_from_viewpoints(mid, setup, rng)
    X, Z = scene.X, scene.Z
    direction = np.where(np.arange(n_scans) % 2 == 0, 1.0, -1.0)  # forth and back
    duration = 2 * half_path / speed
    times, poses_true, poses_reported, starts, lines, corners, points, names = [], [], [], [], [], [], [], []
    velocity, mids = np.empty((n_scans, 3)), np.empty(n_scans)
    t_mid = LEAD_S + 0.5 * duration
    errors = _reported(scene.flange2base, robot_error, rng) @ invert(scene.flange2base)  # per scan: reported = E @ true
    for i in range(n_scans):
        v = velocity[i] = direction[i] * speed * R_cam[i][:, 1]  # the camera's velocity in the board frame
        mids[i] = t_mid
        t = np.arange(t_mid - 0.5 * duration - LEAD_S, t_mid + 0.5 * duration + LEAD_S, 1.0 / TRAJECTORY_HZ)
        cam2target = make_transform(np.broadcast_to(R_cam[i], (len(t), 3, 3)), centre[i] + (t - t_mid)[:, None] * v)
        F = flange_poses(cam2target, X, Z, setup)
        # a corner is seen when it crosses y = 0: R^T (P - C(t)) has y = 0, linear in t
        y0 = (board - centre[i]) @ R_cam[i][:, 1]
        t_cross = t_mid + y0 / (direction[i] * speed)
        c = (board - centre[i] - (t_cross - t_mid)[:, None] * v) @ R_cam[i]
        xn = c[:, 0] / c[:, 2]
        u = cx + f * (xn + k * xn**3) + rng.normal(0.0, noise_px, len(board))
        start = t[0] + LEAD_S - clock_offset  # row 0 on the camera's clock (the robot's clock reads clock_offset later)
        r = (t_cross - clock_offset - start + rng.normal(0.0, jitter_s, len(board))) * line_rate
        r += rng.normal(0.0, noise_px, len(board))
        seen = (u >= 0) & (u <= width - 1)
        corners.append(np.c_[u, r][seen])
        points.append(board[seen])
        lines.append(int(np.ceil(duration * line_rate)))
        starts.append(start)
        times.append(t)
        poses_true.append(F)
        poses_reported.append(errors[i] @ F)
        names.append(f"s{i + 1:02d}.png")
        t_mid += duration + 2 * LEAD_S + 3.0  # the next scan after the robot has turned
    times_all = np.concatenate(times)
    return LineScanScene(setup, X, Z, names, corners, points, np.array(starts), np.array(lines), line_rate,
                         Trajectory(times_all, np.concatenate(poses_reported)),
                         Trajectory(times_all, np.concatenate(poses_true)), f, cx, k, width, clock_offset,
                         (cols, rows, square), mid, velocity, mids)


def _undistorted(u: NDArray[np.float64], f: float, cx: float, k1: float) -> NDArray[np.float64]:
    """``x_n`` of pixels ``u`` along the line (Newton on ``u = cx + f (x + k1 x^3)``)."""
    target = (u - cx) / f
    x = target.copy()
    for _ in range(8):
        x -= (x + k1 * x**3 - target) / (1.0 + 3.0 * k1 * x**2)
    return x


def render_scan(scene: LineScanScene, i: int, rng: np.random.Generator | int | None = None, noise_grey: float = 2.0,
                supersample: int = 2) -> NDArray[np.uint8]:
    """Scan ``i`` of ``scene`` as the camera records it: row ``r`` the view plane's intersection with
    the board at the time ``starts[i] + r / line_rate`` (camera clock), each pixel the board's printed
    pattern averaged over ``supersample`` x ``supersample`` points of it, with ``noise_grey`` of
    sensor noise. Off the printed sheet the background is mid grey."""
    rng = np.random.default_rng(rng)
    cols, rows, square = scene.board
    texture = Chessboard(cols, rows, square).texture(texels_per_m=12000.0)
    n = supersample
    u = (np.arange(scene.width * n) + 0.5) / n - 0.5
    t = scene.starts[i] + ((np.arange(int(scene.lines[i]) * n) + 0.5) / n - 0.5) / scene.line_rate + scene.clock_offset
    xn = _undistorted(u, scene.focal, scene.cx, scene.k1)
    R = scene.cam2target_mid[i, :3, :3]
    d = np.c_[xn, np.zeros_like(xn), np.ones_like(xn)] @ R.T  # each pixel's ray in the board frame
    C = scene.cam2target_mid[i, :3, 3] + (t - scene.t_mid[i])[:, None] * scene.velocity[i]  # the camera per sub-row
    lam = -C[:, 2:3] / d[None, :, 2]
    x = C[:, 0:1] + lam * d[None, :, 0]
    y = C[:, 1:2] + lam * d[None, :, 1]
    map_u = (texture.u0 + x * texture.scale).astype(np.float32)
    map_v = (texture.v0 + y * texture.scale).astype(np.float32)
    fine = cv2.remap(texture.image, map_u, map_v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=128)
    img = cv2.resize(fine, (scene.width, int(scene.lines[i])), interpolation=cv2.INTER_AREA).astype(float)
    img += rng.normal(0.0, noise_grey, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def write_linescan_session(folder: str | Path, scene: LineScanScene, nominal_focal: float | None = None,
                           rng: np.random.Generator | int | None = None) -> Path:
    """Write a simulated line-scan capture as a session folder (docs/guide.md): ``images/sNN.png`` (the
    rendered scans, :func:`render_scan`), ``images.csv`` (``image, time``: each scan's row 0 on the
    camera's clock), ``poses.csv`` (``time`` on the robot's clock, then the controller's flange
    poses: the trajectory; quat_wxyz, mm, deg), ``session.yaml`` (``linescan:`` with the width, the
    line rate and the nominal focal length, ``nominal_focal`` or the true one 3% off) and
    ``ground_truth.yaml``. Returns the folder."""
    out = check_output_folder(folder)
    if (out / "session.yaml").exists():
        raise HandEyeError(f"{out} already holds a session; choose an empty folder")
    (out / "images").mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(rng)
    for i, name in enumerate(scene.names):
        write_png(out / "images" / name, render_scan(scene, i, rng))
    atomic_write(out / "images.csv", "image,time\n" + "".join(f"{n},{float(t)!r}\n" for n, t in zip(scene.names, scene.starts)))
    write_pose_table(out / "poses.csv", [repr(float(t)) for t in scene.trajectory.times], scene.trajectory.flange2base,
                     "quat_wxyz", "mm", "deg", id_column="time")
    focal = float(round(1.03 * scene.focal if nominal_focal is None else nominal_focal, 1))
    spec = {"setup": scene.setup, "target": scene.target_spec,
            "linescan": {"width": scene.width, "line_rate": float(scene.line_rate), "focal": focal},
            "poses": {"file": "poses.csv", "format": "quat_wxyz", "length_unit": "mm", "angle_unit": "deg"},
            "images": {"file": "images.csv"}}
    atomic_write(out / "session.yaml", yaml.safe_dump(spec, sort_keys=False))
    info = setup_info(scene.setup)
    truth = {"setup": scene.setup, info.x_name: scene.X.tolist(), info.z_name: scene.Z.tolist(),
             "focal_px": scene.focal, "cx_px": scene.cx, "k1": scene.k1, "clock_offset_s": scene.clock_offset}
    atomic_write(out / "ground_truth.yaml", yaml.safe_dump(truth, sort_keys=False))
    return out
