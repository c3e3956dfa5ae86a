"""Laser line profiler sessions calibrated: every profile read, then the estimation core.

A laser session (:mod:`handeye.pipelines.laser.session`: ``laser:`` in session.yaml, ``profiles/``) gives
per robot pose the points where the profiler's laser plane met a ball, a plate, a block's edge, a step or
one ball of a fixture. :func:`calibrate_laser_session`
reads each profile (in metres; points outside the stated measuring range left out; a profile that
is missing or has no point left is skipped, named), makes them a sensor model
(:class:`~handeye.sensors.laser.model.SphereProfiles`: every point's distance from the ball;
:class:`~handeye.sensors.laser.plane.PlaneProfiles`: from the plate's plane;
:class:`~handeye.sensors.laser.edge.EdgeProfiles` and :class:`~handeye.sensors.laser.edge.StepProfiles`:
from the nearer of the two faces; :class:`~handeye.sensors.laser.model.SpheresProfiles`: from the
nearest ball of the fixture; :func:`laser_model` picks it), and the estimation core
(:func:`handeye.estimation.core.estimate`) fits X with the ball's centre (and its radius when the
session gives none) or the plane, the arm's table too when the session has joint angles; sets
aside stray points, leaves out profiles the fit does not explain, cross-validates on held-out
profiles (their points' distance from the ball, mm), says what the capture leaves undetermined and
gives the verdict: one :class:`~handeye.result.Calibration`, as for images.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._shared.threads import on_one_blas_thread
from ...errors import DegenerateMotionError, UnusableViewError
from ...io.session import check_keys
from ...options import CalibrationOptions
from ...result import Calibration
from ...sensors.laser.edge import EdgeProfiles, StepProfiles
from ...sensors.laser.model import Profiles, SphereProfiles, SpheresProfiles
from ...sensors.laser.plane import PlaneProfiles
from ...sensors.laser.profiles import check_range, check_shape, read_profile
from .._sensor import estimate_checked, robot_model, sensor_options, session_robot_input, why_skipped
from .session import RIG_KEYS, LaserSession, load_laser_session, rig_laser

__all__ = ["calibrate_laser_session", "read_profiles", "laser_model", "LaserMember", "rig_member", "MIN_POINTS"]

#: A profile with fewer points than this (after the range) is skipped: too few to say where the ball is.
MIN_POINTS = 20


def read_profiles(s: LaserSession) -> tuple[list[int], list, list[tuple[str, str]], list[str]]:
    """Every profile of ``s`` read: the views kept, their points (metres, the range applied), the
    views skipped with why (missing, empty, too few points) and notes."""
    kept, profiles, skipped, notes = [], [], [], []
    read = []
    for k, (name, path) in enumerate(zip(s.names, s.profile_paths)):
        if not path.is_file():
            skipped.append((k, name, f"missing from {path.parent}"))
            continue
        try:
            read.append((k, name, read_profile(path, s.unit)))
        except UnusableViewError as exc:  # this view's file holds no profile: skipped, named
            skipped.append((k, name, why_skipped(exc, path)))
    if s.working_range is not None and read:  # mostly outside the range: the files, not a few stray points
        check_range([p for _, _, p in read], s.working_range, s.unit, str(s.profile_paths[read[0][0]].parent))
    outside = 0
    for k, name, p in read:
        if s.working_range is not None:
            out = np.isfinite(p[:, 2]) & ((p[:, 2] < s.working_range[0]) | (p[:, 2] > s.working_range[1]))
            outside += int(out.sum())
            p[out] = np.nan
        n = int(np.isfinite(p).all(axis=1).sum())
        if n < MIN_POINTS:
            skipped.append((k, name, "no return in the profile (all points empty or NaN)" if n == 0 else
                            f"only {n} points with a return (at least {MIN_POINTS} are needed)"))
            continue
        kept.append(k)
        profiles.append(p)
    if outside:
        notes.append(f"{outside} points outside the stated measuring range left out")
    check_shape(profiles, s.target, s.noise_m, str(s.profile_paths[0].parent) if s.profile_paths else str(s.folder))
    return kept, profiles, [(name, why) for _, name, why in sorted(skipped, key=lambda s: s[0])], notes


def laser_model(s: LaserSession, names: list[str], profiles: list) -> Profiles:
    """The sensor model of the session's target (``s.target``) for the profiles ``profiles`` of the views ``names``."""
    if s.target == "plane":
        return PlaneProfiles(s.setup, names, profiles, s.noise_m)
    if s.target == "edge":
        return EdgeProfiles(s.setup, names, profiles, s.noise_m)
    if s.target == "step":
        return StepProfiles(s.setup, names, profiles, s.noise_m)
    if s.target == "spheres":
        return SpheresProfiles(s.setup, names, profiles, s.radii, s.noise_m)
    return SphereProfiles(s.setup, names, profiles, s.radius, s.noise_m)


