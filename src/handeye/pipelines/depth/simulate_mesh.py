"""Depth cameras' clouds of a known shape (a mesh) on the flange or fixed in the cell, ray-cast with
trimesh (Embree when installed), with the depth camera's noise, holes and flying pixels.

The default shape is a flange-sized disc (:func:`flange_mesh`: 80 mm across, 12 mm thick, bolt
holes and an off-centre locating pin), mounted on the flange (eye-to-hand) in front of the wrist
it sits on, a wall behind.
"""

from __future__ import annotations

import importlib
import io
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..._shared.io import atomic_write, check_output_folder
from ...errors import HandEyeError, SessionError
from ...frames.setups import check_setup, predicted_target2cam, setup_info
from ...geometry.se3 import invert
from ...io.session import write_joint_table, write_pose_table
from ...robot.kinematics import Chain
from ...simulate import default_camera, reported_poses
from ...simulate.scenes import Scene, look_at_viewpoints, scene_from_viewpoints
from .simulate_board import arm_fields, arm_views, depth_reading, pixel_rays

__all__ = ["MeshScene", "flange_mesh", "mesh_scene", "write_mesh_session", "write_clouds", "ray_caster", "cast_rays"]


def _trimesh():
    try:
        return importlib.import_module("trimesh")
    except ImportError:
        raise SessionError("simulating a mesh target needs trimesh and manifold3d: pip install 'handeye[mesh]'") from None


def flange_mesh(diameter: float = 0.080, thickness: float = 0.012, holes: int = 4, hole_diameter: float = 0.0066,
                bolt_circle: float = 0.063, pin: bool = True, pin_diameter: float = 0.006, pin_height: float = 0.008):
    """A flange-sized disc (trimesh.Trimesh, metres): its back face at z = 0 on the flange, its
    front at ``thickness``, ``holes`` bolt holes on the ``bolt_circle``, and (``pin``) a locating pin
    off the centre and off the bolt circle, which fixes the disc's rotation about its axis (without
    it and the holes the disc turns into itself)."""
    trimesh = _trimesh()
    disc = trimesh.creation.cylinder(diameter / 2, thickness, sections=180)
    disc.apply_translation([0.0, 0.0, thickness / 2])
    cut = []
    for k in range(holes):
        a = 2 * np.pi * (k + 0.5) / max(holes, 1)
        hole = trimesh.creation.cylinder(hole_diameter / 2, 3 * thickness, sections=32)
        hole.apply_translation([bolt_circle / 2 * np.cos(a), bolt_circle / 2 * np.sin(a), thickness / 2])
        cut.append(hole)
    if cut:
        disc = trimesh.boolean.difference([disc] + cut, engine="manifold")
    if pin:
        peg = trimesh.creation.cylinder(pin_diameter / 2, pin_height + 0.002, sections=48)
        peg.apply_translation([0.4 * bolt_circle / 2 + 0.006, 0.0, thickness + pin_height / 2 - 0.001])
        disc = trimesh.boolean.union([disc, peg], engine="manifold")
    return disc


@dataclass(frozen=True)
class MeshScene(Scene):
    """A simulated depth capture of a mesh target: per view a cloud (``clouds``, H x W x 3 float32
    in the camera frame, NaN without depth), the mesh (metres, in the target frame: ``Z`` is its
    pose), the depth scale and bias the camera has."""

    K: NDArray[np.float64] = None  # type: ignore[assignment]
    image_size: tuple[int, int] = (640, 480)
    mesh: object = None
    clouds: list = None  # type: ignore[assignment]
    depth_scale: float = 1.0
    depth_bias: float = 0.0
    #: with an arm: the joint angles the controller reports (rad), the arm's name, its nominal and real tables
    joints: NDArray[np.float64] | None = None
    arm: str | None = None
    chain: Chain | None = None
    chain_true: Chain | None = None


