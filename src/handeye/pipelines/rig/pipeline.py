"""Rigs calibrated: each sensor alone, then all in one fit, and a check between them.

:func:`calibrate_rig` takes one sensor model per sensor (each over the rig's views; a view where a
sensor saw nothing has no rows of it) and the robot's poses: it calibrates each sensor alone (its own
answer, and the joint fit's start), then the rig as one model (:class:`~handeye.sensors.rig.Rig`:
sensor 0's X, every other sensor's pose relative to it, the shared target) through the estimation
core, each robot pose's error fitted (:class:`~handeye.robot.models.PoseErrors`, when the robot's
accuracy is stated: the sensors share it): every X and every relative pose with its std from the
joint fit. A sensor whose measurements
fit the rig more than :data:`DISAGREE` times worse than the other sensors' (each against the noise
it states) disagrees with the rest (a wrong focal length, a camera that moved): with three sensors
or more it is named, left out of the joint fit, and keeps its own answer; with two, named in a note.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..._shared.io import files_digests_soon
from ..._shared.threads import on_one_blas_thread
from ...errors import DegenerateMotionError, HandEyeError, InputMismatchError
from ...estimation.core import WEAKEST_NOTE, estimate
from ...estimation.readings import check_readings
from ...estimation.uncertainty import robot_accuracy_cov
from ...estimation.verdict import disagreement_verdict
from ...frames.metrics import std_deg_mm
from ...frames.setups import pose_name
from ...geometry.se3 import invert
from ...options import CalibrationOptions
from ...result import Calibration
from ...robot.models import ControllerPoses, PoseErrors, RobotModel
from ...sensors.base import HasNuisances, SensorModel, SharesTarget
from ...sensors.camera.detect import detect_images
from ...sensors.camera.model import CameraCorners
from ...sensors.camera.pnp import LabelledViews, labelled_by_robot, relabel_points
from ...sensors.camera.targets import target_from_spec
from ...sensors.depth.model import BoardPoints
from ...sensors.rig import Rig
from ...solvers import closed_form
from .._sensor import held_and_freed, label_notes, robot_model, sensor_options, session_robot_input
from .session import RigSession, load_rig_session

__all__ = ["RigCalibration", "calibrate_rig", "calibrate_rig_session", "rig_members", "DISAGREE"]

#: A sensor whose residual in the joint fit, against its stated noise, exceeds the other sensors'
#: (their median, or their stated noise when they fit better than it) by this factor disagrees with the rest.
DISAGREE = 1.5


@dataclass(frozen=True)
class RigCalibration:
    """A rig's calibration: the joint fit (``joint``: sensor 0's X as ``X``; in ``joint.sensor.figures``
    every sensor's X, its residual per view, the relative poses, each sensor's own answer in short
    (``alone``) and the sensors left out; their reasons in ``joint.notes``), each sensor's own
    (``alone``, by name), the sensors that disagreed with the rest (named, with why; left out of
    ``joint``) and the sensors skipped."""

    joint: Calibration | None
    alone: dict[str, Calibration]
    sensor_names: list[str]
    disagreeing: list[tuple[str, str]] = field(default_factory=list)
    skipped: list[tuple[str, str]] = field(default_factory=list)

    def X(self, name: str):
        """Sensor ``name``'s X: the joint fit's, or its own when it was left out."""
        if self.joint is not None and name in self.joint.sensor.figures.get("X_per_sensor", {}):
            return np.array(self.joint.sensor.figures["X_per_sensor"][name]["X"])
        return self.alone[name].X


def _shared(robot: RobotModel, members: list[SensorModel]) -> RobotModel:
    """The robot of the joint fit: the controller's poses with the error of each pose two sensors or
    more saw fitted when the robot states its accuracy (the sensors share it, so it cancels in their
    relative poses: measured, a stereo pair's relative pose 0.12 -> 0.03 mm with 0.01 deg / 0.05 mm of
    robot error); a pose one sensor alone saw is left as reported (its error would take that sensor's
    own measurements: two laser profilers that scanned a ball from poses of their own fitted each
    profile to 0.01-0.03 mm where 0.16-0.18 mm was their noise, and through the controller's poses X
    fitted 1.5x worse than one ball under both); else as given."""
    if type(robot) is not ControllerPoses or robot.accuracy is None:
        return robot
    seen = np.zeros(robot.n_views, dtype=np.intp)
    for m in members:
        seen[np.unique(np.asarray(m.owner))] += 1
    shared = np.flatnonzero(seen >= 2)
    return PoseErrors(robot.poses, robot.accuracy, views=shared) if len(shared) else robot


def _stated_mm(member: SensorModel) -> float:
    """A sensor's stated noise (mm), the median over its rows."""
    return max(float(np.median(member.noise_mm(np.arange(len(member.owner))))), 1e-9)


