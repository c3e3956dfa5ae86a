"""Captures on disk, in both directions: reading and writing sessions and pose tables.

*Capture sessions* (the session format in docs/guide.md): ``session.yaml``, ``poses.csv`` (an ``image`` column, then the
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

Each CSV has a header row naming the pose columns (see :func:`handeye.frames.poses.pose_columns`),
optionally preceded by an ``id`` (or ``image``) column. With ids in both files, rows pair by id;
otherwise by order. Either side may hold the inverse poses, said with ``pose: base2flange`` or
``pose: cam2target`` (defaults ``flange2base``, ``target2cam``).

*Streams*: with a ``time`` column (after the id, if any) in both files, the files are two
recordings on separate clocks, not pairs (``handeye.calibrate_streams`` pairs them by time and
estimates the clock offset). ``time_unit: s | ms | us | ns`` (default s) per side. A stream file
may have no header: its columns are then the time and the pose columns, in that order (ETH's
and TUM's trajectory files: ``t x y z qx qy qz qw`` with ``format: quat_xyzw``).
"""

from __future__ import annotations

import csv
import difflib
import io
import unicodedata
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np
import yaml
from numpy.typing import NDArray

from .._shared.io import atomic_write, read_text
from .._shared.lazy import lazy_module
from .._shared.text import cut, shown, summarize
from ..errors import InputMismatchError, PoseFormatError, SessionError
from ..frames.poses import RobotPoseInput, format_poses, matrix_layout, parse_poses, pose_columns, vendor_columns
from ..frames.setups import check_setup
from ..geometry.se3 import invert
from ..robot.kinematics import Chain, check_joints_against_poses, load_arm
from ..sensors.camera.targets import target_from_spec

cv2 = lazy_module("cv2")  # only to read an image's size
_urdf = lazy_module("handeye.robot.urdf")  # a session's arm given as a URDF: read when one is

__all__ = ["PosePairs", "Session", "load_pose_pairs", "load_pose_streams", "TIME_UNITS", "TIME_COLUMNS", "POSE_KINDS", "load_session",
           "read_pose_table", "read_joints", "read_joint_trajectory", "SessionError", "load_yaml", "check_keys",
           "check_session_keys", "read_session_yaml", "pose_rows_inverted", "read_robot_poses", "joints_of_views",
           "read_camera", "read_intrinsics", "write_pose_table", "write_session", "write_pose_stream", "write_stream_session",
           "write_pose_pairs", "SESSION_FILE", "POSEPAIRS_FILE", "write_joint_session", "write_joint_table",
           "load_joint_stream", "load_camera_stream", "write_joint_stream", "read_image_times", "time_unit_scale",
           "parsed_poses", "pose_table_path", "flange_poses_of", "files_of_views", "session_file", "IMAGE_ORDER",
           "robot_pose_input", "read_unknowns", "UNKNOWN_MODES"]

POSEPAIRS_FILE = "posepairs.yaml"
SESSION_FILE = "session.yaml"
ID_COLUMNS = ("id", "image")
#: Names of a time column (streams: the poses of one clock, seconds unless time_unit says otherwise).
TIME_COLUMNS = ("time", "t", "stamp", "timestamp")
#: Time units of stream files, in seconds.
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm", ".webp"}
#: The same, in the order a view's image is looked for (:func:`files_of_views`): the png first.
IMAGE_ORDER = tuple(sorted(IMAGE_SUFFIXES, key=lambda x: (x != ".png", x)))


def session_file(root: Path, path: str | Path, what: str) -> Path:
    """``path`` (a file or folder a session names, joined to its folder ``root``: ``root / name``)
    checked to lie inside ``root`` once ``..`` and every symlink are resolved; returned as given. A
    session read from elsewhere (a colleague's, a download) must not make handeye open, quote or
    use a file beside or above it (``../../etc/passwd`` as a profile, a link to a key file as an
    image): anything outside is a :class:`SessionError` naming the file and the rule, before the
    file is opened. ``what``: the file in words."""
    path = Path(path)
    inside = Path(root).resolve()
    try:
        resolved = path.resolve()
    except (OSError, RuntimeError):  # a symlink loop
        resolved = None
    if resolved is None or (resolved != inside and inside not in resolved.parents):
        to = "" if resolved is None else f" (it resolves to {cut(resolved)})"
        raise SessionError(f"{cut(path)}: {what} lies outside the session folder {root}{to}: a session reads only "
                           "files inside its own folder, '..' and symbolic links resolved; copy the file into the folder")
    return path


def files_of_views(folder: Path, names: Sequence[str], suffixes: Sequence[str], root: Path | None = None
                   ) -> list[Path | None]:
    """Per view of ``names`` its file in ``folder``: the name itself when it ends in one of
    ``suffixes``, else the name or its stem followed by the first of ``suffixes`` (in their order)
    there is a file for, the suffix in any case (``v01`` or ``v01.png`` finds ``v01.PLY``); None
    for a view without one (a view the sensor missed). The folder is listed once. Each file found
    lies inside the session folder ``root`` (default ``folder``; :func:`session_file`): a link to
    elsewhere is an error."""
    root = folder if root is None else root
    session_file(root, folder, "the folder of the views' files")
    order = [str(x).lower() for x in suffixes]
    listing: dict[tuple[str, str], Path] = {}
    if folder.is_dir():
        for path in sorted(folder.iterdir()):
            if path.suffix.lower() in order and path.is_file():
                listing.setdefault((path.stem, path.suffix.lower()), path)
    out: list[Path | None] = []
    for name in names:
        own = Path(name)
        if own.parent != Path() or own.is_absolute():  # a path, not a name: it too stays inside
            session_file(root, folder / own, f"the file of view {shown(name)}")
        given = [(own.stem, own.suffix.lower())] if own.suffix.lower() in order else []
        tried = given + [(base, suffix) for base in (name, own.stem) for suffix in order]
        found = next((listing[key] for key in tried if key in listing), None)
        out.append(None if found is None else session_file(root, found, f"the file of view {shown(name)}"))
    return out


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
    #: streams (a time column in both files): seconds on each clock; the rows are then not paired
    robot_times: NDArray[np.float64] | None = None
    camera_times: NDArray[np.float64] | None = None
    #: streams whose rows also carry ids: per id in both, camera time minus robot time (the user's pairing)
    paired_delays: NDArray[np.float64] | None = None

    @property
    def is_stream(self) -> bool:
        """Two time-stamped streams rather than pose pairs."""
        return self.robot_times is not None


@dataclass(frozen=True)
class Session:
    """A capture session read from disk (the session format in docs/guide.md), validated."""

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
    #: a robot stream (poses.csv with a time column): its times (s, robot clock) and poses; ``flange2base``
    #: then holds the robot sample nearest each image's time, until the clock offset is estimated
    robot_times: NDArray[np.float64] | None = None
    robot_stream: NDArray[np.float64] | None = None
    #: with a robot stream: each image's time (s, camera clock), from the ``images:`` table
    image_times: NDArray[np.float64] | None = None
    image_times_path: Path | None = None
    #: a ``joints:`` table: each image's joint angles (rad) and the arm's nominal kinematics;
    #: ``flange2base`` then holds the controller's poses when given, else the nominal chain's
    joints: NDArray[np.float64] | None = None
    arm: Chain | None = None
    joints_path: Path | None = None

    @property
    def input_files(self) -> list[Path]:
        """Every file the session is read from: session.yaml, the pose table(s), the images (those
        that exist: a missing one is skipped by the calibration)."""
        tables = [p for p in (self.poses_path, self.image_times_path, self.joints_path) if p is not None]
        return [self.folder / SESSION_FILE] + tables + [p for p in self.image_paths if Path(p).is_file()]


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


