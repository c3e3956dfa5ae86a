"""Depth sessions: spheres found in clouds without any board, clouds read from .npy / .ply / .pcd,
session folders through ``handeye calibrate`` (verdict, cross-validation, files), and the bad input
of depth cameras refused with the file named and nothing written."""

from __future__ import annotations

import json
import re
import shutil

import numpy as np
import pytest
import yaml

from handeye.cli import main
from handeye.errors import DegenerateMotionError, HandEyeError, InputMismatchError, TargetError
from handeye.frames.metrics import rotation_error, translation_error
from handeye.geometry.se3 import invert, make_transform
from handeye.pipelines.depth.pipeline import calibrate_depth_session, calibrate_spheres
from handeye.pipelines.depth.session import load_depth_session
from handeye.pipelines.depth.simulate_board import depth_scene, sphere_scene, write_depth_session
from handeye.sensors.depth import check_frame, find_spheres, fit_sphere, read_cloud


@pytest.fixture(scope="module")
def spheres():
    """10 views of a 50 mm ball on a 12 mm rod at 0.5-1 m (eye-to-hand): depth noise 0.2-0.6 mm, scale 1.002."""
    return sphere_scene(10, "eye_to_hand", 4, stem=0.006)


def test_spheres_are_found_in_clouds_and_nothing_else_is(spheres):
    """Every view's centre within 0.3 mm of the truth (as the camera's scale moves it); a cloud
    without the ball (the wall alone) and a ball of another size are refused, naming the cloud."""
    for k, (cloud, T) in enumerate(zip(spheres.clouds[:5], spheres.target2cam[:5])):
        s = fit_sphere(cloud, spheres.radius, k)
        d = np.linalg.norm(T[:3, 3])
        expected = T[:3, 3] * (spheres.depth_scale * d - (spheres.depth_scale - 1) * spheres.radius) / d
        assert np.linalg.norm(s.centre - expected) < 3e-4
        assert s.n_points > 200 and np.all(np.linalg.eigvalsh(s.cov) > 0)
    wall = spheres.clouds[0].copy()
    s = fit_sphere(wall, spheres.radius, 0)
    wall[s.mask] = np.nan  # the ball's points gone: a wall and a rim of flying pixels
    with pytest.raises(TargetError, match="view 0: no sphere of diameter 50.0 mm"):
        fit_sphere(wall, spheres.radius, 0, where="view 0")
    with pytest.raises(TargetError, match="no sphere of diameter 20.0 mm"):
        fit_sphere(spheres.clouds[0], 0.010, 0)


def test_two_spheres_told_apart_by_their_diameters():
    """Two balls (50 and 30 mm) in one cloud: each found with its own radius, neither taken for the other."""
    a = sphere_scene(1, "eye_in_hand", 1, radius=0.025, holes=0.0)
    b = sphere_scene(1, "eye_in_hand", 2, radius=0.015, holes=0.0)
    ca, cb = a.clouds[0], b.clouds[0]
    # the second ball's pixels pasted where they are nearer than the first scene's
    near = np.isfinite(cb[..., 2]) & (cb[..., 2] < np.nan_to_num(ca[..., 2], nan=np.inf)) & (np.linalg.norm(
        cb - b.target2cam[0, :3, 3], axis=2) < 0.03)
    cloud = np.where(near[..., None], cb, ca)
    found = find_spheres(cloud, [0.025, 0.015], rng=0)
    assert np.linalg.norm(found[0].centre - a.target2cam[0, :3, 3]) < 3e-3
    assert np.linalg.norm(found[1].centre - b.target2cam[0, :3, 3]) < 3e-3


@pytest.mark.parametrize("setup", ["eye_to_hand", "eye_in_hand"])
def test_x_from_a_sphere_without_any_board(setup, spheres):
    """The issue's bar on one session per setup (10 views: the suite's time; the benchmark has 15):
    X within 0.5 mm / 0.2 deg of the truth and within 3 std (the data's: the simulated robot is
    exact), the depth scale within 3 std of 1.002."""
    sc = spheres if setup == "eye_to_hand" else sphere_scene(10, setup, 5, stem=0.006)
    n = 10
    found = [fit_sphere(c, sc.radius, k) for k, c in enumerate(sc.clouds[:n])]
    cal = calibrate_spheres(sc.flange2base[:n], np.array([f.centre for f in found]), setup,
                            np.array([f.cov for f in found]), radii=[sc.radius])
    rot, trans = np.degrees(rotation_error(cal.X, sc.X)), 1e3 * translation_error(cal.X, sc.X)
    assert rot < 0.2 and trans < 0.5, (rot, trans)
    assert np.all(np.abs(1e3 * (cal.X[:3, 3] - sc.X[:3, 3])) <= 3 * cal.std_sources["data"][3:])
    scale = cal.sensor.figures["depth_scale"]
    assert abs(scale["value"] - sc.depth_scale) <= 3 * scale["std"]
    assert np.linalg.norm(cal.Z[:3, 3] - sc.Z[:3, 3]) < 1e-3  # Z: the ball's centre
    assert np.all(cal.std >= cal.std_sources["data"])  # the robot's stated accuracy widens it


