"""A depth camera fixed in the cell that sees the arm itself (markerless, eye-to-hand): clouds of a
meshed arm (its link meshes, :mod:`handeye.robot.meshes`) at joint angles spread about its home,
ray-cast with trimesh (Embree when installed), with the depth camera's noise, holes and flying
pixels (:func:`~handeye.pipelines.depth.simulate_board.depth_reading`), and clutter: the table the arm stands on
and a box beside it.

Examples
--------
>>> from handeye.pipelines.depth.simulate_arm import arm_depth_scene
>>> scene = arm_depth_scene(3, rng=0, image_size=(160, 120))
>>> len(scene.clouds), scene.clouds[0].shape, scene.joints.shape
(3, (120, 160, 3), (3, 7))
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import NDArray

from ..._shared.io import atomic_write, check_output_folder
from ...errors import InputMismatchError
from ...frames.setups import setup_info
from ...geometry.se3 import invert
from ...io.session import write_joint_table
from ...robot.kinematics import Chain, load_arm
from ...robot.meshes import arm_meshes
from ...simulate import default_camera, real_chain
from ...simulate.scenes import Scene, look_at
from .simulate_board import depth_reading, pixel_rays
from .simulate_mesh import cast_rays, ray_caster, write_clouds

__all__ = ["ArmDepthScene", "arm_depth_scene", "write_arm_depth_session", "ARM_CENTRE"]

#: Where the simulated camera aims, in the base frame (m): the middle of the Panda's reach about its home.
ARM_CENTRE = np.array([0.3, 0.0, 0.45])


@dataclass(frozen=True)
class ArmDepthScene(Scene):
    """A simulated capture of the arm by a fixed depth camera: X = cam2base; ``Z`` the identity
    and ``target2cam`` = flange2cam (the arm has no target: its links are posed in the base frame by
    the joint angles); per view a cloud (``clouds``, H x W x 3 float32, camera frame, NaN without
    depth), the joint angles (``joints``, rad), the arm's name, the depth scale and bias."""

    K: NDArray[np.float64] = None  # type: ignore[assignment]
    image_size: tuple[int, int] = (640, 480)
    clouds: list = None  # type: ignore[assignment]
    joints: NDArray[np.float64] = None  # type: ignore[assignment]
    arm: str = "panda"
    depth_scale: float = 1.0
    depth_bias: float = 0.0
    arm_share: NDArray[np.float64] = None  # type: ignore[assignment]  #: per view, the share of the pixels on the arm


def _joint_angles(chain: Chain, n: int, rng: np.random.Generator, setup: str) -> NDArray[np.float64]:
    """``n`` joint configurations uniform within the chain's ``spread`` about its home, inside its limits."""
    home = np.asarray(chain.home.get(setup, np.zeros(chain.n_joints)), float)
    spread = np.asarray(chain.spread if chain.spread is not None else np.full(chain.n_joints, 0.5), float)
    q = home + rng.uniform(-1.0, 1.0, (n, chain.n_joints)) * spread
    if chain.limits is not None:
        q = np.clip(q, chain.limits[:, 0] + 1e-3, chain.limits[:, 1] - 1e-3)
    return q


def _camera(rng: np.random.Generator, distance: tuple[float, float]) -> NDArray[np.float64]:
    """A fixed camera's cam2base: on either side of the arm or in front (azimuth 20-160 deg from +x,
    either side), 15-45 deg above the horizon, ``distance`` (m) from :data:`ARM_CENTRE`, aimed at it."""
    azimuth = np.radians(rng.uniform(20.0, 160.0)) * rng.choice([-1.0, 1.0])
    elevation = np.radians(rng.uniform(15.0, 45.0))
    direction = np.array([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)])
    position = ARM_CENTRE + rng.uniform(*distance) * direction
    return look_at(position[None], ARM_CENTRE[None], rng.uniform(-0.3, 0.3, 1))[0]


def _clutter(trimesh, rng: np.random.Generator):
    """The table the arm stands on (z = 0, 3 m square) and a box beside the arm (0.15-0.3 m sides)."""
    table = trimesh.creation.box([3.0, 3.0, 0.02])
    table.apply_translation([0.2, 0.0, -0.01])
    box = trimesh.creation.box(rng.uniform(0.15, 0.3, 3))
    angle = rng.uniform(-np.pi, np.pi)
    box.apply_translation([0.75 * np.cos(angle) - 0.1, 0.75 * np.sin(angle), box.extents[2] / 2])
    return trimesh.util.concatenate([table, box])


