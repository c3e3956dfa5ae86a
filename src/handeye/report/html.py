"""``report.html``: one self-contained page that says at a glance whether a calibration can be trusted.

Sections (each a ``<section id=...>``): ``verdict`` (banner), ``result`` (X and Z with their
uncertainty, ready-to-paste ROS lines), ``residuals`` (per-pose charts), ``overlays`` (detected vs
reprojected target points on every image, when images were used), ``scene`` (3D view of robot,
camera and target poses), ``axes`` (the motions' rotation axes on the unit sphere), ``solvers``
(every solver on the same data) and ``advice``; a rig's report also has ``rig`` (its picture and a
section per sensor, :mod:`handeye.report._rig`). The charts of the residuals, the 3D scene, the
rotation axes, a sensor's sections or clouds and a rig's picture are inline SVG drawn by :mod:`handeye.report._svg`
(no matplotlib: its import and PNGs were half of ``calibrate --sample --out``'s time); the images are
embedded base64 JPEGs. The page loads nothing from anywhere.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Iterable

import numpy as np
from numpy.typing import NDArray

from .._shared.io import atomic_write
from .._shared.lazy import lazy_module
from .._version import __version__
from ..estimation.verdict import HEADLINES
from ..estimation.verdict import headline as verdict_headline
from ..frames.motions import MotionSet
from ..frames.setups import camera2base, predicted_target2cam, setup_info, target2base
from ..geometry.se3 import screw_parameters
from ..pipelines.kinds import joins_sensors
from ..result import Calibration
from ..robot.kinematics import display_unit
from ..sensors.camera.detect import default_jobs
from ..sensors.camera.pnp import project_points
from ._overlay import jpeg, overlay_thumbnail, zoom_size
from ._page import _COLOURS, _CSS, FIGURE_WIDTH, _e, _fmt, _transform_table
from ._rig import RIG_FIGURES, rig_sections
from ._svg import (
    CATEGORY_COLOURS,
    Canvas,
    Panel,
    View3D,
    colour_bar,
    coolwarm,
    legend,
    legend_row,
    nice_ticks,
    text_width,
    tick_labels,
    triads,
    viridis,
)
from .files import result_dict

cv2 = lazy_module("cv2")

__all__ = ["report_html", "write_report", "SECTIONS"]

#: The section ids of the page, in order.
SECTIONS = ("verdict", "result", "residuals", "overlays", "scene", "axes", "solvers", "advice")
#: Most images shown as overlays (the page stays a few MB at most).
MAX_OVERLAYS = 60
#: An image whose predicted points lie further than this many times the median from the detected
#: ones is flagged in the gallery.
FLAG_FACTOR = 3.0



# ----------------------------------------------------------------------------------------------------
# figures


#: Up to this many poses the residual figure draws a bar and a label per pose.
MAX_LABELLED_POSES = 60
#: The rotation-axes figure draws at most this many motions (evenly chosen, in their order).
MAX_AXES_DRAWN = 1000


def _residual_figure(cal: Calibration) -> str:
    """Per pose: its own Z's distance from the common one (rotation, translation) and, with images,
    its PnP RMS: a panel each, one bar per pose (a line per pose beyond MAX_LABELLED_POSES), as SVG."""
    pres = cal.pose_residuals
    labels = list(cal.image_names) if cal.image_names is not None else [str(i) for i in cal.pose_indices]
    rows = [(pres[:, 0], "rotation (deg)", "#4a78b5", "deg"), (pres[:, 1], "translation (mm)", "#d08c30", "mm")]
    if cal.reprojection_rms is not None:
        rows.append((np.asarray(cal.reprojection_rms, float), "PnP RMS (px)", "#5c9e5c", "px"))
    n = len(pres)
    many = n > MAX_LABELLED_POSES
    turned = n > 12
    below = 46 if many else 12 + (text_width(max(labels, key=len, default=""), 11) if turned else 18)
    left, top, height, gap = 80, 30, 130, 12
    canvas = Canvas(FIGURE_WIDTH, top + len(rows) * (height + gap) - gap + below + 6, "per-pose residuals")
    for k, (values, ylabel, colour, unit) in enumerate(rows):
        finite = values[np.isfinite(values)]
        hi = float(finite.max()) if len(finite) else 1.0
        ylim = (min(0.0, float(finite.min()) if len(finite) else 0.0), 1.05 * hi if hi > 0 else 1.0)
        panel = Panel(canvas, (left, top + k * (height + gap), FIGURE_WIDTH - left - 16, height), (-0.6, n - 0.4), ylim)
        panel.yticks(nice_ticks(*ylim, 4))
        if many:
            panel.stems(np.arange(n), values, colour)
        else:
            panel.bars(np.arange(n), values, colour, tips=[f"{name}: {v:.3f} {unit}" for name, v in zip(labels, values)])
        panel.frame()
        panel.ylabel(ylabel)
        if k == 0:
            panel.title(f"per pose: how far its own {setup_info(cal.setup).z_name} (through X) is from the common one")
        if k == len(rows) - 1:
            if many:
                ticks = nice_ticks(0, n - 1, 8)
                panel.xticks(ticks, [f"{t:.0f}" for t in ticks])
                panel.xlabel("pose (index in the order given)")
            else:
                panel.xticks(np.arange(n), labels, 10 if turned else 11, rotate=turned)
        panel.end()
    return canvas.svg()


def _scene_figure(cal: Calibration) -> str:
    """The robot base frame in 3D: flange path, camera and target frames, as SVG."""
    cam2base, tgt2base = camera2base(cal.X, cal.flange2base, cal.setup), target2base(cal.Z, cal.flange2base, cal.setup)
    on_flange = setup_info(cal.setup).camera_on_flange
    flange = cal.flange2base[:, :3, 3]
    pts = np.vstack([flange, cam2base[:, :3, 3], tgt2base[:, :3, 3], np.zeros((1, 3))])
    extent = float(np.ptp(pts, axis=0).max()) or 1.0
    L = 0.08 * extent
    few = np.unique(np.linspace(0, len(cal.flange2base) - 1, min(len(cal.flange2base), 12)).astype(int))  # not crowded
    centre, half = pts.mean(axis=0), 0.55 * extent  # a cube about the points: equal scales on the three axes
    canvas = Canvas(FIGURE_WIDTH, 760, "3D view of the robot base frame")
    view = View3D(canvas, (150, 60, FIGURE_WIDTH - 300, 620), centre - half, centre + half)
    view.axes(("x (m)", "y (m)", "z (m)"), [nice_ticks(c - half, c + half, 5) for c in centre])
    triads(view, np.eye(4), 1.5 * L, 3)
    view.text(np.zeros(3), "base")
    view.lines(flange, "#777", 0.8)
    view.points(flange, "#777", 2.5)
    triads(view, cal.flange2base[few], 0.5 * L, 0.8)
    triads(view, cam2base[few] if on_flange else cam2base[:1], L)
    view.points(cam2base[:, :3, 3], "#000", 3.0)
    if cal.object_points:
        obj = np.vstack(cal.object_points)
        lo, hi = obj.min(axis=0), obj.max(axis=0)
        corners = np.array([[lo[0], lo[1], 0, 1], [hi[0], lo[1], 0, 1], [hi[0], hi[1], 0, 1], [lo[0], hi[1], 0, 1],
                            [lo[0], lo[1], 0, 1], [np.nan] * 4])
        boards = np.vstack([(T @ corners.T).T for T in (tgt2base[few] if not on_flange else tgt2base[:1])])
        view.lines(boards[:, :3], "#8b4513", 1.5)
    triads(view, tgt2base[few] if not on_flange else tgt2base[:1], L, 2)
    view.points(tgt2base[:, :3, 3], "#8b4513", 3.0, square=True)
    legend(canvas, 12, 40, [("line", "#777", "flange positions (capture order)"), ("dot", "#000", "camera"),
                                 ("square", "#8b4513", "target")])
    shown = "" if len(few) == len(cal.flange2base) else f"; frames of {len(few)} of {len(cal.flange2base)} poses"
    canvas.text(FIGURE_WIDTH / 2, 20, f"robot base frame: axes x red, y green, z blue{shown}", 13, "middle", cls="title")
    return canvas.svg()


def _axes_figure(cal: Calibration, motions: MotionSet) -> str:
    """The motions' rotation axes in the camera frame: on the unit sphere (both ends of each), and
    folded onto the half sphere towards camera +z in an equal-area disc, where clusters and gaps read
    at a glance; coloured by the rotation angle; as SVG."""
    B = motions.B
    if len(B) > MAX_AXES_DRAWN:  # thousands of dots cover each other: an even share of them
        B = B[np.unique(np.linspace(0, len(B) - 1, MAX_AXES_DRAWN).astype(int))]
    axis, _, theta, _ = screw_parameters(B)
    deg = np.degrees(theta)
    vmax = max(90.0, float(deg.max()) if len(deg) else 90.0)
    colours = viridis(deg, 0.0, vmax)
    shown = f" ({len(B)} of {len(motions.B)} motions drawn)" if len(B) < len(motions.B) else ""
    canvas = Canvas(FIGURE_WIDTH, 540, "rotation axes")
    canvas.text(FIGURE_WIDTH / 2, 20, f"rotation axes of the camera motions: well spread over the sphere is best{shown}", 14,
                "middle", cls="title")
    # the unit sphere, seen as the 3D scene is
    view = View3D(canvas, (70, 90, 380, 360), -1.1 * np.ones(3), 1.1 * np.ones(3))
    view.axes(("camera x", "camera y", "camera z"), [np.array([-1.0, 0.0, 1.0])] * 3)  # a tick every quarter crowds
    u, v = np.linspace(0, 2 * np.pi, 25), np.linspace(0, np.pi, 13)
    meridians = [np.c_[np.cos(a) * np.sin(v), np.sin(a) * np.sin(v), np.cos(v)] for a in u[:-1]]
    parallels = [np.c_[np.cos(u) * np.sin(b), np.sin(u) * np.sin(b), np.full_like(u, np.cos(b))] for b in v[1:-1]]
    view.lines(np.vstack([np.vstack([m, [[np.nan] * 3]]) for m in meridians + parallels]), "#cccccc", 0.5)
    view.points(np.vstack([axis, -axis]), colours + colours, 3.5)  # an axis and its opposite are the same rotation axis
    canvas.text(260, 58, "on the unit sphere (both ends of each axis)", 13, "middle", cls="title")
    # Lambert azimuthal equal-area about +z: a cluster looks as big as it is on the sphere
    up = np.where(axis[:, 2:3] < 0, -axis, axis)
    r = np.sqrt(2.0 / (1.0 + np.clip(up[:, 2], -1, 1)))
    lim = 1.05 * np.sqrt(2)
    disc = Panel(canvas, (560, 70, 400, 400), (-lim, lim), (-lim, lim))
    disc.c.line(disc.x(-lim), disc.y(0), disc.x(lim), disc.y(0), "#dddddd", 0.6)
    disc.c.line(disc.x(0), disc.y(-lim), disc.x(0), disc.y(lim), "#dddddd", 0.6)
    for tilt in (30, 60, 90):
        rho = 2 * np.sin(np.radians(tilt) / 2)
        canvas.circle(disc.x(0), disc.y(0), float(disc.x(rho) - disc.x(0)), "none", "#bbbbbb", 0.8, dash="4 3")
        canvas.text(disc.x(rho * np.cos(np.radians(60))), disc.y(rho * np.sin(np.radians(60))), f"{tilt}°", 11, colour="#777")
    for k in np.argsort(deg, kind="stable"):  # the largest rotations on top
        canvas.circle(disc.x(r[k] * up[k, 0]), disc.y(r[k] * up[k, 1]), 4.5, colours[k], "#333333", 0.4, cls="pt")
    disc.frame()
    disc.title("seen from camera +z, equal area (circles: tilt from z)")
    disc.xlabel("← −x     camera x     +x →", 18)
    disc.c.text(disc.box[0] - 18, disc.box[1] + disc.box[3] / 2, "← −y     camera y     +y →", 12, "middle", rotate=-90)
    disc.end()
    colour_bar(canvas, (985, 110, 14, 320), 0.0, vmax, "rotation angle (deg)")
    return canvas.svg()


def _overlay_thumb(cal: Calibration, k: int, T: NDArray[np.float64]) -> tuple[str, str, float] | None:
    """(data URI, caption, RMS px) of image ``k``: detected points (green rings) and the points
    reprojected through X, Z and the robot pose (red crosses); None when the image cannot be read."""
    det = np.asarray(cal.image_points[k], dtype=float)
    proj = project_points(T[k], cal.object_points[k], cal.camera_matrix, cal.dist_coeffs)
    src = overlay_thumbnail(cal.image_paths[k], det, proj)
    if src is None:
        return None
    rms = float(np.sqrt(np.mean(np.sum((proj - det) ** 2, axis=1))))
    return src, f"{cal.image_names[k]}: {rms:.2f} px", rms


def _overlay_thumbs(cal: Calibration) -> list[tuple[str, str, float]]:
    """:func:`_overlay_thumb` of the first MAX_OVERLAYS images, read and drawn in threads (OpenCV
    releases the GIL: the images of a large capture are read again here)."""
    T = predicted_target2cam(cal.X, cal.Z, cal.flange2base, cal.setup)
    with ThreadPoolExecutor(max_workers=default_jobs()) as pool:
        thumbs = list(pool.map(lambda k: _overlay_thumb(cal, k, T), range(min(len(cal.image_paths), MAX_OVERLAYS))))
    return [t for t in thumbs if t is not None]


def _rejected_thumbs(cal: Calibration) -> list[tuple[str, str]]:
    """(data URI, caption with the reason) of each skipped image that can be read, from the input folder."""
    if cal.input_folder is None:
        return []
    out = []
    for name, reason in cal.skipped[:MAX_OVERLAYS]:
        img = cv2.imread(str(Path(cal.input_folder) / "images" / name), cv2.IMREAD_COLOR)
        if img is None or img.shape[0] < 2 or img.shape[1] < 2:
            out.append(("", f"{name}: {reason}"))
            continue
        out.append((jpeg(zoom_size(img)[0]), f"{name}: {reason}"))
    return out


# ----------------------------------------------------------------------------------------------------
# the page


def _view_residual_figure(cal: Calibration) -> str:
    """Per view of a sensor's fit: its RMS residual and, when cross-validated, its held-out error (mm), as SVG."""
    sf = cal.sensor
    n = len(sf.views)
    held = sf.heldout_mm is not None
    fit = np.asarray(sf.residual_mm, float)
    out = np.nan_to_num(np.asarray(sf.heldout_mm, float)) if held else np.zeros(0)
    labels = [str(v) for v in sf.views]
    many, turned = n > MAX_LABELLED_POSES, n > 12
    below = 46 if many else 12 + (text_width(max(labels, key=len, default=""), 10) if turned else 18)
    left, top, height = 80, 52, 190
    canvas = Canvas(FIGURE_WIDTH, top + height + below + 6, "per-view residuals")
    values = np.r_[fit, out]
    hi = float(np.nanmax(values)) if np.isfinite(values).any() else 1.0
    ylim = (0.0, 1.05 * hi if hi > 0 else 1.0)
    panel = Panel(canvas, (left, top, FIGURE_WIDTH - left - 16, height), (-0.6, n - 0.4), ylim)
    panel.yticks(nice_ticks(*ylim, 4))
    x = np.arange(n)
    if many:  # beyond a few dozen views: dots, not a bar per view
        for k in range(n):
            canvas.circle(panel.x(k), panel.y(np.nan_to_num(fit[k])), 2.0, "#4a78b5", cls="pt")
            if held:
                canvas.circle(panel.x(k), panel.y(out[k]), 2.0, "#d08c30", cls="pt")
    else:
        width = 0.4 if held else 0.8
        panel.bars(x - (width / 2 if held else 0), fit, "#4a78b5", width, [f"{v}: {r:.3f} mm in the fit" for v, r in zip(labels, fit)])
        if held:
            panel.bars(x + width / 2, out, "#d08c30", width, [f"{v}: {r:.3f} mm held out" for v, r in zip(labels, out)])
    panel.frame()
    panel.ylabel("RMS residual (mm)")
    panel.title(f"per view: how far the {sf.target}'s model through X misses what the {sf.sensor} measured")
    if many:
        ticks = nice_ticks(0, n - 1, 8)
        panel.xticks(ticks, [f"{t:.0f}" for t in ticks])
        panel.xlabel("view (index in the order given)")
    else:
        panel.xticks(x, labels, 10 if turned else 11, rotate=turned)
    panel.end()
    legend_row(canvas, FIGURE_WIDTH - 16, 14, [("#4a78b5", "in the fit")] + ([("#d08c30", "held out (predicted)")] if held else []))
    return canvas.svg()


