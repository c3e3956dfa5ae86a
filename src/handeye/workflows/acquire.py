"""Capture loops: the robot moves, the camera shoots, handeye decides when it has enough.

:func:`acquire` drives a :class:`Robot` and a :class:`Camera` (two small protocols) through a
capture: it moves to a pose, lets the robot settle, grabs an image, detects the target at once
(retaking, then skipping a view without it), records the pose the robot reports, and writes the
image and the pose into an ordinary session folder after every view (so a stopped capture keeps
what it has and resumes where it stopped). Each next pose is the candidate view that reduces the
predicted error of X most (:mod:`handeye.planning.poses`'s information of the pixel refinement), with X,
Z and the pixel noise re-estimated from what was measured so far; the capture stops when the
predicted std of X (robot accuracy included) reaches the target, or at ``max_poses``. Then the
session is calibrated as ``handeye calibrate`` does.

Backends (:func:`make_robot`, :func:`make_camera`):

* ``sim``: the simulator's robot (pose-dependent kinematic errors, heavy-tailed noise) and camera
  (rendered images): the whole loop runs on any machine; seeded, every view is reproducible.
* ``manual[:FILE]``: the operator moves the robot; handeye prints the next pose to reach, in the
  robot's own format, and reads the pose the robot reports from the terminal (or from FILE, which
  the robot program rewrites).
* ``ur:IP``: a Universal Robots arm through ``ur_rtde`` (``pip install 'handeye[ur]'``): each move
  is confirmed by the operator unless ``yes``, speed and acceleration are capped, ``dry_run``
  prints the moves without making them. UR reports its TCP: set the TCP to the flange (zero) or
  calibrate the TCP pose.
* cameras: ``opencv:INDEX|URL|FILE`` (OpenCV's VideoCapture), ``genicam:PRODUCER.cti``
  (``harvesters``, ``pip install 'handeye[genicam]'``), ``folder:PATH`` (images in name order).

Only ``sim``, ``manual`` (driven by a script) and ``folder`` run in the tests; ``ur`` and
``genicam`` are exercised against stand-ins of their libraries, never against hardware.
"""

from __future__ import annotations

import hashlib
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Protocol, TextIO

import numpy as np
import yaml
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from .._shared.io import atomic_write, check_output_folder, write_png
from .._shared.lazy import lazy_module
from .._shared.progress import Progress
from ..errors import HandEyeError
from ..estimation.uncertainty import robot_accuracy_cov
from ..frames.metrics import std_deg_mm
from ..frames.poses import format_poses, parse_poses, pose_columns
from ..frames.setups import check_setup, flange_poses, predicted_target2cam, setup_info
from ..geometry.se3 import make_transform, perturb
from ..io.session import SESSION_FILE, SessionError, load_session, write_session
from ..options import ROBOT_ACCURACY
from ..pipelines.calibration import calibrate, calibrate_poses
from ..planning.poses import candidate_views, choose_next, reprojection_information
from ..result import Calibration
from ..sensors.camera import solve_pnp, target_from_spec
from ..sensors.camera.render import Renderer, target_texture
from ..simulate import default_camera

cv2 = lazy_module("cv2")

__all__ = ["Robot", "Camera", "SimWorld", "SimRobot", "SimCamera", "ManualRobot", "FolderCamera", "VideoCamera",
           "GenICamCamera", "URRobot", "make_robot", "make_camera", "acquire", "Acquisition", "capture_views"]


class Robot(Protocol):
    """What :func:`acquire` needs of a robot. Poses are rows in the robot's own format."""

    pose_format: str  #: a :func:`handeye.parse_poses` format, e.g. 'rotvec' (UR) or 'euler:ZYX' (KUKA)
    length_unit: str
    angle_unit: str

    def move_to(self, pose: NDArray[np.float64]) -> None:
        """Move the flange to ``pose`` (one row in the robot's format) and return when there."""

    def current_pose(self) -> NDArray[np.float64]:
        """The flange pose the robot reports now (one row in its format)."""


class Camera(Protocol):
    """What :func:`acquire` needs of a camera."""

    def grab(self) -> NDArray[np.uint8]:
        """One fresh image (grayscale or BGR)."""


def _digest_rng(seed: int, *arrays: NDArray[np.float64]) -> np.random.Generator:
    """A generator seeded by ``seed`` and the bytes of ``arrays``: the same pose gets the same noise
    whatever came before it (a resumed capture repeats an uninterrupted one)."""
    h = hashlib.sha256(np.int64(seed).tobytes() + b"".join(np.round(np.asarray(a, float), 9).tobytes() for a in arrays))
    return np.random.default_rng(int.from_bytes(h.digest()[:8], "little"))


