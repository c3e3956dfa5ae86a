"""Depth cameras and 3D sensors: what a view's organized point cloud measures.

A board's corners detected in the intensity image and lifted to 3D from the cloud
(:mod:`~handeye.sensors.depth.clouds`), or spheres found in the cloud without any board
(:mod:`~handeye.sensors.depth.spheres`); the depth noise model. X is fitted to those 3D points by
:mod:`handeye.pipelines.depth.pipeline` (thesis §6.1: other camera types).
"""

from __future__ import annotations

from .clouds import (
    CLOUD_SUFFIXES,
    EDGE_JUMP,
    FRAME_TOLERANCE_PX,
    MAX_DEPTH_M,
    board_pose,
    check_cloud,
    check_frame,
    cloud_pinhole,
    depth_sigma,
    lift_points,
    plane_points,
    read_cloud,
)
from .spheres import Sphere, find_spheres, fit_sphere

__all__ = ["read_cloud", "check_cloud", "check_frame", "cloud_pinhole", "lift_points", "plane_points", "board_pose", "depth_sigma",
           "Sphere", "fit_sphere", "find_spheres",
           "MAX_DEPTH_M", "EDGE_JUMP", "FRAME_TOLERANCE_PX", "CLOUD_SUFFIXES"]
