"""A camera's poses of the target as a sensor model (:mod:`handeye.sensors.base`): pose pairs.

When only the target's pose in each view is known (PnP's, or another tool's ``target2cam``; no
detections), each view measures a whole pose. What a pose says reliably is where the target's
points lie across the camera's viewing rays; along the ray (the target's distance) PnP's pose is
far less certain. So the residuals are those of a virtual target's points (a 0.2 x 0.15 m grid in
the target's plane): the predicted point's offset across the measured point's viewing ray, in
metres at its depth (what pixels measure, without PnP's depth error), every point weighted alike.
(Weighted by its depth, as a pixel's size grows, X was further from the truth on simulated joint
streams: 0.18 mm against 0.12, median of 6; on 10 joint captures 0.094 against 0.102 mm.) The
unknowns besides X: the target's pose (a chart about its start). The start: the closed form on
the poses.

Examples
--------
>>> import numpy as np
>>> from handeye.estimation.core import estimate
>>> from handeye.robot.models import ControllerPoses
>>> from handeye.simulate import random_scene
>>> scene = random_scene(12, "eye_in_hand", rng=0)
>>> model = TargetPoses("eye_in_hand", [f"v{i}" for i in range(12)], scene.target2cam)
>>> cal = estimate(model, ControllerPoses(scene.flange2base))
>>> bool(1e3 * np.abs(cal.X[:3, 3] - scene.X[:3, 3]).max() < 1e-3)
True
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...errors import DegenerateMotionError, InputMismatchError
from ...frames.setups import check_setup, predicted_target2cam
from ..target_pose import ChartedTarget

__all__ = ["TargetPoses", "VIRTUAL_POINTS", "POSE_NOISE"]

#: The virtual target's points (target frame, m) whose viewing rays carry a pose's residuals.
VIRTUAL_POINTS = np.array([[x, y, 0.0] for x in np.linspace(0.0, 0.2, 5) for y in np.linspace(0.0, 0.15, 4)])
#: A pose's noise across the viewing ray to state before any fit, as a share of the depth (0.2 mm at 1 m:
#: 0.3 px of a corner at a focal length of ~1500 px, averaged over a board's corners).
POSE_NOISE = 2e-4


class TargetPoses(ChartedTarget):
    """A camera's poses of the target, one per view (the module docstring).

    Parameters
    ----------
    setup : str
    names : list of str
        Per view its name.
    target2cam : array_like (N, 4, 4)
        Per view the target's pose in the camera frame (m); a view whose pose is not finite is one
        the camera did not see the target in.
    """

    kind = "camera"
    target = "target poses"
    pixel_columns: tuple[int, ...] = ()  # every point weighted alike (the module docstring)
    groups: tuple[tuple[int, ...], ...] = ((0, 1),)
    param_names = ["target.rx", "target.ry", "target.rz", "target.x", "target.y", "target.z"]

    def __init__(self, setup: str, names: list[str], target2cam: ArrayLike) -> None:
        self.setup = check_setup(setup)
        poses = np.asarray(target2cam, dtype=float)
        if poses.ndim != 3 or poses.shape[1:] != (4, 4) or len(poses) != len(names):
            raise InputMismatchError(f"{len(names)} views and target2cam of shape {poses.shape}: give one 4x4 pose per view")
        self.names = list(names)
        self._poses = poses
        seen = np.flatnonzero(np.isfinite(poses).all(axis=(1, 2)))
        m = len(VIRTUAL_POINTS)
        self.owner = np.repeat(seen, m).astype(np.intp)
        self.points = np.tile(VIRTUAL_POINTS, (len(seen), 1))
        measured = np.einsum("mij,mj->mi", poses[self.owner, :3, :3], self.points) + poses[self.owner, :3, 3]
        if np.any(measured[:, 2] <= 0):
            view = self.names[int(self.owner[np.argmax(measured[:, 2] <= 0)])]
            raise InputMismatchError(f"view {view}: the target lies behind the camera (z <= 0 in target2cam); give the "
                                     "target's pose in the camera frame (the camera's z axis along its view)")
        self._ray = measured[:, :2] / measured[:, 2:3]  # each virtual point's viewing ray (normalised coordinates)
        self._depth = measured[:, 2]
        self.noise_px = 1.0  # the stated noise is POSE_NOISE of the depth: a "pixel" of that size
        self.shape = np.ones((len(self.owner), 2))
        self.param_scale = np.full(6, 1e-3)

    def view_poses(self) -> NDArray[np.float64]:
        """The poses given."""
        return self._poses

    def start(self, flange2base, X, Z, rows=None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """X and the target from the closed form; the first start fixes the target's chart and each
        point's stated noise (:data:`POSE_NOISE` of its depth)."""
        if X is None or Z is None:
            raise DegenerateMotionError("target poses need 3 views or more for the closed form")
        self._first_start(X, Z, flange2base, 1.0 / POSE_NOISE)
        return X, self.target_params(Z)

    def residuals(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """Per virtual point (m): the predicted point's offset across its measured viewing ray, at its depth."""
        target2cam = predicted_target2cam(X, self._target2world(p), np.asarray(flange2base, float), self.setup)
        T = target2cam[self.owner[rows]]
        seen = np.einsum("mij,mj->mi", T[:, :3, :3], self.points[rows]) + T[:, :3, 3]
        return (seen[:, :2] / seen[:, 2:3] - self._ray[rows]) * self._depth[rows, None]

    def figures(self, p, cov_p) -> dict[str, Any]:
        """Nothing beyond the core's own figures."""
        return {}

    def notes(self, p, cov_p) -> list[str]:
        """Nothing beyond the core's own notes."""
        return []
