"""A known shape (a mesh, or a template cloud of it) in a depth camera's clouds, through the core.

A depth session whose target is ``{type: mesh, file: flange.stl, unit: mm}`` (optionally with the
shape's placement, ``pose_in_flange`` eye-to-hand or ``pose_in_base`` eye-in-hand) is calibrated in
named steps:

1. :func:`measure_mesh_session`: the shape found in a few clouds (organized or not) without any pose
   guess (:func:`~handeye.sensors.depth.registration.find_shape`), in the others from where those put
   it through the robot (searched for without a guess where it is not there); a cloud where it is
   not found is skipped, named with why;
2. :func:`consistent_views`: the views' poses of the shape checked against each other through the
   robot (the closed form on three views at a time, the largest agreeing set kept, as RANSAC): a
   view that disagrees (a pose found turned over, a shape that turns into itself but for a small
   pin) has its shape found again where the agreeing views put it, or is skipped, named;
3. :class:`~handeye.sensors.depth.mesh.MeshSurface` with every view's points on the surface, and
   :func:`~handeye.estimation.core.estimate`: X, Z, the depth scale and bias, what the capture and
   the shape leave undetermined, the verdict.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..._shared.progress import Progress
from ...errors import DegenerateMotionError, HandEyeError, InputMismatchError, UnusableViewError
from ...estimation.core import estimate, start_from_poses
from ...estimation.readings import check_readings
from ...frames.metrics import rotation_error, translation_error
from ...frames.setups import constant_transforms, predicted_target2cam, robot_world_A
from ...geometry.se3 import invert, mean_transform
from ...options import CalibrationOptions
from ...result import Calibration
from ...sensors.depth.clouds import MAX_DEPTH_M, read_points
from ...sensors.depth.mesh import MeshSurface
from ...sensors.depth.registration import ShapeMatch, find_shape, refine_shape
from ...sensors.depth.shape import Shape, load_shape
from .._sensor import held_and_freed, measure_views, robot_model, session_robot_input
from .session import DepthSession

__all__ = ["MeshViews", "measure_mesh_session", "consistent_views", "mesh_model", "calibrate_mesh_session",
           "AGREE_DEG", "AGREE_SHARE"]

#: Views agree when the target's pose each gives (through the robot and X) differ by less than this
#: (deg) ...
AGREE_DEG = 5.0
#: ... and by less than this share of the shape's size (or 10 mm, whichever is more).
AGREE_SHARE = 0.15


@dataclass
class MeshViews:
    """What a mesh session's clouds gave, per measured view."""

    index: list[int] = field(default_factory=list)  #: into the session's views
    matches: list[ShapeMatch] = field(default_factory=list)
    distance: list[float] = field(default_factory=list)  #: the shape's depth, m
    skipped: list[tuple[str, str]] = field(default_factory=list)  #: (view, why)
    notes: list[str] = field(default_factory=list)


def read_scene(path: str | Path, unit: str) -> NDArray[np.float64]:
    """A scene cloud's points (N, 3, m), organized or not, checked: some points, a plausible unit."""
    q = read_points(path, unit)
    if len(q) == 0:
        raise InputMismatchError(f"{path}: no point has a depth: an empty capture")
    median = float(np.median(q[:, 2]))
    if median > MAX_DEPTH_M:
        raise InputMismatchError(f"{path}: median depth {median:g} m: the cloud looks like millimetres; say depth: "
                                 "{unit: mm} in session.yaml")
    return q


def measure_mesh_session(s: DepthSession, shape: Shape, progress: bool = False, jobs: int | None = None) -> MeshViews:
    """The shape found in every cloud of ``s`` (``jobs`` clouds at a time, threads; default 2); a
    cloud where it is not, skipped with why.

    The shape is searched for without any guess (:func:`~handeye.sensors.depth.registration.find_shape`)
    in :data:`SEEDS` clouds first, those whose flange poses are turned furthest from one another, more
    two at a time until most of them agree through the robot (:func:`_guide`); every other cloud's
    pose is then refined from where those put it (:func:`~handeye.sensors.depth.registration.refine_shape`),
    and searched for without a guess only when it is not there: the simulator's default mesh capture with a
    UR5's joint angles (15 clouds, 4 searched) took 3.7 s of CPU where a search in each took 11.0 s. A shape that turns into itself
    (no whole pose in any view), a session of few clouds, and one whose searched clouds do not agree
    (a robot pose read wrong, another object) have every cloud searched."""
    n = len(s.names)
    where = [str(path) for path in s.cloud_paths]
    refused = (InputMismatchError, UnusableViewError)

    def found(k: int) -> ShapeMatch:
        return find_shape(shape, read_scene(s.cloud_paths[k], s.unit), where=where[k], rng=k)

    bar = Progress(n, "finding the shape", progress)
    guided = not len(shape.free) and n > SEEDS + 1
    order, take = (_spread(s.flange2base), SEEDS) if guided else (list(range(n)), n)
    searched: dict[int, ShapeMatch | str] = {}
    guide = None
    while guide is None and len(searched) < n:
        index, matches, skipped = measure_views(found, s.names, refused, "", jobs=jobs, views=order[len(searched):take], bar=bar)
        searched.update(zip(index, matches))
        searched.update((s.names.index(name), why) for name, why in skipped)
        take += 2
        if guided:
            guide = _guide(s, shape, {k: m for k, m in searched.items() if isinstance(m, ShapeMatch)})
    if guide is not None:
        X, Z, tol = guide

        def predicted(k: int) -> ShapeMatch:
            q = read_scene(s.cloud_paths[k], s.unit)
            try:
                match = refine_shape(shape, q, predicted_target2cam(X, Z, s.flange2base[k], s.setup), where=where[k], rng=k)
                rot, tra = _disagreement(X, Z, s.flange2base[k][None], match.target2cam[None], s.setup)
                if rot[0] < AGREE_DEG and tra[0] < tol:
                    return match
            except InputMismatchError:
                pass  # not where the others put it: searched for without a guess (the view may still be judged and skipped)
            return find_shape(shape, q, where=where[k], rng=k)

        rest = [k for k in range(n) if k not in searched]
        index, matches, skipped = measure_views(predicted, s.names, refused, "", jobs=jobs, views=rest, bar=bar)
        searched.update(zip(index, matches))
        searched.update((s.names.index(name), why) for name, why in skipped)
    bar.close()
    out = MeshViews()
    for k in range(n):
        got = searched[k]
        if isinstance(got, str):
            out.skipped.append((s.names[k], got))
        else:
            out.index.append(k)
            out.matches.append(got)
            out.distance.append(float(np.median(got.points[:, 2])))
    return out


