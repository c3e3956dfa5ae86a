"""The capture behind ``handeye live``'s page, without the web: devices, views on disk, calibrations.

:class:`LiveCapture` runs three threads beside the web server's event loop, so that frames keep
flowing while the robot moves or a calibration runs:

* the camera thread grabs frames (at most ``fps`` a second), finds the target in a downscaled copy
  (:func:`preview_frame`: the preview only, drawn on the page) and hands each frame to ``on_frame``;
  it also grabs the image of a view when one is taken (with the robot's pose read before and after);
* the robot thread makes the moves asked for and reads the robot's pose twice a second;
* the worker thread writes each view into the session folder (the image atomically, then
  ``poses.csv`` and ``session.yaml`` atomically: a view is in the session once its row is), finds
  the target in it at full size as ``handeye calibrate`` does (a view without the target is not
  taken: its image goes to ``rejected/``), removes views (their images go to ``removed/``, never
  deleted), has the session calibrated after every change exactly as ``handeye calibrate`` does
  (:func:`page_calibration`: :func:`handeye.pipelines.folders.calibrate_session`, the detections from
  the cache) in a process of its own (a fit holds the interpreter's lock: in a thread it would stall
  the frames; a process that dies is started again), and plans the next pose (the candidate view
  that narrows X most, as ``handeye acquire`` chooses).

Every change calls ``on_change``; :meth:`LiveCapture.snapshot` is the whole state as plain data (what
a page loaded at any time shows). A camera or robot that fails, a detection or a calibration that
fails: the state says so in words and keeps what it has; nothing here raises into the caller's loop.
"""

from __future__ import annotations

import gc
import multiprocessing
import queue
import threading
import time
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable

import numpy as np
import yaml
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..._shared.io import atomic_write, check_output_folder, write_png
from ..._shared.lazy import lazy_module
from ..._shared.processes import exit_with_parent
from ...errors import HandEyeError
from ...estimation.verdict import headline
from ...frames.motions import relative_motions
from ...frames.poses import format_poses, parse_poses, pose_columns
from ...frames.setups import check_setup, flange_poses, setup_info
from ...io.session import SESSION_FILE, SessionError, load_session, write_session
from ...options import ROBOT_ACCURACY, CalibrationOptions
from ...pipelines.calibration import calibrate_poses
from ...pipelines.folders import calibrate_session
from ...planning.poses import candidate_views, choose_next, reprojection_information
from ...report import write_calibration
from ...result import Calibration
from ...sensors.camera import solve_pnp, target_from_spec
from ...sensors.camera.detect import detect_images, detection_cache_dir, unchanged_files_remembered
from ...sensors.camera.pnp import project_points
from ...sensors.camera.targets import Detection
from ..acquire import SimCamera

cv2 = lazy_module("cv2")

__all__ = ["LiveCapture", "LiveView", "StillSimCamera", "PoseFileRobot", "preview_frame", "page_calibration",
           "calibration_summary", "enough", "STATE_FILE", "MIN_VIEWS"]

#: The capture's own record beside the session: the views removed (names, pose rows), the std after each calibration.
STATE_FILE = "live.yaml"
#: Views a calibration needs.
MIN_VIEWS = 3
#: Messages kept for the page.
MAX_MESSAGES = 12
#: How long a move waits for the next pose to be chosen after the views changed (seconds).
PLAN_WAIT_S = 60.0
#: Two poses read around a grab that differ by more than this (deg, mm) mean the robot moved.
STILL_DEG, STILL_MM = 0.05, 0.5


@dataclass
class LiveView:
    """One view taken: its image's name, the pose as the robot reported it (a row in its format),
    the parsed flange pose, the PnP pose and its RMS, and when it was written (``time.time()``)."""

    name: str
    row: list[float]
    flange2base: NDArray[np.float64]
    target2cam: NDArray[np.float64]
    rms: float
    taken_at: float


class StillSimCamera:
    """The simulated camera for a live page: an image is rendered once per robot pose and given
    again while the robot stands there (the simulated cell is still; rendering 1280x1024 costs
    ~0.5 s, which a real camera does not)."""

    def __init__(self, camera: SimCamera) -> None:
        self.camera = camera
        self._key: bytes | None = None
        self._image: NDArray[np.uint8] | None = None

    def grab(self) -> NDArray[np.uint8]:
        commanded = self.camera.robot.commanded
        if commanded is None:
            raise HandEyeError("the simulated robot has not moved yet: the camera sees nothing")
        key = np.asarray(commanded, dtype=float).tobytes()
        if key != self._key:
            self._image, self._key = self.camera.grab(), key
        return self._image.copy()


