"""parse_poses: every robot pose format, units, and a clear error for each kind of bad row."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from handeye import PoseFormatError, format_poses, parse_poses
from handeye.errors import SessionError
from handeye.frames.poses import pose_columns
from handeye.geometry.se3 import make_transform, random_rotations

FORMATS = ["matrix", "quat_wxyz", "quat_xyzw", "rotvec", "euler:ZYX", "euler:xyz", "euler:ZYZ", "euler:zxy"]


@pytest.fixture
def poses(rng):
    return make_transform(random_rotations(10, rng), rng.uniform(-1.0, 1.0, (10, 3)))


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("length_unit", ["m", "mm"])
@pytest.mark.parametrize("angle_unit", ["rad", "deg"])
def test_round_trip_every_format(poses, fmt, length_unit, angle_unit):
    rows = format_poses(poses, fmt, length_unit, angle_unit)
    assert rows.shape == (10, len(pose_columns(fmt)))
    back = parse_poses(rows, fmt, length_unit, angle_unit)
    assert np.abs(back - poses).max() < 1e-12


def rz(a):
    return Rotation.from_euler("z", a).as_matrix()


def ry(a):
    return Rotation.from_euler("y", a).as_matrix()


def rx(a):
    return Rotation.from_euler("x", a).as_matrix()


def test_kuka_abc_is_intrinsic_zyx():
    # KUKA: A about z, then B about the new y, then C about the new x: R = Rz(A) Ry(B) Rx(C)
    a, b, c = 30.0, -20.0, 45.0
    T = parse_poses([[100.0, 200.0, 300.0, a, b, c]], "euler:ZYX", "mm", "deg")[0]
    R = rz(np.radians(a)) @ ry(np.radians(b)) @ rx(np.radians(c))
    assert np.allclose(T[:3, :3], R) and np.allclose(T[:3, 3], [0.1, 0.2, 0.3])


def test_fanuc_wpr_is_extrinsic_xyz():
    # Fanuc: W about the fixed x, then P about fixed y, then R about fixed z: R = Rz(R) Ry(P) Rx(W)
    w, p, r = 10.0, 20.0, 30.0
    T = parse_poses([[0.0, 0.0, 0.5, w, p, r]], "euler:xyz", "m", "deg")[0]
    assert np.allclose(T[:3, :3], rz(np.radians(r)) @ ry(np.radians(p)) @ rx(np.radians(w)))


def test_quaternion_orders_and_matrix_layout():
    q = Rotation.from_rotvec([0.3, -0.2, 0.1])
    wxyz = q.as_quat(scalar_first=True)
    T1 = parse_poses([np.r_[1.0, 2.0, 3.0, wxyz]], "quat_wxyz")[0]
    T2 = parse_poses([np.r_[1.0, 2.0, 3.0, np.roll(wxyz, -1)]], "quat_xyzw")[0]
    T3 = parse_poses([make_transform(q.as_matrix(), [1.0, 2.0, 3.0]).ravel()], "matrix")[0]
    T4 = parse_poses(make_transform(q.as_matrix(), [1.0, 2.0, 3.0])[None], "matrix")[0]
    for T in (T2, T3, T4):
        assert np.allclose(T, T1)
    assert np.allclose(T1[:3, :3], q.as_matrix())


@pytest.mark.parametrize(
    "values, fmt, kwargs, message",
    [
        ([[0, 0, 0, 1, 0, 0]], "quat_wxyz", {}, "needs 7 columns"),
        ([[0, 0, 0.5, 1, 0, 0, 0], [0, np.nan, 0.5, 1, 0, 0, 0]], "quat_wxyz", {}, "row 1 column 'y'"),
        ([[0, 0, 0.5, 1, 0, 0, 0], [0, 0, 0.5, 1, 0.1, 0, 0]], "quat_wxyz", {}, "row 1: quaternion norm is 1.00499"),
        ([[0, 0, 0.5, 0, 0, 0, 0]], "quat_xyzw", {}, "quaternion norm is 0"),
        ([[0, 0, 0.5, 1, 2, 3]], "euler:XYz", {}, "mixes cases"),
        ([[0, 0, 0.5, 1, 2, 3]], "euler:XXY", {}, "repeats an axis"),
        ([[0, 0, 0.5, 1, 2, 3]], "euler:ABC", {}, "unknown pose format"),
        ([[0, 0, 0.5, 1, 2, 3]], "kuka", {}, "unknown pose format"),
        ([[0, 0, 0.5, 1, 2, 3]], "rotvec", {"length_unit": "cm"}, "unknown length unit"),
        ([[0, 0, 0.5, 1, 2, 3]], "rotvec", {"angle_unit": "grad"}, "unknown angle unit"),
        ([[0, 0, 0.5, 30, 45, 10]], "euler:ZYX", {"angle_unit": "rad"}, "look like degrees"),
        # hypothesis found it: 7.7e155 deg made a NaN rotation that came back as a pose
        ([[0, 0, 0.5, 7.682108069077478e155, 0, 0]], "rotvec", {"angle_unit": "deg"}, "7.682e\\+155 deg or more exceeds 360 deg"),
        ([[0, 0, 0.5, 30, 400, 10]], "euler:ZYX", {"angle_unit": "deg"}, "400 deg or more exceeds 360 deg"),
        ([[800, 100, 400, 0.1, 0.2, 0.3]] * 3, "rotvec", {"length_unit": "m"}, "look like millimetres"),
        ([[0.8, 0.1, 0.4, 0.1, 0.2, 0.3], [0.7, 0.1, 0.4, 0.1, 0.2, 0.3]], "rotvec", {"length_unit": "mm"}, "look like metres"),
        ("abc", "rotvec", {}, "not numbers"),
        ([], "rotvec", {}, "6 columns"),
    ],
)
def test_bad_input_is_named(values, fmt, kwargs, message):
    with pytest.raises(PoseFormatError, match=message):
        parse_poses(values, fmt, **kwargs)


def test_non_orthonormal_matrix_reports_row_and_deviation():
    good = np.eye(4)
    good[:3, 3] = [0.5, 0.0, 0.3]
    bad = good.copy()
    bad[0, 0] = 1.01
    with pytest.raises(PoseFormatError, match=r"entry 1: rotation is not orthonormal \(max \|R\^T R - I\| = 0.0201"):
        parse_poses(np.stack([good, bad]).reshape(2, 16), "matrix")


def test_matrix_with_bad_last_row_or_reflection():
    T = np.eye(4)
    T[3, 0] = 1.0
    with pytest.raises(PoseFormatError, match=r"bottom row is \[1.0, 0.0, 0.0, 1.0\]"):
        parse_poses(T.ravel()[None], "matrix")
    T = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(PoseFormatError, match="reflection"):
        parse_poses(T.ravel()[None], "matrix")


def test_slightly_off_rotations_are_reorthonormalised():
    R = Rotation.from_rotvec([0.1, 0.2, 0.3]).as_matrix()
    T = make_transform(np.round(R, 6), [0.1, 0.2, 0.3])  # as a controller prints them
    out = parse_poses(T.ravel()[None], "matrix")[0]
    assert np.abs(out[:3, :3].T @ out[:3, :3] - np.eye(3)).max() < 1e-15
    assert np.abs(out[:3, :3] - R).max() < 2e-6


def test_pose_columns_follow_design():
    assert pose_columns("quat_wxyz") == ["x", "y", "z", "qw", "qx", "qy", "qz"]
    assert pose_columns("quat_xyzw") == ["x", "y", "z", "qx", "qy", "qz", "qw"]
    assert pose_columns("rotvec") == ["x", "y", "z", "rx", "ry", "rz"]
    assert pose_columns("euler:ZYX") == ["x", "y", "z", "a", "b", "c"]
    assert pose_columns("matrix")[:5] == ["m00", "m01", "m02", "m03", "m10"]


def test_transform_pair_validated_in_one_pass_as_one_by_one(rng):
    """validate_transform_pair: the one-pass check (exact rotations) and the one-by-one fallback
    give what validate_transforms gives each stack; every failure still names its stack and entry."""
    from handeye import InputMismatchError
    from handeye.frames.poses import _rotations_exact, validate_transform_pair, validate_transforms

    A = make_transform(random_rotations(6, rng), rng.normal(size=(6, 3)))
    B = make_transform(random_rotations(6, rng), rng.normal(size=(6, 3)))
    names, counted = ("A (robot)", "B (camera)"), ("poses A", "poses B")
    pair = validate_transform_pair(A, B, names, counted)
    assert pair.shape == (2, 6, 4, 4) and np.array_equal(pair[0], A) and np.array_equal(pair[1], B)
    assert _rotations_exact(A)
    # printed to 6 decimals: not exact, so each stack is re-orthonormalised as validate_transforms does
    B6 = np.round(B, 6)
    assert not _rotations_exact(B6)
    pair = validate_transform_pair(A.tolist(), B6, names, counted)
    assert np.array_equal(pair[1], validate_transforms(B6)) and np.array_equal(pair[0], A)
    # the fast test misses nothing: a reflection, a 1e-10 slip, a NaN
    for entry, change in (((2, 2, slice(0, 3)), -1.0), ((2, 0, 0), 1.0 + 1e-10)):
        T = B.copy()
        T[entry] *= change
        assert not _rotations_exact(T)
    for row in range(3):  # the third row is tested only through c = a x b: a slip there too
        T = B.copy()
        T[2, row, 1] += 1e-10
        assert not _rotations_exact(T)
    T = B.copy()
    T[2, 0, 0] = np.nan
    assert not _rotations_exact(T)
    bad = B.copy()
    bad[2, 2, :3] *= -1.0
    with pytest.raises(PoseFormatError, match=r"B \(camera\): entry 2: rotation has determinant -1, a reflection"):
        validate_transform_pair(A, bad, names, counted)
    bad = A.copy()
    bad[4, 1, 3] = np.nan
    with pytest.raises(PoseFormatError, match=r"A \(robot\): entry 4 contains NaN"):
        validate_transform_pair(bad, B, names, counted)
    with pytest.raises(InputMismatchError, match="6 poses A but 5 poses B; they come in pairs"):
        validate_transform_pair(A, B[:5], names, counted)
    # a bottom row off by rounding is set to 0 0 0 1 on the copy; the caller's arrays are untouched
    A_in = A.copy()
    A_in[:, 3, :3] = 1e-12
    pair = validate_transform_pair(A_in, B, names, counted)
    assert np.array_equal(pair[0], A) and np.all(A_in[:, 3, :3] == 1e-12)
    # one that is not a homogeneous transform's is an error, never overwritten
    A_in[:, 3, :3] = 7.0
    with pytest.raises(PoseFormatError, match=r"A \(robot\): entry 0: the bottom row is \[7.0, 7.0, 7.0, 1.0\], must be"):
        validate_transform_pair(A_in, B, names, counted)
    # column-major matrices (translation in the bottom row) are named as transposed
    with pytest.raises(PoseFormatError, match=r"B \(camera\): entry 0: .*look transposed"):
        validate_transform_pair(A, np.swapaxes(B, -1, -2), names, counted)


@pytest.mark.parametrize("fmt,columns,truth", [
    ("euler:xyz", "X,Y,Z,W,P,R", "euler:xyz"),          # FANUC
    ("euler:ZYX", "X,Y,Z,A,B,C", "euler:ZYX"),          # KUKA (handeye's own names)
    ("rotvec", "X,Y,Z,RX,RY,RZ", "rotvec"),             # Universal Robots (handeye's own names)
    ("euler:xyz", "x,y,z,Rx,Ry,Rz", "euler:xyz"),       # Yaskawa, Denso
    ("euler:ZYZ", "x,y,z,O,A,T", "euler:ZYZ"),          # Kawasaki
    ("quat_wxyz", "x,y,z,q1,q2,q3,q4", "quat_wxyz"),    # ABB
])
def test_pose_columns_named_by_the_robots_own_letters(tmp_path, fmt, columns, truth):
    """Issue 77: a pose table whose rotation columns carry the robot maker's letters for the declared
    format (FANUC's W, P, R for euler:xyz, the guide's own laser example) was refused; it is read as
    that format. A maker's letters for another format are refused, naming the format they are."""
    from handeye.io.session import read_pose_table

    T = make_transform(random_rotations(3, np.random.default_rng(0)), np.array([[500.0, -20, 300], [1, 2, 3], [4, 5, 6]]))
    rows = format_poses(T, truth, "mm", "deg")
    path = tmp_path / "poses.csv"
    path.write_text("id," + columns + "\n" + "".join(f"p{k}," + ",".join(repr(float(v)) for v in r) + "\n" for k, r in enumerate(rows)))
    values, ids = read_pose_table(path, fmt)
    assert ids == ["p0", "p1", "p2"] and np.allclose(parse_poses(values, fmt, "mm", "deg"), T)
    other = "euler:ZYX" if fmt != "euler:ZYX" else "rotvec"
    if columns.lower().endswith("a,b,c"):  # handeye's own names for every Euler sequence: the header check's message
        with pytest.raises(SessionError, match=f"does not match format '{other}'"):
            read_pose_table(path, other)
        return
    with pytest.raises(PoseFormatError, match=rf"poses.csv: header .* does not match format '{other}'.* columns .* are .*format {truth}"):
        read_pose_table(path, other)
