"""What the report pages share: the style sheet, the verdict colours, the figures' width (the figures are
inline SVG, :mod:`handeye.report._svg`: no page imports matplotlib)."""

from __future__ import annotations

import html

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from .files import euler_angles

#: The width of the report's figures in pixels (the page's content is 1,068 px wide: drawn 1:1).
FIGURE_WIDTH = 1060

_COLOURS = {"good": "#1e7b34", "weak": "#b36b00", "partial": "#b36b00", "degenerate": "#b00020", "inconsistent": "#b00020",
            "not checked": "#555555"}

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:0 auto;max-width:1100px;padding:0 16px 40px;color:#222}
h1{font-size:1.5em;margin:18px 0 6px} h2{font-size:1.2em;border-bottom:1px solid #ddd;padding-bottom:4px;margin-top:28px}
.banner{color:#fff;padding:14px 18px;border-radius:6px;font-size:1.15em}
.banner b{font-size:1.3em;text-transform:uppercase;letter-spacing:.04em}
table{border-collapse:collapse;margin:8px 0} td,th{border:1px solid #ddd;padding:3px 8px;text-align:right;font-variant-numeric:tabular-nums}
th{background:#f4f4f4} td.l,th.l{text-align:left}
pre{background:#f6f8fa;padding:8px;font-size:.85em;white-space:pre-wrap;overflow-wrap:anywhere}
.thumbs{display:flex;flex-wrap:wrap;gap:8px} figure{margin:0;font-size:.8em;text-align:center;max-width:100%}
figure img.zoom{cursor:zoom-in;width:360px} figure img.zoom:focus{width:min(900px,100%);cursor:zoom-out;outline:none}
figure.flag img{border:3px solid #b00020} figure.flag figcaption{color:#b00020;font-weight:bold}
figure.rejected img{opacity:.55;border:3px dashed #888}
img{max-width:100%} .note{color:#555;font-size:.9em} section{overflow-wrap:anywhere}
svg.fig{display:block;width:100%;height:auto;margin:6px 0}
"""


def _e(s: object) -> str:
    return html.escape(str(s))


def _fmt(v, digits: int = 3) -> str:
    """Numbers to ``digits`` decimals; an infinite std is 'not determined' (by the data), a NaN one 'not
    defined' (a ball's orientation: the target has none)."""
    return ", ".join(f"{x:.{digits}f}" if np.isfinite(x) else "not defined" if np.isnan(x) else "not determined"
                     for x in np.atleast_1d(v))


def _transform_table(T: NDArray[np.float64], std: NDArray[np.float64] | None) -> str:
    rot = Rotation.from_matrix(T[:3, :3])
    t_mm = 1e3 * T[:3, 3]
    rows = [("translation (mm)", _fmt(t_mm, 3), _fmt(std[3:], 3) if std is not None else "—")]
    rows.append(("rotation vector (deg)", _fmt(rot.as_rotvec(degrees=True), 4), _fmt(std[:3], 4) if std is not None else "—"))
    rows.append(("quaternion w, x, y, z", _fmt(rot.as_quat(canonical=True, scalar_first=True), 6), ""))
    rows.append(("roll, pitch, yaw (deg, fixed x-y-z)", _fmt(euler_angles(rot, "xyz", True), 4), ""))
    body = "".join(f'<tr><td class="l">{_e(a)}</td><td>{b}</td><td>{c}</td></tr>' for a, b, c in rows)
    matrix = "\n".join("  ".join(f"{v: .6f}" for v in row) for row in T)
    return (f'<table><tr><th class="l"></th><th>value</th><th>std (1 sigma)</th></tr>{body}</table>'
            f"<pre>{_e(matrix)}</pre>")
