"""Captures on disk, in both directions: reading and writing sessions and pose tables.

*Capture sessions* (DESIGN §4): ``session.yaml``, ``poses.csv`` (an ``image`` column, then the
pose columns of the declared format) and ``images/``. See :func:`load_session`.

*Pose-pair folders*, for users who already have camera-to-target poses (from their own
detector, or a ViSP/ROS export). A pose-pair folder holds ``posepairs.yaml``::

    setup: eye_in_hand              # eye_in_hand | eye_to_hand
    robot_poses:                    # flange2base as the controller reports it
      file: robot_poses.csv
      format: euler:ZYX             # matrix | quat_wxyz | quat_xyzw | rotvec | euler:<sequence>
      length_unit: mm               # m | mm
      angle_unit: deg               # deg | rad (rotvec and euler)
    camera_poses:                   # target2cam, i.e. solvePnP's rvec/tvec
      file: target2cam.csv
      format: rotvec
      length_unit: m
      angle_unit: rad

Each CSV has a header row naming the pose columns (see :func:`handeye.poses.pose_columns`),
optionally preceded by an ``id`` (or ``image``) column. With ids in both files, rows pair by id;
otherwise by order.
"""

from __future__ import annotations

import csv
import io
import unicodedata
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

import numpy as np
import yaml
from numpy.typing import NDArray

from ._shared.io import atomic_write, read_text
from .errors import HandEyeError, InputMismatchError, PoseFormatError
from .poses import RobotPoseInput, format_poses, parse_poses, pose_columns
from .setups import check_setup
from .vision.targets import target_from_spec

__all__ = ["PosePairs", "Session", "load_pose_pairs", "load_session", "read_pose_table", "SessionError", "load_yaml",
           "read_camera", "read_intrinsics", "write_pose_table", "write_session", "SESSION_FILE", "POSEPAIRS_FILE"]

POSEPAIRS_FILE = "posepairs.yaml"
SESSION_FILE = "session.yaml"
ID_COLUMNS = ("id", "image")
IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".webp"}


class SessionError(HandEyeError):
    """A capture folder that cannot be read: missing files or keys, malformed tables."""


@dataclass(frozen=True)
class PosePairs:
    """Robot and camera poses read from a pose-pair folder, paired row by row."""

    setup: str
    flange2base: NDArray[np.float64]
    target2cam: NDArray[np.float64]
    ids: list[str]
    source: Path
    robot_input: RobotPoseInput | None = None  #: the robot poses as written (for the convention check)
    notes: list[str] = field(default_factory=list)  #: how the files were read, when not as plain UTF-8 CSV
    camera_input: RobotPoseInput | None = None  #: the camera poses as written (for the convention check)


@dataclass(frozen=True)
class Session:
    """A capture session read from disk (DESIGN §4), validated."""

    folder: Path
    setup: str
    target_spec: dict[str, Any]
    flange2base: NDArray[np.float64]  #: (N, 4, 4), metres
    image_names: list[str]
    image_paths: list[Path]
    camera_matrix: NDArray[np.float64] | None  #: K, or None to estimate from the images
    dist_coeffs: NDArray[np.float64] | None
    pose_format: str
    robot_input: RobotPoseInput | None = None  #: the robot poses as written (for the convention check)
    poses_path: Path | None = None  #: the pose table file
    notes: list[str] = field(default_factory=list)  #: how the files were read, when not as plain UTF-8 CSV

    @property
    def input_files(self) -> list[Path]:
        """Every file the session is read from: session.yaml, the pose table, the images."""
        return [self.folder / SESSION_FILE] + ([self.poses_path] if self.poses_path else []) + list(self.image_paths)


