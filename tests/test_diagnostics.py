"""Fault injection: handeye.diagnose must name what is wrong with the data (each case over 50 scenes)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import handeye
import realdata
from handeye.estimation.diagnostics import RobotPoseInput, diagnose
from handeye.frames.metrics import translation_error
from handeye.frames.poses import format_poses, parse_poses
from handeye.geometry.se3 import invert, make_transform, random_rotations
from handeye.simulate import perturb_poses, random_scene

SCENES = 50
SEQUENCES = [s for a in "xyz" for b in "xyz" for c in "xyz" if a != b != c for s in (a + b + c, (a + b + c).upper())]


def _noisy(rng, setup="eye_in_hand", n=12):
    s = random_scene(n, setup, rng)
    f = perturb_poses(s.flange2base, np.radians(0.05), 0.2e-3, rng)
    t = perturb_poses(s.target2cam, np.radians(0.1), 0.5e-3, rng)
    return s, f, t


def test_sequences_are_the_24():
    assert len(SEQUENCES) == 24 and len(set(SEQUENCES)) == 24


@pytest.mark.slow
@pytest.mark.parametrize("setup", ["eye_in_hand", "eye_to_hand"])
def test_clean_data_is_good(setup):
    rng = np.random.default_rng(1)
    for _ in range(SCENES):
        _, f, t = _noisy(rng, setup)
        d = diagnose(f, t, setup, leave_one_out=False)
        assert d.verdict == "good", d.summary()
        assert d.outliers == [] and d.convention_hint is None


@pytest.mark.slow
def test_wrong_euler_sequence_is_named():
    """Angles written in one of the 24 sequences and declared as another: the written one is named."""
    rng = np.random.default_rng(2)
    for k in range(SCENES):
        _, f, t = _noisy(rng)
        written, declared = rng.choice(SEQUENCES, 2, replace=False)
        values = format_poses(f, f"euler:{written}", length_unit="mm", angle_unit="deg")
        read = parse_poses(values, f"euler:{declared}", "mm", "deg")
        d = diagnose(read, t, robot_input=RobotPoseInput(values, f"euler:{declared}", "mm", "deg"),
                     outliers=False, leave_one_out=False)
        assert d.verdict == "inconsistent" and d.convention_hint == f"euler:{written}", (k, written, declared, d.summary())


@pytest.mark.parametrize("setup", ["eye_in_hand", "eye_to_hand"])
def test_inverted_robot_poses_are_named(setup):
    rng = np.random.default_rng(3)
    for _ in range(SCENES):
        _, f, t = _noisy(rng, setup)
        d = diagnose(invert(f), t, setup, leave_one_out=False)
        assert d.verdict == "inconsistent" and d.convention_hint == "invert_robot_poses", d.summary()
        assert "inverted" in d.advice[0]


@pytest.mark.slow
def test_mm_declared_as_m_is_named():
    rng = np.random.default_rng(4)
    for _ in range(SCENES):
        _, f, t = _noisy(rng)
        values = format_poses(f, "quat_wxyz", length_unit="mm")
        # as matrices (the parser itself refuses tens of metres when the values come as a table)
        read = f.copy()
        read[:, :3, 3] *= 1e3
        d = diagnose(read, t, leave_one_out=False)
        assert d.convention_hint == "length_unit:mm", d.summary()
        d = diagnose(f, t, robot_input=RobotPoseInput(values, "quat_wxyz", "mm"), leave_one_out=False)
        assert d.convention_hint is None and d.verdict == "good"


def test_quaternion_order_is_named():
    rng = np.random.default_rng(5)
    for _ in range(SCENES):
        _, f, t = _noisy(rng)
        values = format_poses(f, "quat_xyzw")
        d = diagnose(parse_poses(values, "quat_wxyz"), t, robot_input=RobotPoseInput(values, "quat_wxyz"),
                     outliers=False, leave_one_out=False)
        assert d.verdict == "inconsistent" and d.convention_hint == "quat_xyzw", d.summary()


def _small_rotation_scene(rng, max_deg, n=12):
    """Flange orientations within ``max_deg`` of the base's, positions spread over 0.4 m."""
    s = random_scene(n, "eye_in_hand", rng)
    rv = rng.normal(size=(n, 3))
    rv *= (np.radians(max_deg) * rng.uniform(0.3, 1.0, n) / np.linalg.norm(rv, axis=1))[:, None]
    f = make_transform(Rotation.from_rotvec(rv).as_matrix(), rng.uniform(-0.2, 0.2, (n, 3)) + [0.5, 0.0, 0.6])
    Z = f[0] @ s.X @ make_transform(np.eye(3), [0.0, 0.0, 0.7])  # a target 0.7 m in front of the first view
    return s.X, f, invert(s.X) @ invert(f) @ Z


