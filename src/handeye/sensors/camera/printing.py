"""Targets to print, true to scale: SVG or PDF (vector), with a ruler to check the print and the
``target:`` block to paste into session.yaml.

Each target type draws itself (:meth:`handeye.sensors.camera.targets.Target.print_shapes`): chessboards and
circle grids as vector shapes from their geometry; ChArUco boards, marker grids and tags from
OpenCV's own image of them (rendered at a resolution where every square, or every marker bit, spans
whole pixels, then turned into rectangles), so that the printed layout is exactly the one OpenCV's
detector expects. This module lays the board out on the paper.

A page holds the board in the top-left corner (10 mm margins), then a 100 mm ruler with
centimetre ticks, the instruction to print at 100 % and the ``target:`` block.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..._shared.io import atomic_write, check_output_folder
from ...errors import HandEyeError
from .targets import Target, target_from_spec

__all__ = ["PAPERS", "Page", "target_page", "write_target", "board_size_mm", "largest_square_mm", "scaled_spec"]

#: Paper sizes (width, height) in millimetres, portrait.
PAPERS = {"A4": (210.0, 297.0), "A3": (297.0, 420.0), "A2": (420.0, 594.0), "letter": (215.9, 279.4),
          "tabloid": (279.4, 431.8)}
MARGIN_MM = 10.0
#: The margin used when the board fits only with less (printers leave 3-5 mm unprinted at the edges).
MIN_MARGIN_MM = 6.0
#: Below the board: the ruler (mm), then lines of text this far apart (mm).
RULER_MM, LINE_MM = 12.0, 3.4


@dataclass(frozen=True)
class Page:
    """A page to print: its size (mm) and its shapes, in millimetres with y down: ``('rect', x, y,
    w, h)``, ``('circle', cx, cy, r)``, ``('line', x1, y1, x2, y2, width)``, ``('text', x, y, size_pt,
    string)``."""

    width: float
    height: float
    shapes: list[tuple]


def board_shapes(target: Target) -> tuple[list[tuple], float, float]:
    """The board's shapes (mm, y down, origin at its top-left) and its width and height (mm): its
    :meth:`Target.print_shapes`."""
    return target.print_shapes()


def board_size_mm(target: Target) -> tuple[float, float]:
    """Width and height of the printed board (mm, quiet zones of circle grids and tags included)."""
    _, w, h = board_shapes(target)
    return w, h


def _paper_size(paper: str | tuple[float, float]) -> tuple[float, float]:
    """Width and height (mm) of a paper named in PAPERS, given as WIDTHxHEIGHT, or as a pair."""
    if isinstance(paper, str):
        if paper in PAPERS:
            w, h = PAPERS[paper]
        else:
            try:
                w, h = (float(v) for v in paper.lower().split("x"))
            except ValueError:
                raise HandEyeError(f"paper {paper!r}: use one of {', '.join(PAPERS)} or WIDTHxHEIGHT in mm") from None
    else:
        w, h = (float(v) for v in paper)
    if not (w > 0 and h > 0):
        raise HandEyeError(f"paper {w:g} x {h:g} mm: give positive sizes")
    return w, h


def _footer_mm(spec: dict[str, Any]) -> float:
    """Height of the ruler and the text block below the board (mm)."""
    lines = len(yaml.safe_dump({"target": spec}, sort_keys=False).splitlines())
    return RULER_MM + LINE_MM * (lines + 2)


def _layout(paper: tuple[float, float], board: tuple[float, float], footer: float) -> tuple[float, float, float] | None:
    """(width, height, margin) of the page that holds the board, the 100 mm ruler and the footer:
    upright or turned, with the wide margin or, when only that fits, the narrow one; None if none fits."""
    for margin in (MARGIN_MM, MIN_MARGIN_MM):
        need = (max(board[0], 100.0) + 2 * margin, board[1] + 2 * margin + footer)
        for w, h in (paper, paper[::-1]):
            if need[0] <= w and need[1] <= h:
                return w, h, margin
    return None


def largest_square_mm(spec: dict[str, Any], paper: str | tuple[float, float] = "A4") -> float:
    """The largest ``square`` (mm, to 0.1 mm) with which the target of ``spec`` fits the paper, the
    other sizes (marker, separation) scaled with it; 0 if not even the ruler fits."""
    size = _paper_size(paper)
    _, bw, bh = board_shapes(target_from_spec(spec))
    per_mm = (bw / (1e3 * float(spec["square"])), bh / (1e3 * float(spec["square"])))  # the board grows with the square
    footer = _footer_mm(spec)

    def fits(square: float) -> bool:  # _layout decides, as for the page itself
        return _layout(size, (per_mm[0] * square, per_mm[1] * square), footer) is not None

    lo, hi = 0.0, max(size) / min(per_mm)  # fits(lo) or nothing fits; hi cannot fit
    if not fits(lo):
        return 0.0
    while hi - lo > 1e-3:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if fits(mid) else (lo, mid)
    return float(np.floor(10 * lo + 1e-9) / 10)


def scaled_spec(spec: dict[str, Any], square_mm: float) -> dict[str, Any]:
    """``spec`` with its square ``square_mm`` and its other lengths (the type's ``size_keys``: marker,
    separation) scaled in proportion."""
    keys = type(target_from_spec(spec)).size_keys
    k = 1e-3 * square_mm / float(spec["square"])
    return {key: (round(float(v) * k, 9) if key in keys else v) for key, v in spec.items()}


def target_page(spec: dict[str, Any], paper: str | tuple[float, float] = "A4") -> Page:
    """The page that prints the target of ``spec`` (a session.yaml ``target:`` mapping), true to scale."""
    target = target_from_spec(spec)
    shapes, bw, bh = board_shapes(target)
    block = ["  " + ln for ln in yaml.safe_dump({"target": spec}, sort_keys=False).splitlines()]
    size = _paper_size(paper)
    layout = _layout(size, (bw, bh), _footer_mm(spec))
    if layout is None:
        fits = largest_square_mm(spec, paper)
        name = paper if isinstance(paper, str) else f"{size[0]:g}x{size[1]:g}"
        hint = (f"the largest square that fits {name} is {fits:.1f} mm (--square-mm {fits:.1f}"
                + (", the other sizes in proportion" if set(spec) & {"marker", "separation"} else "") + ")"
                if fits > 0 else f"{name} cannot hold even the ruler")
        raise HandEyeError(f"the board needs {bw:.0f} x {bh:.0f} mm plus margins, ruler and text, more than the "
                           f"{size[0]:g} x {size[1]:g} mm paper holds either way up: {hint}, or choose a larger paper "
                           "(--paper A3)")
    width, height, margin = layout
    page = [(kind, *(v + margin for v in rest[:2]), *rest[2:]) for kind, *rest in shapes]
    y = margin + bh + 6.0
    ruler = 100.0
    page.append(("line", margin, y, margin + ruler, y, 0.3))
    for cm in range(int(ruler // 10) + 1):
        x = margin + 10.0 * cm
        page.append(("line", x, y - (3.0 if cm % 5 else 5.0), x, y, 0.3))
        page.append(("text", x - 1.0, y + 4.0, 7, str(cm)))
    page.append(("text", margin + ruler + 3.0, y + 1.0, 7, "cm"))
    lines = [f"handeye target: {target.describe()}. Print at 100% (no 'fit to page'): the ruler must measure "
             f"{ruler:.0f} mm.", "For session.yaml (if the print is scaled, measure and correct 'square'):"] + block
    for k, text in enumerate(lines):
        page.append(("text", margin, y + RULER_MM - 2.0 + LINE_MM * k, 7, text))
    return Page(width, height, page)


def _svg(page: Page) -> str:
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{page.width:g}mm" height="{page.height:g}mm" '
           f'viewBox="0 0 {page.width:g} {page.height:g}">', f'<rect width="{page.width:g}" height="{page.height:g}" fill="white"/>']
    # every rectangle in one path: abutting rectangles filled one by one leave anti-aliased seams
    rects = [v for kind, *v in page.shapes if kind == "rect"]
    if rects:
        out.append('<path fill="black" d="' + " ".join(f"M{x:.4f} {y:.4f}h{w:.4f}v{h:.4f}h{-w:.4f}z"
                                                         for x, y, w, h in rects) + '"/>')
    for kind, *v in page.shapes:
        if kind == "rect":
            continue
        if kind == "circle":
            out.append(f'<circle cx="{v[0]:.4f}" cy="{v[1]:.4f}" r="{v[2]:.4f}" fill="black"/>')
        elif kind == "line":
            out.append(f'<line x1="{v[0]:.4f}" y1="{v[1]:.4f}" x2="{v[2]:.4f}" y2="{v[3]:.4f}" stroke="black" '
                       f'stroke-width="{v[4]:g}"/>')
        else:
            text = str(v[3]).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
            out.append(f'<text x="{v[0]:.3f}" y="{v[1]:.3f}" font-family="Helvetica, Arial, sans-serif" '
                       f'font-size="{v[2] * 25.4 / 72:.3f}" xml:space="preserve">{text}</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


def _pdf(page: Page) -> bytes:
    """A one-page PDF (vector; the standard Helvetica font, not embedded)."""
    k = 72.0 / 25.4  # points per millimetre
    H = page.height * k
    ops = ["0 g"]
    # every rectangle in one path, filled once: abutting rectangles filled one by one leave seams
    rects = [f"{v[0] * k:.4f} {H - (v[1] + v[3]) * k:.4f} {v[2] * k:.4f} {v[3] * k:.4f} re"
             for kind, *v in page.shapes if kind == "rect"]
    if rects:
        ops += rects + ["f"]
    for kind, *v in page.shapes:
        if kind == "rect":
            continue
        if kind == "circle":
            cx, cy, r = v[0] * k, H - v[1] * k, v[2] * k
            c = 0.5522847498 * r  # four cubic Beziers
            ops.append(f"{cx + r:.3f} {cy:.3f} m {cx + r:.3f} {cy + c:.3f} {cx + c:.3f} {cy + r:.3f} {cx:.3f} {cy + r:.3f} c "
                       f"{cx - c:.3f} {cy + r:.3f} {cx - r:.3f} {cy + c:.3f} {cx - r:.3f} {cy:.3f} c "
                       f"{cx - r:.3f} {cy - c:.3f} {cx - c:.3f} {cy - r:.3f} {cx:.3f} {cy - r:.3f} c "
                       f"{cx + c:.3f} {cy - r:.3f} {cx + r:.3f} {cy - c:.3f} {cx + r:.3f} {cy:.3f} c f")
        elif kind == "line":
            ops.append(f"{v[4] * k:.3f} w {v[0] * k:.3f} {H - v[1] * k:.3f} m {v[2] * k:.3f} {H - v[3] * k:.3f} l S")
        else:
            text = str(v[3]).encode("latin-1", "replace").decode("latin-1")
            text = text.replace("\\", "\\\\").replace("(", "\\(").replace(")", "\\)")
            ops.append(f"BT /F1 {v[2]} Tf {v[0] * k:.3f} {H - v[1] * k:.3f} Td ({text}) Tj ET")
    content = "\n".join(ops).encode("latin-1")
    objects = [b"<< /Type /Catalog /Pages 2 0 R >>", b"<< /Type /Pages /Kids [3 0 R] /Count 1 >>",
               (f"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 {page.width * k:.3f} {H:.3f}] "
                "/Resources << /Font << /F1 5 0 R >> >> /Contents 4 0 R >>").encode(),
               b"<< /Length " + str(len(content)).encode() + b" >>\nstream\n" + content + b"\nendstream",
               b"<< /Type /Font /Subtype /Type1 /BaseFont /Helvetica /Encoding /WinAnsiEncoding >>"]
    out = bytearray(b"%PDF-1.4\n%\xe2\xe3\xcf\xd3\n")
    offsets = []
    for n, body in enumerate(objects, start=1):
        offsets.append(len(out))
        out += f"{n} 0 obj\n".encode() + body + b"\nendobj\n"
    xref = len(out)
    out += f"xref\n0 {len(objects) + 1}\n0000000000 65535 f \n".encode()
    out += b"".join(f"{o:010d} 00000 n \n".encode() for o in offsets)
    out += f"trailer\n<< /Size {len(objects) + 1} /Root 1 0 R >>\nstartxref\n{xref}\n%%EOF\n".encode()
    return bytes(out)


def write_target(spec: dict[str, Any], out: str | Path, paper: str | tuple[float, float] = "A4") -> Path:
    """Write the printable target of ``spec`` to ``out`` (``.svg`` or ``.pdf``), atomically; returns the path."""
    path = Path(out)
    if path.suffix.lower() not in (".svg", ".pdf"):
        raise HandEyeError(f"{path}: write .svg or .pdf")
    check_output_folder(path.parent if str(path.parent) else ".")
    page = target_page(spec, paper)
    data: str | bytes = _svg(page) if path.suffix.lower() == ".svg" else _pdf(page)
    atomic_write(path, data)
    return path
