"""Captures as users make them, where a sensor's fit went wrong while sounding sure (issue 76): each
failure as a simulated capture, the right X or a refusal that names the cause."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from handeye.errors import InputMismatchError, PoseFormatError
from handeye.estimation import core
from handeye.estimation.readings import check_readings
from handeye.frames.metrics import rotation_error, translation_error
from handeye.frames.poses import RobotPoseInput, format_poses
from handeye.pipelines.depth.simulate_board import sphere_scene
from handeye.pipelines.folders import calibrate_folder
from handeye.pipelines.laser.pipeline import calibrate_laser_session, laser_model, read_profiles
from handeye.pipelines.laser.session import load_laser_session
from handeye.pipelines.laser.simulate import FANUC_PROFILER_X, pendant_laser_scene, write_laser_session
from handeye.pipelines.rig.simulate import profiler_pair_scene, write_profiler_pair_session
from handeye.robot.models import ControllerPoses, PoseErrors
from handeye.sensors.depth.model import SphereCentres


def _within(cal, X, k: float = 3.0) -> bool:
    """X within ``k`` of its std on every axis (rotation vector and translation, X's parent frame)."""
    from scipy.spatial.transform import Rotation

    dR = Rotation.from_matrix(cal.X[:3, :3] @ X[:3, :3].T).as_rotvec()
    err = np.r_[np.degrees(np.abs(dR)), 1e3 * np.abs(cal.X[:3, 3] - X[:3, 3])]
    return bool(np.all(err <= k * cal.std))


@pytest.mark.slow
def test_a_laser_start_is_the_polished_fit_not_the_closed_forms_basin(tmp_path):
    """A capture with one turn about W and R and two about P (10 profiles, the profiler 0.87 m from the
    flange): the closed form's own translation was 191 mm off, the fit from it landed 307 mm off at
    5.4 mm RMS; the start is now the candidate's polished fit."""
    sc = pendant_laser_scene("eye_in_hand", rng=5, translations=6, turns=(1, 2, 1), X=FANUC_PROFILER_X)
    s = load_laser_session(write_laser_session(tmp_path / "s", sc))
    kept, profiles, _, _ = read_profiles(s)
    model = laser_model(s, [s.names[k] for k in kept], profiles)
    X0, _ = core._start(model, ControllerPoses(s.flange2base[kept]))
    assert 1e3 * translation_error(X0, sc.X) < 10.0
    # seed 1: the closed forms' rotations half a turn about the laser plane's normal from the truth
    # (pure translations fit both alike); its fit stayed 176 deg off at 1.6 mm RMS, called weak. The
    # starts now try each rotation so turned too, and the turns' profiles pick the right one
    flipped = pendant_laser_scene("eye_in_hand", rng=1, translations=6, turns=(1, 2, 1), X=FANUC_PROFILER_X)
    s1 = load_laser_session(write_laser_session(tmp_path / "s1", flipped))
    kept1, profiles1, _, _ = read_profiles(s1)
    X1, _ = core._start(laser_model(s1, [s1.names[k] for k in kept1], profiles1), ControllerPoses(s1.flange2base[kept1]))
    assert np.degrees(rotation_error(X1, flipped.X)) < 5.0 and 1e3 * translation_error(X1, flipped.X) < 10.0
    cal = calibrate_laser_session(s)
    assert cal.verdict != "inconsistent" and cal.sensor.fit_rms_mm < 0.3
    assert _within(cal, sc.X)


class _BadStart:
    """A sensor model whose start is its own turned half a turn about the sensor's axis (as a closed
    form in another basin of the fit)."""

    def __init__(self, model):
        self._model = model

    def __getattr__(self, name):
        return getattr(self._model, name)

    def start(self, flange2base, X, Z, rows=None):
        X0, p0 = self._model.start(flange2base, X, Z, rows)
        return X0 @ np.diag([-1.0, -1.0, 1.0, 1.0]), p0


@pytest.mark.slow  # over 3.5 s: the fast tier keeps a margin under its 2 minutes
def test_a_fit_far_beyond_what_the_sensor_and_robot_allow_is_inconsistent_not_weak(tmp_path):
    """Started half a turn off, the laser's fit lands in another basin, 0.3 m from X, its residual
    far beyond what the profiler's noise and the robot's accuracy move these profiles by: the verdict
    says the data and the fit disagree, never 'weak, capture again'."""
    sc = pendant_laser_scene("eye_in_hand", rng=5, translations=6, turns=(1, 2, 1), X=FANUC_PROFILER_X)
    s = load_laser_session(write_laser_session(tmp_path / "s", sc))
    kept, profiles, _, _ = read_profiles(s)
    cal = core.estimate(_BadStart(laser_model(s, [s.names[k] for k in kept], profiles)),
                        ControllerPoses(s.flange2base[kept], (0.03, 0.3)))
    assert 1e3 * translation_error(cal.X, sc.X) > 100 and cal.sensor.fit_rms_mm > 2.0
    assert cal.verdict == "inconsistent" and "far beyond" in cal.diagnostics.advice[0]


@pytest.mark.slow
def test_the_promised_held_out_error_is_what_refits_give(tmp_path):
    """Laser captures with few turns: every fold fitted from its own start predicts its views about as
    the held-out error the result promises (within 2x)."""
    ratios = []
    for seed in range(3):
        sc = pendant_laser_scene("eye_in_hand", rng=seed, translations=6, turns=(1, 2, 1), X=FANUC_PROFILER_X)
        s = load_laser_session(write_laser_session(tmp_path / f"s{seed}", sc))
        kept, profiles, _, _ = read_profiles(s)
        model = laser_model(s, [s.names[k] for k in kept], profiles)
        robot = ControllerPoses(s.flange2base[kept], (0.03, 0.3))
        cal = core.estimate(model, robot)
        promised = cal.prediction_error["mm"]
        # every fold refitted from its own start, by hand
        X0, p0 = core._start(model, robot)
        problem = core.Problem(model, robot, X0, p0, held=np.array([3]))  # the given radius held
        full = core.fit(problem)
        views = np.arange(len(kept))
        errors = []
        for test in core.fold_indices(len(views), core.default_folds(len(views))):
            train = np.setdiff1d(views, test)
            X0, p0 = core._start(model, robot, train)
            errors.append(core.view_rms_mm(problem, core._refitted(problem, full, train, X0, p0), test))
        refits = float(np.sqrt(np.nanmean(np.concatenate(errors) ** 2)))
        ratios.append(promised / refits)
        if seed == 0:  # X right (fit 0.15 mm RMS) while folds from their own start land 4.8 mm off: weak, said why
            assert _within(cal, sc.X) and cal.verdict == "weak", cal.verdict
            assert any("so this X rests on its start" in a for a in cal.diagnostics.advice), cal.diagnostics.advice
    assert all(0.5 <= r <= 2.0 for r in ratios), ratios


def test_quaternions_in_the_other_order_are_named_before_any_fit():
    """A ball's centres with the pose table's quaternion columns in the other order: named, with what
    to declare, before the fit (no X)."""
    scene = sphere_scene(12, "eye_to_hand", rng=1)
    rows = format_poses(scene.flange2base, "quat_xyzw", "mm")
    declared = RobotPoseInput(rows, "quat_wxyz", "mm")
    from handeye.frames.poses import parse_poses

    model = SphereCentres("eye_to_hand", [f"v{i}" for i in range(12)], scene.target2cam[:, :3, 3], fit_depth=False)
    robot = ControllerPoses(parse_poses(rows, "quat_wxyz", "mm"), (0.03, 0.3))
    with pytest.raises(PoseFormatError, match="quat_xyzw"):
        check_readings(model, robot, declared)
    check_readings(model, ControllerPoses(scene.flange2base, (0.03, 0.3)), RobotPoseInput(rows, "quat_xyzw", "mm"))


def _rewrite_poses(folder, fmt=None, setup=None):
    """The session's pose table rewritten in ``fmt`` (the declaration kept), or its setup declared ``setup``."""
    spec = yaml.safe_load((folder / "session.yaml").read_text())
    if setup is not None:
        spec["setup"] = setup
    if fmt is not None:
        from handeye.frames.poses import parse_poses
        from handeye.io.session import read_pose_table, write_pose_table

        poses = spec["poses"]
        values, names = read_pose_table(folder / poses["file"], poses["format"], id_columns=("profile", "cloud", "view"))
        F = parse_poses(values, poses["format"], poses["length_unit"], poses["angle_unit"])
        first = (folder / poses["file"]).read_text().split(",")[0]
        write_pose_table(folder / poses["file"], list(names), F, fmt, poses["length_unit"], poses["angle_unit"], id_column=first)
    (folder / "session.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    return folder


@pytest.mark.slow
@pytest.mark.parametrize("wrong", ["euler:XYZ", "setup"])
def test_a_laser_sessions_wrong_reading_is_named(tmp_path, wrong):
    """FANUC W, P, R (extrinsic xyz) declared as intrinsic XYZ, or eye-to-hand declared for an
    eye-in-hand capture: named, with the fix, and no result."""
    sc = pendant_laser_scene("eye_in_hand", rng=2, translations=6, turns=(3, 3, 3))
    folder = write_laser_session(tmp_path / "s", sc)
    spec = yaml.safe_load((folder / "session.yaml").read_text())
    if wrong == "setup":
        _rewrite_poses(folder, setup="eye_to_hand")
        with pytest.raises(InputMismatchError, match="setup: eye_in_hand"):
            calibrate_folder(folder)
    else:
        _rewrite_poses(folder, fmt="euler:xyz")
        spec = yaml.safe_load((folder / "session.yaml").read_text())
        spec["poses"]["format"] = "euler:XYZ"
        (folder / "session.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
        with pytest.raises(PoseFormatError, match="euler:xyz"):
            calibrate_folder(folder)


@pytest.mark.slow
def test_two_profilers_with_poses_of_their_own_fit_no_pose_error_of_their_own(tmp_path):
    """Two profilers that scanned one ball from poses of their own: no pose's error is fitted (it would
    take each profile whole); each profiler fits the controller's poses as well as the best X that puts
    one ball under both, and the relative pose's std covers its error."""
    from handeye.pipelines.rig.pipeline import _shared

    sc = profiler_pair_scene(12, "eye_in_hand", rng=3, robot_error=(0.02, 0.1))
    folder = write_profiler_pair_session(tmp_path / "pair", sc)
    cal = calibrate_folder(folder)
    f = cal.sensor.figures
    rel = np.asarray(f["relative"]["laser_b_to_laser_a"]["matrix"])
    std = np.asarray(f["relative"]["laser_b_to_laser_a"]["std_deg_mm"])
    err = np.r_[np.degrees(rotation_error(rel, sc.relative())), 1e3 * translation_error(rel, sc.relative())]
    assert err[0] <= 3 * np.linalg.norm(std[:3]) and err[1] <= 3 * np.linalg.norm(std[3:])
    assert not any("each pose's own error fitted" in n for n in cal.notes)
    # the best one-ball X of both, by a plain least squares of every point against one sphere
    from scipy.optimize import least_squares
    from scipy.spatial.transform import Rotation

    poses = {}
    for name in ("laser_a", "laser_b"):
        pts = []
        for k, view in enumerate(sc.names):
            path = folder / name / f"{view}.csv"
            if path.exists():
                p = np.genfromtxt(path, delimiter=",", skip_header=1) * 1e-3  # a point without return: empty z
                p = p[np.isfinite(p).all(axis=1)]
                pts.append((k, np.c_[p[:, 0], np.zeros(len(p)), p[:, -1]]))
        poses[name] = pts
    F = sc.flange2base
    X_a, X_b = np.asarray(f["X_per_sensor"]["laser_a"]["X"]), np.asarray(f["X_per_sensor"]["laser_b"]["X"])

    def fun(u):
        out = []
        for name, X0, du in (("laser_a", X_a, u[0:6]), ("laser_b", X_b, u[6:12])):
            R = Rotation.from_rotvec(du[:3]).as_matrix() @ X0[:3, :3]
            t = X0[:3, 3] + du[3:]
            for k, p in poses[name]:
                q = (p @ R.T + t) @ F[k, :3, :3].T + F[k, :3, 3]
                out.append(np.linalg.norm(q - u[12:15], axis=1) - sc.radius)
        return np.concatenate(out)
    best = least_squares(fun, np.r_[np.zeros(12), np.asarray(cal.Z)[:3, 3]], method="lm")
    rms_best = {}
    start = 0
    for name, n_pts in (("laser_a", sum(len(p) for _, p in poses["laser_a"])), ("laser_b", sum(len(p) for _, p in poses["laser_b"]))):
        rms_best[name] = 1e3 * np.sqrt(np.mean(best.fun[start:start + n_pts] ** 2))
        start += n_pts
    ours = dict(zip(("laser_a", "laser_b"), f["rms_mm_per_sensor"]))
    for name in ours:
        assert ours[name] <= 1.05 * rms_best[name], (ours, rms_best)
    # a pose error is fitted where two sensors saw the pose, and only there
    one, two = (SphereCentres("eye_in_hand", sc.names, np.ones((len(F), 3))) for _ in range(2))
    one.owner, two.owner = np.arange(0, 12), np.arange(10, 24)
    shared = _shared(ControllerPoses(F, (0.03, 0.3)), [one, two])
    assert isinstance(shared, PoseErrors) and list(shared.views) == [10, 11] and shared.n_params == 12
    assert type(_shared(ControllerPoses(F, (0.03, 0.3)), [one])) is ControllerPoses


@pytest.mark.slow
def test_a_flanges_depth_bias_is_held_where_translations_cannot_determine_it(tmp_path):
    """A flange (its placement given) at 6 pure translations, 5 on one line: the depth bias is not
    determined (its std would be several times a real camera's tolerance), so it is held at 0, named,
    and X's std takes its tolerance; result.json says what X holds with."""
    from handeye.pipelines.depth.simulate_mesh import mesh_scene, write_mesh_session
    from handeye.report import write_calibration

    sc = mesh_scene(6, "eye_to_hand", rng=0, translations="line", robot_error=(0.01, 0.1), image_size=(320, 240))
    cal = calibrate_folder(write_mesh_session(tmp_path / "s", sc, known_pose=True), progress=False)
    status = {u["name"]: u for u in cal.sensor.unknowns}
    assert status["depth_bias"]["status"] == "held" and status["depth_bias"]["std"] is None
    assert "does not determine it" in status["depth_bias"]["why"]
    assert any(n.startswith("depth_bias held at 0 mm") for n in cal.notes)
    assert "held_unknowns" in cal.std_sources and _within(cal, sc.X)
    write_calibration(cal, tmp_path / "out")
    result = json.loads((tmp_path / "out" / "result.json").read_text())
    assert [u["name"] for u in result["sensor"]["unknowns"]] == ["depth_scale", "depth_bias"]
    assert "X holds with these values" in result["sensor"]["x_holds_with"]


@pytest.mark.slow
def test_pure_translations_without_a_placement_name_the_free_translation(tmp_path):
    """The same flange without its placement: the views agree (they were refused as if the poses were
    wrong); X's rotation is fitted, its translation named free with what fixes it, its std infinite."""
    from handeye.pipelines.depth.simulate_mesh import mesh_scene, write_mesh_session

    sc = mesh_scene(6, "eye_to_hand", rng=0, translations="line", robot_error=(0.01, 0.1), image_size=(320, 240))
    cal = calibrate_folder(write_mesh_session(tmp_path / "s", sc), progress=False)
    assert cal.verdict == "partial", cal.diagnostics.advice
    free = [u.parameter for u in cal.observability.unobservable]
    assert len(free) == 3 and all(f.startswith("translation of cam2base") for f in free)
    assert np.all(np.isinf(cal.std[3:])) and np.degrees(rotation_error(cal.X, sc.X)) < 3 * np.linalg.norm(cal.std[:3])
    assert "placement" in cal.observability.unobservable[0].fix


@pytest.mark.slow  # over 3.5 s: the fast tier keeps a margin under its 2 minutes
def test_a_sensors_unknowns_are_held_or_freed_by_name(tmp_path, capsys):
    """session.yaml's unknowns: and --hold/--free name a sensor's unknowns beside X; a name that is not
    one of them is refused, naming those that are; a camera's images take none."""
    from handeye.cli import main
    from handeye.pipelines.depth.simulate_board import write_depth_session

    folder = write_depth_session(tmp_path / "s", sphere_scene(10, "eye_to_hand", rng=3))
    spec = yaml.safe_load((folder / "session.yaml").read_text())
    spec["unknowns"] = {"depth_scale": "hold"}
    (folder / "session.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    cal = calibrate_folder(folder)
    status = {u["name"]: (u["status"], u["why"]) for u in cal.sensor.unknowns}
    assert status["depth_scale"] == ("held", "held as asked") and status["depth_bias"][0] == "fitted"
    assert main(["calibrate", str(folder), "--free", "depth_scale", "--hold", "depth_bias"]) in (0, 1)
    assert main(["calibrate", str(folder), "--hold", "radius"]) == 2
    assert "'radius' is not an unknown of this depth camera" in capsys.readouterr().err
    spec["unknowns"] = {"depth_scale": "sometimes"}
    (folder / "session.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    assert main(["calibrate", str(folder)]) == 2
    assert "say hold, free or auto" in capsys.readouterr().err
    assert main(["calibrate", "--sample", "--hold", "depth_scale"]) == 2
    assert "a camera's images and poses have no unknowns beside X" in capsys.readouterr().err
