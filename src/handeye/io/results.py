"""A calibration read back from its ``result.json`` or ``result.yaml`` (:func:`load_result`).

The files hold the same mapping for every sensor (images, pose pairs, depth clouds, joint angles):
X and Z, the uncertainty, the verdict with its advice, the held-out error, the notes, the sensor's
own figures and the poses the calibration used. :func:`load_result` turns it back into a
:class:`~handeye.result.Calibration`, so that ``verify``, the exports and the report take a result
from disk as they take one just computed (mrcal's way: a model carries what made it).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import SessionError
from ..frames.setups import check_setup, pose_name
from ..result import Calibration, Diagnostics, HeldOutErrors, Observability, SensorFit, StreamSync, Unobservable
from .session import load_yaml

__all__ = ["load_result", "result_path", "RESULT_FILES"]

#: The files a result folder holds, in the order they are looked for.
RESULT_FILES = ("result.json", "result.yaml")


def result_path(path: str | Path) -> Path:
    """The result file ``path`` names: itself, or the result.json (else result.yaml) in that folder."""
    p = Path(path)
    if p.is_dir():
        found = [p / n for n in RESULT_FILES if (p / n).is_file()]
        if not found:
            raise SessionError(f"{p}: no {' or '.join(RESULT_FILES)} in this folder")
        return found[0]
    if not p.is_file():
        raise SessionError(f"{p}: no such result file")
    return p


def _matrix(data: dict, key: str, where: Path) -> NDArray[np.float64]:
    try:
        T = np.array(data[key]["matrix"], dtype=float)
    except (KeyError, TypeError, ValueError):
        raise SessionError(f"{where}: not a handeye result ({key} with its matrix)") from None
    if T.shape != (4, 4) or not np.isfinite(T).all():
        raise SessionError(f"{where}: {key} must be a finite 4x4 matrix")
    return T


def _vector(values: Any) -> NDArray[np.float64] | None:
    """A list that JSON wrote (null for an undetermined value: infinity) as an array."""
    if values is None:
        return None
    return np.array([np.inf if v is None else v for v in values], dtype=float)


def _std_pair(d: dict | None, rot: str, trans: str) -> NDArray[np.float64] | None:
    if not d or d.get(rot) is None:
        return None
    return np.r_[_vector(d[rot]), _vector(d[trans])]


def _poses(data: dict) -> tuple[NDArray | None, NDArray | None, NDArray]:
    poses = data.get("poses") or {}
    f2b = poses.get("flange2base")
    t2c = poses.get("target2cam")
    pairs = np.asarray(poses.get("pairs") or np.zeros((0, 2)), dtype=np.intp).reshape(-1, 2)
    return (None if f2b is None else np.asarray(f2b, float).reshape(-1, 4, 4),
            None if t2c is None else np.asarray(t2c, float).reshape(-1, 4, 4), pairs)


def _diagnostics(data: dict) -> Diagnostics | None:
    check = data.get("check") or {}
    verdict = check.get("verdict", "not checked")
    if verdict == "not checked":
        return None
    n = check.get("n_poses", len((data.get("poses") or {}).get("flange2base") or []) + len(check.get("outliers") or []))
    return Diagnostics(verdict=verdict, advice=list(check.get("advice") or []), outliers=list(check.get("outliers") or []),
                       consistency=float(check.get("consistency", float("nan"))), scale=check.get("scale"),
                       scale_std=check.get("scale_std"), n_poses=int(n), names=check.get("names"))


def _sensor(data: dict) -> SensorFit | None:
    s = data.get("sensor")
    if not s:
        return None
    held = s.get("heldout_mm")
    return SensorFit(s["kind"], s["target"], list(s["views"]), np.asarray(s["residual_mm"], float), float(s["fit_rms_mm"]),
                     _rig_poses_renamed(dict(s.get("figures") or {})), int(s.get("points", 0)), int(s.get("rejected_points", 0)),
                     None if held is None else np.array([np.nan if v is None else v for v in held], float),
                     unknowns=list(s.get("unknowns") or []))


def _rig_poses_renamed(figures: dict) -> dict:
    """A rig's relative poses keyed as they are now (``cam1_to_cam0``), read from a result that keyed
    them ``cam12cam0`` (handeye 0.1's; read so for one release).

    Told by the figures the renaming needs (``sensors``, whose first names the frame, and ``relative``),
    not by ``sensor.kind``: io/ sits below the kinds' registry (pipelines/kinds.py), so comparing with
    the rig's name here would be the switch on a kind's name tests/test_architecture.py forbids, and a
    0.1 result holds no other mark; figures are the sensor's own record, read by their own keys."""
    sensors, relative = figures.get("sensors"), figures.get("relative")
    if not isinstance(sensors, list) or not sensors or not isinstance(relative, dict):
        return figures
    old = {f"{a}2{sensors[0]}": pose_name(a, sensors[0]) for a in sensors[1:]}
    return dict(figures, relative={old.get(k, k) if old.get(k) not in relative else k: v for k, v in relative.items()})


def _unobservable(data: dict) -> Observability:
    items = [Unobservable(u["parameter"], u["transform"], u["frame"], np.asarray(u["direction"], float), float(u["value_m"]),
                          u["choice"], u["coupled"], u["fix"]) for u in data.get("unobservable") or []]
    return Observability("general" if not items else "partial", items, dict(data.get("known") or {}))


def _images(data: dict) -> dict[str, Any]:
    images, camera = data.get("images"), data.get("camera")
    out: dict[str, Any] = {}
    if isinstance(images, dict):
        out.update(image_names=list(images.get("used") or []), image_sha256=images.get("sha256"),
                   reprojection_rms=np.asarray(images.get("reprojection_rms_px") or [], float),
                   skipped=[(d["image"], d["reason"]) for d in images.get("skipped") or []])
    if isinstance(camera, dict) and camera.get("K") is not None:
        out.update(camera_matrix=np.asarray(camera["K"], float), dist_coeffs=np.asarray(camera.get("dist") or [0.0] * 5, float),
                   intrinsics_source=camera.get("source"), intrinsics_rms=camera.get("rms_px"))
    return out


def load_result(path: str | Path) -> Calibration:
    """A calibration read back from ``result.json`` / ``result.yaml`` (or the folder holding them).

    Round-trips what every calibration has: X, Z, the setup, the method and estimator, the std and
    covariance of X (and Z's std), the verdict with its advice and outliers, the held-out errors, the
    notes, the poses used, the sensor's own figures (depth, laser, ...), the images' names and the
    intrinsics, what was undetermined, the clock offset. The arm's corrected table (joint angles)
    stays in ``arm_corrected.yaml``; the result's ``kinematic`` is None.

    Raises
    ------
    SessionError
        No such file, or not a handeye result (no setup, X and Z).

    Examples
    --------
    >>> import tempfile, handeye
    >>> from handeye.simulate import random_scene
    >>> scene = random_scene(10, "eye_in_hand", rng=0)
    >>> cal = handeye.calibrate_poses(scene.flange2base, scene.target2cam, progress=False)
    >>> folder = tempfile.mkdtemp()
    >>> _ = handeye.write_calibration(cal, folder, report=False)
    >>> back = handeye.load_result(folder)
    >>> bool(np.allclose(back.X, cal.X)), back.verdict == cal.verdict
    (True, True)
    """
    p = result_path(path)
    data = load_yaml(p)  # JSON is YAML
    if not isinstance(data, dict) or "setup" not in data:
        raise SessionError(f"{p}: not a handeye result (setup, X and Z with their matrix)")
    setup = check_setup(str(data["setup"]))
    X, Z = _matrix(data, "X", p), _matrix(data, "Z", p)
    f2b, t2c, pairs = _poses(data)
    unc = data.get("uncertainty") or {}
    cv = data.get("cross_validation")
    sync = data.get("time_sync")
    sources = {k: (None if v is None else np.r_[_vector(v["rotation_deg"]), _vector(v["translation_mm"])])
               for k, v in (unc.get("sources") or {}).items()}
    acc = unc.get("robot_accuracy")
    return Calibration(
        X=X, Z=Z, setup=setup, method=str(data.get("method", "")), flange2base=f2b, target2cam=t2c, pairs=pairs,
        cov=None if unc.get("cov") is None else np.array([_vector(r) for r in unc["cov"]]),
        std=_std_pair(unc, "std_rotation_deg", "std_translation_mm"),
        std_Z=_std_pair(data.get("Z"), "std_rotation_deg", "std_translation_mm"),
        std_sources=sources or None, robot_accuracy=None if not acc else (float(acc["rotation_deg"]), float(acc["translation_mm"])),
        diagnostics=_diagnostics(data), estimator=data.get("estimator"),
        cross_validation=None if not cv else HeldOutErrors(dict(cv.get("per_estimator") or {}), cv.get("folds")),
        notes=list(data.get("notes") or []), inputs_sha256=data.get("inputs_sha256"),
        refinement=(data.get("refinement") or {}).get("type", "none"), sensor=_sensor(data),
        target_scale=float((data.get("target_scale") or {}).get("factor", 1.0)), observability=_unobservable(data),
        sync=None if not sync else StreamSync(float(sync["time_offset_s"]), float(sync["time_offset_std_s"]),
                                              {k: v for k, v in sync.items() if k not in ("time_offset_s",
                                                                                          "time_offset_std_s", "meaning")}),
        pose_indices=None if data.get("check", {}).get("pose_indices_used") is None else
        np.asarray(data["check"]["pose_indices_used"], dtype=np.intp),
        **({"skipped": [(d["view"], d["reason"]) for d in data["skipped"]]} if data.get("skipped") else {}),
        **_images(data),
    )
