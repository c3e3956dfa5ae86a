"""Importers of others' recordings and datasets (issues 21 and 24): easy_handeye2's samples, ViSP's
tutorial folders and ROS-Industrial's industrial_calibration sets (the real ones in ../shared), each
written as a handeye folder that calibrates. ROS bags are in test_streams.py (they carry streams)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

import handeye
from conftest import require_real
from handeye.cli import main
from handeye.errors import HandEyeError, InputMismatchError
from handeye.frames.metrics import rotation_error, translation_error
from handeye.geometry.se3 import invert, make_transform
from handeye.io.importers import import_easy_handeye, import_industrial_calibration, import_visp
from handeye.io.session import load_pose_pairs, load_session
from handeye.simulate import random_scene


def test_easy_handeye_samples_import(tmp_path, capsys):
    """easy_handeye2's samples: the effector in the base (eye-on-base: the base in the effector)
    and the marker in the tracking frame; imported as pose pairs that calibrate to the truth."""
    for setup, kind in (("eye_in_hand", "eye_in_hand"), ("eye_to_hand", "eye_on_base")):
        sc = random_scene(10, setup=setup, rng=5)
        robot = sc.flange2base if kind == "eye_in_hand" else invert(sc.flange2base)

        def tr(T):
            q = Rotation.from_matrix(T[:3, :3]).as_quat()
            return {"translation": dict(zip("xyz", map(float, T[:3, 3]))),
                    "rotation": dict(zip("xyzw", map(float, q)))}
        data = {"parameters": {"name": "cell", "calibration_type": kind},
                "samples": [{"robot": tr(a), "tracking": tr(b)} for a, b in zip(robot, sc.target2cam)]}
        path = tmp_path / f"{kind}.samples"
        path.write_text(yaml.safe_dump(data))
        out = tmp_path / f"{kind}_pairs"
        assert main(["import", "easy-handeye", str(path), "--out", str(out)]) == 0
        pairs = load_pose_pairs(out)
        assert pairs.setup == setup
        cal = handeye.calibrate_poses(pairs.flange2base, pairs.target2cam, pairs.setup, refine="none")
        assert rotation_error(cal.X, sc.X) < 1e-9 and translation_error(cal.X, sc.X) < 1e-9
    data["parameters"]["calibration_type"] = ""
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(InputMismatchError, match="does not say the setup"):
        import_easy_handeye(path, tmp_path / "none")


def _translation_mm(cal) -> np.ndarray:
    return 1e3 * cal.X[:3, 3]


@pytest.mark.parametrize("name, setup, spec", [
    ("eye_to_hand_2025", "eye_to_hand", None),
    ("legacy_eye_in_hand_2022", "eye_in_hand", {"type": "chessboard", "cols": 9, "rows": 6, "square": 0.0262}),
    ("legacy_posepairs_2018", "eye_in_hand", None),
])
def test_visp_folders_import_and_calibrate(tmp_path, name, setup, spec):
    """ViSP's folders (poses, images, camera.xml, the target's txt) calibrate as imported: X within
    a few mm of ViSP's own result printed in its tutorial (ABOUT.md), the intrinsics from camera.xml."""
    src = require_real("visp-franka", name)
    reference = {"eye_to_hand_2025": [954.0, -51.2, 476.2], "legacy_eye_in_hand_2022": [-36.1, -58.7, 30.3],
                 "legacy_posepairs_2018": [53.4, -8.2, -45.4]}[name]
    summary = import_visp(src, tmp_path / "out", setup=setup, target=spec)
    if summary.kind == "posepairs":
        pairs = load_pose_pairs(summary.folder)
        cal = handeye.calibrate_poses(pairs.flange2base, pairs.target2cam, pairs.setup)
    else:
        session = load_session(summary.folder)
        assert session.camera_matrix is not None and len(session.image_names) == 8
        cal = handeye.calibrate(summary.folder, progress=False)
    off = np.linalg.norm(_translation_mm(cal) - reference)
    print(f"ViSP {name}: X {_translation_mm(cal).round(1)} mm, ViSP's {reference}: {off:.1f} mm apart; verdict {cal.verdict}")
    assert off < 5.0


