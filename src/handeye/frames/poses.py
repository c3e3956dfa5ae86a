"""Robot pose formats: parse rows of numbers into ``flange2base`` stacks, and write them back.

Formats (named explicitly, never guessed):

=================  =======================================  ==================================
format             columns                                  notes
=================  =======================================  ==================================
``matrix``         m00 m01 ... m33 (16, row-major)          last row must be 0 0 0 1; or 12 (3x4, row- or column-major)
``quat_wxyz``      x y z qw qx qy qz                        ROS-style order is ``quat_xyzw``
``quat_xyzw``      x y z qx qy qz qw
``rotvec``         x y z rx ry rz                           axis * angle (Universal Robots)
``euler:SEQ``      x y z a b c                              scipy sequence: ``ZYX`` intrinsic
                                                            (KUKA A,B,C), ``xyz`` extrinsic
                                                            (Fanuc W,P,R)
=================  =======================================  ==================================

Lengths in ``m`` or ``mm`` (the library works in metres); angles in ``deg`` or ``rad`` (rotvec
and euler only).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from .._shared.text import shown
from ..errors import InputMismatchError, PoseFormatError
from ..geometry.se3 import invert, make_transform, orthonormality_error

__all__ = ["parse_poses", "format_poses", "pose_columns", "validate_transforms", "matrix_layout", "RobotPoseInput", "FORMATS",
           "VENDOR_COLUMNS", "vendor_columns"]

FORMATS = ("matrix", "quat_wxyz", "quat_xyzw", "rotvec", "euler:<SEQ>")
LENGTH_UNITS = {"m": 1.0, "mm": 1e-3}
ANGLE_UNITS = ("rad", "deg")

#: Largest deviation of a rotation matrix from orthonormality (max |R^T R - I|) that is accepted and
#: re-orthonormalised. Controllers print 6 decimals (~1e-6); 1e-4 leaves room and still rejects junk.
ORTHONORMAL_TOL = 1e-4
#: Largest accepted deviation of a quaternion's norm from 1.
QUAT_NORM_TOL = 1e-3

_EULER_RE = re.compile(r"^euler:([xyzXYZ]{3})$")


@dataclass(frozen=True)
class RobotPoseInput:
    """The robot poses as written (values, declared format and units), so that other readings can
    be tried (:func:`handeye.diagnose`) and results given in the same convention. ``values`` as
    for :func:`parse_poses`."""

    values: NDArray[np.float64]
    format: str
    length_unit: str = "m"
    angle_unit: str = "rad"
    #: the rows are the inverse of the poses used (base2flange rows for flange2base, cam2target rows for target2cam)
    inverted: bool = False

    def rewritten(self, T: ArrayLike) -> "RobotPoseInput":
        """The same declaration with the poses ``T`` (as handeye uses them) written as its rows: for poses
        that were derived from the rows (interpolated between them), so that the check re-reads them."""
        T = np.asarray(T, dtype=float)
        rows = format_poses(invert(T) if self.inverted else T, self.format, self.length_unit, self.angle_unit)
        return replace(self, values=rows)


def _parse_format(fmt: str) -> tuple[str, str | None]:
    if not isinstance(fmt, str):
        raise PoseFormatError(f"pose format must be a string, got {shown(fmt)}; one of {', '.join(FORMATS)}")
    if fmt in ("matrix", "quat_wxyz", "quat_xyzw", "rotvec"):
        return fmt, None
    m = _EULER_RE.match(fmt)
    if m:
        seq = m.group(1)
        if not (seq.isupper() or seq.islower()):
            raise PoseFormatError(
                f"Euler sequence {shown(seq)} mixes cases: use upper case for intrinsic rotations "
                f"(e.g. 'euler:ZYX', KUKA A,B,C) or lower case for extrinsic ones (e.g. 'euler:xyz', Fanuc W,P,R)"
            )
        s = seq.lower()
        if s[0] == s[1] or s[1] == s[2]:
            raise PoseFormatError(f"Euler sequence {shown(seq)} repeats an axis in consecutive rotations")
        return "euler", seq
    raise PoseFormatError(
        f"unknown pose format {shown(fmt)}; use one of: matrix, quat_wxyz, quat_xyzw, rotvec, "
        f"euler:<sequence> (e.g. euler:ZYX intrinsic, euler:xyz extrinsic)"
    )


def pose_columns(fmt: str) -> list[str]:
    """The column names of a pose format, as written in ``poses.csv`` (the session format in docs/guide.md)."""
    kind, _ = _parse_format(fmt)
    if kind == "matrix":
        return [f"m{i}{j}" for i in range(4) for j in range(4)]
    rot = {
        "quat_wxyz": ["qw", "qx", "qy", "qz"],
        "quat_xyzw": ["qx", "qy", "qz", "qw"],
        "rotvec": ["rx", "ry", "rz"],
        "euler": ["a", "b", "c"],
    }[kind]
    return ["x", "y", "z"] + rot


def _check_units(length_unit: str, angle_unit: str, what: str = "poses") -> float:
    if length_unit not in LENGTH_UNITS:
        raise PoseFormatError(f"{what}: unknown length unit {shown(length_unit)}; use 'm' or 'mm'")
    if angle_unit not in ANGLE_UNITS:
        raise PoseFormatError(f"{what}: unknown angle unit {shown(angle_unit)}; use 'rad' or 'deg'")
    return LENGTH_UNITS[length_unit]


def _as_rows(values: ArrayLike, kind: str, what: str) -> NDArray[np.float64]:
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError) as exc:
        raise PoseFormatError(f"{what}: values are not numbers ({exc})") from None
    if kind == "matrix" and arr.ndim == 3 and arr.shape[1:] == (4, 4):
        arr = arr.reshape(len(arr), 16)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2:
        raise PoseFormatError(f"{what}: expected a table of shape (N, columns), got shape {arr.shape}")
    return arr


def parse_poses(
    values: ArrayLike,
    format: str = "quat_wxyz",
    length_unit: str = "m",
    angle_unit: str = "rad",
    *,
    what: str = "robot poses",
) -> NDArray[np.float64]:
    """Parse rows of pose values into a stack of 4x4 transforms (lengths in metres).

    Parameters
    ----------
    values : array_like, shape (N, k)
        One pose per row, columns as in the module table. ``matrix`` also accepts ``(N, 4, 4)``.
    format : str
        ``matrix``, ``quat_wxyz``, ``quat_xyzw``, ``rotvec`` or ``euler:SEQ`` with a scipy sequence
        (upper case = intrinsic, lower case = extrinsic).
    length_unit : {'m', 'mm'}
    angle_unit : {'rad', 'deg'}
        Used by ``rotvec`` and ``euler``.
    what : str
        How the rows are named in error messages.

    Returns
    -------
    T : ndarray, shape (N, 4, 4)

    Raises
    ------
    PoseFormatError
        Naming the row: wrong column count, NaN/inf, quaternion norm off by more than 1e-3,
        rotation matrix not orthonormal (with its deviation), unknown format or unit, and values
        that cannot be in the declared unit (e.g. metres of tens of metres, radians beyond 2 pi).

    Examples
    --------
    A KUKA controller's X, Y, Z (mm) and A, B, C (deg, intrinsic ZYX):

    >>> from handeye import parse_poses
    >>> T = parse_poses([[500.0, 0.0, 300.0, 90.0, 0.0, 180.0]], format="euler:ZYX", length_unit="mm", angle_unit="deg")
    >>> T.shape, T[0, :3, 3].round(3).tolist()
    ((1, 4, 4), [0.5, 0.0, 0.3])
    """
    kind, seq = _parse_format(format)
    scale = _check_units(length_unit, angle_unit, what)
    rows = _as_rows(values, kind, what)
    ncols = len(pose_columns(format))
    if kind == "matrix" and rows.ndim == 2 and rows.shape[1] == 12:  # 3x4, row- or column-major: as 16 row-major
        # values (16 values are read row-major: a transposed layout is named by the checks below, as it cannot
        # be told from a wrong bottom row in one pose; session files, read whole, are named and transposed)
        rows = matrix_layout(rows)[1] if np.isfinite(rows).all() else np.concatenate(
            [rows, np.tile([0.0, 0.0, 0.0, 1.0], (len(rows), 1))], axis=1)
    if rows.shape[1] != ncols:
        raise PoseFormatError(
            f"{what}: format {shown(format)} needs {ncols} columns ({' '.join(pose_columns(format))}), "
            f"got {rows.shape[1]}"
        )
    if len(rows) == 0:
        raise PoseFormatError(f"{what}: no poses given")
    bad = ~np.isfinite(rows)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise PoseFormatError(
            f"{what}: row {i} column {shown(pose_columns(format)[j])} is {rows[i, j]} (NaN or infinite); "
            f"{int(bad.any(axis=1).sum())} row(s) affected"
        )

    if kind == "matrix":
        T = validate_transforms(rows.reshape(-1, 4, 4), what=what)  # names a transposed layout
        T[:, :3, 3] *= scale
    else:
        t = rows[:, :3] * scale
        rot = rows[:, 3:]
        if kind in ("quat_wxyz", "quat_xyzw"):
            norm = _norms(rot)
            off = np.abs(norm - 1.0)
            if (off > QUAT_NORM_TOL).any():
                i = int(np.argmax(off))
                raise PoseFormatError(
                    f"{what}: row {i}: quaternion norm is {norm[i]:.6g}, not 1 (tolerance {QUAT_NORM_TOL}); "
                    f"check the column order ({format}) and that all four components are present"
                )
            R = Rotation.from_quat(rot, scalar_first=(kind == "quat_wxyz")).as_matrix()
        else:
            ang = np.deg2rad(rot) if angle_unit == "deg" else rot
            mag = _norms(rot) if kind == "rotvec" else np.abs(rot).max(axis=1)
            if angle_unit == "rad" and (mag > 2 * np.pi + 1e-6).any():
                i = int(np.argmax(mag))
                raise PoseFormatError(
                    f"{what}: row {i}: rotation of {mag[i]:.4g} rad exceeds 2 pi; "
                    f"the angles look like degrees: declare angle_unit 'deg'"
                )
            if angle_unit == "deg" and (mag > 360.0 + 1e-4).any():  # 1e155 deg gave NaN rotations
                i = int(np.argmax(mag))
                raise PoseFormatError(
                    f"{what}: row {i}: rotation of {np.abs(rot[i]).max():.4g} deg or more exceeds 360 deg, not the angle of a pose; "
                    f"check the column order ({format}) and the units"
                )
            if kind == "rotvec":
                R = Rotation.from_rotvec(ang).as_matrix()
            else:
                R = Rotation.from_euler(seq, ang).as_matrix()
        T = make_transform(R, t)
    _check_lengths(T[:, :3, 3], length_unit, what)
    return T


def _norms(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Row norms; values near 1e308 give an infinite norm (refused by the checks), not a warning."""
    with np.errstate(over="ignore"):
        return np.linalg.norm(v, axis=1)


