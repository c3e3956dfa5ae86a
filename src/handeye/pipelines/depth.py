"""Depth-camera sessions on disk: clouds (and intensity images) with robot poses, through one pipeline.

A depth session is a session folder (docs/guide.md, "Depth cameras") whose ``session.yaml`` has a
``depth:`` mapping::

    setup: eye_to_hand
    target: {type: sphere, diameter: 0.05}     # or a board (chessboard, charuco, ...) as for images
    camera: {K: ..., dist: ...}                # optional: the intensity image's intrinsics
    depth:
      unit: m                                  # the clouds' unit: m | mm
      range: [0.3, 1.5]                        # optional: the camera's stated working range, metres
    poses: {file: poses.csv, format: quat_wxyz, length_unit: mm, angle_unit: deg}

``poses.csv``'s first column is ``image`` (a board: the intensity image in ``images/``, its cloud
the file of the same stem in ``clouds/``: .npy, .ply or .pcd) or ``cloud`` (spheres: the cloud
file in ``clouds/``). :func:`calibrate_depth_session` measures every view (a board's corners where
their rays meet its plane fitted to the cloud, :func:`~handeye.sensors.depth.plane_points`; a sphere's
centre, :func:`~handeye.sensors.depth.find_spheres`; a view that cannot be
measured is skipped with its reason, never silently), fits X with the depth scale and bias,
leaves out views the fit does not explain (named), cross-validates on held-out views (3D error
at the target, mm) and gives the verdict.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._shared.progress import Progress
from ..errors import DegenerateMotionError, HandEyeError, InputMismatchError
from ..estimation.verdict import ACCEPT_DEG, ACCEPT_MM
from ..frames.setups import setup_info
from ..io.depth_session import DepthSession, is_depth_session, load_depth_session
from ..options import ROBOT_ACCURACY
from ..sensors.camera import detect_images, target_from_spec
from ..sensors.depth.clouds import check_frame, depth_sigma, plane_points, read_cloud
from ..sensors.depth.spheres import find_spheres
from .depth_fit import DepthCalibration, calibrate_depth, calibrate_spheres, predict_points

__all__ = ["DepthSession", "DepthResult", "is_depth_session", "load_depth_session", "calibrate_depth_session",
           "OUTLIER_FACTOR"]

#: A view whose RMS 3D residual exceeds this many times the median view's (and 1 mm) is left out.
OUTLIER_FACTOR = 5.0
#: Held-out folds of the cross-validation.
FOLDS = 5
#: A fit whose RMS 3D residual exceeds this many times what the robot's accuracy and the depth noise
#: allow explains nothing: the verdict is inconsistent.
FIT_FACTOR = 5.0


@dataclass(frozen=True)
class DepthResult:
    """A depth session calibrated: X with its std, the verdict and what it rests on."""

    session: DepthSession
    calibration: DepthCalibration
    verdict: str  #: good | weak | inconsistent (a session that cannot determine X raises instead)
    advice: list[str]
    used: list[str]  #: the views the fit used
    skipped: list[tuple[str, str]]  #: views left out, each with its reason
    distances_m: NDArray[np.float64]  #: per used view, the target's median depth
    heldout_mm: float | None  #: k-fold cross-validation: RMS 3D error of held-out views' points predicted from the robot
    fit_mm: float  #: the RMS 3D residual of the used views in the fit, mm
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        """Plain numbers and strings (result.yaml / result.json)."""
        cal = self.calibration
        out: dict[str, Any] = {
            "setup": cal.setup, "kind": self.session.kind, "verdict": self.verdict, "advice": list(self.advice),
            "X": cal.X.tolist(), "Z": cal.Z.tolist(),
            "std": {"rotation_deg": cal.std[:3].tolist(), "translation_mm": cal.std[3:].tolist(),
                    "data_only_rotation_deg": cal.std_data[:3].tolist() if cal.std_data is not None else None,
                    "data_only_translation_mm": cal.std_data[3:].tolist() if cal.std_data is not None else None},
            "depth": {"scale": cal.depth_scale, "scale_std": cal.depth_scale_std, "bias_mm": 1e3 * cal.depth_bias,
                      "bias_std_mm": 1e3 * cal.depth_bias_std, "noise_along_rays_mm": cal.rms_mm},
            "views": {"used": list(self.used), "skipped": [{"view": n, "reason": r} for n, r in self.skipped],
                      "distance_m": self.distances_m.tolist(),
                      "residual_mm": cal.residuals_mm.tolist() if cal.residuals_mm is not None else None},
            "fit_rms_mm": self.fit_mm, "heldout_rms_mm": self.heldout_mm, "notes": list(self.notes),
        }
        if cal.centres is not None:
            out["spheres"] = {"centres_m": cal.centres.tolist(), "centres_std_mm": cal.centres_std.tolist(),
                              "frame": setup_info(cal.setup).z_name.split("2")[1]}
        return out


@dataclass
class _Views:
    """What the clouds gave, per measured view."""

    index: list[int] = field(default_factory=list)  #: into the session's views
    object_points: list = field(default_factory=list)  #: boards: (M, 3) per view
    points: list = field(default_factory=list)  #: boards: (M, 3) lifted; spheres: (K, 3) centres (NaN: not seen)
    covs: list = field(default_factory=list)  #: spheres: (K, 3, 3)
    distance: list = field(default_factory=list)
    skipped: list = field(default_factory=list)


def _measure_boards(s: DepthSession, progress: bool, notes: list[str], jobs: int | None) -> _Views:
    target = target_from_spec(s.target_spec)
    out = _Views()
    frames = []
    for k, res in enumerate(detect_images(s.image_paths or [], target, jobs=jobs, progress=progress)):
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
    return out


def _measure_spheres(s: DepthSession, progress: bool) -> _Views:
    out = _Views()
    radii = s.radii or []
    bar = Progress(len(s.cloud_paths), "finding spheres", progress)
    for k, path in enumerate(s.cloud_paths):
        bar.update()
        cloud = read_cloud(path, None, s.unit)
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


def _fit(s: DepthSession, v: _Views, keep: list[int], fit_depth: bool, robot_accuracy, uncertainty: bool = True
         ) -> DepthCalibration:
    F = s.flange2base[[v.index[i] for i in keep]]
    if s.kind == "spheres":
        return calibrate_spheres(F, np.array([v.points[i] for i in keep]), s.setup,
                                 np.array([v.covs[i] for i in keep]), fit_depth, robot_accuracy, uncertainty=uncertainty,
                                 radii=np.array(s.radii))
    return calibrate_depth(F, [v.object_points[i] for i in keep], [v.points[i] for i in keep], s.setup, fit_depth,
                           robot_accuracy, uncertainty=uncertainty)


def _rms_mm(predicted: list, measured: list) -> float:
    d = np.concatenate([(p - m)[np.isfinite(m).all(axis=1)] for p, m in zip(predicted, measured)])
    return float(1e3 * np.sqrt(np.mean(np.sum(d**2, axis=1))))


def _heldout(s: DepthSession, v: _Views, keep: list[int], fit_depth: bool) -> float | None:
    """k-fold over the views: each fold's points predicted from its robot poses by the fit to the others."""
    if len(keep) < 6:
        return None
    folds = np.array_split(np.array(keep), min(FOLDS, len(keep) // 2))
    predicted, measured = [], []
    for fold in folds:
        rest = [i for i in keep if i not in set(fold.tolist())]
        try:
            cal = _fit(s, v, rest, fit_depth, None, uncertainty=False)
        except HandEyeError:  # the others alone do not determine X: no prediction for this fold
            continue
        F = s.flange2base[[v.index[i] for i in fold]]
        predicted += predict_points(cal, F, None if s.kind == "spheres" else [v.object_points[i] for i in fold])
        measured += [v.points[i] for i in fold]
    return _rms_mm(predicted, measured) if predicted else None


def _outliers(cal: DepthCalibration, keep: list[int]) -> list[int]:
    """The views (of ``keep``) whose residual the fit does not explain (none below 6 views)."""
    r = cal.residuals_mm
    if r is None or len(keep) < 6:
        return []
    bad = (r > OUTLIER_FACTOR * np.median(r)) & (r > 1.0)
    return [keep[i] for i in np.nonzero(bad)[0]]


def _allowed_mm(robot_accuracy: tuple[float, float] | None, distance_m: float) -> float:
    """The RMS 3D residual (mm) a point may have, known before any fit: the robot's stated accuracy
    (its rotation at ~1 m) and the depth noise at the views' distance."""
    acc = (0.0, 0.0) if robot_accuracy is None else robot_accuracy
    return float(np.sqrt(3.0) * (acc[1] + np.radians(acc[0]) * 1e3) + 1e3 * depth_sigma(np.array([distance_m]))[0])


def _fit_limit_mm(robot_accuracy: tuple[float, float] | None, distance_m: float) -> float:
    """The RMS 3D residual (mm) beyond which a fit explains nothing (:data:`FIT_FACTOR` times what is allowed)."""
    return FIT_FACTOR * max(_allowed_mm(robot_accuracy, distance_m), 0.5)


def _one_wrong_view(s: DepthSession, v: _Views, keep: list[int], fit_depth: bool, limit_mm: float) -> int | None:
    """The one view without which the others fit within ``limit_mm`` (RMS), when the fit to all is
    dragged off by it (a wrong view among few pulls a least-squares fit everywhere); else None."""
    best = None
    for i in keep:
        rest = [j for j in keep if j != i]
        try:
            cal = _fit(s, v, rest, fit_depth, None, uncertainty=False)
        except HandEyeError:
            continue
        rms = float(np.sqrt(np.mean(np.square(cal.residuals_mm))))
        if best is None or rms < best[0]:
            best = (rms, i)
    return best[1] if best is not None and best[0] <= limit_mm else None


def _verdict(cal: DepthCalibration, heldout: float | None, fit_mm: float, n_outliers: int, n: int,
             robot_accuracy: tuple[float, float] | None, distance_m: float) -> tuple[str, list[str]]:
    advice = list(cal.notes)
    rot, mm = 3 * float(np.linalg.norm(cal.std[:3])), 3 * float(np.linalg.norm(cal.std[3:]))
    # what a point's residual may be, known before the fit (never from its residuals): the robot's
    # accuracy (its rotation at ~1 m) and the depth noise at the views' distance
    allowed = _allowed_mm(robot_accuracy, distance_m)
    if fit_mm > _fit_limit_mm(robot_accuracy, distance_m) or abs(cal.depth_scale - 1.0) > 0.05:
        return "inconsistent", advice + [
            f"the views' points are {fit_mm:.1f} mm (RMS) from the fit (depth scale {cal.depth_scale:.3f}), far beyond "
            f"the {allowed:.1f} mm the robot's accuracy and the depth noise allow: the robot poses and the clouds "
            "disagree (the clouds' and poses' order, the pose format or unit, the setup, the clouds' unit)"]
    if heldout is not None and heldout > 4 * max(fit_mm, 0.1):
        return "inconsistent", advice + [
            f"held-out views are predicted {heldout:.2f} mm (RMS) off, {heldout / fit_mm:.1f}x the fit's {fit_mm:.2f} mm: "
            "the robot poses and the clouds disagree (the setup, the pose format or unit, a target that moved, or "
            "the clouds' and poses' order)"]
    if n_outliers > n // 3:
        return "inconsistent", advice + [f"{n_outliers} of {n} views are not explained by the fit (5x the median "
                                         "view's residual): too many to leave out; check the poses' format and unit, "
                                         "the setup, and that the target did not move"]
    if rot > ACCEPT_DEG or mm > ACCEPT_MM:
        return "weak", advice + [f"3 std of X are {mm:.1f} mm / {rot:.2f} deg, beyond {ACCEPT_MM:g} mm / {ACCEPT_DEG:g} deg: "
                                 "take more views (10-20) with rotations of 30 deg or more about varied axes"]
    return "good", advice


def calibrate_depth_session(folder: str | Path | DepthSession, fit_depth: bool = True,
                            robot_accuracy: tuple[float, float] | None = ROBOT_ACCURACY,
                            progress: bool = False, jobs: int | None = None) -> DepthResult:
    """Calibrate a depth session (:func:`load_depth_session`): measure every view, fit X with the
    depth scale and bias, leave out views the fit does not explain, cross-validate, judge.
    ``jobs``: detection threads for a board's intensity images (default: the cores).

    Raises
    ------
    SessionError, InputMismatchError
        A bad session or cloud (another size than its image, no depth, mm given as m, another frame
        than the image's), naming the file.
    DegenerateMotionError
        Fewer than 3 views measured, or views that cannot determine X; says what to capture.
    """
    s = folder if isinstance(folder, DepthSession) else load_depth_session(folder)
    notes = list(s.notes)
    v = _measure_spheres(s, progress) if s.kind == "spheres" else _measure_boards(s, progress, notes, jobs)
    if len(v.index) < 3:
        raise DegenerateMotionError(
            f"{len(v.index)} of {len(s.names)} views measured ({'; '.join(f'{n}: {r}' for n, r in v.skipped[:5])}): "
            "at least 3 are needed, 10-20 with the flange turned 30 deg or more about varied axes to trust X")
    keep = list(range(len(v.index)))
    skipped = list(v.skipped)
    cal = _fit(s, v, keep, fit_depth, robot_accuracy)
    bad = _outliers(cal, keep)
    limit = _fit_limit_mm(robot_accuracy, float(np.median(v.distance)))
    if not bad and len(keep) >= 6 and np.sqrt(np.mean(np.square(cal.residuals_mm))) > limit:
        wrong = _one_wrong_view(s, v, keep, fit_depth, limit)  # one view may have dragged the whole fit off
        bad = [] if wrong is None else [wrong]
    if bad and len(bad) <= len(keep) // 3:  # a few wrong views are left out, named; more make the verdict
        med = float(np.median(cal.residuals_mm))
        for i in bad:
            skipped.append((s.names[v.index[i]], f"the fit does not explain this view: {cal.residuals_mm[keep.index(i)]:.2f} "
                                                 f"mm RMS against the median view's {med:.2f} mm (a wrong detection, a "
                                                 "target that moved, or a wrong robot pose)"))
        keep = [i for i in keep if i not in bad]
        cal = _fit(s, v, keep, fit_depth, robot_accuracy)
    F = s.flange2base[[v.index[i] for i in keep]]
    fit_mm = _rms_mm(predict_points(cal, F, None if s.kind == "spheres" else [v.object_points[i] for i in keep]),
                     [v.points[i] for i in keep])
    heldout = _heldout(s, v, keep, fit_depth)
    distances = np.array([v.distance[i] for i in keep])
    verdict, advice = _verdict(cal, heldout, fit_mm, len(bad), len(v.index), robot_accuracy, float(np.median(distances)))
    if s.working_range is not None:
        lo, hi = s.working_range
        out = [f"{s.names[v.index[i]]} ({d:.2f} m)" for i, d in zip(keep, distances) if not lo <= d <= hi]
        if out:
            advice.append(f"{len(out)} view(s) outside the camera's stated range {lo:g}-{hi:g} m: {', '.join(out[:5])}; "
                          "depth is least accurate there: capture within the range")
    if skipped:
        advice.append(f"{len(skipped)} view(s) left out: " + "; ".join(f"{n}: {r}" for n, r in skipped[:5]))
    return DepthResult(s, cal, verdict, advice, [s.names[v.index[i]] for i in keep], skipped, distances, heldout,
                       fit_mm, notes)