def arm_depth_scene(n_views: int = 10, rng: np.random.Generator | int | None = None, *, arm: str = "panda",
                    image_size: tuple[int, int] = (640, 480), distance: tuple[float, float] = (0.8, 1.5),
                    depth_noise: tuple[float, float] = (1e-4, 5e-4), depth_scale: float = 1.002, depth_bias: float = 0.0,
                    holes: float = 0.01, clutter: bool = True, cam2base: NDArray[np.float64] | None = None,
                    joints: NDArray[np.float64] | None = None, table_error: tuple[float, float] | None = None) -> ArmDepthScene:
    """A fixed depth camera's clouds of the arm ``arm`` (its meshes, with the maker's hand) at
    ``n_views`` joint configurations about its eye-to-hand home (within the chain's spread).

    Parameters
    ----------
    n_views : int
    rng : Generator, int or None
    arm : str
        An arm with meshes (:func:`~handeye.robot.meshes.mesh_arm_names`).
    image_size : (int, int)
        Width, height (px); a ~50 deg wide pinhole.
    distance : (float, float)
        The camera's distance (m) from :data:`ARM_CENTRE`, drawn uniformly.
    depth_noise, depth_scale, depth_bias, holes
        As :func:`~handeye.pipelines.depth.simulate_board.depth_reading`: noise ``a + b z^2`` (m), the camera's depth
        scale and bias, the share of pixels without depth; the arm's outline has flying pixels.
    clutter : bool
        The table under the arm and a box beside it in the scene.
    cam2base : ndarray (4, 4), optional
        The camera's pose (default: drawn, :func:`_camera`).
    joints : ndarray (n_views, n), optional
        The joint angles (rad) instead of drawn ones.
    table_error : (float, float), optional
        (mm, deg): the arm as built is off its nominal table by Gaussian errors of these sizes in
        every entry (the links are posed by the real table, the joint angles the controller reports
        are the same); None: the arm is its nominal table.
    """
    rng = np.random.default_rng(rng)
    chain = load_arm(arm)
    meshes = arm_meshes(arm)
    trimesh = importlib.import_module("trimesh")  # arm_meshes found it, or said to install it
    q = _joint_angles(chain, n_views, rng, "eye_to_hand") if joints is None else np.atleast_2d(np.asarray(joints, float))
    X = _camera(rng, distance) if cam2base is None else np.asarray(cam2base, float)
    real = chain if table_error is None else real_chain(chain, rng, *table_error)
    K = default_camera(image_size)[0]
    w, h = image_size
    rays = pixel_rays(K, image_size).reshape(-1, 3)
    vertices, faces, _ = meshes.merged()
    posed = meshes.posed_vertices(meshes.link2base(real, q))
    scenery = _clutter(trimesh, rng) if clutter else None
    behind_caster = None if scenery is None else ray_caster(scenery)
    clouds, share = [], []
    for k in range(len(q)):
        body = trimesh.Trimesh(posed[k], faces, process=False)
        whole = body if scenery is None else trimesh.util.concatenate([body, scenery])
        t, on = cast_rays(ray_caster(whole), len(faces), rays, X)
        t_behind = np.full(len(rays), np.inf) if behind_caster is None else cast_rays(behind_caster, 0, rays, X)[0]
        truth = (rays * np.where(np.isfinite(t), t, np.nan)[:, None]).reshape(h, w, 3)
        behind = (rays * np.where(np.isfinite(t_behind), t_behind, np.nan)[:, None]).reshape(h, w, 3)
        behind = np.where(np.isfinite(behind), behind, truth)  # nothing behind: a flying pixel stays on the arm
        mask = on.reshape(h, w)
        clouds.append(depth_reading(truth, mask, behind, rng, depth_scale, depth_bias, depth_noise, holes))
        share.append(float(mask.mean()))
    F = real.forward(q)
    return ArmDepthScene("eye_to_hand", X, np.eye(4), F, invert(X) @ F, K=K, image_size=tuple(image_size), clouds=clouds,
                         joints=q, arm=chain.name.lower(), depth_scale=depth_scale, depth_bias=depth_bias,
                         arm_share=np.array(share))


def write_arm_depth_session(folder: str | Path, scene: ArmDepthScene, *, organized: bool = True) -> Path:
    """Write a simulated capture of the arm as a depth session: ``clouds/viewNN.npy`` (float32
    metres, H x W x 3, or N x 3 of the points with depth when not ``organized``), ``joints.csv``
    (degrees; first column ``cloud``), ``session.yaml`` (``target: {type: arm}``, ``joints: {file:
    joints.csv, unit: deg, arm: ...}``, no poses: the flange's come from the arm's table) and
    ``ground_truth.yaml`` (cam2base, the depth scale and bias). Returns the folder."""
    if len(scene.clouds) != len(scene.joints):
        raise InputMismatchError(f"{len(scene.clouds)} clouds and {len(scene.joints)} joint rows: one of each per view")
    out = check_output_folder(folder)
    names = write_clouds(out, scene.clouds, organized)
    write_joint_table(out / "joints.csv", names, scene.joints, "deg", id_column="cloud")
    spec = {"setup": scene.setup, "target": {"type": "arm"}, "depth": {"unit": "m"},
            "joints": {"file": "joints.csv", "unit": "deg", "arm": scene.arm}}
    atomic_write(out / "session.yaml", yaml.safe_dump(spec, sort_keys=False))
    info = setup_info(scene.setup)
    truth = {"setup": scene.setup, info.x_name: np.asarray(scene.X).tolist(), "depth_scale": float(scene.depth_scale),
             "depth_bias": float(scene.depth_bias), "arm": scene.arm}
    atomic_write(out / "ground_truth.yaml", yaml.safe_dump(truth, sort_keys=False))
    return out
