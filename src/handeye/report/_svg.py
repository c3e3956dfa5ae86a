"""Figures drawn as inline SVG by a few lines of our own: a report's bars, lines, points and text
need no plotting library (importing matplotlib.figure and drawing PNGs was half of
``calibrate --sample``'s 0.9 s, issue 81).

* :class:`Canvas`: the picture in pixels (lines broken by NaN, rectangles, circles, squares, text),
  written out as one ``<svg>`` element; every text is escaped;
* :class:`Panel`: a 2D axes box in a canvas (data to pixels, ticks, grid, labels, bars);
* :class:`View3D`: an orthographic view of a cube of data at a fixed angle (matplotlib's default
  azimuth -60 deg, elevation 30 deg), with its three back panes, grid, tick and axis labels;
* :func:`legend`, :func:`legend_row`, :func:`colour_bar`, :func:`viridis`, :func:`coolwarm`, :func:`nice_ticks`.

Elements a test counts carry a class: ``bar`` (one rectangle per bar), ``pt`` (one per point),
``panel`` (a 2D axes' group), ``title``.
"""

from __future__ import annotations

import html

import numpy as np
from numpy.typing import NDArray

#: viridis at 0, 1/8, ..., 1 (sRGB): colours between are interpolated, close enough to the original ramp.
_VIRIDIS = np.array([[68, 1, 84], [71, 45, 123], [59, 82, 139], [44, 114, 142], [33, 145, 140], [40, 174, 128],
                     [94, 201, 98], [173, 220, 48], [253, 231, 37]], float)

#: coolwarm (a diverging ramp about its middle, for signed values) at 0, 1/8, ..., 1 (sRGB).
_COOLWARM = np.array([[59, 76, 192], [98, 130, 234], [141, 176, 254], [184, 208, 249], [221, 221, 221], [245, 196, 173],
                      [244, 154, 123], [222, 96, 77], [180, 4, 38]], float)

#: Colours for categories (matplotlib's tab20: pairs of a strong and a light shade; every other one is tab10).
CATEGORY_COLOURS = ("#1f77b4", "#aec7e8", "#ff7f0e", "#ffbb78", "#2ca02c", "#98df8a", "#d62728", "#ff9896", "#9467bd",
                    "#c5b0d5", "#8c564b", "#c49c94", "#e377c2", "#f7b6d2", "#7f7f7f", "#c7c7c7", "#bcbd22", "#dbdb8d",
                    "#17becf", "#9edae5")

#: A character's width as a share of the font size (system sans-serif fonts, for layout and legends).
CHAR_WIDTH = 0.52


def _ramp(table: NDArray[np.float64], values: NDArray[np.float64], vmin: float, vmax: float) -> list[str]:
    t = np.clip((np.asarray(values, float) - vmin) / max(vmax - vmin, 1e-12), 0.0, 1.0)
    t = np.nan_to_num(t) * (len(table) - 1)
    i = np.minimum(t.astype(int), len(table) - 2)
    rgb = table[i] + (t - i)[:, None] * (table[i + 1] - table[i])
    return [f"#{r:02x}{g:02x}{b:02x}" for r, g, b in np.rint(rgb).astype(int)]


def viridis(values: NDArray[np.float64], vmin: float, vmax: float) -> list[str]:
    """Hex colours of ``values`` on a viridis-like ramp from ``vmin`` to ``vmax`` (clipped)."""
    return _ramp(_VIRIDIS, values, vmin, vmax)


def coolwarm(values: NDArray[np.float64], vmin: float, vmax: float) -> list[str]:
    """Hex colours of ``values`` on a coolwarm-like diverging ramp, blue at ``vmin``, grey halfway, red at
    ``vmax`` (clipped)."""
    return _ramp(_COOLWARM, values, vmin, vmax)


