"""Rigs (issue 63): several cameras in one fit, their relative poses, and the sensor that disagrees."""

from __future__ import annotations

import numpy as np
import pytest

from handeye.errors import InputMismatchError
from handeye.frames.metrics import rotation_error, translation_error, within_std
from handeye.pipelines.rig import calibrate_rig
from handeye.robot.models import ControllerPoses, PoseErrors
from handeye.sensors.camera.model import CameraCorners
from handeye.simulate.rig import rig_scene

ERROR = (0.01, 0.05)



def test_stereo_pair_relative_pose_from_the_joint_fit():
    """A stereo pair on the flange with a calibrated arm's error: the relative pose within 3 std and
    better known than either X (the robot's error cancels in it); each camera's X from the joint fit
    no worse than calibrated alone."""
    sc = rig_scene(15, "eye_in_hand", rng=3001, robot_error=ERROR)
    rig = calibrate_rig(sc.camera_models(), ["left", "right"], ControllerPoses(sc.flange2base, ERROR))
    assert rig.joint.verdict in ("good", "weak") and rig.disagreeing == []
    rel = rig.joint.sensor.figures["relative"]["right2left"]
    R, std = np.array(rel["matrix"]), np.array(rel["std_deg_mm"])
    assert within_std(R, sc.relative(1), std)
    assert 1e3 * translation_error(R, sc.relative(1)) < 0.2 and rotation_error(R, sc.relative(1)) < 0.01
    assert std[3:].max() < rig.joint.std[3:].min()  # the relative pose is better known than X
    for name, cam in zip(["left", "right"], sc.cameras):
        assert translation_error(rig.X(name), cam.X) <= 1.2 * translation_error(rig.alone[name].X, cam.X)
    assert "each pose's own error fitted" in " ".join(rig.joint.notes)


def test_three_fixed_cameras_one_with_a_wrong_focal_length_is_named():
    """Three fixed cameras, the board on the flange, one camera missing a third of the views: every X
    within 3 std; the same with one camera's focal length 5% off: that camera is named, left out, and
    the others' X stay right."""
    sc = rig_scene(12, "eye_to_hand", rng=4001, cameras=3, robot_error=ERROR, missing={2: 1 / 3})
    rig = calibrate_rig(sc.camera_models(), ["c0", "c1", "c2"], ControllerPoses(sc.flange2base, ERROR))
    assert rig.disagreeing == []
    for name, cam in zip(["c0", "c1", "c2"], sc.cameras):
        f = rig.joint.sensor.figures["X_per_sensor"][name]
        assert within_std(np.array(f["X"]), cam.X, np.array(f["std_deg_mm"]))  # the robot's accuracy in it
    bad = calibrate_rig(sc.camera_models({1: 0.05}), ["c0", "c1", "c2"], ControllerPoses(sc.flange2base, ERROR))
    assert [n for n, _ in bad.disagreeing] == ["c1"] and "wrong intrinsic" in bad.disagreeing[0][1]
    assert sorted(bad.joint.sensor.figures["X_per_sensor"]) == ["c0", "c2"]
    assert 1e3 * translation_error(bad.X("c0"), sc.cameras[0].X) < 1.0


def test_bad_rigs_are_named():
    """Two sensors with one name; a sensor that saw too few views is skipped by name and the others
    still calibrated; per-pose errors need the robot's accuracy."""
    sc = rig_scene(10, "eye_to_hand", rng=5, cameras=3, missing={2: 0.9})
    members = sc.camera_models()
    with pytest.raises(InputMismatchError, match="c0 given twice"):
        calibrate_rig(members, ["c0", "c0", "c1"], ControllerPoses(sc.flange2base))
    rig = calibrate_rig(members, ["c0", "c1", "c2"], ControllerPoses(sc.flange2base, ERROR))
    assert [n for n, _ in rig.skipped] == ["c2"] and "at least 3" in rig.skipped[0][1]
    assert sorted(rig.joint.sensor.figures["X_per_sensor"]) == ["c0", "c1"]
    with pytest.raises(InputMismatchError, match="accuracy"):
        PoseErrors(sc.flange2base)