def read_camera(spec: Any, where: str) -> tuple[NDArray[np.float64] | None, NDArray[np.float64] | None]:
    """``K`` and ``dist`` from a ``camera:`` mapping (``(None, None)`` when absent), validated;
    errors name ``where``."""
    if spec is None:
        return None, None
    if not isinstance(spec, dict):
        raise SessionError(f"{where}: camera must be a mapping with K (3x3) and dist")
    try:
        K = np.asarray(_require(spec, "K", f"{where}: camera"), dtype=float)
        dist = np.asarray(spec.get("dist", [0.0] * 5), dtype=float).ravel()
    except (TypeError, ValueError):
        raise SessionError(f"{where}: camera K and dist must be numbers") from None
    if K.shape != (3, 3) or not np.isfinite(K).all() or K[0, 0] <= 0 or K[1, 1] <= 0 or np.any(K[2] != [0, 0, 1]):
        raise SessionError(f"{where}: camera K must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0; got {K.tolist()}")
    if len(dist) not in (4, 5, 8, 12, 14) or not np.isfinite(dist).all():
        raise SessionError(f"{where}: camera dist must hold 4, 5, 8, 12 or 14 OpenCV coefficients, got {len(dist)}")
    return K, dist


def load_session(folder: str | Path) -> Session:
    """Load and validate a capture session folder (DESIGN §4).

    Raises
    ------
    SessionError
        Missing folder, session.yaml, key, poses file or image; duplicate image names; images in
        ``images/`` that no pose row names (a pose count that differs from the image count).
    PoseFormatError, InputMismatchError, TargetError
        Bad pose values, unknown setup, unusable target description.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise SessionError(f"{folder}: no such session folder")
    yml = folder / SESSION_FILE
    notes: list[str] = []
    spec = load_yaml(yml, notes)
    where = str(yml)
    setup = check_setup(str(_require(spec, "setup", where)))
    target_spec = _require(spec, "target", where)
    target_from_spec(target_spec, where=f"{where}: target")  # a bad target fails now, before any image work
    K, dist = read_camera(spec.get("camera"), where)
    poses = _require(spec, "poses", where)
    if not isinstance(poses, dict):
        raise SessionError(f"{where}: poses must be a mapping with file, format, length_unit, angle_unit")
    csv_path = folder / str(_require(poses, "file", f"{where}: poses"))
    fmt = str(_require(poses, "format", f"{where}: poses"))
    length_unit = str(_require(poses, "length_unit", f"{where}: poses"))
    angle_unit = str(poses.get("angle_unit", "rad"))
    f2b, names, values = _read_pose_file(csv_path, fmt, length_unit, angle_unit, id_columns=("image",), notes=notes)
    if names is None:
        raise SessionError(f"{csv_path}: the first column must be 'image', naming each pose's image in images/")
    image_dir = folder / "images"
    if not image_dir.is_dir():
        raise SessionError(f"{image_dir}: no images folder; the images named in {csv_path.name} go there")
    all_files = sorted(p.name for p in image_dir.iterdir() if p.is_file())
    on_disk = [n for n in all_files if Path(n).suffix.lower() in IMAGE_SUFFIXES]
    files = _match_image_names(names, all_files, notes)  # a row may name an image of any suffix
    missing = [n for n, f in zip(names, files) if f is None]
    if missing:
        raise SessionError(f"{image_dir}: image file(s) missing: {', '.join(missing[:10])}"
                           + (f" and {len(missing) - 10} more" if len(missing) > 10 else ""))
    paths = [image_dir / f for f in files]
    unnamed = sorted(set(on_disk) - set(files))
    if unnamed:
        raise SessionError(
            f"{csv_path.name} has {len(names)} poses but images/ holds {len(on_disk)} images; no pose for "
            f"{', '.join(unnamed[:10])}: add their poses or move them out of images/"
        )
    return Session(folder, setup, dict(target_spec), f2b, list(names), paths, K, dist, fmt,
                   RobotPoseInput(values, fmt, length_unit, angle_unit), csv_path, notes)


def _match_image_names(names: list[str], on_disk: list[str], notes: list[str]) -> list[str | None]:
    """The file in ``images/`` each pose row names: the same name, else the same name once
    Unicode-normalised (macOS writes decomposed accents) or, when unique, once lower-cased (a
    session made on Windows); None when there is none."""
    disk = set(on_disk)
    by_nfc = {unicodedata.normalize("NFC", n): n for n in on_disk}
    by_lower: dict[str, list[str]] = {}
    for n in on_disk:
        by_lower.setdefault(unicodedata.normalize("NFC", n).lower(), []).append(n)
    out, loose = [], []
    for name in names:
        key = unicodedata.normalize("NFC", name)
        if name in disk:
            out.append(name)
        elif key in by_nfc:
            out.append(by_nfc[key])
        elif len(by_lower.get(key.lower(), [])) == 1:
            out.append(by_lower[key.lower()][0])
            loose.append(f"{name} -> {out[-1]}")
        else:
            out.append(None)
    if loose:
        notes.append(f"image names matched without regard to case: {', '.join(loose[:5])}"
                     + (f" and {len(loose) - 5} more" if len(loose) > 5 else ""))
    return out


def load_yaml(path: Path, notes: list[str] | None = None) -> dict[str, Any]:
    """A YAML mapping from ``path`` (any encoding :func:`handeye._shared.io.read_text` reads; how
    it was read goes into ``notes``); one-line errors that name the file and the position."""
    path = Path(path)
    if not path.is_file():
        raise SessionError(f"{path}: " + ("is a folder, not a file" if path.is_dir() else "file not found"))
    text, note = read_text(path)
    if note and notes is not None:
        notes.append(note)
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:  # one line: the problem and where
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise SessionError(f"{path}: not valid YAML ({problem}{at})") from None
    if data is None:
        raise SessionError(f"{path}: empty file; expected a mapping of keys (see the README)")
    if not isinstance(data, dict):
        raise SessionError(f"{path}: expected a mapping of keys, got {type(data).__name__}")
    return data


def _require(mapping: dict[str, Any], key: str, where: str) -> Any:
    if key not in mapping or mapping[key] is None:
        raise SessionError(f"{where}: missing key '{key}'")
    return mapping[key]


def _delimiter(text: str) -> str:
    """The value separator of a pose table, from its header line: ',' unless the header has none
    and ';' (a spreadsheet in a locale with decimal commas), a tab or spaces separate it."""
    header = next((line for line in text.splitlines() if line.strip()), "")
    if "," in header:
        return ","
    for d in (";", "\t"):
        if d in header:
            return d
    return " " if len(header.split()) > 1 else ","


def read_pose_table(
    path: Path, fmt: str, id_columns: tuple[str, ...] = ID_COLUMNS, notes: list[str] | None = None
) -> tuple[NDArray[np.float64], list[str] | None]:
    """Read a CSV of poses with a header row; returns the pose values and the ids (or None).

    Any encoding :func:`handeye._shared.io.read_text` reads; values separated by ',' or (a
    header without commas) by ';' with decimal commas, tabs or spaces; header names in any case.
    How the file was read, when not plain UTF-8 CSV, goes into ``notes``. Raises
    :class:`SessionError` naming the file, line and column of anything malformed.
    """
    if not path.is_file():
        raise SessionError(f"{path}: " + ("is a folder, not a file" if path.is_dir() else "file not found"))
    expected = pose_columns(fmt)
    text, note = read_text(path)
    delim = _delimiter(text)
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=delim, skipinitialspace=delim == " ")
    try:
        rows = [r for r in reader if r and any(c.strip() for c in r)]
    except csv.Error as exc:
        raise SessionError(f"{path}: not a readable CSV table ({exc})") from None
    if not rows:
        raise SessionError(f"{path}: empty file; expected a header row ({', '.join(expected)}) and one row per pose")
    header = [c.strip() for c in rows[0]]
    id_col = header[0] if header and header[0].lower() in id_columns else None
    pose_header = [c.lower() for c in (header[1:] if id_col else header)]
    if pose_header != expected:
        raise SessionError(
            f"{path}: header {header} does not match format {fmt!r}, which needs the columns "
            f"{', '.join(expected)} (after an '{id_columns[0]}' column)"
        )
    decimal_comma = delim != "," and any("," in c for r in rows[1:] for c in r)
    ids: list[str] = []
    values = np.empty((len(rows) - 1, len(expected)))
    for k, row in enumerate(rows[1:]):
        line = k + 2
        cells = [c.strip() for c in row]
        if len(cells) != len(header):
            raise SessionError(f"{path}: line {line} has {len(cells)} values, the header has {len(header)}")
        if id_col:
            ids.append(cells[0])
            cells = cells[1:]
        for c, cell in enumerate(cells):
            try:
                values[k, c] = float(cell.replace(",", ".") if decimal_comma else cell)
            except ValueError:
                raise SessionError(f"{path}: line {line}, column '{expected[c]}': {cell!r} is not a number") from None
    if len(values) == 0:
        raise SessionError(f"{path}: no pose rows after the header")
    if id_col and any(not i for i in ids):
        raise SessionError(f"{path}: line {ids.index('') + 2} has an empty {id_col}")
    if id_col and len(set(ids)) != len(ids):
        dup = sorted({i for i in ids if ids.count(i) > 1})
        raise SessionError(f"{path}: duplicate {id_col} values {dup}")
    if notes is not None:
        if note:
            notes.append(note)
        if delim != ",":
            sep = {";": "semicolons", "\t": "tabs"}.get(delim, "spaces")
            notes.append(f"{path.name}: values read as separated by {sep}" + (", with decimal commas" if decimal_comma else ""))
    return values, (ids if id_col else None)


def _read_pose_file(
    path: Path, fmt: str, length_unit: str, angle_unit: str, id_columns: tuple[str, ...] = ID_COLUMNS,
    notes: list[str] | None = None,
) -> tuple[NDArray[np.float64], list[str] | None, NDArray[np.float64]]:
    """A pose CSV read and parsed into transforms (metres), with its ids and raw values; errors name
    the file and row."""
    values, ids = read_pose_table(path, fmt, id_columns=id_columns, notes=notes)
    try:
        return parse_poses(values, fmt, length_unit, angle_unit, what=str(path)), ids, values
    except PoseFormatError as exc:
        raise PoseFormatError(f"{exc} (rows count from 0 after the header)" if "row " in str(exc) else str(exc)) from None


def _read_poses(folder: Path, spec: Any, key: str,
                notes: list[str]) -> tuple[NDArray[np.float64], list[str] | None, Path, RobotPoseInput]:
    where = f"{folder / POSEPAIRS_FILE}: {key}"
    if not isinstance(spec, dict):
        raise SessionError(f"{where}: expected a mapping with file, format, length_unit, angle_unit")
    path = folder / str(_require(spec, "file", where))
    fmt = str(_require(spec, "format", where))
    length_unit = str(_require(spec, "length_unit", where))
    angle_unit = str(spec.get("angle_unit", "rad"))
    T, ids, values = _read_pose_file(path, fmt, length_unit, angle_unit, notes=notes)
    return T, ids, path, RobotPoseInput(values, fmt, length_unit, angle_unit)


def load_pose_pairs(folder: str | Path) -> PosePairs:
    """Load a pose-pair folder (see the module docstring).

    Raises
    ------
    SessionError
        Missing folder, file or key; malformed CSV.
    PoseFormatError
        Pose values that do not fit their declared format or units.
    InputMismatchError
        Unknown setup; robot and camera rows that do not pair up.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise SessionError(f"{folder}: no such folder")
    notes: list[str] = []
    spec = load_yaml(folder / POSEPAIRS_FILE, notes)
    where = str(folder / POSEPAIRS_FILE)
    setup = check_setup(str(_require(spec, "setup", where)))
    f2b, robot_ids, robot_path, robot_input = _read_poses(folder, _require(spec, "robot_poses", where), "robot_poses",
                                                          notes)
    t2c, cam_ids, cam_path, camera_input = _read_poses(folder, _require(spec, "camera_poses", where), "camera_poses",
                                                       notes)
    if robot_ids is not None and cam_ids is not None:
        missing = sorted(set(robot_ids) ^ set(cam_ids))
        if missing:
            raise InputMismatchError(
                f"ids {missing} appear in only one of {robot_path.name} and {cam_path.name}; every robot pose "
                f"needs its camera pose"
            )
        row_of = {k: n for n, k in enumerate(cam_ids)}
        order = [row_of[k] for k in robot_ids]
        t2c = t2c[order]
        camera_input = RobotPoseInput(camera_input.values[order], camera_input.format, camera_input.length_unit,
                                      camera_input.angle_unit)
        ids = robot_ids
    else:
        if len(f2b) != len(t2c):
            raise InputMismatchError(
                f"{robot_path.name} has {len(f2b)} poses but {cam_path.name} has {len(t2c)}; they pair row by row "
                f"(or add an 'id' column to both)"
            )
        ids = robot_ids or cam_ids or [str(k) for k in range(len(f2b))]
    return PosePairs(setup, f2b, t2c, ids, folder, robot_input, notes, camera_input)