def nice_ticks(lo: float, hi: float, n: int = 5) -> NDArray[np.float64]:
    """At most about ``n`` + 1 round tick values (steps of 1, 2, 2.5 or 5 times a power of ten) within [lo, hi]."""
    if not (np.isfinite(lo) and np.isfinite(hi)) or hi <= lo:
        return np.array([lo]) if np.isfinite(lo) else np.zeros(0)
    raw = (hi - lo) / max(n, 1)
    power = 10.0 ** np.floor(np.log10(raw))
    step = next(m * power for m in (1, 2, 2.5, 5, 10) if m * power >= raw)
    ticks = np.arange(np.ceil(lo / step - 1e-9), np.floor(hi / step + 1e-9) + 1) * step
    return np.where(np.abs(ticks) < 1e-12 * step, 0.0, ticks)


def tick_labels(ticks: NDArray[np.float64]) -> list[str]:
    """Tick values as text, with as many decimals as their step needs (an exponent for very large or small
    ones) and a true minus sign."""
    ticks = np.asarray(ticks, float)
    if len(ticks) and (np.abs(ticks).max() >= 1e5 or 0 < np.abs(ticks[ticks != 0]).min(initial=1.0) < 1e-4):
        return [f"{t:.3g}".replace("-", "−") for t in ticks]  # far from 1: short, with an exponent
    step = float(np.min(np.diff(ticks))) if len(ticks) > 1 else abs(float(ticks[0])) if len(ticks) and ticks[0] else 1.0
    digits = int(max(0, -np.floor(np.log10(step) + 1e-9))) + (1 if round(step / 10.0 ** np.floor(np.log10(step)), 6) == 2.5 else 0)
    return [f"{t:.{digits}f}".replace("-", "−") for t in ticks]


def text_width(s: str, size: float) -> float:
    """About how wide ``s`` is drawn at font size ``size`` (pixels)."""
    return CHAR_WIDTH * size * len(s)


def _n(v: float) -> str:
    return f"{v:.1f}".rstrip("0").rstrip(".") if np.isfinite(v) else "0"


def _runs(u: NDArray[np.float64], v: NDArray[np.float64]) -> str:
    """An SVG path's ``d`` through the points (u, v), a new stroke after every NaN."""
    out, pen = [], False
    for a, b in zip(u, v):
        if not (np.isfinite(a) and np.isfinite(b)):
            pen = False
            continue
        out.append(f"{'L' if pen else 'M'}{a:.1f} {b:.1f}")
        pen = True
    return "".join(out)


