"""Planning a line-scan camera's capture (``handeye plan --sensor line_scan``): straight scans that
determine X, the line's intrinsics and the clock offset, and the std they would give.

A line-scan camera sees the board only while a straight move carries it across the view plane, so a
plan is a set of moves: per scan where the flange starts and where it ends, at one speed. What
determines X (docs/guide.md, "Line-scan cameras"): the flange turned 10-30 deg about two or three
axes between scans (each turn a new view plane through the board), scans forth and back in turn (a
clock offset shifts a forward scan one way and a backward one the other) and at different distances
(the robot's known change of distance tells the focal length from the distance). The plan draws the
scans as the simulator does (:func:`handeye.pipelines.linescan.simulate.linescan_scene`, about the placements
given) and predicts X's std by calibrating a simulated capture of exactly those scans through the
estimation core, the robot's stated accuracy fitted per scan as calibrate fits it
(:func:`handeye.pipelines.linescan.pipeline.linescan_robot`). The same number of scans at one distance,
turned at most :data:`NARROW_DEG`, is predicted beside it: what the turns and the distances buy.

Examples
--------
>>> import numpy as np
>>> from handeye.geometry.se3 import make_transform
>>> X = make_transform(np.eye(3), [0.0, 0.0, 0.05])                     # the camera on the flange
>>> Z = make_transform(np.diag([1.0, -1.0, -1.0]), [0.6, 0.0, 0.0])     # the board on the table, printed side up
>>> plan = plan_linescan("eye_in_hand", X, Z, n_scans=10, rng=0)
>>> plan.moves.shape, bool(np.all(plan.std_data[3:] < plan.std_narrow[3:]))   # turns and distances place X
((10, 2, 4, 4), True)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ...errors import DegenerateMotionError, InputMismatchError
from ...estimation.core import estimate
from ...frames.setups import check_setup
from ...geometry.se3 import make_transform
from ...options import ROBOT_ACCURACY
from ...sensors.camera.targets import target_from_spec
from ...sensors.linescan.model import LINESCAN_NOISE_PX, LineScanCorners
from ...simulate import DEFAULT_TARGETS
from ..kinds import PlanRequest, SensorPlan
from .pipeline import linescan_robot
from .simulate import LINESCAN_CAMERA, LineScanScene, linescan_scene

__all__ = ["LineScanPlan", "plan_linescan", "NARROW_DEG", "FEWEST_SCANS", "plan_command"]

#: The comparison capture turns the camera at most this much (deg) from the board's normal, at one distance.
NARROW_DEG = 10.0
#: The fewest scans a plan takes (10-15 to trust X).
FEWEST_SCANS = 6
#: The board's frame as the simulator scans it (+z towards the camera) from a camera plan's (OpenCV's
#: board frame: the printed side faces the camera along its -z).
_TOWARDS_CAMERA = make_transform(np.diag([1.0, -1.0, -1.0]), np.zeros(3))


@dataclass(frozen=True)
class LineScanPlan:
    """A line-scan capture's plan: per scan the flange's pose where its straight move starts and ends
    (N, 2, 4, 4; in path order, forth and back in turn), the speed (m/s) and the line rate that
    gives square pixels at the planned distance (rows/s); X's predicted std as calibrate would report
    it (deg, mm per axis; the robot's stated accuracy in it) and from the scans alone, and the latter
    for the same number of scans at one distance turned at most :data:`NARROW_DEG` (inf where those
    cannot determine X)."""

    setup: str
    moves: NDArray[np.float64]
    speed: float
    line_rate: float
    distance: float
    std_X: NDArray[np.float64]
    std_data: NDArray[np.float64]
    std_narrow: NDArray[np.float64]
    robot_accuracy: tuple[float, float] | None
    cone_deg: float


def _predicted_std(scene: LineScanScene, focal: float, noise_px: float, accuracy: tuple[float, float] | None
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """X's std from the simulated capture ``scene`` (the corners' noise, an exact robot whose stated
    accuracy is fitted per scan as calibrate fits it), as calibrate reports it and from the scans
    alone; inf where they do not determine X."""
    model = LineScanCorners(scene.setup, scene.names, scene.corners, scene.target_points, scene.starts, scene.line_rate,
                            scene.trajectory, focal, scene.width, noise_px)
    try:
        cal = estimate(model, linescan_robot(model.flange2base_ref, accuracy), held_out=False)  # the std alone: no folds
    except DegenerateMotionError:
        return np.full(6, np.inf), np.full(6, np.inf)
    return np.asarray(cal.std, dtype=float), np.asarray(cal.std_sources["data"], dtype=float)


def plan_linescan(setup: str, X: NDArray[np.float64], Z: NDArray[np.float64], n_scans: int = 12, *,
                  points: NDArray[np.float64] | None = None, focal: float | None = None, width: int | None = None,
                  distance: float = 0.4, speed: float = 0.2, cone_deg: float = 30.0, noise_px: float = LINESCAN_NOISE_PX,
                  robot_accuracy: tuple[float, float] | None = ROBOT_ACCURACY,
                  rng: np.random.Generator | int | None = 0) -> LineScanPlan:
    """Straight scans for a line-scan camera's capture of a planar target, and X's predicted std.

    Parameters
    ----------
    setup : {'eye_in_hand', 'eye_to_hand'}
    X, Z : (4, 4)
        Rough placements: the camera on the flange (``cam2flange``, its view plane ``y = 0``) and the
        board in the base (eye-in-hand), or the camera in the base and the board on the flange
        (eye-to-hand); the board's frame as a camera plan's (OpenCV's: its printed side faces the
        camera along the board's -z).
    n_scans : int
        Scans to capture (at least :data:`FEWEST_SCANS`; 10-15 to trust X).
    points : (n, 3), optional
        The target's points (its frame, m; z = 0): default the simulator's chessboard (9 x 6 inner
        corners, 20 mm squares).
    focal, width : optional
        The camera's focal length (px) and pixels along the line; default the simulator's.
    distance, speed : float
        The camera's distance from the board at the middle of the scans (m; each scan within 25% of
        it) and the move's speed (m/s).
    cone_deg : float
        The camera's view direction within this angle of the board's normal.
    noise_px : float
        The corners' noise along the line (px).
    robot_accuracy : (deg, mm) or None
        The robot's absolute accuracy per axis, in the predicted std as calibrate puts it.

    Returns
    -------
    LineScanPlan
    """
    setup = check_setup(setup)
    if n_scans < FEWEST_SCANS:
        raise InputMismatchError(f"n_scans={n_scans}: a line-scan plan needs at least {FEWEST_SCANS} scans (10-15 to "
                                 "trust X)")
    if not (distance > 0 and speed > 0 and 0 <= cone_deg < 80):
        raise InputMismatchError(f"distance {distance:g} m, speed {speed:g} m/s and cone {cone_deg:g} deg: the first two "
                                 "positive, the cone within 0-80 deg")
    rng = np.random.default_rng(rng)
    focal = float(LINESCAN_CAMERA["focal"] if focal is None else focal)
    cell = (np.asarray(X, float), np.asarray(Z, float) @ _TOWARDS_CAMERA)
    common = {"cell": cell, "points": points, "focal": focal, "width": width, "distance": distance, "speed": speed,
              "noise_px": noise_px, "jitter_s": 0.0, "clock_offset": 0.0, "k1": 0.0}
    scene = linescan_scene(n_scans, setup, rng, cone_deg=cone_deg, **common)
    narrow = linescan_scene(n_scans, setup, rng, cone_deg=NARROW_DEG, depth_spread=0.0, **common)
    seen, corners = min(len(c) for c in scene.corners), max(len(c) for c in scene.target_points)
    if seen < corners:
        raise InputMismatchError(f"a scan sees {seen} of the target's {corners} points: the line "
                                 f"of {scene.width} px at f = {focal:g} px covers {scene.width / focal * distance:.2f} m at "
                                 f"{distance:g} m; plan from further away (--standoff) or with a smaller board")
    reported, data = _predicted_std(scene, focal, noise_px, robot_accuracy)
    narrow_data = _predicted_std(narrow, focal, noise_px, robot_accuracy)[1]
    return LineScanPlan(setup, scene.moves, speed, scene.line_rate, distance, reported, data, narrow_data, robot_accuracy,
                        cone_deg)


def _line_camera(text: str | None) -> tuple[int | None, float | None]:
    """--line-camera WIDTH,FOCAL: pixels along the line and the focal length (px); (None, None) when not given."""
    if text is None:
        return None, None
    try:
        width, focal = (float(v) for v in text.replace(" ", "").split(","))
    except ValueError:
        raise InputMismatchError(f"--line-camera {text!r}: give WIDTH,FOCAL, the pixels along the line and the focal "
                                 "length in pixels, e.g. 2048,2400") from None
    if not (np.isfinite(width) and np.isfinite(focal)) or width < 2 or focal <= 0:
        raise InputMismatchError(f"--line-camera {text!r}: the width (px) must be 2 or more and the focal length positive")
    return int(width), focal


def plan_command(request: PlanRequest) -> SensorPlan:
    """``handeye plan --sensor line_scan`` (the line-scan camera's registration's ``plan`` hook): straight
    scans across a chessboard (or the ``target`` / ``target_spec`` given) and the std they would give,
    beside the same number of scans at one distance turned at most :data:`NARROW_DEG`; ``options``:
    ``line_camera`` (WIDTH,FOCAL) and ``speed`` (m/s)."""
    points = None
    if request.target_spec is not None or request.target is not None:  # else the simulator's chessboard
        points = target_from_spec(request.target_spec or DEFAULT_TARGETS[request.target]).object_points()
    width, focal = _line_camera(request.options.get("line_camera"))
    speed = request.options.get("speed")
    plan = plan_linescan(request.setup, request.X, request.Z, n_scans=request.poses or 12, points=points, focal=focal,
                         width=width, distance=request.standoff or 0.4, speed=0.2 if speed is None else speed,
                         noise_px=request.noise_px, robot_accuracy=request.robot_accuracy, rng=request.seed)
    return SensorPlan(
        [f"s{k + 1:02d}.{end}" for k in range(len(plan.moves)) for end in ("start", "end")], plan.moves.reshape(-1, 4, 4),
        "scan", plan,
        f"{len(plan.moves)} straight scans across the board at {plan.speed:g} m/s, forth and back in turn, the camera within "
        f"{plan.cone_deg:g} deg of the board's normal at {0.75 * plan.distance:.2f}-{1.25 * plan.distance:.2f} m (line rate "
        f"{plan.line_rate:.0f} rows/s for square pixels); each scan's start and end:",
        "scan", "each scan's pose error fitted with it", "scans",
        f"the same number of scans at one distance, turned at most {NARROW_DEG:g} deg", "X is not determined",
        " (turns between scans place X; distances tell the focal length from the distance)",
        "per scan the flange's pose where its straight move starts and where it ends; record the robot's trajectory (with "
        "times) and each scan's start time for the line-scan session (docs/guide.md, 'Line-scan cameras')")