#: The clouds searched for the shape without a guess before the others are found from where they put it.
SEEDS = 4


def _spread(flange2base: NDArray[np.float64]) -> list[int]:
    """The views in the order that turns the flange furthest from those before (the first view first; each next
    the one whose smallest rotation from them is largest): a few first ones fix X and Z best."""
    F = np.asarray(flange2base, float)
    order = [0]
    gap = np.asarray(rotation_error(F, F[0]), dtype=float)
    for _ in range(len(F) - 1):
        gap[order] = -1.0
        order.append(int(np.argmax(gap)))
        gap = np.minimum(gap, rotation_error(F, F[order[-1]]))
    return order


def _guide(s: DepthSession, shape: Shape, found: dict[int, ShapeMatch]
           ) -> tuple[NDArray[np.float64], NDArray[np.float64], float] | None:
    """X, Z and the agreement's tolerance (m) from the views the shape was searched for in, when at least
    3 agree through the robot (:func:`_agreeing`) and more than twice as many as disagree; else None. A
    consistent wrong answer (a disc found turned by the same half turn in 3 of the first 4 views) is then
    unlikely: the simulator's disc was found turned in 3 of 45 clouds, in 1 of ~800 sessions 3 of 4 would be."""
    if len(found) < 3:
        return None
    views = sorted(found)
    tol = max(0.01, AGREE_SHARE * shape.size)
    try:
        agree, X, Z = _agreeing(s.flange2base[views], np.array([found[k].target2cam for k in views]), s.setup,
                                None if s.mesh is None else s.mesh.placement, tol)
    except HandEyeError:
        return None
    ok = int(agree.sum())
    return (X, Z, tol) if ok >= 3 and ok > 2 * (len(views) - ok) else None


