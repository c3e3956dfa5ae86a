"""Depth-camera sessions on disk: clouds (and intensity images) with robot poses, through one pipeline.

A depth session is a session folder (docs/guide.md, "Depth cameras") whose ``session.yaml`` has a
``depth:`` mapping::

    setup: eye_to_hand
    target: {type: sphere, diameter: 0.05}     # or a board (chessboard, charuco, ...) as for images,
                                               # or {type: mesh, file: flange.stl, unit: mm} (pipelines.mesh)
    camera: {K: ..., dist: ...}                # optional: the intensity image's intrinsics
    depth:
      unit: m                                  # the clouds' unit: m | mm
      range: [0.3, 1.5]                        # optional: the camera's stated working range, metres
    poses: {file: poses.csv, format: quat_wxyz, length_unit: mm, angle_unit: deg}
    joints: {file: joints.csv, unit: deg, arm: ur5}   # optional: the arm's table fitted with X

``poses.csv``'s first column is ``image`` (a board: the intensity image in ``images/``, its cloud
the file of the same stem in ``clouds/``: .npy, .ply or .pcd) or ``cloud`` (spheres: the cloud
file in ``clouds/``). :func:`calibrate_depth_session` measures every view (a board's corners where
their rays meet its plane fitted to the cloud, :func:`~handeye.sensors.depth.plane_points`; a sphere's
centre, :func:`~handeye.sensors.depth.find_spheres`; a view that cannot be
measured is skipped with its reason, never silently) into a sensor model
(:mod:`handeye.sensors.depth.model`), and the estimation core (:func:`handeye.estimation.core.estimate`)
fits X with the depth scale and bias, the arm's table too when the session has joint angles, leaves
out views the fit does not explain (named), cross-validates on held-out views (3D error at the
target, mm) and gives the verdict: one :class:`~handeye.result.Calibration`, as for images.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._shared.progress import Progress
from ..._shared.threads import on_one_blas_thread
from ...errors import DegenerateMotionError, InputMismatchError, UnusableViewError
from ...estimation.core import estimate
from ...io.session import check_keys
from ...options import ROBOT_ACCURACY, CalibrationOptions
from ...result import Calibration
from ...robot.models import ControllerPoses
from ...sensors.camera import detect_images, target_from_spec
from ...sensors.camera.pnp import labelled_by_robot
from ...sensors.depth.clouds import board_pose, check_frame, plane_points, read_cloud
from ...sensors.depth.model import BoardPoints, SphereCentres
from ...sensors.depth.spheres import find_spheres
from .._sensor import estimate_checked, label_notes, robot_model, sensor_options, session_robot_input, why_skipped
from .arm import calibrate_arm_depth_session
from .mesh import calibrate_mesh_session
from .scene import calibrate_scene_session
from .session import RIG_DEPTH_KEYS, DepthSession, load_depth_session, rig_depth

__all__ = ["calibrate_depth_session", "calibrate_depth", "calibrate_spheres", "measure_depth_session", "DepthViews",
           "DepthMember", "rig_member"]


@dataclass
class DepthViews:
    """What a depth session's clouds gave, per measured view (:func:`measure_depth_session`)."""

    index: list[int] = field(default_factory=list)  #: into the session's views
    object_points: list = field(default_factory=list)  #: boards: (M, 3) per view
    points: list = field(default_factory=list)  #: boards: (M, 3) lifted; spheres: (K, 3) centres (NaN: not seen)
    covs: list = field(default_factory=list)  #: spheres: (K, 3, 3)
    distance: list = field(default_factory=list)  #: the target's median depth, m
    skipped: list = field(default_factory=list)  #: (view, why)
    notes: list = field(default_factory=list)


def measure_depth_session(s: DepthSession, progress: bool = False, jobs: int | None = None,
                          detected: list | None = None) -> DepthViews:
    """Every view of ``s`` measured: a board's corners where their rays meet its plane fitted to
    the cloud, or the spheres' centres; a view that cannot be measured is skipped with its reason.
    ``detected``: the board already found in each view's intensity image (a rig detects every
    sensor's images in one parallel pass)."""
    if s.kind == "spheres":
        return _measure_spheres(s, progress)
    v = DepthViews()
    _measure_boards(s, progress, v, jobs, detected)
    return v


