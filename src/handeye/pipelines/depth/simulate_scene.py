"""Depth cameras' clouds of whatever object they see (no target, no mesh given to the calibration):
an irregular object ray-cast from a few views, with the depth camera's noise, holes and flying pixels.

Eye-in-hand: the object stands on a table fixed in the cell, the camera on the flange looks at it
from above. Eye-to-hand: the object sits on the flange (on the wrist, a rod it is mounted on), a
fixed camera looks at it. The session written (:func:`write_scene_session`) says
``target: {type: scene}``: the calibration gets the clouds and the robot poses, nothing of the
object.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..._shared.io import atomic_write, check_output_folder
from ...errors import SessionError
from ...frames.setups import check_setup, setup_info
from ...io.session import write_pose_table
from ...simulate import default_camera, reported_poses
from ...simulate.scenes import scene_from_viewpoints
from .simulate_board import depth_reading, pixel_rays
from .simulate_mesh import MeshScene, cast_rays, framed_viewpoints, ray_caster, write_clouds

__all__ = ["irregular_mesh", "scene_capture", "write_scene_session"]


def _trimesh():
    try:
        return importlib.import_module("trimesh")
    except ImportError:
        raise SessionError("simulating a scene needs trimesh, manifold3d and embreex: pip install 'handeye[mesh]'") from None


def irregular_mesh(rng: np.random.Generator | int | None = 0, size: float = 0.12):
    """An irregular object about ``size`` (m) across, resting on z = 0 (trimesh.Trimesh, metres): a
    lumpy potato (a sphere pushed in and out by a dozen smooth bumps) with a block and a peg stuck
    into it at random angles; no symmetry, so its pose is whole in any view of it."""
    trimesh = _trimesh()
    rng = np.random.default_rng(rng)
    blob = trimesh.creation.icosphere(subdivisions=4, radius=1.0)
    u = np.asarray(blob.vertices, float)
    centres = rng.normal(size=(12, 3))
    centres /= np.linalg.norm(centres, axis=1, keepdims=True)
    heights = rng.uniform(-0.18, 0.3, 12)
    widths = rng.uniform(0.35, 0.8, 12)
    bump = np.exp(-np.sum((u[:, None, :] - centres[None]) ** 2, axis=2) / widths**2) @ heights
    stretch = np.array([1.0, rng.uniform(0.65, 0.85), rng.uniform(0.55, 0.75)])
    blob.vertices = u * (1.0 + bump)[:, None] * stretch * (0.35 * size)
    block = trimesh.creation.box(extents=np.array([0.45, 0.3, 0.22]) * size)
    block.apply_transform(_placed(rng, 0.3 * size))
    peg = trimesh.creation.cylinder(0.07 * size, 0.5 * size, sections=48)
    peg.apply_transform(_placed(rng, 0.3 * size))
    mesh = trimesh.boolean.union([blob, block, peg], engine="manifold")
    mesh.apply_translation([0.0, 0.0, -float(mesh.bounds[0, 2])])
    return mesh


def _placed(rng: np.random.Generator, reach: float) -> NDArray[np.float64]:
    """A transform: a random orientation, its origin ``reach`` from the centre, above the middle."""
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=int(rng.integers(2**31))).as_matrix()
    direction = rng.normal(size=3) * [1.0, 1.0, 0.4] + [0.0, 0.0, 0.5]
    T[:3, 3] = reach * direction / np.linalg.norm(direction)
    return T


@dataclass(frozen=True)
class SceneCapture(MeshScene):
    """A simulated capture of an object as the scene (:func:`scene_capture`): ``mesh`` is the object
    (in its own frame, ``Z`` its pose: object2base eye-in-hand, object2flange eye-to-hand), ``clouds``
    what the camera measured of it and of what it stands on."""


def _blots(h: int, w: int, rng: np.random.Generator, count: int) -> NDArray[np.bool_]:
    """``count`` elliptic blots (H, W) without depth (a dark or shiny patch), each 2-5% of the image's width."""
    v, u = np.mgrid[0:h, 0:w]
    out = np.zeros((h, w), bool)
    for _ in range(count):
        cu, cv = rng.uniform(0.2 * w, 0.8 * w), rng.uniform(0.2 * h, 0.8 * h)
        a, b = rng.uniform(0.02, 0.05, 2) * w
        out |= ((u - cu) / a) ** 2 + ((v - cv) / b) ** 2 < 1.0
    return out


