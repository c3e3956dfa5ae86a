"""The type checker on the estimation core, the sensor models and the robot models: the contract
declared as protocols (sensors/base.py, robot/models.py) holds wherever a model is written or used
in those folders ([tool.mypy] in pyproject.toml)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from handeye.estimation.core import Problem, plan_of
from handeye.robot.kinematics import load_arm
from handeye.robot.models import ControllerPoses, FittedTable, FollowsMotion, JointAngles, JointTrajectory, PoseErrors
from handeye.sensors.base import Differentiable, DrawsSections, HasNuisances, Noise, PixelResiduals
from handeye.sensors.camera.model import CameraCorners
from handeye.sensors.depth.model import SphereCentres

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("mypy") is None, reason="mypy is not installed (pip install -e '.[test]')")
def test_mypy_finds_nothing_in_the_core_the_sensors_and_the_robot():
    """~20 s from a cold cache (1-2 min on a busy machine), a few seconds from a warm one."""
    done = subprocess.run([sys.executable, "-m", "mypy"], cwd=ROOT, capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
    config = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    assert all(f'"src/handeye/{folder}"' in config for folder in ("estimation", "sensors", "robot"))  # what it checked


def _corners(n: int = 4) -> CameraCorners:
    K = np.array([[800.0, 0, 320], [0, 800.0, 240], [0, 0, 1]])
    grid = np.c_[np.mgrid[0:3, 0:2].reshape(2, -1).T * 0.02, np.zeros(6)]
    uv = [grid[:, :2] * 800 / 0.5 + [320, 240] for _ in range(n)]
    return CameraCorners("eye_in_hand", [f"v{i}" for i in range(n)], uv, [grid] * n, K, np.zeros(5))


def test_the_capabilities_are_asked_by_protocol_and_the_jacobian_picked_once():
    """A camera's corners are differentiable, in pixels, drawn, without nuisances; a ball's centres none
    of that. The plan picks the sensor's own derivatives for exact robot poses, the chain rule for an
    arm's table, view-by-view differences for each pose's error, finite differences along a trajectory."""
    camera, ball = _corners(), SphereCentres("eye_in_hand", ["a", "b", "c"], np.full((3, 3), 0.5), fit_depth=False)
    assert isinstance(camera, Differentiable) and isinstance(camera, PixelResiduals) and isinstance(camera, DrawsSections)
    assert not isinstance(camera, HasNuisances)
    assert not isinstance(ball, Differentiable) and not isinstance(ball, PixelResiduals)
    assert Noise.of(camera).pixel_size is not None and Noise.of(ball).pixel_size is None
    assert Noise.of(camera).groups.shape == np.asarray(camera.shape).shape and Noise.of(camera).mask is None

    ur5 = load_arm("ur5")
    q = np.radians([[0, -90, 90, -90, -90, 0], [10, -80, 85, -95, -90, 20], [-15, -100, 95, -80, -85, -30],
                    [5, -95, 80, -85, -80, 10]])
    poses = ur5.forward(q)
    table, trajectory = JointAngles(ur5, q), JointTrajectory(ur5, q, times=np.arange(4.0), trajectory=q)
    assert isinstance(table, FittedTable) and not isinstance(ControllerPoses(poses), FittedTable)
    assert isinstance(trajectory, FollowsMotion) and not isinstance(table, FollowsMotion)
    assert plan_of(camera, ControllerPoses(poses)).jacobian == "own"
    assert plan_of(ball, ControllerPoses(poses)).jacobian == "differences"
    assert plan_of(camera, table).jacobian == "chained"
    errors = plan_of(camera, PoseErrors(poses, (0.1, 1.0)))
    assert errors.jacobian == "per view" and errors.per_view and not errors.eliminates  # 24 unknowns: the joint Jacobian
    moving = plan_of(camera, trajectory)
    assert moving.jacobian == "differences" and moving.takes == "motion"
    problem = Problem(camera, ControllerPoses(poses), np.eye(4), np.zeros(6))
    assert problem.plan is problem.plan  # read once per problem