def _measure_boards(s: DepthSession, progress: bool, out: DepthViews, jobs: int | None, detected: list | None) -> None:
    notes = out.notes
    frames = []
    if detected is None:
        detected = detect_images(s.image_paths or [], target_from_spec(s.target_spec), jobs=jobs, progress=progress)
    for k, res in enumerate(detected):
        if res.detection is None:
            out.skipped.append((s.names[k], res.error or "target not found"))
            continue
        cloud = read_cloud(s.cloud_paths[k], res.image_size, s.unit)
        if s.K is not None:
            frames.append(check_frame(cloud, s.K, s.dist, where=str(s.cloud_paths[k])))
        try:  # where the corners' rays meet the board's plane, fitted to the cloud
            points, _, _ = plane_points(cloud, res.detection.image_points, where=str(s.cloud_paths[k]))
        except InputMismatchError as exc:
            out.skipped.append((s.names[k], str(exc)))
            continue
        out.index.append(k)
        out.object_points.append(res.detection.object_points)
        out.points.append(points)
        out.distance.append(float(np.median(points[:, 2])))
    if frames:
        notes.append(f"clouds in the image's frame: their points project {max(frames):.2f} px (RMS, worst view) from "
                     "their pixels with the given intrinsics")
    symmetries = target_from_spec(s.target_spec).symmetries()
    if len(symmetries) > 1 and len(out.index) > 1:  # a chessboard's corners named from either end, view by view
        poses = np.array([board_pose(o, q)[0] for o, q in zip(out.object_points, out.points)])
        labelled = labelled_by_robot(poses, out.object_points, s.flange2base[out.index], s.setup, symmetries)
        out.object_points[:] = labelled.object_points
        notes += label_notes(str(s.target_spec.get("type", "board")), len(symmetries), s.setup,
                             [s.names[k] for k in out.index], labelled)


def _measure_spheres(s: DepthSession, progress: bool) -> DepthViews:
    out = DepthViews()
    radii = s.radii or []
    bar = Progress(len(s.cloud_paths), "finding spheres", progress)
    for k, path in enumerate(s.cloud_paths):
        bar.update()
        try:
            cloud = read_cloud(path, None, s.unit)
        except UnusableViewError as exc:  # no cloud to look in: this view skipped, named
            out.skipped.append((s.names[k], why_skipped(exc, path)))
            continue
        if s.K is not None:
            check_frame(cloud, s.K, s.dist, where=str(path))
        found = find_spheres(cloud, radii, rng=k, where=str(path))
        if all(f is None for f in found):
            out.skipped.append((s.names[k], "no sphere of diameter " + " or ".join(f"{2e3 * r:.1f} mm" for r in radii)
                                + " found in the cloud"))
            continue
        out.index.append(k)
        out.points.append(np.array([f.centre if f is not None else np.full(3, np.nan) for f in found]))
        out.covs.append(np.array([f.cov if f is not None else np.eye(3) for f in found]))
        out.distance.append(float(np.median([f.centre[2] for f in found if f is not None])))
    bar.close()
    return out


def sensor_model(s: DepthSession, v: DepthViews, fit_depth: bool = True) -> BoardPoints | SphereCentres:
    """The measured views of ``s`` as a sensor model (:mod:`handeye.sensors.depth.model`)."""
    names = [s.names[k] for k in v.index]
    if s.kind == "spheres":
        return SphereCentres(s.setup, names, np.array(v.points), np.array(v.covs), np.array(s.radii), fit_depth)
    return BoardPoints(s.setup, names, v.object_points, v.points, fit_depth)


