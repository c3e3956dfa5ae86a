"""Planning a laser line profiler's capture (``handeye plan --sensor laser_line``): flange poses
that determine X, and the std they would give.

A ball's profile tells where its centre is across the laser plane only through the circle's size,
so X's rotation is known through the lever of the centre's offsets from the plane and of the
flange's turns between profiles: the plan draws the views from all around the target's top
(within ``cone_deg``, any roll, the laser plane cutting the ball on either side of its centre), as
:func:`handeye.pipelines.laser.simulate.profiler_views` does, and predicts X's std by calibrating a simulated
capture of exactly those poses through the estimation core, the robot's stated accuracy in it.
The same number of profiles with the flange turned at most :data:`NARROW_DEG` is predicted beside
it: how much the turns widen the lever.

Examples
--------
>>> import numpy as np
>>> from handeye.geometry.se3 import make_transform
>>> X = make_transform(np.eye(3), [0.0, 0.05, 0.08])          # the profiler on the flange
>>> Z = make_transform(np.eye(3), [0.6, 0.0, 0.05])           # the ball's centre in the base
>>> plan = plan_laser("eye_in_hand", X, Z, n_poses=16, rng=0)
>>> plan.flange2base.shape, bool(np.all(plan.std_data[3:] < plan.std_narrow[3:]))   # the turns place X
((16, 4, 4), True)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ...errors import DegenerateMotionError, InputMismatchError
from ...estimation.core import estimate
from ...frames.motions import order_path
from ...frames.setups import check_setup, predicted_target2cam, setup_info
from ...geometry.se3 import invert
from ...options import ROBOT_ACCURACY
from ...robot.models import ControllerPoses
from ...sensors.laser.edge import EdgeProfiles, StepProfiles
from ...sensors.laser.model import LASER_NOISE_M, Profiles, SphereProfiles, SpheresProfiles
from ...sensors.laser.plane import PlaneProfiles
from ..kinds import PlanRequest, SensorPlan
from .simulate import BLOCK, FIXTURE, TARGETS, profile_reading, profiler_views

#: The targets a laser plan predicts the std for (its simulated capture goes through their models).
PLANNED = TARGETS
#: The fewest profiles each target's closed-form start takes (a fixture: 3 or more on each of its balls).
FEWEST = {"sphere": 5, "plane": 16, "edge": 10, "step": 10, "spheres": 12}

__all__ = ["LaserPlan", "plan_laser", "assumed_shape", "NARROW_DEG", "FEWEST", "plan_command"]

#: The comparison capture turns the flange at most this much (deg) between profiles.
NARROW_DEG = 10.0


@dataclass(frozen=True)
class LaserPlan:
    """A laser capture's plan: the flange poses in path order, X's predicted std as calibrate would
    report it (deg, mm per axis; the robot's stated accuracy in it) and from the profiles alone (the
    profiler's noise, the lever), and the latter for the same number of profiles turned at most
    :data:`NARROW_DEG` (inf where those cannot determine X)."""

    setup: str
    target: str
    flange2base: NDArray[np.float64]
    std_X: NDArray[np.float64]
    std_data: NDArray[np.float64]
    std_narrow: NDArray[np.float64]
    robot_accuracy: tuple[float, float] | None
    cone_deg: float


def _flange_poses(setup: str, X: NDArray[np.float64], Z: NDArray[np.float64], sensor2target: NDArray[np.float64]
                  ) -> NDArray[np.float64]:
    """The flange poses that put the sensor at ``sensor2target`` (per view) of the target."""
    if setup_info(setup).camera_on_flange:  # Z = target2base: flange = Z sensor2target X^-1
        return Z @ sensor2target @ invert(X)
    return X @ invert(sensor2target) @ invert(Z)  # X = sensor2base, Z = target2flange


def _predicted_std(setup: str, target: str, X, Z, flange2base, radius: float, noise_m: float,
                   accuracy: tuple[float, float] | None, rng: np.random.Generator
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """X's std from a simulated capture of these poses (the profiler's noise, an exact robot whose
    stated accuracy enters the std), as calibrate reports it and from the profiles alone; inf where
    they do not determine X."""
    profiles = [profile_reading(target, T, radius, rng, noise_m) for T in predicted_target2cam(X, Z, flange2base, setup)]
    keep = [k for k, p in enumerate(profiles) if np.isfinite(p[:, 2]).sum() >= 20]
    model = _model(setup, target, [f"p{k + 1:02d}.csv" for k in keep], [profiles[k] for k in keep], radius, noise_m)
    try:
        cal = estimate(model, ControllerPoses(flange2base[keep], accuracy), held_out=False)  # the std alone: no folds
    except DegenerateMotionError:
        return np.full(6, np.inf), np.full(6, np.inf)
    return np.asarray(cal.std, dtype=float), np.asarray(cal.std_sources["data"], dtype=float)


def _model(setup: str, target: str, names: list[str], profiles: list[NDArray[np.float64]], radius: float,
           noise_m: float) -> Profiles:
    """The laser model of ``target`` for these profiles (a fixture: :data:`FIXTURE`'s balls)."""
    if target == "sphere":
        return SphereProfiles(setup, names, profiles, radius, noise_m)
    if target == "spheres":
        return SpheresProfiles(setup, names, profiles, 0.5 * np.asarray(FIXTURE["diameters"]), noise_m)
    return {"plane": PlaneProfiles, "edge": EdgeProfiles, "step": StepProfiles}[target](setup, names, profiles, noise_m)


def assumed_shape(target: str) -> str:
    """In words, the shape a plan for ``target`` predicts with where the session's own is not given
    (an edge's angle, a step's height, a fixture's balls are the simulator's)."""
    if target == "edge":
        return f"a block's edge of {BLOCK['angle_deg']:g} deg, its line along the target frame's x"
    if target == "step":
        return f"a step of {1e3 * BLOCK['step']:g} mm, its riser along the target frame's x"
    if target == "spheres":
        balls = ", ".join(f"{1e3 * d:g} mm at ({', '.join(f'{1e3 * c:g}' for c in centre)}) mm"
                          for d, centre in zip(FIXTURE["diameters"], FIXTURE["centres"]))
        return f"a fixture of {len(FIXTURE['diameters'])} balls ({balls} in the target frame)"
    return "a ball" if target == "sphere" else "a plate"


def plan_laser(setup: str, X: NDArray[np.float64], Z: NDArray[np.float64], n_poses: int = 20, target: str = "sphere",
               radius: float = 0.02, noise_m: float = LASER_NOISE_M, cone_deg: float = 45.0,
               robot_accuracy: tuple[float, float] | None = ROBOT_ACCURACY,
               rng: np.random.Generator | int | None = 0) -> LaserPlan:
    """Flange poses for a laser profiler's capture of a ball, a plate, a block's edge, a step or a
    fixture of balls, and X's predicted std.

    Parameters
    ----------
    setup : {'eye_in_hand', 'eye_to_hand'}
    X, Z : (4, 4)
        Rough placements: the profiler on the flange (``sensor2flange``) and the target in the base
        (eye-in-hand), or the profiler in the base and the target on the flange (eye-to-hand). The
        target frame's origin is the ball's centre (a point on the plate; on an edge's or a step's
        line, which runs along its x; the fixture's first ball's centre), its +z the side the profiler
        looks from.
    n_poses : int
        Profiles to capture (at least :data:`FEWEST`'s: 16 for a plate, 10 for an edge or a step).
    target : {'sphere', 'plane', 'edge', 'step', 'spheres'}
        An edge's angle, a step's height and a fixture's balls are the simulator's
        (:func:`assumed_shape`): the sessions' own are fitted, the plan's std is for those.
    radius, noise_m : float
        The ball's radius and the profiler's noise along z (m).
    cone_deg : float
        The views come from within this angle of the target's +z.
    robot_accuracy : (deg, mm) or None
        The robot's absolute accuracy per axis, in the predicted std as calibrate puts it.

    Returns
    -------
    LaserPlan
    """
    setup = check_setup(setup)
    if target not in PLANNED:
        raise InputMismatchError(f"target={target!r}: a laser plan is for one of {', '.join(PLANNED)}")
    if n_poses < FEWEST[target]:
        raise InputMismatchError(f"n_poses={n_poses}: a {target} needs at least {FEWEST[target]} profiles (15-20 to "
                                 "trust X)")
    rng = np.random.default_rng(rng)
    flange2base = _flange_poses(setup, X, Z, profiler_views(target, n_poses, radius, rng, cone_deg))
    flange2base = flange2base[order_path(flange2base)]
    narrow = _flange_poses(setup, X, Z, profiler_views(target, n_poses, radius, rng, NARROW_DEG / 4, NARROW_DEG / 4))
    reported, data = _predicted_std(setup, target, X, Z, flange2base, radius, noise_m, robot_accuracy, rng)
    narrow_data = _predicted_std(setup, target, X, Z, narrow, radius, noise_m, robot_accuracy, rng)[1]
    if target in ("edge", "step"):  # the simulator's block views tilt at most its own cone
        cone_deg = min(cone_deg, BLOCK["cone_deg"])
    return LaserPlan(setup, target, flange2base, reported, data, narrow_data, robot_accuracy, cone_deg)


#: What places X's rotation, per target (the plan's last line).
_LEVER = {"sphere": "the ball's centre across the laser plane, its rotation",
          "spheres": "the balls' centres across the laser plane, its rotation",
          "plane": "the plate's tilt in each profile, its rotation",
          "edge": "the faces' tilts and the edge's crossing point in each profile, its rotation",
          "step": "the levels' tilt and the riser's crossing point in each profile, its rotation"}


def plan_command(request: PlanRequest) -> SensorPlan:
    """``handeye plan --sensor laser_line`` (the laser's registration's ``plan`` hook): flange poses around
    a ball (over a plate, across an edge or a step, around a fixture's balls) and the std they would give,
    beside the same number of profiles turned at most :data:`NARROW_DEG`; ``options``: ``diameter``, the
    ball's (m)."""
    target = request.target or "sphere"
    if target not in TARGETS:
        raise InputMismatchError(f"--target {target}: a laser line profiler scans one of {', '.join(TARGETS)} (--target "
                                 "sphere is the default)")
    diameter = request.options.get("diameter")
    if target != "sphere" and diameter is not None:
        raise InputMismatchError(f"--diameter is a ball's; --target {target} has none"
                                 + (" (the plan's fixture is the simulator's: see its output)" if target == "spheres" else "")
                                 + ": leave it out")
    plan = plan_laser(request.setup, request.X, request.Z, n_poses=request.poses or 20, target=target,
                      radius=(0.04 if diameter is None else diameter) / 2, robot_accuracy=request.robot_accuracy,
                      rng=request.seed)
    axis = "its faces' bisector" if target == "edge" else "the target frame's +z"
    return SensorPlan(
        [f"p{k + 1:02d}.csv" for k in range(len(plan.flange2base))], plan.flange2base, "profile", plan,
        f"{len(plan.flange2base)} profiles of {assumed_shape(target)}, the profiler within {plan.cone_deg:g} deg of {axis}, "
        "turned about its view direction, in path order:",
        "profile", "which no capture removes", "profiles", f"the same number of profiles with the flange turned at most "
        f"{NARROW_DEG:g} deg", "X is not determined (profiles at nearly one orientation only slide along a plate, an edge "
        "or a step)", " (turns between profiles place X's translation; " + _LEVER[target] + ")",
        "flange2base per profile; it is the poses.csv of the laser session to capture (replace each row by the pose the "
        "robot reports)")