def read_intrinsics(path: str | Path) -> tuple[NDArray[np.float64], NDArray[np.float64], tuple[int, int]]:
    """K, dist and image size from a YAML file (top level, or under ``camera:`` as in session.yaml)."""
    p = Path(path)
    data = load_yaml(p)
    cam = data["camera"] if isinstance(data.get("camera"), dict) else data
    size = cam.get("image_size", data.get("image_size"))
    if "K" not in cam or size is None:
        raise SessionError(f"{p}: needs K: [[fx,0,cx],[0,fy,cy],[0,0,1]] and image_size: [width, height] "
                           "(dist optional), at the top level or under camera:")
    K, dist = read_camera({"K": cam["K"], "dist": cam.get("dist") or [0.0] * 5}, str(p))
    try:
        w, h = (int(v) for v in size)
    except (TypeError, ValueError):
        raise SessionError(f"{p}: image_size must be [width, height]") from None
    if w <= 0 or h <= 0:
        raise SessionError(f"{p}: image_size must be positive")
    return K, dist, (w, h)


def _number(v: float) -> str:
    """The one number format of the files handeye writes: the shortest text that reads back exactly."""
    return repr(float(v))


def write_pose_table(path: str | Path, names: list[str], flange2base: NDArray[np.float64], format: str = "quat_wxyz",
                     length_unit: str = "m", angle_unit: str = "rad", protect: Iterable[str | Path] = ()) -> Path:
    """Write robot poses as a session ``poses.csv`` (``image`` column first) in the given format and
    units, atomically and never over a ``protect`` path; returns the path."""
    rows = format_poses(flange2base, format, length_unit, angle_unit)
    if len(names) != len(rows):
        raise InputMismatchError(f"{len(names)} image names for {len(rows)} poses")
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["image"] + pose_columns(format))
    for name, row in zip(names, rows):
        w.writerow([name] + [_number(v) for v in row])
    path = Path(path)
    atomic_write(path, buf.getvalue(), protect)
    return path


