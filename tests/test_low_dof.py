"""Robots that cannot rotate freely (issue 20): SCARA (one rotation axis) and Cartesian (no rotation).

Ground truth from :func:`handeye.simulate.low_dof_scene`; the bars: the determined part of X exact on
noise-free data, X complete with ``known``, honest std on noisy data, general data unchanged.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

import handeye
from handeye.cli import main
from handeye.errors import InputMismatchError
from handeye.frames.motions import MotionSet
from handeye.frames.poses import format_poses
from handeye.frames.setups import setup_info
from handeye.simulate import low_dof_scene, realistic_scene
from handeye.solvers.low_dof import motion_kind, solve_low_dof

SETUPS = ("eye_in_hand", "eye_to_hand")


def _errors(cal, sc):
    d_rot = np.degrees(Rotation.from_matrix(cal.X[:3, :3] @ sc.X[:3, :3].T).as_rotvec())
    return d_rot, 1e3 * (cal.X[:3, 3] - sc.X[:3, 3])


def _known(sc, robot: str, setup: str, on_x: bool = True) -> dict:
    info = setup_info(setup)
    name, T = (info.x_name, sc.X) if on_x else (info.z_name, sc.Z)
    axes = "z" if robot == "scara" else "xyz"
    return {f"{name}.{a}": float(T["xyz".index(a), 3]) for a in axes}


@pytest.mark.parametrize("setup", SETUPS)
def test_noise_free_scara_determined_part_exact_and_known_completes_it(setup):
    sc = low_dof_scene(12, setup, "scara", 1, robot_noise=(0, 0), pixel_px=0)
    cal = handeye.calibrate_poses(sc.flange2base, sc.target2cam, setup)  # no exception
    assert cal.verdict == "partial" and cal.motion_kind == "one_axis"
    (u,) = cal.unobservable
    info = setup_info(setup)
    assert u.transform == info.x_name and u.frame == ("flange" if setup == "eye_in_hand" else "base")
    assert abs(u.direction[2]) > 0.999  # the SCARA's vertical: flange z (eye-in-hand) or base z
    assert "along the " + u.frame + " z axis" in u.parameter and "known=" in u.fix
    assert np.abs(cal.X[:3, :3] - sc.X[:3, :3]).max() < 1e-9
    dt = cal.X[:3, 3] - sc.X[:3, 3]
    assert np.abs(dt - u.direction * (u.direction @ dt)).max() < 1e-9  # all but the axis component
    assert np.isinf(cal.std[5]) and np.isfinite(cal.std[:5]).all()
    for on_x in (True, False):  # the camera's offset from the drawing, or the target's height
        done = handeye.calibrate_poses(sc.flange2base, sc.target2cam, setup, known=_known(sc, "scara", setup, on_x))
        assert not done.unobservable and done.verdict == "good"
        assert np.abs(done.X - sc.X).max() < 1e-9 and np.abs(done.Z - sc.Z).max() < 1e-9
        assert np.isfinite(done.std).all()
        (k,) = done.known.values()
        assert k["used"]


@pytest.mark.parametrize("setup", SETUPS)
def test_noise_free_cartesian_rotation_exact_translation_named(setup):
    sc = low_dof_scene(10, setup, "cartesian", 2, robot_noise=(0, 0), pixel_px=0)
    cal = handeye.calibrate_poses(sc.flange2base, sc.target2cam, setup)
    assert cal.motion_kind == "translation_only" and len(cal.unobservable) == 3
    assert np.abs(cal.X[:3, :3] - sc.X[:3, :3]).max() < 1e-9
    assert np.isinf(cal.std[3:]).all() and np.isfinite(cal.std[:3]).all()
    done = handeye.calibrate_poses(sc.flange2base, sc.target2cam, setup, known=_known(sc, "cartesian", setup, False))
    assert not done.unobservable and np.abs(done.X - sc.X).max() < 1e-9
    # two of three given: one direction stays open, and it is the third axis
    two = dict(list(_known(sc, "cartesian", setup).items())[:2])
    part = handeye.calibrate_poses(sc.flange2base, sc.target2cam, setup, known=two)
    (u,) = part.unobservable
    assert abs(u.direction[2]) > 0.999 and np.abs(part.X[:2, 3] - sc.X[:2, 3]).max() < 1e-9


@pytest.mark.slow
@pytest.mark.parametrize("setup", SETUPS)
def test_noisy_scara_with_known_is_within_three_std(setup):
    """0.05 deg / 0.2 mm robot noise, 0.3 px: X's error within 3 reported std in >= 95% of 50 sessions."""
    covered = 0
    for seed in range(50):
        sc = low_dof_scene(15, setup, "scara", seed, robot_noise=(0.05, 0.2), pixel_px=0.3)
        cal = handeye.calibrate_poses(sc.flange2base, sc.target2cam, setup, known=_known(sc, "scara", setup, seed % 2 == 0),
                                      robot_accuracy=None)
        d_rot, d_t = _errors(cal, sc)
        covered += (np.linalg.norm(d_t) <= 3 * np.linalg.norm(cal.std[3:])
                    and np.linalg.norm(d_rot) <= 3 * np.linalg.norm(cal.std[:3]))
    assert covered >= 48, covered