def _check_lengths(t: NDArray[np.float64], length_unit: str, what: str) -> None:
    """Reject translations that cannot be robot flange positions (or camera-to-target distances)
    in the declared unit."""
    dist = _norms(t)
    if length_unit == "m" and np.median(dist) > 20.0:
        raise PoseFormatError(
            f"{what}: the median distance of the poses from their frame's origin is {np.median(dist):.4g} m, "
            f"more than any robot arm reaches or camera sees a target at; the lengths look like millimetres: "
            f"declare length_unit 'mm'"
        )
    if length_unit == "mm" and len(t) > 1 and dist.max() < 2e-3:
        raise PoseFormatError(
            f"{what}: every position is within {dist.max() * 1e3:.3g} mm of its frame's origin; "
            f"the lengths look like metres: declare length_unit 'm'"
        )


def _rotations_exact(T: NDArray[np.float64], tol: float = 5e-14) -> bool:
    """True when every rotation block of a stack ``(N, 4, 4)`` whose bottom rows are ``0 0 0 1``
    is a proper rotation to within ``tol`` (first two rows orthonormal, third their cross
    product; the default keeps every entry of ``R^T R - I`` within 1e-13); NaN fails. The fast
    path of :func:`validate_transforms`: with the rotation rows a, b, c and ``w = T[3, 3] = 1``,
    ``[a.a - w^2, b.b - w^2, a.b, a x b - w c]`` are all zero exactly when the rows are orthonormal
    and right-handed (``c = a x b`` then has unit length and is orthogonal to both); a few products
    of whole columns, several times cheaper than ``R^T R`` and ``det`` on stacks of small matrices.
    Inputs that fail it take the full checks. The products run on strided column views of blocks
    small enough to stay in cache: a transposed copy first costs more than it saves (measured,
    9,900 matrices: 0.26 vs 0.98 ms), and column passes over a whole large stack reread it from
    memory each time (42,000 matrices: 4.4 ms in one block)."""
    flat = T.reshape(-1, 16)
    for start in range(0, len(flat), _EXACT_BLOCK):
        a0, a1, a2, _, b0, b1, b2, _, c0, c1, c2, _, _, _, _, w = flat[start:start + _EXACT_BLOCK].T
        ww = w * w
        residuals = (a0 * a0 + a1 * a1 + a2 * a2 - ww, b0 * b0 + b1 * b1 + b2 * b2 - ww, a0 * b0 + a1 * b1 + a2 * b2,
                     a1 * b2 - a2 * b1 - c0 * w, a2 * b0 - a0 * b2 - c1 * w, a0 * b1 - a1 * b0 - c2 * w)
        if not all(np.abs(r).max(initial=0.0) <= tol for r in residuals):  # NaN compares False: fails
            return False
    return True


