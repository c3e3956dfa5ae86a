"""Markerless hand-eye from colour images (issue 62, "the robot itself"): the CPU renderer against a
known case, the outline model's derivatives, the simulator's X recovered through ``handeye
calibrate``, EasyHeC's real capture imported and checked (its masks do not all agree with their own
joint angles: named), and bad input refused by name with nothing written."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
import yaml

from handeye.cli import main
from handeye.errors import SessionError
from handeye.frames.metrics import rotation_error, translation_error
from handeye.geometry.se3 import perturb
from handeye.pipelines.silhouette.importers import import_easyhec
from handeye.pipelines.silhouette.pipeline import arm_views, global_start, outline_rounds, pairing_notes
from handeye.pipelines.silhouette.session import load_silhouette_session, read_masks
from handeye.pipelines.silhouette.simulate import silhouette_scene, write_silhouette_session
from handeye.robot.meshes import arm_meshes
from handeye.sensors.silhouette.model import SilhouetteContours
from handeye.sensors.silhouette.render import bilinear, iou, project, render_silhouettes, signed_distance

pytest.importorskip("rtbdata", reason="the Panda's meshes come from rtb-data (pip install 'handeye[markerless]')")

EASYHEC = Path(__file__).resolve().parents[2] / "shared" / "data" / "real" / "easyhec-franka-markerless"
#: EasyHeC's own initial guess for this capture (its configs/franka/example_franka_offline.yaml, init_Tc_c2b: the base
#: in the camera's frame), set by hand with its tuning tool: an independent start for the same fit
EASYHEC_INIT = np.linalg.inv(np.array([[9.3969262e-01, 3.4202009e-01, 6.4914198e-09, -6.4085639e-01],
                                       [1.7101002e-01, -4.6984622e-01, -8.6602539e-01, 4.9582830e-01],
                                       [-2.9619810e-01, 8.1379771e-01, -4.9999991e-01, 1.2412001e+00],
                                       [0.0, 0.0, 0.0, 1.0]]))


@pytest.fixture(scope="module")
def scene():
    """10 masks of a Panda at 640x480 from a fixed camera 1-2 m away, boundaries off by ~1 px, blobs."""
    return silhouette_scene(10, rng=4)


@pytest.fixture(scope="module")
def easyhec(tmp_path_factory):
    if not EASYHEC.is_dir():
        pytest.skip("EasyHeC's capture is not in ../shared/data/real")
    return import_easyhec(EASYHEC, tmp_path_factory.mktemp("easyhec") / "s").folder


def test_renderer_fills_a_square_and_leaves_out_what_is_behind():
    """A 0.2 m square 1 m in front of a 100 px camera covers 20 x 20 pixels (OpenCV fills half a pixel
    beyond the outline: 21 x 21); a triangle behind the camera draws nothing; the signed distance
    is zero on the boundary, read between pixel centres."""
    K = np.array([[100.0, 0, 31.5], [0, 100, 23.5], [0, 0, 1]])
    square = np.array([[-0.1, -0.1, 1.0], [0.1, -0.1, 1.0], [0.1, 0.1, 1.0], [-0.1, 0.1, 1.0]])
    faces = np.array([[0, 2, 1], [0, 3, 2]])
    drawn = render_silhouettes(square[None], faces, K, (64, 48))[0]
    assert drawn.sum() == 21 * 21
    behind = square * [1, 1, -1]
    assert render_silhouettes(np.stack([square, behind]), faces, K, (64, 48))[1].sum() == 0
    assert np.isnan(project(behind, K)[0]).all()
    exact = np.zeros((48, 64), bool)
    exact[14:34, 22:42] = True  # pixel centres inside the square's 20 x 20 pixels
    sdf = signed_distance(exact)
    assert bilinear(sdf, np.array([[21.5, 23.0], [41.5, 23.0], [31.0, 13.5]])) == pytest.approx([0, 0, 0], abs=1e-6)
    assert iou(exact, drawn) == pytest.approx(400 / 441)


@pytest.mark.slow
def test_outline_model_derivatives_and_residuals(scene):
    """At the true X the outline points sit on the masks' boundaries (about the segmentation's pixel);
    the model's Jacobian matches finite differences."""
    views = arm_views(_session(scene), scene.masks)
    points, owner = views.outline_points(scene.X, spacing=2.0)
    model = SilhouetteContours([f"v{k}" for k in range(10)], points, owner, scene.K, None, views.sdf, scene.X)
    rows = np.arange(len(owner))
    px = model.residuals_px(scene.X, rows)
    assert len(rows) > 2000 and np.median(np.abs(px)) < 1.2
    X = perturb(scene.X, [0.002, -0.001, 0.001], [0.003, 0.002, -0.004])
    J = model.jacobian(X, None, None, rows)[:, 0]
    h = 1e-6
    for j in (0, 4):
        d = np.zeros(6)
        d[j] = h
        num = (model.residuals(perturb(X, d[:3], d[3:]), None, None, rows) -
               model.residuals(perturb(X, -d[:3], -d[3:]), None, None, rows))[:, 0] / (2 * h)
        assert np.median(np.abs(num - J[:, j])) < 1e-6 * np.median(np.abs(num))