@pytest.mark.slow
@pytest.mark.parametrize("setup", SETUPS)
def test_noisy_cartesian_rotation_within_three_std_translation_unobservable(setup):
    covered = 0
    for seed in range(30):
        sc = low_dof_scene(15, setup, "cartesian", seed)
        cal = handeye.calibrate_poses(sc.flange2base, sc.target2cam, setup, robot_accuracy=None)
        assert len(cal.unobservable) == 3 and np.isinf(cal.std[3:]).all()
        d_rot, _ = _errors(cal, sc)
        covered += np.linalg.norm(d_rot) <= 3 * np.linalg.norm(cal.std[:3])
    assert covered >= 29, covered


def test_general_data_take_the_general_path_and_known_is_only_compared():
    sc = realistic_scene(15, "eye_in_hand", 3)
    plain = handeye.calibrate_poses(sc.flange2base, sc.target2cam, "eye_in_hand")
    given = handeye.calibrate_poses(sc.flange2base, sc.target2cam, "eye_in_hand", known={"cam2flange.z": 0.5})
    assert plain.motion_kind == "general" and not plain.unobservable and plain.verdict != "partial"
    assert np.array_equal(plain.X, given.X) and np.array_equal(plain.std, given.std)
    assert not given.known["cam2flange.z"]["used"]
    assert any("known cam2flange.z" in n and "check the cam2flange" in n for n in given.notes)


def test_scara_known_the_data_determine_is_compared_not_used():
    sc = low_dof_scene(12, "eye_in_hand", "scara", 4, robot_noise=(0, 0), pixel_px=0)
    cal = handeye.calibrate_poses(sc.flange2base, sc.target2cam, "eye_in_hand", known={"cam2flange.x": float(sc.X[0, 3])})
    assert not cal.known["cam2flange.x"]["used"] and len(cal.unobservable) == 1


def test_solver_batched_equals_one_by_one():
    scenes = [low_dof_scene(8, "eye_in_hand", "scara", s) for s in range(3)]
    sets = [MotionSet.from_poses(sc.flange2base, sc.target2cam, "eye_in_hand") for sc in scenes]
    assert {motion_kind(m) for m in sets} == {"one_axis"}
    batch = MotionSet(np.stack([m.dq_a for m in sets]), np.stack([m.dq_b for m in sets]))
    X = solve_low_dof(batch, "one_axis").X
    for k, m in enumerate(sets):
        assert np.allclose(X[k], solve_low_dof(m).X, atol=1e-12)


@pytest.mark.parametrize("known, message", [
    ({"cam2base.z": 0.1}, "belongs to eye_to_hand"),
    ({"camera.z": 0.1}, "name a translation component of cam2flange or target2base"),
    ({"cam2flange.w": 0.1}, "name a translation component"),
    ({"cam2flange.z": 85.0}, "give metres (0.085 if that was mm)"),
    ({"cam2flange.z": "0.08 pm 0.001"}, "0.012+-0.001"),
    ({"cam2flange.z": (0.08, -1.0)}, "non-negative std"),
    ({"cam2flange.z": float("nan")}, "finite value"),
])
def test_bad_known_values_are_refused(known, message):
    sc = low_dof_scene(8, "eye_in_hand", "scara", 0)
    with pytest.raises(InputMismatchError, match=message.replace("(", r"\(").replace(")", r"\)").replace("+", r"\+")):
        handeye.calibrate_poses(sc.flange2base, sc.target2cam, "eye_in_hand", known=known)