class Canvas:
    """A picture ``width`` x ``height`` pixels; ``label`` is what a screen reader says of it."""

    def __init__(self, width: float, height: float, label: str):
        self.width, self.height, self.label = width, height, label
        self.parts: list[str] = []

    def add(self, element: str) -> None:
        self.parts.append(element)

    def line(self, x1: float, y1: float, x2: float, y2: float, colour: str, width: float = 1.0, dash: str | None = None) -> None:
        d = f' stroke-dasharray="{dash}"' if dash else ""
        self.add(f'<line x1="{_n(x1)}" y1="{_n(y1)}" x2="{_n(x2)}" y2="{_n(y2)}" stroke="{colour}" stroke-width="{width:g}"{d}/>')

    def path(self, u: NDArray[np.float64], v: NDArray[np.float64], colour: str, width: float = 1.0,
             dash: str | None = None, cls: str | None = None) -> None:
        """A line through the points, broken where a coordinate is NaN."""
        d = _runs(np.asarray(u, float), np.asarray(v, float))
        if d:
            extra = (f' stroke-dasharray="{dash}"' if dash else "") + (f' class="{cls}"' if cls else "")
            self.add(f'<path d="{d}" fill="none" stroke="{colour}" stroke-width="{width:g}" stroke-linejoin="round"{extra}/>')

    def rect(self, x: float, y: float, w: float, h: float, fill: str, stroke: str | None = None, cls: str | None = None,
             tip: str | None = None) -> None:
        s = f' stroke="{stroke}"' if stroke else ""
        c = f' class="{cls}"' if cls else ""
        body = f"<title>{html.escape(tip)}</title></rect>" if tip else "/>"
        self.add(f'<rect x="{_n(x)}" y="{_n(y)}" width="{_n(w)}" height="{_n(h)}" fill="{fill}"{s}{c}' + (">" + body if tip else body))

    def polygon(self, u: NDArray[np.float64], v: NDArray[np.float64], fill: str, stroke: str = "none", width: float = 1.0) -> None:
        pts = " ".join(f"{a:.1f},{b:.1f}" for a, b in zip(u, v))
        self.add(f'<polygon points="{pts}" fill="{fill}" stroke="{stroke}" stroke-width="{width:g}"/>')

    def circle(self, x: float, y: float, r: float, fill: str, stroke: str | None = None, width: float = 0.5,
               cls: str | None = None, dash: str | None = None) -> None:
        s = f' stroke="{stroke}" stroke-width="{width:g}"' if stroke else ""
        s += f' stroke-dasharray="{dash}"' if dash else ""
        c = f' class="{cls}"' if cls else ""
        self.add(f'<circle cx="{_n(x)}" cy="{_n(y)}" r="{r:g}" fill="{fill}"{s}{c}/>')

    def square(self, x: float, y: float, half: float, fill: str, cls: str | None = None) -> None:
        c = f' class="{cls}"' if cls else ""
        self.add(f'<rect x="{_n(x - half)}" y="{_n(y - half)}" width="{2 * half:g}" height="{2 * half:g}" fill="{fill}"{c}/>')

    def text(self, x: float, y: float, s: str, size: float = 12.0, anchor: str = "start", colour: str = "#222",
             rotate: float = 0.0, middle: bool = True, cls: str | None = None) -> None:
        """``s`` at (x, y): ``anchor`` start, middle or end; ``middle``: (x, y) is the text's vertical
        middle, else its baseline; ``rotate`` degrees clockwise about (x, y)."""
        r = f' transform="rotate({rotate:g} {_n(x)} {_n(y)})"' if rotate else ""
        c = f' class="{cls}"' if cls else ""
        dy = ' dy="0.35em"' if middle else ""
        dy += ' style="white-space:pre"' if "  " in s else ""  # runs of spaces kept, as written
        self.add(f'<text x="{_n(x)}" y="{_n(y)}"{dy} font-size="{size:g}" text-anchor="{anchor}" fill="{colour}"{r}{c}>'
                 f"{html.escape(s)}</text>")

    def svg(self) -> str:
        """The picture as one ``<svg>`` element: as wide as the page allows, its height to scale (inline in
        HTML: no namespace needed, and a page without '://' in it fetches nothing)."""
        return (f'<svg class="fig" viewBox="0 0 {_n(self.width)} {_n(self.height)}" '
                f'width="{_n(self.width)}" height="{_n(self.height)}" role="img" aria-label="{html.escape(self.label)}" '
                f'font-family="system-ui,-apple-system,Segoe UI,Roboto,sans-serif">'
                f"<title>{html.escape(self.label)}</title>" + "".join(self.parts) + "</svg>")