def _named(names: tuple[str, ...], member: SensorModel, sensor: str) -> tuple[str, ...]:
    """Of the unknowns ``names`` (``radius``: every sensor's; ``laser_a.radius``: one sensor's), those of
    ``member`` (sensor ``sensor``), as its own fit names them."""
    own = {n.name for n in (member.nuisances if isinstance(member, HasNuisances) else ())}
    return tuple(dict.fromkeys(n.split(".", 1)[1] if n.startswith(f"{sensor}.") else n for n in names
                               if (n in own) or (n.startswith(f"{sensor}.") and n.split(".", 1)[1] in own)))


def _in_rig(names: tuple[str, ...], rig: Rig) -> tuple[str, ...]:
    """The unknowns ``names`` as the rig's joint fit names them: each sensor's own (``<sensor>.<name>``)."""
    return tuple(n.name for n in rig.nuisances if n.name in names or n.name.split(".", 1)[1] in names)


def calibrate_rig(members: list[SensorModel], sensor_names: list[str], robot: RobotModel, *, shared_target: bool = True,
                  folds: int | None = None, hold: tuple[str, ...] = (), free: tuple[str, ...] = ()) -> RigCalibration:
    """Calibrate a rig (the module docstring).

    Parameters
    ----------
    members : list of SensorModel
        One per sensor, each over the rig's views.
    sensor_names : list of str
        Distinct names.
    robot : RobotModel
        The robot's poses (one table for the rig).
    shared_target : bool
        The sensors see one target.
    folds : int, optional
        Cross-validation folds of the joint fit.
    hold, free : tuple of str
        The sensors' unknowns beside X to hold or to fit whatever the capture
        (:func:`~handeye.estimation.core.estimate`): ``radius`` for every sensor's, ``laser_a.radius``
        for one sensor's.

    Returns
    -------
    RigCalibration

    Raises
    ------
    InputMismatchError
        Names not distinct, or counts that differ.

    Examples
    --------
    >>> from handeye.robot.models import ControllerPoses
    >>> from handeye.pipelines.rig.simulate import rig_scene
    >>> sc = rig_scene(12, "eye_in_hand", rng=0)
    >>> rig = calibrate_rig(sc.camera_models(), ["left", "right"], ControllerPoses(sc.flange2base))
    >>> rig.joint.verdict, sorted(rig.joint.sensor.figures["relative"])
    ('good', ['right_to_left'])
    """
    if len(members) != len(sensor_names):
        raise InputMismatchError(f"{len(members)} sensors and {len(sensor_names)} names: one name per sensor")
    if len(set(sensor_names)) != len(sensor_names):
        twice = sorted({n for n in sensor_names if sensor_names.count(n) > 1})
        raise InputMismatchError(f"sensor name(s) {', '.join(twice)} given twice: each sensor needs its own name")
    own = [(s, m.nuisances if isinstance(m, HasNuisances) else ()) for m, s in zip(members, sensor_names)]
    every = {n.name for _, nuisances in own for n in nuisances} | {f"{s}.{n.name}" for s, nuisances in own for n in nuisances}
    unknown = [n for n in (*hold, *free) if n not in every]
    if unknown:
        raise InputMismatchError(f"{', '.join(unknown)}: not an unknown of the rig's sensors that can be held or freed; "
                                 f"theirs are {', '.join(sorted(every)) or 'none'}")
    alone: dict[str, Calibration] = {}
    skipped: list[tuple[str, str]] = []
    for m, name in zip(members, sensor_names):
        try:
            alone[name] = estimate(m, robot, folds, hold=_named(hold, m, name), free=_named(free, m, name))
        except HandEyeError as e:
            skipped.append((name, str(e)))
    kept = [k for k, n in enumerate(sensor_names) if n in alone]
    disagreeing: list[tuple[str, str]] = []
    joint = None
    while len(kept) >= 2:
        names = [sensor_names[k] for k in kept]
        starts = [(alone[n].X, alone[n].sensor.params) for n in names]  # each sensor's own fit: X and its unknowns
        kept_members = [members[k] for k in kept]
        rig = Rig(kept_members, names, starts, shared_target)
        joint = estimate(rig, _shared(robot, kept_members), folds, hold=_in_rig(hold, rig), free=_in_rig(free, rig))
        # each sensor's residual in the joint fit against the noise it states
        ratio = np.array([_member_rms(joint, i) / _stated_mm(members[k]) for i, k in enumerate(kept)])
        worst = int(np.argmax(ratio))
        # sensors that fit better than they state are held to 1: a camera whose corners are found to 0.02 px
        # where 0.2 px is stated makes no other sensor look worse
        others = max(float(np.median(np.delete(ratio, worst))), 1.0)
        worse = float(ratio[worst] / others)
        if worse > DISAGREE:
            why = (f"its measurements fit the rig {worse:.1f}x worse than the other sensors' do (against "
                   "each one's stated noise): a wrong intrinsic (focal length, distortion), a sensor that moved during the "
                   "capture, or another sensor's data")
            if len(kept) > 2:
                disagreeing.append((names[worst], why + "; left out of the joint fit, its own answer kept"))
                kept.pop(worst)
                continue
            # which of two is wrong the data cannot tell, that one is (the robot's accuracy the fit infers
            # takes the disagreement too)
            bad, other = names[worst], names[1 - worst]
            figures = dict(joint.sensor.figures, disagreeing_pair={"sensor": bad, "other": other, "ratio": worse})
            joint = replace(joint, sensor=replace(joint.sensor, figures=figures), notes=list(joint.notes) + [
                f"{bad}: {why}; with two sensors it stays in (the other's data are the only check)"],
                diagnostics=disagreement_verdict(joint.diagnostics, (
                    f"{bad} fits the rig {worse:.1f}x worse than {other} does: check its intrinsics (focal length, "
                    f"distortion) and that it did not move, then calibrate again (its own answer is beside the rig's, "
                    f"sensors/{bad}/); the X and the robot accuracy below take the disagreement in")))
        break
    if joint is not None and joint.robot_accuracy is not None:
        # each sensor's X takes the robot's error common to all poses whole, as X's std does: the same
        # accuracy (raised to what the views show) and the same formula as the first sensor's
        per = {}
        for n, f in joint.sensor.figures["X_per_sensor"].items():
            cov = np.asarray(f["cov"]) + robot_accuracy_cov(np.asarray(f["X"]), joint.robot_accuracy)
            per[n] = dict(f, std_deg_mm=std_deg_mm(cov).tolist(), cov=cov.tolist())
        joint = replace(joint, sensor=replace(joint.sensor, figures=dict(joint.sensor.figures, X_per_sensor=per)))
    if joint is None and not alone:
        raise DegenerateMotionError("no sensor of the rig could be calibrated: " + "; ".join(f"{n}: {w}" for n, w in skipped))
    if joint is not None:  # each sensor's own answer and the sensors left out, in the joint fit's figures and notes
        own = {n: {"kind": c.sensor.sensor, "target": c.sensor.target, "X": c.X.tolist(), "std_deg_mm": c.std.tolist(),
                   "cov": None if c.cov is None else c.cov.tolist(), "Z": c.Z.tolist(), "verdict": c.verdict,
                   "fit_rms_mm": c.sensor.fit_rms_mm,
                   "heldout_mm": None if c.prediction_error is None else c.prediction_error["mm"]} for n, c in alone.items()}
        figures = dict(joint.sensor.figures, alone=own, disagreeing=[n for n, _ in disagreeing], skipped=[n for n, _ in skipped])
        joint = replace(joint, sensor=replace(joint.sensor, figures=figures), notes=_left_out(disagreeing, skipped) + list(joint.notes))
    return RigCalibration(joint, alone, list(sensor_names), disagreeing, skipped)