def ray_caster(mesh):
    """A ray caster on ``mesh`` (trimesh.Trimesh; Embree's when embreex is installed, else trimesh's own)."""
    trimesh = _trimesh()
    try:
        return importlib.import_module("trimesh.ray.ray_pyembree").RayMeshIntersector(mesh)
    except Exception:  # no embreex: trimesh's pure-Python caster (slower)
        return trimesh.ray.ray_triangle.RayMeshIntersector(mesh)


def cast_rays(caster, n_target_faces: int, rays_cam: NDArray[np.float64], cam2target: NDArray[np.float64]
              ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Per ray (camera frame, (P, 3)): the depth along it to the first hit (inf: none) and whether it hit the target."""
    origin = np.broadcast_to(cam2target[:3, 3], rays_cam.shape)
    direction = rays_cam @ cam2target[:3, :3].T
    loc, ray, tri = caster.intersects_location(origin, direction, multiple_hits=False)
    t = np.full(len(rays_cam), np.inf)
    hit_target = np.zeros(len(rays_cam), bool)
    t[ray] = np.einsum("mi,mi->m", loc - origin[ray], direction[ray]) / np.einsum("mi,mi->m", direction[ray], direction[ray])
    hit_target[ray] = tri < n_target_faces
    return t, hit_target


def framed_viewpoints(n_views: int, rng: np.random.Generator, K: NDArray[np.float64], image_size: tuple[int, int],
                      distance: tuple[float, float], tilt_max_deg: float, centre: NDArray[np.float64]) -> NDArray[np.float64]:
    """(n, 4, 4) cam2target: views of a shape about ``centre`` from ``distance`` (m) and within
    ``tilt_max_deg`` of its z axis, the shape anywhere in the middle two thirds of the image."""
    w, h = image_size
    cam2target = look_at_viewpoints(n_views, rng, distance=distance, tilt_max_deg=tilt_max_deg, aim_jitter=0.0,
                                    centre=centre)
    off = np.c_[rng.uniform(-w / 3, w / 3, n_views) / K[0, 0], rng.uniform(-h / 3, h / 3, n_views) / K[1, 1]]
    turn = Rotation.from_rotvec(np.c_[off[:, 1], -off[:, 0], np.zeros(n_views)]).as_matrix()
    cam2target[:, :3, :3] = cam2target[:, :3, :3] @ turn
    return cam2target


def mesh_scene(n_views: int = 15, setup: str = "eye_to_hand", rng: np.random.Generator | int | None = None, *,
               mesh=None, image_size: tuple[int, int] = (640, 480), depth_noise: tuple[float, float] = (1e-4, 5e-4),
               depth_scale: float = 1.002, depth_bias: float = 0.0, holes: float = 0.01,
               distance: tuple[float, float] = (0.6, 1.2), tilt_max_deg: float = 50.0,
               robot_error: tuple[float, float] | None = None, wrist: bool = True, translations: str | None = None,
               arm: str | None = None, length_mm: float = 0.5, angle_deg: float = 0.05, joint_noise_deg: float = 0.002
               ) -> MeshScene:
    """A depth camera's capture of ``mesh`` (trimesh, metres; default :func:`flange_mesh`): on the
    flange in front of a fixed camera (eye-to-hand) or fixed in the cell, seen by the camera on the
    flange (eye-in-hand).

    ``n_views`` views at ``distance`` (m) from the mesh's centre, from directions within
    ``tilt_max_deg`` of its z axis, the mesh anywhere in the middle two thirds of the image; behind it
    the wrist it is mounted on (``wrist``: a 70 mm rod along -z, 150 mm long) and a tilted wall
    0.2-0.4 m further. Noise, scale, bias and holes as :func:`~handeye.pipelines.depth.simulate_board.depth_scene`'s;
    the pixels on the mesh's outline are flying pixels; ``robot_error`` as there. ``translations``:
    the flange keeps the first view's orientation and moves up to 0.1 m along each axis (``'any'``:
    what a known placement of the shape makes enough), along the mesh's z axis only (``'axis'``:
    a disc's own axis, about which such a capture cannot turn X), or along one line but for the last
    view, 80 mm off it (``'line'``: one axis jogged, then one step aside). ``arm`` (a shipped arm's name): the
    views are the arm's at joint angles drawn about its home, its real table off the nominal one by
    ``length_mm`` / ``angle_deg`` per entry (:func:`~handeye.pipelines.depth.simulate_board.arm_views`), ``flange2base``
    its nominal table's poses at the joint angles it reports.
    """
    trimesh = _trimesh()
    setup = check_setup(setup)
    rng = np.random.default_rng(rng)
    mesh = flange_mesh() if mesh is None else mesh
    K = default_camera(image_size)[0]
    w, h = image_size
    centre = np.asarray(mesh.bounds, float).mean(axis=0)
    views = None
    if arm is not None:
        if translations is not None or robot_error is not None:
            raise HandEyeError("an arm's views are its joint angles: leave translations and robot_error out")
        points = np.asarray(mesh.vertices, float)[:: max(1, len(mesh.vertices) // 200)]
        views = arm_views(setup, points, K, image_size, n_views, rng, arm, length_mm, angle_deg, joint_noise_deg)
        # a board is seen from its -z side, the shape from its +z (the wrist behind it): turned over about
        # its x axis, in place (its points stay where the views were drawn to see them)
        over = np.diag([1.0, -1.0, -1.0, 1.0])
        scene = replace(views.scene, Z=views.scene.Z @ over, target2cam=views.scene.target2cam @ over)
        views = replace(views, scene=scene)
        cam2target = invert(scene.target2cam)
    else:
        cam2target = framed_viewpoints(n_views, rng, K, image_size, distance, tilt_max_deg, centre)
        scene = scene_from_viewpoints(cam2target, setup, rng)
    if translations is not None:
        F = np.repeat(scene.flange2base[:1], n_views, axis=0)
        if translations == "axis":
            F[:, :3, 3] += np.outer(rng.uniform(-0.1, 0.1, n_views), (F[0] @ scene.Z)[:3, 2])
        elif translations == "line":  # all but the last view on one line, as a user jogs one axis, then one step off it
            line = rng.normal(size=3)
            line /= np.linalg.norm(line)
            F[:-1, :3, 3] += np.outer(np.linspace(-0.1, 0.1, n_views - 1), line)
            off = np.cross(line, rng.normal(size=3))
            F[-1, :3, 3] += 0.08 * off / np.linalg.norm(off)
        else:
            F[:, :3, 3] += rng.uniform(-0.1, 0.1, (n_views, 3))
        scene = Scene(setup, scene.X, scene.Z, F, predicted_target2cam(scene.X, scene.Z, F, setup))
        cam2target = invert(scene.target2cam)
    parts = [mesh]
    if wrist:
        rod = trimesh.creation.cylinder(0.035, 0.15, sections=64)
        rod.apply_translation([0.0, 0.0, -0.075 - 1e-4])
        parts.append(rod)
    caster = ray_caster(trimesh.util.concatenate(parts))
    rays = pixel_rays(K, image_size).reshape(-1, 3)
    clouds = []
    for c2t in cam2target:
        t, on = cast_rays(caster, len(mesh.faces), rays, c2t)
        origin_cam = -c2t[:3, 3] @ c2t[:3, :3]  # the target's origin in the camera frame, and a wall behind it
        normal = -origin_cam / np.linalg.norm(origin_cam) + rng.normal(0.0, 0.3, 3)
        normal /= np.linalg.norm(normal)
        wall = origin_cam * (1.0 + rng.uniform(0.2, 0.4) / np.linalg.norm(origin_cam))
        with np.errstate(divide="ignore", invalid="ignore"):
            t_wall = (normal @ wall) / (rays @ normal)
        t_wall = np.where(t_wall > 0, t_wall, np.inf)
        depth = np.minimum(t, t_wall)
        truth = (rays * np.where(np.isfinite(depth), depth, np.nan)[:, None]).reshape(h, w, 3)
        behind = (rays * t_wall[:, None]).reshape(h, w, 3)
        mask = (on & (t < t_wall)).reshape(h, w)
        clouds.append(depth_reading(truth, mask, behind, rng, depth_scale, depth_bias, depth_noise, holes))
    return MeshScene(setup, scene.X, scene.Z, reported_poses(scene.flange2base, robot_error, rng), scene.target2cam, K=K,
                     image_size=tuple(image_size), mesh=mesh, clouds=clouds, depth_scale=depth_scale, depth_bias=depth_bias,
                     **arm_fields(views))


def write_clouds(folder: Path, clouds: list[NDArray[np.float64]], organized: bool = True) -> list[str]:
    """Write each cloud as ``clouds/viewNN.npy`` (float32, metres; ``organized``: the image grid with
    NaN holes, else the valid points alone), atomically; returns the files' names in order."""
    (folder / "clouds").mkdir(parents=True, exist_ok=True)
    names = [f"view{k + 1:02d}.npy" for k in range(len(clouds))]
    for name, cloud in zip(names, clouds):
        data = cloud if organized else cloud.reshape(-1, 3)[np.isfinite(cloud.reshape(-1, 3)).all(axis=1)]
        buf = io.BytesIO()
        np.save(buf, np.asarray(data, np.float32))
        atomic_write(folder / "clouds" / name, buf.getvalue())
    return names


def write_mesh_session(folder: str | Path, scene: MeshScene, *, mesh_unit: str = "mm", organized: bool = True,
                       known_pose: bool = False) -> Path:
    """Write a simulated mesh capture as a depth session: ``target.stl`` (in ``mesh_unit``),
    ``clouds/viewNN.npy`` (float32 metres: H x W x 3, or N x 3 of the points with depth when not
    ``organized``), ``poses.csv`` (quat_wxyz, mm, deg; first column ``cloud``), with an arm ``joints.csv``
    (the joint angles the controller reports, degrees, and a ``joints:`` block), ``session.yaml``
    (``target: {type: mesh, file: target.stl, unit: ...}``, with the mesh's true pose in the flange
    or base frame when ``known_pose``) and ``ground_truth.yaml``. Returns the folder."""
    out = check_output_folder(folder)
    names = write_clouds(out, scene.clouds, organized)
    mesh = scene.mesh.copy()
    mesh.apply_scale(1e3 if mesh_unit == "mm" else 1.0)
    atomic_write(out / "target.stl", mesh.export(file_type="stl"))
    write_pose_table(out / "poses.csv", names, scene.flange2base, "quat_wxyz", "mm", "deg", id_column="cloud")
    if scene.joints is not None:  # the joint angles the controller reports, degrees
        write_joint_table(out / "joints.csv", names, scene.joints, id_column="cloud")
    info = setup_info(scene.setup)
    target: dict = {"type": "mesh", "file": "target.stl", "unit": mesh_unit}
    if known_pose:  # a 4x4 with its translation in the mesh's unit
        Z = np.array(scene.Z, float)
        Z[:3, 3] *= 1e3 if mesh_unit == "mm" else 1.0
        target[info.z_name.replace("target2", "pose_in_")] = np.round(Z, 12).tolist()
    spec = {"setup": scene.setup, "target": target, "depth": {"unit": "m"},
            "poses": {"file": "poses.csv", "format": "quat_wxyz", "length_unit": "mm", "angle_unit": "deg"}}
    if scene.joints is not None:
        spec["joints"] = {"file": "joints.csv", "unit": "deg", "arm": scene.arm}
    atomic_write(out / "session.yaml", yaml.safe_dump(spec, sort_keys=False))
    truth = {"setup": scene.setup, info.x_name: scene.X.tolist(), info.z_name: scene.Z.tolist(),
             "depth_scale": float(scene.depth_scale), "depth_bias": float(scene.depth_bias)}
    if scene.chain_true is not None:
        truth |= {"arm": scene.arm, "table_true": scene.chain_true.table.tolist()}
    atomic_write(out / "ground_truth.yaml", yaml.safe_dump(truth, sort_keys=False))
    return out