@on_one_blas_thread  # narrow matrices throughout: a second BLAS thread spins more than it works
def calibrate_depth_session(folder: str | Path | DepthSession, options: CalibrationOptions | None = None, *,
                            fit_depth: bool = True, progress: bool = False, jobs: int | None = None,
                            **changes) -> Calibration:
    """Calibrate a depth session (:func:`~handeye.pipelines.depth.session.load_depth_session`): measure
    every view, fit X with the depth scale and bias (and the arm's table, with joint angles), leave
    out views the fit does not explain, cross-validate, judge.

    Parameters
    ----------
    folder : path or DepthSession
    options : CalibrationOptions, optional
        ``robot_accuracy`` (the controller's poses' stated accuracy, added to X's std), ``folds`` and
        ``arm`` (the arm of a ``joints:`` table, instead of session.yaml's) are used; the options of
        image sessions (method, refine, ...) have no meaning here and are refused when changed.
    fit_depth : bool
        Estimate the depth scale and bias (else taken as 1 and 0).
    progress : bool
        Progress on stderr. ``jobs``: detection threads for a board's intensity images.

    Returns
    -------
    Calibration
        X with its std and verdict; ``sensor`` holds the depth scale and bias, the spheres' centres
        and each view's residual; ``skipped`` the views not measured or left out, with why.

    Raises
    ------
    SessionError, InputMismatchError
        A bad session or cloud (another size than its image, no depth, mm given as m, another frame
        than the image's), naming the file; options that only image sessions use.
    DegenerateMotionError
        Fewer than 3 views measured, or views that cannot determine X; says what to capture.

    Examples
    --------
    >>> import tempfile, handeye
    >>> from handeye.pipelines.depth.simulate_board import sphere_scene, write_depth_session
    >>> folder = write_depth_session(tempfile.mkdtemp() + "/s", sphere_scene(10, "eye_to_hand", rng=3))
    >>> cal = calibrate_depth_session(folder)
    >>> cal.verdict, cal.sensor.target
    ('good', 'spheres')
    """
    opts = sensor_options(options, changes, "a depth session", table=True)
    s = folder if isinstance(folder, DepthSession) else load_depth_session(folder, arm=opts.arm)
    if s.kind == "mesh":  # a known shape: found in each cloud, then every point against its surface
        return calibrate_mesh_session(s, opts, fit_depth=fit_depth, progress=progress, jobs=jobs)
    if s.kind == "scene":  # no target: X from the views' clouds agreeing through the robot
        return calibrate_scene_session(s, opts, progress=progress, jobs=jobs)
    if s.kind == "arm":  # the arm itself (markerless): every point against the arm posed at its joint angles
        if opts.compliance:
            raise InputMismatchError(f"{s.folder}: compliance (--compliance): the arm as its own target is posed by its "
                                     "given table, which is not fitted here; leave compliance out")
        return calibrate_arm_depth_session(s, opts, fit_depth=fit_depth, progress=progress, jobs=jobs)
    v = measure_depth_session(s, progress, jobs)
    if len(v.index) < 3:
        raise DegenerateMotionError(
            f"{len(v.index)} of {len(s.names)} views measured ({'; '.join(f'{n}: {r}' for n, r in v.skipped[:5])}): "
            "at least 3 are needed, 10-20 with the flange turned 30 deg or more about varied axes to trust X")
    cal = estimate_checked(sensor_model(s, v, fit_depth), robot_model(s, v.index, opts), s, opts, v.index)
    return _with_session(cal, s, v)


def _with_session(cal: Calibration, s: DepthSession, v: DepthViews) -> Calibration:
    """``cal`` with the session's files, the views not measured, the working range's advice and the
    notes of reading and measuring."""
    used = {s.names[v.index[k]] for k in cal.pose_indices}
    distances = [d for k, d in enumerate(v.distance) if s.names[v.index[k]] in used]
    figures = dict(cal.sensor.figures, distance_m=distances)
    advice = []
    if s.working_range is not None:
        lo, hi = s.working_range
        out = [f"{n} ({d:.2f} m)" for n, d in zip(cal.sensor.views, distances) if not lo <= d <= hi]
        if out:
            advice.append(f"{len(out)} view(s) outside the camera's stated range {lo:g}-{hi:g} m: {', '.join(out[:5])}; "
                          "depth is least accurate there: capture within the range")
    skipped = list(v.skipped) + list(cal.skipped)
    diag = replace(cal.diagnostics, advice=list(cal.diagnostics.advice) + advice) if advice else cal.diagnostics
    return replace(cal, sensor=replace(cal.sensor, figures=figures), skipped=skipped, diagnostics=diag,
                   notes=list(s.notes) + list(v.notes) + list(cal.notes), input_folder=s.folder,
                   robot_input=session_robot_input(s, cal.flange2base))


def calibrate_depth(flange2base: NDArray[np.float64], object_points: list[NDArray[np.float64]],
                    points: list[NDArray[np.float64]], setup: str = "eye_in_hand", fit_depth: bool = True,
                    robot_accuracy: tuple[float, float] | None = ROBOT_ACCURACY,
                    uncertainty: bool = True) -> Calibration:
    """X and Z from robot poses and a board's corners lifted to 3D, with the depth scale and bias
    (:class:`~handeye.sensors.depth.model.BoardPoints` through :func:`~handeye.estimation.core.estimate`).

    ``object_points``: per view the corners in the board's frame (m); ``points``: the same corners
    measured in the camera frame (:func:`~handeye.sensors.depth.plane_points`, NaN rows: no depth);
    ``robot_accuracy``: the poses' stated accuracy (deg, mm), added to X's std (None: exact);
    ``uncertainty``: False skips the cross-validation and the jackknife."""
    names = [f"view {i}" for i in range(len(flange2base))]
    return estimate(BoardPoints(setup, names, object_points, points, fit_depth),
                    ControllerPoses(np.asarray(flange2base, float), robot_accuracy), uncertainty=uncertainty)