def load_session(folder: str | Path, strict_images: bool = True, arm: str | None = None) -> Session:
    """Load and validate a capture session folder (the session format in docs/guide.md).

    ``strict_images=False``: an image named in the pose table but missing from ``images/`` is kept
    in the session (its path does not exist) for :func:`handeye.pipelines.calibration.observe` to skip with
    the reason, as it skips unreadable images.

    Raises
    ------
    SessionError
        Missing folder, session.yaml, key, poses file or (``strict_images``) image; duplicate image names; images in
        ``images/`` that no pose row names (a pose count that differs from the image count).
    PoseFormatError, InputMismatchError, TargetError
        Bad pose values, unknown setup, unusable target description.
    """
    folder, spec, where, notes = read_session_yaml(folder)
    check_session_keys(spec, SESSION_KEYS, {"poses": POSES_KEYS, "camera": CAMERA_KEYS, "joints": JOINTS_KEYS,
                                            "images": IMAGES_KEYS}, where)
    setup = check_setup(str(_require(spec, "setup", where)))
    target_spec = _require(spec, "target", where)
    target_from_spec(target_spec, where=f"{where}: target")  # a bad target fails now, before any image work
    K, dist = read_camera(spec.get("camera"), where)
    if arm is not None and spec.get("joints") is None:
        raise SessionError(f"{where}: arm {shown(arm)} was given for joint angles, and there is no joints: table (file, "
                           "unit) to use it with; leave the arm out, or add the joint angles")
    joints = _read_joints(folder, spec.get("joints"), where, notes, arm) if spec.get("joints") is not None else None
    if spec.get("poses") is None and joints is not None:  # joint angles alone: the nominal chain's flange poses
        return _joint_session(folder, setup, target_spec, K, dist, joints, None, notes, strict_images)
    poses = _require(spec, "poses", where)
    if not isinstance(poses, dict):
        raise SessionError(f"{where}: poses must be a mapping with file, format, length_unit, angle_unit")
    csv_path = session_file(folder, folder / str(_require(poses, "file", f"{where}: poses")), "the pose table")
    fmt = str(_require(poses, "format", f"{where}: poses"))
    length_unit = str(_require(poses, "length_unit", f"{where}: poses"))
    angle_unit = str(poses.get("angle_unit", "rad"))
    values, names, robot_times = read_pose_table(csv_path, fmt, id_columns=("image",), notes=notes, times=True)
    f2b = parsed_poses(values, fmt, length_unit, angle_unit, csv_path)
    inverted = pose_rows_inverted(poses, where)
    if inverted:  # the rows are base2flange: handeye uses their inverses
        f2b = invert(f2b)
    stream = None
    if robot_times is not None:  # a robot stream: the images carry their own times
        if names is not None:
            raise SessionError(f"{csv_path}: an 'image' and a time column: give either image names (poses paired with "
                               "images) or times (a robot stream, with the images' times in an images: table)")
        robot_times = robot_times * time_unit_scale(poses, f"{where}: poses")
        names, image_times, times_path = read_image_times(folder, spec.get("images"), where, notes)
        stream = (robot_times, f2b, image_times, times_path)
        nearest = _nearest(robot_times, image_times)
        f2b, values = f2b[nearest], values[nearest]
    if names is None:
        raise SessionError(f"{csv_path}: the first column must be 'image', naming each pose's image in images/ "
                           "(or 'time', for a robot stream with an images: table of image times)")
    paths, missing, unnamed, on_disk = _images_named(folder, names, csv_path, notes)
    if missing and strict_images:
        raise SessionError(f"{folder / 'images'}: image file(s) missing: {', '.join(missing[:10])}"
                           + (f" and {len(missing) - 10} more" if len(missing) > 10 else ""))
    if unnamed:
        raise SessionError(
            f"{csv_path.name} has {len(names)} poses but images/ holds {on_disk} images; no pose for "
            f"{', '.join(unnamed[:10])}: add their poses or move them out of images/"
        )
    session = Session(folder, setup, dict(target_spec), f2b, list(names), paths, K, dist, fmt,
                      RobotPoseInput(values, fmt, length_unit, angle_unit, inverted), csv_path, notes)
    if stream is not None:
        session = replace(session, robot_times=stream[0], robot_stream=stream[1], image_times=stream[2],
                          image_times_path=stream[3])
    if joints is not None:
        if stream is not None:
            raise SessionError(f"{where}: joints: with a robot stream is not supported; give joint angles per image")
        return _joint_session(folder, setup, target_spec, K, dist, joints, session, notes, strict_images)
    return session


@dataclass(frozen=True)
class _Joints:
    names: list[str]
    q: NDArray[np.float64]  # rad
    arm: Chain
    path: Path


def read_joints(folder: Path, spec: Any, where: str, notes: list[str], override: str | None = None,
                id_columns: tuple[str, ...] = ("image",)) -> tuple[list[str], NDArray[np.float64], Chain, Path]:
    """The ``joints:`` block of a session.yaml: each view's name, its joint angles (rad, as the arm's
    table takes them), the arm and the table's path (:func:`_read_joints`; ``id_columns``: the
    names the first column may have, ``image``, ``cloud``, ``profile``)."""
    j = _read_joints(folder, spec, where, notes, override, id_columns)
    return j.names, j.q, j.arm, j.path


def read_joint_trajectory(folder: Path, spec: Any, where: str, notes: list[str], override: str | None = None
                          ) -> tuple[NDArray[np.float64], NDArray[np.float64], Chain, Path]:
    """A ``joints:`` block whose table is a trajectory (a line-scan camera's): a time column (the
    robot's clock, ``time_unit`` as a pose table's) then one column per joint. Returns the times (s,
    increasing), the joint angles (rad, as the arm's table takes them), the arm and the table's path."""
    j = _read_joints(folder, spec, where, notes, override, TIME_COLUMNS)
    try:
        times = np.array([float(t) for t in j.names]) * time_unit_scale(spec, f"{where}: joints")
    except ValueError:
        raise SessionError(f"{j.path}: the time column holds a value that is not a number") from None
    if len(times) < 2 or not np.all(np.diff(times) > 0):
        k = int(np.flatnonzero(np.diff(times) <= 0)[0]) + 2 if len(times) > 1 else 1
        raise SessionError(f"{j.path}: the times must increase, two rows or more (line {k}): sort the samples, drop "
                           "repeats")
    return times, j.q, j.arm, j.path


def _read_joints(folder: Path, spec: Any, where: str, notes: list[str], override: str | None = None,
                 id_columns: tuple[str, ...] = ("image",)) -> _Joints:
    """The ``joints:`` block: ``file`` (an ``image`` column, then one column per joint), ``unit``
    (deg or rad) and ``arm`` (a shipped arm's name, or a YAML DH table in the folder); ``override``
    (``--arm``): the arm to use instead (a name, or a file relative to the current folder)."""
    if not isinstance(spec, dict):
        raise SessionError(f"{where}: joints must be a mapping with file, unit (deg or rad) and arm")
    path = session_file(folder, folder / str(_require(spec, "file", f"{where}: joints")), "the joints table")
    unit = str(_require(spec, "unit", f"{where}: joints"))
    if unit not in ("deg", "rad"):
        raise SessionError(f"{where}: joints: unit {shown(unit)}; use deg or rad")
    arm_name = str(override if override is not None else _require(spec, "arm", f"{where}: joints"))
    if override is None and arm_name.lower().endswith((".urdf", ".yaml", ".yml")):  # the session's own file: inside it
        session_file(folder, folder / arm_name, "the arm's table")
    try:
        arm = _arm_chain(arm_name, Path() if override is not None else folder, spec.get("base_link"), spec.get("tip_link"))
    except InputMismatchError as exc:
        raise SessionError(f"{where}: joints: {'arm given: ' if override is not None else ''}{exc}") from None
    if override is not None and spec.get("arm") not in (None, override):
        notes.append(f"joint angles read with the arm given ({arm.name}), not session.yaml's ({spec.get('arm')})")
    pendant = spec.get("pendant", False)
    if not isinstance(pendant, bool):
        raise SessionError(f"{where}: joints: pendant {shown(pendant)}; use true (the angles as the teach pendant shows them) "
                           "or false")
    names, q = _joint_table(path, arm, unit, id_columns, notes, "write unit: deg under joints:")
    if len(set(names)) != len(names):
        what = "times" if id_columns == TIME_COLUMNS else f"{id_columns[0]} names"
        raise SessionError(f"{path}: duplicate {what} [{summarize(sorted({x for x in names if names.count(x) > 1}))}]")
    return _Joints(names, _model_angles(np.radians(q) if unit == "deg" else q, arm, pendant, path.name, notes), arm, path)


def _model_angles(q: NDArray[np.float64], arm: Chain, pendant: bool, where: str, notes: list[str]) -> NDArray[np.float64]:
    """Joint angles (rad) as ``arm``'s table takes them: converted from the teach pendant's
    (:meth:`Chain.from_pendant`) when ``pendant``, with a note saying so."""
    if not pendant:
        return q
    if arm.pendant_coupling is None:
        notes.append(f"{where}: pendant angles given, and {arm.name}'s teach pendant shows its table's own joint angles: "
                     "nothing to convert")
        return q
    j, i, f = arm.pendant_coupling
    notes.append(f"{where}: the teach pendant's angles converted to {arm.name}'s table: joint {j} = J{j} + "
                 f"{f:g} x J{i}")
    return arm.from_pendant(q)


