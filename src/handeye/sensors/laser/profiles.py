"""A laser profile read from its file and checked: points in the sensor's laser plane, metres.

A profile file holds the points of one profile in the sensor's frame: ``x`` along the laser line,
``z`` along its measuring axis, ``y = 0`` the laser plane. ``.csv`` with a header ``x,z`` (or
``x,y,z`` with y = 0), an empty cell or ``nan`` where there is no return; ``.npy`` of shape
(n, 2) or (n, 3). :func:`read_profile` gives (n, 3) metres with NaN rows for missing returns and
refuses, naming the file: a y that is not 0, millimetres given as metres, a file it cannot read.
"""

from __future__ import annotations

import csv
import io
import warnings
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..._shared.text import cut, shown
from ...errors import SessionError, UnusableViewError

__all__ = ["read_profile", "check_range", "check_shape", "PROFILE_SUFFIXES", "MAX_PROFILE_M", "MAX_PROFILE_POINTS"]

PROFILE_SUFFIXES = (".csv", ".npy", ".txt")
#: No laser profiler measures points this far (m) from itself: a profile whose median distance is
#: larger was written in millimetres.
MAX_PROFILE_M = 2.0
#: A laser line gives a few thousand points (profilers: 640 to 8,192 across the line); a file with more
#: than this is not one profile (a scan of many, a cloud), and would outweigh every other view in a fit.
MAX_PROFILE_POINTS = 65_536


def _text(path: Path) -> str:
    """A profile file's text: numbers and a header, so UTF-8 (a byte-order mark allowed); a binary or
    corrupt file (NUL bytes, bytes no text has) is an :class:`UnusableViewError`, not a traceback."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise SessionError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if b"\x00" in data:
        raise UnusableViewError(f"{path}: not a text profile (a NUL byte at byte {data.index(0)}): a binary or corrupt file")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise UnusableViewError(f"{path}: not a text profile (byte 0x{data[exc.start]:02x} at byte {exc.start} is not "
                                "UTF-8): a binary or corrupt file") from None


def _from_csv(path: Path) -> NDArray[np.float64]:
    text = _text(path)
    fast = _numbers(text)
    if fast is not None:
        return fast
    rows = [r for r in csv.reader(io.StringIO(text)) if r and not r[0].lstrip().startswith("#")]
    if not rows:
        raise UnusableViewError(f"{path}: empty profile file; expected a header x,z (or x,y,z) and one row per point")
    header = [c.strip().lower() for c in rows[0]]
    if header not in (["x", "z"], ["x", "y", "z"]):
        raise SessionError(f"{path}: header {cut(str(rows[0]), 300)} : give x,z (or x,y,z), the points in the sensor's laser plane")
    values = np.full((len(rows) - 1, 3), np.nan)
    cols = [0, 2] if len(header) == 2 else [0, 1, 2]
    for k, row in enumerate(rows[1:]):
        if len(row) != len(header):
            raise SessionError(f"{path}: line {k + 2} has {len(row)} values; the header has {len(header)}")
        for c, cell in zip(cols, row):
            cell = cell.strip()
            try:
                values[k, c] = float(cell) if cell and cell.lower() != "nan" else np.nan
            except ValueError:
                raise SessionError(f"{path}: line {k + 2}: {shown(cell)} is not a number") from None
        if len(header) == 2:
            values[k, 1] = 0.0
    return values


def _numbers(text: str) -> NDArray[np.float64] | None:
    """A plain ``x,z`` / ``x,y,z`` file (a header, then numbers or empty cells, nothing else) read
    by numpy's own parser; None for anything else (the careful reader says what is wrong)."""
    head, _, body = text.partition("\n")
    header = [c.strip().lower() for c in head.split(",")]
    if header not in (["x", "z"], ["x", "y", "z"]) or "#" in body:
        return None
    body = body.replace("\r\n", "\n").replace(" ", "").replace("\t", "").strip()  # empty cells: nan (string work in C)
    body = body.replace(",,", ",nan,").replace(",\n", ",nan\n").replace("\n,", "\nnan,")
    body = ("nan" if body.startswith(",") else "") + body + ("nan" if body.endswith(",") else "")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # an empty file: numpy warns, the careful reader says what is wrong
            values = np.loadtxt(io.StringIO(body), delimiter=",", ndmin=2)
    except ValueError:
        return None
    if values.shape[1] != len(header) or not len(values):
        return None
    return np.c_[values[:, 0], np.zeros(len(values)), values[:, 1]] if len(header) == 2 else values