def test_degrees_declared_as_radians_is_named():
    """Flange orientations within 6 deg of the base's: in degrees the numbers stay below 2 pi and
    pass the parser's range check when declared as radians; the diagnosis names the unit."""
    rng = np.random.default_rng(6)
    for _ in range(SCENES):
        _, f, t = _small_rotation_scene(rng, 6.0)
        values = format_poses(f, "rotvec", angle_unit="deg")
        read = parse_poses(values, "rotvec", angle_unit="rad")
        d = diagnose(read, t, robot_input=RobotPoseInput(values, "rotvec", "m", "rad"), outliers=False,
                     leave_one_out=False)
        assert d.verdict == "inconsistent" and d.convention_hint == "angle_unit:deg", d.summary()


def _random_poses_run(args):
    X, f, f_bad, t, _ = args
    cal = handeye.calibrate_poses(f_bad, t, refine="pose")  # runs diagnose and leaves the outliers out
    clean = handeye.calibrate_poses(f, t, refine="pose")
    return (cal.diagnostics.outliers, cal.pose_indices.tolist(), cal.notes, translation_error(clean.X, X),
            translation_error(cal.X, X))


@pytest.mark.slow
def test_random_poses_are_named_and_left_out():
    """20% of the poses replaced by random ones: every replaced pose named, clean ones named in at
    most 5% of scenes, and the calibration on what is left within 1.5x of the clean-data error."""
    rng = np.random.default_rng(7)
    n, n_bad = 15, 3
    tasks = []
    for _ in range(SCENES):  # the draws here, the calibrations on both cores
        s, f, t = _noisy(rng, n=n)
        bad = rng.choice(n, n_bad, replace=False)
        f_bad = f.copy()
        f_bad[bad] = make_transform(random_rotations(n_bad, rng), f[bad][:, :3, 3] + rng.uniform(-0.3, 0.3, (n_bad, 3)))
        tasks.append((s.X, f, f_bad, t, bad))
    with realdata.worker_pool() as pool:
        runs = list(pool.map(_random_poses_run, tasks))
    false_scenes = 0
    for (_, _, _, _, bad), (outliers, used, notes, _, _) in zip(tasks, runs):
        assert set(bad.tolist()) <= set(outliers), (sorted(bad), outliers)
        assert sorted(set(range(n)) - set(outliers)) == used
        assert any("left out" in note for note in notes)
        false_scenes += bool(set(outliers) - set(bad.tolist()))
    err_clean, err_bad = [r[3] for r in runs], [r[4] for r in runs]
    rms = lambda e: float(np.sqrt(np.mean(np.square(e))))  # noqa: E731
    print(f"clean poses named in {false_scenes}/{SCENES} scenes; X translation RMS clean {1e3 * rms(err_clean):.3f} mm, "
          f"with 20% random poses {1e3 * rms(err_bad):.3f} mm")
    assert false_scenes <= 0.05 * SCENES
    assert rms(err_bad) <= 1.5 * rms(err_clean)


def test_rotations_about_one_axis_are_degenerate():
    rng = np.random.default_rng(8)
    for _ in range(SCENES):
        s, f, t = _noisy(rng)
        # robot turns only about the camera's optical axis: flange2base_i = F0 X Rz(a_i) X^-1
        a = rng.uniform(-1.0, 1.0, 12)
        Rz = make_transform(np.array([[[np.cos(x), -np.sin(x), 0], [np.sin(x), np.cos(x), 0], [0, 0, 1]] for x in a]),
                            np.zeros((12, 3)))
        f1 = f[0] @ s.X @ Rz @ invert(s.X)
        t1 = invert(s.X) @ invert(f1) @ s.Z
        d = diagnose(f1, t1)
        assert d.verdict == "degenerate", d.summary()
        assert "about one axis, the camera's z axis" in d.advice[0]
        assert "about the camera's x axis and the camera's y axis" in d.advice[0]


def test_small_rotations_are_weak_with_advice():
    rng = np.random.default_rng(9)
    for _ in range(SCENES):
        _, f, t = _small_rotation_scene(rng, 2.0)
        d = diagnose(f, t, leave_one_out=False)
        assert d.verdict == "weak", d.summary()
        assert any("less than 5 deg" in a for a in d.advice)


