"""Result files: what a calibration writes to disk (atomically, never over its inputs).

The HTML report and the full result contents (uncertainty, verdict, ROS snippets) come with the
reporting work; this module already writes the transform in the forms robot programs need.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Iterable

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from ._io import atomic_write
from .calibration import Calibration

__all__ = ["result_dict", "write_results"]


def _transform_dict(T: np.ndarray) -> dict[str, Any]:
    rot = Rotation.from_matrix(T[:3, :3])
    return {
        "matrix": T.tolist(),
        "translation_m": T[:3, 3].tolist(),
        "translation_mm": (1e3 * T[:3, 3]).tolist(),
        "quaternion_wxyz": rot.as_quat(canonical=True, scalar_first=True).tolist(),
        "quaternion_xyzw": rot.as_quat(canonical=True).tolist(),
        "rotvec_rad": rot.as_rotvec().tolist(),
        "rotvec_deg": rot.as_rotvec(degrees=True).tolist(),
    }


def result_dict(cal: Calibration) -> dict[str, Any]:
    """A plain, JSON/YAML-ready description of a calibration."""
    from . import __version__

    x_name = "cam2flange" if cal.setup == "eye_in_hand" else "cam2base"
    z_name = "target2base" if cal.setup == "eye_in_hand" else "target2flange"
    mres = cal.motion_residuals
    pres = cal.pose_residuals
    out = {
        "handeye_version": __version__,
        "setup": cal.setup,
        "method": cal.method,
        "X_name": x_name,
        "X": _transform_dict(cal.X),
        "Z_name": z_name,
        "Z": _transform_dict(cal.Z),
        "n_poses": int(len(cal.flange2base)),
        "n_motions": int(len(cal.pairs)),
        "motion_residuals": {
            "columns": ["angle_deg", "pitch_mm"],
            "median": np.median(mres, axis=0).tolist(),
            "max": mres.max(axis=0).tolist(),
        },
        "pose_residuals": {
            "columns": ["rotation_deg", "translation_mm"],
            "values": pres.tolist(),
        },
    }
    if cal.image_names is not None:
        out["images"] = {
            "used": list(cal.image_names),
            "reprojection_rms_px": cal.reprojection_rms.tolist(),
            "skipped": [{"image": n, "reason": r} for n, r in cal.skipped],
        }
        out["camera"] = {
            "source": cal.intrinsics_source,
            "K": cal.camera_matrix.tolist(),
            "dist": cal.dist_coeffs.tolist(),
            "rms_px": cal.intrinsics_rms,
        }
    out["refinement"] = {"type": cal.refinement}
    if cal.refined_rms is not None:
        out["refinement"]["rms_px"] = cal.refined_rms
    if cal.pose_noise is not None:
        out["refinement"]["pose_noise"] = dict(cal.pose_noise)
    if cal.cov is not None:
        out["uncertainty"] = {
            "std_rotation_deg": cal.std[:3].tolist(),
            "std_translation_mm": cal.std[3:].tolist(),
            "cov": cal.cov.tolist(),
            "cov_parameters": "X: rotation vector increment (rad, left), translation (m)",
        }
    if cal.diagnostics is not None:
        d = cal.diagnostics
        out["check"] = {
            "verdict": d.verdict,
            "outliers": list(d.outliers),
            "pose_indices_used": [int(i) for i in cal.pose_indices],
            "consistency": float(d.consistency),
            "advice": list(d.advice),
        }
    out["notes"] = list(cal.notes)
    return out


def write_results(cal: Calibration, out_dir: str | Path, protect: Iterable[Path] = ()) -> list[Path]:
    """Write ``result.json`` and ``result.yaml`` into ``out_dir``; returns their paths."""
    out_dir = Path(out_dir)
    data = result_dict(cal)
    protect = list(protect)
    paths = [out_dir / "result.json", out_dir / "result.yaml"]
    atomic_write(paths[0], json.dumps(data, indent=2) + "\n", protect)
    atomic_write(paths[1], yaml.safe_dump(data, sort_keys=False), protect)
    return paths
