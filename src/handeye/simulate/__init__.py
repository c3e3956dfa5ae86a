"""Synthetic hand-eye captures with ground truth, for tests, examples, benchmarks and the study.

* :mod:`~handeye.simulate.scenes`: viewpoints of a target turned into robot poses through the true
  X and Z (the thesis's §5.2 set-up), their noise, and rendered sessions (``simulate_session``);
* :mod:`~handeye.simulate.arms`: captures by arms with real robots' errors, joint angles through
  shipped arms' tables, robots that cannot rotate freely;
* :mod:`~handeye.simulate.streams`: continuous recordings on two clocks;
* :mod:`~handeye.simulate._common`'s cells, arms as built and reported poses, which every kind of
  sensor's simulator (``pipelines/<kind>/simulate.py``: a depth camera's, a laser profiler's, a
  line-scan camera's, a rig's, a colour camera's masks) builds its captures on.

Sessions are written by :mod:`handeye.io.session`'s writers. The depth cameras' and the laser
profilers' simulators that were here are in their kinds' folders (the old names still import, with a
DeprecationWarning, for one release).
"""

from __future__ import annotations

from .._shared.moved import forward_names
from ..frames.setups import flange_poses
from ._common import (
    ARM_DH,
    DEFAULT_TARGETS,
    EXACT,
    MIN_IMAGE_SIDE,
    REALISTIC,
    RealisticErrors,
    arm_forward_kinematics,
    arm_mount,
    default_camera,
    reaching,
    real_chain,
    reported_poses,
    sample_joints,
    scene_layout,
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
           "simulate_stream_session", "arm_mount", "reaching", "real_chain", "reported_poses", "sample_joints", "scene_layout"]

__getattr__ = forward_names(__name__)  # the depth cameras' and laser profilers' simulators, moved to their kinds' folders