@dataclass
class SimWorld:
    """A simulated cell: the true X and Z, the target, the camera, and the robot's errors.

    The robot reaches a commanded pose up to a smooth, pose-dependent error (kinematic errors:
    ``kinematic_deg``, ``kinematic_mm`` at most, varying with where the flange is) and reports the
    commanded pose with Student-t noise (``noise_deg``, ``noise_mm``, 3 degrees of freedom); the
    camera renders the target from the true pose with ``noise_px`` of feature noise.
    """

    setup: str
    X: NDArray[np.float64]
    Z: NDArray[np.float64]
    target_spec: dict
    image_size: tuple[int, int] = (640, 480)
    seed: int = 0
    kinematic_deg: float = 0.02
    kinematic_mm: float = 0.3
    noise_deg: float = 0.01
    noise_mm: float = 0.03
    noise_px: float = 0.2
    K: NDArray[np.float64] = field(default=None)
    dist: NDArray[np.float64] = field(default=None)

    def __post_init__(self) -> None:
        self.setup = check_setup(self.setup)
        if self.K is None:
            self.K, self.dist = default_camera(self.image_size)
        rng = np.random.default_rng([self.seed, 7])
        self._kin = rng.normal(size=(6, 6))  # the kinematic error's smooth dependence on the pose

    @classmethod
    def default(cls, setup: str = "eye_in_hand", seed: int = 0, target: dict | None = None) -> "SimWorld":
        """A cell like handeye's realistic scenes: a camera ~6 cm off the flange looking along it at a
        board 0.45 m below (eye-in-hand), or on a stand 0.7 m from a board on the flange (eye-to-hand)."""
        spec = target or {"type": "chessboard", "cols": 9, "rows": 6, "square": 0.025}
        rng = np.random.default_rng([seed, 3])
        obj = target_from_spec(spec).object_points()
        centre = 0.5 * (obj.min(axis=0) + obj.max(axis=0))
        tilt = Rotation.from_rotvec(rng.normal(0, np.radians(4), 3)).as_matrix()
        yaw = Rotation.from_euler("z", rng.uniform(-180, 180), degrees=True).as_matrix()
        down = Rotation.from_euler("x", 180, degrees=True).as_matrix()
        if setup_info(setup).camera_on_flange:
            X = make_transform(yaw @ tilt, rng.uniform(-0.06, 0.06, 3) * [1, 1, 0.5])
            Z = make_transform(down, np.array([0.5, 0.0, 0.0]) - down @ centre)
        else:
            Z = make_transform(down @ tilt, [0.02, -0.01, 0.03])
            X = make_transform(yaw @ Rotation.from_euler("x", -100, degrees=True).as_matrix(), [0.5, 0.7, 0.6])
        return cls(setup, X, Z, spec, seed=seed)

    def true_pose(self, commanded: NDArray[np.float64]) -> NDArray[np.float64]:
        """Where the flange really is when ``commanded`` was asked for."""
        feat = np.r_[commanded[:3, 3], Rotation.from_matrix(commanded[:3, :3]).as_rotvec() / np.pi]
        e = np.tanh(self._kin @ feat)  # smooth in the pose, within +-1
        rot = np.radians(self.kinematic_deg) * e[:3]
        return perturb(commanded, rot, 1e-3 * self.kinematic_mm * e[3:])

    def reported(self, commanded: NDArray[np.float64]) -> NDArray[np.float64]:
        """What the controller reports at ``commanded``: the command with heavy-tailed noise."""
        rng = _digest_rng(self.seed, commanded)
        rot = np.radians(self.noise_deg) * rng.standard_t(3, 3)
        return perturb(commanded, rot, 1e-3 * self.noise_mm * rng.standard_t(3, 3))


class SimRobot:
    """The simulated robot of a :class:`SimWorld` (poses as quat_wxyz in m)."""

    pose_format, length_unit, angle_unit = "quat_wxyz", "m", "rad"

    def __init__(self, world: SimWorld) -> None:
        self.world = world
        self.commanded: NDArray[np.float64] | None = None

    def move_to(self, pose: NDArray[np.float64]) -> None:
        self.commanded = parse_poses(np.atleast_2d(pose), self.pose_format, self.length_unit, self.angle_unit)[0]

    def current_pose(self) -> NDArray[np.float64]:
        if self.commanded is None:
            raise HandEyeError("the simulated robot has not moved yet")
        return format_poses(self.world.reported(self.commanded)[None], self.pose_format)[0]