def _left_out(disagreeing: list[tuple[str, str]], skipped: list[tuple[str, str]]) -> list[str]:
    """The sensors left out of the joint fit, with why, in words."""
    return ([f"sensor {n} disagrees with the rest: {why}" for n, why in disagreeing]
            + [f"sensor {n} skipped: {why}" for n, why in skipped])


def _member_rms(joint: Calibration, k: int) -> float:
    """Sensor ``k``'s RMS residual (mm) in the joint fit."""
    return float(joint.sensor.figures["rms_mm_per_sensor"][k])


def _member_notes(notes: list[str], name: str, names: list[str]) -> list[str]:
    """The rig's notes that concern sensor ``name``: those about it, and those about no sensor.

    A note about sensors begins by naming them, as the rig's notes are written: ``sensor NAME: ...``,
    ``sensor NAME disagrees ...`` / ``skipped ...``, ``NAME: ...`` or a relative pose ``A_to_B: ...``
    (``A2B: ...`` in results written before it was so named); the head is matched whole (a sensor
    ``cam`` is not in a note about ``camera``)."""
    pairs = {key: {a, b} for a in names for b in names if a != b for key in (pose_name(a, b), f"{a}2{b}")}

    def about(note: str) -> set[str]:
        head = note.split(":", 1)[0]
        words = note.split(" ", 2)
        out = {n for n in names if head in (n, f"sensor {n}") or (len(words) > 2 and words[0] == "sensor" and words[1] == n)}
        return out | pairs.get(head, set())
    return [n for n in notes if not about(n) or name in about(n)]


