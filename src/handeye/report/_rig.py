"""A rig's part of ``report.html``: a picture of the rig, then a section per sensor.

The picture: every sensor's frame (its X from the joint fit) in X's parent frame (the flange
eye-in-hand, the robot base eye-to-hand), with the target where the first view saw it (eye-to-hand,
the target on the flange: its origin in every view too). A section per
sensor (``<section class="sensor" id="sensor-NAME">``): whether it is in the joint fit (or disagreed
with the rest, or was skipped, and why), its X with its std, its pose relative to the first sensor,
its own calibration's verdict and held-out error, and its residual per view in the joint fit.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..frames.metrics import rotation_error, translation_error
from ..frames.setups import pose_name, setup_info, target2base
from ..geometry.se3 import invert
from ..result import Calibration
from ._page import _axis_triad, _e, _equal_axes, _figure, _img, _png, _transform_table

#: The sensor figures the rig's sections show (left out of the sensor's table of figures).
RIG_FIGURES = ("X_per_sensor", "view_rms_mm_per_sensor", "relative", "alone", "rms_mm_per_sensor", "sensors", "disagreeing",
               "skipped", "images_per_sensor", "disagreeing_pair")


def _triad(ax, T: NDArray[np.float64], length: float, lw: float, label: str | None = None) -> None:
    _axis_triad(ax, T, length, lw)
    if label:
        ax.text(*T[:3, 3], f" {label}", fontsize=9)


def _panel(ax, points: NDArray[np.float64], title: str) -> None:
    """Equal axes around ``points`` (n, 3), labelled."""
    _equal_axes(ax, points, 0.6)
    ax.set_box_aspect((1, 1, 1))
    for setter, axis in ((ax.set_xlabel, "x"), (ax.set_ylabel, "y"), (ax.set_zlabel, "z")):
        setter(f"{axis} (m)", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.locator_params(nbins=4)
    ax.set_title(title, fontsize=9)


def rig_figure(cal: Calibration):
    """The rig in X's parent frame (a matplotlib Figure): on the left the sensors and that frame's
    origin, each sensor's frame labelled, a line from the first sensor to each other one; on the right
    the same with the target where the first view saw it (eye-to-hand: its origin in every view too)."""
    info = setup_info(cal.setup)
    frames = {n: np.asarray(f["X"], float) for n, f in cal.sensor.figures["X_per_sensor"].items()}
    targets = target2base(cal.Z, cal.flange2base, cal.setup)
    if info.camera_on_flange:  # the flange's frame: the target where the first view saw it
        targets = invert(cal.flange2base[:1]) @ targets[:1]
    parent = "flange" if info.camera_on_flange else "robot base"
    sensors = np.vstack([T[:3, 3] for T in frames.values()])
    first = next(iter(frames.values()))
    fig = _figure((12.0, 5.6))
    for k, with_target in enumerate((False, True)):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        points = np.vstack([sensors, np.zeros((1, 3))] + ([targets[:, :3, 3]] if with_target else []))
        L = 0.12 * (float(np.ptp(points, axis=0).max()) or 1.0)
        _triad(ax, np.eye(4), 1.2 * L, 2.5, parent)
        if with_target:
            _triad(ax, targets[0], L, 2.0, "target" + (" (first view)" if len(cal.flange2base) > 1 else ""))
            if len(targets) > 1:  # the target rides on the flange: where it was in every view
                ax.scatter(*targets[:, :3, 3].T, color="#8b4513", s=10, marker="s", label="the target's origin in each view")
                ax.legend(loc="upper left", fontsize=7)
        for name, T in frames.items():
            _triad(ax, T, L, 1.5, name)
            ax.plot(*np.c_[first[:3, 3], T[:3, 3]], color="#777", lw=0.8, ls="--")
        _panel(ax, points, "with the target" if with_target else f"the sensors and the {parent}")
    fig.suptitle(f"the rig in the {parent}'s frame: each sensor's axes (x red, y green, z blue: the optical axis)",
                 fontsize=10)
    return fig


def _sensor_residual_figure(views: list[str], rms: list[float | None], name: str) -> str:
    fig = _figure((10, 2.0))
    ax = fig.subplots(1, 1)
    values = np.array([np.nan if v is None else v for v in rms], float)
    x = np.arange(len(values))
    ax.bar(x, np.nan_to_num(values), color="#4a78b5")
    ax.set_ylabel("RMS (mm)")
    ax.set_title(f"sensor {name}: its residual per view in the joint fit (none where it saw nothing)", fontsize=9)
    ax.grid(axis="y", alpha=0.3)
    if len(x) <= 60:
        ax.set_xticks(x)
        ax.set_xticklabels(views, rotation=90 if len(x) > 12 else 0, fontsize=7)
    return _png(fig)


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
    parts = ['<section id="rig"><h2>The rig</h2>' + _img(_png(rig_figure(cal)), "the rig's sensors")
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
            parts.append(_img(_sensor_residual_figure(views, per_view[name], name), f"sensor {name}'s residual per view"))
        parts.append("</section>")
    parts.append("</section>")
    return "".join(parts)
