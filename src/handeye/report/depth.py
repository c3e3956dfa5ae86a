"""Files of a depth-camera calibration (:func:`handeye.pipelines.depth.calibrate_depth_session`):
``result.json``, ``result.yaml`` and a self-contained ``report.html`` (the verdict, X with its std,
the depth scale and bias, every view's distance and residual, the views left out and why)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Iterable

import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from .._shared.io import atomic_write, check_output_folder
from .._version import __version__
from ..frames.setups import setup_info
from ..pipelines.depth import DepthResult
from ._page import _COLOURS, _CSS, _e

__all__ = ["depth_result_dict", "depth_report_html", "write_depth_results"]


def depth_result_dict(r: DepthResult) -> dict:
    """The result as result.yaml / result.json hold it: X under its frame name, as a matrix and as
    a translation (m) and quaternion (x, y, z, w), with everything :meth:`DepthResult.as_dict` says."""
    info = setup_info(r.calibration.setup)
    out = {"handeye_version": __version__, "session": str(r.session.folder)}
    for name, T in ((info.x_name, r.calibration.X), (info.z_name, r.calibration.Z)):
        out[name] = {"matrix": T.tolist(), "translation_m": T[:3, 3].tolist(),
                     "quaternion_xyzw": Rotation.from_matrix(T[:3, :3]).as_quat().tolist()}
    body = r.as_dict()
    body.pop("X")
    body.pop("Z")
    return out | body


def depth_report_html(r: DepthResult) -> str:
    """The depth calibration as one self-contained HTML page."""
    cal, info = r.calibration, setup_info(r.calibration.setup)
    colour = _COLOURS.get(r.verdict, "#555555")
    residual = cal.residuals_mm if cal.residuals_mm is not None else np.full(len(r.used), np.nan)
    rows = "".join(f'<tr><td class="l">{_e(n)}</td><td>{d:.3f}</td><td>{e:.3f}</td></tr>'
                   for n, d, e in zip(r.used, r.distances_m, residual))
    skipped = "".join(f"<li>{_e(n)}: {_e(why)}</li>" for n, why in r.skipped)
    held = "—" if r.heldout_mm is None else f"{r.heldout_mm:.3f} mm"
    x = cal.X
    return (f"<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>handeye depth calibration</title>"
            f"<style>{_CSS}</style></head><body><h1>Hand-eye calibration of a depth camera</h1>"
            f"<p class=\"note\">handeye {_e(__version__)} · session {_e(r.session.folder)} · {_e(cal.setup)} · "
            f"{_e(r.session.kind)}</p>"
            f'<section id="verdict"><div class="banner" style="background:{colour}"><b>{_e(r.verdict)}</b> — '
            f"{len(r.used)} views, fit {r.fit_mm:.3f} mm RMS, held-out views predicted from the robot {held}</div></section>"
            f'<section id="result"><h2>{_e(info.x_name)}</h2><table>'
            + "".join(f"<tr>{''.join(f'<td>{v: .6f}</td>' for v in row)}</tr>" for row in x)
            + f"</table><p>std: rotation {np.array2string(cal.std[:3], precision=4)} deg, translation "
            f"{np.array2string(cal.std[3:], precision=3)} mm (the data's alone: "
            f"{np.array2string(cal.std_data[3:], precision=3) if cal.std_data is not None else '—'} mm)</p>"
            f"<p>depth scale {cal.depth_scale:.5f} ± {cal.depth_scale_std:.5f}, depth bias {1e3 * cal.depth_bias:+.3f} ± "
            f"{1e3 * cal.depth_bias_std:.3f} mm, noise along the rays {cal.rms_mm:.3f} mm</p></section>"
            '<section id="views"><h2>Per view</h2><table><tr><th class="l">view</th><th>distance (m)</th>'
            f"<th>RMS residual (mm)</th></tr>{rows}</table>"
            + (f"<p>Left out:</p><ul>{skipped}</ul>" if skipped else "") + "</section>"
            '<section id="advice"><h2>Advice</h2><ul>'
            + "".join(f"<li>{_e(a)}</li>" for a in (r.advice or ["Nothing to fix."]))
            + "</ul></section></body></html>\n")


def write_depth_results(r: DepthResult, out_dir: str | Path, protect: Iterable[str | Path] = ()) -> list[Path]:
    """Write ``result.json``, ``result.yaml`` and ``report.html`` into ``out_dir`` (checked first,
    never inside the session folder), atomically; returns their paths."""
    out = check_output_folder(out_dir, [r.session.folder])
    out.mkdir(parents=True, exist_ok=True)
    d = depth_result_dict(r)
    protect = list(protect) + r.session.cloud_paths + list(r.session.image_paths or [])
    paths = [out / "result.json", out / "result.yaml", out / "report.html"]
    atomic_write(paths[0], json.dumps(d, indent=2) + "\n", protect)
    atomic_write(paths[1], yaml.safe_dump(d, sort_keys=False), protect)
    atomic_write(paths[2], depth_report_html(r), protect)
    return paths