def test_industrial_calibration_sets_import_and_calibrate(tmp_path):
    """ROS-Industrial's ChArUco set (eye-to-hand) imported from its cal_data.yaml: X within 2 cm /
    1 deg of the camera pose the dataset gives as its guess, as the repository's own test allows."""
    src = require_real("industrial-calibration", "test_set_charuco")
    summary = import_industrial_calibration(src / "cal_data.yaml", tmp_path / "charuco")
    session = load_session(summary.folder)
    assert session.setup == "eye_to_hand" and session.target_spec["dictionary"] == "DICT_6X6_250"
    cal = handeye.calibrate(summary.folder, progress=False)
    guess = make_transform(Rotation.from_quat([-0.048080, -0.558686, 0.827604, -0.025104]).as_matrix(),
                           [-0.019646, 1.27843, 0.283965])
    dmm, ddeg = 1e3 * translation_error(cal.X, guess), np.degrees(rotation_error(cal.X, guess))
    print(f"industrial ChArUco: X {_translation_mm(cal).round(1)} mm, {dmm:.1f} mm / {ddeg:.2f} deg from the guess")
    assert dmm < 20 and ddeg < 1.0
    with pytest.raises(HandEyeError, match="already holds a session"):
        import_industrial_calibration(src, summary.folder)


def test_visp_2025_eye_in_hand_imports_and_its_board_scale_is_named(tmp_path):
    """ViSP's 2025 eye-in-hand folder names a 23.6 mm board in chessboard-data.txt; its images show the
    26.2 mm one (found in session 8): imported as it is, the calibration answers and names the scale."""
    summary = import_visp(require_real("visp-franka", "eye_in_hand_2025"), tmp_path / "out")
    cal = handeye.calibrate(summary.folder, progress=False, refine="none")
    assert cal.verdict == "inconsistent" and cal.diagnostics.scale == pytest.approx(1.11, abs=0.03)
    assert any("multiply it by 1.1" in a for a in cal.diagnostics.advice)


def test_visp_import_takes_the_setup_from_the_data_or_says_it_assumed_one(tmp_path, capsys):
    """ViSP's folders do not record the setup. The import checks the images' poses: the eye-to-hand
    folder is consistent only as eye-to-hand (the camera 1.07 m from the base, the tag 0.08 m from
    the flange), so it is written so, with the check's sentence, and calibrates to ViSP's rMc within
    2 mm; the eye-in-hand folder fits the assumed eye-in-hand, which the import says it took and how
    to change. Nothing of the kind with --setup given. ``-o`` is ``--out``."""
    visp = require_real("visp-franka")
    assert main(["import", "visp", str(visp / "eye_to_hand_2025"), "-o", str(tmp_path / "a")]) == 0
    out = capsys.readouterr().out
    assert "setup: eye_to_hand, from the data" in out and "most likely the setup is eye_to_hand" in out
    assert load_session(tmp_path / "a").setup == "eye_to_hand"
    cal = handeye.calibrate(tmp_path / "a", progress=False)
    assert 1e3 * np.linalg.norm(cal.X[:3, 3] - [0.9540358034, -0.05123574465, 0.4762201018]) < 2.0  # ViSP's rMc
    assert main(["import", "visp", str(visp / "eye_in_hand_2025"), "-o", str(tmp_path / "b")]) == 0
    out = capsys.readouterr().out
    assert "eye_in_hand assumed" in out and "--setup eye_to_hand" in out
    assert load_session(tmp_path / "b").setup == "eye_in_hand"
    assert main(["import", "visp", str(visp / "eye_to_hand_2025"), "--out", str(tmp_path / "c"), "--setup", "eye_in_hand"]) == 0
    out = capsys.readouterr().out
    assert "assumed" not in out and "from the data" not in out
    assert load_session(tmp_path / "c").setup == "eye_in_hand"


