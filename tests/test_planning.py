"""``handeye plan`` (issue 8): planned poses see the target, promise an accuracy they keep, and beat
easy_handeye's fixed 17-pose pattern."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

import realdata
from handeye.cli import main
from handeye.errors import HandEyeError
from handeye.estimation.diagnostics import diagnose
from handeye.frames.poses import parse_poses
from handeye.geometry.se3 import invert, make_transform
from handeye.io.session import read_pose_table
from handeye.pipelines.rig.plan import RigPlanCamera, plan_rig
from handeye.planning.poses import (
    easy_handeye_poses,
    fronto_parallel_start,
    order_path,
    plan_poses,
    predicted_cov,
    reprojection_information,
    simulate_errors,
    visible_mask,
)
from handeye.sensors.camera.pnp import project_points
from handeye.sensors.camera.targets import target_from_spec
from handeye.simulate import DEFAULT_TARGETS, default_camera
from handeye.solvers.refine import predicted_target2cam

SIZE = (1280, 1024)
K, DIST = default_camera(SIZE)
OBJ = target_from_spec({"type": "chessboard", "cols": 9, "rows": 6, "square": 0.025}).object_points()
STANDOFF = 0.5


def _mounting(setup):
    """A rough camera mounting and target placement, as a user would give them."""
    if setup == "eye_in_hand":
        X = make_transform(Rotation.from_euler("z", 90, degrees=True).as_matrix(), [0.03, -0.05, 0.08])
        Z = make_transform(Rotation.from_rotvec([np.pi, 0, 0]).as_matrix(), [0.6, 0.1, 0.0])
    else:
        X = make_transform(Rotation.from_euler("xyz", [170, 10, 5], degrees=True).as_matrix(), [0.8, 0.0, 0.9])
        Z = make_transform(Rotation.from_rotvec([np.pi, 0, 0]).as_matrix(), [0.0, 0.02, 0.05])
    return X, Z


def test_information_matches_finite_differences_of_the_refinement_residuals():
    """The analytic J^T J is that of refine_reprojection's 12 unknowns (pinhole camera)."""
    for setup in ("eye_in_hand", "eye_to_hand"):
        X, Z = _mounting(setup)
        plan = plan_poses(setup, X, Z, OBJ, K, SIZE, n_poses=4, standoff=STANDOFF)
        F = plan.flange2base

        def residuals(x):
            Xp = make_transform(Rotation.from_rotvec(x[:3]).as_matrix() @ X[:3, :3], X[:3, 3] + x[3:6])
            Zp = make_transform(Rotation.from_rotvec(x[6:9]).as_matrix() @ Z[:3, :3], Z[:3, 3] + x[9:12])
            T = predicted_target2cam(Xp, Zp, F, setup)
            return np.concatenate([project_points(Ti, OBJ, K, np.zeros(5)).ravel() for Ti in T])

        h = 1e-7
        J = np.stack([(residuals(h * e) - residuals(-h * e)) / (2 * h) for e in np.eye(12)], axis=1)
        info = reprojection_information(F, X, Z, setup, OBJ, K).sum(axis=0)
        assert np.abs(info - J.T @ J).max() <= 1e-5 * np.abs(info).max()


@pytest.mark.parametrize("setup", ["eye_in_hand", "eye_to_hand"])
def test_every_planned_pose_sees_every_target_point(setup):
    X, Z = _mounting(setup)
    plan = plan_poses(setup, X, Z, OBJ, K, SIZE, DIST, n_poses=12, standoff=STANDOFF, margin_px=20)
    assert plan.flange2base.shape == (12, 4, 4)
    T = predicted_target2cam(X, Z, plan.flange2base, setup)
    assert np.allclose(T, plan.target2cam, atol=1e-12)
    for Ti in T:
        px = project_points(Ti, OBJ, K, DIST)
        assert np.all(px >= 20) and np.all(px[:, 0] <= SIZE[0] - 21) and np.all(px[:, 1] <= SIZE[1] - 21)
        assert np.all((OBJ @ Ti[:3, :3].T + Ti[:3, 3])[:, 2] > 0)  # in front of the camera
    # distinct poses, views within the allowed tilt, rotations large enough to observe X
    tilt = np.degrees(np.arccos(np.clip(T[:, 2, 2], -1, 1)))
    assert np.all(tilt <= 45 + 1e-9)
    rel = Rotation.from_matrix(T[1:, :3, :3]) * Rotation.from_matrix(T[0, :3, :3]).inv()
    assert np.median(np.degrees(rel.magnitude())) > 20
    assert len({tuple(np.round(f[:3, 3], 6)) for f in plan.flange2base}) == 12
    diag = diagnose(plan.flange2base, plan.target2cam, setup)  # our own data check agrees
    assert diag.verdict == "good" and min(diag.axis_shares) > 0.1