#: The report draws at most this many views' sections (the worst half of them, and the rest evenly).
MAX_SECTIONS = 24


def _section_rms(sf) -> list[float]:
    """Per section its RMS residual (mm): its own (``rms_mm``: a rig's, a section per sensor and view),
    else its view's."""
    return [float(sec.get("rms_mm", sf.residual_mm[k] if k < len(sf.residual_mm) else np.nan)) for k, sec in enumerate(sf.sections)]


def _shown_sections(sf) -> list[int]:
    """The sections drawn (those with points): all up to :data:`MAX_SECTIONS`, else the worst half of
    that by residual and the rest evenly over the others, in the views' order."""
    drawn = [k for k, sec in enumerate(sf.sections) if np.isfinite(np.asarray(sec["points_mm"], float)).any()]
    if len(drawn) <= MAX_SECTIONS:
        return drawn
    rms = np.nan_to_num(np.asarray(_section_rms(sf))[drawn], nan=-1.0)
    worst = [drawn[i] for i in np.argsort(-rms)[:MAX_SECTIONS // 2]]
    rest = [k for k in drawn if k not in worst]
    return sorted(worst + [rest[i] for i in np.linspace(0, len(rest) - 1, MAX_SECTIONS - len(worst)).astype(int)])


#: What a section is drawn in when the sensor does not say (``plane``; a result written before each sensor said).
SECTION_PLANE = "the sensor's own plane"
#: At most this many of a section's points are drawn (:func:`_thinned`): a profile's or a cloud's thousands
#: would make the page heavy and look no different.
MAX_SECTION_POINTS = 200


def _thinned(residual: NDArray[np.float64], most: int) -> NDArray[np.intp]:
    """The indices of at most ``most`` points to draw, in order: the quarter with the largest residuals (the
    points worth seeing), and the rest evenly."""
    n = len(residual)
    if n <= most:
        return np.arange(n)
    worst = np.argsort(-np.nan_to_num(np.abs(residual), nan=-1.0), kind="stable")[:most // 4]
    rest = np.setdiff1d(np.arange(n), worst)
    return np.sort(np.r_[worst, rest[np.linspace(0, len(rest) - 1, most - len(worst)).astype(int)]])


def _sections_figure(cal: Calibration) -> str:
    """Each drawn section (a view, or a rig's sensor in a view) in the sensor's own plane (a profiler's
    laser plane, a camera's image, a line-scan camera's scan, a depth camera's image: its ``plane``),
    in one grid of cells at one scale, as SVG: its points coloured by residual (signed: a diverging
    scale about 0; a size: from 0), and the fitted target through X (a ball's circle or a plate's line,
    a board's grid, a mesh's edges)."""
    sf = cal.sensor
    shown = _shown_sections(sf)
    rms = _section_rms(sf)
    cols, rows = min(6, len(shown)), -(-len(shown) // min(6, len(shown)))
    drawn = [np.vstack([sf.sections[k]["points_mm"], np.asarray(sf.sections[k]["curve_mm"], float).reshape(-1, 2)]) for k in shown]
    boxes = [(np.nanmin(d, axis=0), np.nanmax(d, axis=0)) for d in drawn]  # the points and the target drawn
    cell = 1.25 * max(max(float(np.max(hi - lo)) for lo, hi in boxes), 1e-3)  # mm: the largest view's extent, a margin
    left, top, bar_room = 16, 58, 150
    px = min(160.0, (FIGURE_WIDTH - left - bar_room) / cols)  # a cell's side in pixels
    scale = px / cell
    res_all = np.concatenate([np.asarray(sf.sections[k]["residual_mm"], float) for k in shown])
    limit = max(float(np.nanpercentile(np.abs(res_all), 99)), 1e-3)
    signed = bool(np.nanmin(res_all) < 0)  # a signed distance (a profile, a surface) or a size (a corner's error)
    ramp, vmin = (coolwarm, -limit) if signed else (viridis, 0.0)
    many = len(res_all) > 30 * len(shown)  # profiles and clouds: small dots; a board's corners: larger ones
    canvas = Canvas(FIGURE_WIDTH, top + rows * px + 40, "each view with the fitted target's section")
    for i, (k, (lo, hi)) in enumerate(zip(shown, boxes)):
        sec = sf.sections[k]
        cx, cy = left + (i % cols + 0.5) * px, top + (i // cols + 0.5) * px  # the cell's centre, the view's centre on it
        mid = 0.5 * (lo + hi)
        curve = np.asarray(sec["curve_mm"], float).reshape(-1, 2)
        canvas.path(cx + scale * (curve[:, 0] - mid[0]), cy + scale * (curve[:, 1] - mid[1]), "#555", 0.8)
        points, res = np.asarray(sec["points_mm"], float), np.asarray(sec["residual_mm"], float)
        keep = _thinned(res, MAX_SECTION_POINTS)
        for (u, v), colour in zip(points[keep], ramp(res[keep], vmin, limit)):
            if np.isfinite(u) and np.isfinite(v):
                canvas.circle(cx + scale * (u - mid[0]), cy + scale * (v - mid[1]), 1.2 if many else 2.2, colour, cls="pt")
        label = sec.get("label", sf.views[k] if k < len(sf.views) else "")
        canvas.text(cx, cy - 0.45 * px, f"{label}: {rms[k]:.3f} mm", 9, "middle")
    bar = float(10 ** np.floor(np.log10(max(cell / 4, 1e-3))))  # a scale bar: every cell is drawn at this one scale
    y = top + rows * px + 14
    canvas.line(left + 0.1 * px, y, left + 0.1 * px + scale * bar, y, "#000", 1.5)
    canvas.text(left + 0.1 * px, y + 12, f"{bar:g} mm", 9)
    colour_bar(canvas, (left + cols * px + 20, top + 10, 14, min(rows * px - 20, 300)), vmin, limit,
               "residual (mm)" if signed else "residual's size (mm)", ramp=ramp)
    plane = sf.sections[shown[0]].get("plane", SECTION_PLANE)
    lines = any(np.isfinite(np.asarray(sf.sections[k]["curve_mm"], float)).any() for k in shown)
    canvas.text(FIGURE_WIDTH / 2, 22, f"each view in {plane}, one scale: the points coloured by their residual"
                + (f", and the fitted {sf.target} through X (lines)" if lines else ""), 13, "middle", cls="title")
    return canvas.svg()


#: What a sensor's clouds are drawn in when its sections do not say (their ``frame``).
CLOUD_FRAME = "views' common"
#: The clouds' figure draws at most this many points (a random share, the same in every panel).
MAX_CLOUD_POINTS = 1500


def _clouds_figure(cal: Calibration) -> str:
    """The views' clouds registered through X (sections of 3D clouds: ``cloud_mm`` in the ``frame``
    they agree in, a scene's), seen along that frame's three axes, as SVG: above, coloured by view
    (where they overlap they should lie on one surface); below, coloured by each point's residual."""
    sf = cal.sensor
    clouds = [np.asarray(sec["cloud_mm"], float).reshape(-1, 3) for sec in sf.sections]
    res = [np.asarray(sec["residual_mm"], float) for sec in sf.sections]
    pts = np.concatenate(clouds) if clouds else np.zeros((0, 3))
    label = np.concatenate([np.full(len(c), k) for k, c in enumerate(clouds)]) if clouds else np.zeros(0, int)
    r = np.concatenate(res) if res else np.zeros(0)
    order = np.random.default_rng(0).permutation(len(pts))[:MAX_CLOUD_POINTS]  # no view drawn over all the others
    pts, label, r = pts[order], label[order].astype(int), r[order]
    ok = np.isfinite(pts).all(axis=1)
    pts, label, r = pts[ok], label[ok], r[ok]
    frame = sf.sections[0].get("frame", CLOUD_FRAME) if sf.sections else CLOUD_FRAME
    palette = CATEGORY_COLOURS if len(clouds) > 10 else CATEGORY_COLOURS[::2]
    by_view = [palette[k % len(palette)] for k in label]
    limit = max(float(np.percentile(np.abs(r), 98)), 1e-3) if len(r) else 1.0
    by_residual = coolwarm(r, -limit, limit)
    left, top, w, h, gap_x, gap_y = 70, 60, 240, 190, 60, 74
    canvas = Canvas(FIGURE_WIDTH, top + 2 * h + gap_y + 50, "the views' registered clouds, coloured by view")
    canvas.text(FIGURE_WIDTH / 2, 22, f"the views' clouds registered through X, in the {frame} frame (along its z, y and x "
                "axes): coloured by view (above) and by residual (below)", 13, "middle", cls="title")
    for c, (a, b) in enumerate([(0, 1), (0, 2), (1, 2)]):
        lo, hi = (pts[:, [a, b]].min(axis=0), pts[:, [a, b]].max(axis=0)) if len(pts) else (np.zeros(2), np.ones(2))
        mm_per_px = 1.08 * max((hi[0] - lo[0]) / w, (hi[1] - lo[1]) / h, 1e-6)  # one scale on both axes
        mid = 0.5 * (lo + hi)
        xlim = (mid[0] - mm_per_px * w / 2, mid[0] + mm_per_px * w / 2)
        ylim = (mid[1] - mm_per_px * h / 2, mid[1] + mm_per_px * h / 2)
        for row, colours in enumerate((by_view, by_residual)):
            panel = Panel(canvas, (left + c * (w + gap_x), top + row * (h + gap_y), w, h), xlim, ylim)
            for (u, v), colour in zip(pts[:, [a, b]], colours):
                canvas.circle(float(panel.x(u)), float(panel.y(v)), 1.2, colour, cls="pt")
            panel.frame()
            ticks = nice_ticks(*xlim, 4)
            panel.xticks(ticks, tick_labels(ticks), 10)
            panel.yticks(nice_ticks(*ylim, 4), grid=False, size=10)
            panel.xlabel(f"{'xyz'[a]} (mm)", 30, 11)
            panel.ylabel(f"{'xyz'[b]} (mm)", 11)
            panel.end()
    right = left + 3 * w + 2 * gap_x + 16
    shown = list(sf.views)[:12]  # the legend's room: the first dozen views
    legend(canvas, right, top, [("dot", palette[k % len(palette)], str(name)) for k, name in enumerate(shown)]
           + ([("dot", "#ffffff", f"... {len(sf.views) - len(shown)} more")] if len(sf.views) > len(shown) else []), 10)
    colour_bar(canvas, (right, top + h + gap_y, 14, h), -limit, limit, "residual (mm)", ramp=coolwarm)
    return canvas.svg()


def _sensor_residuals_section(cal: Calibration) -> str:
    """A sensor's fit: each view's residual, the views left out and the sensor's own figures."""
    sf = cal.sensor
    parts = ['<section id="residuals"><h2>Per-view residuals</h2>' + _view_residual_figure(cal),
             f"<p>{sf.points} measurements fitted, {sf.rejected} set aside as outliers (beyond 5 of their std); "
             f"{sf.fit_rms_mm:.3f} mm RMS.</p>"]
    shown = _shown_sections(sf) if sf.sections and "cloud_mm" not in sf.sections[0] else []
    if sf.sections and "cloud_mm" in sf.sections[0]:  # 3D clouds in one frame (a scene's), not sections in a plane
        parts.append(_clouds_figure(cal))
    elif shown:
        parts.append(_sections_figure(cal)
                     + (f"<p>{len(shown)} of {len(sf.sections)} views drawn: the {MAX_SECTIONS // 2} that fit worst and "
                        "others evenly.</p>" if len(shown) < len(sf.sections) else ""))
    if cal.skipped:
        parts.append("<p>Views not used: " + "; ".join(f"{_e(n)} ({_e(r)})" for n, r in cal.skipped) + "</p>")
    shown = {k: v for k, v in sf.figures.items() if not (joins_sensors(cal) and k in RIG_FIGURES)}  # a rig's: in its own sections
    rows = "".join(f'<tr><td class="l">{_e(_figure_label(k))}</td><td class="l">{_e(_figure_text(v))}</td></tr>'
                   for k, v in shown.items())
    if rows:  # a rig's figures are all in its sections: no empty table
        parts.append(f"<h3>The {_e(sf.sensor)}'s own figures</h3>"
                     f'<table><tr><th class="l">figure</th><th class="l">value</th></tr>{rows}</table>')
    parts.append("</section>")
    return "".join(parts)


#: A sensor figure's key's last word, when it is a unit, as the report writes the unit.
FIGURE_UNITS = {"m": "m", "mm": "mm", "um": "µm", "px": "px", "s": "s", "ms": "ms", "hz": "Hz", "deg": "deg", "rad": "rad"}


def _figure_label(key: str) -> str:
    """A sensor figure's key in words: ``clock_offset_s`` is 'clock offset (s)', ``line_rate_hz`` 'line rate (Hz)'."""
    words = str(key).split("_")
    if len(words) > 1 and words[-1].lower() in FIGURE_UNITS:
        return " ".join(words[:-1]) + f" ({FIGURE_UNITS[words[-1].lower()]})"
    return " ".join(words)


def _number(x: float, digits: int = 6) -> str:
    """A number as people write it: a whole number without a point, else ``digits`` significant figures."""
    x = float(x)
    if np.isfinite(x) and x == round(x) and abs(x) < 1e15:
        return str(int(round(x)))
    return f"{x:.{digits}g}"


def _figure_text(value) -> str:
    """A sensor figure as text: a value with its std, yes or no, a whole number as one, numbers rounded
    (a list in brackets, a table's rows split by semicolons), 'none' for an empty list."""
    if isinstance(value, dict) and "value" in value:
        return f"{value['value']:.6g} ± {value.get('std', 0.0):.3g}" + ("" if value.get("fitted", True) else " (not fitted)")
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if value is None:
        return "—"
    if isinstance(value, str):
        return value
    if isinstance(value, (list, tuple)) and value and all(isinstance(v, str) for v in value):
        return ", ".join(value)
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):  # not numbers (a mapping, text): as written
        return str(value)
    if a.ndim == 0:
        return _number(a)
    if a.size == 0:
        return "none"
    if a.ndim == 1:
        return "[" + ", ".join(_number(x, 4) for x in a) + "]"
    return "; ".join("[" + ", ".join(_number(x, 4) for x in row) + "]" for row in a.reshape(len(a), -1))


def _verdict_section(cal: Calibration, verdict: str, pres: NDArray[np.float64]) -> str:
    std_txt = ""
    if cal.std is not None and cal.unobservable:
        std_txt = f" · {len(cal.unobservable)} direction(s) of X not determined by the data (see Result)"
    elif cal.std is not None:
        std_txt = (f" · std of X per axis: translation up to {np.max(cal.std[3:]):.3f} mm, rotation up to "
                   f"{np.max(cal.std[:3]):.4f} deg")
    headline = verdict_headline(cal) if verdict == cal.verdict else HEADLINES.get(verdict, "")
    tail = (f"; median pose consistency {np.median(pres[:, 0]):.3f} deg / {np.median(pres[:, 1]):.3f} mm" if len(pres)
            else f"; fit {cal.sensor.fit_rms_mm:.3f} mm RMS" if cal.sensor is not None else "")
    if cal.prediction_error is not None and cal.sensor is not None:
        tail += f", held-out views {cal.prediction_error['mm']:.3f} mm"
    return (f'<section id="verdict"><div class="banner" style="background:{_COLOURS.get(verdict, "#555")}">'
            f"<b>{_e(verdict)}</b> — {_e(headline)}{_e(std_txt)}{_e(tail)}</div></section>")


def _result_section(cal: Calibration, data: dict) -> str:
    parts = [f'<section id="result"><h2>Result</h2><h3>X = {_e(data["X_name"])}</h3>'
             f"<p>maps camera coordinates into the {setup_info(cal.setup).x_parent} frame; "
             f"refinement: {_e(cal.refinement)}"
             + (f", RMS {cal.refined_rms:.3f} px over all target points" if cal.refined_rms is not None else "")
             + "</p>" + _transform_table(cal.X, cal.std)
             + _determined_table(cal, data)
             + f"<h3>Z = {_e(data['Z_name'])}</h3>" + _transform_table(cal.Z, cal.std_Z)
             + "<h3>Paste into ROS 2</h3>"
             + f"<pre>{_e(data['ros']['static_transform_publisher'])}</pre><pre>{_e(data['ros']['urdf_joint'])}</pre>"]
    if cal.certificate is not None:
        c = cal.certificate
        parts.append(f"<p><b>Certificate:</b> X is {'' if c.optimal else 'not '}the global minimum of the stated "
                     f"cost ({_e(c.cost_name)}): cost {c.cost:.6g}, lower bound {c.lower_bound:.6g}, gap "
                     f"{c.gap:.3g}{'' if c.tight else ' (relaxation not tight)'}</p>")
    if cal.time_offset is not None:
        st = cal.streams or {}
        parts.append(f"<p><b>Clock offset</b> (camera minus robot): {1e3 * cal.time_offset:.2f} &plusmn; "
                     f"{1e3 * cal.time_offset_std:.2f} ms; {len(st.get('keyframe_camera_times_s', []))} keyframes of "
                     f"{st.get('camera_samples', '?')} camera and {st.get('robot_samples', '?')} robot samples, the robot "
                     "interpolated at each keyframe's time minus the offset</p>")
    if cal.cross_validation is not None:
        parts.append(_cross_validation_table(cal))
    if cal.pose_noise is not None:
        parts.append(f"<p>noise estimated from the data (per axis): {_e(cal.pose_noise_text())}</p>")
    if cal.camera_matrix is not None:
        K = cal.camera_matrix
        parts.append(f"<p>intrinsics ({_e(cal.intrinsics_source)}): fx {K[0, 0]:.2f}, fy {K[1, 1]:.2f}, "
                     f"cx {K[0, 2]:.2f}, cy {K[1, 2]:.2f}, dist [{_fmt(cal.dist_coeffs, 4)}]"
                     + (f"; camera calibration RMS {cal.intrinsics_rms:.3f} px" if cal.intrinsics_rms is not None else "")
                     + "</p>")
    parts.append("</section>")
    return "".join(parts)


def _determined_table(cal: Calibration, data: dict) -> str:
    """Which parameters of X the data determine, which were given (``known=``), which stay open; only
    for motions that determine part of X (SCARA, Cartesian robots)."""
    if cal.motion_kind == "general" and not cal.known:
        return ""
    rows = "".join(f'<tr><td class="l">{_e(k)}</td><td class="l">{_e(v)}</td></tr>' for k, v in data["determined"].items())
    parts = ["<h3>What the data determine</h3>",
             f'<table><tr><th class="l">parameter of X</th><th class="l">from</th></tr>{rows}</table>']
    for u in cal.unobservable:
        parts.append(f"<p><b>Not determined:</b> {_e(u.parameter)} (direction [{_fmt(u.direction, 3)}] in the "
                     f"{_e(u.frame)} frame); set to {_e(u.choice)}. {_e(u.coupled)}. To fix it: {_e(u.fix)}.</p>")
    for name, k in cal.known.items():
        use = "used: the data cannot determine it" if k["used"] else f"not used: the data give {k['data_m']:.5f} m"
        parts.append(f"<p>known {_e(name)} = {k['value_m']:.5f} ± {k['std_m']:.5f} m ({_e(use)})</p>")
    return "".join(parts)


#: What the held-out table's rows are, by who made the calibration: a camera's estimators, or a
#: sensor's fit beside its closed-form start.
HELD_OUT_CAMERA = ("Each view predicted from its robot pose by X and Z fitted without it: where the target's points land "
                   "against where the camera saw them. The estimator used is listed first: the preferred refinement (the "
                   "pixel refinement while the robot's errors do not dominate its residuals, else the pose refinement) is "
                   "replaced only by a candidate better by more than one standard error of the per-view differences, so "
                   "the one used need not have the smallest error here.")
HELD_OUT_SENSOR = ("Each view predicted from its robot {robot} by X and the target fitted without it (its fold of the "
                   "cross-validation): how far its measurements lie from the target's model, in millimetres at the "
                   "target. The {sensor}'s fit is listed first, then its closed-form start refitted the same way: the "
                   "fit should predict the views it has not seen better than its start does.")


def _cross_validation_table(cal: Calibration) -> str:
    """Held-out prediction error of every estimator tried, the one used first."""
    rows = sorted(cal.cross_validation.items(),  # the score the choice was made by: px with images, else mm
                  key=lambda kv: (kv[0] != cal.estimator, kv[1]["mm"] if kv[1]["px"] is None else kv[1]["px"]))
    body = []
    for name, r in rows:
        px = "—" if r.get("px") is None else f"{r['px']:.3f}"
        used = " (used)" if name == cal.estimator else ""
        body.append(f'<tr><td class="l">{_e(name)}{used}</td><td>{px}</td><td>{r["mm"]:.3f}</td></tr>')
    body = "".join(body)
    text = HELD_OUT_CAMERA if cal.sensor is None else HELD_OUT_SENSOR.format(
        robot="joint angles" if cal.kinematic is not None else "pose", sensor=cal.sensor.sensor)
    return (f"<h3>Held-out prediction error (cross-validated)</h3><p class=\"note\">{_e(text)}</p>"
            f'<table><tr><th class="l">estimator</th><th>px</th><th>mm at the target</th></tr>{body}</table>')


def _residuals_section(cal: Calibration) -> str:
    parts = ['<section id="residuals"><h2>Per-pose residuals</h2>' + _residual_figure(cal)]
    parts.append(f"<p>Screw congruence per motion (|angle_A − angle_B|; |pitch_A − pitch_B| as a share of the motion's "
                 f"translation; independent of X, both 0 for consistent data): {_e(cal.screw_congruence_text())}.</p>")
    left, kept = cal.outliers_split()
    d = cal.diagnostics

    def named(idx):
        return ", ".join(_e(d.pose_name(i)) + (f" ({d.outlier_residuals[i][0]:.2f} deg / {d.outlier_residuals[i][1]:.1f} "
                                               "mm from the others)" if i in d.outlier_residuals else "") for i in idx)
    if left and not cal.image_names:  # images left out are listed with the skipped ones, with why
        parts.append(f"<p>Left out as outliers: {named(left)}.</p>")
    if kept:
        parts.append(f"<p>Looked like outliers by their PnP poses but kept: the robust pixel refinement judges their "
                     f"points one by one: {named(kept)}.</p>")
    if cal.skipped:
        parts.append("<p>Skipped images: " + "; ".join(f"{_e(n)} ({_e(r)})" for n, r in cal.skipped) + "</p>")
    parts.append("</section>")
    return "".join(parts)


def _overlays_section(cal: Calibration) -> str:
    parts = ['<section id="overlays"><h2>Target points: detected vs predicted by X</h2>']
    if cal.image_paths:
        parts.append("<p class=\"note\">Green rings: detected points. Red crosses: the same points projected through "
                     "the robot pose, X and Z — where they part, the hand-eye model does not explain that image. "
                     f"Each image is cropped around the target, grey and faded. Caption: RMS distance; red frame: more than "
                     f"{FLAG_FACTOR:g}x the median. Click an image to enlarge it.</p><div class=\"thumbs\">")
        thumbs = _overlay_thumbs(cal)
        median = float(np.median([t[2] for t in thumbs])) if thumbs else 0.0
        for src, caption, rms in thumbs:
            flag = rms > FLAG_FACTOR * max(median, 0.1)
            caption += f" (over {FLAG_FACTOR:g}x the median {median:.2f} px: check this view)" if flag else ""
            cls = ' class="flag"' if flag else ""
            parts.append(f'<figure{cls}><img class="zoom" tabindex="0" src="{src}" alt="{_e(caption)}">'
                         f"<figcaption>{_e(caption)}</figcaption></figure>")
        for src, caption in _rejected_thumbs(cal):
            img = (f'<img class="zoom" tabindex="0" src="{src}" alt="{_e(caption)}">' if src else "")
            parts.append(f'<figure class="rejected">{img}<figcaption>not used — {_e(caption)}</figcaption></figure>')
        parts.append("</div>")
        if len(cal.image_paths) > MAX_OVERLAYS:
            parts.append(f"<p class=\"note\">first {MAX_OVERLAYS} of {len(cal.image_paths)} images shown</p>")
    else:
        parts.append("<p class=\"note\">No images: this calibration was made from poses.</p>")
    parts.append("</section>")
    return "".join(parts)


def _axes_section(cal: Calibration) -> str:
    motions = cal.motions or MotionSet.from_poses(cal.flange2base, cal.target2cam, cal.setup, cal.pairs)
    obs = ""
    if cal.diagnostics is not None and cal.diagnostics.axis_shares is not None:
        sh = cal.diagnostics.axis_shares
        obs = (f"<p>Spread of the rotation axes (eigenvalue shares, 1/3 each is ideal): {_fmt(sh, 2)}; rotation angles "
               f"{np.min(cal.diagnostics.rotation_angles_deg):.1f}–{np.max(cal.diagnostics.rotation_angles_deg):.1f} deg.</p>")
    return ('<section id="axes"><h2>Rotation axes</h2>' + _axes_figure(cal, motions) + obs
            + "</section>")


def _solvers_section(rows: list[dict] | None) -> str:
    parts = ['<section id="solvers"><h2>Every solver on the same data</h2>']
    if rows is not None:
        parts.append("<table><tr><th class=\"l\">method</th><th>X vs result (deg)</th><th>X vs result (mm)</th>"
                     "<th>median pose (deg)</th><th>median pose (mm)</th><th>time (ms)</th></tr>")
        for r in rows:
            if "error" in r:
                parts.append(f'<tr><td class="l">{_e(r["method"])}</td><td class="l" colspan="5">{_e(r["error"])}</td></tr>')
            else:
                parts.append(f'<tr><td class="l">{_e(r["method"])}</td><td>{r["dX_deg"]:.4f}</td><td>{r["dX_mm"]:.3f}</td>'
                             f'<td>{r["median_pose_deg"]:.4f}</td><td>{r["median_pose_mm"]:.3f}</td><td>{r["ms"]:.1f}</td></tr>')
        parts.append("</table><p class=\"note\">Closed forms without refinement, all on the poses used above. Solvers "
                     "that disagree by much more than the std of X point to noisy or inconsistent data.</p>")
    else:
        parts.append("<p class=\"note\">not computed</p>")
    parts.append("</section>")
    return "".join(parts)


#: The report suggests more rotation about an axis whose share of the rotation axes is below this
#: (1/3 is ideal; the check calls the data weak only below AXIS_SHARE_WEAK), and a look at the data when
#: the closed forms land further from X than this many std.
AXIS_SHARE_HINT, SOLVER_SPREAD_HINT = 0.15, 3.0


def _could_be_better(cal: Calibration, rows: list[dict] | None) -> list[str]:
    """What is not wrong enough to change the verdict but worth knowing: rotation axes that are not
    well spread, solvers that disagree by more than the std of X."""
    out = []
    d = cal.diagnostics
    if d is not None and d.axis_shares is not None and d.axis_shares.min() < AXIS_SHARE_HINT:
        out.append(f"The rotation axes are not well spread (shares {_fmt(d.axis_shares, 2)}; 1/3 each is ideal): "
                   "the next capture should turn the camera more about its weakest axis "
                   f"({_fmt(d.weakest_axis, 2)} in the camera frame).")
    solved = [r for r in (rows or []) if "error" not in r]
    if solved and cal.std is not None and np.isfinite(cal.std).all():
        spread = float(np.median([r["dX_mm"] for r in solved])) / max(float(np.linalg.norm(cal.std[3:])), 1e-9)
        if spread > SOLVER_SPREAD_HINT:
            out.append(f"The closed-form solvers land a median {spread:.1f} std of X away from it: their "
                       "disagreement says the poses are noisier than a good capture's; more poses with larger "
                       "rotations would pin X down better.")
    return out


def _kinematics_section(cal: Calibration) -> str:
    """The arm's table as a calibration from joint angles found it: each entry's correction with
    its std, whether the capture determines it, and how far the corrections move the flange."""
    k = cal.kinematic
    if k is None:
        return ""
    rows = []
    for name, c, s, p, d in zip(k.names, k.correction, k.std, k.prior_std, k.determined):
        f, unit = display_unit(name)
        digits = 3 if unit == "mm" else 4
        rows.append(f'<tr><td class="l">{_e(name)}</td><td>{f * c:+.{digits}f} {unit}</td><td>{f * s:.{digits}f}</td>'
                    f'<td>{f * p:.{digits}f}</td><td class="l">{"yes" if d else "no: held near nominal"}</td></tr>')
    shift = k.flange_shift_mm
    return ('<section id="kinematics"><h2>Arm kinematics</h2>'
            f'<p>{_e(k.nominal.name)}\'s {_e(k.nominal.convention.upper())} table, corrected with X: '
            f"{int(k.determined.sum())} of {len(k.names)} entries determined by the capture"
            + (f"; the corrections move the flange {shift[0]:.2f} mm (median; up to {shift[1]:.2f} mm) from where the "
               "nominal table puts it over this capture's joint angles" if shift is not None else "")
            + ". The corrected table is in arm_corrected.yaml and arm_corrected.urdf.</p>"
            + ("" if k.accuracy_mm is None else
               f"<p>The arm's accuracy at the flange within the capture's joint ranges: {k.accuracy_mm['before_median']:.2f} mm "
               f"with the nominal table (median), {k.accuracy_mm['after_median']:.3f} mm with the corrected one (predicted "
               "by the fit, 1 std)"
               + ("" if "workspace_after_median" not in k.accuracy_mm else
                  f"; over the joints' whole range (their limits, beyond the capture's: extrapolated) "
                  f"{k.accuracy_mm['workspace_before_median']:.2f} mm with the nominal table and "
                  f"{k.accuracy_mm['workspace_after_median']:.3f} mm with the corrected one")
               + ".</p>")
            + '<table><tr><th class="l">entry</th><th>correction</th><th>std</th><th>prior std</th>'
            '<th class="l">determined</th></tr>' + "".join(rows) + "</table>"
            f'<p class="note">Nominal table: {_e(k.nominal.source or k.nominal.name)}</p></section>')


def _advice_section(cal: Calibration, data: dict, rows: list[dict] | None = None) -> str:
    advice = list(data["check"]["advice"]) + [n for n in cal.notes if n not in data["check"]["advice"]]
    advice += [a for a in _could_be_better(cal, rows) if a not in advice]
    if not advice:
        advice = ["Nothing to fix: the motions rotate about well-spread axes and the poses agree."]
    return '<section id="advice"><h2>Advice</h2><ul>' + "".join(f"<li>{_e(a)}</li>" for a in advice) + "</ul></section>"


def report_html(cal: Calibration, parent_frame: str | None = None, child_frame: str | None = None,
                solver_rows: list[dict] | None = None) -> str:
    """The report page for a calibration, as one self-contained HTML string.

    ``solver_rows``: the solver comparison to draw (:func:`handeye.estimation.diagnostics.compare_solvers`);
    default ``cal.solver_comparison``; the section says "not computed" when there is none.
    """
    data = result_dict(cal, parent_frame, child_frame)
    verdict = data["check"]["verdict"]
    pres = cal.pose_residuals
    if solver_rows is None:
        solver_rows = cal.solver_comparison
    parts = [f"<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>handeye report: {_e(data['X_name'])}</title>"
             f"<style>{_CSS}</style></head><body>",
             f"<h1>Hand-eye calibration ({_e(cal.setup.replace('_', '-'))})</h1>"
             f"<p class=\"note\">handeye {_e(__version__)} · method {_e(cal.method)} · {len(cal.flange2base)} "
             + (f"poses, {len(cal.pairs)} motions" if cal.sensor is None else "views")  # a sensor's fit pairs no motions
             + " · inputs sha256 "
             f"{_e((cal.inputs_sha256 or '')[:16])}…</p>",
             _verdict_section(cal, verdict, pres),
             _result_section(cal, data)]
    if cal.target2cam is None:  # a sensor's fit (depth, laser, ...): its views' residuals and figures
        parts += [rig_sections(cal) if joins_sensors(cal) else "", _sensor_residuals_section(cal), _kinematics_section(cal),
                  '<section id="scene"><h2>Robot, sensor and target</h2>' + _scene_figure(cal)
                  + "</section>", _advice_section(cal, data), "</body></html>\n"]
        return "".join(parts)
    parts += [_residuals_section(cal),
              _kinematics_section(cal),
              _overlays_section(cal),
              '<section id="scene"><h2>Robot, camera and target</h2>' + _scene_figure(cal) + "</section>",
              _axes_section(cal),
              _solvers_section(solver_rows),
              _advice_section(cal, data, solver_rows),
              "</body></html>\n"]
    return "".join(parts)


def write_report(cal: Calibration, path: str | Path, protect: Iterable[Path] = (), parent_frame: str | None = None,
                 child_frame: str | None = None, solver_rows: list[dict] | None = None) -> Path:
    """Write :func:`report_html` to ``path`` atomically (never over a ``protect`` path); returns the path."""
    path = Path(path)
    atomic_write(path, report_html(cal, parent_frame, child_frame, solver_rows), protect)
    return path
