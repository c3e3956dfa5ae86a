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

With ``arm=`` the scans are a real arm's: the nominal table's joint angles along each straight move,
which the arm as built (its table off the nominal one) turns into a slightly other, slightly curved
move; the corners are seen where that true motion crosses the view plane, and the controller reports
the joint angles it commanded (with encoder noise) and the nominal table's poses at them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..._shared.io import atomic_write, check_output_folder, write_png
from ..._shared.lazy import lazy_module
from ...errors import HandEyeError, InputMismatchError
from ...frames.setups import check_setup, flange_poses, predicted_target2cam, setup_info
from ...geometry.se3 import invert, make_transform
from ...io.session import write_joint_table, write_pose_table
from ...robot.kinematics import Chain, joints_at, load_arm
from ...sensors.camera.targets.chessboard import Chessboard
from ...sensors.linescan.model import Trajectory
from ...simulate import arm_mount, reaching, real_chain, reported_poses
from ...simulate.scenes import scene_from_viewpoints
from ..kinds import SimulateRequest

cv2 = lazy_module("cv2")

__all__ = ["LineScanScene", "linescan_scene", "render_scan", "write_linescan_session", "LINESCAN_CAMERA", "simulate_command"]

#: The simulated camera: pixels along the line, focal length (px), principal point off the middle
#: (px), radial distortion along the line, and the board (inner corners per row and column, square, m).
LINESCAN_CAMERA = {"width": 2048, "focal": 2400.0, "cx_offset": 7.3, "k1": -0.03, "board": (9, 6, 0.02)}
#: The robot's trajectory is sampled at this rate (Hz), from this long (s) before each scan to after it.
TRAJECTORY_HZ, LEAD_S = 250.0, 0.6
#: An arm's scan is reached by the nominal table's joint angles solved every this many samples (the
#: joints linear between them), its joints within this many of the arm's spreads from home.
KNOT_SAMPLES, ARM_REACH_SPREADS = 25, 2.5


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
    board: tuple[int, int, float] | None  #: the chessboard's inner corners per row and column and square (None: other points)
    #: the camera's true pose in the board frame over the robot's clock (what :func:`render_scan` draws)
    cam_true: Trajectory | None = None
    #: per scan the flange's true pose where its straight move starts and where it ends (N, 2, 4, 4)
    moves: NDArray[np.float64] | None = None
    #: with an arm: the joint angles the controller reports (rad) at ``trajectory.times``, the arm's
    #: name, its nominal and real tables
    joints: NDArray[np.float64] | None = None
    arm: str | None = None
    chain: Chain | None = None
    chain_true: Chain | None = None

    @property
    def target_spec(self) -> dict:
        """The board as session.yaml's ``target:`` mapping."""
        cols, rows, square = self.board
        return {"type": "chessboard", "cols": cols, "rows": rows, "square": square}


