"""Another tool's laser capture as a laser session (``handeye import robcalibrator``, this kind's
registration's ``imports``): GilbertPan97/RobCalibrator's scans of a ball.

Examples
--------
>>> from handeye.pipelines.kinds import importer_of
>>> importer_of("robcalibrator") is import_robcalibrator
True
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from ..._shared.io import atomic_write
from ...io.importers import ImportSummary, new_folder, numbered_files
from ...io.session import SESSION_FILE, SessionError, write_pose_table

__all__ = ["import_robcalibrator", "opencv_sequence"]


def opencv_sequence(path: Path, key: str) -> NDArray[np.float64]:
    """The numbers of ``key: [...]`` in an OpenCV FileStorage YAML (``%YAML:1.0``), ``.Nan`` as NaN
    (PyYAML does not read OpenCV's ``.Nan``)."""
    text = path.read_text(encoding="utf-8", errors="replace")
    at = text.find(key + ":")
    start, end = text.find("[", at), text.find("]", at)
    if at < 0 or start < 0 or end < 0:
        raise SessionError(f"{path}: no {key}: [...] sequence (an OpenCV FileStorage YAML)")
    cells = [c for c in re.split(r"[\s,]+", text[start + 1:end]) if c]
    try:
        return np.array([np.nan if c.lower().lstrip("+-.") in ("nan", "inf") else float(c) for c in cells], dtype=float)
    except ValueError as exc:
        raise SessionError(f"{path}: {key}: not a sequence of numbers ({exc})") from None


def import_robcalibrator(folder: str | Path, out: str | Path, diameter: float | None = None) -> ImportSummary:
    """GilbertPan97/RobCalibrator's laser scans (``p1.yml`` ... one profile each: ``scan_line`` x, y,
    z in mm; ``RobPoses.rob``: the FANUC flange poses x, y, z, w, p, r in mm and degrees, W, P, R
    about the fixed axes, scipy's ``"xyz"``; ``calibration.sec``: the setup and the ball's radius)
    as a laser session: ``profiles/pN.csv`` (x, z in mm), ``poses.csv``, ``session.yaml``.
    ``diameter`` (m) when ``calibration.sec`` does not give the radius."""
    src = Path(folder)
    poses_file = src / "RobPoses.rob"
    if not poses_file.is_file():
        raise SessionError(f"{src}: no RobPoses.rob (RobCalibrator's robot poses)")
    try:
        poses = np.array(json.loads(poses_file.read_text(encoding="utf-8"))["RobPoses"], dtype=float)
    except (ValueError, KeyError, TypeError) as exc:
        raise SessionError(f"{poses_file}: expected JSON {{\"RobPoses\": [[x, y, z, w, p, r], ...]}} ({exc})") from None
    scans = numbered_files(src, r"p(\d+)\.yml")
    missing = [k for k in range(1, len(poses) + 1) if k not in scans]
    if missing or poses.ndim != 2 or poses.shape[1] != 6:
        raise SessionError(f"{src}: {len(poses)} poses of 6 values in RobPoses.rob and scans p1.yml ... p{len(poses)}.yml"
                           + (f"; missing {', '.join(f'p{k}.yml' for k in missing[:5])}" if missing else ""))
    setup, notes = "eye_in_hand", []
    sec = src / "calibration.sec"
    if sec.is_file():
        conf = json.loads(sec.read_text(encoding="utf-8"))
        kind = str(conf.get("Config", {}).get("CalibType", "")).lower()
        setup = "eye_to_hand" if "tohand" in kind or "onbase" in kind else "eye_in_hand"
        radius = (conf.get("CalibObj") or {}).get("Radius")
        if diameter is None and radius is not None:
            diameter = 2e-3 * float(radius)
            notes.append(f"the ball's diameter {2 * float(radius):g} mm from calibration.sec (its Radius, mm)")
    dest = new_folder(out, [src])
    (dest / "profiles").mkdir(parents=True, exist_ok=True)
    names = []
    for k in range(1, len(poses) + 1):
        xyz = opencv_sequence(scans[k], "scan_line").reshape(-1, 3)
        names.append(f"p{k}.csv")
        rows = "".join(f"{x!r},{'' if not np.isfinite(z) else repr(float(z))}\n" for x, z in xyz[:, [0, 2]].tolist())
        atomic_write(dest / "profiles" / names[-1], "x,z\n" + rows)
    write_pose_table(dest / "poses.csv", names, None, "euler:xyz", "mm", "deg", id_column="profile", rows=poses)
    target: dict[str, Any] = {"type": "sphere"} | ({} if diameter is None else {"diameter": float(diameter)})
    spec = {"setup": setup, "target": target, "laser": {"unit": "mm"},
            "poses": {"file": "poses.csv", "format": "euler:xyz", "length_unit": "mm", "angle_unit": "deg"}}
    atomic_write(dest / SESSION_FILE, f"# imported by handeye from RobCalibrator's {src}\n" + yaml.safe_dump(spec, sort_keys=False))
    return ImportSummary(dest, "laser session", len(names), len(names), notes)
