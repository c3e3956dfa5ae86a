"""``handeye simulate --sensor depth``: which of the depth camera's simulators makes the capture, by
its target (a mesh, a ball, a board, the arm itself, or whatever object the camera sees):
:mod:`~handeye.pipelines.depth.simulate_board` (a board or balls), :mod:`~handeye.pipelines.depth.simulate_mesh`,
:mod:`~handeye.pipelines.depth.simulate_arm` and :mod:`~handeye.pipelines.depth.simulate_scene`."""

from __future__ import annotations

from pathlib import Path

from ...errors import InputMismatchError
from ...frames.setups import setup_info
from ...simulate import DEFAULT_TARGETS
from ..kinds import SimulateRequest
from .simulate_arm import arm_depth_scene, write_arm_depth_session
from .simulate_board import depth_scene, sphere_scene, write_depth_session
from .simulate_mesh import mesh_scene, write_mesh_session
from .simulate_scene import scene_capture, write_scene_session

__all__ = ["simulate_command"]


def _arm(request: SimulateRequest) -> str:
    """A depth camera fixed in the cell and the arm itself as the target (markerless): always eye_to_hand."""
    if request.robot != "arm":
        raise InputMismatchError("--sensor depth --target arm simulates a meshed arm's joint angles; leave --robot out")
    arm = request.arm or "panda"
    sc = arm_depth_scene(request.poses, request.seed, arm=arm, image_size=request.image_size)
    write_arm_depth_session(request.out, sc)
    return (f"wrote depth session {request.out} ({request.poses} clouds of the {arm} itself, its joint angles in joints.csv, "
            f"a camera fixed {1e3 * float(sc.X[2, 3]):.0f} mm above its base, eye_to_hand; a table and a box as clutter); "
            f"ground truth in {Path(request.out) / 'ground_truth.yaml'}")


def _scene(request: SimulateRequest) -> str:
    """No target: whatever object the camera sees."""
    if request.robot != "arm" or request.arm is not None:
        raise InputMismatchError("--target scene simulates a 6-axis arm's controller poses; leave --robot and --arm out")
    write_scene_session(request.out, scene_capture(request.poses, request.setup, request.seed, image_size=request.image_size))
    where = "on a plate, the camera on the flange" if setup_info(request.setup).camera_on_flange else \
        "on the flange, a camera fixed in the cell"
    return (f"wrote depth session {request.out} ({request.poses} clouds of an irregular object {where}, 0.3-0.5 m away, "
            f"target: {{type: scene}}: no target, no mesh); ground truth in {Path(request.out) / 'ground_truth.yaml'}")


def simulate_command(request: SimulateRequest) -> str:
    """``handeye simulate --sensor depth`` (the depth camera's registration's ``simulate`` hook): a depth
    camera's clouds of a mesh (the default: a flange-sized disc on the flange), a ball, a board, the
    arm itself or an irregular object, written to ``request.out``; returns what was written, in words."""
    target = request.target or "mesh"
    if target == "arm":  # markerless: a camera fixed in the cell sees the arm itself
        return _arm(request)
    if target == "scene":
        return _scene(request)
    if request.robot != "arm":
        raise InputMismatchError("--sensor depth simulates a 6-axis arm (its controller's poses, or with --arm its joint "
                                 "angles); leave --robot out")
    if target == "mesh":
        if request.arm is not None and setup_info(request.setup).camera_on_flange:
            raise InputMismatchError("--target mesh --arm simulates the shape on the arm's flange before a fixed camera: "
                                     "give --setup eye_to_hand")
        write_mesh_session(request.out, mesh_scene(request.poses, request.setup, request.seed, image_size=request.image_size,
                                                   arm=request.arm))
        what = "a flange-sized disc (target.stl) with bolt holes and a locating pin"
    elif target == "sphere":
        write_depth_session(request.out, sphere_scene(request.poses, request.setup, request.seed,
                                                      image_size=request.image_size, arm=request.arm))
        what = "a 50 mm ball"
    elif target in DEFAULT_TARGETS:
        write_depth_session(request.out, depth_scene(request.poses, request.setup, request.seed, target=target,
                                                     image_size=request.image_size, noise_px=request.noise_px, arm=request.arm))
        what = f"a {target} with its intensity images"
    else:
        raise InputMismatchError(f"--target {target}: a depth camera's simulated target is mesh (default), sphere, scene, "
                                 f"arm or a board ({', '.join(DEFAULT_TARGETS)})")
    arm = f", {request.arm}'s joint angles in joints.csv (the arm 1-3 mm off its nominal table)" if request.arm else ""
    return (f"wrote depth session {request.out} ({request.poses} clouds of {what}, {request.setup}{arm}); ground truth in "
            f"{Path(request.out) / 'ground_truth.yaml'}")
