"""The handeye command: the README's main job, pose-pair folders, and one-line errors."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

import handeye
from handeye.cli import main
from handeye.frames.metrics import rotation_error, translation_error
from handeye.io.session import load_pose_pairs

EXAMPLE = Path(handeye.__file__).parent / "data" / "example_posepairs"


def test_bundled_example_is_accurate():
    pairs = load_pose_pairs(EXAMPLE)
    truth = yaml.safe_load((EXAMPLE / "ground_truth.yaml").read_text())
    cal = handeye.calibrate_poses(pairs.flange2base, pairs.target2cam, setup=pairs.setup)
    X_true = np.array(truth["cam2flange"])
    # robot 0.05 deg / 0.2 mm and camera 0.1 deg / 0.5 mm noise on 12 poses
    assert np.degrees(rotation_error(cal.X, X_true)) < 0.3
    assert 1e3 * translation_error(cal.X, X_true) < 2.0


def test_bundled_example_uncertainty_covers_the_error():
    """The pose refinement's std against the known truth of the bundled example: the error, per
    rotation and translation, is within 3 predicted standard deviations (norms)."""
    pairs = load_pose_pairs(EXAMPLE)
    truth = yaml.safe_load((EXAMPLE / "ground_truth.yaml").read_text())
    cal = handeye.calibrate_poses(pairs.flange2base, pairs.target2cam, setup=pairs.setup)
    X_true = np.array(truth["cam2flange"])
    assert cal.refinement == "pose" and cal.method == "daniilidis+pose"
    assert rotation_error(cal.X, X_true) < 3 * np.sqrt(np.trace(cal.cov[:3, :3]))
    assert translation_error(cal.X, X_true) < 3 * np.sqrt(np.trace(cal.cov[3:, 3:]))
    closed = handeye.calibrate_poses(pairs.flange2base, pairs.target2cam, setup=pairs.setup, refine="none")
    assert closed.method == "daniilidis" and closed.std_sources["model"] is None  # no noise model: the jackknife's
    assert closed.std_sources["jackknife"] is not None and closed.std_sources["robot_accuracy"] is not None
    assert rotation_error(closed.X, X_true) < 3 * np.sqrt(np.trace(closed.cov[:3, :3]))
    assert translation_error(closed.X, X_true) < 3 * np.sqrt(np.trace(closed.cov[3:, 3:]))


def test_example_command_prints_x(capsys):
    assert main(["calibrate-poses", "--example"]) == 0
    out = capsys.readouterr().out
    assert "cam2flange (4x4, metres)" in out and "quaternion    wxyz" in out and "rotation vec   deg" in out
    assert "std of X (pose refinement: model + jackknife + robot accuracy)" in out and "pose noise estimated from the data" in out
    # the pitch difference as a share of the motion (on consistent data well under a few percent), not bare mm
    worst = float(re.search(r"screw congruence per motion .*worst [0-9.]+ deg / ([0-9.]+)%", out).group(1))
    assert worst < 3.0
    assert main(["calibrate-poses", "--example", "--refine", "none"]) == 0
    closed = capsys.readouterr().out
    assert "std of X (daniilidis: jackknife + robot accuracy)" in closed  # a closed form's verdict has a std too


@pytest.mark.slow
def test_console_script_runs_as_subprocess(tmp_path):
    exe = shutil.which("handeye")
    cmd = [exe] if exe else [sys.executable, "-m", "handeye.cli"]
    res = subprocess.run(cmd + ["calibrate-poses", "--example", "--out", str(tmp_path)], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    data = json.loads((tmp_path / "result.json").read_text())
    assert yaml.safe_load((tmp_path / "result.yaml").read_text())["X"]["matrix"] == data["X"]["matrix"]
    X = np.array(data["X"]["matrix"])
    assert np.allclose(X[:3, 3], data["X"]["translation_m"]) and data["X_name"] == "cam2flange"
    assert data["refinement"]["type"] == "pose" and set(data["refinement"]["pose_noise"]) == {
        "robot_rotation_deg", "camera_rotation_deg", "translation_mm", "camera_depth_mm"}
    assert data["check"]["verdict"] == "good" and data["check"]["outliers"] == []
    assert data["check"]["pose_indices_used"] == list(range(data["n_poses"]))
    assert len(data["Z"]["std_translation_mm"]) == 3 and min(data["Z"]["std_translation_mm"]) > 0  # Z has a std too
    cov = np.array(data["uncertainty"]["cov"])
    assert cov.shape == (6, 6) and np.allclose(data["uncertainty"]["std_translation_mm"], 1e3 * np.sqrt(np.diag(cov)[3:]))


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the user cache folder of Linux ($XDG_CACHE_HOME)")
def test_check_then_calibrate_detects_once(tmp_path, monkeypatch, capsys):
    """The command line keeps detections in the user's cache folder: ``check`` then ``calibrate`` on
    the same images detects once, and X is the same to the last bit as with ``--no-cache`` (which
    neither reads nor writes the cache); the environment is left as it was."""
    from handeye.sensors.camera import detect

    monkeypatch.delenv("HANDEYE_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    calls = []
    uncached = detect._detect_uncached
    monkeypatch.setattr(detect, "_detect_uncached", lambda p, t, *a: calls.append(p) or uncached(p, t, *a))
    assert main(["check", "--sample", "--no-progress"]) in (0, 1)
    entries = sorted((tmp_path / "xdg" / "handeye" / "detections").rglob("*.npz"))
    assert len(entries) == len(calls) == 12 and "HANDEYE_CACHE_DIR" not in os.environ
    assert main(["calibrate", "--sample", "--no-progress", "--out", str(tmp_path / "warm")]) in (0, 1)
    assert len(calls) == 12  # calibrate detected nothing
    assert main(["calibrate", "--sample", "--no-progress", "--no-cache", "--out", str(tmp_path / "cold")]) in (0, 1)
    assert len(calls) == 24 and sorted((tmp_path / "xdg").rglob("*.npz")) == entries
    capsys.readouterr()
    warm, cold = (json.loads((tmp_path / d / "result.json").read_text()) for d in ("warm", "cold"))
    assert warm["X"]["matrix"] == cold["X"]["matrix"] and warm["uncertainty"] == cold["uncertainty"]
    assert warm["check"]["verdict"] == cold["check"]["verdict"]


def _copy_example(tmp_path: Path) -> Path:
    folder = tmp_path / "pairs"
    shutil.copytree(EXAMPLE, folder)
    return folder


def _run(argv, capsys):
    code = main(argv)
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def test_folder_argument_and_out(tmp_path, capsys):
    folder = _copy_example(tmp_path)
    code, out, _ = _run(["calibrate-poses", str(folder), "--out", str(tmp_path / "res")], capsys)
    assert code == 0 and (tmp_path / "res" / "result.json").is_file()
    assert not list((tmp_path / "res").glob("*.tmp"))  # atomic writes leave no temporaries


def test_refuses_to_overwrite_inputs(tmp_path, capsys):
    folder = _copy_example(tmp_path)
    (folder / "result.json").write_text("{}")  # pretend the user keeps a file of that name there
    code, _, err = _run(["calibrate-poses", str(folder), "--out", str(folder)], capsys)
    assert code == 2 and "inside the input folder" in err
    code, _, err = _run(["calibrate-poses", str(folder), "--out", str(folder / "sub")], capsys)
    assert code == 2 and "inside the input folder" in err and not (folder / "sub").exists()
    assert (folder / "result.json").read_text() == "{}"


def _one_line_error(argv, capsys, expect):
    code, _, err = _run(argv, capsys)
    assert code != 0
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert expect in lines[0], lines[0]


def test_missing_folder(tmp_path, capsys):
    _one_line_error(["calibrate-poses", str(tmp_path / "nope")], capsys, "no such folder")


def test_missing_yaml_and_key(tmp_path, capsys):
    folder = _copy_example(tmp_path)
    (folder / "posepairs.yaml").unlink()
    _one_line_error(["calibrate-poses", str(folder)], capsys, "no posepairs.yaml. The folder must hold pose pairs")
    (folder / "session.yaml").write_text("setup: eye_in_hand\n")  # a session's file: the folder's kind named, with its command
    _one_line_error(["calibrate-poses", str(folder)], capsys, "it is a capture session; calibrate it with `handeye calibrate`")
    (folder / "session.yaml").unlink()
    spec = yaml.safe_load((EXAMPLE / "posepairs.yaml").read_text())
    del spec["robot_poses"]["length_unit"]
    (folder / "posepairs.yaml").write_text(yaml.safe_dump(spec))
    _one_line_error(["calibrate-poses", str(folder)], capsys, "missing key 'length_unit'")


def test_count_mismatch_and_bad_cell(tmp_path, capsys):
    folder = _copy_example(tmp_path)
    lines = (folder / "target2cam.csv").read_text().splitlines()
    (folder / "target2cam.csv").write_text("\n".join(lines[:-1]) + "\n")
    _one_line_error(["calibrate-poses", str(folder)], capsys, "appear in only one of")
    lines[3] = lines[3].replace(lines[3].split(",")[2], "abc", 1)
    (folder / "target2cam.csv").write_text("\n".join(lines) + "\n")
    _one_line_error(["calibrate-poses", str(folder)], capsys, "line 4, column 'y': 'abc' is not a number")


def test_wrong_header_and_wrong_units(tmp_path, capsys):
    folder = _copy_example(tmp_path)
    spec = yaml.safe_load((folder / "posepairs.yaml").read_text())
    spec["robot_poses"]["format"] = "quat_wxyz"
    (folder / "posepairs.yaml").write_text(yaml.safe_dump(spec))
    _one_line_error(["calibrate-poses", str(folder)], capsys, "does not match format 'quat_wxyz'")
    spec["robot_poses"]["format"] = "euler:ZYX"
    spec["robot_poses"]["length_unit"] = "m"
    (folder / "posepairs.yaml").write_text(yaml.safe_dump(spec))
    _one_line_error(["calibrate-poses", str(folder)], capsys, "look like millimetres")


def test_degenerate_data_is_an_error_not_an_answer(tmp_path, capsys):
    folder = _copy_example(tmp_path)
    robot = (folder / "robot_poses.csv").read_text().splitlines()
    cam = (folder / "target2cam.csv").read_text().splitlines()
    (folder / "robot_poses.csv").write_text("\n".join(robot[:3]) + "\n")
    (folder / "target2cam.csv").write_text("\n".join(cam[:3]) + "\n")
    _one_line_error(["calibrate-poses", str(folder)], capsys, "Only 2 pose(s): hand-eye calibration needs at least 3")


def test_example_and_folder_are_exclusive(capsys):
    _one_line_error(["calibrate-poses"], capsys, "give a pose-pair folder")


def test_no_check_no_out_and_honest_outlier_lines(capsys):
    """--no-check reaches check=False; without --out the command says it wrote nothing; the check
    line names poses left out and poses kept (by the pixel refinement) apart; the consistency score
    says what it measures."""
    from dataclasses import replace

    from handeye.cli import print_calibration

    assert main(["calibrate-poses", "--example", "--no-check", "--refine", "none"]) == 0
    out = capsys.readouterr().out
    assert "check:" not in out and "no --out: nothing written" in out
    pairs = load_pose_pairs(Path(handeye.__file__).parent / "data" / "example_posepairs")
    cal = handeye.calibrate_poses(pairs.flange2base, pairs.target2cam, refine="none")
    n = len(cal.flange2base)
    kept = replace(cal, diagnostics=replace(cal.diagnostics, outliers=[1]), pose_indices=np.arange(n))
    print_calibration(kept)
    text = capsys.readouterr().out
    assert "left out" not in text  # put back: the pixel refinement's note says so, once
    left = replace(cal, diagnostics=replace(cal.diagnostics, outliers=[1]), pose_indices=np.delete(np.arange(n), 1))
    print_calibration(left)
    assert "left out as outliers: pose 1" in capsys.readouterr().out
    assert "median pose residual in units of 1 deg or 2% of the camera's motion" in cal.diagnostics.summary()


def test_mistyped_options_and_commands_get_the_subcommand_usage_and_a_hint(capsys):
    assert main(["calibrate", "--outt", "x", "--sample"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert err.startswith("handeye calibrate: error: unrecognized argument(s) --outt (did you mean --out?)")
    assert "usage: handeye calibrate [-h]" in err  # the sub-command's usage, not the top level's
    assert main(["calibrat", "--sample"]) == 2
    assert "unknown command 'calibrat'; did you mean 'calibrate'?" in capsys.readouterr().err
    assert main(["check", "a-folder", "another-folder"]) == 2
    assert "unrecognized argument(s) 'another-folder'" in capsys.readouterr().err


@pytest.mark.slow
def test_wrong_euler_sequence_is_named_for_an_image_session(tmp_path, capsys):
    """The sample session (a symmetric chessboard) declared euler:XYZ instead of ZYX: the images
    were labelled against the wrongly read robot poses, so each other reading relabels them anew;
    check and calibrate name the sequence."""
    session = tmp_path / "session"
    shutil.copytree(Path(handeye.__file__).parent / "data" / "sample_session", session)
    spec = session / "session.yaml"
    spec.write_text(spec.read_text().replace("format: euler:ZYX", "format: euler:XYZ"))
    assert main(["check", str(session), "--no-progress"]) == 2
    out = capsys.readouterr().out
    assert "convention hint: euler:ZYX" in out and "declare format euler:ZYX" in out, out[-1500:]
    # calibrate answers (the fix is in the notes) with check's exit status for the same data
    assert main(["calibrate", str(session), "--no-progress", "--refine", "none"]) == 2
    assert "check: inconsistent" in capsys.readouterr().out


def test_no_parser_takes_an_abbreviated_option():
    """Every parser of the command line, subcommands and their subcommands included, refuses
    abbreviations (`--square 0.04` was taken for `--square-mm`)."""
    import argparse

    from handeye.cli import build_parser

    todo, seen = [build_parser()], 0
    while todo:
        parser = todo.pop()
        seen += 1
        assert parser.allow_abbrev is False, parser.prog
        for action in parser._actions:  # noqa: SLF001
            if isinstance(action, argparse._SubParsersAction):  # noqa: SLF001
                todo.extend(action.choices.values())
    assert seen >= 15


def test_simulate_renders_a_charuco_board_by_default(tmp_path):
    """handeye's advice prefers a board that cannot be read from the wrong end: the command's
    default target is ChArUco (the API's simulate_session keeps the thesis's chessboard)."""
    assert main(["simulate", "--out", str(tmp_path / "s"), "--poses", "4", "--seed", "1"]) == 0
    assert yaml.safe_load((tmp_path / "s" / "session.yaml").read_text())["target"]["type"] == "charuco"


def test_check_states_the_std_as_calibrate_does(capsys):
    """check and calibrate print X's std the one way: per axis, rotation in deg and translation in mm,
    labelled with what it is made of (issue 60, item 2)."""
    assert main(["check", "--sample", "--no-progress"]) == 0
    checked = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("std of X")]
    assert main(["calibrate", "--sample", "--no-progress"]) == 0
    calibrated = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("std of X")]
    assert len(checked) == len(calibrated) == 1
    assert checked[0].split(" mm")[0] == calibrated[0].split(" mm")[0]  # the same numbers and label


def test_base2flange_poses_in_an_image_session_and_unknown_keys(tmp_path, capsys):
    """A session whose poses.csv holds base2flange rows says so with ``pose: base2flange`` under
    poses: and calibrates to the same X as the flange2base rows; an unknown key anywhere in
    session.yaml is an error naming the nearest known key, never ignored (issue 60, item 1)."""
    import yaml

    import handeye
    from handeye.frames.poses import format_poses, parse_poses
    from handeye.geometry.se3 import invert
    from handeye.io.session import write_pose_table

    src = Path(handeye.__file__).parent / "data" / "sample_session"
    folder = shutil.copytree(src, tmp_path / "s")
    rows = np.loadtxt(folder / "poses.csv", delimiter=",", skiprows=1, usecols=range(1, 7))
    names = [line.split(",")[0] for line in (folder / "poses.csv").read_text().splitlines()[1:]]
    inverse = format_poses(invert(parse_poses(rows, "euler:ZYX", "mm", "deg")), "euler:ZYX", "mm", "deg")
    write_pose_table(folder / "poses.csv", names, None, "euler:ZYX", "mm", "deg", rows=inverse)
    spec = yaml.safe_load((folder / "session.yaml").read_text())
    spec["poses"]["pose"] = "base2flange"
    (folder / "session.yaml").write_text(yaml.safe_dump(spec))
    back = handeye.calibrate(folder, progress=False)
    ref = handeye.calibrate(src, progress=False)
    assert back.verdict == ref.verdict and np.allclose(back.X, ref.X, atol=1e-6)
    spec["poses"]["lenght_unit"] = spec["poses"].pop("length_unit")
    (folder / "session.yaml").write_text(yaml.safe_dump(spec))
    assert main(["check", str(folder), "--no-progress"]) != 0
    assert "unknown key 'lenght_unit' (did you mean 'length_unit'?)" in capsys.readouterr().err
    spec["poses"]["length_unit"] = spec["poses"].pop("lenght_unit")
    spec["cameras"] = spec.pop("camera")
    (folder / "session.yaml").write_text(yaml.safe_dump(spec))
    with pytest.raises(handeye.SessionError, match="unknown key 'cameras' \\(did you mean 'camera'\\?\\)"):
        handeye.calibrate(folder, progress=False)


def test_a_noise_the_data_do_not_resolve_is_said_so_not_printed_as_zero():
    """Issue 60, item 7: an estimated noise that reached zero reads 'below what the data resolve'."""
    from handeye.result import Calibration

    cal = Calibration(np.eye(4), np.eye(4), "eye_in_hand", "pose", pose_noise={
        "robot_rotation_deg": 0.012, "camera_rotation_deg": 0.0, "translation_mm": 0.0, "camera_depth_mm": 0.25})
    text = cal.pose_noise_text()
    assert "robot rotation 0.0120 deg" in text and "camera depth (along its optical axis) 0.250 mm" in text
    assert text.count("below what the data resolve") == 2 and "0.000" not in text


def test_only_handeyes_words_reach_the_terminal(tmp_path, capfd):
    """A missing image and an image named in CJK: calibrate --out says which image it skipped, and
    neither OpenCV's '[ WARN...] imread_' nor matplotlib's missing-glyph warnings reach stderr
    (issue 60, item 12)."""
    import handeye

    folder = shutil.copytree(Path(handeye.__file__).parent / "data" / "sample_session", tmp_path / "s")
    (folder / "images" / "003.jpg").unlink()
    (folder / "images" / "004.jpg").rename(folder / "images" / "画像004.jpg")
    (folder / "poses.csv").write_text((folder / "poses.csv").read_text().replace("004.jpg", "画像004.jpg"), encoding="utf-8")
    assert main(["calibrate", str(folder), "--out", str(tmp_path / "out"), "--no-progress"]) in (0, 1)
    out, err = capfd.readouterr()
    assert "skipped 003.jpg: missing from images/" in out
    assert "[ WARN" not in err and "Glyph" not in err, err[-2000:]


def test_notes_fold_to_the_terminal_width_and_stay_one_line_in_a_pipe(monkeypatch):
    """Issue 60, item 9: a ~500-character note is folded to the terminal's width when printed to a
    terminal (every line within it, the words intact), and stays one line in a pipe or a log."""
    import io

    from handeye.cli._printing import wrapped

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    monkeypatch.setenv("COLUMNS", "80")
    note = " ".join(["the std of X includes the robot's absolute accuracy"] * 10)
    folded = wrapped(note, "note: ", Terminal()).splitlines()
    assert len(folded) > 3 and all(len(line) <= 79 for line in folded)
    assert " ".join(line.strip() for line in folded) == "note: " + note
    assert wrapped(note, "note: ", io.StringIO()) == "note: " + note


def test_the_help_names_every_importer_and_every_laser_target(capsys):
    """Issue 77: handeye --help's import line omitted EasyHeC, and simulate --help listed sphere and
    plane for laser_line where edges, steps and fixtures of balls exist too. Both lists now come from
    the commands' own tables."""
    from handeye.cli.import_ import SOURCES
    from handeye.pipelines.laser.simulate import TARGETS

    assert main(["--help"]) == 0
    top = " ".join(capsys.readouterr().out.split())
    assert all(kind in top.split("import ", 1)[1].split(" target ", 1)[0] for kind in SOURCES) and "easyhec" in top
    assert main(["simulate", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    laser = text.split("with --sensor laser_line:", 1)[1].split(";", 1)[0]
    assert all(t in laser for t in TARGETS) and {"edge", "step", "spheres"} <= set(TARGETS)
    assert "a block's edge, a step or a fixture of balls" in text


def test_the_guides_laser_section_claims_nothing_missing_that_ships():
    """Issue 77: the guide's laser section ended 'Not yet: edges and several balls as targets, and
    line-scan cameras', all three documented (and shipped) in the same guide."""
    from handeye.pipelines.laser.simulate import TARGETS

    guide = (Path(__file__).resolve().parents[1] / "docs" / "guide.md").read_text(encoding="utf-8")
    laser = guide.split("\n## Laser")[1].split("\n## ")[0]
    assert all(f"{{type: {t}" in laser for t in TARGETS) and "\n## Line-scan cameras" in guide
    not_yet = " ".join(s for s in re.split(r"(?<=\.)\s", laser) if "Not yet" in s)
    assert not any(word in not_yet for word in ("edge", "balls", "line-scan"))