def scene_capture(n_views: int = 9, setup: str = "eye_in_hand", rng: np.random.Generator | int | None = None, *,
                  mesh=None, image_size: tuple[int, int] = (640, 480), distance: tuple[float, float] = (0.3, 0.5),
                  tilt_max_deg: float = 45.0, depth_noise: tuple[float, float] = (1e-4, 5e-4), holes: float = 0.02,
                  blots: int = 3, table: float = 0.22, depth_scale: float = 1.0, depth_bias: float = 0.0,
                  robot_error: tuple[float, float] | None = None) -> SceneCapture:
    """A depth camera's ``n_views`` clouds of an irregular object (:func:`irregular_mesh`, or ``mesh``:
    trimesh, metres, resting on z = 0), ray-cast with Embree.

    The camera is ``distance`` (m) from the object's centre, its direction within ``tilt_max_deg``
    of the object's z axis, the object anywhere in the middle two thirds of the image, the camera's
    X random (any orientation on the flange, or anywhere in the cell). Eye-in-hand the object stands
    on a square plate ``table`` (m) across (0: none); eye-to-hand it sits on the wrist (a 70 mm rod along -z, part of
    what moves with the flange) and nothing else is within the camera's range. Depth noise
    ``depth_noise[0] + depth_noise[1] z^2`` (m), a share ``holes`` of pixels without depth and
    ``blots`` patches without depth per view, flying pixels on the object's outline; depths ``depth_scale``
    times the true ones plus ``depth_bias`` (m).
    ``robot_error`` (deg, mm): the controller's poses off by that much (:func:`~handeye.pipelines.depth.simulate_mesh.mesh_scene`'s).
    """
    trimesh = _trimesh()
    setup = check_setup(setup)
    rng = np.random.default_rng(rng)
    mesh = irregular_mesh(rng) if mesh is None else mesh
    K = default_camera(image_size)[0]
    w, h = image_size
    centre = np.asarray(mesh.bounds, float).mean(axis=0)
    cam2target = framed_viewpoints(n_views, rng, K, image_size, distance, tilt_max_deg, centre)
    scene = scene_from_viewpoints(cam2target, setup, rng)
    parts = [mesh]
    if setup_info(setup).camera_on_flange:
        if table:
            plate = trimesh.creation.box(extents=[table, table, 0.02])
            plate.apply_translation(centre * [1.0, 1.0, 0.0] + [0.0, 0.0, -0.01 - 1e-4])
            parts.append(plate)
    else:
        rod = trimesh.creation.cylinder(0.035, 0.15, sections=64)
        rod.apply_translation(centre * [1.0, 1.0, 0.0] + [0.0, 0.0, -0.075 + 1e-3])
        parts.append(rod)
    caster = ray_caster(trimesh.util.concatenate(parts))
    rays = pixel_rays(K, image_size).reshape(-1, 3)
    clouds = []
    for c2t in cam2target:
        t, on = cast_rays(caster, len(mesh.faces), rays, c2t)
        truth = (rays * np.where(np.isfinite(t), t, np.nan)[:, None]).reshape(h, w, 3)
        # the object's outline flies towards what is behind it: 5 cm further along the ray
        behind = (rays * (np.where(np.isfinite(t), t, 0.0) + 0.05)[:, None]).reshape(h, w, 3)
        cloud = depth_reading(truth, on.reshape(h, w), behind, rng, depth_scale, depth_bias, depth_noise, holes)
        cloud[_blots(h, w, rng, blots)] = np.nan
        clouds.append(cloud)
    return SceneCapture(setup, scene.X, scene.Z, reported_poses(scene.flange2base, robot_error, rng), scene.target2cam, K=K,
                        image_size=tuple(image_size), mesh=mesh, clouds=clouds, depth_scale=depth_scale, depth_bias=depth_bias)


def write_scene_session(folder: str | Path, capture: MeshScene, *, organized: bool = True) -> Path:
    """Write a simulated scene capture as a depth session: ``clouds/viewNN.npy`` (float32 metres),
    ``poses.csv`` (quat_wxyz, mm, deg; first column ``cloud``), ``session.yaml`` (``target: {type:
    scene}``: nothing of the object) and ``ground_truth.yaml`` (X, and the object's pose and mesh for
    reference: ``object.stl`` in mm). Returns the folder."""
    out = check_output_folder(folder)
    names = write_clouds(out, capture.clouds, organized)
    write_pose_table(out / "poses.csv", names, capture.flange2base, "quat_wxyz", "mm", "deg", id_column="cloud")
    spec = {"setup": capture.setup, "target": {"type": "scene"}, "depth": {"unit": "m"},
            "poses": {"file": "poses.csv", "format": "quat_wxyz", "length_unit": "mm", "angle_unit": "deg"}}
    atomic_write(out / "session.yaml", yaml.safe_dump(spec, sort_keys=False))
    mesh = capture.mesh.copy()
    mesh.apply_scale(1e3)
    atomic_write(out / "object.stl", mesh.export(file_type="stl"))
    info = setup_info(capture.setup)
    truth = {"setup": capture.setup, info.x_name: np.asarray(capture.X).tolist(), "depth_scale": float(capture.depth_scale),
             "depth_bias": float(capture.depth_bias),
             "object_pose": np.asarray(capture.Z).tolist(), "object_mesh": "object.stl (mm; not read by the calibration)"}
    atomic_write(out / "ground_truth.yaml", yaml.safe_dump(truth, sort_keys=False))
    return out