def _arm_chain(name: str, base: Path, base_link: str | None = None, tip_link: str | None = None) -> Chain:
    """The chain an arm is named by: a URDF (its chain from ``base_link`` to ``tip_link`` when given)
    or a DH table file, relative to ``base``, or a shipped arm's name."""
    if name.lower().endswith(".urdf"):
        return _urdf.chain_from_urdf(base / name, base_link, tip_link)
    return load_arm(base / name if name.lower().endswith((".yaml", ".yml")) else name)


def _joint_table(path: Path, arm: Chain, unit: str, first: tuple[str, ...], notes: list[str], fix: str
                 ) -> tuple[list[str], NDArray[np.float64]]:
    """A table of joint angles: its first column (named one of ``first``: the image, or a time) as
    text, and the joint angles (N, n) in ``unit``, in the arm's order when the columns name its
    joints; ``fix``: how to give the unit as degrees, for the error that says they look like it."""
    text = _text_of(path, notes)
    delim = _delimiter(text)
    rows = [[c.strip() for c in r] for r in csv.reader(io.StringIO(text, newline=""), delimiter=delim,
                                                       skipinitialspace=delim == " ")
            if r and any(c.strip() for c in r) and not r[0].lstrip().startswith("#")]
    if not rows or rows[0][0].lower() not in first:
        raise SessionError(f"{path}: the first column must be {' or '.join(repr(f) for f in first)}, then one column "
                           f"per joint ({arm.name}: {arm.n_joints})")
    n = arm.n_joints
    columns = rows[0][1:]
    order = _joint_order(columns, arm.joint_names)
    if order is not None:  # named as the arm's joints: read in the arm's order
        if order != list(range(1, n + 1)):
            notes.append(f"{path.name}: joint columns taken in {arm.name}'s order ({', '.join(arm.joint_names)})")
        rows = [[r[0]] + [r[k] for k in order] if len(r) == n + 1 else r for r in rows]
    names, q = [], np.empty((len(rows) - 1, n))
    for k, row in enumerate(rows[1:]):
        if len(row) != n + 1:
            raise SessionError(f"{path}: line {k + 2} has {len(row) - 1} joint values; {arm.name} has {n} joints")
        names.append(row[0])
        for j, cell in enumerate(row[1:]):
            try:
                q[k, j] = float(cell)
            except ValueError:
                raise SessionError(f"{path}: line {k + 2}, joint {j + 1}: {shown(cell)} is not a number") from None
    if not len(q):
        raise SessionError(f"{path}: no rows after the header")
    if not np.isfinite(q).all():
        raise SessionError(f"{path}: line {int(np.argmin(np.isfinite(q).all(axis=1))) + 2} holds NaN or infinite values")
    if unit == "rad" and np.abs(q).max() > 2.5 * np.pi:
        raise SessionError(f"{path}: joint angles up to {np.abs(q).max():.1f} given as rad: they look like degrees; "
                           f"{fix}")
    return names, q


def load_joint_stream(path: str | Path, arm: str | Chain, unit: str = "rad", time_unit: str = "s",
                      pendant: bool = False) -> tuple[NDArray[np.float64], NDArray[np.float64], Chain, list[str]]:
    """A recording of joint angles (``/joint_states`` as CSV): a header ``time`` (or t, stamp,
    timestamp), then one column per joint (named as the arm's joints, in any order, or in the arm's
    order); returns the times (s), the joint angles (N, n) in radians as the arm's table takes them
    (``pendant``: recorded as the teach pendant shows them, converted), the arm's chain and notes
    (how the columns were read)."""
    if unit not in ("deg", "rad"):
        raise SessionError(f"{path}: joint unit {shown(unit)}; use deg or rad")
    scale = time_unit_scale({"time_unit": time_unit}, str(path))
    try:
        chain = arm if isinstance(arm, Chain) else _arm_chain(str(arm), Path())
    except InputMismatchError as exc:
        raise SessionError(f"{path}: {exc}") from None
    notes: list[str] = []
    stamps, q = _joint_table(Path(path), chain, unit, TIME_COLUMNS, notes, "give their unit as deg (--robot-units m,deg)")
    try:
        times = scale * np.array([float(t) for t in stamps])
    except ValueError:
        raise SessionError(f"{path}: the time column holds a value that is not a number") from None
    return times, _model_angles(np.radians(q) if unit == "deg" else q, chain, pendant, Path(path).name, notes), chain, notes


def _joint_order(columns: list[str], joint_names: tuple[str, ...] | None) -> list[int] | None:
    """The column (1-based, after the image column) of each of the arm's joints when the columns
    name them all (exactly, or with a prefix: ``ur5_shoulder_pan_joint``), else None."""
    if joint_names is None or len(columns) != len(joint_names):
        return None
    order = []
    for name in joint_names:
        hits = [k for k, c in enumerate(columns) if c == name or c.endswith("_" + name) or c.endswith("/" + name)]
        if len(hits) != 1:
            return None
        order.append(hits[0] + 1)
    return order if len(set(order)) == len(order) else None


def _joint_session(folder: Path, setup: str, target_spec, K, dist, joints: _Joints, posed: Session | None,
                   notes: list[str], strict_images: bool) -> Session:
    """A session whose robot side is joint angles: alone (the flange poses from the nominal chain,
    the images named by the joints table), or beside the controller's poses (the same images in
    both tables; the two checked against each other)."""
    if posed is None:
        paths, missing, unnamed, _ = _images_named(folder, joints.names, joints.path, notes)
        if missing and strict_images:
            raise SessionError(f"{folder / 'images'}: image file(s) missing: {summarize(missing)}")
        if unnamed:
            raise SessionError(f"{joints.path.name} has {len(joints.names)} rows but images/ holds images it does not "
                               f"name: {summarize(unnamed)}; add their joint angles or move them out of images/")
        return Session(folder, setup, dict(target_spec), joints.arm.forward(joints.q), list(joints.names), paths, K, dist,
                       "joints", None, None, notes, joints=joints.q, arm=joints.arm, joints_path=joints.path)
    index = {n: k for k, n in enumerate(joints.names)}
    absent = [n for n in posed.image_names if n not in index]
    if absent or len(joints.names) != len(posed.image_names):
        raise SessionError(f"{joints.path.name} and {posed.poses_path.name if posed.poses_path else 'the poses'} must name "
                           f"the same images: {len(joints.names)} and {len(posed.image_names)} rows"
                           + (f"; no joint angles for {summarize(absent)}" if absent else ""))
    q = joints.q[[index[n] for n in posed.image_names]]
    try:
        finding = check_joints_against_poses(joints.arm, q, posed.flange2base, where=f"{joints.path.name}",
                                             names=list(posed.image_names))
    except InputMismatchError as exc:
        raise SessionError(f"{folder}: {exc}") from None
    return replace(posed, joints=q, arm=joints.arm, joints_path=joints.path, notes=notes + [finding])


def _images_named(folder: Path, names: list[str], table: Path,
                  notes: list[str]) -> tuple[list[Path], list[str], list[str], int]:
    """The images a table's rows name in ``folder/images``: each row's path (its name as written
    when no file matches), the names with no file, the images no row names, and how many images
    the folder holds; a row may name an image of any suffix. No images folder: an error."""
    image_dir = session_file(folder, folder / "images", "the images' folder")
    if not image_dir.is_dir():
        raise SessionError(f"{image_dir}: no images folder; the images named in {table.name} go there")
    all_files = sorted(p.name for p in image_dir.iterdir() if p.is_file())
    on_disk = [n for n in all_files if Path(n).suffix.lower() in IMAGE_SUFFIXES]
    files = _match_image_names(names, all_files, notes)
    missing = [n for n, f in zip(names, files) if f is None]
    paths = [session_file(folder, image_dir / (f if f is not None else n), f"the image of {shown(n)}")
             for f, n in zip(files, names)]
    return paths, missing, sorted(set(on_disk) - set(files)), len(on_disk)


def time_unit_scale(spec: dict[str, Any], where: str) -> float:
    """Seconds per unit of a block's ``time_unit`` (default s); an unknown unit is a SessionError."""
    unit = str(spec.get("time_unit", "s"))
    if unit not in TIME_UNITS:
        raise SessionError(f"{where}: time_unit {shown(unit)}; use one of {', '.join(TIME_UNITS)}")
    return TIME_UNITS[unit]


def _nearest(times: NDArray[np.float64], query: NDArray[np.float64]) -> NDArray[np.intp]:
    """Per query time, the index of the nearest of the (increasing) ``times``."""
    k = np.clip(np.searchsorted(times, query), 1, len(times) - 1)
    return np.where(np.abs(query - times[k - 1]) <= np.abs(times[k] - query), k - 1, k)