#: Matrices per block of :func:`_rotations_exact` (512 KiB of 4x4 doubles).
_EXACT_BLOCK = 4096


def validate_transform_pair(
    A: ArrayLike, B: ArrayLike, what: tuple[str, str], counted: tuple[str, str], tol: float = ORTHONORMAL_TOL
) -> NDArray[np.float64]:
    """:func:`validate_transforms` of two stacks that pair up, returned as one ``(2, N, 4, 4)`` array.

    Both ``(N, 4, 4)``: one call on the two stacked (the common case); when that fails, or the
    shapes differ, each stack is checked on its own, for its message (``what``). Different lengths
    raise :class:`InputMismatchError` counting them as ``counted`` (e.g. ``("poses A", "poses B")``).
    """
    try:
        T = np.array((A, B), dtype=float)
    except (TypeError, ValueError):  # different lengths, ragged or non-numeric: checked one by one
        T = None
    if T is not None and T.ndim == 4 and T.shape[-2:] == (4, 4):
        try:
            return _validated(T.reshape(-1, 4, 4), "", tol).reshape(T.shape)  # T is ours: checked in place
        except PoseFormatError:
            pass  # checked one by one below, for a message naming the stack and its entry
    A, B = validate_transforms(A, what[0], tol), validate_transforms(B, what[1], tol)
    if len(A) != len(B):
        raise InputMismatchError(f"{len(A)} {counted[0]} but {len(B)} {counted[1]}; they come in pairs")
    return np.stack((A, B))