class PoseFileRobot:
    """A robot the operator moves (``--robot manual:POSE_FILE``): its pose is read from a file its
    program rewrites (the numbers of ``pose_format`` in the units, separated by commas or spaces)."""

    def __init__(self, path: str | Path, pose_format: str, length_unit: str = "mm", angle_unit: str = "deg") -> None:
        format_poses(np.eye(4)[None], pose_format, length_unit, angle_unit)  # a clear error for a bad format or unit
        self.path, self.pose_format, self.length_unit, self.angle_unit = Path(path), pose_format, length_unit, angle_unit

    def move_to(self, pose: NDArray[np.float64]) -> None:
        raise HandEyeError("this robot is moved by hand: jog it to the pose shown, then take the view")

    def current_pose(self) -> NDArray[np.float64]:
        if not self.path.is_file():
            raise HandEyeError(f"{self.path}: no pose file yet (the robot program writes its pose there)")
        text = self.path.read_text()
        cols = pose_columns(self.pose_format)
        try:
            v = np.array([float(x) for x in text.replace(",", " ").split()])
        except ValueError:
            v = np.zeros(0)
        if len(v) != len(cols):
            raise HandEyeError(f"{self.path}: cannot read the pose {text.strip()[:60]!r}: give the {len(cols)} numbers "
                               f"{', '.join(cols)}")
        parse_poses(v[None], self.pose_format, self.length_unit, self.angle_unit)  # a clear error for bad values
        return v


def _in_words(exc: BaseException) -> str:
    """An exception as one line for the page (handeye's own errors say what to do; others name their type)."""
    text = str(exc).strip() or type(exc).__name__
    return text if isinstance(exc, (HandEyeError, OSError)) else f"{type(exc).__name__}: {text}"


def _missed_and_axes(pts: NDArray[np.float64], det: Detection, all_points: NDArray[np.float64], K, dist):
    """The target points not detected and the target's axes, projected through the PnP pose of the
    detected ones (full-size pixels), or (None, None) without a pose."""
    sol = solve_pnp(Detection(det.ids, pts, det.object_points), K, dist)
    if sol is None or not np.all(np.isfinite(sol[0])):  # too few points, or all on a line: no pose
        return None, None
    found = np.asarray(det.object_points, dtype=float)
    gap = np.min(np.linalg.norm(all_points[:, None, :] - found[None, :, :], axis=2), axis=1)
    missed = project_points(sol[0], all_points[gap > 1e-9], K, dist)
    size = float(np.ptp(all_points[:, :2], axis=0).max()) * 0.3
    axes = project_points(sol[0], np.array([[0, 0, 0], [size, 0, 0], [0, size, 0], [0, 0, size]], float), K, dist)
    return missed, axes