def _session(scene):
    """A session-like object for :func:`arm_views` (meshes, arm, joints, camera)."""
    return SimpleNamespace(meshes=arm_meshes("panda"), arm=scene.chain, joints=scene.joints, K=scene.K, dist=None)


@pytest.mark.slow
def test_simulated_session_through_the_command_line(tmp_path, capsys, scene):
    """``handeye calibrate`` on a simulated session: X within 5 mm / 0.5 deg of the truth and within
    3 of its std, the masks' IoU on the fit and held out reported; the inputs untouched."""
    folder = write_silhouette_session(tmp_path / "s", scene)
    before = {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    code = main(["calibrate", str(folder), "--out", str(tmp_path / "out")])
    assert code in (0, 1)
    result = json.loads((tmp_path / "out" / "result.json").read_text())
    X = np.array(result["X"]["matrix"])
    truth = np.array(yaml.safe_load((folder / "ground_truth.yaml").read_text())["cam2base"])
    err_mm, err_deg = 1e3 * translation_error(X, truth), np.degrees(rotation_error(X, truth))
    assert err_mm < 5.0 and err_deg < 0.5
    std_mm = np.array(result["uncertainty"]["std_translation_mm"])
    assert np.all(np.abs(1e3 * (X[:3, 3] - truth[:3, 3])) < 3 * std_mm)
    figures = result["sensor"]["figures"]
    assert figures["iou_mean"] > 0.9 and figures["iou_heldout_mean"] > 0.9
    assert max(result["uncertainty"]["sources"]["arm_table"]["translation_mm"]) > 1.0  # the arm's table in X's std
    assert {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()} == before
    assert (tmp_path / "out" / "report.html").is_file()


@pytest.mark.slow
def test_easyhec_capture_is_imported_started_and_its_pairing_checked(easyhec):
    """EasyHeC's 10 views: the session reads (640x480 masks, 7 joint angles a view); the outline fit
    from the global start (no guess) and from EasyHeC's own hand-set initial guess (36 deg / 0.28 m
    away) land on the same X (within 30 mm / 2 deg); there the masks agree with the arm (IoU > 0.6),
    and the check names the masks that agree better with another view's joint angles than their own
    (this capture's images and joint angles are not paired one to one)."""
    s = load_silhouette_session(easyhec)
    masks = read_masks(s)
    assert masks.shape == (10, 480, 640) and s.joints.shape == (10, 7)
    views = arm_views(s, masks)
    X0, score = global_start(views, candidates=1)
    X, _ = outline_rounds(views, X0)
    theirs, _ = outline_rounds(views, EASYHEC_INIT)
    assert np.degrees(rotation_error(EASYHEC_INIT, X)) > 20  # their guess is far: the two starts are not one
    assert translation_error(X, theirs) < 0.03 and np.degrees(rotation_error(X, theirs)) < 2 and score > 0.55
    assert views.ious(X).mean() > 0.6
    notes, M = pairing_notes(views, X, s.names)
    assert M.shape == (10, 10) and len(notes) >= 4 and "paired in the same order" in notes[0]
    # the one-to-one re-pairing that fits best is said, with its IoU above the given pairing's (issue 76:
    # an independent renderer matched masks 4, 7 and 9 to views 8, 2 and 4)
    repair = notes[-1]
    assert repair.startswith("the one-to-one pairing that fits best")
    so, given = (float(v) for v in re.findall(r"mean IoU (\d\.\d+) so paired, (\d\.\d+) as given", repair)[0])
    assert so > given + 0.05
    assert "000004.png with 000008.png's" in repair or "000007.png with 000002.png's" in repair


@pytest.mark.slow
def test_a_few_outline_rounds_converge_on_the_simulator(scene):
    """From 2 deg / 40 mm off, the outline rounds bring X within 10 mm / 0.5 deg of the truth."""
    views = arm_views(_session(scene), scene.masks)
    X, rounds = outline_rounds(views, perturb(scene.X, np.radians([1.5, -1.0, 1.0]), [0.03, -0.02, 0.02]), rounds=6,
                               spacing=3.0)
    assert 1e3 * translation_error(X, scene.X) < 10 and np.degrees(rotation_error(X, scene.X)) < 0.5


@pytest.mark.parametrize("fault, message", [
    ("mask_size", "the mask is 320x240 and its image 640x480"),
    ("mask_missing", "mask(s) missing for 000003.png"),
    ("joint_count", "has 9 joint values; Panda has 7 joints"),
    ("arm_without_meshes", "is not one handeye has meshes for"),
    ("unknown_arm", "unknown arm 'foo'"),
    ("no_camera", "camera: K is needed"),
    ("eye_in_hand", "calibrates a camera fixed in the cell that sees the arm"),
])
def test_bad_input_is_refused_by_name_with_nothing_written(easyhec, tmp_path, capsys, fault, message):
    folder = tmp_path / "s"
    shutil.copytree(easyhec, folder)
    spec = yaml.safe_load((folder / "session.yaml").read_text())
    if fault == "mask_size":
        cv2.imwrite(str(folder / "masks" / "000002.png"), np.zeros((240, 320), np.uint8))
    elif fault == "mask_missing":
        (folder / "masks" / "000003.png").unlink()
    elif fault == "joint_count":
        lines = (folder / "joints.csv").read_text().splitlines()
        (folder / "joints.csv").write_text("\n".join([lines[0] + ",f1,f2"] + [r + ",0,0" for r in lines[1:]]) + "\n")
    elif fault == "unknown_arm":
        spec["joints"]["arm"] = "foo"
    elif fault == "arm_without_meshes":
        spec["joints"]["arm"] = "ur5"
        lines = (folder / "joints.csv").read_text().splitlines()
        (folder / "joints.csv").write_text("\n".join([lines[0][:lines[0].rindex(",")]] + [r[:r.rindex(",")] for r in lines[1:]])
                                           + "\n")
    elif fault == "eye_in_hand":
        spec["setup"] = "eye_in_hand"
    else:
        del spec["camera"]
    (folder / "session.yaml").write_text(yaml.safe_dump(spec))
    if fault == "mask_size":
        with pytest.raises(SessionError, match=message):
            read_masks(load_silhouette_session(folder))
    out = tmp_path / "out"
    assert main(["calibrate", str(folder), "--out", str(out)]) != 0
    assert message in capsys.readouterr().err
    assert not out.exists() or not any(out.iterdir())
