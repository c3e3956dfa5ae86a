"""Planning a laser line profiler's capture (``handeye plan --sensor laser_line``): flange poses
that determine X, and the std they would give.

A ball's profile tells where its centre is across the laser plane only through the circle's size,
so X's rotation is known through the lever of the centre's offsets from the plane and of the
flange's turns between profiles: the plan draws the views from all around the target's top
(within ``cone_deg``, any roll, the laser plane cutting the ball on either side of its centre), as
:func:`handeye.simulate.laser.profiler_views` does, and predicts X's std by calibrating a simulated
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

from ..errors import DegenerateMotionError, InputMismatchError
from ..estimation.core import estimate
from ..frames.setups import check_setup, predicted_target2cam, setup_info
from ..geometry.se3 import invert
from ..options import ROBOT_ACCURACY
from ..robot.models import ControllerPoses
from ..sensors.laser.model import LASER_NOISE_M, SphereProfiles
from ..sensors.laser.plane import PlaneProfiles
from ..simulate.laser import TARGETS, profile_reading, profiler_views

#: The targets a laser plan predicts the std for (its simulated capture goes through their models).
PLANNED = ("sphere", "plane")
from .poses import order_path

__all__ = ["LaserPlan", "plan_laser", "NARROW_DEG"]

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
    names = [f"p{k + 1:02d}.csv" for k in keep]
    shown = [profiles[k] for k in keep]
    model = (SphereProfiles(setup, names, shown, radius, noise_m) if target == "sphere" else
             PlaneProfiles(setup, names, shown, noise_m))
    try:
        cal = estimate(model, ControllerPoses(flange2base[keep], accuracy))
    except DegenerateMotionError:
        return np.full(6, np.inf), np.full(6, np.inf)
    return np.asarray(cal.std, dtype=float), np.asarray(cal.std_sources["data"], dtype=float)


def plan_laser(setup: str, X: NDArray[np.float64], Z: NDArray[np.float64], n_poses: int = 20, target: str = "sphere",
               radius: float = 0.02, noise_m: float = LASER_NOISE_M, cone_deg: float = 45.0,
               robot_accuracy: tuple[float, float] | None = ROBOT_ACCURACY,
               rng: np.random.Generator | int | None = 0) -> LaserPlan:
    """Flange poses for a laser profiler's capture of a ball (or a plate) and X's predicted std.

    Parameters
    ----------
    setup : {'eye_in_hand', 'eye_to_hand'}
    X, Z : (4, 4)
        Rough placements: the profiler on the flange (``sensor2flange``) and the target in the base
        (eye-in-hand), or the profiler in the base and the target on the flange (eye-to-hand). The
        target frame's origin is the ball's centre (a point on the plate), its +z the side the
        profiler looks from.
    n_poses : int
        Profiles to capture (at least 16 for a plate, whose closed form needs them).
    target : {'sphere', 'plane'}
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
        later = f" ({target}: not yet; plan with a sphere or a plane, or simulate the capture with handeye simulate " \
                "--sensor laser_line --target " + target + ")" if target in TARGETS else ""
        raise InputMismatchError(f"target={target!r}: a laser plan is for a {' or a '.join(PLANNED)}{later}")
    if n_poses < (16 if target == "plane" else 5):
        raise InputMismatchError(f"n_poses={n_poses}: a {target} needs at least {16 if target == 'plane' else 5} "
                                 "profiles (15-20 to trust X)")
    rng = np.random.default_rng(rng)
    flange2base = _flange_poses(setup, X, Z, profiler_views(target, n_poses, radius, rng, cone_deg))
    flange2base = flange2base[order_path(flange2base)]
    narrow = _flange_poses(setup, X, Z, profiler_views(target, n_poses, radius, rng, NARROW_DEG / 4, NARROW_DEG / 4))
    reported, data = _predicted_std(setup, target, X, Z, flange2base, radius, noise_m, robot_accuracy, rng)
    narrow_data = _predicted_std(setup, target, X, Z, narrow, radius, noise_m, robot_accuracy, rng)[1]
    return LaserPlan(setup, target, flange2base, reported, data, narrow_data, robot_accuracy, cone_deg)