def rig_members(cal: Calibration) -> dict[str, Calibration]:
    """Each sensor's own result from a rig's calibration (:func:`calibrate_rig_session`): the joint
    fit's X of that sensor with its covariance, the shared target, the rig's verdict and the notes
    that concern it; a sensor left out of the joint fit (it disagreed with the rest) gets its own
    calibration's X, std and verdict. A sensor that was skipped has none. Empty when ``cal`` is not
    a rig's.

    Each is a :class:`~handeye.result.Calibration` as one sensor's calibration is: written, it
    reads back with :func:`handeye.load_result` and ``handeye verify`` takes it.

    Examples
    --------
    >>> from handeye.robot.models import ControllerPoses
    >>> from handeye.pipelines.rig.simulate import rig_scene
    >>> sc = rig_scene(12, "eye_in_hand", rng=0)
    >>> rig = calibrate_rig(sc.camera_models(), ["left", "right"], ControllerPoses(sc.flange2base))
    >>> members = rig_members(rig.joint)
    >>> sorted(members), bool(np.allclose(members["left"].X, rig.joint.X))
    (['left', 'right'], True)
    """
    if cal.sensor is None or "X_per_sensor" not in cal.sensor.figures:
        return {}
    f = cal.sensor.figures
    names = list(f["sensors"]) + list(f.get("disagreeing", []))
    first = f["sensors"][0]
    out = {}
    for name in names:
        joint = name in f["X_per_sensor"]
        mine = f["X_per_sensor"][name] if joint else f["alone"][name]
        seen = [(v, r) for v, r in zip(_view_names(cal), _per_view(f, name, cal)) if r is not None]
        views, rms = [v for v, _ in seen], [r for _, r in seen]
        figures = dict(mine.get("figures") or {}) | {"rig": {"sensors": names, "in_joint_fit": joint, "first_sensor": first},
                                                     "alone": f["alone"].get(name)}
        if joint and name != first:
            figures["rig"]["pose_in_first_sensor"] = f["relative"][pose_name(name, first)]
        record = replace(cal.sensor, sensor=mine.get("kind", cal.sensor.sensor), target=mine.get("target", cal.sensor.target),
                         views=views, residual_mm=np.asarray(rms, float), figures=figures, heldout_mm=None,
                         sections=None, fit_rms_mm=float(np.sqrt(np.mean(np.square(rms)))) if rms else float("nan"))
        cov = None if mine.get("cov") is None else np.asarray(mine["cov"], float)
        how = (f"sensor {name} of a rig of {len(names)}: X from the joint fit of "
               f"{', '.join(f['sensors'])}" if joint else
               f"sensor {name} of a rig of {len(names)}: left out of the joint fit, its own calibration")
        notes = _member_notes(list(cal.notes), name, names)
        if cal.kinematic is not None:  # one arm, one table: written once, beside the rig's result
            notes.append("the arm's table was fitted with the rig: its corrected table is the rig's (arm_corrected.yaml "
                         "beside the rig's result.json)")
        if name != first:  # the weakest direction the core names is the first sensor's X's
            notes = [n for n in notes if not n.startswith(WEAKEST_NOTE)]
        member = replace(cal, kinematic=None, X=np.asarray(mine["X"], float), cov=cov, std=np.asarray(mine["std_deg_mm"], float),
                         sensor=record, notes=[how] + notes)
        if mine.get("Z") is not None:  # its own target (a profiler's ball beside a camera's board)
            member = replace(member, Z=np.asarray(mine["Z"], float),
                             std_Z=None if mine.get("Z_std_deg_mm") is None else np.asarray(mine["Z_std_deg_mm"], float))
        if name in f.get("images_per_sensor", {}):  # a camera of a rig session: its images and intrinsics
            im = f["images_per_sensor"][name]
            member = replace(member, image_names=list(im["names"]), image_sha256=list(im["sha256"]),
                             camera_matrix=np.asarray(im["K"], float), dist_coeffs=np.asarray(im["dist"], float),
                             intrinsics_source="session.yaml", reprojection_rms=np.zeros(0))
        if not joint:
            member = replace(member, Z=np.asarray(mine["Z"], float), std_sources=None, std_Z=None, cross_validation=None,
                             diagnostics=replace(cal.diagnostics, verdict=mine["verdict"]))
        out[name] = member
    return out