class Panel:
    """A 2D axes in ``canvas``: the box (x, y, width, height) in pixels shows ``xlim`` x ``ylim``."""

    def __init__(self, canvas: Canvas, box: tuple[float, float, float, float], xlim: tuple[float, float],
                 ylim: tuple[float, float]):
        self.c, self.box, self.xlim, self.ylim = canvas, box, xlim, ylim
        canvas.add('<g class="panel">')

    def x(self, v):
        x0, _, w, _ = self.box
        return x0 + (np.asarray(v, float) - self.xlim[0]) / (self.xlim[1] - self.xlim[0]) * w

    def y(self, v):
        _, y0, _, h = self.box
        return y0 + h - (np.asarray(v, float) - self.ylim[0]) / (self.ylim[1] - self.ylim[0]) * h

    def frame(self) -> None:
        x0, y0, w, h = self.box
        self.c.add(f'<rect x="{_n(x0)}" y="{_n(y0)}" width="{_n(w)}" height="{_n(h)}" fill="none" stroke="#444" stroke-width="0.8"/>')

    def yticks(self, ticks: NDArray[np.float64], grid: bool = True, size: float = 11) -> None:
        x0, _, w, _ = self.box
        for t, s in zip(ticks, tick_labels(ticks)):
            y = float(self.y(t))
            if grid:
                self.c.line(x0, y, x0 + w, y, "#e3e3e3", 0.8)
            self.c.line(x0 - 4, y, x0, y, "#444", 0.8)
            self.c.text(x0 - 7, y, s, size, "end")

    def xticks(self, positions, labels: list[str], size: float = 11, rotate: bool = False) -> None:
        _, y0, _, h = self.box
        for p, s in zip(positions, labels):
            x = float(self.x(p))
            self.c.line(x, y0 + h, x, y0 + h + 4, "#444", 0.8)
            if rotate:
                self.c.text(x, y0 + h + 7, s, size, "end", rotate=-90)
            else:
                self.c.text(x, y0 + h + 14, s, size, "middle")

    def bars(self, x, values, colour: str, width: float = 0.8, tips: list[str] | None = None) -> None:
        """One rectangle (class ``bar``) per value from 0; a NaN's is empty. ``tips``: each bar's hover text."""
        zero = float(self.y(0.0))
        for k, (xi, v) in enumerate(zip(x, values)):
            v = float(v) if np.isfinite(v) else 0.0
            left, right = float(self.x(xi - width / 2)), float(self.x(xi + width / 2))
            top = float(self.y(v))
            self.c.rect(left, min(top, zero), right - left, abs(zero - top), colour, cls="bar", tip=tips[k] if tips else None)

    def stems(self, x, values, colour: str) -> None:
        """A vertical line from 0 per value, all in one path (for hundreds of values)."""
        xs, vs = np.asarray(x, float), np.nan_to_num(np.asarray(values, float))
        u = np.repeat(self.x(xs), 3)
        v = np.stack([np.full(len(xs), float(self.y(0.0))), self.y(vs), np.full(len(xs), np.nan)], axis=1).ravel()
        u[2::3] = np.nan
        self.c.path(u, v, colour, 1.0)

    def ylabel(self, s: str, size: float = 12) -> None:
        x0, y0, _, h = self.box
        self.c.text(x0 - 52, y0 + h / 2, s, size, "middle", rotate=-90)

    def xlabel(self, s: str, offset: float = 34, size: float = 12) -> None:
        x0, y0, w, h = self.box
        self.c.text(x0 + w / 2, y0 + h + offset, s, size, "middle")

    def title(self, s: str, size: float = 13) -> None:
        x0, y0, w, _ = self.box
        self.c.text(x0 + w / 2, y0 - 10, s, size, "middle", middle=False, cls="title")

    def end(self) -> None:
        self.c.add("</g>")


