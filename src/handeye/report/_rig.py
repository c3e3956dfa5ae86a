"""A rig's part of ``report.html``: a picture of the rig, then a section per sensor (figures as inline SVG,
:mod:`handeye.report._svg`).

The picture: every sensor's frame (its X from the joint fit) in X's parent frame (the flange
eye-in-hand, the robot base eye-to-hand), with the target where the first view saw it (eye-to-hand,
the target on the flange: its origin in every view too). A section per
sensor (``<section class="sensor" id="sensor-NAME">``): whether it is in the joint fit (or disagreed
with the rest, or was skipped, and why), its X with its std, its pose relative to the first sensor,
its own calibration's verdict and held-out error, and its residual per view in the joint fit.
"""

from __future__ import annotations

import numpy as np

from ..frames.metrics import rotation_error, translation_error
from ..frames.setups import pose_name, setup_info, target2base
from ..geometry.se3 import invert
from ..result import Calibration
from ._page import FIGURE_WIDTH, _e, _transform_table
from ._svg import Canvas, Panel, View3D, legend, nice_ticks, text_width, triads

#: The sensor figures the rig's sections show (left out of the sensor's table of figures).
RIG_FIGURES = ("X_per_sensor", "view_rms_mm_per_sensor", "relative", "alone", "rms_mm_per_sensor", "sensors", "disagreeing",
               "skipped", "images_per_sensor", "disagreeing_pair")


#: The rig's picture: its height, and each panel's 3D view (x, y, width, height) within its half of the width.
RIG_HEIGHT, RIG_VIEW = 540, (95, 90, 340, 360)


def rig_figure(cal: Calibration) -> str:
    """The rig in X's parent frame (inline SVG): on the left the sensors and that frame's origin, each
    sensor's frame labelled, a dashed line from the first sensor to each other one; on the right the
    same with the target where the first view saw it (eye-to-hand: its origin in every view too)."""
    info = setup_info(cal.setup)
    frames = {n: np.asarray(f["X"], float) for n, f in cal.sensor.figures["X_per_sensor"].items()}
    targets = target2base(cal.Z, cal.flange2base, cal.setup)
    if info.camera_on_flange:  # the flange's frame: the target where the first view saw it
        targets = invert(cal.flange2base[:1]) @ targets[:1]
    parent = "flange" if info.camera_on_flange else "robot base"
    sensors = np.vstack([T[:3, 3] for T in frames.values()])
    first = next(iter(frames.values()))
    canvas = Canvas(FIGURE_WIDTH, RIG_HEIGHT, "the rig's sensors")
    canvas.text(FIGURE_WIDTH / 2, 20, f"the rig in the {parent}'s frame: each sensor's axes (x red, y green, z blue: the "
                "optical axis)", 13, "middle", cls="title")
    for k, with_target in enumerate((False, True)):
        left = k * FIGURE_WIDTH / 2
        points = np.vstack([sensors, np.zeros((1, 3))] + ([targets[:, :3, 3]] if with_target else []))
        extent = float(np.ptp(points, axis=0).max()) or 1.0
        L, centre, half = 0.12 * extent, points.mean(axis=0), 0.6 * extent  # a cube about the points
        x, y, w, h = RIG_VIEW
        view = View3D(canvas, (left + x, y, w, h), centre - half, centre + half)
        view.axes(("x (m)", "y (m)", "z (m)"), [nice_ticks(c - half, c + half, 4) for c in centre])
        triads(view, np.eye(4), 1.2 * L, 2.5)
        view.text(np.zeros(3), parent)
        if with_target:
            triads(view, targets[0], L, 2.0)
            view.text(targets[0][:3, 3], "target" + (" (first view)" if len(cal.flange2base) > 1 else ""))
            if len(targets) > 1:  # the target rides on the flange: where it was in every view
                view.points(targets[:, :3, 3], "#8b4513", 2.5, square=True)
                legend(canvas, left + 12, 56, [("square", "#8b4513", "the target's origin in each view")])
        for name, T in frames.items():
            view.lines(np.vstack([first[:3, 3], T[:3, 3]]), "#777", 0.8, dash="4 3")
            triads(view, T, L, 1.5)
            view.text(T[:3, 3], name)
        canvas.text(left + FIGURE_WIDTH / 4, 44, "with the target" if with_target else f"the sensors and the {parent}", 12,
                    "middle", cls="title")
    return canvas.svg()