def _view_names(cal: Calibration) -> list[str]:
    """Every view of the rig, the fit's or not."""
    return list(cal.diagnostics.names) if cal.diagnostics is not None and cal.diagnostics.names else list(cal.sensor.views)


def _per_view(f: dict, name: str, cal: Calibration) -> list:
    """Sensor ``name``'s RMS residual per view of the rig (None where it has none)."""
    return f.get("view_rms_mm_per_sensor", {}).get(name) or [None] * len(_view_names(cal))


class _Labels:
    """A symmetric board's labelling in a rig (a chessboard's corners named from either end, view by view
    and sensor by sensor): each camera's views against the robot's motion
    (:func:`~handeye.sensors.camera.pnp.labelled_by_robot`; a depth camera's when its board is measured),
    then, with one target for all, each sensor's whole labelling turned to the first's, so that all name
    one target frame: the target's pose Z from each sensor's closed form, the symmetry that brings it
    nearest the first sensor's."""

    def __init__(self, symmetries: list[NDArray[np.float64]], flange2base: NDArray[np.float64], setup: str,
                 shared: bool) -> None:
        self.symmetries, self.flange2base, self.setup, self.shared = symmetries, flange2base, setup, shared
        self.reference: NDArray[np.float64] | None = None  # the first sensor's Z
        self.done = False  # a camera's views were labelled
        self.none = LabelledViews(np.zeros((0, 4, 4)), [], np.zeros(0, np.intp), np.zeros(0, bool), np.zeros(0, bool))

    def labelled(self, name: str, model: CameraCorners, object_points: list[NDArray[np.float64]], view_names: list[str],
                 notes: list[str]) -> list[NDArray[np.float64]]:
        """``object_points`` of camera ``name`` (``model`` over them) relabelled; what is in doubt said in ``notes``."""
        if len(self.symmetries) < 2:
            return object_points
        poses = model.view_poses()
        views = np.flatnonzero(np.isfinite(poses).all(axis=(1, 2)))
        if len(views) < 2:
            return object_points
        got = labelled_by_robot(poses[views], [object_points[v] for v in views], self.flange2base[views], self.setup,
                                self.symmetries)
        self.done = True
        notes += [f"sensor {name}: {n}" for n in label_notes("board", 1, self.setup, [view_names[v] for v in views], got)]
        out = list(object_points)
        for v, points in zip(views, got.object_points):
            out[v] = points
        best = self._turn(name, views, got.target2cam, notes)
        return [relabel_points(p, self.symmetries[best]) if len(p) else p for p in out] if best else out

    def board(self, name: str, model: BoardPoints, notes: list[str]) -> BoardPoints:
        """A depth camera's board (its views labelled against the robot when measured) turned to the
        first sensor's labelling."""
        if len(self.symmetries) < 2:
            return model
        poses = model.view_poses()
        views = np.flatnonzero(np.isfinite(poses).all(axis=(1, 2)))
        best = self._turn(name, views, poses[views], notes)
        return model.relabelled(self.symmetries[best]) if best else model

    def _turn(self, name: str, views: NDArray[np.intp], target2cam: NDArray[np.float64], notes: list[str]) -> int:
        """The symmetry that turns sensor ``name``'s labelling (its poses ``target2cam`` of ``views``) to the
        first's (0: none; the first sets the reference): the one bringing its Z nearest the first's."""
        if not self.shared or len(views) < 3:
            return 0
        try:
            Z = closed_form(self.flange2base[views], target2cam, self.setup, "daniilidis")[1]
        except HandEyeError:  # its own fit says why
            return 0
        if self.reference is None:
            self.reference = Z
            return 0
        # the symmetry S with Z S nearest the first's Z: a half turn moves the board's corners by its size
        best = int(np.argmin([np.linalg.norm((invert(self.reference) @ Z @ S)[:3] - np.eye(4)[:3]) for S in self.symmetries]))
        if best:
            notes.append(f"sensor {name}: the symmetric target's corners named from the other end than in the first "
                         "sensor's views: renamed, so that every sensor sees one target frame")
        return best