def test_a_sphere_seen_from_motions_about_one_axis_is_refused(spheres):
    """Flange turned about its z axis only: X's rotation is not determined; the error says what to capture."""
    F = np.array([make_transform(np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]]),
                                 [0.4, 0.1 * np.sin(a), 0.3]) for a in np.linspace(0, 1.5, 8)])
    centres = np.tile([0.0, 0.0, 0.7], (8, 1)) + np.random.default_rng(0).normal(0, 1e-4, (8, 3))
    with pytest.raises(DegenerateMotionError, match="at least two different axes"):
        calibrate_spheres(F, centres, "eye_to_hand")


@pytest.fixture(scope="module")
def board_session(tmp_path_factory):
    """A 4-view board session (rendered images, clouds): copied by each test that damages it."""
    return write_depth_session(tmp_path_factory.mktemp("depth") / "board", depth_scene(4, "eye_in_hand", 3))


def _session(tmp_path, scene, **kw):
    return write_depth_session(tmp_path / "session", scene, **kw)


@pytest.mark.slow
def test_a_sphere_session_through_the_command_line(tmp_path, capsys, spheres):
    """calibrate on a sphere session folder (clouds in mm): exit 0, the verdict good, X and the
    scale in result.yaml as in the library, the view beyond the stated range named, held-out views
    predicted within 0.2 mm; the same from a session where one cloud is another view's (the fit
    leaves it out, naming it, and check says so)."""
    folder = _session(tmp_path, spheres, unit="mm", working_range=(0.3, 0.9))
    assert main(["calibrate", str(folder), "--out", str(tmp_path / "out"), "--no-progress"]) == 0
    result = yaml.safe_load((tmp_path / "out" / "result.yaml").read_text())
    assert result["verdict"] == "good" and result["sensor"]["target"] == "spheres" and result["X_name"] == "cam2base"
    X = np.array(result["X"]["matrix"])
    assert 1e3 * translation_error(X, spheres.X) < 0.5
    assert result["cross_validation"]["prediction_error"]["mm"] < 0.2
    assert any("outside the camera's stated range 0.3-0.9 m" in a for a in result["check"]["advice"]) == bool(
        np.any(np.linalg.norm(spheres.target2cam[:, :3, 3], axis=1) > 0.9))
    scale = json.loads((tmp_path / "out" / "result.json").read_text())["sensor"]["figures"]["depth_scale"]
    assert scale == result["sensor"]["figures"]["depth_scale"]
    assert "report.html" in {p.name for p in (tmp_path / "out").iterdir()}
    # options of image sessions are refused, not dropped
    assert main(["calibrate", str(folder), "--method", "tsai_lenz", "--no-progress"]) != 0
    assert "method (--method): options of image and pose sessions" in capsys.readouterr().err
    assert main(["check", str(folder), "--refine", "pose", "--no-progress"]) != 0
    assert "refine (--refine): options of image and pose sessions" in capsys.readouterr().err
    # a cloud swapped for another view's: check (calibrate's verdict) leaves it out with the reason
    swapped = tmp_path / "session" / "clouds"
    (swapped / "view03.npy").write_bytes((swapped / "view09.npy").read_bytes())
    capsys.readouterr()
    assert main(["check", str(folder), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"view03.npy +left out: the fit does not explain this view", out) and "verdict: good" in out
    assert "9 of 10 views used" in out


@pytest.mark.slow
def test_a_board_session_with_rendered_images(tmp_path):
    """A board session: the corners detected in rendered intensity images, lifted from the clouds;
    X within 0.3 mm / 0.1 deg, the verdict good, every view used."""
    sc = depth_scene(7, "eye_in_hand", 7)
    cal = calibrate_depth_session(_session(tmp_path, sc))
    assert cal.verdict == "good" and len(cal.sensor.views) == 7 and not cal.skipped
    assert 1e3 * translation_error(cal.X, sc.X) < 0.3
    assert np.degrees(rotation_error(cal.X, sc.X)) < 0.1
    scale = cal.sensor.figures["depth_scale"]
    assert abs(scale["value"] - 1.002) <= 3 * scale["std"]
    assert any("clouds in the image's frame" in n for n in cal.notes)


def test_a_chessboard_named_from_the_other_end_in_one_view_is_renamed(board_session):
    """A detector names a chessboard's corners from either end: one view's named from the other end (a pose
    half a turn away, which no X explains) is renamed against the robot's motion before the fit."""
    from dataclasses import replace

    from handeye.pipelines.depth.pipeline import measure_depth_session
    from handeye.sensors.camera import detect_images, target_from_spec
    from handeye.sensors.camera.pnp import relabel_points

    s = load_depth_session(board_session)
    target = target_from_spec(s.target_spec)
    found = detect_images(s.image_paths, target)
    turned = list(found)
    det = found[2].detection
    turned[2] = replace(found[2], detection=replace(det, object_points=relabel_points(det.object_points,
                                                                                      target.symmetries()[1])))
    assert not np.allclose(turned[2].detection.object_points, det.object_points)
    mine, truth = measure_depth_session(s, detected=turned), measure_depth_session(s, detected=found)
    for a, b in zip(mine.object_points, truth.object_points):
        assert np.allclose(a, b)


def test_clouds_read_from_ply_and_pcd_as_from_npy(tmp_path, spheres):
    """The same organized cloud written as .npy, .ply (plyfile) and .pcd (pypcd4, organized and
    unorganized) reads back the same, missing depth (0, 0, 0 or NaN) as NaN."""
    plyfile = pytest.importorskip("plyfile")
    pypcd4 = pytest.importorskip("pypcd4")
    cloud = spheres.clouds[0].astype(np.float32)
    h, w = cloud.shape[:2]
    np.save(tmp_path / "c.npy", cloud)
    flat = np.nan_to_num(cloud.reshape(-1, 3), nan=0.0)
    vertex = np.rec.fromarrays(flat.T, dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    plyfile.PlyData([plyfile.PlyElement.describe(vertex, "vertex")]).write(str(tmp_path / "c.ply"))
    pc = pypcd4.PointCloud.from_xyz_points(cloud.reshape(-1, 3))
    pc.save(tmp_path / "flat.pcd")
    organized = pypcd4.PointCloud(pc.metadata.model_copy(update={"width": w, "height": h}), pc.pc_data)
    organized.save(tmp_path / "organized.pcd")
    ref = read_cloud(tmp_path / "c.npy")
    for name in ("c.ply", "flat.pcd", "organized.pcd"):
        got = read_cloud(tmp_path / name, (w, h))
        np.testing.assert_array_equal(np.isnan(got), np.isnan(ref))
        np.testing.assert_allclose(got[np.isfinite(got)], ref[np.isfinite(ref)], rtol=1e-6)
    with pytest.raises(InputMismatchError, match=r"flat.pcd: .* points, and its image is 320x240"):
        read_cloud(tmp_path / "flat.pcd", (320, 240))


def test_a_cloud_in_the_depth_sensors_frame_is_named(spheres):
    """A cloud moved 25 mm sideways (the depth sensor's frame, not the colour camera's) projects off
    its pixels with the image's K: refused, naming the file and the fix."""
    cloud = spheres.clouds[0]
    assert check_frame(cloud, spheres.K) < 0.01
    shifted = cloud + np.array([0.025, 0.0, 0.0], dtype=np.float32)
    with pytest.raises(InputMismatchError, match="view01.npy: .* another frame than the image"):
        check_frame(shifted, spheres.K, where="view01.npy")


@pytest.mark.parametrize("damage, message", [
    ("size", r"view02.npy: the cloud is 320x240 and its image 640x480"),
    ("nan", r"view02.npy: no point has a depth"),
    ("mm", r"view02.npy: median depth .* looks like millimetres"),
])
def test_bad_clouds_are_refused_naming_the_file_and_nothing_is_written(tmp_path, capsys, board_session, damage,
                                                                        message):
    """The issue's bad input, each through ``handeye calibrate`` on a board session: exit non-zero
    with the file named, no output folder made."""
    folder = shutil.copytree(board_session, tmp_path / "session")
    path = folder / "clouds" / "view02.npy"
    cloud = np.load(path)
    bad = {"size": cloud[::2, ::2], "nan": np.full_like(cloud, np.nan), "mm": cloud * 1000}[damage]
    np.save(path, bad)
    out = tmp_path / "out"
    assert main(["calibrate", str(folder), "--out", str(out), "--no-progress"]) != 0
    assert not out.exists()
    assert re.search(message, capsys.readouterr().err)


def test_a_depth_session_needs_its_files(tmp_path):
    """A missing cloud and a pose table without an image/cloud column: SessionError naming them."""
    folder = _session(tmp_path, sphere_scene(3, "eye_to_hand", 1))
    (folder / "clouds" / "view02.npy").unlink()
    with pytest.raises(Exception, match=r"no cloud for 'view02.npy'"):
        load_depth_session(folder)
    text = (folder / "poses.csv").read_text().replace("cloud,", "name,", 1)
    (folder / "poses.csv").write_text(text)
    with pytest.raises(Exception, match=r"poses.csv: header \['name', .* does not match"):
        load_depth_session(folder)


def test_bad_robot_poses_in_a_depth_session_name_the_table(tmp_path):
    """A pose table with a NaN, and a session.yaml without the poses' length unit: refused, naming the file."""
    folder = _session(tmp_path, sphere_scene(3, "eye_to_hand", 1))
    lines = (folder / "poses.csv").read_text().splitlines()
    cells = lines[2].split(",")
    cells[3] = "nan"
    (folder / "poses.csv").write_text("\n".join(lines[:2] + [",".join(cells)] + lines[3:]) + "\n")
    with pytest.raises(Exception, match=r"poses.csv"):
        load_depth_session(folder)
    spec = yaml.safe_load((folder / "session.yaml").read_text())
    del spec["poses"]["length_unit"]
    (folder / "session.yaml").write_text(yaml.safe_dump(spec))
    with pytest.raises(Exception, match=r"session.yaml: poses must be a mapping with file, format, length_unit"):
        load_depth_session(folder)


@pytest.mark.slow
def test_robot_poses_in_the_wrong_order_are_called_inconsistent(tmp_path, spheres):
    """The clouds paired with another view's robot pose: not an answer to trust. The verdict is
    inconsistent (the residuals far beyond what the stated robot accuracy and the depth noise allow),
    and the advice says what to check. The robot poses inverted (base2flange given): named before any
    fit, with both readings that fit (the poses inverted, or the other setup: the same equations)."""
    from dataclasses import replace

    session = load_depth_session(_session(tmp_path, spheres))
    order = np.roll(np.arange(len(session.names)), 5)
    cal = calibrate_depth_session(replace(session, flange2base=session.flange2base[order]))
    assert cal.verdict == "inconsistent", (cal.verdict, cal.diagnostics.advice)
    assert any("the robot poses and the measurements disagree" in a for a in cal.diagnostics.advice)
    with pytest.raises(HandEyeError, match="declare pose: base2flange") as raised:
        calibrate_depth_session(replace(session, flange2base=invert(session.flange2base)))
    assert "declare setup:" in str(raised.value)


@pytest.mark.slow
def test_depth_sessions_in_a_fleet_and_with_exports(tmp_path, capsys, spheres):
    """Two depth sessions in one ``calibrate`` (a fleet): both calibrated, each into its own folder
    with the same result files as any session; a depth result exports a ROS 2 launch file as any
    calibration does (issue 60, item 13)."""
    a = write_depth_session(tmp_path / "a", spheres)
    b = write_depth_session(tmp_path / "b", sphere_scene(8, "eye_in_hand", 7))
    assert main(["calibrate", str(a), str(b), "--out", str(tmp_path / "fleet"), "--no-progress", "--export",
                 "ros2-launch"]) == 0, capsys.readouterr()
    fleet = json.loads((tmp_path / "fleet" / "fleet.json").read_text())
    items = fleet["sessions"] if isinstance(fleet, dict) else fleet
    assert [i["verdict"] for i in items] == ["good", "good"], items
    for name in ("a", "b"):
        result = json.loads((tmp_path / "fleet" / name / "result.json").read_text())
        assert result["sensor"]["kind"] == "depth camera"
        assert (tmp_path / "fleet" / name / "handeye_static_tf.launch.py").is_file()


@pytest.mark.slow
def test_a_depth_session_with_joint_angles_fits_the_joints_compliance_when_asked(tmp_path):
    """compliance=True reaches the depth camera's robot model (the options record, not a loose field):
    the loaded joints' compliance is fitted with the table; without joint angles, or for a sensor
    that fits no table, it is refused by name."""
    from handeye.pipelines.silhouette.pipeline import calibrate_silhouette_session
    sc = depth_scene(8, "eye_to_hand", rng=2, arm="ur5", image_size=(240, 180))
    folder = write_depth_session(tmp_path / "j", sc)
    plain = calibrate_depth_session(folder)
    loaded = calibrate_depth_session(folder, compliance=True)
    assert not any(n.endswith(".compliance") for n in plain.kinematic.names)
    assert any(n.endswith(".compliance") for n in loaded.kinematic.names)
    assert main(["calibrate", str(folder), "--compliance", "--out", str(tmp_path / "out")]) in (0, 1)
    assert "compliance" in json.dumps(json.loads((tmp_path / "out" / "result.json").read_text()))
    poses = write_depth_session(tmp_path / "p", depth_scene(6, "eye_to_hand", rng=2, image_size=(240, 180)))
    with pytest.raises(InputMismatchError, match="the session has none .a joints: table"):
        calibrate_depth_session(poses, compliance=True)
    with pytest.raises(InputMismatchError, match="compliance .--compliance.: options of image and pose sessions"):
        calibrate_silhouette_session(poses, compliance=True)