def check_range(profiles: list[NDArray[np.float64]], working_range: tuple[float, float], unit: str, where: str) -> None:
    """Refuse profiles (metres, as :func:`read_profile` gives them) whose points lie mostly outside
    the stated measuring range ``working_range`` (near, far along z, metres): not a few points
    beyond it (left out by the caller) but the session's reading of the files. When their x lies
    in the range instead, the x and z columns are swapped, which no fit would notice: a profile's
    points lie in the laser plane (y = 0), where swapping x and z is a half turn of the sensor's
    frame, so the fit is as good and X half a turn off. ``where``: the profiles' folder."""
    points = np.concatenate([p[np.isfinite(p).all(axis=1)] for p in profiles]) if profiles else np.zeros((0, 3))
    if not len(points):
        return
    lo, hi = working_range
    inside_z = float(np.mean((points[:, 2] >= lo) & (points[:, 2] <= hi)))
    if inside_z >= 0.5:
        return
    f = 1e3 if unit == "mm" else 1.0
    z = np.percentile(points[:, 2], [5, 95]) * f
    x = np.percentile(points[:, 0], [5, 95]) * f
    shown_range = f"[{lo * f:g}, {hi * f:g}] {unit}"
    if float(np.mean((points[:, 0] >= lo) & (points[:, 0] <= hi))) >= 0.5:
        raise SessionError(f"{where}: the profiles' z lies at {z[0]:.4g} to {z[1]:.4g} {unit}, outside the stated range "
                           f"{shown_range} for {100 * (1 - inside_z):.0f}% of the points, and their x within it: the x "
                           "and z columns are swapped; write each point as x (along the laser line), then z (the distance "
                           "along the sensor's axis)")
    raise SessionError(f"{where}: {100 * (1 - inside_z):.0f}% of the profiles' points lie outside the stated range "
                       f"{shown_range} (z {z[0]:.4g} to {z[1]:.4g} {unit}, x {x[0]:.4g} to {x[1]:.4g} {unit}): check the "
                       "range: under laser: (the sensor's measuring range along z) and the unit")


def _robust_rms(r: NDArray[np.float64]) -> float:
    """The RMS of residuals ``r`` from their median absolute value (a few spikes do not move it)."""
    return float(1.4826 * np.median(np.abs(r)))


def _line_and_arc(points: NDArray[np.float64]) -> tuple[float, float, float]:
    """One profile's fit (m) to a straight line and to a circle's arc in the laser plane (robust
    RMS of each), and the arc's radius (m; inf when the points are a line)."""
    xz = points[np.isfinite(points).all(axis=1)][:, [0, 2]]
    centred = xz - xz.mean(axis=0)
    line = _robust_rms(centred @ np.linalg.svd(centred, full_matrices=False)[2][-1])
    A = np.c_[centred, np.ones(len(xz))]  # x^2 + z^2 + D x + E z + F = 0 (Kasa), about the centroid
    (d, e, f), *_ = np.linalg.lstsq(A, -np.sum(centred**2, axis=1), rcond=None)
    r2 = (d * d + e * e) / 4 - f
    if not np.isfinite(r2) or r2 <= 0:
        return line, np.inf, np.inf
    r = float(np.sqrt(r2))
    return line, _robust_rms(np.hypot(centred[:, 0] + d / 2, centred[:, 1] + e / 2) - r), r


