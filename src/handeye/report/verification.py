"""Files of a verification (:func:`handeye.pipelines.verify.verify`): ``verify.json`` and a
self-contained ``verify.html`` with the per-view errors, their distribution (an inline SVG chart) and each
view's image with the detected and the predicted target points."""

from __future__ import annotations

import json
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Iterable

import numpy as np

from .._shared.io import atomic_write, check_output_folder
from .._version import __version__
from ..pipelines.verify import NOT_THIS, Verification
from ..sensors.camera.detect import default_jobs
from ._overlay import overlay_thumbnail
from ._page import _COLOURS, _CSS, _e
from ._svg import Canvas, Panel, legend_row, nice_ticks, tick_labels

__all__ = ["verification_html", "write_verification"]


def _histogram(v: Verification) -> str:
    """The per-view errors' histograms (px, and mm at the target), each with its RMS (red) and the
    promised cross-validated error (green, dashed) as lines, as SVG."""
    canvas = Canvas(1060, 300, "errors per view")
    for k, (values, unit) in enumerate(((v.px, "px"), (v.mm, "mm at the target"))):
        values = np.asarray(values, float)
        rms = float(np.sqrt(np.mean(values**2))) if len(values) else 0.0
        promised = None if v.promised is None else v.promised.get(unit.split()[0])
        counts, edges = np.histogram(values, bins=min(20, max(5, len(values) // 2)))
        marks = [rms] + ([float(promised)] if promised is not None else [])
        lo, hi = min(float(edges[0]), *marks), max(float(edges[-1]), *marks)
        pad = 0.05 * ((hi - lo) or 1.0)
        top = max(int(counts.max()) if len(counts) else 1, 1)
        panel = Panel(canvas, (80 + 510 * k, 40, 440, 200), (lo - pad, hi + pad), (0.0, 1.08 * top))
        ticks = nice_ticks(0.0, top, 4)
        panel.yticks(ticks[ticks == np.round(ticks)])  # whole views
        step = float(edges[1] - edges[0])
        panel.bars((edges[:-1] + edges[1:]) / 2, counts, "#4a78b5", 0.94 * step,
                   [f"{a:.3f}-{b:.3f} {unit}: {c} views" for a, b, c in zip(edges[:-1], edges[1:], counts)])
        entries = [("#b00020", "RMS")]
        y0, y1 = panel.y(0.0), panel.y(1.08 * top)
        canvas.line(panel.x(rms), y0, panel.x(rms), y1, "#b00020", 1.5)
        if promised is not None:
            canvas.line(panel.x(promised), y0, panel.x(promised), y1, "#1e7b34", 1.5, dash="6 4")
            entries.append(("#1e7b34", "promised (cross-validated)"))
        panel.frame()
        xt = nice_ticks(lo - pad, hi + pad, 6)
        panel.xticks(xt, tick_labels(xt))
        panel.xlabel(f"error per view ({unit})")
        if k == 0:
            panel.ylabel("views")
        panel.end()
        legend_row(canvas, 80 + 510 * k + 440, 22, entries)
    return canvas.svg()


#: Most views drawn as pictures (the page stays a few MB at most).
MAX_PICTURES = 60


def _pictures(v: Verification) -> str:
    """Each view's image around the target: detected points (green rings) and the points predicted
    from the robot pose through X and Z (red crosses); flagged views framed in red."""
    n = min(len(v.image_paths), MAX_PICTURES)
    if n == 0:
        return ""
    with ThreadPoolExecutor(max_workers=default_jobs()) as pool:  # OpenCV releases the GIL
        srcs = list(pool.map(lambda k: overlay_thumbnail(v.image_paths[k], v.detected[k], v.predicted[k]), range(n)))
    figures = []
    for name, px, src in zip(v.names, v.px, srcs):
        flag = name in v.flagged
        caption = f"{name}: {px:.2f} px" + (" (far off: check this view)" if flag else "")
        img = f'<img class="zoom" tabindex="0" src="{src}" alt="{_e(caption)}">' if src else ""
        cls = ' class="flag"' if flag else ""
        figures.append(f"<figure{cls}>{img}<figcaption>{_e(caption)}</figcaption></figure>")
    more = f'<p class="note">first {n} of {len(v.image_paths)} views shown</p>' if len(v.image_paths) > n else ""
    return ('<section id="predictions"><h2>Where X puts the target</h2><p class="note">Green rings: detected points. '
            "Red crosses: the same points predicted from the robot pose through X and Z. Where they part, the "
            "calibration does not explain that view. Each image is cropped around the target and faded; click one "
            "to enlarge it.</p>"
            f'<div class="thumbs">{"".join(figures)}</div>{more}</section>')


def verification_html(v: Verification) -> str:
    """The verification as one self-contained HTML page."""
    colour = {"good": _COLOURS["good"], "worse than promised": _COLOURS["inconsistent"],
              NOT_THIS: _COLOURS["inconsistent"]}.get(v.verdict, "#555555")
    flags = bool(v.flagged)  # the flag column only when a view is flagged (an empty column puzzles)
    rows = "".join(f'<tr><td class="l">{_e(n)}</td><td>{p:.3f}</td><td>{m:.3f}</td>'
                   + (f'<td class="l">{"far off" if n in v.flagged else ""}</td>' if flags else "") + "</tr>"
                   for n, p, m in zip(v.names, v.px, v.mm))
    skipped = "".join(f"<li>{_e(n)}: {_e(r)}</li>" for n, r in v.skipped)
    return (f"<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>handeye verification</title>"
            f"<style>{_CSS}</style></head><body><h1>Verification on a new capture</h1>"
            f"<p class=\"note\">handeye {_e(__version__)} · result {_e(v.result_path)} · session {_e(v.session_folder)}</p>"
            f'<section id="verdict"><div class="banner" style="background:{colour}"><b>{_e(v.verdict)}</b> — '
            f"{len(v.names)} views predicted from their robot poses: RMS {v.rms_px:.3f} px, {v.rms_mm:.3f} mm at the "
            f"target</div></section>"
            f'<section id="distribution"><h2>Distribution</h2>{_histogram(v)}</section>'
            f'<section id="views"><h2>Per view</h2><table><tr><th class="l">view</th><th>px</th><th>mm at the target</th>'
            + ('<th class="l">flag</th>' if flags else "") + f"</tr>{rows}</table>"
            + (f"<p>Not used: </p><ul>{skipped}</ul>" if skipped else "") + "</section>"
            + _pictures(v) +
            '<section id="advice"><h2>Advice</h2><ul>'
            + "".join(f"<li>{_e(a)}</li>" for a in (v.advice or ["Nothing to fix: the calibration predicts the new "
                                                                  "views as well as it promised."]))
            + "</ul></section></body></html>\n")


def write_verification(v: Verification, out_dir: str | Path, protect: Iterable[Path] = ()) -> list[Path]:
    """Write ``verify.json`` and ``verify.html`` into ``out_dir`` (checked first, never inside the
    session folder), atomically; returns their paths."""
    inputs = [v.session_folder] if v.session_folder is not None else []
    out = check_output_folder(out_dir, inputs)
    paths = [out / "verify.json", out / "verify.html"]
    atomic_write(paths[0], json.dumps(v.as_dict(), indent=2) + "\n", protect)
    atomic_write(paths[1], verification_html(v), protect)
    return paths