def test_reach_box_is_respected_and_explained():
    X, Z = _mounting("eye_in_hand")
    box = np.array([0.4, -0.2, 0.2, 1.0, 0.6, 0.8])
    plan = plan_poses("eye_in_hand", X, Z, OBJ, K, SIZE, DIST, n_poses=10, standoff=STANDOFF, reach_box=box)
    t = plan.flange2base[:, :3, 3]
    assert np.all(t >= box[:3]) and np.all(t <= box[3:])
    with pytest.raises(HandEyeError, match="reach box"):
        plan_poses("eye_in_hand", X, Z, OBJ, K, SIZE, DIST, n_poses=10, standoff=STANDOFF,
                   reach_box=[5, 5, 5, 6, 6, 6])
    with pytest.raises(HandEyeError, match="increase the standoff"):
        plan_poses("eye_in_hand", X, Z, OBJ, K, SIZE, DIST, standoff=0.08)


@pytest.mark.slow
def test_plan_beats_easy_handeye_by_30_percent():
    """Issue 8's bar: 12 planned poses, 0.3 px, 100 runs each through PnP + Daniilidis + reprojection
    refinement: the RMS translation error of X is >= 30% lower than with easy_handeye's 17 poses
    around a straight-on view at the same standoff. The comparison is also made against the
    easy_handeye pattern as if every pose saw the whole target (predicted covariance), which is
    kinder to it than reality: at this standoff 6 of its 17 poses lose part of the target."""
    setup = "eye_in_hand"
    X, Z = _mounting(setup)
    plan = plan_poses(setup, X, Z, OBJ, K, SIZE, DIST, n_poses=12, standoff=STANDOFF, noise_px=0.3)
    eh = easy_handeye_poses(fronto_parallel_start(X, Z, OBJ, STANDOFF, setup))
    assert eh.shape == (17, 4, 4)
    with realdata.worker_pool() as pool:  # the two simulations side by side (each seeded: the same numbers)
        runs = [pool.submit(simulate_errors, F, X, Z, setup, OBJ, K, DIST, SIZE, 0.3, 100, rng=seed)
                for F, seed in ((plan.flange2base, 1), (eh, 2))]
        (err_plan, n_plan), (err_eh, n_eh) = (r.result() for r in runs)
    rms_plan, rms_eh = np.sqrt(np.mean(err_plan**2, axis=0)), np.sqrt(np.mean(err_eh**2, axis=0))
    print(f"\nplan: {n_plan} poses, RMS {rms_plan[0]:.4f} deg / {rms_plan[1]:.4f} mm; "
          f"easy_handeye: {n_eh} of 17 usable, RMS {rms_eh[0]:.4f} deg / {rms_eh[1]:.4f} mm")
    assert n_plan == 12
    assert rms_plan[1] <= 0.7 * rms_eh[1]
    assert rms_plan[0] <= 0.7 * rms_eh[0]
    # kinder comparison: all 17 easy_handeye poses counted
    std_eh_all = np.sqrt(np.diag(predicted_cov(reprojection_information(eh, X, Z, setup, OBJ, K).sum(axis=0), 0.3)))
    assert np.linalg.norm(plan.std_X[3:]) <= 0.7 * 1e3 * np.linalg.norm(std_eh_all[3:])
    # the printed prediction is honest: within 25% of the simulated RMS (pinhole information vs a
    # distorting camera and a nonlinear estimator)
    pred_t, pred_r = np.linalg.norm(plan.std_X[3:]), np.linalg.norm(plan.std_X[:3])
    assert 0.75 < rms_plan[1] / pred_t < 1.25 and 0.75 < rms_plan[0] / pred_r < 1.25