def preview_frame(image: NDArray[np.uint8], target, K: NDArray[np.float64], dist: NDArray[np.float64],
                  detect_width: int = 320, frame_width: int = 640, quality: int = 80) -> tuple[dict[str, Any], bytes]:
    """One frame for the page: the image as JPEG (at most ``frame_width`` wide) and what the preview
    found of the target in it, in that JPEG's pixels.

    The preview searches a copy at most ``detect_width`` wide (the full-size search of a 1280x1024
    image takes ~0.5 s with the accurate detectors; this one a tenth of that), and projects the
    points it missed and the target's axes through the PnP pose of those it found. It is a preview:
    a view taken is searched at full size, as ``handeye calibrate`` does.

    Returns
    -------
    header : dict
        ``width``, ``height`` (of the JPEG), ``found`` (bool), ``n_found``, ``n_total``, ``corners``,
        ``missed`` (lists of [x, y]), ``axes`` (origin, x, y, z tips, or None).
    jpeg : bytes
    """
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    h, w = gray.shape[:2]
    all_points = target.object_points()
    s = min(1.0, detect_width / w)
    small = gray if s >= 1.0 else cv2.resize(gray, (max(1, round(w * s)), max(1, round(h * s))), interpolation=cv2.INTER_AREA)
    try:
        det = target.detect(small)
    except cv2.error:  # a detector's assertion on a degenerate image: no target
        det = None
    fs = min(1.0, frame_width / w)
    shown = image if fs >= 1.0 else cv2.resize(image, (max(1, round(w * fs)), max(1, round(h * fs))), interpolation=cv2.INTER_AREA)
    ok, jpeg = cv2.imencode(".jpg", shown, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise HandEyeError("could not encode the camera's image as JPEG")
    to_shown = lambda p: None if p is None else ((np.asarray(p) + 0.5) * fs - 0.5).round(2).tolist()  # noqa: E731
    header: dict[str, Any] = {"width": shown.shape[1], "height": shown.shape[0], "found": det is not None,
                              "n_found": 0 if det is None else len(det), "n_total": len(all_points),
                              "corners": [], "missed": [], "axes": None}
    if det is not None:
        pts = (np.asarray(det.image_points, dtype=float) + 0.5) / (small.shape[1] / w) - 0.5
        missed, axes = _missed_and_axes(pts, det, all_points, K, dist)
        header.update(corners=to_shown(pts), missed=to_shown(missed) or [], axes=to_shown(axes))
    return header, jpeg.tobytes()


@dataclass
class _Job:
    kind: str
    future: Future
    args: tuple = ()


def _done(future: Future, ok: bool, text: str) -> None:
    if not future.done():
        future.set_result({"ok": ok, "message": text})


class LiveCapture:
    """A capture driven from a page: see the module's text. ``start`` it, ``stop`` it at the end.

    Parameters
    ----------
    folder : path
        The session folder (new, or one ``handeye live`` or ``handeye acquire`` wrote: its views come back).
    robot, camera
        :mod:`handeye.workflows.acquire` backends.
    setup, target_spec, K, dist, image_size
        The cell, as :func:`handeye.workflows.acquire.acquire` takes it.
    X0, Z0 : (4, 4)
        Rough X and Z for the planner's first poses.
    results : path, optional
        Where ``finish`` writes the report (default: ``FOLDER-results`` beside the folder).
    target_std : (deg, mm)
        "Enough" when X's std per axis is within these (and the verdict is good).
    can_move : bool
        Whether the page may move the robot (a robot backend that moves).
    fps, detect_width, frame_width
        Frames a second at most; the width the preview searches at; the width of the frames sent.
    isolated : bool
        Calibrate in a process of its own (default); False: in the worker thread.
    log : callable, optional
        Called with each message the page shows, as one line (the command prints them: the server's log).
    on_change, on_frame
        Called (from the threads) after every change of the state, and with each frame (header, JPEG).

    Examples
    --------
    >>> import tempfile
    >>> from handeye.workflows.acquire import SimWorld, SimRobot, SimCamera
    >>> world = SimWorld.default("eye_in_hand", seed=1)
    >>> robot = SimRobot(world)
    >>> live = LiveCapture(tempfile.mkdtemp() + "/cell", robot, StillSimCamera(SimCamera(world, robot)), "eye_in_hand",
    ...                    world.target_spec, world.K, world.dist, world.image_size, world.X, world.Z, isolated=False)
    >>> live.start(move_first=True)
    >>> live.take().result(30)["ok"], live.move_next().result(30)["ok"], live.take().result(30)["ok"]
    (True, True, True)
    >>> [v["name"] for v in live.snapshot()["views"]]
    ['000.png', '001.png']
    >>> live.stop()
    """

    def __init__(self, folder: str | Path, robot, camera, setup: str, target_spec: dict, K, dist,
                 image_size: tuple[int, int], X0, Z0, *, results: str | Path | None = None,
                 target_std: tuple[float, float] = (0.05, 0.5), min_views: int = 6,
                 robot_accuracy: tuple[float, float] | None = ROBOT_ACCURACY, standoff: float = 0.5,
                 can_move: bool = True, fps: float = 8.0, detect_width: int = 320, frame_width: int = 640,
                 isolated: bool = True, log: Callable[[str], None] | None = None,
                 on_change: Callable[[], None] | None = None,
                 on_frame: Callable[[dict[str, Any], bytes], None] | None = None) -> None:
        self.folder = check_output_folder(folder)
        self.results = Path(results) if results else self.folder.with_name(self.folder.name + "-results")
        self.robot, self.camera, self.setup = robot, camera, check_setup(setup)
        self.target_spec, self.target = target_spec, target_from_spec(target_spec)
        self.obj = self.target.object_points()
        self.K, self.dist = np.asarray(K, dtype=float), np.asarray(dist, dtype=float).ravel()
        self.image_size, self.X0, self.Z0 = tuple(image_size), np.asarray(X0, float), np.asarray(Z0, float)
        self.target_std, self.min_views, self.robot_accuracy = tuple(target_std), int(min_views), robot_accuracy
        self.standoff, self.can_move, self.fps = float(standoff), bool(can_move), float(fps)
        self.detect_width, self.frame_width = int(detect_width), int(frame_width)
        self.log = log or (lambda text: None)
        self.on_change = on_change or (lambda: None)
        self.on_frame = on_frame or (lambda header, jpeg: None)
        self.views: list[LiveView] = []
        self.removed: list[dict[str, Any]] = []  #: the views removed: name and pose row
        self.history: list[dict[str, Any]] = []
        self.calibration: dict[str, Any] | None = None
        self.next_pose: dict[str, Any] | None = None
        self.coverage: dict[str, Any] | None = None
        self.finished: dict[str, Any] | None = None
        self.robot_state: dict[str, Any] = {"columns": pose_columns(robot.pose_format), "values": None, "error": None,
                                            "moving": False, "format": robot.pose_format,
                                            "units": [robot.length_unit, robot.angle_unit]}
        self.camera_state: dict[str, Any] = {"error": None, "last_frame_at": None}
        self.messages: list[dict[str, Any]] = []
        self.busy: str | None = None
        self.planning = True  #: the next pose is being chosen again (the views changed)
        self._cam2target = candidate_views(self.obj, self.K, self.image_size, self.dist, self.standoff)
        self._tried: list[int] = []
        self._next_k: int | None = None
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._work: queue.Queue[_Job] = queue.Queue()
        self._takes: queue.Queue[_Job] = queue.Queue()
        self._moves: queue.Queue[_Job] = queue.Queue()
        self._dirty = False
        self._threads: list[threading.Thread] = []
        self._thumbs: dict[str, bytes] = {}
        self.isolated = bool(isolated)
        self._enough_said = False
        self._search_width = self.detect_width
        self._pool: ProcessPoolExecutor | None = None

    # -- the page's actions (each returns a Future of {"ok": bool, "message": str}) ----------------------------
    def take(self) -> Future:
        """Take a view: an image grabbed now and the pose the robot reports, kept when the target is in it."""
        return self._queued(self._takes, "take")

    def remove(self, name: str) -> Future:
        """Remove view ``name`` from the session (its image moves to ``removed/``)."""
        return self._queued(self._work, "remove", (str(name),))

    def move_next(self) -> Future:
        """Move the robot to the planner's next pose."""
        return self._queued(self._moves, "move")

    def finish(self) -> Future:
        """Write the calibration of the views so far (result files and report.html) into ``results``."""
        return self._queued(self._work, "finish")

    def _queued(self, q: queue.Queue, kind: str, args: tuple = ()) -> Future:
        future: Future = Future()
        if self._stop.is_set():
            _done(future, False, "the capture has stopped")
        else:
            q.put(_Job(kind, future, args))
        return future

    # -- life cycle ---------------------------------------------------------------------------------------------
    def start(self, move_first: bool = False) -> None:
        """Read back the views already in the folder, then start the threads; ``move_first``: move the
        robot to the planner's first pose (the simulated cell: its camera sees nothing before)."""
        self._resume()
        if detection_cache_dir() is None:
            self._say("warn", "the detection cache is off: each calibration finds the target in every image again (slower)")
        self._dirty = bool(self.views)
        self._plan(force=True)
        if self.isolated:  # the calibration's process started now (~2 s of imports), not at the third view
            self._pool = _calibration_pool()
            self._pool.submit(ready)
        if move_first and self.can_move:  # before the camera starts: it would see nothing before
            self._guarded(self._move, Future())
        for name, loop in (("camera", self._camera_loop), ("robot", self._robot_loop), ("worker", self._worker_loop)):
            t = threading.Thread(target=loop, name=f"handeye-live-{name}", daemon=True)
            t.start()
            self._threads.append(t)

    def stop(self, timeout: float = 10.0) -> None:
        """Stop the threads (a device call in progress is left to end on its own: they are daemons)."""
        self._stop.set()
        for t in self._threads:
            t.join(timeout)
        for q in (self._work, self._takes, self._moves):
            while not q.empty():
                _done(q.get_nowait().future, False, "the capture has stopped")
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    # -- state --------------------------------------------------------------------------------------------------
    def snapshot(self) -> dict[str, Any]:
        """The whole state as plain data (JSON): what the page shows."""
        info = setup_info(self.setup)
        with self._lock:
            return {
                "session": str(self.folder.resolve()), "results": str(self.results.resolve()), "setup": str(self.setup),
                "x_name": info.x_name, "target_std": list(self.target_std), "min_views": self.min_views,
                "can_move": self.can_move,
                "views": [{"name": v.name, "rms": round(v.rms, 4), "row": [float(x) for x in v.row], "taken_at": v.taken_at}
                          for v in self.views],
                "removed": [d["name"] for d in self.removed], "calibration": self.calibration, "history": list(self.history),
                "coverage": self.coverage, "next_pose": self.next_pose, "planning": self.planning, "robot": dict(self.robot_state),
                "camera": dict(self.camera_state), "messages": list(self.messages), "finished": self.finished,
                "busy": self.busy,
            }

    def thumbnail(self, name: str) -> bytes | None:
        """A JPEG thumbnail of a view's image (taken or removed), or None for no such view."""
        with self._lock:
            known = {v.name for v in self.views} | {d["name"] for d in self.removed}
        if name not in known:
            return None
        if name not in self._thumbs:
            path = self.folder / "images" / name
            if not path.is_file():
                path = self.folder / "removed" / name
            img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
            if img is None:
                return None
            s = 200.0 / img.shape[1]
            ok, buf = cv2.imencode(".jpg", cv2.resize(img, None, fx=s, fy=s, interpolation=cv2.INTER_AREA),
                                   [cv2.IMWRITE_JPEG_QUALITY, 80])
            self._thumbs[name] = buf.tobytes()
        return self._thumbs[name]

    def _say(self, level: str, text: str) -> None:
        with self._lock:
            self.messages = (self.messages + [{"t": time.time(), "level": level, "text": text}])[-MAX_MESSAGES:]
        self.log(f"handeye live: {text}")
        self._changed()

    def _changed(self) -> None:
        try:
            self.on_change()
        except Exception:  # the page's side closed: the capture goes on  # noqa: BLE001
            pass

    # -- the session folder ----------------------------------------------------------------------------------------
    def _parsed(self, row) -> NDArray[np.float64]:
        r = self.robot
        return parse_poses(np.atleast_2d(np.asarray(row, dtype=float)), r.pose_format, r.length_unit, r.angle_unit)[0]

    def _resume(self) -> None:
        """The views of a capture stopped in the folder (its poses as written), each observed again."""
        state = self.folder / STATE_FILE
        if state.is_file():
            saved = yaml.safe_load(state.read_text()) or {}
            self.removed = [{"name": str(d["name"]), "row": [float(x) for x in d["row"]]} for d in saved.get("removed", [])]
            self.history = [dict(h) for h in saved.get("history", [])]
        if not (self.folder / SESSION_FILE).is_file():
            return
        session = load_session(self.folder)
        if session.setup != self.setup:
            raise SessionError(f"{self.folder} holds an {session.setup} capture; this one is {self.setup}: choose another folder")
        ri, r = session.robot_input, self.robot
        if ri is None or (ri.format, ri.length_unit, ri.angle_unit) != (r.pose_format, r.length_unit, r.angle_unit):
            raise SessionError(f"{self.folder}: its poses are written as {ri.format if ri else '?'} "
                               f"({ri.length_unit if ri else '?'}, {ri.angle_unit if ri else '?'}), the robot's as "
                               f"{r.pose_format} ({r.length_unit}, {r.angle_unit}): continue with the same robot backend")
        paths = [self.folder / "images" / n for n in session.image_names]
        for name, row, res in zip(session.image_names, ri.values, detect_images(paths, self.target, progress=False)):
            sol = None if res.detection is None else solve_pnp(res.detection, self.K, self.dist)
            if sol is None:
                raise SessionError(f"{self.folder / 'images' / name}: the target is not found in a view of the session "
                                   f"({res.error or 'no pose'}): remove its row from poses.csv, or choose another folder")
            taken = (self.folder / "images" / name).stat().st_mtime
            self.views.append(LiveView(name, [float(x) for x in row], self._parsed(row), sol[0], float(sol[1]), taken))
        self._say("info", f"continued the capture in {self.folder}: {len(self.views)} views")

    def _next_name(self) -> str:
        """A name no image in the folder has (taken, removed or rejected: none is ever overwritten)."""
        used = [int(p.stem) for sub in ("images", "removed", "rejected") if (self.folder / sub).is_dir()
                for p in (self.folder / sub).iterdir() if p.stem.isdigit()]
        return f"{max(used, default=-1) + 1:03d}.png"

    def _write_session(self) -> None:
        """poses.csv and session.yaml of the views now (atomically), then the capture's own record (with
        the removed views' poses: nothing is lost). No view left: no session files (a session has a view)."""
        r = self.robot
        if not self.views:
            for name in ("poses.csv", SESSION_FILE):
                (self.folder / name).unlink(missing_ok=True)
            self._write_record()
            return
        write_session(self.folder, self.setup, self.target_spec, [v.name for v in self.views], None, r.pose_format,
                      r.length_unit, r.angle_unit, camera=(self.K, self.dist), comment="captured by handeye live",
                      rows=np.array([v.row for v in self.views], dtype=float))
        self._write_record()

    def _accept(self, image: NDArray[np.uint8], row: NDArray[np.float64], future: Future) -> None:
        """A view grabbed: its image written, the target found at full size (or the image set aside
        in ``rejected/``), then its row in poses.csv."""
        name = self._next_name()
        path = self.folder / "images" / name
        write_png(path, image)
        res = detect_images([path], self.target, jobs=1, progress=False)[0]
        sol = None if res.detection is None else solve_pnp(res.detection, self.K, self.dist)
        if sol is None:
            (self.folder / "rejected").mkdir(exist_ok=True)
            path.replace(self.folder / "rejected" / name)
            why = res.error or "too few points for a pose"
            _done(future, False, f"not taken: {why} in the image (kept as rejected/{name}); move the robot so that "
                  "the whole target is in view")
            self._say("warn", f"view not taken: {why} (the image is in rejected/{name})")
            return
        view = LiveView(name, [float(x) for x in row], self._parsed(row), sol[0], float(sol[1]), time.time())
        with self._lock:
            self.views.append(view)
            self._write_session()
            view.taken_at = time.time()
            self._dirty, self.finished = True, None
            self._stale_plan()
        _done(future, True, f"view {name} taken ({len(res.detection)} points, RMS {sol[1]:.2f} px)")
        self._say("info", f"took view {name}: {len(self.views)} views ({len(res.detection)} points, PnP RMS {sol[1]:.2f} px)")

    def _remove(self, name: str, future: Future) -> None:
        with self._lock:
            keep = [v for v in self.views if v.name != name]
            if len(keep) == len(self.views):
                _done(future, False, f"no view {name} to remove (removed already?)")
                return
            (self.folder / "removed").mkdir(exist_ok=True)
            gone = next(v for v in self.views if v.name == name)
            self.views, self.removed = keep, self.removed + [{"name": name, "row": gone.row}]
            self._write_session()  # the row goes first: the session never names an image that is not there
            (self.folder / "images" / name).replace(self.folder / "removed" / name)
            self._dirty, self.finished = True, None
            self._stale_plan()
        _done(future, True, f"view {name} removed (its image is in removed/{name})")
        self._say("info", f"removed view {name}: {len(self.views)} views")

    def _stale_plan(self) -> None:
        """The views changed: the next pose is chosen again (after the calibration), none offered meanwhile
        (a move now would go where the planner chose before the last view: to the same pose again)."""
        self._next_k, self.next_pose, self.planning = None, None, True

    def _finish(self, future: Future) -> None:
        if len(self.views) < MIN_VIEWS:
            _done(future, False, f"nothing to write yet: at least {MIN_VIEWS} views are needed")
            return
        with self._lock:
            self.busy = "writing the report"
        self._changed()
        try:
            done = self._in_process(self.results)
        finally:
            with self._lock:
                self.busy = None
        if done.get("files") is None:
            _done(future, False, f"nothing written: {done.get('error')}")
            self._say("error", f"nothing written: {done.get('error')}")
            return
        n = done["n_views"]
        with self._lock:
            self.finished = {"files": done["files"], "folder": str(self.results.resolve()), "n_views": n,
                             "session": str(self.folder.resolve())}
        _done(future, True, f"wrote {', '.join(done['files'])} into {self.results}")
        self._say("info", f"wrote the calibration of {n} views and its report into {self.results}")

    # -- threads ---------------------------------------------------------------------------------------------------
    def _camera_loop(self) -> None:
        period = 1.0 / max(self.fps, 0.1)
        while not self._stop.is_set():
            start = time.monotonic()
            try:
                job = self._takes.get_nowait()
            except queue.Empty:
                job = None
            if job is not None:
                self._guarded(self._grab_view, job.future)
                continue
            self._guarded(self._frame)
            try:  # wait for the next frame, but take a view at once when asked
                job = self._takes.get(timeout=max(0.0, period - (time.monotonic() - start)))
                self._guarded(self._grab_view, job.future)
            except queue.Empty:
                pass

    def _guarded(self, step: Callable, *args) -> None:
        """A step of a thread; whatever it raises is said on the page (and answers its future), never raised."""
        try:
            step(*args)
        except Exception as exc:  # noqa: BLE001  (a device, a disk, a fit: the page says which and goes on)
            text = _in_words(exc)
            if args and isinstance(args[-1], Future):
                _done(args[-1], False, text)
            self._say("error", f"{getattr(step, '__name__', 'step').strip('_').replace('_', ' ')}: {text}")

    def _frame(self) -> None:
        try:
            image = self.camera.grab()
        except Exception as exc:  # noqa: BLE001  (a camera that stops: said, retried)
            text = _in_words(exc)
            if self.camera_state["error"] != text:
                with self._lock:
                    self.camera_state["error"] = text
                self._say("error", f"camera: {text}")
            self._stop.wait(1.0)
            return
        captured = time.time()
        width = self._search_width
        header, jpeg = preview_frame(image, self.target, self.K, self.dist, width, self.frame_width)
        if not header["found"]:  # the next frame searches a copy twice as wide (a board at the image's edge, or
            # small), up to the full size, then starts again: a frame without the board costs little
            self._search_width = self.detect_width if width >= image.shape[1] else min(2 * width, image.shape[1])
        header.update(captured_at=captured, searched_width=min(width, image.shape[1]))
        with self._lock:
            recovered = self.camera_state["error"] is not None
            self.camera_state.update(error=None, last_frame_at=captured)
        if recovered:
            self._say("info", "camera: frames again")
        self.on_frame(header, jpeg)

    def _grab_view(self, future: Future) -> None:
        if self.robot_state["moving"]:
            _done(future, False, "not taken: the robot is moving; take the view when it has stopped")
            return
        before = np.asarray(self.robot.current_pose(), dtype=float)
        image = self.camera.grab()
        after = np.asarray(self.robot.current_pose(), dtype=float)
        moved = np.linalg.inv(self._parsed(before)) @ self._parsed(after)
        if (np.degrees(np.linalg.norm(Rotation.from_matrix(moved[:3, :3]).as_rotvec())) > STILL_DEG
                or 1e3 * np.linalg.norm(moved[:3, 3]) > STILL_MM):
            _done(future, False, "not taken: the robot moved while the image was taken; let it stop, then take the view")
            return
        self._work.put(_Job("accept", future, (image, after)))

    def _robot_loop(self) -> None:
        while not self._stop.is_set():
            try:
                job = self._moves.get(timeout=0.5)
            except queue.Empty:
                job = None
            if job is not None:
                self._guarded(self._move, job.future)
            self._read_pose()

    def _read_pose(self) -> None:
        try:
            values, error = [float(v) for v in self.robot.current_pose()], None
        except Exception as exc:  # noqa: BLE001  (a robot that disconnects: said, the capture keeps what it has)
            values, error = None, _in_words(exc)
        with self._lock:
            changed = (values, error) != (self.robot_state["values"], self.robot_state["error"])
            new_error = error is not None and error != self.robot_state["error"]
            self.robot_state.update(values=values, error=error)
        if new_error:
            self._say("error", f"robot: {error}")
        elif changed:
            self._changed()

    def _move(self, future: Future) -> None:
        if not self.can_move:
            _done(future, False, "this robot is moved by hand: jog it to the pose shown")
            return
        end = time.monotonic() + PLAN_WAIT_S  # a move asked right after a view waits for the pose chosen after it
        while self.planning and not self._stop.is_set() and time.monotonic() < end:
            self._stop.wait(0.05)
        with self._lock:
            k, row = self._next_k, None if self.next_pose is None else self.next_pose["values"]
        if k is None:
            _done(future, False, "the planner is choosing the next pose after the last view: move in a moment"
                  if self.planning else "no next pose: the planner has no candidate left")
            return
        with self._lock:
            self.robot_state["moving"] = True
        self._changed()
        try:
            self.robot.move_to(np.asarray(row, dtype=float))
        finally:
            with self._lock:
                self.robot_state["moving"] = False
                if k not in self._tried:
                    self._tried.append(k)
        _done(future, True, "the robot is at the planner's next pose: take the view")
        self._read_pose()
        self._changed()

    def _worker_loop(self) -> None:
        while not self._stop.is_set():
            try:
                job = self._work.get_nowait() if self._dirty else self._work.get(timeout=0.2)
            except queue.Empty:
                job = None
            if job is None:
                if self._dirty:
                    self._guarded(self._calibrate)
                    self._guarded(self._plan)
                continue
            if job.kind == "accept":
                self._guarded(self._accept, *job.args, job.future)
            elif job.kind == "remove":
                self._guarded(self._remove, *job.args, job.future)
            elif job.kind == "finish":
                self._guarded(self._finish, job.future)

    # -- calibration, coverage, the next pose ----------------------------------------------------------------
    def _calibrate(self) -> None:
        """The session calibrated as ``handeye calibrate`` does (in the calibration's process), summarised for the page."""
        with self._lock:
            self._dirty = False
            names = [v.name for v in self.views]
            self.busy = "calibrating"
        self._changed()
        started = time.time()
        try:
            if len(names) < MIN_VIEWS:
                summary = {"n_views": len(names), "error": f"at least {MIN_VIEWS} views are needed ({len(names)} so far)"}
            else:
                summary = self._in_process(None)
        finally:
            with self._lock:
                self.busy = None
        summary.update(views=names, started_at=started, computed_at=time.time())
        with self._lock:
            self.calibration = summary
            if summary.get("std_deg") is not None:
                self.history = [h for h in self.history if h["n"] != len(names)] + [
                    {"n": len(names), "std_deg": max(summary["std_deg"]), "std_mm": max(summary["std_mm"])}]
                self.history.sort(key=lambda h: h["n"])
            self._write_record()
        self._changed()
        if summary.get("enough") and not self._enough_said:  # said once, when it first is
            self._say("info", "enough: " + summary["enough_text"])
        self._enough_said = bool(summary.get("enough"))

    def _in_process(self, results: Path | None) -> dict[str, Any]:
        """:func:`page_calibration` in the calibration's process (started again, once, if it died)."""
        args = (str(self.folder), self.robot_accuracy, self.target_std, self.min_views, None if results is None else str(results))
        if not self.isolated:
            return page_calibration(*args)
        for attempt in (0, 1):
            if self._pool is None:
                self._pool = _calibration_pool()
            try:
                return self._pool.submit(page_calibration, *args).result()
            except BrokenProcessPool:
                self._pool.shutdown(wait=False, cancel_futures=True)
                self._pool = None
                if not attempt:
                    self._say("error", "the calibration's process stopped (killed?): started again")
        # a process that cannot start (a script without `if __name__ == "__main__":` starts itself again)
        self.isolated = False
        self._say("warn", "the calibration's process stopped twice: calibrating in this one from now on (frames may "
                  "stall during a calibration)")
        return page_calibration(*args)

    def _write_record(self) -> None:
        atomic_write(self.folder / STATE_FILE, yaml.safe_dump({"removed": self.removed, "history": self.history},
                                                             sort_keys=False))

    def _model(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """X and Z for the planner: the last calibration's, the views' rough ones, or the given ones."""
        c = self.calibration or {}
        if c.get("X") is not None:
            return np.asarray(c["X"]), np.asarray(c["Z"])
        if len(self.views) >= MIN_VIEWS:
            try:
                cal = calibrate_poses(np.array([v.flange2base for v in self.views]), np.array([v.target2cam for v in self.views]),
                                      self.setup, refine="none", check=False, progress=False, uncertainty=False)
                return cal.X, cal.Z
            except HandEyeError:  # the first views may not determine X yet
                pass
        return self.X0, self.Z0

    def _plan(self, force: bool = False) -> None:
        """The next pose (the candidate view that narrows X most, as ``handeye acquire`` chooses) and the coverage."""
        X, Z = self._model()
        with self._lock:
            views, tried = list(self.views), list(self._tried)
        flange2base = flange_poses(self._cam2target, X, Z, self.setup)
        info = (reprojection_information(np.array([v.flange2base for v in views]), X, Z, self.setup, self.obj, self.K).sum(axis=0)
                if views else np.zeros((12, 12)))
        exclude = np.zeros(len(flange2base), bool)
        exclude[tried] = True
        weight = np.r_[np.full(3, self.standoff**2), np.ones(3)]
        k = choose_next(info, reprojection_information(flange2base, X, Z, self.setup, self.obj, self.K), weight, exclude)
        r = self.robot
        pose = None if k is None else {
            "columns": pose_columns(r.pose_format), "format": r.pose_format, "units": [r.length_unit, r.angle_unit],
            "values": [float(v) for v in format_poses(flange2base[k][None], r.pose_format, r.length_unit, r.angle_unit)[0]],
            "candidate": int(k), "can_move": self.can_move}
        coverage = _coverage(views, self.setup)
        with self._lock:
            if force or not self._dirty:  # else the views changed meanwhile: the plan after the next calibration counts
                self._next_k, self.next_pose, self.coverage, self.planning = k, pose, coverage, False
        self._changed()


def _calibration_pool() -> ProcessPoolExecutor:
    """The calibration's process: spawned (no threads of the server forked into it), and gone with the
    server even when the server is killed outright."""
    return ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"), initializer=exit_with_parent)


def ready() -> bool:
    """Run in the calibration's process at the start: it has the process import what a calibration needs,
    then freezes what the imports made (:func:`gc.freeze`: they live as long as the process, and each full
    collection during a calibration would walk them all). Nothing in any other process."""
    if multiprocessing.parent_process() is not None:
        gc.freeze()
    return True


def page_calibration(folder: str, robot_accuracy, target_std: tuple[float, float], min_views: int,
                     results: str | None = None) -> dict[str, Any]:
    """The session in ``folder`` calibrated as ``handeye calibrate`` does, as plain data for the page
    (:func:`calibration_summary`); ``results``: also write its files and report there (``files``).
    Runs in the calibration's own process: a fit holds the interpreter's lock for most of its time,
    which would stall the frames of a thread beside it."""
    try:
        with unchanged_files_remembered():  # the views' images are written once: not read and hashed again each time
            cal = calibrate_session(folder, CalibrationOptions(robot_accuracy=robot_accuracy), progress=False)
    except HandEyeError as exc:  # e.g. motions about one axis: not yet a calibration, said why
        return {"n_views": None, "error": str(exc)}
    out = calibration_summary(cal, target_std, min_views)
    if results is not None:
        n = len(cal.image_names or [])
        cal = replace(cal, notes=[f"captured by handeye live: {n} views"] + list(cal.notes))
        out["files"] = [p.name for p in write_calibration(cal, results)]
    return out


def calibration_summary(cal: Calibration, target_std: tuple[float, float], min_views: int) -> dict[str, Any]:
    """X, Z, X's std, the verdict, the held-out error and whether it is enough (:func:`enough`), as plain data."""
    info = setup_info(cal.setup)
    std = None if cal.std is None or not np.all(np.isfinite(cal.std)) else np.asarray(cal.std, dtype=float)
    held = {k: (None if v is None else float(v)) for k, v in (cal.prediction_error or {}).items()}
    n = len(cal.image_names or cal.flange2base)
    out: dict[str, Any] = {
        "n_views": n, "error": None, "x_name": info.x_name, "X": np.asarray(cal.X).round(12).tolist(),
        "Z": np.asarray(cal.Z).round(12).tolist(), "t_mm": (1e3 * np.asarray(cal.X)[:3, 3]).round(4).tolist(),
        "rotvec_deg": np.degrees(Rotation.from_matrix(np.asarray(cal.X)[:3, :3]).as_rotvec()).round(5).tolist(),
        "std_deg": None if std is None else std[:3].round(5).tolist(),
        "std_mm": None if std is None else std[3:].round(4).tolist(),
        "verdict": cal.verdict, "headline": headline(cal), "held_out": held,
        "advice": list(cal.diagnostics.advice[:3]) if cal.diagnostics is not None else [],
        "skipped": [list(s) for s in (cal.skipped or [])], "estimator": cal.estimator or cal.method,
    }
    out["enough"], out["enough_text"] = enough(cal, std, n, target_std, min_views)
    return out


def enough(cal: Calibration, std: NDArray[np.float64] | None, n: int, target_std: tuple[float, float],
           min_views: int) -> tuple[bool, str]:
    """Whether to stop, in words: as ``handeye acquire`` stops (X's std within ``target_std``, or held
    above it by the robot's accuracy, which more views do not narrow), with a good verdict and at
    least ``min_views`` views."""
    deg, mm = target_std
    if std is None:
        return False, "X's std is not known yet: take more views, turning the flange about different axes"
    known = f"X's std is {std[:3].max():.3f} deg / {std[3:].max():.2f} mm per axis"
    target = f"the {deg:g} deg / {mm:g} mm asked for"
    within = lambda s: s[:3].max() <= deg and s[3:].max() <= mm  # noqa: E731
    if cal.verdict != "good":
        return False, f"not yet: the verdict is {cal.verdict} ({headline(cal)}); {known}"
    if n < min_views:
        return False, f"not yet: {known}; take at least {min_views} views ({n} so far)"
    if within(std):
        return True, f"{known}, within {target}, and the verdict is good. You can stop: press Finish to write the report"
    floor = (cal.std_sources or {}).get("robot_accuracy")
    if floor is not None and not within(np.asarray(floor, dtype=float)):
        return True, (f"{known}: the robot's accuracy keeps it above {target} whatever more views add, and the "
                      "verdict is good. You can stop: press Finish to write the report")
    return False, f"not yet: {known}, above {target}: take the next pose"


def _coverage(views: list[LiveView], setup: str) -> dict[str, Any] | None:
    """The robot's rotations between every two views: their axes (unit, the sign making z >= 0) and
    angles, and a sentence on how well they spread (X's rotation needs two axes apart, its
    translation rotations well away from zero)."""
    if len(views) < 2:
        return None
    f2b = np.array([v.flange2base for v in views])
    A, _ = relative_motions(f2b, np.array([v.target2cam for v in views]), setup, pairs="all")
    rotvec = Rotation.from_matrix(A[:, :3, :3]).as_rotvec()
    angle = np.linalg.norm(rotvec, axis=1)
    axis = rotvec / np.maximum(angle, 1e-12)[:, None]
    axis = np.where(axis[:, 2:3] < 0, -axis, axis)
    ok = angle > np.radians(0.5)
    spread = 0.0
    if ok.sum() >= 2:
        a = axis[ok]
        spread = float(np.degrees(np.arccos(np.clip(np.abs(a @ a.T), 0, 1))).max())
    deg = np.degrees(angle)
    text = (f"{len(A)} motions between {len(views)} views: rotations of {deg.min():.0f} to {deg.max():.0f} deg "
            f"(median {np.median(deg):.0f}), their axes up to {spread:.0f} deg apart")
    if deg.max() < 10:
        text += "; turn the flange more between views (20 deg and more)"
    elif spread < 30:
        text += "; turn the flange about other axes too"
    return {"axes": axis.round(4).tolist(), "angles_deg": deg.round(2).tolist(), "spread_deg": round(spread, 1),
            "summary": text}