def calibrate_spheres(flange2base: NDArray[np.float64], centres: NDArray[np.float64], setup: str = "eye_to_hand",
                      covariances: NDArray[np.float64] | None = None, fit_depth: bool = True,
                      robot_accuracy: tuple[float, float] | None = ROBOT_ACCURACY,
                      uncertainty: bool = True, radii: NDArray[np.float64] | None = None) -> Calibration:
    """X from the centres of spheres measured by a depth camera, without any board
    (:class:`~handeye.sensors.depth.model.SphereCentres` through :func:`~handeye.estimation.core.estimate`).

    Eye-to-hand: a sphere on the flange, seen by the fixed camera (``Z`` is its centre in the
    flange frame). Eye-in-hand: one or more spheres fixed in the cell (``Z``: the first one's
    centre in the base frame). ``centres`` (N, 3) or (N, K, 3), NaN where not seen;
    ``covariances`` their shapes (:class:`~handeye.sensors.depth.Sphere`'s ``cov``); ``radii`` (K,)."""
    names = [f"view {i}" for i in range(len(flange2base))]
    return estimate(SphereCentres(setup, names, centres, covariances, radii, fit_depth),
                    ControllerPoses(np.asarray(flange2base, float), robot_accuracy), uncertainty=uncertainty)


@dataclass(frozen=True)
class DepthMember:
    """A rig's depth camera (its registration's ``rig_member``): a depth session over the rig's views."""

    session: DepthSession
    #: what a view it missed lacks
    missing: str = "cloud"

    @property
    def seen(self) -> list[bool]:
        """Per view of the rig whether it has a cloud (and, for a board, an intensity image)."""
        d = self.session
        images = d.image_paths or [None] * len(d.cloud_paths)
        return [c.is_file() and (i is None or i.is_file()) for c, i in zip(d.cloud_paths, images)]

    @property
    def files(self) -> list[Path]:
        """Its clouds and intensity images."""
        return [p for p in self.session.cloud_paths + (self.session.image_paths or []) if p.is_file()]

    @property
    def target_spec(self) -> dict[str, Any]:
        """The target it sees."""
        return self.session.target_spec

    @property
    def board_images(self) -> list[Path]:
        """Its intensity images that show a board, over the views it saw (found with the cameras')."""
        d = self.session
        if d.kind == "spheres" or d.image_paths is None:
            return []
        return [d.image_paths[k] for k, ok in enumerate(self.seen) if ok]

    def model(self, name: str, names: list[str], notes: list[str], progress: bool = False,
              detected: list | None = None) -> BoardPoints | SphereCentres:
        """Its sensor model over the rig's views ``names``: the views it has measured as a depth
        session's are (a board's corners lifted onto its plane in the cloud, or the spheres' centres); a
        view it missed, or could not measure (said by its ``name`` in ``notes``), has no rows.
        ``detected``: the board found in :attr:`board_images` with the cameras' images."""
        d = self.session
        seen = [k for k, ok in enumerate(self.seen) if ok]
        mine = replace(d, names=[names[k] for k in seen], cloud_paths=[d.cloud_paths[k] for k in seen],
                       image_paths=None if d.image_paths is None else [d.image_paths[k] for k in seen],
                       flange2base=d.flange2base[seen])
        v = measure_depth_session(mine, progress, detected=detected)
        index = [seen[i] for i in v.index]
        notes += [f"sensor {name}: {n}" for n in v.notes]
        notes += [f"sensor {name}: view {view} skipped: {why}" for view, why in v.skipped]
        notes.append(f"sensor {name}: {len(index)} of {len(names)} views measured in its clouds")
        if d.kind == "spheres":
            centres = np.full((len(names), len(d.radii), 3), np.nan)
            covs = np.broadcast_to(np.eye(3), (len(names), len(d.radii), 3, 3)).copy()
            centres[index] = np.array(v.points).reshape(-1, len(d.radii), 3)
            covs[index] = np.array(v.covs).reshape(-1, len(d.radii), 3, 3)
            return SphereCentres(d.setup, names, centres, covs, np.array(d.radii))
        obj, pts = [np.zeros((0, 3))] * len(names), [np.zeros((0, 3))] * len(names)
        for k, o, q in zip(index, v.object_points, v.points):
            obj[k], pts[k] = o, q
        return BoardPoints(d.setup, names, obj, pts)


def rig_member(folder: Path, setup: str, names: list[str], flange2base: NDArray[np.float64], block: dict[str, Any],
               name: str, target: Any, where: str) -> DepthMember:
    """A rig's depth camera read (its block under ``sensors:``: ``depth:``, ``camera:``, its folders of
    ``clouds`` and ``images`` named by view, and its ``target``), checked as a depth session's are."""
    check_keys(block, RIG_DEPTH_KEYS, where)
    check_keys(block["depth"], ("unit", "range"), f"{where}: depth")
    return DepthMember(rig_depth(folder, setup, names, flange2base, block, name, target, where))