def validate_transforms(T: ArrayLike, what: str = "transforms", tol: float = ORTHONORMAL_TOL) -> NDArray[np.float64]:
    """Check a stack of 4x4 transforms and return a copy with exactly orthonormal rotations.

    Raises :class:`PoseFormatError` naming the first bad entry: wrong shape, NaN/inf, a rotation
    block that is not orthonormal within ``tol`` (max ``|R^T R - I|``) or that is a reflection.
    """
    try:
        T = np.array(T, dtype=float)
    except (TypeError, ValueError) as exc:
        raise PoseFormatError(f"{what}: values are not numbers ({exc})") from None
    if T.ndim == 2:
        T = T[None]
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise PoseFormatError(f"{what}: expected a stack of 4x4 transforms (N, 4, 4), got shape {T.shape}")
    return _validated(T, what, tol)


#: How far a 4x4's bottom row may be from [0, 0, 0, 1] (rounding in a file, float32 storage).
BOTTOM_ROW_TOL = 1e-6


def matrix_layout(rows: NDArray[np.float64]) -> tuple[str, NDArray[np.float64]]:
    """How rows of 12 or 16 matrix values are laid out, and the rows as 16 row-major values.

    16 values: row-major 4x4 when the bottom row is 0 0 0 1, column-major (Eigen, OpenGL) when the last
    column is and the bottom row is not. 12 values: the top 3x4 of a transform, row-major (R | t by
    rows) or column-major (R's columns, then t: Eigen's and many controllers' dumps), told apart by
    which reading gives orthonormal rotations; row-major when both or neither do (the checks that
    follow then name what is wrong). Returns ``("row-major 4x4" | "column-major 4x4" | "row-major 3x4"
    | "column-major 3x4", rows (N, 16))``.
    """
    n = len(rows)
    if rows.shape[1] == 16:
        M = rows.reshape(n, 4, 4)
        unit = np.array([0.0, 0.0, 0.0, 1.0])
        bottom = np.abs(M[:, 3] - unit).max(initial=0.0) <= BOTTOM_ROW_TOL
        last = np.abs(M[:, :, 3] - unit).max(initial=0.0) <= BOTTOM_ROW_TOL
        if last and not bottom:
            return "column-major 4x4", np.swapaxes(M, 1, 2).reshape(n, 16)
        return "row-major 4x4", rows
    by_rows = rows.reshape(n, 3, 4)
    by_columns = np.swapaxes(rows.reshape(n, 4, 3), 1, 2)
    layout, top = "row-major 3x4", by_rows
    if (orthonormality_error(by_rows[:, :, :3]).max(initial=0.0) > ORTHONORMAL_TOL
            and orthonormality_error(by_columns[:, :, :3]).max(initial=0.0) <= ORTHONORMAL_TOL):
        layout, top = "column-major 3x4", by_columns
    return layout, np.concatenate([top.reshape(n, 12), np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))], axis=1)