@on_one_blas_thread  # narrow matrices throughout: a second BLAS thread spins more than it works
def calibrate_rig_session(folder: str | Path | RigSession, options: CalibrationOptions | None = None, *,
                          progress: bool = False, jobs: int | None = None,
                          **changes) -> Calibration:
    """Calibrate a rig session folder (:mod:`handeye.pipelines.rig.session`): the target found in every
    sensor's images, then :func:`calibrate_rig`.

    Returns
    -------
    Calibration
        The joint fit: X is the first sensor's; ``sensor.figures`` holds every sensor's X with its
        std (``X_per_sensor``), its residual per view (``view_rms_mm_per_sensor``), the relative
        poses (``relative``), each sensor's own answer (``alone``: X, std, verdict, its fit's RMS and
        held-out error, mm) and the sensors that disagreed or were skipped; the notes say the same
        in words.
        With one sensor left, that sensor's own calibration, with a note.

    Raises
    ------
    SessionError
        A bad session (:func:`~handeye.pipelines.rig.session.load_rig_session`).
    DegenerateMotionError
        No sensor could be calibrated.
    """
    opts = sensor_options(options, changes, "a rig session", table=True)
    s = folder if isinstance(folder, RigSession) else load_rig_session(folder, opts.arm)
    cameras = [sensor for sensor in s.sensors if sensor.member is None]
    members, notes = [], list(s.notes)
    image_paths = [p for sensor in cameras for p in sensor.images if p is not None]
    # each image's digest (its own result refuses them in verify), hashed on the core the fit leaves idle
    hashed = files_digests_soon(image_paths, s.folder)
    # every camera's images, and the other sensors' images of the same board (a depth camera's intensity
    # images), in one parallel detection (no worker idle at the end of each sensor's)
    same = [x for x in s.sensors if x.member is not None and x.member.target_spec == s.target_spec and x.member.board_images]
    board_paths = [p for x in same for p in x.member.board_images]
    # a board seen in images (not a ball or a plate of profilers and depth cameras alone)
    target = target_from_spec(s.target_spec, where="target") if image_paths or board_paths else None
    results = detect_images(image_paths + board_paths, target, jobs=jobs, progress=progress) if target is not None else []
    found, board_found = iter(results[:len(image_paths)]), iter(results[len(image_paths):])
    robot = robot_model(s, list(range(len(s.names))), opts)  # joint angles through the arm's table, or poses
    labels = _Labels(target.symmetries() if target is not None else [np.eye(4)], robot.flange2base(np.zeros(robot.n_params)),
                     s.setup, s.shared_target)
    for sensor in s.sensors:
        if sensor.member is not None:  # another kind's sensor: its model from its own measurements
            mine = [next(board_found) for _ in sensor.member.board_images] if any(sensor is x for x in same) else None
            model = sensor.member.model(sensor.name, s.names, notes, progress, mine)
            members.append(labels.board(sensor.name, model, notes) if isinstance(model, BoardPoints) and mine is not None
                           else model)
            continue
        paths = [p for p in sensor.images if p is not None]
        image_points, object_points = [], []
        for p in sensor.images:
            det = next(found).detection if p is not None else None
            image_points.append(np.zeros((0, 2)) if det is None else det.image_points)
            object_points.append(np.zeros((0, 3)) if det is None else det.object_points)
        seen = sum(len(u) > 0 for u in image_points)
        notes.append(f"sensor {sensor.name}: the target found in {seen} of {len(paths)} images")
        object_points = labels.labelled(sensor.name, CameraCorners(s.setup, s.names, image_points, object_points, sensor.K,
                                                                   sensor.dist), object_points, s.names, notes)
        members.append(CameraCorners(s.setup, s.names, image_points, object_points, sensor.K, sensor.dist))
    if labels.done and target is not None:  # X is fixed by the labelling; Z only up to the board's symmetry
        notes += label_notes(target.type, len(labels.symmetries), s.setup, [], labels.none)
    # one target's pose for all, when every model can map it into its unknowns (a depth camera's balls
    # cannot: their centres stay its own)
    shared = s.shared_target and all(isinstance(m, SharesTarget) for m in members)
    if members:  # the poses' reading checked on the first sensor's views before any sensor is fitted
        check_readings(members[0], robot, s.pose_input, s.flange2base)
    hold, free = held_and_freed(s, opts)
    rig = calibrate_rig(members, [x.name for x in s.sensors], robot, shared_target=shared, folds=opts.folds, hold=hold,
                        free=free)
    if rig.joint is None:
        only = next(iter(rig.alone.values()))
        return replace(only, notes=notes + _left_out(rig.disagreeing, rig.skipped) + ["one sensor left: its own calibration, "
                                                                                       "no rig"] + list(only.notes),
                       input_folder=s.folder)
    # each camera's images by name and digest: its own result refuses them in verify (they are no second capture)
    by_path = hashed.result()[1]
    images = {x.name: {"names": [p.name for p in x.images if p is not None],
                       "sha256": [by_path[str(p)] for p in x.images if p is not None],
                       "K": np.asarray(x.K).tolist(), "dist": np.asarray(x.dist).tolist()} for x in cameras}
    joint = replace(rig.joint, sensor=replace(rig.joint.sensor, figures=dict(rig.joint.sensor.figures, images_per_sensor=images)))
    return replace(joint, notes=notes + list(rig.joint.notes),
                   skipped=[(n, w) for n, w in rig.skipped] + list(rig.joint.skipped), input_folder=s.folder,
                   robot_input=session_robot_input(s, joint.flange2base))