def test_easy_handeye_pattern():
    T0 = make_transform(Rotation.from_euler("xyz", [180, 0, 30], degrees=True).as_matrix(), [0.5, 0.1, 0.4])
    P = easy_handeye_poses(T0)
    rel = invert(T0) @ P  # rotations about the flange's own axes
    angles = np.degrees(Rotation.from_matrix(rel[:12, :3, :3]).magnitude())
    assert np.allclose(angles, [25] * 6 + [12.5] * 6)
    axes = Rotation.from_matrix(rel[:12, :3, :3]).as_rotvec()
    assert np.allclose(np.abs(axes[:, :3]).argmax(axis=1), [0, 0, 1, 1, 2, 2] * 2)
    moves = P[12:, :3, 3] - T0[:3, 3]  # moves along the base axes, orientation kept
    assert np.allclose(moves, [[0.05, 0, 0], [-0.05, 0, 0], [0, 0.1, 0], [0, -0.1, 0], [0, 0, 0.1 / 3]])
    assert np.allclose(P[12:, :3, :3], T0[:3, :3])


def test_order_path_is_a_shorter_permutation():
    rng = np.random.default_rng(0)
    T = make_transform(Rotation.random(15, random_state=1).as_matrix(), rng.uniform(-0.5, 0.5, (15, 3)))

    def length(order):
        P = T[order]
        d = np.linalg.norm(np.diff(P[:, :3, 3], axis=0), axis=1)
        a = (Rotation.from_matrix(P[1:, :3, :3]) * Rotation.from_matrix(P[:-1, :3, :3]).inv()).magnitude()
        return float(np.sum(d + 0.25 * a))

    order = order_path(T)
    assert sorted(order.tolist()) == list(range(15)) and order[0] == 0
    assert length(order) < 0.8 * length(np.arange(15))


def test_visible_mask_rejects_points_behind_or_outside():
    T = invert(make_transform(np.eye(3), [0.1, 0.075, -0.5]))  # camera 0.5 m in front of the board centre
    assert visible_mask(T[None], OBJ, K, DIST, SIZE)[0]
    behind = invert(make_transform(Rotation.from_rotvec([np.pi, 0, 0]).as_matrix(), [0.1, 0.075, -0.5]))
    aside = invert(make_transform(np.eye(3), [0.6, 0.075, -0.5]))
    assert not visible_mask(np.array([behind, aside]), OBJ, K, DIST, SIZE).any()


@pytest.fixture
def camera_yaml(tmp_path):
    p = tmp_path / "camera.yaml"
    p.write_text(yaml.safe_dump({"K": K.tolist(), "dist": DIST.tolist(), "image_size": list(SIZE)}))
    return p


def test_cli_writes_poses_in_the_robot_format(tmp_path, camera_yaml, capsys):
    out = tmp_path / "poses.csv"
    code = main(["plan", "--intrinsics", str(camera_yaml), "--target-in-base", "0.6,0.1,0",
                 "--cam-in-flange", "0.03,-0.05,0.08,0,0,90", "--standoff", "0.5", "--poses", "8",
                 "--out", str(out), "--format", "euler:ZYX", "--length-unit", "mm"])
    assert code == 0
    text = capsys.readouterr().out
    assert "predicted std of X" in text and "easy_handeye" in text
    rows, names = read_pose_table(out, "euler:ZYX", ("image",))
    assert names == [f"{k:03d}.png" for k in range(8)]
    F = parse_poses(rows, "euler:ZYX", "mm", "deg")
    X, Z = _mounting("eye_in_hand")
    plan = plan_poses("eye_in_hand", X, Z, target_from_spec(DEFAULT_TARGETS["chessboard"]).object_points(),
                      K, SIZE, DIST, n_poses=8, standoff=0.5)
    assert F.shape == (8, 4, 4)
    assert np.abs(F - plan.flange2base).max() < 1e-9  # the same plan, written and read back exactly
    # the std calibrate would report: the pixels' part plus the robot's accuracy, as calibrate adds it
    from handeye.estimation.uncertainty import robot_accuracy_cov
    from handeye.frames.metrics import std_deg_mm
    assert np.allclose(plan.std_reported, std_deg_mm(plan.cov_X + robot_accuracy_cov(X, (0.03, 0.3))))
    assert np.all(plan.std_reported[3:] >= 0.3) and np.all(plan.std_X[3:] < 0.3)
    line = next(t for t in text.splitlines() if t.startswith("predicted std of X as calibrate would report it"))
    assert f"{plan.std_reported[3]:.3f}" in line
    assert "flange rotation vector (deg)" in text and "0.8, 1 and 1.25 x --standoff 500 mm" in text
    # never over an existing file (it may be a session's recorded poses)
    assert main(["plan", "--intrinsics", str(camera_yaml), "--target-in-base", "0.6,0.1,0", "--standoff", "0.5",
                 "--out", str(out)]) == 2
    assert "exists" in capsys.readouterr().err


