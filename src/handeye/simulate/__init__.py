"""Synthetic hand-eye captures with ground truth, for tests, examples, benchmarks and the study.

* :mod:`~handeye.simulate.scenes`: viewpoints of a target turned into robot poses through the true
  X and Z (the thesis's §5.2 set-up), their noise, and rendered sessions (``simulate_session``);
* :mod:`~handeye.simulate.arms`: captures by arms with real robots' errors, joint angles through
  shipped arms' tables, robots that cannot rotate freely;
* :mod:`~handeye.simulate.streams`: continuous recordings on two clocks;
* :mod:`~handeye.simulate.depth`: depth cameras' clouds of a board or a sphere;
* :mod:`~handeye.simulate.laser`: laser line profilers' profiles of a ball;
* :mod:`~handeye.simulate.mesh`: depth cameras' clouds of a known shape (a mesh), ray-cast.

Sessions are written by :mod:`handeye.io.session`'s writers.
"""

from __future__ import annotations

from ..frames.setups import flange_poses
from ._common import (
    ARM_DH,
    DEFAULT_TARGETS,
    EXACT,
    MIN_IMAGE_SIDE,
    REALISTIC,
    RealisticErrors,
    arm_forward_kinematics,
    default_camera,
)
from .arms import (
    LOW_DOF_ROBOTS,
    KinematicScene,
    RealisticScene,
    capture_joint_views,
    kinematic_scene,
    low_dof_scene,
    realistic_scene,
    robot_accuracy_of,
    simulate_kinematic_session,
    simulate_realistic_session,
)
from .depth import DepthScene, SphereScene, depth_scene, sphere_scene, write_depth_session
from .laser import LaserScene, laser_scene, write_laser_session
from .mesh import MeshScene, flange_mesh, mesh_scene, write_mesh_session
from .scenes import (
    Noise,
    Scene,
    SceneBatch,
    add_noise,
    look_at,
    look_at_viewpoints,
    perturb_poses,
    random_scene,
    scene_from_viewpoints,
    seed_scenes,
    seed_viewpoints,
    simulate_session,
    visible_viewpoints,
)
from .streams import JointStreamScene, StreamScene, joint_stream_scene, simulate_stream_session, stream_scene

__all__ = ["Scene", "SceneBatch", "Noise", "random_scene", "flange_poses", "look_at", "look_at_viewpoints", "perturb_poses",
           "seed_viewpoints", "scene_from_viewpoints", "visible_viewpoints", "default_camera", "MIN_IMAGE_SIDE", "DEFAULT_TARGETS",
           "seed_scenes", "add_noise", "simulate_session", "RealisticErrors", "RealisticScene", "REALISTIC", "EXACT",
           "realistic_scene", "arm_forward_kinematics", "ARM_DH", "robot_accuracy_of", "simulate_realistic_session",
           "KinematicScene", "kinematic_scene", "simulate_kinematic_session", "capture_joint_views",
           "low_dof_scene", "LOW_DOF_ROBOTS", "StreamScene", "stream_scene", "JointStreamScene", "joint_stream_scene",
           "simulate_stream_session", "DepthScene", "depth_scene", "SphereScene", "sphere_scene", "write_depth_session",
           "LaserScene", "laser_scene", "write_laser_session", "MeshScene", "flange_mesh", "mesh_scene", "write_mesh_session"]