def _disagreement(X, Z, F, T, setup) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per view, how far its own Z (through X and its robot pose) is from ``Z``: deg, m."""
    Zi = constant_transforms(X, F, T, setup)
    return np.degrees(rotation_error(Zi, Z)), translation_error(Zi, Z)


def _agreeing(F, T, setup, placement, tol_m: float) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64]]:
    """The largest set of views whose poses ``T`` agree through the robot ``F`` (RANSAC over three
    views at a time; one at a time with the ``placement`` known), refitted on it: (agree, X, Z)."""
    n = len(T)
    rng = np.random.default_rng(0)
    best = (np.zeros(n, bool), np.inf)
    if placement is not None:  # each view gives X whole
        Xi = invert(robot_world_A(F, setup)) @ placement @ invert(T)
        for j in range(n):
            ok = (np.degrees(rotation_error(Xi, Xi[j])) < AGREE_DEG) & (translation_error(Xi, Xi[j]) < tol_m)
            if ok.sum() > best[0].sum():
                best = (ok, 0.0)
        return best[0], mean_transform(Xi[best[0]]), placement
    for _ in range(min(80, n * (n - 1) * (n - 2) // 6)):
        pick = rng.choice(n, 3, replace=False)
        try:  # (pure translations: X's rotation from them, its translation left to the fit to name); the closed
            # form alone: a hypothesis only sorts the views, the agreeing ones are refined together below
            X, Z = start_from_poses(F[pick], T[pick], setup, refine=False)
        except HandEyeError:
            continue
        rot, tra = _disagreement(X, Z, F, T, setup)
        ok = (rot < AGREE_DEG) & (tra < tol_m)
        spread = float(np.median(tra[ok])) if ok.any() else np.inf
        if ok.sum() > best[0].sum() or (ok.sum() == best[0].sum() and spread < best[1]):
            best = (ok, spread)
    agree = best[0]
    if agree.sum() < 3:
        raise DegenerateMotionError(f"no 3 of the {n} views' poses of the shape agree through the robot: check the poses' "
                                    "format and unit, the setup, and that the shape is the part that was scanned")
    X, Z = start_from_poses(F[agree], T[agree], setup)
    return agree, X, Z


def consistent_views(s: DepthSession, shape: Shape, v: MeshViews) -> MeshViews:
    """``v`` with the views whose pose of the shape disagrees with the others' (through the robot)
    found again where the others put it (:func:`~handeye.sensors.depth.registration.refine_shape`),
    or skipped, named. A shape that turns into itself (its pose not whole in any view) is left as it is."""
    if len(shape.free) or len(v.index) < 4:
        return v
    F = s.flange2base[v.index]
    T = np.array([m.target2cam for m in v.matches])
    tol = max(0.01, AGREE_SHARE * shape.size)
    agree, X, Z = _agreeing(F, T, s.setup, None if s.mesh is None else s.mesh.placement, tol)
    out = MeshViews(notes=list(v.notes), skipped=list(v.skipped))
    for j, k in enumerate(v.index):
        match = v.matches[j]
        if not agree[j]:
            guess = predicted_target2cam(X, Z, F[j], s.setup)
            try:
                match = refine_shape(shape, read_scene(s.cloud_paths[k], s.unit), guess, where=str(s.cloud_paths[k]))
                rot, tra = _disagreement(X, Z, F[j][None], match.target2cam[None], s.setup)
                if rot[0] >= 3 * AGREE_DEG or tra[0] >= tol:  # a disc's turn is pinned loosely by one view
                    raise InputMismatchError("the shape where the other views put it does not fit its points")
            except InputMismatchError as exc:
                out.skipped.append((s.names[k], f"its pose of the shape disagrees with the other views' through the robot, "
                                                f"and {exc}"))
                continue
            first, again = v.matches[j].target2cam, match.target2cam
            out.notes.append(f"{s.names[k]}: the shape was found turned or elsewhere ({np.degrees(rotation_error(first, again)):.0f} "
                             f"deg, {1e3 * translation_error(first, again):.0f} mm off); found again where the other views put it")
        out.index.append(k)
        out.matches.append(match)
        out.distance.append(v.distance[j])
    return out


def mesh_model(s: DepthSession, shape: Shape, v: MeshViews, fit_depth: bool = True) -> MeshSurface:
    """The measured views of ``s`` as a :class:`~handeye.sensors.depth.mesh.MeshSurface`."""
    return MeshSurface(s.setup, [s.names[k] for k in v.index], shape, [m.points for m in v.matches],
                       [m.normals for m in v.matches], np.array([m.target2cam for m in v.matches]),
                       None if s.mesh is None else s.mesh.placement, fit_depth)


def calibrate_mesh_session(s: DepthSession, options: CalibrationOptions, *, fit_depth: bool = True,
                           progress: bool = False, jobs: int | None = None) -> Calibration:
    """A depth session with a mesh target (the module's docstring): the shape read, found in every
    cloud, the views made consistent, X fitted with every view's points against the surface.

    Raises
    ------
    SessionError
        The mesh file is not a mesh, or its size in the declared unit is implausible (a mesh in mm
        declared m), naming the file.
    DegenerateMotionError
        Fewer than 3 views where the shape is found, or views that cannot determine X.
    """
    if s.mesh is None:
        raise InputMismatchError(f"{s.folder}: the session's target is not a mesh")
    shape = load_shape(s.mesh.file, s.mesh.unit)
    v = measure_mesh_session(s, shape, progress, jobs)
    if len(v.index) >= 3:  # the poses' reading checked on every view the shape was found in, before any is judged by them
        check_readings(mesh_model(s, shape, v, fit_depth), robot_model(s, v.index, options), s.pose_input, s.flange2base,
                       np.asarray(v.index))
    v = consistent_views(s, shape, v)
    if len(v.index) < 3:
        raise DegenerateMotionError(
            f"the shape is found in {len(v.index)} of {len(s.names)} clouds ({'; '.join(f'{n}: {r}' for n, r in v.skipped[:5])}): "
            "at least 3 are needed, 10-20 with the flange turned 30 deg or more about varied axes to trust X")
    hold, free = held_and_freed(s, options)
    cal = estimate(mesh_model(s, shape, v, fit_depth), robot_model(s, v.index, options), options.folds, hold=hold, free=free)
    used = {s.names[v.index[k]] for k in cal.pose_indices}
    distances = [d for k, d in zip(v.index, v.distance) if s.names[k] in used]
    figures = dict(cal.sensor.figures, distance_m=distances)
    return replace(cal, sensor=replace(cal.sensor, figures=figures), skipped=list(v.skipped) + list(cal.skipped),
                   notes=list(s.notes) + list(v.notes) + list(cal.notes), input_folder=s.folder,
                   robot_input=session_robot_input(s, cal.flange2base))
