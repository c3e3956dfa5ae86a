"""One result schema for every sensor: result.json read back by ``handeye.load_result`` (issue 59).

Image, pose-pair, depth and joint sessions write the same keys (X, Z, verdict, uncertainty,
cross_validation, check, notes; a camera's own under images/camera, any other sensor's under
sensor), and each reads back into a Calibration with the same X, Z, std, verdict and notes; the
exports and verify take the result read back."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import handeye
from handeye.cli import main
from handeye.errors import SessionError
from handeye.pipelines.depth.pipeline import calibrate_depth_session
from handeye.pipelines.depth.simulate_board import sphere_scene, write_depth_session
from handeye.report import write_calibration, write_exports
from handeye.simulate import simulate_kinematic_session, simulate_session

BUNDLED = Path(handeye.__file__).parent / "data"
COMMON = {"X", "Z", "X_name", "Z_name", "setup", "method", "estimator", "verdict", "check", "notes", "uncertainty",
          "cross_validation", "poses", "handeye_version"}


def _round_trip(cal, folder):
    write_calibration(cal, folder, report=False)
    data = json.loads((folder / "result.json").read_text())
    back = handeye.load_result(folder)
    np.testing.assert_allclose(back.X, cal.X, atol=0)
    np.testing.assert_allclose(back.Z, cal.Z, atol=0)
    np.testing.assert_array_equal(back.std, cal.std)  # inf (undetermined) read back as inf
    np.testing.assert_allclose(back.cov, cal.cov)
    assert back.verdict == cal.verdict and back.notes == cal.notes and back.setup == cal.setup
    assert back.diagnostics.advice == cal.diagnostics.advice
    assert back.robot_accuracy == cal.robot_accuracy  # the robot's accuracy the std took
    assert back.prediction_error == cal.prediction_error
    np.testing.assert_allclose(back.flange2base, cal.flange2base)
    assert (back.target2cam is None) == (cal.target2cam is None)
    return data, back


def test_an_image_session_and_a_pose_pair_folder_read_back(tmp_path):
    cal = handeye.check_folder(BUNDLED / "sample_session", progress=False).calibration
    data, back = _round_trip(cal, tmp_path / "images")
    assert COMMON <= set(data) and {"images", "camera"} <= set(data) and "sensor" not in data
    np.testing.assert_allclose(back.camera_matrix, cal.camera_matrix)
    assert back.image_names == cal.image_names and back.image_sha256 == cal.image_sha256
    np.testing.assert_allclose(back.pose_residuals, cal.pose_residuals)  # the camera's poses came back with it
    pairs = handeye.check_folder(BUNDLED / "example_posepairs", progress=False).calibration
    data, _ = _round_trip(pairs, tmp_path / "pairs")
    assert COMMON <= set(data)
    # the exports take the result read back: the same ROS launch file as from the calibration itself
    a = write_exports(cal, tmp_path / "a", ["ros2-launch"])[0].read_text()
    b = write_exports(back, tmp_path / "b", ["ros2-launch"])[0].read_text()
    assert a == b


@pytest.mark.slow
def test_a_depth_session_writes_the_same_keys_and_reads_back(tmp_path):
    folder = write_depth_session(tmp_path / "s", sphere_scene(8, "eye_to_hand", 6))
    cal = calibrate_depth_session(folder)
    data, back = _round_trip(cal, tmp_path / "out")
    assert COMMON <= set(data) and "sensor" in data and "images" not in data
    assert back.sensor.figures == json.loads(json.dumps(cal.sensor.figures))
    assert back.sensor.views == cal.sensor.views and back.sensor.target == "spheres"
    np.testing.assert_array_equal(np.isfinite(back.std_Z), np.isfinite(cal.std_Z))  # a ball has no orientation: null


@pytest.mark.slow
def test_a_joint_session_reads_back(tmp_path):
    simulate_kinematic_session(tmp_path / "s", 8, "eye_in_hand", seed=2, image_size=(640, 480))
    cal = handeye.check_folder(tmp_path / "s", progress=False).calibration
    assert cal.kinematic is not None
    data, back = _round_trip(cal, tmp_path / "out")
    assert "kinematics" in data and back.kinematic is None  # the table itself is in arm_corrected.yaml
    assert (tmp_path / "out" / "arm_corrected.yaml").is_file()


@pytest.mark.slow
def test_verify_takes_a_result_read_back(tmp_path):
    """verify with a Calibration object gives what it gives with the result's folder."""
    simulate_session(tmp_path / "a", setup="eye_in_hand", n_poses=8, seed=4)
    simulate_session(tmp_path / "b", setup="eye_in_hand", n_poses=6, seed=5)
    assert main(["calibrate", str(tmp_path / "a"), "--out", str(tmp_path / "out"), "--no-progress"]) in (0, 1)
    from handeye.pipelines.verify import verify

    by_path = verify(tmp_path / "out", tmp_path / "b", progress=False)
    by_object = verify(handeye.load_result(tmp_path / "out"), tmp_path / "b", progress=False)
    np.testing.assert_allclose(by_path.px, by_object.px)
    assert by_path.verdict == by_object.verdict


def test_what_is_not_a_result_is_refused(tmp_path):
    with pytest.raises(SessionError, match="no result.json or result.yaml"):
        handeye.load_result(tmp_path)
    (tmp_path / "result.json").write_text('{"hello": 1}')
    with pytest.raises(SessionError, match="not a handeye result"):
        handeye.load_result(tmp_path / "result.json")