def test_rig_session_round_trip_and_bad_sessions(tmp_path):
    """simulate --sensor rig, then calibrate: every camera's X right from rendered images, a ROS 2
    launch file with a frame per camera, result.json read back; a sensor named twice, a sensor
    without intrinsics, a missing image (a view that camera did not see, said in a note)."""
    import yaml

    from handeye import load_result
    from handeye.cli import main
    from handeye.errors import SessionError
    from handeye.pipelines.rig import calibrate_rig_session
    folder = tmp_path / "s"
    assert main(["simulate", "--sensor", "rig", "--poses", "8", "--out", str(folder), "--seed", "2"]) == 0
    (folder / "cam1" / "v03.png").unlink()
    assert main(["calibrate", str(folder), "--out", str(tmp_path / "out"), "--robot-accuracy", "0.01,0.05"]) == 0
    truth = yaml.safe_load((folder / "ground_truth.yaml").read_text())
    back = load_result(tmp_path / "out" / "result.json")
    for name in ("cam0", "cam1"):
        f = back.sensor.figures["X_per_sensor"][name]
        assert within_std(np.array(f["X"]), np.array(truth["cameras"][name]["cam2flange"]), np.array(f["std_deg_mm"]))
    assert "sensor cam1: no image for 1 of 8 views (v03)" in " ".join(back.notes)
    launch = (tmp_path / "out" / "rig_static_tf.launch.py").read_text()
    assert "'cam0_optical_frame'" in launch and "'cam1_optical_frame'" in launch
    text = (folder / "session.yaml").read_text()
    (folder / "session.yaml").write_text(text.replace("  cam1:", "  cam0:", 1))
    with pytest.raises(SessionError, match="key 'cam0' given twice"):
        calibrate_rig_session(folder)
    spec = yaml.safe_load(text)
    del spec["sensors"]["cam1"]["camera"]
    (folder / "session.yaml").write_text(yaml.safe_dump(spec))
    with pytest.raises(SessionError, match="cam1: camera .K and dist. is missing"):
        calibrate_rig_session(folder)


def test_a_rig_of_sensors_with_residuals_of_different_widths():
    """A camera (two residual columns) beside a laser profiler (one): the profiler's rows padded with
    zeros in a noise group of their own, each sensor's columns in groups of their own; sensors that
    see different targets share none."""
    from handeye.sensors.laser.model import SphereProfiles
    from handeye.sensors.rig import Rig
    from handeye.simulate import laser_scene

    sc = rig_scene(6, "eye_in_hand", rng=1)
    c = sc.cameras[0]
    camera = CameraCorners("eye_in_hand", sc.names, c.image_points, c.object_points, c.K, c.dist)
    camera.start(sc.flange2base, c.X, sc.Z)
    laser = SphereProfiles("eye_in_hand", sc.names, laser_scene(6, "eye_in_hand", rng=1).profiles, 0.02)
    rig = Rig([camera, laser], ["camera", "laser"], [(c.X, camera.target_params(sc.Z)), (c.X, np.zeros(3))],
              shared_target=False)
    on_laser = rig.member == 1
    assert rig.shape.shape == (len(rig.owner), 2)
    assert set(rig.noise_groups[~on_laser].ravel()) == {0} and set(rig.noise_groups[on_laser, 0]) == {1}
    assert set(rig.noise_groups[on_laser, 1]) == {2}
    X, p = rig.start(sc.flange2base, None, None)
    r = rig.residuals(X, p, sc.flange2base, np.arange(len(rig.owner)))
    assert np.all(r[on_laser, 1] == 0) and np.all(np.isfinite(r)) and np.abs(r[~on_laser]).max() < 1e-2
    with pytest.raises(InputMismatchError, match="share none"):
        Rig([camera, laser], ["camera", "laser"], [(c.X, np.zeros(6)), (c.X, np.zeros(3))])