def read_image_times(folder: Path, spec: Any, where: str, notes: list[str]
                      ) -> tuple[list[str], NDArray[np.float64], Path]:
    """The ``images:`` table of a session with a robot stream: a CSV with a header ``image, time``
    (the camera's clock), in ``time_unit`` (default s)."""
    if not isinstance(spec, dict) or "file" not in spec:
        raise SessionError(f"{where}: the poses are a robot stream (a time column), so the images need their times: "
                           "add images: {file: images.csv} with columns image, time")
    path = session_file(folder, folder / str(spec["file"]), "the images' times")
    text = _text_of(path, notes)
    rows = [r for r in csv.reader(io.StringIO(text, newline=""), delimiter=_delimiter(text), skipinitialspace=True)
            if r and any(c.strip() for c in r)]
    header = [c.strip().lower() for c in rows[0]] if rows else []
    if len(header) != 2 or header[0] != "image" or header[1] not in TIME_COLUMNS:
        raise SessionError(f"{path}: header {cut(str(header), 300)}; expected image, time")
    names, times = [], []
    for k, row in enumerate(rows[1:]):
        if len(row) != 2:
            raise SessionError(f"{path}: line {k + 2} has {len(row)} values, the header has 2")
        try:
            times.append(float(row[1]))
        except ValueError:
            raise SessionError(f"{path}: line {k + 2}, column 'time': {shown(row[1].strip())} is not a number") from None
        names.append(row[0].strip())
    if not names:
        raise SessionError(f"{path}: no rows after the header")
    if len(set(names)) != len(names):
        raise SessionError(f"{path}: duplicate image names {summarize(sorted({n for n in names if names.count(n) > 1}))}")
    return names, np.asarray(times) * time_unit_scale(spec, f"{where}: images"), path


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


def _text_of(path: Path, notes: list[str] | None) -> str:
    """The text of an input file (:func:`handeye._shared.io.read_text`: any usual encoding, how it was
    read into ``notes``), or a one-line error for a missing file or a folder."""
    if not path.is_file():
        raise SessionError(f"{path}: " + ("is a folder, not a file" if path.is_dir() else "file not found"))
    text, note = read_text(path)
    if note and notes is not None:
        notes.append(note)
    return text


#: The keys of an image session's session.yaml and of its blocks (docs/guide.md): any other is an error.
SESSION_KEYS = ("setup", "target", "camera", "poses", "joints", "images")
POSES_KEYS = ("file", "format", "length_unit", "angle_unit", "pose", "time_unit")
CAMERA_KEYS = ("K", "dist")
JOINTS_KEYS = ("file", "unit", "arm", "pendant", "base_link", "tip_link")
IMAGES_KEYS = ("file", "time_unit")


def check_keys(mapping: Any, known: tuple[str, ...], where: str) -> None:
    """Raise :class:`SessionError` for a key of ``mapping`` that is not ``known``, naming the nearest
    known key: a misspelt key would otherwise do nothing, silently."""
    if not isinstance(mapping, dict):
        return
    for key in mapping:
        if key not in known:
            near = difflib.get_close_matches(str(key), known, n=1, cutoff=0.5)
            raise SessionError(f"{where}: unknown key {shown(key)}" + (f" (did you mean {shown(near[0])}?)" if near else "")
                               + f"; the keys there are {', '.join(known)}")


def read_session_yaml(folder: str | Path) -> tuple[Path, dict[str, Any], str, list[str]]:
    """A session folder's session.yaml read: the folder, the mapping, where it came from (for the
    errors) and how it was read (notes); a missing folder or file is a :class:`SessionError` that
    says what the folder must hold."""
    folder = Path(folder)
    if not folder.is_dir():
        raise SessionError(f"{folder}: no such session folder")
    yml = folder / SESSION_FILE
    if not yml.is_file():
        _missing_folder_file(folder, SESSION_FILE)
    notes: list[str] = []
    return folder, load_yaml(yml, notes), str(yml), notes


def check_session_keys(spec: dict, top: tuple[str, ...], blocks: dict[str, tuple[str, ...]], where: str) -> None:
    """:func:`check_keys` on a session.yaml's top level (``top``) and on each of its ``blocks``."""
    check_keys(spec, top, where)
    for key, known in blocks.items():
        check_keys(spec.get(key), known, f"{where}: {key}")


#: What ``unknowns:`` in session.yaml may say of each of a sensor's unknowns beside X (its depth scale and
#: bias, a ball's radius, a line-scan camera's focal length, ...: :class:`~handeye.sensors.base.Nuisance`).
UNKNOWN_MODES = ("auto", "hold", "free")


def read_unknowns(spec: dict, where: str) -> dict[str, str]:
    """session.yaml's ``unknowns:`` block (optional): per unknown's name (``depth_scale``, ``radius``,
    ...) whether the fit holds it at its nominal or given value (``hold``), fits it whatever the
    capture (``free``) or fits it where the capture determines it (``auto``, the default). The names
    are checked against the sensor's own when it is fitted."""
    block = spec.get("unknowns")
    if block is None:
        return {}
    if not isinstance(block, dict):
        raise SessionError(f"{where}: unknowns must be a mapping of an unknown's name to hold, free or auto, e.g. "
                           "unknowns: {depth_scale: hold}")
    out = {}
    for name, mode in block.items():
        if str(mode) not in UNKNOWN_MODES:
            raise SessionError(f"{where}: unknowns: {repr(name)[:40]}: {repr(mode)[:40]}; say hold, free or auto")
        out[str(name)] = str(mode)
    return out


def pose_rows_inverted(poses: dict, where: str) -> bool:
    """Whether a ``poses:`` block says its rows are the inverses of the flange poses
    (``pose: base2flange``; the default ``flange2base``: the controller's poses as it reports them)."""
    kind = str(poses.get("pose", "flange2base"))
    if kind not in POSE_KINDS["robot_poses"]:
        raise SessionError(f"{where}: poses: pose {shown(kind)}; use flange2base (the default: the controller's poses) or "
                           "base2flange (the table's rows are their inverses)")
    return kind == "base2flange"


def read_robot_poses(folder: Path, poses: Any, where: str, notes: list[str], id_columns: tuple[str, ...],
                     first_column: str) -> tuple[NDArray[np.float64], list[str], Path, RobotPoseInput]:
    """A sensor session's ``poses:`` block (``file``, ``format``, ``length_unit``, ``angle_unit``,
    ``pose``): the flange poses (inverted when the rows are base2flange), each view's name (the
    table's first column, one of ``id_columns``; ``first_column`` says what it must be when it is
    missing), the table's path and the rows as written with their declaration (other readings of
    them are tried when they fit nothing: :mod:`handeye.estimation.readings`)."""
    table = pose_table_path(folder, poses, where)
    values, names = read_pose_table(table, str(poses["format"]), id_columns=id_columns, notes=notes)
    if names is None:
        raise SessionError(f"{table}: the first column must be {first_column}")
    return flange_poses_of(values, poses, table, where), list(names), table, robot_pose_input(values, poses, where)


def robot_pose_input(values: NDArray[np.float64], poses: dict, where: str) -> RobotPoseInput:
    """A pose table's rows ``values`` with the ``poses:`` block's declaration (format, units, inverted)."""
    return RobotPoseInput(np.asarray(values, float), str(poses["format"]), str(poses["length_unit"]),
                          str(poses.get("angle_unit", "rad")), pose_rows_inverted(poses, where))


def pose_table_path(folder: Path, poses: Any, where: str, what: str = "") -> Path:
    """The pose table a ``poses:`` block names, checked: a mapping with ``file``, ``format`` and
    ``length_unit``, and the file there (``what``: the table in words, for the messages)."""
    if not isinstance(poses, dict) or not {"file", "format", "length_unit"} <= set(poses):
        raise SessionError(f"{where}: poses must be a mapping with file, format, length_unit (m | mm) and angle_unit "
                           f"(deg | rad){': ' + what if what else ''}")
    table = session_file(folder, folder / str(poses["file"]), "the pose table")
    if not table.is_file():
        raise SessionError(f"{table}: no such pose table{f' ({what})' if what else ''}")
    return table


def flange_poses_of(values: NDArray[np.float64], poses: dict, table: Path, where: str) -> NDArray[np.float64]:
    """The flange poses of a pose table's rows ``values`` in the ``poses:`` block's format and units,
    inverted when the rows are base2flange."""
    f2b = parsed_poses(values, str(poses["format"]), str(poses["length_unit"]), str(poses.get("angle_unit", "rad")), table)
    return invert(f2b) if pose_rows_inverted(poses, where) else f2b