def write_session(folder: str | Path, setup: str, target_spec: dict[str, Any], names: list[str],
                  flange2base: NDArray[np.float64], format: str = "quat_wxyz", length_unit: str = "mm",
                  angle_unit: str = "deg", camera: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
                  comment: str | None = None) -> Path:
    """Write ``session.yaml`` and ``poses.csv`` of a session (DESIGN §4) into ``folder``, atomically;
    the images (``images/<name>``) are the caller's. ``camera``: ``(K, dist)`` to put in
    session.yaml. Returns the session.yaml path."""
    folder = Path(folder)
    check_setup(setup)
    target_from_spec(target_spec)
    write_pose_table(folder / "poses.csv", names, flange2base, format, length_unit, angle_unit)
    spec: dict[str, Any] = {"setup": setup, "target": dict(target_spec)}
    if camera is not None:
        spec["camera"] = {"K": np.asarray(camera[0], dtype=float).tolist(),
                          "dist": np.asarray(camera[1], dtype=float).ravel().tolist()}
    spec["poses"] = {"file": "poses.csv", "format": format, "length_unit": length_unit, "angle_unit": angle_unit}
    text = (f"# {comment}\n" if comment else "") + yaml.safe_dump(spec, sort_keys=False)
    atomic_write(folder / SESSION_FILE, text)
    return folder / SESSION_FILE