@pytest.mark.parametrize("argv, expect", [
    (["--standoff", "0.5"], "--target-in-base is needed"),
    (["--target-in-base", "1,2", "--standoff", "0.5"], "give 3 or 6"),
    (["--target-in-base", "0.6,0,0", "--standoff", "0.5", "--camera-in-base", "1,0,1,0,0,0"], "are for eye_to_hand"),
    (["--setup", "eye_to_hand", "--standoff", "0.5"], "--camera-in-base is needed"),
    (["--target-in-base", "0.6,0,0", "--standoff", "0.5", "--poses", "2"], "argument --poses: 2 is too small: give a whole number >= 3"),
    (["--target-in-base", "0.6,0,0", "--standoff", "0.5", "--format", "euler:XYZz"], "euler"),
    (["--target-in-base", "0.6,0,0", "--standoff", "0.5", "--reach-box", "1,1,1,0,0,0"], "reach box"),
])
def test_cli_bad_input(tmp_path, camera_yaml, capsys, argv, expect):
    code = main(["plan", "--intrinsics", str(camera_yaml), "--out", str(tmp_path / "p.csv")] + argv)
    err = capsys.readouterr().err
    assert code == 2 and expect in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "p.csv").exists()


def test_cli_bad_intrinsics(tmp_path, capsys):
    bad = tmp_path / "cam.yaml"
    bad.write_text("K: [[1, 0]]\nimage_size: [640, 480]\n")
    broken = tmp_path / "broken.yaml"
    broken.write_text("K: [[1, 0, 0]\n")
    for path, expect in ((tmp_path / "none.yaml", "file not found"), (bad, "camera K must be"),
                         (broken, "not valid YAML")):
        code = main(["plan", "--intrinsics", str(path), "--target-in-base", "0.6,0,0", "--standoff", "0.5",
                     "--out", str(tmp_path / "p.csv")])
        err = capsys.readouterr().err
        assert code == 2 and expect in err and len(err.strip().splitlines()) == 1


def test_plan_takes_a_session_yaml_as_intrinsics(tmp_path, capsys):
    """A session.yaml has K but no image_size: plan reads the size from the session's images."""
    from pathlib import Path

    import handeye

    sample = Path(handeye.__file__).parent / "data" / "sample_session" / "session.yaml"
    out = tmp_path / "poses.csv"
    assert main(["plan", "--intrinsics", str(sample), "--target-spec", str(sample), "--target-in-base", "0.6,0.1,0",
                 "--standoff", "0.5", "--poses", "6", "--out", str(out)]) == 0
    assert out.is_file() and len(out.read_text().splitlines()) == 7
    lone = tmp_path / "lone.yaml"  # K without images beside it: the error says what is missing
    lone.write_text(sample.read_text())
    assert main(["plan", "--intrinsics", str(lone), "--target-in-base", "0.6,0.1,0", "--standoff", "0.5",
                 "--out", str(tmp_path / "p.csv")]) == 2
    assert "image_size" in capsys.readouterr().err


@pytest.mark.slow
def test_a_rig_plans_through_its_registrations_plan_hook(tmp_path, camera_yaml, capsys):
    """Issue 78: a rig's plan was reached by the camera's --rig-camera only, not through its kind's plan
    hook as every other kind's. Now ``plan --sensor rig`` plans it (the rig's registration names
    ``plan``), ``plan --rig-camera`` alone still does and writes the same poses, and another kind
    refuses --rig-camera, naming the rig."""
    from handeye.pipelines.kinds import kind_named
    rig = kind_named("rig")
    assert rig.plan is not None and rig.hook("plan").__module__ == "handeye.pipelines.rig.plan"
    common = ["--intrinsics", str(camera_yaml), "--cam-in-flange", "0,0,0.05", "--target-in-base", "0.6,0,0",
              "--standoff", "0.7", "--poses", "6", "--rig-camera", f"right,{camera_yaml},0.12,0,0,0,-6,0"]
    assert main(["plan", "--sensor", "rig", *common, "--out", str(tmp_path / "a.csv")]) == 0
    assert "every camera (cam0, right)" in capsys.readouterr().out
    assert main(["plan", *common, "--out", str(tmp_path / "b.csv")]) == 0
    assert (tmp_path / "a.csv").read_text() == (tmp_path / "b.csv").read_text()
    assert main(["plan", "--sensor", "laser_line", "--target-in-base", "0.6,0,0", "--rig-camera", f"r,{camera_yaml},0.1,0,0",
                 "--out", str(tmp_path / "c.csv")]) == 2
    assert "--rig-camera is a rig's: add --sensor rig" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize("setup", ["eye_in_hand", "eye_to_hand"])
