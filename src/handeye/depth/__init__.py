"""Depth cameras and 3D sensors: hand-eye calibration from organized point clouds.

A board's corners detected in the intensity image and lifted to 3D from the cloud, or spheres
found in the cloud without any board; X and Z fitted to those 3D points with the camera's depth
scale and bias as unknowns (thesis §6.1: other camera types).
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
from .fit import DepthCalibration, calibrate_depth, calibrate_spheres, predict_points
from .session import DepthResult, DepthSession, calibrate_depth_session, is_depth_session, load_depth_session
from .spheres import Sphere, find_spheres, fit_sphere

__all__ = ["read_cloud", "check_cloud", "check_frame", "cloud_pinhole", "lift_points", "plane_points", "board_pose", "depth_sigma",
           "DepthCalibration", "calibrate_depth", "calibrate_spheres", "Sphere", "fit_sphere", "find_spheres",
           "DepthSession", "DepthResult", "is_depth_session", "load_depth_session", "calibrate_depth_session", "predict_points",
           "MAX_DEPTH_M", "EDGE_JUMP", "FRAME_TOLERANCE_PX", "CLOUD_SUFFIXES"]