def joints_of_views(joints: tuple[list[str], NDArray[np.float64], Chain, Path], names: list[str],
                    flange2base: NDArray[np.float64] | None = None, notes: list[str] | None = None) -> NDArray[np.float64]:
    """The joint angles of :func:`read_joints` in the order of the views ``names`` (the poses'
    table's), which both tables must name alike. With the controller's ``flange2base`` of those
    views, the two are checked against each other as an image session's are
    (:func:`~handeye.robot.kinematics.check_joints_against_poses`: another arm, degrees read as
    radians, the columns reversed, rows swapped, named before any fit), the finding into ``notes``."""
    j_names, q, arm, path = joints
    index = {n: k for k, n in enumerate(j_names)}
    absent = [n for n in names if n not in index]
    if absent or len(j_names) != len(names):
        raise SessionError(f"{path}: the joint angles and the poses must name the same views: {len(j_names)} and "
                           f"{len(names)} rows" + (f"; no joint angles for {', '.join(absent[:5])}" if absent else ""))
    q = q[[index[n] for n in names]]
    if flange2base is not None:
        try:
            finding = check_joints_against_poses(arm, q, flange2base, where=path.name, names=list(names))
        except InputMismatchError as exc:
            raise SessionError(f"{path.parent}: {exc}") from None
        if notes is not None:
            notes.append(finding)
    return q



class _UniqueKeyLoader(yaml.SafeLoader):
    """PyYAML's safe loader, refusing a key given twice in one mapping (it would keep the last one
    silently: two sensors of one name, a setting written twice)."""


def _unique_mapping(loader: yaml.SafeLoader, node: yaml.MappingNode, deep: bool = False) -> dict:
    seen = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        if key in seen:
            raise yaml.constructor.ConstructorError(None, None, f"key {key!r} given twice", key_node.start_mark)
        seen.add(key)
    return loader.construct_mapping(node, deep)


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _unique_mapping)

#: Values a YAML file's aliases (``*name``) may add to it, expanded: an anchor shared by a few keys is
#: YAML as people write it; a billion-laughs file (aliases of aliases, 9**9 values from 1 kB) would
#: make any message quoting a value, or any ``str()`` of it, run for hours.
MAX_ALIAS_VALUES = 100_000
_ALIASES = ("a file of settings holds a few hundred values; write them out (an anchor may stand for a block a few times, "
            "not for aliases of aliases)")


def _expanded_size(node: yaml.Node, memo: dict[int, int], active: set[int]) -> int:
    """The number of values under ``node`` with every alias expanded (``memo``: per node already
    counted; ``active``: the nodes being counted, an alias to one of them is a loop)."""
    key = id(node)
    if key in memo:
        return memo[key]
    if key in active:
        raise SessionError(f"an alias (*name) at line {node.start_mark.line + 1} refers to its own anchor: {_ALIASES}")
    active.add(key)
    if isinstance(node, yaml.SequenceNode):
        size = 1 + sum(_expanded_size(child, memo, active) for child in node.value)
    elif isinstance(node, yaml.MappingNode):
        size = 1 + sum(_expanded_size(k, memo, active) + _expanded_size(v, memo, active) for k, v in node.value)
    else:
        size = 1
    active.discard(key)
    memo[key] = size
    return size


def _bounded_single_node(self: _UniqueKeyLoader) -> yaml.Node | None:
    """The document's node graph, refused before anything is built from it when its aliases expand
    it by more than :data:`MAX_ALIAS_VALUES` values, or one refers to itself."""
    node = yaml.composer.Composer.get_single_node(self)
    if node is not None:
        memo: dict[int, int] = {}
        total = _expanded_size(node, memo, set())
        if total - len(memo) > MAX_ALIAS_VALUES:
            raise SessionError(f"its aliases (*name) expand it to {total:,} values: {_ALIASES}")
    return node


_UniqueKeyLoader.get_single_node = _bounded_single_node


def load_yaml(path: Path, notes: list[str] | None = None) -> dict[str, Any]:
    """A YAML mapping from ``path`` (any encoding :func:`handeye._shared.io.read_text` reads; how
    it was read goes into ``notes``); one-line errors that name the file and the position."""
    path = Path(path)
    if path.name in (SESSION_FILE, POSEPAIRS_FILE):  # a folder's description: a link to elsewhere is not its
        session_file(path.parent, path, "the folder's description")
    read_as: list[str] = []
    text = _text_of(path, read_as)
    if notes is not None:
        notes.extend(read_as)
    try:
        data = yaml.load(text, Loader=_UniqueKeyLoader)
    except SessionError as exc:  # aliases beyond reason (:func:`_bounded_single_node`)
        raise SessionError(f"{path}: {exc}") from None
    except yaml.reader.ReaderError as exc:  # a character YAML does not take: most often bytes of another encoding
        line, column = text.count("\n", 0, exc.position) + 1, exc.position - text.rfind("\n", 0, exc.position)
        code = exc.character if isinstance(exc.character, int) else ord(exc.character)
        if read_as and "not UTF-8" in read_as[0]:  # the byte that made it so, where it is
            raise SessionError(f"{path}: not UTF-8 text: byte 0x{code:02X} at line {line}, column {column} is no "
                               "character (read as Windows-1252 / Latin-1, it is a control code YAML refuses); save the "
                               "file as UTF-8") from None
        raise SessionError(f"{path}: character U+{code:04X} at line {line}, column {column} is a control character YAML "
                           "refuses: remove it, or save the file as UTF-8 text") from None
    except yaml.YAMLError as exc:  # one line: the problem and where
        mark = getattr(exc, "problem_mark", None)
        at = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise SessionError(f"{path}: not valid YAML ({problem}{at})") from None
    if data is None:
        raise SessionError(f"{path}: empty file; expected a mapping of keys (see docs/guide.md)")
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
    path: Path, fmt: str, id_columns: tuple[str, ...] = ID_COLUMNS, notes: list[str] | None = None,
    times: bool = False, headerless: bool = False,
):
    """Read a CSV of poses with a header row; returns the pose values and the ids (or None), and
    with ``times=True`` the time column too (or None): ``(values, ids, times)``.

    Any encoding :func:`handeye._shared.io.read_text` reads; values separated by ',' or (a
    header without commas) by ';' with decimal commas, tabs or spaces; header names in any case.
    Columns: an optional id column (``id_columns``), with ``times=True`` an optional time column
    (``time``, ``t``, ``stamp`` or ``timestamp``), then the pose columns of ``fmt``. With
    ``headerless=True`` (streams, named explicitly) a first row of numbers is data: the columns are
    then the time and the pose columns, in that order (ETH's and TUM's trajectory files). How the
    file was read, when not plain UTF-8 CSV, goes into ``notes``. Raises :class:`SessionError`
    naming the file, line and column of anything malformed.
    """
    expected = pose_columns(fmt)
    text = _text_of(path, notes)
    delim = _delimiter(text)
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=delim, skipinitialspace=delim == " ")
    try:
        rows = [r for r in reader if r and any(c.strip() for c in r) and not r[0].lstrip().startswith("#")]
    except csv.Error as exc:
        raise SessionError(f"{path}: not a readable CSV table ({exc})") from None
    if not rows:
        raise SessionError(f"{path}: empty file; expected a header row ({', '.join(expected)}) and one row per pose")
    header = [c.strip() for c in rows[0]]
    implicit = headerless and _numeric_row(header)
    if implicit:  # no header: time, then the pose columns
        if len(header) != len(expected) + 1:
            raise SessionError(f"{path}: no header row, and its {len(header)} values per row are not a time and the "
                               f"{len(expected)} columns of {shown(fmt)}: add a header ({', '.join(expected)}, after an "
                               "'id' or a 'time' column)")
        header = [TIME_COLUMNS[0]] + expected
        rows = [header] + rows
        if notes is not None:
            notes.append(f"{path.name}: no header row; columns read as {', '.join(header)}")
    id_col = header[0] if header and header[0].lower() in id_columns else None
    rest = [c.lower() for c in (header[1:] if id_col else header)]
    time_col = rest[0] if times and rest and rest[0] in TIME_COLUMNS else None
    pose_header = rest[1:] if time_col else rest
    three_by_four = fmt == "matrix" and pose_header == expected[:12]  # 3x4 rows: the bottom row 0 0 0 1 implied
    if three_by_four:
        expected = expected[:12]
    pose_header = vendor_columns(pose_header, fmt, str(path))  # a robot maker's names for its format: FANUC's w, p, r
    if pose_header != expected:
        stream = not times and rest and rest[0] in TIME_COLUMNS
        raise SessionError(
            f"{path}: header {cut(str(header), 300)} does not match format {shown(fmt)}, which needs the columns "
            f"{', '.join(expected)} (after an '{id_columns[0]}' column)"
            + (f"; its '{rest[0]}' column makes it a stream, which this file's place does not take" if stream else ""))
    decimal_comma = delim != "," and any("," in c for r in rows[1:] for c in r)
    ids: list[str] = []
    n_num = len(expected) + (1 if time_col else 0)
    numbers = np.empty((len(rows) - 1, n_num))
    names = ([time_col] if time_col else []) + expected
    for k, row in enumerate(rows[1:]):
        line = k + (1 if implicit else 2)
        cells = [c.strip() for c in row]
        if len(cells) != len(header):
            raise SessionError(f"{path}: line {line} has {len(cells)} values, the header has {len(header)}")
        if id_col:
            ids.append(cells[0])
            cells = cells[1:]
        for c, cell in enumerate(cells):
            try:
                numbers[k, c] = float(cell.replace(",", ".") if decimal_comma else cell)
            except ValueError:
                raise SessionError(f"{path}: line {line}, column '{names[c]}': {shown(cell)} is not a number") from None
    if len(numbers) == 0:
        raise SessionError(f"{path}: no pose rows after the header")
    if id_col and any(not i for i in ids):
        raise SessionError(f"{path}: line {ids.index('') + 2} has an empty {id_col}")
    if id_col and len(set(ids)) != len(ids):
        dup = sorted({i for i in ids if ids.count(i) > 1})
        raise SessionError(f"{path}: duplicate {id_col} values [{summarize(map(repr, dup))}]")
    if notes is not None:
        if delim != ",":
            sep = {";": "semicolons", "\t": "tabs"}.get(delim, "spaces")
            notes.append(f"{path.name}: values read as separated by {sep}" + (", with decimal commas" if decimal_comma else ""))
    values = numbers[:, 1:] if time_col else numbers
    if fmt == "matrix" and np.isfinite(values).all():  # 3x4 or 4x4, row- or column-major: read and named
        layout, values = matrix_layout(values)
        if notes is not None:
            notes.append(f"{path.name}: matrices read as {layout}" + (" (R's columns, then t)" if layout == "column-major 3x4"
                                                                     else " (transposed, as Eigen or OpenGL store them)"
                                                                     if layout == "column-major 4x4" else "")
                         + (", with the bottom row 0 0 0 1" if three_by_four else ""))
    elif three_by_four:  # NaN or infinite values: named by the pose parser, in the 4x4 layout
        values = np.concatenate([values, np.tile([0.0, 0.0, 0.0, 1.0], (len(values), 1))], axis=1)
    if not times:
        return values, (ids if id_col else None)
    return values, (ids if id_col else None), (numbers[:, 0].copy() if time_col else None)