def _pair_folder(folder, sc, setup):
    folder.mkdir()
    for name, T, fmt in (("robot_poses.csv", sc.flange2base, "quat_wxyz"), ("target2cam.csv", sc.target2cam, "rotvec")):
        rows = format_poses(T, fmt, "m", "rad")
        cols = ["x", "y", "z"] + (["qw", "qx", "qy", "qz"] if fmt == "quat_wxyz" else ["rx", "ry", "rz"])
        lines = ["id," + ",".join(cols)] + [f"p{i:02d}," + ",".join(repr(float(v)) for v in r) for i, r in enumerate(rows)]
        (folder / name).write_text("\n".join(lines) + "\n")
    spec = {"setup": setup,
            "robot_poses": {"file": "robot_poses.csv", "format": "quat_wxyz", "length_unit": "m", "angle_unit": "rad"},
            "camera_poses": {"file": "target2cam.csv", "format": "rotvec", "length_unit": "m", "angle_unit": "rad"}}
    (folder / "posepairs.yaml").write_text(yaml.safe_dump(spec))
    return folder


@pytest.mark.slow
def test_cli_names_what_is_undetermined_and_takes_known(tmp_path, capsys):
    sc = low_dof_scene(12, "eye_in_hand", "scara", 5)
    folder = _pair_folder(tmp_path / "scara", sc, "eye_in_hand")
    assert main(["check", str(folder)]) == 1
    assert "verdict: partial" in capsys.readouterr().out
    assert main(["calibrate-poses", str(folder), "--out", str(tmp_path / "open")]) == 1
    out = capsys.readouterr().out
    assert "NOT DETERMINED: translation of cam2flange along the flange z axis" in out and "check: partial" in out
    data = json.loads((tmp_path / "open" / "result.json").read_text())  # strict JSON: no Infinity
    assert data["check"]["verdict"] == "partial" and data["uncertainty"]["std_translation_mm"][2] is None
    assert data["unobservable"][0]["transform"] == "cam2flange" and data["determined"]["cam2flange.z"] == "undetermined"
    html = (tmp_path / "open" / "report.html").read_text()
    assert "Not determined:" in html and "PARTIAL" in html.upper()
    height = f"{sc.Z[2, 3]:.6f}+-0.0005"
    assert main(["calibrate-poses", str(folder), "--known", f"target2base.z={height}", "--out", str(tmp_path / "done")]) == 0
    out = capsys.readouterr().out
    assert "NOT DETERMINED" not in out and "known target2base.z" in out and "used" in out
    data = json.loads((tmp_path / "done" / "result.json").read_text())
    assert data["determined"]["cam2flange.z"] == "given (target2base.z)" and data["known"]["target2base.z"]["used"]
    assert abs(data["X"]["translation_m"][2] - sc.X[2, 3]) < 3 * data["uncertainty"]["std_translation_mm"][2] / 1e3 + 1e-4
    assert main(["calibrate-poses", str(folder), "--known", "target2base.z"]) == 2
    assert "--known 'target2base.z': give TRANSFORM.AXIS=METRES" in capsys.readouterr().err


def test_rendered_scara_session_calibrates_with_known(tmp_path):
    """handeye calibrate on images of a SCARA session: partial without known, complete with the
    target's height (the PnP poses, refined on poses: the pixel refinement does not run there)."""
    sc = handeye.simulate.simulate_session(tmp_path / "s", robot="scara", n_poses=6, seed=2)
    truth = yaml.safe_load((tmp_path / "s" / "ground_truth.yaml").read_text())
    assert truth["robot"] == "scara" and np.allclose(truth["cam2flange"], sc.X)
    open_ = handeye.calibrate(tmp_path / "s", progress=False)
    assert open_.verdict == "partial" and len(open_.image_names) == 6
    assert any("pixel refinement does not run" in n for n in open_.notes)
    cal = handeye.calibrate(tmp_path / "s", progress=False, known={"target2base.z": float(sc.Z[2, 3])})
    assert cal.verdict == "good" and not cal.unobservable
    d_rot, d_t = _errors(cal, sc)
    assert np.all(np.abs(d_t) <= 3 * cal.std[3:]) and np.all(np.abs(d_rot) <= 3 * cal.std[:3])
    assert np.abs(d_t).max() < 1.0  # mm