@pytest.mark.slow
def test_public_name_and_check_command(tmp_path, capsys):
    """``handeye.diagnose`` (DESIGN §6) and ``handeye check``: exit 0 on the bundled example, 2 with
    the Euler sequence declared wrong (the right one named); calibrate-poses answers with that verdict
    and refuses it in strict mode."""
    import shutil
    from pathlib import Path

    from handeye.cli import main

    assert handeye.diagnose is diagnose
    example = Path(handeye.__file__).parent / "data" / "example_posepairs"
    assert main(["check", str(example)]) == 0
    out = capsys.readouterr().out
    assert "verdict: good" in out and "resid deg" in out
    assert "held-out prediction error" in out and "<- chosen" in out and "mm at the target" in out
    folder = tmp_path / "pairs"
    shutil.copytree(example, folder)
    spec = (folder / "posepairs.yaml").read_text().replace("format: euler:ZYX", "format: euler:XYZ")
    (folder / "posepairs.yaml").write_text(spec)
    assert main(["check", str(folder)]) == 2
    out = capsys.readouterr().out
    assert "verdict: inconsistent" in out and "convention hint: euler:ZYX" in out
    # calibrate-poses answers with the verdict and the fix (check's exit status, 2), or refuses with --strict
    assert main(["calibrate-poses", str(folder)]) == 2
    out = capsys.readouterr().out
    assert "check: inconsistent" in out and "Euler sequence ZYX" in out
    # the fix first, and X marked as no result to use
    assert out.startswith("INCONSISTENT DATA: the robot angles follow the Euler sequence ZYX"), out[:300]
    assert out.index("do not use it") < out.index("(4x4, metres)")
    assert main(["calibrate-poses", str(folder), "--strict"]) == 2
    err = capsys.readouterr().err
    assert "Euler sequence ZYX" in err and len(err.strip().splitlines()) == 1


def _leave_one_out_by_loop(flange2base, target2cam, setup):
    """The definition: a new Daniilidis solve per left-out pose (inf when it is refused)."""
    from handeye.errors import HandEyeError
    from handeye.estimation.diagnostics import _solve
    from handeye.frames.metrics import rotation_error

    X = _solve(flange2base, target2cam, setup)
    out = np.empty((len(flange2base), 2))
    for k in range(len(flange2base)):
        keep = np.arange(len(flange2base)) != k
        try:
            Xk = _solve(flange2base[keep], target2cam[keep], setup)
        except HandEyeError:
            out[k] = np.inf
            continue
        out[k] = np.degrees(rotation_error(Xk, X)), 1e3 * translation_error(Xk, X)
    return out


@pytest.mark.parametrize("setup", ["eye_in_hand", "eye_to_hand"])
def test_leave_one_out_in_one_batch_equals_the_loop(setup):
    """diagnose's leave-one-out subtracts each pose's motions from the Daniilidis moment sum and
    checks observability per run, all poses in one batch: the same moves as a solve per pose,
    and inf for the same poses (a pose that alone gives the second rotation axis)."""
    from handeye.estimation.diagnostics import _leave_one_out
    from handeye.geometry.se3 import from_rotvec_translation

    rng = np.random.default_rng(4)
    s = random_scene(12, setup, rng=rng)
    f = perturb_poses(s.flange2base, np.radians(0.05), 0.2e-3, rng)
    t = perturb_poses(s.target2cam, np.radians(0.1), 0.5e-3, rng)
    got = _leave_one_out(f, t, setup, np.ones(len(f), bool))
    want = _leave_one_out_by_loop(f, t, setup)
    assert np.all(np.isfinite(got)) and np.abs(got - want).max() < 1e-9
    # only pose 5 rotates off the y axis: leaving it out leaves X undetermined
    n = 8
    rotvec = np.outer(np.radians(np.linspace(-40, 40, n)), [0.0, 1.0, 0.0])
    rotvec[5] = np.radians([25.0, 10.0, 0.0])
    flange2base = from_rotvec_translation(rotvec, rng.normal(scale=0.2, size=(n, 3)))
    if setup == "eye_in_hand":  # X = cam2flange, Z = target2base
        target2cam = invert(s.X) @ invert(flange2base) @ s.Z
    else:  # X = cam2base, Z = target2flange
        target2cam = invert(s.X) @ flange2base @ s.Z
    got = _leave_one_out(flange2base, target2cam, setup, np.ones(n, bool))
    want = _leave_one_out_by_loop(flange2base, target2cam, setup)
    assert np.isinf(got[5]).all() and np.isinf(want[5]).all()
    from handeye.frames.motions import MotionSet
    from handeye.solvers.daniilidis import motion_groups
    from handeye.solvers.observability import observable_leave_one_out

    motions = MotionSet.from_poses(flange2base, target2cam, setup, "all")
    for block in (2_000_000, 60):  # one block, and blocks of two runs
        assert np.flatnonzero(~observable_leave_one_out(motions, motion_groups(motions.pairs, n), block)).tolist() == [5]
    finite = np.isfinite(want[:, 0])
    assert finite.sum() == n - 1 and np.array_equal(np.isfinite(got[:, 0]), finite)
    assert np.abs(got[finite] - want[finite]).max() < 1e-9