def check_shape(profiles: list[NDArray[np.float64]], target: str, noise_m: float, where: str) -> None:
    """Refuse profiles of another target than the one declared, before any fit: arcs where a
    plate's straight lines are declared (the target is a ball), straight lines only where a
    ball's arcs are (the target is a plate). A fit on the wrong shape fails with no word of it
    (the profiles "do not determine" the sensor's rotation). ``where``: the profiles' folder."""
    if target not in ("plane", "sphere", "spheres") or not profiles:
        return
    tol = max(5.0 * noise_m, 5e-5)  # straight or round to a few times the noise
    fits = [_line_and_arc(p) for p in profiles if int(np.isfinite(p).all(axis=1).sum()) >= 10]
    if not fits:
        return
    lines = [f for f in fits if f[0] <= tol]
    arcs = [f for f in fits if f[0] > tol and f[1] <= tol and f[2] < 1.0]
    if target == "plane" and len(arcs) >= 0.5 * len(fits):
        r = float(np.median([f[2] for f in arcs]))
        raise SessionError(f"{where}: {len(arcs)} of {len(fits)} profiles are arcs of circles (radius {1e3 * r:.1f} mm "
                           f"median, {1e3 * float(np.median([f[0] for f in arcs])):.2f} mm RMS off a straight line), not the "
                           "straight lines a plate gives: the target is a ball; write target: {type: sphere, diameter: ...} "
                           "(metres; it is estimated when left out)")
    if target in ("sphere", "spheres") and len(lines) >= 0.9 * len(fits):
        raise SessionError(f"{where}: no profile is an arc: {len(lines)} of {len(fits)} are straight lines (to "
                           f"{1e3 * float(np.median([f[0] for f in lines])):.3f} mm RMS, the noise "
                           f"{1e3 * noise_m:g} mm), as a plate gives, and a ball's profiles are arcs: the target is a "
                           "plate; write target: {type: plane} (an edge or a step: type: edge or step)")


def read_profile(path: str | Path, unit: str = "m") -> NDArray[np.float64]:
    """The profile in ``path`` as (n, 3) points in metres (``unit``: the file's, m or mm), NaN rows
    where there is no return.

    Raises
    ------
    SessionError
        The file is missing or unreadable; a y that is not 0 (the points are not in the laser plane:
        another frame); a median distance beyond :data:`MAX_PROFILE_M` (millimetres given as metres).
    """
    path = Path(path)
    if not path.is_file():
        raise SessionError(f"{path}: no such profile file")
    if path.suffix.lower() == ".npy":
        try:
            a = np.asarray(np.load(path, allow_pickle=False), dtype=float)
        except (ValueError, OSError, EOFError) as exc:
            raise UnusableViewError(f"{path}: not a readable .npy array ({cut(str(exc), 200)})") from None
        if a.ndim != 2 or a.shape[1] not in (2, 3):
            raise UnusableViewError(f"{path}: a profile is an (n, 2) array of x, z (or (n, 3) of x, y, z); got shape {a.shape}")
        points = np.c_[a[:, 0], np.zeros(len(a)), a[:, 1]] if a.shape[1] == 2 else a.copy()
    else:
        points = _from_csv(path)
    if len(points) > MAX_PROFILE_POINTS:
        raise UnusableViewError(f"{path}: {len(points):,} points, and a profile is one laser line's: a few thousand "
                                "(8,192 on the widest profilers): this file is a scan of many profiles, or another file")
    f = 1e-3 if unit == "mm" else 1.0
    points = points * f
    finite = np.isfinite(points).all(axis=1)
    points[~finite] = np.nan
    y = np.abs(points[finite, 1])
    if y.size and y.max() > 1e-9:
        raise SessionError(f"{path}: y up to {y.max() / f:g} {unit}: a profile's points lie in the laser plane (y = 0 in "
                           "the sensor's frame); give x and z in the sensor's own frame")
    if finite.any() and np.median(np.linalg.norm(points[finite], axis=1)) > MAX_PROFILE_M:
        raise SessionError(f"{path}: the points lie a median {np.median(np.linalg.norm(points[finite], axis=1)):.0f} m from "
                           f"the sensor: they look like millimetres; write unit: mm under laser: in session.yaml")
    return points
