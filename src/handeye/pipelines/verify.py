"""Verification on views the calibration has not seen: predict each from its robot pose through X
and Z and compare with where the camera finds the target.

A calibration's own cross-validation (``result.prediction_error``) predicts views held out of its
own capture. A second, independent capture is the stronger test (the thesis's §6.1 asks for tests
on real data before a result is trusted; Zivid's projection check does the same): other poses,
another day, the robot warmed up or not. :func:`verify` reads a result and a session, detects the
target, and gives per view the RMS pixel error and the error in millimetres at the target's
distance (:func:`handeye.estimation.validation.view_errors`), with a verdict against what the calibration
promised.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .._shared.io import file_digest
from .._shared.text import summarize
from ..errors import InputMismatchError
from ..estimation.validation import Views, view_errors
from ..frames.setups import predicted_target2cam
from ..io.results import load_result, result_path
from ..io.session import Session, SessionError, load_session
from ..result import Calibration
from ..sensors.camera.model import CameraCorners
from ..sensors.camera.pnp import project_points
from .calibration import observe

__all__ = ["Verification", "verify", "PROMISE_FACTOR", "FLAG_FACTOR", "NOT_THIS"]

#: A verification passes when its RMS error stays within this factor of the calibration's own
#: cross-validated prediction error (a new capture differs more from the calibration's than its
#: folds differ from each other, so some excess is expected).
PROMISE_FACTOR = 2.0
#: Views whose error exceeds this many times the median are named.
FLAG_FACTOR = 3.0


@dataclass(frozen=True)
class Verification:
    """What :func:`verify` found."""

    setup: str
    names: list[str]  #: the views checked (images with the target)
    px: NDArray[np.float64]  #: per view, RMS pixel error of the predicted target points
    mm: NDArray[np.float64]  #: per view, the same in millimetres at the target's distance
    verdict: str  #: 'good', 'worse than promised', 'not compared' (no promise in the result) or NOT_THIS
    advice: list[str] = field(default_factory=list)
    promised: dict | None = None  #: the calibration's cross-validated prediction error ({'px', 'mm'})
    skipped: list[tuple[str, str]] = field(default_factory=list)  #: (image, reason)
    flagged: list[str] = field(default_factory=list)  #: views far worse than the others
    result_path: Path | None = None
    session_folder: Path | None = None
    #: per view: the image file, the detected target points and the points predicted through X, Z and
    #: the robot pose (px), for the page's pictures (not in verify.json)
    image_paths: list[Path] = field(default_factory=list, repr=False)
    detected: list[NDArray[np.float64]] = field(default_factory=list, repr=False)
    predicted: list[NDArray[np.float64]] = field(default_factory=list, repr=False)

    @property
    def rms_px(self) -> float:
        return float(np.sqrt(np.mean(self.px**2)))

    @property
    def rms_mm(self) -> float:
        return float(np.sqrt(np.mean(self.mm**2)))

    def table(self) -> str:
        rows = [f"{'view':<24} {'px':>8} {'mm':>8}"]
        rows += [f"{n:<24.24} {p:>8.3f} {m:>8.3f}" + ("  <- far off" if n in self.flagged else "")
                 for n, p, m in zip(self.names, self.px, self.mm)]
        return "\n".join(rows)

    def summary(self) -> str:
        said = [] if self.promised is None else [f"{self.promised[u]:.3f} {u}" for u in ("px", "mm")
                                                 if self.promised.get(u) is not None]
        promise = f"; the calibration promised {', '.join(said)} (cross-validated)" if said else ""
        lines = [f"verification: {self.verdict} ({len(self.names)} views: RMS {self.rms_px:.3f} px, {self.rms_mm:.3f} mm "
                 f"at the target; median {np.median(self.px):.3f} px, worst {self.px.max():.3f} px{promise})"]
        lines += [f"advice: {a}" for a in self.advice]
        return "\n".join(lines)

    def as_dict(self) -> dict:
        return {"setup": self.setup, "verdict": self.verdict, "rms_px": self.rms_px, "rms_mm": self.rms_mm,
                "promised": self.promised, "advice": list(self.advice), "flagged": list(self.flagged),
                "views": [{"image": n, "px": float(p), "mm": float(m)} for n, p, m in zip(self.names, self.px, self.mm)],
                "skipped": [{"image": n, "reason": r} for n, r in self.skipped],
                "result": None if self.result_path is None else str(self.result_path),
                "session": None if self.session_folder is None else str(self.session_folder)}


def _with_intrinsics(session: Session, cal: Calibration) -> Session:
    """The session with the intrinsics the calibration used (refined with X and Z, when it came
    from images); else the session's own; a session with neither cannot be verified in pixels."""
    if cal.camera_matrix is not None:
        return replace(session, camera_matrix=cal.camera_matrix, dist_coeffs=cal.dist_coeffs)
    if session.camera_matrix is None:
        raise SessionError(f"{session.folder}: no intrinsics: the result holds none (a calibration from poses) and "
                           "session.yaml has no camera: K, dist")
    return session


#: The verdict when the target is nowhere near where X and Z put it.
NOT_THIS = "not this calibration's"
#: ... judged so when the predicted target is off by more than this fraction of its distance (median).
ELSEWHERE_FRACTION = 0.1