def test_industrial_calibration_circle_grid_set_imports_and_calibrates(tmp_path):
    """ROS-Industrial's 10x10 modified circle grid (eye-in-hand, nominal intrinsics; a square grid
    whose corner circle is drawn large): imported as ``modified_circles``, every image is read from
    its big circle, and it calibrates with a verdict. findCirclesGrid puts the big circle at the same
    index in all 15 images, so OpenCV's order is that same reading; X equals calibrateHandEye's
    (Daniilidis) on it. Read as a plain symmetric grid, the labels chosen from the robot motion alone
    agree (the same X, no image in doubt): four robot motions from the first pose are pure
    translations, and judged by their noise-set pitch one image was read a quarter turn off and four
    named as matching no reading."""
    src = require_real("industrial-calibration", "test_set_10x10")
    summary = import_industrial_calibration(src, tmp_path / "c")
    session = load_session(summary.folder)
    assert session.setup == "eye_in_hand" and session.target_spec["type"] == "modified_circles"
    cal = handeye.calibrate(summary.folder, progress=False, refine="none")
    print(f"industrial 10x10: X {np.round(1e3 * cal.X[:3, 3], 1)} mm, verdict {cal.verdict}")
    assert cal.verdict in ("good", "weak") and np.isfinite(cal.X).all() and len(cal.image_names) == 15
    spec = yaml.safe_load((summary.folder / "session.yaml").read_text())
    spec["target"]["type"] = "circles"
    (summary.folder / "session.yaml").write_text(yaml.safe_dump(spec))
    symmetric = handeye.calibrate(summary.folder, progress=False, refine="none")
    assert not [n for n in symmetric.notes if "symmetric circles target" in n]
    assert rotation_error(symmetric.X, cal.X) < 1e-6 and translation_error(symmetric.X, cal.X) < 1e-6
    K = np.array(session.camera_matrix)
    grid = np.zeros((100, 3))
    grid[:, :2] = np.mgrid[0:10, 0:10].T.reshape(-1, 2) * 0.0254
    params = cv2.SimpleBlobDetector_Params()
    params.minArea = 10.0
    R_f, t_f, R_t, t_t = [], [], [], []
    for name, flange2base in zip(session.image_names, session.flange2base):
        gray = cv2.imread(str(summary.folder / "images" / name), cv2.IMREAD_GRAYSCALE)
        params.maxArea = gray.size / 20.0
        blobs = cv2.SimpleBlobDetector_create(params)
        found, centres = cv2.findCirclesGrid(gray, (10, 10), flags=cv2.CALIB_CB_SYMMETRIC_GRID, blobDetector=blobs)
        assert found
        big = max(blobs.detect(gray), key=lambda d: d.size).pt
        assert np.argmin(np.linalg.norm(centres.reshape(-1, 2) - big, axis=1)) == 90, name  # the big circle
        _, rvec, tvec = cv2.solvePnP(grid, centres, K, None)
        R_f.append(flange2base[:3, :3])
        t_f.append(flange2base[:3, 3])
        R_t.append(cv2.Rodrigues(rvec)[0])
        t_t.append(tvec)
    R, t = cv2.calibrateHandEye(R_f, t_f, R_t, t_t, method=cv2.CALIB_HAND_EYE_DANIILIDIS)
    X_opencv = make_transform(R, t.ravel())
    assert np.degrees(rotation_error(cal.X, X_opencv)) < 0.05 and 1e3 * translation_error(cal.X, X_opencv) < 0.5


def test_each_importer_has_its_own_help_and_options(capsys):
    """``handeye import KIND --help`` describes that source and lists only its options; an option of
    another source is named as unknown for this one."""
    helps = {}
    for kind in ("rosbag", "easy-handeye", "visp", "industrial-calibration"):
        assert main(["import", kind, "--help"]) == 0
        helps[kind] = capsys.readouterr().out
    assert len(set(helps.values())) == 4
    assert "--robot-topic" in helps["rosbag"] and "--robot-topic" not in helps["visp"]
    assert "ViSP's hand-eye tutorial" in helps["visp"] and "--target-spec" in helps["visp"]
    assert "--setup" not in helps["industrial-calibration"]
    assert main(["import", "visp", "folder", "--out", "x", "--robot-topic", "/pose"]) == 2
    err = capsys.readouterr().err
    assert "unrecognized argument(s) --robot-topic" in err and "usage: handeye import visp" in err