def test_leave_one_out_observability_reads_no_uninitialised_memory(monkeypatch):
    """The padding row of the per-run blocks was np.empty: with all-pairs motions (no padding used)
    the largest rotation of a run was whatever the allocator handed back, and a run that leaves X
    undetermined passed as observable about one time in six. Here every np.empty comes back full of
    large numbers (the worst memory can hold): the answer must not change."""
    from handeye.frames.motions import MotionSet
    from handeye.geometry.se3 import from_rotvec_translation
    from handeye.solvers.daniilidis import motion_groups
    from handeye.solvers.observability import observable_leave_one_out

    rng = np.random.default_rng(4)
    s = random_scene(12, "eye_to_hand", rng=rng)
    n = 8
    rotvec = np.outer(np.radians(np.linspace(-40, 40, n)), [0.0, 1.0, 0.0])
    rotvec[5] = np.radians([25.0, 10.0, 0.0])  # the only pose off the y axis
    flange2base = from_rotvec_translation(rotvec, rng.normal(scale=0.2, size=(n, 3)))
    motions = MotionSet.from_poses(flange2base, invert(s.X) @ flange2base @ s.Z, "eye_to_hand", "all")
    groups = motion_groups(motions.pairs, n)
    empty = np.empty
    monkeypatch.setattr(np, "empty", lambda shape, dtype=float, **kw: np.full(shape, 1e6, dtype=dtype))
    try:
        got = observable_leave_one_out(motions, groups)
    finally:
        monkeypatch.setattr(np, "empty", empty)
    assert np.flatnonzero(~got).tolist() == [5]


def test_leave_one_out_observability_matches_the_check_on_each_subset():
    """All poses at once (counting the motions that pass each test) against check_observability on
    the motions left after dropping each pose, on random, one-axis-but-a-few and small-rotation poses."""
    from handeye.errors import DegenerateMotionError
    from handeye.frames.motions import MotionSet
    from handeye.geometry.se3 import from_rotvec_translation
    from handeye.solvers.daniilidis import motion_groups
    from handeye.solvers.observability import check_observability, observable_leave_one_out

    rng = np.random.default_rng(8)
    for trial in range(24):
        n = int(rng.integers(4, 12))
        s = random_scene(n, "eye_in_hand", rng=trial)
        rotvec = rng.normal(size=(n, 3)) * [0.02, 0.02, 0.6] if trial % 3 else rng.normal(scale=0.4, size=(n, 3))
        rotvec[: trial % 3] = rng.normal(scale=0.5, size=(trial % 3, 3))  # a few poses off the z axis
        if trial % 4 == 3:
            rotvec *= 0.01  # rotations too small
        flange2base = from_rotvec_translation(rotvec, rng.normal(scale=0.2, size=(n, 3)))
        motions = MotionSet.from_poses(flange2base, invert(s.X) @ invert(flange2base) @ s.Z, "eye_in_hand", "all")
        got = observable_leave_one_out(motions, motion_groups(motions.pairs, n))
        for p in range(n):
            keep = (motions.pairs != p).all(axis=1)
            try:
                check_observability(MotionSet(motions.dq_a[keep], motions.dq_b[keep]))
                expected = True
            except DegenerateMotionError:
                expected = False
            assert got[p] == expected, (trial, p)


@pytest.mark.parametrize("setup", ["eye_in_hand", "eye_to_hand"])
def test_the_wrong_setup_is_named_before_inverted_poses(setup):
    """Eye-in-hand data declared eye-to-hand reads exactly as inverted robot poses: both readings
    are named, ranked by where they put the camera and the target (a camera 1.3 m from the flange
    it rides on is unlikely)."""
    from handeye.simulate import realistic_scene

    sc = realistic_scene(12, setup, 1)
    other = "eye_to_hand" if setup == "eye_in_hand" else "eye_in_hand"
    d = handeye.diagnose(sc.flange2base, sc.target2cam, other)
    assert d.verdict == "inconsistent" and d.convention_hint == f"setup:{setup}", d.summary()
    assert d.advice[0].index(f"the setup is {setup}") < d.advice[0].index("the robot poses are inverted")
    assert f"declare setup: {setup}" in d.advice[0]