@pytest.mark.parametrize("robot", ["scara", "cartesian"])
def test_plan_for_robots_that_cannot_rotate_freely(robot, tmp_path, capsys):
    from handeye.planning.poses import plan_poses
    from handeye.sensors.camera.targets import target_from_spec
    from handeye.simulate import DEFAULT_TARGETS, default_camera

    obj = target_from_spec(DEFAULT_TARGETS["chessboard"]).object_points()
    K, dist = default_camera((1280, 1024))
    X = handeye.geometry.se3.make_transform(np.eye(3), [0.04, 0.0, 0.06])
    Z = handeye.geometry.se3.make_transform(Rotation.from_euler("x", 180, degrees=True).as_matrix(), [0.45, 0.0, 0.0])
    plan = plan_poses("eye_in_hand", X, Z, obj, K, (1280, 1024), dist, n_poses=10, standoff=0.4, robot=robot,
                      z_range=(0.2, 0.6))
    R = plan.flange2base[:, :3, :3]
    assert np.allclose(R[:, 2, 2], -1.0)  # the flange points down: every rotation about the vertical
    assert np.all((plan.flange2base[:, 2, 3] >= 0.2) & (plan.flange2base[:, 2, 3] <= 0.6))
    if robot == "cartesian":
        assert np.allclose(R, R[0]) and np.isinf(plan.std_X[3:]).all() and len(plan.unobservable) == 3
    else:
        assert np.ptp(np.arctan2(R[:, 1, 0], R[:, 0, 0])) > np.radians(60)  # the planner uses the turn
        assert np.isinf(plan.std_X[5]) and np.isfinite(plan.std_X[:5]).all()
        assert plan.unobservable == ["translation of cam2flange along the flange z axis"]
    # the planned poses calibrate to the part of X they determine
    t2c = handeye.frames.setups.predicted_target2cam(X, Z, plan.flange2base, "eye_in_hand")
    cal = handeye.calibrate_poses(plan.flange2base, t2c)
    assert cal.verdict == "partial" and np.abs(cal.X[:3, :3] - X[:3, :3]).max() < 1e-9


def test_plan_cli_warns_what_a_scara_cannot_determine(tmp_path, capsys):
    (tmp_path / "camera.yaml").write_text(yaml.safe_dump(
        {"K": [[1000.0, 0, 640], [0, 1000.0, 512], [0, 0, 1]], "dist": [0.0] * 5, "image_size": [1280, 1024]}))
    argv = ["plan", "--robot", "scara", "--intrinsics", str(tmp_path / "camera.yaml"), "--standoff", "0.4",
            "--target-in-base", "0.45,0,0,180,0,0", "--cam-in-flange", "0.04,0,0.06", "--z-range", "0.2,0.9",
            "--out", str(tmp_path / "poses.csv")]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "translation [" in out and "inf] mm" in out
    assert "warning: a scara robot cannot determine the translation of cam2flange along the flange z axis" in out
    assert "--known target2base.z=METRES" in out and (tmp_path / "poses.csv").is_file()
    assert main(argv[:-1] + [str(tmp_path / "p2.csv"), "--z-range", "0.9,0.2"]) == 2
    assert "zmin below zmax" in capsys.readouterr().err


@pytest.mark.parametrize("robot", ["scara", "cartesian"])
@pytest.mark.parametrize("setup", SETUPS)
def test_swapped_poses_are_named_and_left_out(robot, setup):
    """Two robot poses swapped (mislabelled images): the outlier search runs on low-DOF data too,
    with the low-DOF solver, and the calibration leaves them out; clean data lose no pose."""
    sc = low_dof_scene(15, setup, robot, 3)
    f = sc.flange2base.copy()
    f[[2, 7]] = f[[7, 2]]
    cal = handeye.calibrate_poses(f, sc.target2cam, setup, known=_known(sc, robot, setup), robot_accuracy=None)
    assert cal.diagnostics.outliers == [2, 7] and 2 not in cal.pose_indices and len(cal.pose_indices) == 13
    assert any("2, 7 disagree" in n for n in cal.notes)
    d_rot, d_t = _errors(cal, sc)
    assert np.linalg.norm(d_t) <= 3 * np.linalg.norm(cal.std[3:]) and np.linalg.norm(d_rot) <= 3 * np.linalg.norm(cal.std[:3])
    clean = handeye.diagnose(sc.flange2base, sc.target2cam, setup)
    assert clean.verdict == "partial" and clean.outliers == []


