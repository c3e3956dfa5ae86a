"""Line-scan camera session folders read and checked (the format in docs/guide.md, "Line-scan cameras").

::

    SESSION/
      session.yaml
      poses.csv        # the robot's trajectory: a time column (its clock), then the pose columns
      images.csv       # image, time: each scan's file in images/ and the time of its row 0 (the camera's clock)
      images/          # the scans: one pushbroom image each (rows in the order exposed)

``session.yaml``::

    setup: eye_in_hand
    linescan:
      width: 2048          # pixels along the line
      line_rate: 1200      # rows per second
      focal: 2470          # the focal length's nominal value (px: the lens's focal length over the pixel pitch); fitted
      noise: 0.2           # optional: the corners' noise (px)
    target: {type: chessboard, cols: 9, rows: 6, square: 0.02}
    poses: {file: poses.csv, format: quat_wxyz, length_unit: mm, angle_unit: deg}
    images: {file: images.csv}

The robot's clock and the camera's may differ by a fraction of a second: the offset is fitted. Nothing
is measured here (:mod:`handeye.pipelines.linescan` does that); every key is checked (an unknown one
is an error naming the nearest known key).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import SessionError
from ..frames.setups import check_setup
from ..sensors.camera.targets import target_from_spec
from ..sensors.linescan.model import LINESCAN_NOISE_PX
from .session import (
    IMAGES_KEYS,
    POSES_KEYS,
    SESSION_FILE,
    check_session_keys,
    flange_poses_of,
    has_section,
    pose_table_path,
    read_image_times,
    read_pose_table,
    read_session_yaml,
    time_unit_scale,
)

__all__ = ["LineScanSession", "load_linescan_session", "is_linescan_session", "LINESCAN_KEYS"]

#: The keys of a ``linescan:`` block.
LINESCAN_KEYS = ("width", "line_rate", "focal", "noise")


@dataclass(frozen=True)
class LineScanSession:
    """A line-scan session's inputs, read and checked (no image read yet)."""

    folder: Path
    setup: str
    target_spec: dict[str, Any]
    names: list[str]  #: per scan: the image's file name
    image_paths: list[Path]
    starts: NDArray[np.float64]  #: per scan: its row 0's time (s, the camera's clock)
    times: NDArray[np.float64]  #: the trajectory's times (s, the robot's clock)
    flange2base: NDArray[np.float64]  #: the trajectory's poses
    width: int
    line_rate: float
    focal: float
    noise_px: float
    notes: list[str] = field(default_factory=list)

    @property
    def input_files(self) -> list[Path]:
        """Every file the session is read from."""
        return [self.folder / SESSION_FILE] + [p for p in self.image_paths if p.is_file()]


def is_linescan_session(folder: str | Path) -> bool:
    """Whether ``folder``'s session.yaml has a ``linescan:`` mapping."""
    return has_section(folder, "linescan")


def _positive(spec: dict, key: str, where: str, what: str) -> float:
    try:
        value = float(spec[key])
    except KeyError:
        raise SessionError(f"{where}: linescan: {key} is missing: {what}") from None
    except (TypeError, ValueError):
        raise SessionError(f"{where}: linescan: {key} {spec[key]!r} is not a number: {what}") from None
    if not value > 0 or not np.isfinite(value):
        raise SessionError(f"{where}: linescan: {key} {value:g}: {what}, a positive number")
    return value


def load_linescan_session(folder: str | Path) -> LineScanSession:
    """Read and check a line-scan session folder (the module docstring); nothing is measured yet.

    Raises :class:`SessionError` naming the file or key: no ``linescan:`` mapping, a missing or bad
    width, line rate or focal length, a bad target, a trajectory without a time column, an image
    missing, a scan whose time lies outside the trajectory.
    """
    folder, spec, where, notes = read_session_yaml(folder)
    if not isinstance(spec.get("linescan"), dict):
        raise SessionError(f"{where}: no linescan: mapping (width, line_rate, focal)")
    check_session_keys(spec, ("setup", "target", "linescan", "poses", "images"),
                       {"linescan": LINESCAN_KEYS, "poses": POSES_KEYS, "images": IMAGES_KEYS}, where)
    setup = check_setup(str(spec.get("setup", "")))
    target_from_spec(spec.get("target"), where=f"{where}: target")
    ls = spec["linescan"]
    width = _positive(ls, "width", where, "the pixels along the line")
    if width != int(width):
        raise SessionError(f"{where}: linescan: width {width:g}: a whole number of pixels")
    line_rate = _positive(ls, "line_rate", where, "the rows per second")
    focal = _positive(ls, "focal", where, "the focal length's nominal value in pixels (the lens's focal length over the "
                                          "pixel pitch, e.g. 16 mm / 7 um = 2286)")
    if focal < 0.05 * width:
        raise SessionError(f"{where}: linescan: focal {focal:g} px for a line of {int(width)} px: give it in pixels (the "
                           "lens's focal length over the pixel pitch), not millimetres")
    noise = float(ls.get("noise", LINESCAN_NOISE_PX))
    if not 0 < noise < 50:
        raise SessionError(f"{where}: linescan: noise {noise:g}: the corners' noise in pixels (e.g. 0.2)")
    poses = spec.get("poses")
    table = pose_table_path(folder, poses, where, "the robot's trajectory, a time column first")
    values, _, times = read_pose_table(table, str(poses["format"]), id_columns=(), notes=notes, times=True)
    if times is None:
        raise SessionError(f"{table}: no time column: a line-scan session's poses are the robot's trajectory, a time "
                           "column (the robot's clock) then the pose columns")
    f2b = flange_poses_of(values, poses, table, where)
    times = np.asarray(times, float) * time_unit_scale(poses, f"{where}: poses")
    names, starts, _ = read_image_times(folder, spec.get("images"), where, notes)
    paths = [folder / "images" / n for n in names]
    missing = [p.name for p in paths if not p.is_file()]
    if missing:
        raise SessionError(f"{folder / 'images'}: scan image(s) missing: {', '.join(missing[:10])}")
    outside = [n for n, t in zip(names, starts) if not times[0] - 1.0 <= t <= times[-1] + 1.0]
    if outside:
        raise SessionError(f"{table}: the trajectory runs {times[0]:.3f}-{times[-1]:.3f} s; the scans "
                           f"{', '.join(outside[:5])} start outside it: give the trajectory around every scan, on a clock "
                           "within a fraction of a second of the camera's (images.csv's time)")
    return LineScanSession(folder, setup, dict(spec["target"]), list(names), paths, np.asarray(starts, float), times, f2b,
                           int(width), line_rate, focal, noise, notes)