class View3D:
    """An orthographic view of the cube [lo, hi] (per axis) in ``box`` (x, y, width, height) of ``canvas``,
    seen from ``azim`` / ``elev`` degrees (matplotlib's default view), the cube's edges equal on screen."""

    def __init__(self, canvas: Canvas, box: tuple[float, float, float, float], lo: NDArray[np.float64],
                 hi: NDArray[np.float64], azim: float = -60.0, elev: float = 30.0):
        self.c, self.box = canvas, box
        self.lo, self.hi = np.asarray(lo, float), np.asarray(hi, float)
        a, e = np.radians(azim), np.radians(elev)
        self.towards = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])  # to the viewer
        self.right = np.array([-np.sin(a), np.cos(a), 0.0])
        self.up = np.cross(self.towards, self.right)
        x0, y0, w, h = box
        reach_u, reach_v = np.abs(self.right).sum(), np.abs(self.up).sum()  # the unit cube's half extent on screen
        self.scale = min(w / (2 * reach_u), h / (2 * reach_v))
        self.centre = (x0 + w / 2, y0 + h / 2)

    def _unit(self, P: NDArray[np.float64]) -> NDArray[np.float64]:
        return 2 * (np.asarray(P, float).reshape(-1, 3) - self.lo) / (self.hi - self.lo) - 1

    def project(self, P: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Pixels (u, v) of points ``P`` (n, 3); NaN stays NaN."""
        q = self._unit(P)
        return self.centre[0] + self.scale * q @ self.right, self.centre[1] - self.scale * q @ self.up

    def depth(self, P: NDArray[np.float64]) -> NDArray[np.float64]:
        """Towards the viewer: larger is nearer."""
        return self._unit(P) @ self.towards

    def _corner(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.lo + (np.asarray(q, float) + 1) / 2 * (self.hi - self.lo)

    def axes(self, labels: tuple[str, str, str], ticks: list[NDArray[np.float64]], size: float = 11) -> None:
        """The three back panes (grey, a grid line at each tick), and each axis's tick labels and label
        along a front edge of the floor (x, y) or the left upright edge (z)."""
        back = -np.sign(self.towards)
        back[back == 0] = -1
        for k in range(3):  # the pane at the back of axis k: spanned by the other two
            i, j = [m for m in range(3) if m != k]
            q = np.zeros((4, 3))
            q[:, k] = back[k]
            q[:, i] = [-1, 1, 1, -1]
            q[:, j] = [-1, -1, 1, 1]
            u, v = self.project(self._corner(q))
            self.c.polygon(u, v, "#f3f3f3", "#c8c8c8", 0.8)
            for m, n in ((i, j), (j, i)):  # grid lines at axis m's ticks, running along n
                for t in ticks[m]:
                    ends = np.zeros((2, 3))
                    ends[:, k] = back[k]
                    ends[:, n] = [-1, 1]
                    P = self._corner(ends)
                    P[:, m] = t
                    u, v = self.project(P)
                    self.c.line(u[0], v[0], u[1], v[1], "#dcdcdc", 0.7)
        front = np.sign(self.towards)
        front[front == 0] = 1
        edges = {0: np.array([0.0, front[1], -1.0]), 1: np.array([front[0], 0.0, -1.0]),
                 2: np.array([-np.sign(self.right[0]) or -1.0, -np.sign(self.right[1]) or -1.0, 0.0])}
        for k, mid in edges.items():
            a, b = mid.copy(), mid.copy()
            a[k], b[k] = -1, 1
            u, v = self.project(self._corner(np.vstack([a, b])))
            self.c.line(u[0], v[0], u[1], v[1], "#888", 0.8)
            mu, mv = self.project(self._corner(mid))
            out = np.array([mu[0] - self.centre[0], mv[0] - self.centre[1]])
            out /= np.linalg.norm(out) or 1.0
            anchor = "end" if out[0] < -0.5 else "start" if out[0] > 0.5 else "middle"
            for t, s in zip(ticks[k], tick_labels(ticks[k])):
                P = self._corner(mid)[None]
                P[0, k] = t
                tu, tv = self.project(P)
                self.c.text(tu[0] + 12 * out[0], tv[0] + 12 * out[1], s, size, anchor)
            far = 12 + text_width(max(tick_labels(ticks[k]) or [""], key=len), size) * abs(out[0]) + 18
            self.c.text(mu[0] + far * out[0], mv[0] + max(far * out[1], 0 if k == 2 else 28), labels[k], size + 1,
                        anchor if k == 2 else "middle")

    def lines(self, P: NDArray[np.float64], colour: str, width: float = 1.0, dash: str | None = None) -> None:
        """A line through ``P`` (n, 3), broken at NaN rows."""
        u, v = self.project(P)
        self.c.path(u, v, colour, width, dash)

    def points(self, P: NDArray[np.float64], colours: str | list[str], radius: float = 3.0, square: bool = False,
               stroke: str | None = None) -> None:
        """A dot (class ``pt``) per point, the far ones drawn first."""
        P = np.asarray(P, float).reshape(-1, 3)
        colours = [colours] * len(P) if isinstance(colours, str) else colours
        u, v = self.project(P)
        for k in np.argsort(self.depth(P), kind="stable"):
            if square:
                self.c.square(u[k], v[k], radius, colours[k], cls="pt")
            else:
                self.c.circle(u[k], v[k], radius, colours[k], stroke, 0.4, cls="pt")

    def text(self, P: NDArray[np.float64], s: str, size: float = 11) -> None:
        u, v = self.project(P)
        self.c.text(u[0] + 4, v[0], s, size)


#: The x, y and z axes' colours of a frame's triad.
AXIS_COLOURS = ("#d62728", "#2ca02c", "#1f77b4")


def triads(view: View3D, T: NDArray[np.float64], length: float, width: float = 1.5) -> None:
    """The x, y, z axes (red, green, blue) of one frame ``(4, 4)`` or many ``(N, 4, 4)``: a path per colour."""
    T = np.asarray(T, float).reshape(-1, 4, 4)
    o = T[:, :3, 3]
    for k, colour in enumerate(AXIS_COLOURS):
        seg = np.stack([o, o + length * T[:, :3, k], np.full_like(o, np.nan)], axis=1).reshape(-1, 3)
        view.lines(seg, colour, width)


def legend(canvas: Canvas, x: float, y: float, entries: list[tuple[str, str, str]], size: float = 11) -> None:
    """A framed legend with its top left at (x, y): each entry (kind, colour, text), kind ``line``
    (a line with a dot), ``dot`` or ``square``."""
    row = size + 8
    width = 40 + max(text_width(t, size) for _, _, t in entries)
    canvas.rect(x, y, width, row * len(entries) + 8, "#ffffff", "#cccccc")
    for k, (kind, colour, text) in enumerate(entries):
        cy = y + 4 + row * (k + 0.5)
        if kind == "line":
            canvas.line(x + 8, cy, x + 28, cy, colour, 1.0)
            canvas.circle(x + 18, cy, 2.5, colour)
        elif kind == "square":
            canvas.square(x + 18, cy, 3.5, colour)
        else:
            canvas.circle(x + 18, cy, 3.5, colour)
        canvas.text(x + 34, cy, text, size)


def legend_row(canvas: Canvas, right: float, y: float, entries: list[tuple[str, str]], size: float = 11) -> None:
    """A legend in one row ending at ``right``, centred on height ``y``: each entry (colour, text) a square and its text."""
    x = right - sum(32 + text_width(t, size) for _, t in entries) + 14
    for colour, text in entries:
        canvas.square(x + 5, y, 5, colour)
        canvas.text(x + 15, y, text, size)
        x += 32 + text_width(text, size)


def colour_bar(canvas: Canvas, box: tuple[float, float, float, float], vmin: float, vmax: float, label: str,
               size: float = 11, ramp=viridis) -> None:
    """A vertical bar of ``ramp`` (:func:`viridis`, :func:`coolwarm`) from ``vmin`` (bottom) to ``vmax``, with
    ticks and ``label`` beside it."""
    x0, y0, w, h = box
    steps = 48
    colours = ramp(np.linspace(vmin, vmax, steps), vmin, vmax)
    for k, colour in enumerate(colours):  # slightly overlapping bands: no seams between them
        canvas.rect(x0, y0 + h - (k + 1) * h / steps, w, h / steps + 0.6, colour)
    canvas.rect(x0, y0, w, h, "none", "#444")
    ticks = nice_ticks(vmin, vmax, 5)
    for t, s in zip(ticks, tick_labels(ticks)):
        y = y0 + h - (t - vmin) / (vmax - vmin) * h
        canvas.line(x0 + w, y, x0 + w + 4, y, "#444", 0.8)
        canvas.text(x0 + w + 7, y, s, size)
    canvas.text(x0 + w + 26 + text_width(max(tick_labels(ticks), key=len), size), y0 + h / 2, label, size, "middle", rotate=-90)
