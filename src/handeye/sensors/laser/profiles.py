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
from ...errors import SessionError

__all__ = ["read_profile", "PROFILE_SUFFIXES", "MAX_PROFILE_M"]

PROFILE_SUFFIXES = (".csv", ".npy", ".txt")
#: No laser profiler measures points this far (m) from itself: a profile whose median distance is
#: larger was written in millimetres.
MAX_PROFILE_M = 2.0


def _from_csv(path: Path) -> NDArray[np.float64]:
    text = path.read_text(encoding="utf-8-sig")
    fast = _numbers(text)
    if fast is not None:
        return fast
    rows = [r for r in csv.reader(io.StringIO(text)) if r and not r[0].lstrip().startswith("#")]
    if not rows:
        raise SessionError(f"{path}: empty profile file; expected a header x,z (or x,y,z) and one row per point")
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
        except (ValueError, OSError) as exc:
            raise SessionError(f"{path}: not a readable .npy array ({exc})") from None
        if a.ndim != 2 or a.shape[1] not in (2, 3):
            raise SessionError(f"{path}: a profile is an (n, 2) array of x, z (or (n, 3) of x, y, z); got shape {a.shape}")
        points = np.c_[a[:, 0], np.zeros(len(a)), a[:, 1]] if a.shape[1] == 2 else a.copy()
    else:
        points = _from_csv(path)
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