def _check_bottom_rows(T: NDArray[np.float64], what: str) -> None:
    """A bottom row other than [0, 0, 0, 1] is an error; one holding the translation (with the last
    column empty) is named as a transposed, column-major matrix."""
    bottom = T[:, 3]
    if np.abs(bottom[:, :3]).max(initial=0.0) <= BOTTOM_ROW_TOL and np.abs(bottom[:, 3] - 1.0).max(initial=0.0) <= BOTTOM_ROW_TOL:
        return  # the common case, in two reductions
    off = np.abs(bottom - [0.0, 0.0, 0.0, 1.0]).max(axis=1)
    off[np.isnan(off)] = np.inf
    i = int(np.argmax(off > BOTTOM_ROW_TOL))
    transposed = np.abs(T[:, :3, 3]).max(axis=1) <= BOTTOM_ROW_TOL
    if transposed[off > BOTTOM_ROW_TOL].all():
        raise PoseFormatError(
            f"{what}: entry {i}: the bottom row is {T[i, 3].tolist()}, with the translation there and the last "
            "column empty: the matrices look transposed (column-major, as Eigen or OpenGL store them); pass their "
            "transposes (np.swapaxes(T, -1, -2)), with the translation in the last column")
    raise PoseFormatError(f"{what}: entry {i}: the bottom row is {T[i, 3].tolist()}, must be [0, 0, 0, 1] "
                          "(a 4x4 homogeneous transform, rotation top-left, translation in the last column)")


def _validated(T: NDArray[np.float64], what: str, tol: float) -> NDArray[np.float64]:
    """:func:`validate_transforms` of a float stack ``(N, 4, 4)`` the caller owns: fixed in place."""
    if not np.isfinite(T).all():
        i = int(np.argmin(np.isfinite(T).all(axis=(1, 2))))
        raise PoseFormatError(f"{what}: entry {i} contains NaN or infinite values")
    _check_bottom_rows(T, what)
    T[:, 3, :3] = 0.0  # exact, after the check above allowed rounding
    T[:, 3, 3] = 1.0
    if _rotations_exact(T):
        return T
    R = T[:, :3, :3]
    dev = orthonormality_error(R)
    if len(dev) and dev.max() > tol:
        i = int(np.argmax(dev))
        raise PoseFormatError(
            f"{what}: entry {i}: rotation is not orthonormal (max |R^T R - I| = {dev[i]:.3g}, tolerance {tol:g}); "
            f"check the matrix layout (row-major 4x4) and the units"
        )
    det = np.linalg.det(R)
    if len(det) and det.min() < 0:
        i = int(np.argmax(det < 0))
        raise PoseFormatError(f"{what}: entry {i}: rotation has determinant {det[i]:.4g}, a reflection, not a rotation")
    inexact = dev > 1e-13
    if inexact.any():  # replace by the nearest exact rotation; exact ones are left bit-for-bit
        T[inexact, :3, :3] = Rotation.from_matrix(R[inexact]).as_matrix()
    return T


