"""Line-scan cameras: one row of pixels at a time, the robot's motion sweeping the second dimension.

A scan's image is a pushbroom image: row ``r`` was exposed at ``start + r / line_rate`` on the
camera's clock, while the robot moved the camera (or the target) through the camera's view plane.
:mod:`~handeye.sensors.linescan.model` fits X, the target's pose, the intrinsics along the line and
the clock offset to the corners of a planar target found in several scans;
:mod:`~handeye.sensors.linescan.resection` gives each scan's pose from its corners in closed form
(Gupta and Hartley's linear pushbroom camera), the start.
"""

from __future__ import annotations

from .model import LineScanCorners, Trajectory
from .resection import pushbroom_resection, resolve_mirrors

__all__ = ["LineScanCorners", "Trajectory", "pushbroom_resection", "resolve_mirrors"]