def linescan_scene(n_scans: int = 12, setup: str = "eye_in_hand", rng: np.random.Generator | int | None = None, *,
                   distance: float = 0.4, speed: float = 0.2, cone_deg: float = 30.0, noise_px: float = 0.1,
                   jitter_s: float = 2e-5, robot_error: tuple[float, float] | None = None, clock_offset: float = 0.012,
                   focal: float | None = None, k1: float | None = None, depth_spread: float = 0.25,
                   arm: str | None = None, length_mm: float = 0.5, angle_deg: float = 0.05,
                   joint_noise_deg: float = 0.002, cell: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
                   points: NDArray[np.float64] | None = None, width: int | None = None) -> LineScanScene:
    """A line-scan camera's capture of a chessboard (the module docstring).

    ``n_scans`` scans (:data:`LINESCAN_CAMERA`: 2,048 pixels, f = 2,400 px; a 9 x 6 board of 20 mm
    squares), each from ``distance`` (m; each scan's within ``depth_spread`` of it: the robot's known
    change of distance is what tells the focal length from the distance) within ``cone_deg`` of the
    board's normal, any roll, the
    motion at ``speed`` (m/s) along the camera's y axis, forth and back in turn; the line rate gives
    square pixels at that distance. ``noise_px``: the corners' noise (px, along the line and across);
    ``jitter_s``: the rows' timing jitter (s); ``robot_error`` (deg, mm): the controller's poses off by
    a constant and a heavy-tailed error per scan of that size per axis; ``clock_offset`` (s).
    ``arm`` (a shipped arm's name): the scans are that arm's (the module docstring), the camera
    (eye-in-hand) or the board (eye-to-hand) on its flange and the other ``distance`` away at its
    home, its real table off the nominal one by ``length_mm`` / ``angle_deg`` per entry (1-3 mm at
    the flange), the joint angles reported with ``joint_noise_deg`` of encoder noise per sample
    (``joints``), ``trajectory`` the nominal table's poses at them; give no ``robot_error`` then.
    ``cell`` (X, Z): the camera's and the board's placement as given, not drawn (a plan's; the board's
    +z towards the camera); ``points`` (n, 3; z = 0, m): another target's points than the chessboard's
    (a plan's; such a scene is not rendered); ``width``: other pixels along the line than
    :data:`LINESCAN_CAMERA`'s.

    Examples
    --------
    >>> sc = linescan_scene(4, "eye_in_hand", rng=0)
    >>> len(sc.corners), sc.corners[0].shape
    (4, (54, 2))
    """
    setup = check_setup(setup)
    if n_scans < 1:
        raise InputMismatchError(f"n_scans={n_scans}: at least 1")
    if arm is not None and (robot_error is not None or cell is not None):
        raise InputMismatchError("linescan_scene: give arm (its table's error and its own cell) or robot_error (an error "
                                 "of the poses) and cell, not both")
    rng = np.random.default_rng(rng)
    cam = LINESCAN_CAMERA
    f = float(cam["focal"] if focal is None else focal)
    k = float(cam["k1"] if k1 is None else k1)
    width = int(cam["width"] if width is None else width)
    cx = 0.5 * width + float(cam["cx_offset"])
    cols, rows, square = cam["board"]
    if points is None:
        board = Chessboard(cols, rows, square).object_points()
        half_path = 0.5 * np.hypot(cols, rows) * square + 0.04  # the board's half diagonal and a margin
    else:
        board = np.asarray(points, float).reshape(-1, 3)
        half_path = 0.5 * float(np.hypot(*np.ptp(board[:, :2], axis=0))) + 0.06
    aim = board.mean(axis=0)
    line_rate = speed * f / distance
    direction = np.where(np.arange(n_scans) % 2 == 0, 1.0, -1.0)  # forth and back
    duration = 2 * half_path / speed
    mids = LEAD_S + 0.5 * duration + np.arange(n_scans) * (duration + 2 * LEAD_S + 3.0)  # after the robot has turned

    def motion(i: int, R: NDArray[np.float64], centre: NDArray[np.float64]):
        """Scan ``i``'s sample times (robot clock) and the camera's straight move in the board frame."""
        t = np.arange(mids[i] - 0.5 * duration - LEAD_S, mids[i] + 0.5 * duration + LEAD_S, 1.0 / TRAJECTORY_HZ)
        v = direction[i] * speed * R[:, 1]  # the camera's velocity in the board frame
        return t, make_transform(np.broadcast_to(R, (len(t), 3, 3)), centre + (t - mids[i])[:, None] * v)

    chain = chain_true = None
    if arm is None:
        views = [_scan_view(rng, aim, distance, cone_deg, depth_spread) for _ in range(n_scans)]
        mid = make_transform(np.array([R for R, _ in views]), np.array([c for _, c in views]))  # cam2target
        if cell is None:
            scene = scene_from_viewpoints(mid, setup, rng)
            X, Z, flange_mid = scene.X, scene.Z, scene.flange2base
        else:
            X, Z = (np.asarray(T, float) for T in cell)
            flange_mid = flange_poses(mid, X, Z, setup)
        errors = reported_poses(flange_mid, robot_error, rng) @ invert(flange_mid)  # per scan: reported = E @ true
        moves = []
        for i, (R, centre) in enumerate(views):
            t, cam2target = motion(i, R, centre)
            F = flange_poses(cam2target, X, Z, setup)
            moves.append((t, cam2target, errors[i] @ F, None))
    else:
        chain = load_arm(arm)
        X, Z = arm_mount(chain, setup, rng, distance)
        chain_true = real_chain(chain, rng, length_mm, angle_deg)
        moves = [_arm_move(chain, chain_true, X, Z, setup, rng, i, lambda i: motion(i, *_scan_view(
            rng, aim, distance, cone_deg, depth_spread)), joint_noise_deg) for i in range(n_scans)]
    times, poses_reported, joints, starts, lines, corners, seen_points, names, cams = [], [], [], [], [], [], [], [], []
    for i, (t, cam2target, reported, q) in enumerate(moves):
        t_cross, c = _crossings(board, t, cam2target)
        xn = c[:, 0] / c[:, 2]
        u = cx + f * (xn + k * xn**3) + rng.normal(0.0, noise_px, len(board))
        start = t[0] + LEAD_S - clock_offset  # row 0 on the camera's clock (the robot's clock reads clock_offset later)
        r = (t_cross - clock_offset - start + rng.normal(0.0, jitter_s, len(board))) * line_rate
        r += rng.normal(0.0, noise_px, len(board))
        seen = (u >= 0) & (u <= width - 1) & np.isfinite(t_cross)
        corners.append(np.c_[u, r][seen])
        seen_points.append(board[seen])
        lines.append(int(np.ceil(duration * line_rate)))
        starts.append(start)
        times.append(t)
        cams.append(cam2target)
        poses_reported.append(reported)
        joints.append(q)
        names.append(f"s{i + 1:02d}.png")
    times_all = np.concatenate(times)
    poses_true = flange_poses(np.concatenate(cams), X, Z, setup)
    ends = flange_poses(np.array([[c[0], c[-1]] for c in cams]), X, Z, setup)
    return LineScanScene(setup, X, Z, names, corners, seen_points, np.array(starts), np.array(lines), line_rate,
                         Trajectory(times_all, np.concatenate(poses_reported)), Trajectory(times_all, poses_true), f, cx, k,
                         width, clock_offset, (cols, rows, square) if points is None else None,
                         Trajectory(times_all, np.concatenate(cams)), ends,
                         None if arm is None else np.concatenate(joints), arm, chain, chain_true)


