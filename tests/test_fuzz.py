"""Property tests: whatever the format, units, shape or values, the pose parsers and validators
return poses or raise :class:`handeye.HandEyeError`; nothing else escapes (no IndexError, no
ValueError from numpy or scipy, no UnicodeDecodeError)."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from handeye import HandEyeError, parse_poses
from handeye.frames.poses import format_poses, pose_columns, validate_transforms
from handeye.io.session import load_yaml, read_pose_table

FORMATS = ["matrix", "quat_wxyz", "quat_xyzw", "rotvec", "euler:ZYX", "euler:xyz", "euler:XYX", "euler:zyz"]
formats = st.one_of(st.sampled_from(FORMATS), st.text(max_size=12),
                    st.builds(lambda s: f"euler:{s}", st.text(alphabet="xyzXYZaq", max_size=4)))
length_units = st.one_of(st.sampled_from(["m", "mm"]), st.text(max_size=4))
angle_units = st.one_of(st.sampled_from(["rad", "deg"]), st.text(max_size=4))
numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64),
                    st.floats(min_value=-4.0, max_value=4.0), st.integers(-10**6, 10**6))
shapes = st.one_of(st.tuples(st.integers(0, 4), st.integers(0, 18)), st.tuples(st.integers(0, 3)),
                   st.tuples(st.integers(0, 3), st.integers(1, 5), st.integers(1, 5)))
arrays = shapes.flatmap(lambda shape: st.lists(numbers, min_size=int(np.prod(shape)), max_size=int(np.prod(shape)))
                        .map(lambda v, shape=shape: np.array(v, dtype=float).reshape(shape)))
odd_values = st.one_of(arrays, st.just(None), st.text(max_size=8), st.lists(st.text(max_size=3), max_size=3),
                       st.lists(st.lists(numbers, max_size=8), max_size=3))

SETTINGS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _plausible(fmt: str, rng: np.random.Generator, n: int) -> np.ndarray:
    """Values close to valid poses of ``fmt`` (to reach past the shape checks)."""
    try:
        cols = len(pose_columns(fmt))
    except HandEyeError:
        cols = 7
    v = rng.normal(size=(n, cols))
    if fmt.startswith("quat"):
        v[:, 3:] /= np.linalg.norm(v[:, 3:], axis=1, keepdims=True)
    return v


@SETTINGS
@given(values=odd_values, fmt=formats, length_unit=length_units, angle_unit=angle_units)
def test_parse_poses_raises_only_handeye_errors(values, fmt, length_unit, angle_unit):
    try:
        T = parse_poses(values, fmt, length_unit, angle_unit)
    except HandEyeError:
        return
    assert T.ndim == 3 and T.shape[1:] == (4, 4) and np.isfinite(T).all()
    R = T[:, :3, :3]
    assert np.allclose(R @ np.swapaxes(R, 1, 2), np.eye(3), atol=1e-9)


@SETTINGS
@given(fmt=st.sampled_from(FORMATS), length_unit=st.sampled_from(["m", "mm"]), angle_unit=st.sampled_from(["rad", "deg"]),
       seed=st.integers(0, 2**32 - 1), n=st.integers(1, 4), scale=st.sampled_from([1e-9, 1.0, 1e3, 1e9]),
       poke=st.one_of(st.none(), st.tuples(st.integers(0, 3), st.integers(0, 15), numbers)))
def test_parse_poses_near_valid_values(fmt, length_unit, angle_unit, seed, n, scale, poke):
    """Values near valid ones, scaled and with one entry replaced: poses or a HandEyeError, and a
    pose that comes back is a rigid transform."""
    v = _plausible(fmt, np.random.default_rng(seed), n) * scale
    if poke is not None:
        v[poke[0] % n, poke[1] % v.shape[1]] = poke[2]
    try:
        T = parse_poses(v, fmt, length_unit, angle_unit)
    except HandEyeError:
        return
    R = T[:, :3, :3]
    assert np.allclose(R @ np.swapaxes(R, 1, 2), np.eye(3), atol=1e-9) and np.allclose(np.linalg.det(R), 1.0)
    assert np.array_equal(T[:, 3], np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)))


@SETTINGS
@given(values=odd_values)
def test_validate_transforms_raises_only_handeye_errors(values):
    try:
        T = validate_transforms(values)
    except HandEyeError:
        return
    assert T.shape[1:] == (4, 4) and np.isfinite(T).all()


@SETTINGS
@given(fmt=formats, length_unit=length_units, angle_unit=angle_units, seed=st.integers(0, 2**32 - 1))
def test_format_poses_round_trip_or_error(fmt, length_unit, angle_unit, seed):
    """format_poses accepts what parse_poses accepts, and the two are inverse."""
    rng = np.random.default_rng(seed)
    from handeye.geometry.se3 import make_transform, random_rotations
    T = make_transform(random_rotations(3, rng), rng.uniform(-0.9, 0.9, (3, 3)))
    try:
        rows = format_poses(T, fmt, length_unit, angle_unit)
    except HandEyeError:
        return
    back = parse_poses(rows, fmt, length_unit, angle_unit)
    assert np.allclose(back, T, atol=1e-9)


cells = st.one_of(st.text(max_size=6), numbers.map(repr), st.sampled_from(["", " ", "nan", "1,5", "1e400", "0x10", "é"]))
separators = st.sampled_from([",", ";", "\t", " ", "|"])
encodings = st.sampled_from(["utf-8", "utf-8-sig", "utf-16", "latin-1", "cp1252"])


@SETTINGS
@given(fmt=st.sampled_from(FORMATS), rows=st.lists(st.lists(cells, max_size=9), max_size=5), sep=separators,
       encoding=encodings, header=st.booleans(), junk=st.binary(max_size=20))
def test_read_pose_table_raises_only_handeye_errors(fmt, rows, sep, encoding, header, junk):
    """Any table text in any encoding, with its header or without, or random bytes: values or a
    HandEyeError (whose message names the file)."""
    lines = ([sep.join(["id"] + pose_columns(fmt))] if header else []) + [sep.join(r) for r in rows]
    text = "\n".join(lines)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "poses.csv"
        try:
            data = text.encode(encoding)
        except UnicodeEncodeError:
            data = text.encode("utf-8")
        for content in (data, junk, data + junk):
            path.write_bytes(content)
            try:
                values, ids = read_pose_table(path, fmt)
            except HandEyeError as exc:
                assert "poses.csv" in str(exc)
                continue
            assert values.shape[1] == len(pose_columns(fmt)) and len(values) >= 1
            assert ids is None or len(ids) == len(values)


@SETTINGS
@given(content=st.one_of(st.binary(max_size=64), st.text(max_size=64).map(lambda t: t.encode("utf-8")),
                         st.text(max_size=64).map(lambda t: t.encode("utf-16"))))
def test_load_yaml_raises_only_handeye_errors(content):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "session.yaml"
        path.write_bytes(content)
        try:
            data = load_yaml(path)
        except HandEyeError as exc:
            assert "session.yaml" in str(exc)
            return
        assert isinstance(data, dict)


@SETTINGS
@given(fmt=st.sampled_from(FORMATS), seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5), sep=separators,
       encoding=encodings, ids=st.booleans(), poke=st.one_of(st.none(), st.tuples(st.integers(0, 4), st.integers(0, 16), cells)))
def test_read_pose_table_of_near_valid_tables(fmt, seed, n, sep, encoding, ids, poke):
    """Well-formed tables in any separator and encoding read back the values written (decimal
    commas with ';'); with one cell replaced by anything, values or a HandEyeError naming the file."""
    values = _plausible(fmt, np.random.default_rng(seed), n)
    header = (["id"] if ids else []) + pose_columns(fmt)
    body = [[f"p{k}"] * ids + [repr(float(v)).replace(".", ",") if sep == ";" else repr(float(v)) for v in row]
            for k, row in enumerate(values)]
    if poke is not None:
        body[poke[0] % n][poke[1] % len(header)] = poke[2]
    text = "\n".join(sep.join(r) for r in [header] + body) + "\n"
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "poses.csv"
        path.write_bytes(text.encode(encoding, errors="replace"))
        try:
            got, got_ids = read_pose_table(path, fmt)
        except HandEyeError as exc:
            assert "poses.csv" in str(exc)
            assert poke is not None or sep == "|", str(exc)  # an untouched table in a known layout reads
            return
    assert got.shape == values.shape
    if poke is None:
        assert np.array_equal(got, values) and got_ids == ([f"p{k}" for k in range(n)] if ids else None)