def _sensor_residual_figure(views: list[str], rms: list[float | None], name: str) -> str:
    """A sensor's RMS residual per view in the joint fit (inline SVG): a bar per view, none where it saw nothing."""
    values = np.array([np.nan if v is None else v for v in rms], float)
    n = len(values)
    labelled, turned = n <= 60, n > 12
    below = 12 + (text_width(max(views, key=len, default=""), 10) if turned else 18) if labelled else 12
    left, top, height = 80, 34, 120
    canvas = Canvas(FIGURE_WIDTH, top + height + below + 6, f"sensor {name}'s residual per view")
    hi = float(np.nanmax(values)) if np.isfinite(values).any() else 1.0
    ylim = (0.0, 1.05 * hi if hi > 0 else 1.0)
    panel = Panel(canvas, (left, top, FIGURE_WIDTH - left - 16, height), (-0.6, n - 0.4), ylim)
    panel.yticks(nice_ticks(*ylim, 4))
    panel.bars(np.arange(n), values, "#4a78b5", tips=[f"{v}: {r:.3f} mm" for v, r in zip(views, values)])
    panel.frame()
    panel.ylabel("RMS (mm)")
    panel.title(f"sensor {name}: its residual per view in the joint fit (none where it saw nothing)")
    if labelled:
        panel.xticks(np.arange(n), views, 10 if turned else 11, rotate=turned)
    panel.end()
    return canvas.svg()


def _status(cal: Calibration, name: str) -> str:
    """Why a sensor is not in the joint fit, from the notes (or an empty string)."""
    for note in cal.notes:
        if note.startswith((f"sensor {name} disagrees", f"sensor {name} skipped")):
            return note
    return ""


def rig_sections(cal: Calibration) -> str:
    """The rig's picture and a section per sensor (the module docstring), as HTML."""
    figures = cal.sensor.figures
    joint = list(figures["X_per_sensor"])
    alone = figures.get("alone", {})
    names = joint + [n for n in list(alone) + list(figures.get("skipped", [])) if n not in joint]
    rms = dict(zip(figures.get("sensors", joint), figures.get("rms_mm_per_sensor", [])))
    per_view = figures.get("view_rms_mm_per_sensor", {})
    views = list(cal.diagnostics.names) if cal.diagnostics is not None and cal.diagnostics.names else []
    parts = ['<section id="rig"><h2>The rig</h2>' + rig_figure(cal)
             + f"<p>{len(joint)} sensor(s) in the joint fit ({_e(', '.join(joint))})"
             + (f"; {len(names) - len(joint)} not ({_e(', '.join(n for n in names if n not in joint))})" if len(names) > len(joint)
                else "") + ". X of the first, " + _e(joint[0]) + ", is the result's X; the others' are below.</p>"]
    for name in names:
        parts.append(f'<section class="sensor" id="sensor-{_e(name)}"><h3>Sensor {_e(name)}</h3>')
        own = alone.get(name)
        if name in joint:
            X, std = np.asarray(figures["X_per_sensor"][name]["X"]), np.asarray(figures["X_per_sensor"][name]["std_deg_mm"])
            line = "in the joint fit" + (f": {rms[name]:.3f} mm RMS over its views" if rms.get(name) is not None else "")
        else:
            X = None if own is None else np.asarray(own["X"])
            std = None if own is None else np.asarray(own["std_deg_mm"])
            line = _status(cal, name) or "not in the joint fit"
        if own is not None:
            line += f"; calibrated alone: {own['verdict']}"
            if own.get("heldout_mm") is not None:
                line += f", held-out views {own['heldout_mm']:.3f} mm (cross-validated)"
            if name in joint:
                A = np.asarray(own["X"])
                line += (f", its own X {1e3 * translation_error(A, X):.3f} mm / {np.degrees(rotation_error(A, X)):.4f} deg "
                         "from the joint fit's")
        parts.append(f"<p>{_e(line)}.</p>")
        if X is not None:
            parts.append(f"<p>X ({_e(pose_name(name, setup_info(cal.setup).x_name.split('2', 1)[1]))}), "
                         + ("from the joint fit, its std with the robot's accuracy" if name in joint else "its own calibration")
                         + ":</p>" + _transform_table(X, std))
        rel = figures.get("relative", {}).get(pose_name(name, joint[0]))
        if rel is not None:
            parts.append(f"<p>Its pose in {_e(joint[0])}'s frame ({_e(pose_name(name, joint[0]))}, the robot's error common "
                         "to every pose cancels in it, each pose's own error where both saw the pose):</p>"
                         + _transform_table(np.asarray(rel["matrix"]), np.asarray(rel["std_deg_mm"])))
        if name in per_view and views:
            parts.append(_sensor_residual_figure(views, per_view[name], name))
        parts.append("</section>")
    parts.append("</section>")
    return "".join(parts)