def _numeric_row(cells: list[str]) -> bool:
    try:
        [float(c) for c in cells]
    except ValueError:
        return False
    return bool(cells)


def _read_pose_file(
    path: Path, fmt: str, length_unit: str, angle_unit: str, id_columns: tuple[str, ...] = ID_COLUMNS,
    notes: list[str] | None = None,
) -> tuple[NDArray[np.float64], list[str] | None, NDArray[np.float64]]:
    """A pose CSV read and parsed into transforms (metres), with its ids and raw values; errors name
    the file and row."""
    values, ids = read_pose_table(path, fmt, id_columns=id_columns, notes=notes)
    return parsed_poses(values, fmt, length_unit, angle_unit, path), ids, values


def parsed_poses(values, fmt: str, length_unit: str, angle_unit: str, path: Path) -> NDArray[np.float64]:
    """The 4x4 poses of a pose table's ``values`` (:func:`~handeye.frames.poses.parse_poses`), a bad
    format or value a SessionError naming ``path``."""
    try:
        return parse_poses(values, fmt, length_unit, angle_unit, what=str(path))
    except PoseFormatError as exc:
        raise PoseFormatError(f"{exc} (rows count from 0 after the header)" if "row " in str(exc) else str(exc)) from None


#: What the rows of each pose file may hold: the pose handeye uses, or its inverse.
POSE_KINDS = {"robot_poses": ("flange2base", "base2flange"), "camera_poses": ("target2cam", "cam2target")}


@dataclass(frozen=True)
class _Side:
    poses: NDArray[np.float64]  #: as handeye uses them (flange2base, target2cam), metres
    ids: list[str] | None
    times: NDArray[np.float64] | None  #: seconds, when the file has a time column
    path: Path
    input: RobotPoseInput


def _read_poses(folder: Path, spec: Any, key: str, notes: list[str], where_file: str = POSEPAIRS_FILE) -> _Side:
    """One side of a pose-pair folder (``key``: robot_poses or camera_poses): the file, its
    declared format and units, ``pose`` (the rows may be the inverse of what handeye uses) and,
    for streams, ``time_unit``."""
    where = f"{folder / where_file}: {key}"
    if not isinstance(spec, dict):
        raise SessionError(f"{where}: expected a mapping with file, format, length_unit, angle_unit")
    path = folder / str(_require(spec, "file", where))
    if where_file == POSEPAIRS_FILE:  # a pose-pair folder's own file (streams named on the command line are the user's)
        session_file(folder, path, f"the {key} table")
    fmt = str(_require(spec, "format", where))
    length_unit = str(_require(spec, "length_unit", where))
    angle_unit = str(spec.get("angle_unit", "rad"))
    kinds = POSE_KINDS[key]
    kind = str(spec.get("pose", kinds[0]))
    if kind not in kinds:
        raise SessionError(f"{where}: pose {shown(kind)}; use {kinds[0]} (the default) or {kinds[1]} (rows of the inverse)")
    scale = time_unit_scale(spec, where)
    values, ids, times = read_pose_table(path, fmt, notes=notes, times=True, headerless=True)
    T = parsed_poses(values, fmt, length_unit, angle_unit, path)
    inverted = kind == kinds[1]
    if inverted:
        T = invert(T)
    return _Side(T, ids, None if times is None else times * scale, path,
                 RobotPoseInput(values, fmt, length_unit, angle_unit, inverted))


def _paired(robot: _Side, camera: _Side) -> tuple[NDArray[np.float64], RobotPoseInput, list[str]]:
    """The camera poses in the robot rows' order (by id when both have ids, else by row), their
    input as written in that order, and the ids."""
    if robot.ids is not None and camera.ids is not None:
        missing = sorted(set(robot.ids) ^ set(camera.ids))
        if missing:
            raise InputMismatchError(
                f"ids [{summarize(map(repr, missing))}] appear in only one of {robot.path.name} and {camera.path.name}; every "
                f"robot pose needs its camera pose")
        row_of = {k: n for n, k in enumerate(camera.ids)}
        order = [row_of[k] for k in robot.ids]
        return camera.poses[order], replace(camera.input, values=camera.input.values[order]), robot.ids
    if len(robot.poses) != len(camera.poses):
        raise InputMismatchError(
            f"{robot.path.name} has {len(robot.poses)} poses but {camera.path.name} has {len(camera.poses)}; they pair "
            f"row by row (or add an 'id' column to both, or a time column to both for streams)")
    return camera.poses, camera.input, robot.ids or camera.ids or [str(k) for k in range(len(robot.poses))]


def _paired_delays(robot: _Side, camera: _Side) -> NDArray[np.float64] | None:
    """For streams whose rows also carry ids: per id in both, the camera time minus the robot time
    (how the user paired them)."""
    if robot.ids is None or camera.ids is None:
        return None
    t_robot = dict(zip(robot.ids, robot.times))
    common = [(k, t) for k, t in zip(camera.ids, camera.times) if k in t_robot]
    if not common:
        return None
    return np.array([t - t_robot[k] for k, t in common])


