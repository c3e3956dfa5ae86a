"""Work done once and shared (issues 80 and 81): the check's pose fit and the pose candidate's, the
closed forms' motions per fold, a live calibration's unchanged images. The answers must be those of
the work done every time."""

from __future__ import annotations

import shutil
from importlib.resources import files

import numpy as np
import yaml

import handeye
from handeye.estimation import core, estimators, refinement
from handeye.estimation.estimators import choose, closed_fit
from handeye.estimation.validation import Views, cross_validate
from handeye.pipelines import calibration
from handeye.sensors.camera import detect
from handeye.sensors.camera.detect import detect_images, unchanged_files_remembered
from handeye.sensors.camera.targets import target_from_spec
from handeye.simulate import Noise, add_noise, random_scene

SAMPLE = files("handeye") / "data" / "sample_session"


def _poses(n: int = 12, seed: int = 0):
    scene = random_scene(n, "eye_in_hand", rng=seed)
    target2cam = add_noise(scene.target2cam, Noise(rot_deg=0.05, trans_mm=0.5), np.random.default_rng(seed))
    return scene.flange2base, target2cam


def test_the_checks_pose_fit_is_the_pose_candidates_and_the_answer_is_unchanged(monkeypatch):
    flange2base, target2cam = _poses()
    calls = []
    real = core.fit_poses
    monkeypatch.setattr(refinement, "fit_poses", lambda *a, **k: calls.append(len(a[0])) or real(*a, **k))
    shared = handeye.calibrate_poses(flange2base, target2cam, progress=False)
    assert calls == [12]  # the check's refit on all 12 poses, reused by the pose candidate
    # without sharing (the function under its decorator): each asks for its own fit, and gets the same numbers
    calls.clear()
    alone = calibration.calibrate_poses.__wrapped__(flange2base, target2cam, progress=False)
    assert calls == [12, 12]
    assert shared.estimator == alone.estimator
    assert np.array_equal(shared.X, alone.X) and np.array_equal(shared.std, alone.std)
    assert shared.verdict == alone.verdict


def test_closed_forms_sharing_a_folds_motions_cross_validate_as_alone():
    flange2base, target2cam = _poses(9, seed=3)
    views = Views(flange2base, target2cam, "eye_in_hand")
    shared: dict = {}
    for name in ("daniilidis", "tsai_lenz", "park_martin", "shah"):
        together = cross_validate(closed_fit(name, shared=shared), views, 4, name)
        alone = cross_validate(closed_fit(name), views, 4, name)
        assert np.array_equal(together.mm, alone.mm), name
    assert len(shared) == 4  # one motion set per fold's training poses, made once for the three AX = XB solvers
    choice = choose(views, estimators.pose_candidates("daniilidis", views), 4)
    assert np.isfinite(choice.best.score)


def test_degenerate_fold_motions_fail_every_closed_form_that_uses_them():
    flange2base, target2cam = _poses(6, seed=1)
    # every pose turned about one axis: no closed form can determine X from such motions
    axis_only = flange2base.copy()
    for k in range(len(axis_only)):
        c, s = np.cos(0.3 * k), np.sin(0.3 * k)
        axis_only[k, :3, :3] = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    views = Views(axis_only, target2cam, "eye_in_hand")
    shared: dict = {}
    for name in ("daniilidis", "tsai_lenz"):
        assert not np.isfinite(cross_validate(closed_fit(name, shared=shared), views, 3, name).score)
    assert shared and all(isinstance(v, Exception) for v in shared.values())


def test_a_live_calibration_does_not_read_unchanged_images_again_and_a_changed_one_is(tmp_path, monkeypatch):
    folder = tmp_path / "s"
    shutil.copytree(str(SAMPLE), folder)
    target = target_from_spec(yaml.safe_load((folder / "session.yaml").read_text())["target"])
    paths = sorted((folder / "images").iterdir())[:3]
    plain = detect_images(paths, target, jobs=1, progress=False)
    reads = []
    stored = detect._detect_stored
    monkeypatch.setattr(detect, "_detect_stored", lambda p, *a: reads.append(p) or stored(p, *a))
    with unchanged_files_remembered():
        first = detect_images(paths, target, jobs=2, progress=False)
        again = detect_images(paths, target, jobs=2, progress=False)
        assert len(reads) == 3  # the first pass read them (from the cache on disk), the second did not
        # a file rewritten (another image under the same name) is read again
        paths[0].write_bytes(paths[1].read_bytes())
        changed = detect_images(paths[:1], target, jobs=1, progress=False)[0]
    assert reads[3:] == [str(paths[0])]
    assert np.array_equal(changed.detection.image_points, plain[1].detection.image_points)
    detect_images(paths[1:2], target, jobs=1, progress=False)  # outside it: read as before
    assert len(reads) == 5
    for a, b, c in zip(plain, first, again):
        assert np.array_equal(a.detection.image_points, c.detection.image_points)
        assert np.array_equal(b.detection.object_points, c.detection.object_points)