class SimCamera:
    """The simulated camera: the target rendered from where the simulated robot really is."""

    def __init__(self, world: SimWorld, robot: SimRobot) -> None:
        self.world, self.robot = world, robot
        self.renderer = Renderer(world.K, world.dist, world.image_size)
        self.texture = target_texture(target_from_spec(world.target_spec))

    def grab(self) -> NDArray[np.uint8]:
        w = self.world
        true = w.true_pose(self.robot.commanded)
        t2c = predicted_target2cam(w.X, w.Z, true[None], w.setup)[0]
        return self.renderer.render(self.texture, t2c, rng=_digest_rng(w.seed + 1, true), noise_px=w.noise_px)


class ManualRobot:
    """The operator moves the robot: ``move_to`` shows the pose to reach and waits for the pose the
    robot then reports, typed (or pasted) on ``inp`` or written into ``pose_file`` (read when it
    changes), as the numbers of the robot's format separated by commas or spaces; ``current_pose``
    returns it. The camera grabs only after that, with the robot where it reported."""

    def __init__(self, pose_format: str, length_unit: str = "mm", angle_unit: str = "deg",
                 inp: TextIO | None = None, out: TextIO | None = None, pose_file: str | Path | None = None,
                 poll_s: float = 0.2, timeout_s: float = 600.0) -> None:
        format_poses(np.eye(4)[None], pose_format, length_unit, angle_unit)  # a clear error for a bad format or unit
        self.pose_format, self.length_unit, self.angle_unit = pose_format, length_unit, angle_unit
        self.inp, self.out = inp or sys.stdin, out or sys.stdout
        self.pose_file = None if pose_file is None else Path(pose_file)
        self.poll_s, self.timeout_s = poll_s, timeout_s
        self._last_file = self.pose_file.read_text() if self.pose_file and self.pose_file.is_file() else None
        self._reported: NDArray[np.float64] | None = None

    def move_to(self, pose: NDArray[np.float64]) -> None:
        cols = pose_columns(self.pose_format)
        values = ", ".join(f"{c}={v:.4f}" for c, v in zip(cols, pose))
        self.out.write(f"move the robot to ({self.pose_format}, {self.length_unit}, {self.angle_unit}): {values}\n")
        self.out.flush()
        self._reported = self._read()

    def _parse(self, text: str) -> NDArray[np.float64]:
        try:
            v = np.array([float(x) for x in text.replace(",", " ").split()])
        except ValueError:
            v = np.zeros(0)
        cols = pose_columns(self.pose_format)
        if len(v) != len(cols):
            raise HandEyeError(f"cannot read the robot pose {text.strip()!r}: give the {len(cols)} numbers "
                               f"{', '.join(cols)}")
        parse_poses(v[None], self.pose_format, self.length_unit, self.angle_unit)  # a clear error for bad values
        return v

    def _read(self) -> NDArray[np.float64]:
        if self.pose_file is None:
            self.out.write(f"then the pose the robot reports ({', '.join(pose_columns(self.pose_format))}): ")
            self.out.flush()
            line = self.inp.readline()
            if not line:
                raise KeyboardInterrupt  # end of input: stop as on Ctrl-C, keeping what was captured
            return self._parse(line)
        start = time.monotonic()
        while time.monotonic() - start < self.timeout_s:
            text = self.pose_file.read_text() if self.pose_file.is_file() else None
            if text is not None and text != self._last_file and text.strip():
                self._last_file = text
                return self._parse(text)
            time.sleep(self.poll_s)
        raise HandEyeError(f"{self.pose_file}: no new pose within {self.timeout_s:g} s")

    def current_pose(self) -> NDArray[np.float64]:
        if self._reported is None:
            raise HandEyeError("no pose reported yet")
        return self._reported