def _missing_folder_file(folder: Path, name: str) -> None:
    """Raise :class:`SessionError` for a folder without its description file ``name``, saying
    which kind of folder it is when it holds the other kind's file, and how to make one if not."""
    if (folder / name).is_dir():
        raise SessionError(f"{folder / name}: is a folder, not a file")
    other = POSEPAIRS_FILE if name == SESSION_FILE else SESSION_FILE
    if (folder / other).is_file():
        kind, call = (("a pose-pair folder", "`handeye calibrate-poses` (Python: load_pose_pairs, then calibrate_poses)")
                      if other == POSEPAIRS_FILE else ("a capture session", "`handeye calibrate` (Python: handeye.calibrate)"))
        raise SessionError(f"{folder}: holds {other}, not {name}: it is {kind}; calibrate it with {call}")
    what, example = (("a capture session: session.yaml (setup, target, camera, poses file), the robot poses and "
                      "images/", "sample_session") if name == SESSION_FILE else
                     ("pose pairs: posepairs.yaml (setup, robot_poses, camera_poses) and the two pose files",
                      "example_posepairs"))
    raise SessionError(f"{folder}: no {name}. The folder must hold {what} (docs/guide.md shows the layout; an "
                       f"example is the package's data/{example}); `handeye import` makes one from a ROS bag, ViSP, "
                       "easy_handeye or industrial_calibration data")


def load_pose_pairs(folder: str | Path) -> PosePairs:
    """Load a pose-pair folder (see the module docstring); with a time column in both files, two
    streams (:attr:`PosePairs.robot_times`, :attr:`PosePairs.camera_times`; rows not paired).

    Raises
    ------
    SessionError
        Missing folder, file or key; malformed CSV; a time column in only one file.
    PoseFormatError
        Pose values that do not fit their declared format or units.
    InputMismatchError
        Unknown setup; robot and camera rows that do not pair up.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise SessionError(f"{folder}: no such folder")
    if not (folder / POSEPAIRS_FILE).is_file():
        _missing_folder_file(folder, POSEPAIRS_FILE)
    notes: list[str] = []
    spec = load_yaml(folder / POSEPAIRS_FILE, notes)
    where = str(folder / POSEPAIRS_FILE)
    setup = check_setup(str(_require(spec, "setup", where)))
    robot = _read_poses(folder, _require(spec, "robot_poses", where), "robot_poses", notes)
    camera = _read_poses(folder, _require(spec, "camera_poses", where), "camera_poses", notes)
    return _pairs_or_streams(setup, robot, camera, folder, notes)


def load_pose_streams(robot_spec: dict[str, Any], camera_spec: dict[str, Any], setup: str,
                      folder: str | Path = ".") -> PosePairs:
    """Two stream files described as in ``posepairs.yaml`` (``file`` relative to ``folder``), e.g.
    from the command line; both must have a time column (or no header: time, then the pose columns)."""
    folder = Path(folder)
    notes: list[str] = []
    setup = check_setup(setup)
    robot = _read_poses(folder, robot_spec, "robot_poses", notes, where_file="(robot stream)")
    camera = _read_poses(folder, camera_spec, "camera_poses", notes, where_file="(camera stream)")
    for side in (robot, camera):
        _require_times(side)
    return _pairs_or_streams(setup, robot, camera, robot.path.parent, notes)


def _require_times(side: _Side) -> None:
    """A stream file's side must have a time column."""
    if side.times is None:
        raise SessionError(f"{side.path}: no time column; a stream needs one (header 'time', then the pose columns)")


def load_camera_stream(spec: dict[str, Any], folder: str | Path = ".") -> tuple[NDArray[np.float64], NDArray[np.float64],
                                                                              list[str]]:
    """One camera stream file described as in ``posepairs.yaml``'s ``camera_poses`` (``file``
    relative to ``folder``, with a time column): its times (s), ``target2cam`` poses and notes."""
    notes: list[str] = []
    camera = _read_poses(Path(folder), spec, "camera_poses", notes, where_file="(camera stream)")
    _require_times(camera)
    return camera.times, camera.poses, notes


def _pairs_or_streams(setup: str, robot: _Side, camera: _Side, folder: Path, notes: list[str]) -> PosePairs:
    if (robot.times is None) != (camera.times is None):
        has, lacks = (robot, camera) if robot.times is not None else (camera, robot)
        raise SessionError(f"{has.path.name} has a time column but {lacks.path.name} has none: give both times "
                           "(two streams, paired by time) or neither (poses paired by id or row)")
    if robot.times is not None:
        ids = robot.ids if robot.ids is not None else [f"{t:.6f}" for t in robot.times]
        return PosePairs(setup, robot.poses, camera.poses, ids, folder, robot.input, notes, camera.input,
                         robot.times, camera.times, _paired_delays(robot, camera))
    t2c, camera_input, ids = _paired(robot, camera)
    return PosePairs(setup, robot.poses, t2c, ids, folder, robot.input, notes, camera_input)


def read_intrinsics(path: str | Path) -> tuple[NDArray[np.float64], NDArray[np.float64], tuple[int, int]]:
    """K, dist and image size from a YAML file (top level, or under ``camera:`` as in session.yaml)."""
    p = Path(path)
    data = load_yaml(p)
    cam = data["camera"] if isinstance(data.get("camera"), dict) else data
    size = cam.get("image_size", data.get("image_size"))
    if size is None and "K" in cam and (p.parent / "images").is_dir():  # a session.yaml: the images' size
        size = _image_size(p.parent / "images")
    if "K" not in cam or size is None:
        raise SessionError(f"{p}: needs K: [[fx,0,cx],[0,fy,cy],[0,0,1]] and image_size: [width, height] "
                           "(dist optional), at the top level or under camera: (a session.yaml with K and "
                           "images/ beside it will do)")
    K, dist = read_camera({"K": cam["K"], "dist": cam.get("dist") or [0.0] * 5}, str(p))
    try:
        w, h = (int(v) for v in size)
    except (TypeError, ValueError):
        raise SessionError(f"{p}: image_size must be [width, height]") from None
    if w <= 0 or h <= 0:
        raise SessionError(f"{p}: image_size must be positive")
    return K, dist, (w, h)


def _image_size(folder: Path) -> tuple[int, int] | None:
    """The size (width, height) of the first image in ``folder`` that OpenCV can read, or None."""
    for p in sorted(folder.iterdir()):
        if p.suffix.lower() in IMAGE_SUFFIXES:
            img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
            if img is not None:
                return img.shape[1], img.shape[0]
    return None


def _number(v: float) -> str:
    """The one number format of the files handeye writes: the shortest text that reads back exactly."""
    return repr(float(v))


def write_pose_table(path: str | Path, names: list[str], flange2base: NDArray[np.float64] | None,
                     format: str = "quat_wxyz", length_unit: str = "m", angle_unit: str = "rad",
                     protect: Iterable[str | Path] = (), id_column: str = "image",
                     rows: NDArray[np.float64] | None = None) -> Path:
    """Write poses as a session ``poses.csv`` (``image`` column first, or ``id_column``) in the given
    format and units, atomically and never over a ``protect`` path; returns the path. ``rows``: the
    values as written already (a robot's own report), instead of ``flange2base``."""
    if rows is None:
        rows = format_poses(flange2base, format, length_unit, angle_unit)
    else:
        rows = np.asarray(rows, dtype=float)
        parse_poses(rows, format, length_unit, angle_unit)  # they must read back
    if len(names) != len(rows):
        raise InputMismatchError(f"{len(names)} image names for {len(rows)} poses")
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([id_column] + pose_columns(format))
    for name, row in zip(names, rows):
        w.writerow([name] + [_number(v) for v in row])
    path = Path(path)
    atomic_write(path, buf.getvalue(), protect)
    return path


def write_session(folder: str | Path, setup: str, target_spec: dict[str, Any], names: list[str],
                  flange2base: NDArray[np.float64] | None, format: str = "quat_wxyz", length_unit: str = "mm",
                  angle_unit: str = "deg", camera: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
                  comment: str | None = None, rows: NDArray[np.float64] | None = None) -> Path:
    """Write ``session.yaml`` and ``poses.csv`` of a session (the session format in docs/guide.md) into ``folder``, atomically;
    the images (``images/<name>``) are the caller's. ``camera``: ``(K, dist)`` to put in
    session.yaml. Returns the session.yaml path."""
    folder = Path(folder)
    setup = check_setup(setup)
    target_from_spec(target_spec)
    write_pose_table(folder / "poses.csv", names, flange2base, format, length_unit, angle_unit, rows=rows)
    poses = {"file": "poses.csv", "format": format, "length_unit": length_unit, "angle_unit": angle_unit}
    return _write_session_yaml(folder, setup, target_spec, camera, poses, None, comment)