@pytest.mark.slow
@pytest.mark.parametrize("robot", ["scara", "cartesian"])
def test_a_noisy_camera_does_not_hide_the_robots_low_dof_motion(robot):
    """PnP on a single AprilTag (4 corners, 0.5 px) strays by a degree and more from the one axis
    (or none) the robot turns about: the camera looked 'general' while the robot read one-axis, and
    all 10 of these sessions were refused with an error. The robot's kind decides while the camera
    strays within ~6 deg of it: each is answered, partial, its rotation within 3 std of the truth."""
    for seed in range(10):
        sc = low_dof_scene(10, "eye_in_hand", robot, seed, target="apriltag", pixel_px=0.5)
        cal = handeye.calibrate_poses(sc.flange2base, sc.target2cam, "eye_in_hand", progress=False)
        assert cal.verdict == "partial" and cal.motion_kind == {"scara": "one_axis"}.get(robot, "translation_only")
        d_rot, _ = _errors(cal, sc)
        assert np.linalg.norm(d_rot) <= 3 * np.linalg.norm(cal.std[:3]), (seed, d_rot, cal.std[:3])


@pytest.mark.parametrize("robot", ["cartesian", "scara"])
def test_one_flipped_camera_pose_of_a_low_dof_robot_is_answered_and_named(robot):
    """One camera pose 20 deg off (a flipped planar PnP solution) among 12 views of a gantry or a
    SCARA made the camera look as if it rotated freely, and the session was refused; the camera
    shows the robot's kind when 3/4 of its views agree (the kind is checked on those), and the
    partial path's outlier search names the odd one. Camera poses of another scene (rotating
    freely) are still refused."""
    from handeye.geometry.se3 import make_transform

    for seed in range(4):
        sc = low_dof_scene(12, "eye_in_hand", robot, seed)
        t2c = sc.target2cam.copy()
        t2c[4] = t2c[4] @ make_transform(Rotation.from_rotvec(np.radians(20.0) * np.array([1.0, 0.3, 0.0])).as_matrix(),
                                         np.zeros(3))
        cal = handeye.calibrate_poses(sc.flange2base, t2c, "eye_in_hand", progress=False)
        assert cal.verdict == "partial" and cal.diagnostics.outliers == [4]
        d_rot, _ = _errors(cal, sc)
        assert np.all(np.abs(d_rot) <= 3 * cal.std[:3]), (seed, d_rot, cal.std[:3])
    other = realistic_scene(12, "eye_in_hand", 3)
    with pytest.raises(handeye.DegenerateMotionError):
        handeye.calibrate_poses(sc.flange2base, other.target2cam, "eye_in_hand", progress=False)


@pytest.mark.slow
@pytest.mark.parametrize("robot", ["scara", "cartesian"])
@pytest.mark.parametrize("setup", SETUPS)
def test_another_scenes_low_dof_camera_poses_are_inconsistent_not_partial(robot, setup):
    """A SCARA's (or gantry's) robot poses paired with the camera poses of another session of the
    same robot: the camera shows the robot's kind of motion, so the partial path took them and
    answered 'partial' (pose residuals of 50-140 deg). Judged as general data are, by the
    consistency score of the low-DOF solver: 'inconsistent' with what to check, refused with
    strict; each session's own poses stay 'partial' with the score it was judged by."""
    kind = {"scara": "one_axis", "cartesian": "translation_only"}[robot]
    for seed in range(3):
        own = low_dof_scene(12, setup, robot, seed, robot_noise=(0.05, 0.2), pixel_px=0.3)
        other = low_dof_scene(12, setup, robot, seed + 100, robot_noise=(0.05, 0.2), pixel_px=0.3)
        good = handeye.calibrate_poses(own.flange2base, own.target2cam, setup, progress=False)
        assert good.verdict == "partial" and good.diagnostics.consistency <= 3.0
        cal = handeye.calibrate_poses(own.flange2base, other.target2cam, setup, progress=False)
        assert cal.verdict == "inconsistent" and cal.motion_kind == kind and cal.unobservable
        assert cal.diagnostics.consistency > 3.0
        assert any("do not agree on one camera mounting" in a for a in cal.diagnostics.advice)
        with pytest.raises(InputMismatchError, match="do not agree"):
            handeye.calibrate_poses(own.flange2base, other.target2cam, setup, strict=True, progress=False)