@on_one_blas_thread  # narrow matrices throughout: a second BLAS thread spins more than it works
def calibrate_laser_session(folder: str | Path | LaserSession, options: CalibrationOptions | None = None, *,
                            progress: bool = False, jobs: int | None = None,
                            **changes) -> Calibration:
    """Calibrate a laser line profiler session (the module docstring).

    Parameters
    ----------
    folder : path or LaserSession
    options : CalibrationOptions, optional
        ``robot_accuracy`` (the controller's poses' stated accuracy, added to X's std), ``folds`` and
        ``arm`` (the arm of a ``joints:`` table) are used; the options of image sessions are refused
        when changed.
    progress : bool
        Unused (a laser session calibrates in seconds); accepted as every pipeline does.
    jobs : int, optional
        Unused (the profiles are read in one process); accepted as every pipeline does.

    Returns
    -------
    Calibration
        X (``sensor2flange`` eye-in-hand, ``sensor2base`` eye-to-hand: the matrix ``cam2flange`` /
        ``cam2base`` names), Z the ball's centre, the std, the verdict; ``sensor`` holds the ball's
        radius and centre and each profile's residual; ``skipped`` the profiles not used, with why.

    Raises
    ------
    SessionError
        A bad session or profile file, naming it (a y that is not 0, millimetres given as metres, ...).
    DegenerateMotionError
        Fewer than 3 usable profiles, or profiles whose poses cannot determine the sensor's rotation.

    Examples
    --------
    >>> import tempfile
    >>> from handeye.pipelines.laser.simulate import laser_scene, write_laser_session
    >>> folder = write_laser_session(tempfile.mkdtemp() + "/s", laser_scene(20, "eye_in_hand", rng=1))
    >>> cal = calibrate_laser_session(folder)
    >>> cal.verdict, cal.sensor.target, cal.sensor.figures["radius_mm"]["value"]
    ('good', 'sphere', 20.0)
    """
    opts = sensor_options(options, changes, "a laser session", table=True)
    s = folder if isinstance(folder, LaserSession) else load_laser_session(folder, arm=opts.arm)
    kept, profiles, skipped, notes = read_profiles(s)
    if len(kept) < 3:
        why = f" ({'; '.join(f'{n}: {r}' for n, r in skipped[:5])})" if skipped else ""
        raise DegenerateMotionError(
            f"{len(kept)} of {len(s.names)} profiles usable{why}: at least 3 are needed, 15-20 with the flange turned "
            "10 deg or more about two or three axes to trust X")
    names = [s.names[k] for k in kept]
    cal = estimate_checked(laser_model(s, names, profiles), robot_model(s, kept, opts), s, opts, kept)
    return replace(cal, skipped=skipped + list(cal.skipped), notes=list(s.notes) + notes + list(cal.notes),
                   input_folder=s.folder,
                   robot_input=session_robot_input(s, cal.flange2base))


@dataclass(frozen=True)
class LaserMember:
    """A rig's laser profiler (its registration's ``rig_member``): a laser session over the rig's views."""

    session: LaserSession
    #: what a view it missed lacks
    missing: str = "profile"

    @property
    def seen(self) -> list[bool]:
        """Per view of the rig whether it has a profile."""
        return [p.is_file() for p in self.session.profile_paths]

    @property
    def files(self) -> list[Path]:
        """Its profiles."""
        return [p for p in self.session.profile_paths if p.is_file()]

    @property
    def target_spec(self) -> dict[str, Any]:
        """The target it scans."""
        return self.session.target_spec

    @property
    def board_images(self) -> list[Path]:
        """None: a profiler has no image of the session's board."""
        return []

    def model(self, name: str, names: list[str], notes: list[str], progress: bool = False,
              detected: list | None = None) -> Profiles:
        """Its sensor model over the rig's views ``names``: its profiles read (a view without one, or
        whose profile is skipped, has no rows), the notes and skips said in ``notes`` by its ``name``."""
        kept, profiles, skipped, more = read_profiles(self.session)
        full = [np.zeros((0, 3))] * len(names)
        for k, p in zip(kept, profiles):
            full[k] = p
        notes += [f"sensor {name}: {n}" for n in more]
        notes += [f"sensor {name}: profile {v} skipped: {why}" for v, why in skipped if not why.startswith("missing")]
        notes.append(f"sensor {name}: {len(kept)} of {len(names)} profiles used")
        return laser_model(self.session, names, full)


def rig_member(folder: Path, setup: str, names: list[str], flange2base: NDArray[np.float64], block: dict[str, Any],
               name: str, target: Any, where: str) -> LaserMember:
    """A rig's laser profiler read (its block under ``sensors:``: ``laser:``, its folder of ``profiles``
    named by view, default the sensor's name, and its ``target``), checked as a laser session's are."""
    check_keys(block, RIG_KEYS, where)
    return LaserMember(rig_laser(folder, setup, names, flange2base, block["laser"], folder / str(block.get("profiles", name)),
                                 target, where))