def _scan_view(rng: np.random.Generator, aim: NDArray[np.float64], distance: float, cone_deg: float,
               depth_spread: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A scan's camera orientation in the board frame and its position at the scan's middle: within
    ``cone_deg`` of the board's normal, any roll, about ``distance`` from a point near ``aim``."""
    tilt = np.radians(cone_deg) * np.sqrt(rng.uniform())
    axis = rng.normal(size=2)
    axis /= np.linalg.norm(axis)
    R = (Rotation.from_rotvec(tilt * np.r_[axis, 0.0]) * Rotation.from_euler("x", 180, degrees=True)
         * Rotation.from_euler("z", rng.uniform(-180, 180), degrees=True)).as_matrix()
    hit = aim + np.r_[rng.uniform(-0.02, 0.02, 2), 0.0]
    return R, hit - R[:, 2] * distance * rng.uniform(1 - depth_spread, 1 + depth_spread)


def _arm_move(chain: Chain, true: Chain, X, Z, setup: str, rng: np.random.Generator, i: int, draw,
              joint_noise_deg: float):
    """Scan ``i`` by the arm: a straight move (``draw(i)``: its times and the camera's poses in the
    board frame) reached by the nominal table's joint angles (solved every :data:`KNOT_SAMPLES`
    samples from home, linear between; a move out of reach drawn again), which the real table turns
    into the true move. Returns the times, the camera's true poses in the board frame, the
    controller's flange poses (the nominal table's at the reported angles) and the reported angles."""
    home = chain.home[setup]
    limit = ARM_REACH_SPREADS * (chain.spread if chain.spread is not None else np.full(chain.n_joints, np.pi))
    for _ in range(50):
        t, cam2target = draw(i)
        wanted = flange_poses(cam2target, X, Z, setup)
        knots = np.unique(np.r_[np.arange(0, len(t), KNOT_SAMPLES), len(t) - 1])
        q, solved = home, []
        for j in knots:
            q, gap = reaching(chain, wanted[j], q)
            if gap > 1e-6 or np.any(np.abs(q - home) > limit):
                break
            solved.append(q)
        if len(solved) == len(knots):
            break
    else:
        raise HandEyeError(f"the simulated {chain.name} could not reach scan {i + 1}'s move: a shorter stand-off or "
                           "another arm")
    Q = np.array(solved)
    q_t = joints_at(t[knots], Q, t)
    cam_true = invert(predicted_target2cam(X, Z, true.forward(q_t), setup))
    reported = q_t + np.radians(rng.normal(0.0, joint_noise_deg, q_t.shape))
    return t, cam_true, chain.forward(reported), reported


def _crossings(points: NDArray[np.float64], t: NDArray[np.float64], cam2target: NDArray[np.float64]
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """When each of the board's ``points`` crosses the camera's view plane (y = 0) along the camera's
    poses ``cam2target`` at times ``t`` (NaN when it never does), and the point in the camera frame
    then: the sign change between samples, then Newton on the interpolated move."""
    move = Trajectory(t, cam2target)

    def in_camera(T):  # the points in the camera frame at poses T (one per point)
        return np.einsum("mji,mj->mi", T[:, :3, :3], points - T[:, :3, 3])

    y = np.einsum("tj,tjm->tm", cam2target[:, :3, 1], points.T[None] - cam2target[:, :3, 3:])  # (T, points)
    change = (y[:-1] * y[1:]) <= 0
    has = change.any(axis=0)
    j = np.argmax(change, axis=0)
    m = np.arange(len(points))
    y0, y1 = y[j, m], y[j + 1, m]
    tc = np.where(has, t[j] + (t[j + 1] - t[j]) * y0 / np.where(y0 != y1, y0 - y1, 1.0), t[0])
    rate = (y1 - y0) / (t[j + 1] - t[j])
    for _ in range(3):
        tc = tc - in_camera(move.at(tc))[:, 1] / np.where(rate != 0, rate, 1.0)
    return np.where(has, tc, np.nan), in_camera(move.at(tc))


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
    the board at the time ``starts[i] + r / line_rate`` (camera clock), where the camera truly was
    then (``cam_true``), each pixel the board's printed pattern averaged over ``supersample`` x
    ``supersample`` points of it, with ``noise_grey`` of sensor noise. Off the printed sheet the
    background is mid grey."""
    if scene.cam_true is None or scene.board is None:
        raise InputMismatchError("render_scan draws a chessboard along the camera's true move: a scene from "
                                 "linescan_scene without points=")
    rng = np.random.default_rng(rng)
    cols, rows, square = scene.board
    texture = Chessboard(cols, rows, square).texture(texels_per_m=12000.0)
    n = supersample
    u = (np.arange(scene.width * n) + 0.5) / n - 0.5
    t = scene.starts[i] + ((np.arange(int(scene.lines[i]) * n) + 0.5) / n - 0.5) / scene.line_rate + scene.clock_offset
    xn = _undistorted(u, scene.focal, scene.cx, scene.k1)
    cam2target = scene.cam_true.at(t)  # the camera per sub-row
    R, C = cam2target[:, :3, :3], cam2target[:, :3, 3]
    map_u = np.empty((len(t), len(u)), np.float32)
    map_v = np.empty_like(map_u)
    for a in range(0, len(t), 256):  # each pixel's ray R @ (xn, 0, 1) met with the board's plane, in blocks of sub-rows
        b = slice(a, a + 256)
        d = [R[b, k, 0:1] * xn[None] + R[b, k, 2:3] for k in range(3)]
        lam = -C[b, 2:3] / d[2]
        map_u[b] = texture.u0 + (C[b, 0:1] + lam * d[0]) * texture.scale
        map_v[b] = texture.v0 + (C[b, 1:2] + lam * d[1]) * texture.scale
    fine = cv2.remap(texture.image, map_u, map_v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=128)
    img = cv2.resize(fine, (scene.width, int(scene.lines[i])), interpolation=cv2.INTER_AREA).astype(float)
    img += rng.normal(0.0, noise_grey, img.shape)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def write_linescan_session(folder: str | Path, scene: LineScanScene, nominal_focal: float | None = None,
                           rng: np.random.Generator | int | None = None) -> Path:
    """Write a simulated line-scan capture as a session folder (docs/guide.md): ``images/sNN.png`` (the
    rendered scans, :func:`render_scan`), ``images.csv`` (``image, time``: each scan's row 0 on the
    camera's clock), ``poses.csv`` (``time`` on the robot's clock, then the controller's flange
    poses: the trajectory; quat_wxyz, mm, deg), with an arm ``joints.csv`` (``time``, then the
    joint angles in degrees), ``session.yaml`` (``linescan:`` with the width, the
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
    times = [repr(float(t)) for t in scene.trajectory.times]
    write_pose_table(out / "poses.csv", times, scene.trajectory.flange2base, "quat_wxyz", "mm", "deg", id_column="time")
    focal = float(round(1.03 * scene.focal if nominal_focal is None else nominal_focal, 1))
    spec = {"setup": scene.setup, "target": scene.target_spec,
            "linescan": {"width": scene.width, "line_rate": float(scene.line_rate), "focal": focal},
            "poses": {"file": "poses.csv", "format": "quat_wxyz", "length_unit": "mm", "angle_unit": "deg"},
            "images": {"file": "images.csv"}}
    if scene.joints is not None:  # the trajectory's joint angles as the controller reports them, degrees
        write_joint_table(out / "joints.csv", times, scene.joints, id_column="time")
        spec["joints"] = {"file": "joints.csv", "unit": "deg", "arm": scene.arm}
    atomic_write(out / "session.yaml", yaml.safe_dump(spec, sort_keys=False))
    info = setup_info(scene.setup)
    truth = {"setup": scene.setup, info.x_name: scene.X.tolist(), info.z_name: scene.Z.tolist(),
             "focal_px": scene.focal, "cx_px": scene.cx, "k1": scene.k1, "clock_offset_s": scene.clock_offset}
    if scene.chain_true is not None:
        truth |= {"arm": scene.arm, "table_true": scene.chain_true.table.tolist()}
    atomic_write(out / "ground_truth.yaml", yaml.safe_dump(truth, sort_keys=False))
    return out


def simulate_command(request: SimulateRequest) -> str:
    """``handeye simulate --sensor line_scan`` (the line-scan camera's registration's ``simulate`` hook):
    a line-scan session of a chessboard written to ``request.out``; returns what was written, in words."""
    if request.robot != "arm" or request.target is not None:
        raise InputMismatchError("--sensor line_scan simulates a 6-axis arm (its controller's poses, or with --arm its "
                                 "joint angles) and a chessboard; leave --robot and --target out")
    sc = linescan_scene(request.poses, request.setup, request.seed, arm=request.arm)
    write_linescan_session(request.out, sc, rng=request.seed)
    arm = f", {request.arm}'s joint angles along the trajectory in joints.csv (the arm 1-3 mm off its nominal table)" \
        if request.arm else ""
    return (f"wrote line-scan session {request.out} ({request.poses} scans of a {sc.board[0]} x {sc.board[1]} chessboard, "
            f"{request.setup}, {sc.width} px at {sc.line_rate:.0f} lines/s, the robot's clock {1e3 * sc.clock_offset:.0f} ms "
            f"after the camera's{arm}); ground truth in {Path(request.out) / 'ground_truth.yaml'}")