def _refuse_own_images(sess: Session, cal: Calibration, where: str) -> None:
    """A session that reuses the calibration's own images is not a second capture."""
    own = {d: n for n, d in zip(cal.image_names or [], cal.image_sha256 or []) if d}
    if not own:  # a calibration from poses, or written before results held the images' digests
        return
    digests = {name: file_digest(p) for name, p in zip(sess.image_names, sess.image_paths) if Path(p).is_file()}
    same = [(name, own[d]) for name, d in digests.items() if d in own]
    if same:
        raise InputMismatchError(
            f"{sess.folder}: image(s) {summarize(n for n, _ in same)} are the calibration's own inputs (the same bytes as "
            f"{summarize(m for _, m in same)} in {where}): verify needs a capture the calibration has not "
            "seen (other poses, another day); the calibration's own held-out error is its cross-validation")


def _not_where_predicted(X, Z, views: Views) -> str | None:
    """Why these views cannot belong to this calibration (the target is far from where X and Z put it), or None."""
    T = predicted_target2cam(X, Z, views.flange2base, views.setup)
    off = np.linalg.norm(T[:, :3, 3] - views.target2cam[:, :3, 3], axis=1)
    distance = np.linalg.norm(views.target2cam[:, :3, 3], axis=1)
    frac = float(np.median(off / np.maximum(distance, 1e-9)))
    if frac <= ELSEWHERE_FRACTION:
        return None
    return (f"these views do not belong to this calibration: the target is a median {1e3 * np.median(off):.0f} mm "
            f"({100 * frac:.0f}% of its distance) from where X and Z put it; check that the result and the session come "
            "from the same cell, camera mounting and target placement, and that the robot poses are in the same frame "
            "and convention")


def verify(result: str | Path | Calibration, session: str | Path, jobs: int | None = None,
           progress: bool = True) -> Verification:
    """Predict every view of ``session`` (images + robot poses) from the calibration ``result`` (a
    :class:`~handeye.result.Calibration`, or result.json / result.yaml or their folder, read by
    :func:`handeye.load_result`) and compare with the detections.

    Raises
    ------
    SessionError
        Unreadable result or session; fewer than 3 images with the target.
    InputMismatchError
        The session's setup differs from the result's; the session holds the calibration's own images.
    """
    path = None if isinstance(result, Calibration) else result_path(result)
    cal = result if isinstance(result, Calibration) else load_result(path)
    sess = load_session(session)
    if sess.setup != cal.setup:
        raise InputMismatchError(f"the result is {cal.setup} but {sess.folder} is {sess.setup}")
    if cal.sensor is not None and cal.sensor.sensor != CameraCorners.kind:  # a rig's camera has its own result: checkable
        raise InputMismatchError(f"the result is a {cal.sensor.sensor}'s ({cal.sensor.target}); verify checks a camera's "
                                 "result on images: calibrate the second capture and compare, or cross-validate (check)")
    _refuse_own_images(sess, cal, path.name if path is not None else "the calibration")
    obs = observe(_with_intrinsics(sess, cal), jobs=jobs, progress=progress)
    if cal.target_scale != 1.0:  # the calibration corrected the target's size: its X and Z are for that size
        obs = obs.scaled(cal.target_scale)
    views = obs.views()
    px, mm = view_errors(cal.X, cal.Z, views)
    names = [sess.image_names[k] for k in obs.used]
    T = predicted_target2cam(cal.X, cal.Z, views.flange2base, views.setup)
    pictures = {"image_paths": [Path(sess.image_paths[k]) for k in obs.used], "detected": list(obs.image_points),
                "predicted": [project_points(T[i], obs.object_points[i], obs.K, obs.dist) for i in range(len(T))]}
    elsewhere = _not_where_predicted(cal.X, cal.Z, views)
    if elsewhere is not None:
        return Verification(sess.setup, names, px, mm, NOT_THIS, [elsewhere], cal.prediction_error,
                            list(obs.skipped), [], path, sess.folder, **pictures)
    median = float(np.median(px))
    flagged = [n for n, p in zip(names, px) if p > FLAG_FACTOR * max(median, 0.1)]
    advice = []
    if flagged:
        advice.append(f"view(s) {summarize(flagged)} are predicted over {FLAG_FACTOR:g}x worse than the median: check "
                      "their robot poses (a wrong pose, a tool that moved) or their images")
    promised = cal.prediction_error
    # in pixels when the calibration promised pixels; a sensor's fit (a rig's camera) promises mm at the target
    unit = next((u for u in ("px", "mm") if promised is not None and promised.get(u)), None)
    rms = float(np.sqrt(np.mean((px if unit == "px" else mm) ** 2)))
    if unit is None:
        verdict = "not compared"
        advice.append("the result holds no cross-validated prediction error to compare with (a calibration from poses, "
                      "or refine='none'): judge the errors against your application's tolerance")
    elif rms <= PROMISE_FACTOR * promised[unit]:
        verdict = "good"
    else:
        verdict = "worse than promised"
        advice.append(f"the new views are predicted {rms / promised[unit]:.1f}x worse than the calibration's own "
                      "held-out views: the camera or the target moved since, the robot's errors differ in this part of "
                      "its workspace, or the calibration's poses did not cover it; recalibrate with poses like these")
    return Verification(sess.setup, names, px, mm, verdict, advice, promised, list(obs.skipped), flagged,
                        path, sess.folder, **pictures)