def format_poses(
    T: ArrayLike, format: str = "quat_wxyz", length_unit: str = "m", angle_unit: str = "rad"
) -> NDArray[np.float64]:
    """The inverse of :func:`parse_poses`: rows of values in the given format and units."""
    kind, seq = _parse_format(format)
    scale = _check_units(length_unit, angle_unit)
    T = validate_transforms(T)
    if kind == "matrix":
        out = T.copy()
        out[:, :3, 3] /= scale
        return out.reshape(len(T), 16)
    t = T[:, :3, 3] / scale
    rot = Rotation.from_matrix(T[:, :3, :3])
    if kind == "quat_wxyz":
        r = rot.as_quat(scalar_first=True)
    elif kind == "quat_xyzw":
        r = rot.as_quat()
    elif kind == "rotvec":
        r = rot.as_rotvec(degrees=(angle_unit == "deg"))
    else:
        r = rot.as_euler(seq, degrees=(angle_unit == "deg"))
    return np.hstack([t, r])


#: Rotation columns as robot makers name them (after x, y, z) where they are not handeye's own names
#: (:func:`pose_columns`: a, b, c for every Euler sequence, KUKA's A, B, C among them), the pose
#: formats they are, and whose: a pose table may name its columns so for those formats.
VENDOR_COLUMNS = (
    (("w", "p", "r"), ("euler:xyz",), "FANUC's W, P, R: about the fixed x, y, z axes, format euler:xyz"),
    (("rx", "ry", "rz"), ("rotvec", "euler:xyz", "euler:XYZ"),
     "Universal Robots' RX, RY, RZ: a rotation vector, format rotvec; Yaskawa's and Denso's Rx, Ry, Rz: about the fixed "
     "x, y, z axes, format euler:xyz; Staubli's: about x, then the new y, then the new z, format euler:XYZ"),
    (("o", "a", "t"), ("euler:ZYZ",), "Kawasaki's O, A, T: about z, then the new y, then the new z, format euler:ZYZ"),
    (("q1", "q2", "q3", "q4"), ("quat_wxyz",), "ABB's q1, q2, q3, q4: a quaternion with its scalar first, format quat_wxyz"),
)


def vendor_columns(header: list[str], fmt: str, where: str) -> list[str]:
    """A pose table's column names (lower case, after its id and time columns) as :func:`pose_columns`
    names them for ``fmt`` when they are a robot maker's names for that format (:data:`VENDOR_COLUMNS`:
    FANUC's x, y, z, w, p, r for ``euler:xyz``), else as given; a maker's names for another format are
    refused, saying which format they are (``where``: the table, for the message).

    Examples
    --------
    >>> vendor_columns(["x", "y", "z", "w", "p", "r"], "euler:xyz", "poses.csv")
    ['x', 'y', 'z', 'a', 'b', 'c']
    >>> vendor_columns(["x", "y", "z", "w", "p", "r"], "euler:ZYX", "poses.csv")
    Traceback (most recent call last):
    ...
    handeye.errors.PoseFormatError: poses.csv: header x, y, z, w, p, r does not match format 'euler:ZYX', whose columns are x, y, z, \
a, b, c: columns w, p, r are FANUC's W, P, R: about the fixed x, y, z axes, format euler:xyz; declare the format these columns are, \
or name them as euler:ZYX's
    """
    expected = pose_columns(fmt)
    if header == expected or header[:3] != ["x", "y", "z"]:
        return header
    for names, formats, whose in VENDOR_COLUMNS:
        if tuple(header[3:]) != names:
            continue
        if fmt in formats:
            return expected
        raise PoseFormatError(f"{where}: header {', '.join(header)} does not match format {fmt!r}, whose columns are "
                              f"{', '.join(expected)}: columns {', '.join(names)} are {whose}; declare the format these "
                              f"columns are, or name them as {fmt}'s")
    return header