def write_joint_table(path: str | Path, names: list[str], joints: NDArray[np.float64], unit: str = "deg",
                      id_column: str = "image", joint_names: list[str] | None = None) -> Path:
    """Write joint angles ``joints`` (N, n; radians) as a session's ``joints.csv``: an ``id_column``
    naming each view, then one column per joint (``joint_names`` or ``joint1`` ...) in ``unit``
    (deg or rad), atomically; returns the path."""
    q = np.asarray(joints, dtype=float)
    q = np.degrees(q) if unit == "deg" else q
    columns = list(joint_names) if joint_names is not None else [f"joint{k + 1}" for k in range(q.shape[1])]
    lines = [f"{id_column}," + ",".join(columns)]
    lines += [f"{n}," + ",".join(_number(v) for v in row) for n, row in zip(names, q)]
    path = Path(path)
    atomic_write(path, "\n".join(lines) + "\n")
    return path


def write_joint_session(folder: str | Path, setup: str, target_spec: dict[str, Any], names: list[str],
                        joints: NDArray[np.float64], arm: str, flange2base: NDArray[np.float64] | None = None,
                        camera: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
                        comment: str | None = None, joint_names: list[str] | None = None, unit: str = "deg") -> Path:
    """Write ``session.yaml`` and ``joints.csv`` (``unit``, an ``image`` column then one per joint,
    named ``joint_names`` or ``joint1`` ...) of a session whose robot side is joint angles
    ``joints`` (N, n; radians) of ``arm`` (a shipped arm's name, or a table or URDF file in the
    folder), with the controller's ``flange2base`` in ``poses.csv`` too when given; atomically.
    The images are the caller's. Returns the session.yaml path."""
    folder = Path(folder)
    setup = check_setup(setup)
    target_from_spec(target_spec)
    write_joint_table(folder / "joints.csv", names, joints, unit, joint_names=joint_names)
    poses = None
    if flange2base is not None:
        write_pose_table(folder / "poses.csv", names, flange2base, "quat_wxyz", "mm", "deg")
        poses = {"file": "poses.csv", "format": "quat_wxyz", "length_unit": "mm", "angle_unit": "deg"}
    return _write_session_yaml(folder, setup, target_spec, camera, poses, None, comment,
                               joints={"file": "joints.csv", "unit": unit, "arm": arm})


def _write_session_yaml(folder: Path, setup: str, target_spec: dict[str, Any], camera, poses: dict[str, Any] | None,
                        images: dict[str, Any] | None, comment: str | None, joints: dict[str, Any] | None = None) -> Path:
    """session.yaml with its keys in the order of the session format (docs/guide.md), atomically; returns its path."""
    spec: dict[str, Any] = {"setup": setup, "target": dict(target_spec)}
    if camera is not None:
        spec["camera"] = {"K": np.asarray(camera[0], dtype=float).tolist(),
                          "dist": np.asarray(camera[1], dtype=float).ravel().tolist()}
    if poses is not None:
        spec["poses"] = poses
    if joints is not None:
        spec["joints"] = joints
    if images is not None:
        spec["images"] = images
    text = (f"# {comment}\n" if comment else "") + yaml.safe_dump(spec, sort_keys=False)
    atomic_write(folder / SESSION_FILE, text)
    return folder / SESSION_FILE


def write_joint_stream(path: str | Path, times: NDArray[np.float64], joints: NDArray[np.float64],
                       joint_names: list[str] | None = None, unit: str = "rad") -> Path:
    """Write time-stamped joint angles (``joints`` (N, n) in radians, ``times`` in seconds) as the
    CSV :func:`load_joint_stream` reads: a ``time`` column, then one per joint named
    ``joint_names`` (or joint1 ...), in ``unit``; atomically. Returns the path."""
    q = np.asarray(joints, dtype=float)
    times = np.asarray(times, dtype=float)
    if q.ndim != 2 or len(times) != len(q):
        raise InputMismatchError(f"{len(times)} times for joint angles of shape {q.shape}")
    if unit not in ("deg", "rad"):
        raise InputMismatchError(f"joint unit {shown(unit)}; use deg or rad")
    q = np.degrees(q) if unit == "deg" else q
    columns = list(joint_names) if joint_names is not None else [f"joint{k + 1}" for k in range(q.shape[1])]
    if len(columns) != q.shape[1]:
        raise InputMismatchError(f"{len(columns)} joint names for {q.shape[1]} joints")
    lines = ["time," + ",".join(columns)]
    lines += [_number(t) + "," + ",".join(_number(v) for v in row) for t, row in zip(times, q)]
    atomic_write(Path(path), "\n".join(lines) + "\n")
    return Path(path)


def write_pose_stream(path: str | Path, times: NDArray[np.float64], poses: NDArray[np.float64], format: str = "quat_xyzw",
                      length_unit: str = "m", angle_unit: str = "rad", ids: list[str] | None = None) -> Path:
    """Write time-stamped poses (a stream, seconds) as a CSV with a ``time`` column (after an ``id``
    column when ``ids`` are given), atomically; returns the path."""
    rows = format_poses(poses, format, length_unit, angle_unit)
    times = np.asarray(times, dtype=float)
    if len(times) != len(rows) or (ids is not None and len(ids) != len(rows)):
        raise InputMismatchError(f"{len(times)} times{'' if ids is None else f', {len(ids)} ids'} for {len(rows)} poses")
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow((["id"] if ids is not None else []) + ["time"] + pose_columns(format))
    for k, row in enumerate(rows):
        w.writerow(([ids[k]] if ids is not None else []) + [_number(times[k])] + [_number(v) for v in row])
    path = Path(path)
    atomic_write(path, buf.getvalue())
    return path


def write_stream_session(folder: str | Path, setup: str, target_spec: dict[str, Any], robot_times: NDArray[np.float64],
                         flange2base: NDArray[np.float64], image_names: list[str], image_times: NDArray[np.float64],
                         format: str = "quat_xyzw", length_unit: str = "m", angle_unit: str = "rad",
                         camera: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
                         comment: str | None = None) -> Path:
    """Write ``session.yaml`` of a session whose poses are a robot stream: ``robot.csv`` (time, then
    the pose columns) and ``images.csv`` (image, time on the camera's clock); the images are the
    caller's. Returns the session.yaml path."""
    folder = Path(folder)
    setup = check_setup(setup)
    target_from_spec(target_spec)
    if len(image_names) != len(image_times):
        raise InputMismatchError(f"{len(image_names)} image names for {len(image_times)} image times")
    write_pose_stream(folder / "robot.csv", robot_times, flange2base, format, length_unit, angle_unit)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["image", "time"])
    for name, t in zip(image_names, image_times):
        w.writerow([name, _number(t)])
    atomic_write(folder / "images.csv", buf.getvalue())
    poses = {"file": "robot.csv", "format": format, "length_unit": length_unit, "angle_unit": angle_unit, "time_unit": "s"}
    return _write_session_yaml(folder, setup, target_spec, camera, poses, {"file": "images.csv", "time_unit": "s"},
                               comment)


def write_pose_pairs(folder: str | Path, setup: str, flange2base: NDArray[np.float64], target2cam: NDArray[np.float64],
                     robot_times: NDArray[np.float64] | None = None, camera_times: NDArray[np.float64] | None = None,
                     ids: list[str] | None = None, comment: str | None = None) -> Path:
    """Write a pose-pair folder (``posepairs.yaml``, ``robot_poses.csv``, ``camera_poses.csv``; poses
    as quat_xyzw in metres): pairs by id (``ids``, default row numbers) or, with both ``*_times``,
    two streams. Returns the posepairs.yaml path."""
    folder = Path(folder)
    setup = check_setup(setup)
    if (robot_times is None) != (camera_times is None):
        raise InputMismatchError("give both robot_times and camera_times (streams) or neither (pairs)")
    if robot_times is not None:
        write_pose_stream(folder / "robot_poses.csv", robot_times, flange2base)
        write_pose_stream(folder / "camera_poses.csv", camera_times, target2cam)
    else:
        if len(flange2base) != len(target2cam):
            raise InputMismatchError(f"{len(flange2base)} robot poses for {len(target2cam)} camera poses")
        names = ids if ids is not None else [f"{k:04d}" for k in range(len(flange2base))]
        write_pose_table(folder / "robot_poses.csv", names, flange2base, "quat_xyzw", "m", "rad", id_column="id")
        write_pose_table(folder / "camera_poses.csv", names, target2cam, "quat_xyzw", "m", "rad", id_column="id")
    side = {"format": "quat_xyzw", "length_unit": "m", "angle_unit": "rad"}
    spec = {"setup": setup, "robot_poses": {"file": "robot_poses.csv", **side},
            "camera_poses": {"file": "camera_poses.csv", **side}}
    text = (f"# {comment}\n" if comment else "") + yaml.safe_dump(spec, sort_keys=False)
    atomic_write(folder / POSEPAIRS_FILE, text)
    return folder / POSEPAIRS_FILE