class FolderCamera:
    """Images from a folder, one per ``grab``, in name order (replays; tests)."""

    def __init__(self, folder: str | Path) -> None:
        folder = Path(folder)
        if not folder.is_dir():
            raise HandEyeError(f"{folder}: no such image folder")
        self.paths = sorted(p for p in folder.iterdir() if p.suffix.lower() in (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"))
        self.next = 0

    def grab(self) -> NDArray[np.uint8]:
        if self.next >= len(self.paths):
            raise HandEyeError(f"the image folder has no more images (all {len(self.paths)} used)")
        img = cv2.imread(str(self.paths[self.next]), cv2.IMREAD_UNCHANGED)
        self.next += 1
        if img is None:
            raise HandEyeError(f"{self.paths[self.next - 1]}: cannot read the image")
        return img


class VideoCamera:
    """OpenCV's VideoCapture (a USB/UVC index, a stream URL or a video file). A few frames are read
    and dropped before each grab, so that the image is taken after the robot stopped, not buffered."""

    def __init__(self, source: str, flush: int = 3) -> None:
        self.cap = cv2.VideoCapture(int(source) if source.isdigit() else source)
        if not self.cap.isOpened():
            raise HandEyeError(f"cannot open the camera {source!r} with OpenCV (an index, a stream URL or a video file)")
        self.flush = flush

    def grab(self) -> NDArray[np.uint8]:
        for _ in range(self.flush):
            self.cap.grab()
        ok, img = self.cap.read()
        if not ok or img is None:
            raise HandEyeError("the camera gave no image (disconnected, or the end of a video file)")
        return img


class GenICamCamera:
    """A GenICam camera through ``harvesters`` and the vendor's GenTL producer (``.cti`` file)."""

    def __init__(self, cti: str, harvester_module: Any = None) -> None:
        if harvester_module is None:
            try:
                from harvesters import core as harvester_module  # noqa: PLC0415  (an optional extra)
            except ImportError:
                raise HandEyeError("GenICam cameras need the harvesters package: pip install 'handeye[genicam]'") from None
        if not Path(cti).is_file():
            raise HandEyeError(f"{cti}: no such GenTL producer (.cti) file; your camera vendor's SDK installs one")
        self.h = harvester_module.Harvester()
        self.h.add_file(str(cti))
        self.h.update()
        if not self.h.device_info_list:
            raise HandEyeError(f"no GenICam camera found through {cti}")
        self.ia = self.h.create(0)
        self.ia.start()

    def grab(self) -> NDArray[np.uint8]:
        with self.ia.fetch() as buffer:
            comp = buffer.payload.components[0]
            return np.array(comp.data.reshape(comp.height, comp.width, -1).squeeze(), dtype=np.uint8)


class URRobot:
    """A Universal Robots arm through ``ur_rtde``: poses as UR writes them (x, y, z in m and a
    rotation vector in rad: 'rotvec'); linear moves at capped speed, each confirmed on ``inp``
    unless ``yes``; ``dry_run`` prints the moves and reports the commanded pose, needing neither
    ``ur_rtde`` nor a controller (issue 60, item 11)."""

    pose_format, length_unit, angle_unit = "rotvec", "m", "rad"
    MAX_SPEED, MAX_ACCEL = 0.25, 0.5  # m/s, m/s^2: a calibration needs no haste

    def __init__(self, host: str, speed: float = 0.1, accel: float = 0.3, yes: bool = False, dry_run: bool = False,
                 inp: TextIO | None = None, out: TextIO | None = None, control: Any = None, receive: Any = None) -> None:
        self.speed, self.accel = min(float(speed), self.MAX_SPEED), min(float(accel), self.MAX_ACCEL)
        self.yes, self.dry_run = yes, dry_run
        self.inp, self.out = inp or sys.stdin, out or sys.stdout
        self._commanded: NDArray[np.float64] | None = None
        if (control is None or receive is None) and not dry_run:  # a dry run moves nothing and reads back its commands
            try:
                import rtde_control  # noqa: PLC0415  (an optional extra)
                import rtde_receive  # noqa: PLC0415
            except ImportError:
                raise HandEyeError("Universal Robots arms need the ur_rtde package: pip install 'handeye[ur]'") from None
            try:
                receive = rtde_receive.RTDEReceiveInterface(host)
                control = rtde_control.RTDEControlInterface(host)
            except RuntimeError as exc:
                raise HandEyeError(f"cannot reach the UR controller at {host} ({exc})") from None
        self.control, self.receive = control, receive

    def move_to(self, pose: NDArray[np.float64]) -> None:
        pose = [float(v) for v in pose]
        text = ", ".join(f"{v:.4f}" for v in pose)
        if self.dry_run:
            self.out.write(f"dry run: would move linearly to [{text}] at {self.speed:g} m/s\n")
            self._commanded = np.array(pose)
            return
        if not self.yes:
            self.out.write(f"move linearly to [{text}] at {self.speed:g} m/s? [y/N] ")
            self.out.flush()
            if self.inp.readline().strip().lower() not in ("y", "yes"):
                raise KeyboardInterrupt  # the operator declined: stop, keeping what was captured
        if not self.control.moveL(pose, self.speed, self.accel):
            raise HandEyeError(f"the robot refused the move to [{text}] (out of reach, or a protective stop)")

    def current_pose(self) -> NDArray[np.float64]:
        if self.dry_run and self._commanded is not None:
            return self._commanded
        if self.receive is None:
            raise HandEyeError("dry run: no pose commanded yet, and no controller connected to read one from")
        return np.array(self.receive.getActualTCPPose(), dtype=float)


def make_robot(spec: str, world: SimWorld | None = None, pose_format: str = "quat_wxyz", length_unit: str = "mm",
               angle_unit: str = "deg", speed: float = 0.1, yes: bool = False, dry_run: bool = False) -> Robot:
    """A robot from a backend name: ``sim`` (needs ``world``), ``manual`` or ``manual:POSE_FILE`` (in
    ``pose_format`` and the units), ``ur:HOST`` (at ``speed`` m/s, capped; ``yes``: no confirmation
    before each move; ``dry_run``: print the moves only)."""
    kind, _, arg = spec.partition(":")
    if kind == "sim":
        if world is None:
            raise HandEyeError("the sim robot needs a simulated world")
        return SimRobot(world)
    if kind == "manual":
        return ManualRobot(pose_format, length_unit, angle_unit, pose_file=arg or None)
    if kind == "ur":
        if not arg:
            raise HandEyeError("--robot ur:HOST: give the controller's address, e.g. ur:192.168.1.10")
        return URRobot(arg, speed=speed, yes=yes, dry_run=dry_run)
    raise HandEyeError(f"robot backend {spec!r}; use sim, manual[:POSE_FILE] or ur:HOST")


def make_camera(spec: str, world: SimWorld | None = None, robot: Robot | None = None) -> Camera:
    """A camera from a backend name: ``sim`` (with the sim robot), ``opencv:INDEX|URL|FILE``,
    ``genicam:PRODUCER.cti``, ``folder:PATH``."""
    kind, _, arg = spec.partition(":")
    if kind == "sim":
        if world is None or not isinstance(robot, SimRobot):
            raise HandEyeError("the sim camera goes with the sim robot (--robot sim)")
        return SimCamera(world, robot)
    if kind == "opencv":
        return VideoCamera(arg or "0")
    if kind == "genicam":
        return GenICamCamera(arg)
    if kind == "folder":
        return FolderCamera(arg)
    raise HandEyeError(f"camera backend {spec!r}; use sim, opencv:INDEX|URL|FILE, genicam:PRODUCER.cti or folder:PATH")


@dataclass
class Acquisition:
    """What :func:`acquire` did: the session written, why it stopped, the predicted std after each
    view, and the calibration of the session (None when it was not calibrated)."""

    folder: Path
    n_views: int
    stopped: str
    predicted_std: list[list[float]]  #: per view captured, the predicted std of X (deg x3, mm x3)
    skipped: list[str] = field(default_factory=list)  #: views without the target, in words
    calibration: Calibration | None = None
    resumed_from: int = 0  #: views already in the folder when this run started


def _pixel_noise(rms: list[float], n_points: int) -> float:
    """Pixel noise from the per-image PnP RMS (a PnP fit absorbs 6 of the 2M coordinates)."""
    dof = max(2 * n_points - 6, 1)
    return float(np.median(rms)) * np.sqrt(2 * n_points / dof)


def _predicted_std(info: NDArray[np.float64], sigma_px: float, X: NDArray[np.float64],
                   accuracy: tuple[float, float] | None) -> NDArray[np.float64]:
    """The std of X (deg x3, mm x3) the pixel refinement will report on views of ``info``, the
    robot's absolute accuracy included as calibrate adds it."""
    ridge = 1e-9 * max(float(np.trace(info)), 1.0) * np.eye(12)
    cov = sigma_px**2 * np.linalg.inv(info + ridge)[:6, :6]
    if accuracy is not None:
        cov = cov + robot_accuracy_cov(X, accuracy)
    return std_deg_mm(cov)


def _stop(cal: Calibration | None, within: Callable) -> str | None:
    """Why the capture stops on ``cal`` (calibrate's answer on the views so far): its std is ``within``
    the target, or the robot's accuracy it holds is not (more views do not narrow that); else None."""
    if cal is None or cal.std is None or within(cal.std):
        return "target std reached"
    floor = (cal.std_sources or {}).get("robot_accuracy")
    return "robot accuracy" if floor is not None and not within(floor) else None


def _write_state(folder: Path, setup: str, spec: dict, names: list[str], rows: list, robot: Robot,
                 K: NDArray[np.float64] | None, dist: NDArray[np.float64] | None) -> None:
    """session.yaml and poses.csv with the poses exactly as the robot reported them (not re-formatted:
    a resumed capture reads back the very numbers an uninterrupted one used)."""
    write_session(folder, setup, spec, names, None, robot.pose_format, robot.length_unit, robot.angle_unit,
                  camera=None if K is None else (K, dist), comment="captured by handeye acquire", rows=np.array(rows))


def _resume(folder: Path, setup: str, robot: Robot) -> tuple[list[str], list]:
    """The views of an interrupted capture in ``folder`` (names and pose rows as written), or none."""
    if not (folder / SESSION_FILE).is_file():
        return [], []
    session = load_session(folder)
    if session.setup != setup:
        raise SessionError(f"{folder} holds an {session.setup} capture; this one is {setup}: choose another folder")
    ri = session.robot_input
    if ri is None or (ri.format, ri.length_unit, ri.angle_unit) != (robot.pose_format, robot.length_unit, robot.angle_unit):
        raise SessionError(f"{folder}: its poses are written as {ri.format if ri else '?'}, the robot's as "
                           f"{robot.pose_format}: resume with the same robot backend")
    return list(session.image_names), [list(v) for v in ri.values]


def _observe_one(target, img: NDArray[np.uint8], K, dist) -> tuple[NDArray[np.float64], float] | None:
    gray = img if img.ndim == 2 else cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    det = target.detect(gray)
    if det is None:
        return None
    sol = solve_pnp(det, K, dist)
    return None if sol is None else (sol[0], sol[1])


#: When the std calibrate reports is still above the target, calibrate again after this many more views.
RECHECK_AFTER = 2


def _check_target_std(target_std, X0, accuracy) -> None:
    """The target std checked against the floor the robot's absolute accuracy sets (no number of
    views goes below it: a constant robot error is absorbed into X)."""
    try:
        deg, mm = (float(v) for v in target_std)
    except (TypeError, ValueError):
        raise HandEyeError(f"target std {target_std!r}: give (degrees, millimetres)") from None
    if not (deg > 0 and mm > 0):
        raise HandEyeError(f"target std ({deg:g}, {mm:g}): give positive numbers (deg, mm)")
    if accuracy is None:
        return
    cov = robot_accuracy_cov(np.asarray(X0, dtype=float), accuracy)
    floor = std_deg_mm(cov)
    if floor[:3].max() > deg or floor[3:].max() > mm:
        raise HandEyeError(
            f"the target std {deg:g} deg / {mm:g} mm is below what the robot's absolute accuracy allows here "
            f"({floor[:3].max():.3f} deg / {floor[3:].max():.3f} mm per axis, assumed {accuracy[0]:g} deg / "
            f"{accuracy[1]:g} mm: a constant robot error goes into X whole, and X's translation moves by its rotation "
            f"times the camera's distance); ask for less, or give the robot's real accuracy (--robot-accuracy)")


#: Progress of a capture: a file beside the session's, so a stopped capture resumes with the same choices.
STATE_FILE = "acquire.yaml"


def _load_state(folder: Path, names: list[str]) -> tuple[list[int], list[str]]:
    """The candidates already tried and the views skipped, of a capture resumed in ``folder``."""
    path = folder / STATE_FILE
    if not names:
        return [], []
    if not path.is_file():
        raise SessionError(f"{folder} holds a session but no {STATE_FILE}: it was not captured by handeye acquire; "
                           "choose an empty folder")
    state = yaml.safe_load(path.read_text()) or {}
    return [int(k) for k in state.get("tried", [])], [str(v) for v in state.get("skipped", [])]


def _save_state(folder: Path, tried: list[int], skipped: list[str], std: list[list[float]]) -> None:
    atomic_write(folder / STATE_FILE, yaml.safe_dump({"tried": tried, "skipped": skipped, "predicted_std": std},
                                                      sort_keys=False))


def _save_image(folder: Path, name: str, img: NDArray[np.uint8]) -> None:
    (folder / "images").mkdir(parents=True, exist_ok=True)
    write_png(folder / "images" / name, img)


def _model(measured: list, setup: str, X0, Z0, noise_px: float, n_points: int):
    """X, Z and the pixel noise from the views measured so far (the rough ones before three views)."""
    if len(measured) < 3:
        return X0, Z0, noise_px
    f2b = np.array([m[0] for m in measured])
    t2c = np.array([m[1] for m in measured])
    try:
        cal = calibrate_poses(f2b, t2c, setup, refine="none", check=False, progress=False, uncertainty=False)
    except HandEyeError:  # the first views may not determine X yet (one rotation axis)
        return X0, Z0, noise_px
    return cal.X, cal.Z, _pixel_noise([m[2] for m in measured], n_points)


def _grab_target(camera: Camera, target, K, dist, retakes: int):
    """An image with the target found, and its PnP pose and RMS; None after ``retakes`` retakes."""
    for _ in range(1 + retakes):
        img = camera.grab()
        seen = _observe_one(target, img, K, dist)
        if seen is not None:
            return img, seen
    return None


def acquire(
    robot: Robot,
    camera: Camera,
    out: str | Path,
    setup: str,
    target_spec: dict,
    K: NDArray[np.float64],
    dist: NDArray[np.float64],
    image_size: tuple[int, int],
    X0: NDArray[np.float64],
    Z0: NDArray[np.float64],
    target_std: tuple[float, float] = (0.05, 0.5),
    max_poses: int = 20,
    min_poses: int = 6,
    standoff: float = 0.5,
    tilt_max_deg: float = 45.0,
    margin_px: float = 20.0,
    robot_accuracy: tuple[float, float] | None = ROBOT_ACCURACY,
    noise_px: float = 0.3,
    retakes: int = 1,
    settle_s: float = 0.0,
    calibrate_session: bool = True,
    progress: bool = True,
    on_view: Callable[[int], None] | None = None,
) -> Acquisition:
    """Capture a session with ``robot`` and ``camera`` into ``out`` until X is known well enough.

    Parameters
    ----------
    setup, target_spec, K, dist, image_size
        The cell: the setup, the target (a session.yaml ``target:`` mapping) and the camera.
    X0, Z0 : (4, 4)
        Rough X and Z (from a drawing: a few cm and degrees off is fine) for the first views; then
        X and Z come from the views captured.
    target_std : (deg, mm)
        Stop when the predicted std of X (per axis, robot accuracy included) is within both.
    max_poses, min_poses : int
        At most ``max_poses`` views; never stop on the target std before ``min_poses``.
    standoff, tilt_max_deg, margin_px
        The candidate views (:func:`handeye.planning.poses.candidate_views`).
    robot_accuracy : (deg, mm) or None
        As :func:`handeye.calibrate` adds it to the std (the floor the target std must allow).
    noise_px : float
        Pixel noise assumed until three views measure it.
    retakes, settle_s
        Grabs per view before it is skipped; seconds to wait after each move.
    on_view : callable, optional
        Called with the number of views captured after each (a KeyboardInterrupt from it stops the
        capture as Ctrl-C does).

    Returns
    -------
    Acquisition
        ``stopped``: 'target std reached', 'robot accuracy' (the robot's error the views show puts
        X's std above the target whatever more views add: see the calibration's notes), 'max poses',
        'no candidate left' or 'interrupted' (the views captured are kept; run again with the same
        ``out`` to resume).
    """
    setup = check_setup(setup)
    _check_target_std(target_std, X0, robot_accuracy)
    cap = _Capture.open(out, setup, target_spec, robot, camera, K, dist)
    cam2target = candidate_views(cap.obj, cap.K, image_size, cap.dist, standoff, tilt_max_deg, margin_px)
    weight = np.r_[np.full(3, standoff**2), np.ones(3)]
    stopped, cal, next_check, resumed = "max poses", None, 0, len(cap.names)
    bar = Progress(max_poses, "capturing", progress)
    bar.update(resumed)
    within = lambda std: std[:3].max() <= target_std[0] and std[3:].max() <= target_std[1]  # noqa: E731
    try:
        while len(cap.measured) < max_poses:
            X, Z, sigma = _model(cap.measured, setup, X0, Z0, noise_px, len(cap.obj))
            info = cap.information(X, Z)
            if len(cap.measured) >= 3:
                std = _predicted_std(info, sigma, X, robot_accuracy)
                cap.history.append([float(v) for v in std])
                if len(cap.measured) >= max(min_poses, next_check) and within(std):
                    # the prediction says enough: calibrate, and stop when the std calibrate reports agrees
                    cal = calibrate(cap.folder, progress=False, robot_accuracy=robot_accuracy) if calibrate_session else None
                    if (reason := _stop(cal, within)) is not None:
                        stopped = reason
                        break
                    cal, next_check = None, len(cap.measured) + RECHECK_AFTER  # the data's spread asks for more
            flange2base = flange_poses(cam2target, X, Z, setup)
            exclude = np.zeros(len(cam2target), bool)
            exclude[cap.tried] = True
            k = choose_next(info, reprojection_information(flange2base, X, Z, setup, cap.obj, cap.K), weight, exclude)
            if k is None:
                stopped = "no candidate left"
                break
            cap.tried.append(k)
            if cap.view(flange2base[k], k, retakes, settle_s):
                bar.update()
                if on_view is not None:
                    on_view(len(cap.names))
    except KeyboardInterrupt:
        stopped = "interrupted"
    finally:
        bar.close()
    if cal is None and calibrate_session and stopped != "interrupted" and len(cap.names) >= 3:
        cal = calibrate(cap.folder, progress=False, robot_accuracy=robot_accuracy)
    return Acquisition(cap.folder, len(cap.names), stopped, cap.history, cap.skipped, cal, resumed)


@dataclass
class _Capture:
    """A capture in progress: the session folder, the views so far (names, poses as reported, and
    per view the parsed pose, the PnP pose and its RMS), the candidates tried, the views skipped."""

    folder: Path
    setup: str
    target_spec: dict
    robot: Robot
    camera: Camera
    K: NDArray[np.float64]
    dist: NDArray[np.float64]
    target: Any = None
    obj: NDArray[np.float64] = None
    names: list[str] = field(default_factory=list)
    rows: list = field(default_factory=list)
    measured: list = field(default_factory=list)
    tried: list[int] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    history: list[list[float]] = field(default_factory=list)

    @classmethod
    def open(cls, out, setup, target_spec, robot, camera, K, dist) -> "_Capture":
        """A new capture in ``out``, or the stopped one there, its views observed again from their images."""
        folder = check_output_folder(out)
        target = target_from_spec(target_spec)
        cap = cls(folder, setup, target_spec, robot, camera, np.asarray(K, dtype=float),
                  np.asarray(dist, dtype=float).ravel(), target, target.object_points())
        cap.names, cap.rows = _resume(folder, setup, robot)
        cap.tried, cap.skipped = _load_state(folder, cap.names)
        for name, row in zip(cap.names, cap.rows):
            seen = _observe_one(target, cv2.imread(str(folder / "images" / name), cv2.IMREAD_UNCHANGED), cap.K, cap.dist)
            if seen is None:
                raise SessionError(f"{folder / 'images' / name}: the target is no longer found in a captured view")
            cap.measured.append((cap._parsed(row), *seen))
        return cap

    def _parsed(self, row) -> NDArray[np.float64]:
        r = self.robot
        return parse_poses(np.atleast_2d(row), r.pose_format, r.length_unit, r.angle_unit)[0]

    def information(self, X, Z) -> NDArray[np.float64]:
        """The pixel refinement's information (12, 12) of the views so far, under X and Z."""
        if not self.measured:
            return np.zeros((12, 12))
        f2b = np.array([m[0] for m in self.measured])
        return reprojection_information(f2b, X, Z, self.setup, self.obj, self.K).sum(axis=0)

    def view(self, flange2base: NDArray[np.float64], k: int, retakes: int, settle_s: float) -> bool:
        """Move to ``flange2base`` (candidate ``k``), grab until the target is found (or skip the
        view), record image and reported pose; the session and the state are written at once."""
        r = self.robot
        r.move_to(format_poses(flange2base[None], r.pose_format, r.length_unit, r.angle_unit)[0])
        if settle_s > 0:
            time.sleep(settle_s)
        got = _grab_target(self.camera, self.target, self.K, self.dist, retakes)
        if got is None:
            self.skipped.append(f"candidate {k}: the target was not found in {1 + retakes} image(s)")
            _save_state(self.folder, self.tried, self.skipped, self.history)
            return False
        reported = np.asarray(r.current_pose(), dtype=float)
        name = f"{len(self.names):03d}.png"
        _save_image(self.folder, name, got[0])
        self.names.append(name)
        self.rows.append(list(reported))
        self.measured.append((self._parsed(reported), *got[1]))
        _write_state(self.folder, self.setup, self.target_spec, self.names, self.rows, r, self.K, self.dist)
        _save_state(self.folder, self.tried, self.skipped, self.history)
        return True


def capture_views(robot: Robot, camera: Camera, out: str | Path, setup: str, target_spec: dict,
                  K: NDArray[np.float64], dist: NDArray[np.float64], flange2base: NDArray[np.float64],
                  retakes: int = 1, settle_s: float = 0.0) -> Path:
    """Capture a session at the given robot poses into ``out`` (views without the target are left
    out): e.g. a second, independent capture to verify a calibration on."""
    folder = check_output_folder(out)
    if (folder / SESSION_FILE).exists():
        raise HandEyeError(f"{folder} already holds a session; choose an empty folder")
    target = target_from_spec(target_spec)
    names, rows = [], []
    for T in flange2base:
        robot.move_to(format_poses(T[None], robot.pose_format, robot.length_unit, robot.angle_unit)[0])
        if settle_s > 0:
            time.sleep(settle_s)
        got = _grab_target(camera, target, K, dist, retakes)
        if got is None:
            continue
        name = f"{len(names):03d}.png"
        _save_image(folder, name, got[0])
        names.append(name)
        rows.append(list(np.asarray(robot.current_pose(), dtype=float)))
    if len(names) < 3:
        raise HandEyeError(f"only {len(names)} of {len(flange2base)} verification views show the target")
    _write_state(folder, setup, target_spec, names, rows, robot, K, dist)
    return folder