def test_a_rig_plan_every_camera_can_use_and_its_promise_kept(tmp_path, camera_yaml, capsys, setup):
    """plan --rig-camera: poses in which every camera of a stereo rig sees the whole board, written as a
    rig session's poses.csv; a capture of exactly those poses (0.3 px of corner noise) calibrated as a
    rig puts every camera's X within 3 of the std the plan predicted; bad --rig-camera values named."""
    from handeye.frames.metrics import within_std
    from handeye.pipelines.rig.pipeline import calibrate_rig
    from handeye.robot.models import ControllerPoses
    from handeye.sensors.camera.model import CameraCorners
    X, Z = _mounting(setup)
    def arg(T):  # a pose as the CLI takes it: x,y,z (m), rotation vector (deg)
        return ",".join(repr(float(v)) for v in np.r_[T[:3, 3], Rotation.from_matrix(T[:3, :3]).as_rotvec(degrees=True)])
    flags = ("--cam-in-flange", "--target-in-base") if setup == "eye_in_hand" else ("--camera-in-base", "--target-in-flange")
    placement = [flags[0], arg(X), flags[1], arg(Z)]
    out = tmp_path / "poses.csv"
    rel = "right," + str(camera_yaml) + ",0.12,0,0,0,-6,0"  # 120 mm to the right, turned in by 6 deg
    assert main(["plan", "--setup", setup, "--intrinsics", str(camera_yaml), *placement, "--standoff", "0.6",
                 "--poses", "10", "--rig-camera", rel, "--target", "chessboard", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "every camera (cam0, right)" in text and "right    rotation" in text
    rows, names = read_pose_table(out, "quat_wxyz", ("view",))
    F = parse_poses(rows, "quat_wxyz", "m", "deg")
    right = make_transform(Rotation.from_rotvec([0, -6, 0], degrees=True).as_matrix(), [0.12, 0, 0])
    obj = target_from_spec(DEFAULT_TARGETS["chessboard"]).object_points()
    cams = [RigPlanCamera("cam0", np.eye(4), K, SIZE, DIST), RigPlanCamera("right", right, K, SIZE, DIST)]
    plan = plan_rig(setup, X, Z, obj, cams, n_poses=10, standoff=0.6)
    assert names == [f"v{k + 1:02d}" for k in range(10)] and np.abs(F - plan.flange2base).max() < 1e-9
    rng = np.random.default_rng(1)
    models = []
    for cam in cams:
        T = predicted_target2cam(X @ cam.cam2first, Z, F, setup)
        assert visible_mask(T, obj, K, DIST, SIZE, 20.0).all()  # every camera sees the whole board in every pose
        corners = [project_points(t, obj, K, DIST) + rng.normal(0, 0.3, (len(obj), 2)) for t in T]
        models.append(CameraCorners(setup, names, corners, [obj] * len(T), K, DIST))
    rig = calibrate_rig(models, ["cam0", "right"], ControllerPoses(F, None))
    for cam in cams:
        X_cam = np.array(rig.joint.sensor.figures["X_per_sensor"][cam.name]["X"])
        assert within_std(X_cam, X @ cam.cam2first, plan.std_per_camera[cam.name])
    for bad, expect in (("right,cam.yaml,0.1", "NAME,INTRINSICS,X,Y,Z"), ("cam0," + str(camera_yaml) + ",0.1,0,0", "is taken")):
        assert main(["plan", "--intrinsics", str(camera_yaml), *placement, "--setup", setup, "--standoff", "0.6",
                     "--rig-camera", bad, "--out", str(tmp_path / "p2.csv")]) == 2
        assert expect in capsys.readouterr().err
