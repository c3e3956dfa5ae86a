"""Depth-camera session folders read and checked: ``session.yaml`` with a ``depth:`` mapping, the
clouds in ``clouds/`` (and a board's intensity images in ``images/``), the robot poses; nothing is
measured here (:mod:`handeye.pipelines.depth.pipeline` does that).
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..._shared.text import cut, shown
from ...errors import SessionError
from ...frames.poses import RobotPoseInput
from ...frames.setups import check_setup, setup_info
from ...geometry.se3 import make_transform
from ...io.extras import cloud_extras, mesh_extras, needed
from ...io.session import (
    CAMERA_KEYS,
    IMAGE_ORDER,
    JOINTS_KEYS,
    POSES_KEYS,
    check_session_keys,
    files_of_views,
    joints_of_views,
    read_camera,
    read_joints,
    read_robot_poses,
    read_session_yaml,
    read_unknowns,
    session_file,
)
from ...robot.kinematics import Chain
from ...sensors.camera import target_from_spec
from ...sensors.depth.clouds import CLOUD_SUFFIXES

__all__ = ["DepthSession", "MeshTarget", "ArmTarget", "SceneTarget", "load_depth_session", "rig_depth", "arm_hand",
           "ARM_KEYS", "RIG_DEPTH_KEYS",
           "extras", "rig_extras"]

#: What the pose table's first column must be, for the error that finds it is not.
FIRST_COLUMN = ("'image' (a board: its intensity image in images/, the cloud of the same name in clouds/) or 'cloud' "
                "(spheres, a mesh, a scene: the cloud in clouds/)")


@dataclass(frozen=True)
class DepthSession:
    """A depth session's inputs, read and checked (no cloud read yet)."""

    folder: Path
    setup: str
    target_spec: dict[str, Any]
    names: list[str]  #: per view: the image's (boards) or the cloud's (spheres) file name
    cloud_paths: list[Path]
    image_paths: list[Path] | None  #: boards only
    flange2base: NDArray[np.float64]
    K: NDArray[np.float64] | None
    dist: NDArray[np.float64] | None
    unit: str
    working_range: tuple[float, float] | None
    radii: list[float] | None  #: spheres only, metres
    notes: list[str] = field(default_factory=list)
    #: a ``joints:`` table: each view's joint angles (rad) and the arm; ``flange2base`` then holds the
    #: controller's poses when given, else the nominal table's
    joints: NDArray[np.float64] | None = None
    arm: Chain | None = None
    joints_path: Path | None = None
    #: a mesh target (``type: mesh``): its file, unit and, when the session gives it, its placement
    #: (Z: target2flange eye-to-hand, target2base eye-in-hand, metres)
    mesh: MeshTarget | None = None
    #: the arm itself as the target (``type: arm``): its hand and fingers; the joint angles pose it
    arm_target: ArmTarget | None = None
    #: the pose table's rows as written, with their declaration (None without a pose table)
    pose_input: RobotPoseInput | None = None
    unknowns: dict[str, str] = field(default_factory=dict)  #: session.yaml's ``unknowns:`` (hold, free or auto by name)
    #: whatever the camera sees as the target (``type: scene``): no target, no mesh
    scene: SceneTarget | None = None

    @property
    def kind(self) -> str:
        """What the clouds hold: 'spheres', 'mesh', 'arm', 'scene' or 'board'."""
        if self.radii is not None:
            return "spheres"
        if self.scene is not None:
            return "scene"
        return "mesh" if self.mesh is not None else "arm" if self.arm_target is not None else "board"


@dataclass(frozen=True)
class MeshTarget:
    """A known shape as the target (``target: {type: mesh, file: ..., unit: mm}``): the mesh or
    template cloud's file, its unit, and the shape's placement Z (metres) when the session gives it
    (``pose_in_flange`` eye-to-hand, ``pose_in_base`` eye-in-hand)."""

    file: Path
    unit: str
    placement: NDArray[np.float64] | None = None


@dataclass(frozen=True)
class ArmTarget:
    """The arm itself as the target (``target: {type: arm}``, markerless): whether its maker's hand
    is on the flange (``hand``, default true) and the gap between its fingers (``finger_opening``,
    metres, default 0). The arm, its meshes and each cloud's joint angles come from ``joints:``."""

    hand: bool = True
    finger_opening: float = 0.0


@dataclass(frozen=True)
class SceneTarget:
    """Whatever the camera sees as the target (``target: {type: scene}``): no board, no mesh; X from
    the views' clouds agreeing through the robot (:mod:`handeye.pipelines.depth.scene`). ``fit_depth``
    (``depth_scale: fit``): the depth's scale and bias fitted with X, else held at 1 and 0."""

    fit_depth: bool = False


#: The keys of a scene target.
SCENE_KEYS = ("type", "depth_scale")


def _scene(target: Any, where: str) -> SceneTarget | None:
    """The scene target of ``target`` (None for another type), checked: its keys, the depth's scale
    held (``depth_scale: hold``, the default) or fitted (``depth_scale: fit``)."""
    if not isinstance(target, dict) or str(target.get("type", "")).lower() != "scene":
        return None
    unknown = sorted(set(target) - set(SCENE_KEYS))
    if unknown:
        raise SessionError(f"{where}: target: unknown key(s) {', '.join(unknown)} for a scene (keys: {', '.join(SCENE_KEYS)}; "
                           "a scene needs nothing else: its clouds and the robot's poses are the calibration)")
    depth = str(target.get("depth_scale", "hold")).lower()
    if depth not in ("hold", "fit"):
        raise SessionError(f"{where}: target: depth_scale is hold (1 and 0, the default) or fit (the depth's scale and "
                           f"bias fitted with X), got {target.get('depth_scale')!r}")
    return SceneTarget(depth == "fit")


#: The keys of an arm target.
ARM_KEYS = ("type", "hand", "finger_opening")


def _arm_target(target: Any, setup: str, spec: dict, where: str) -> ArmTarget | None:
    """The arm target of ``target`` (None for another type), checked: its keys, a camera fixed in
    the cell (eye_to_hand), a ``joints:`` table to pose the arm by."""
    if not isinstance(target, dict) or str(target.get("type", "")).lower() != "arm":
        return None
    unknown = sorted(set(target) - set(ARM_KEYS))
    if unknown:
        raise SessionError(f"{where}: target: unknown key(s) {', '.join(unknown)}{_did_you_mean(unknown, ARM_KEYS)} for the "
                           f"arm (keys: {', '.join(ARM_KEYS)})")
    if setup_info(setup).camera_on_flange:
        raise SessionError(f"{where}: target: arm is the arm seen by a depth camera fixed in the cell: setup: eye_to_hand "
                           f"(got {setup})")
    if not spec.get("joints"):
        raise SessionError(f"{where}: target: arm needs each cloud's joint angles: joints: {{file: joints.csv, unit: deg, "
                           "arm: panda}} (the first column 'cloud')")
    return ArmTarget(*arm_hand(target, where))


def arm_hand(target: dict, where: str) -> tuple[bool, float]:
    """The arm's hand of a target that is the arm itself (a depth camera's ``type: arm``, a
    silhouette session's ``type: robot``): whether the maker's hand is on the flange (``hand``,
    default true) and the gap between its fingers (``finger_opening``, metres, default 0), checked."""
    hand = target.get("hand", True)
    if not isinstance(hand, bool):
        raise SessionError(f"{where}: target: hand is true (the maker's gripper on the flange) or false, got {shown(hand)}")
    try:
        opening = float(target.get("finger_opening", 0.0))
    except (TypeError, ValueError):
        opening = float("nan")
    if not 0.0 <= opening <= 0.1:
        raise SessionError(f"{where}: target: finger_opening is the gap between the fingers in metres (0 to 0.08 for the "
                           f"Franka Hand), got {shown(target.get('finger_opening'))}")
    return hand, opening


def _did_you_mean(unknown: list[str], known: tuple[str, ...]) -> str:
    """`` (did you mean 'unit'?)`` for the known keys nearest to ``unknown`` ones (a typo), as the
    other session keys' messages have it; empty when none is near."""
    near = [m[0] for m in (difflib.get_close_matches(str(u), known, n=1, cutoff=0.5) for u in unknown) if m]
    return f" (did you mean {', '.join(repr(n) for n in dict.fromkeys(near))}?)" if near else ""


#: The keys of a mesh target (besides the placement's, ``pose_in_flange`` or ``pose_in_base``).
MESH_KEYS = ("type", "file", "unit")


def _placement(value: Any, unit: str, where: str) -> NDArray[np.float64]:
    """A placement as a 4x4 matrix (its translation in the mesh's ``unit``) or ``[x, y, z, rx, ry, rz]``
    (``unit``; a rotation vector in degrees), in metres."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        a = np.zeros(0)
    factor = 1e-3 if unit == "mm" else 1.0
    if a.shape == (6,) and np.isfinite(a).all():
        return make_transform(Rotation.from_rotvec(np.radians(a[3:])).as_matrix(), a[:3] * factor)
    if a.shape == (4, 4) and np.isfinite(a).all() and np.allclose(a[:3, :3] @ a[:3, :3].T, np.eye(3), atol=1e-6) \
            and np.allclose(a[3], [0, 0, 0, 1]):
        return make_transform(a[:3, :3], a[:3, 3] * factor)
    raise SessionError(f"{where}: the shape's placement is a 4x4 rigid transform or [x, y, z, rx, ry, rz] (translation in "
                       f"the mesh's unit {unit}, rotation vector in degrees), got {shown(value)}")


def _mesh(target: Any, folder: Path, setup: str, where: str) -> MeshTarget | None:
    """The mesh target of ``target`` (None for another type), checked: its keys, its file, its unit
    and placement (the one the setup's Z is: ``pose_in_flange`` eye-to-hand, ``pose_in_base`` eye-in-hand)."""
    if not isinstance(target, dict) or str(target.get("type", "")).lower() != "mesh":
        return None
    key = "pose_in_" + setup_info(setup).z_name.split("2", 1)[1]
    other = {"pose_in_flange", "pose_in_base"} - {key}
    unknown = sorted(set(target) - set(MESH_KEYS) - {key})
    if unknown:
        hint = f" ({', '.join(other)} is the other setup's: with setup {setup} the shape's placement is {key})" \
            if set(unknown) & other else ""
        raise SessionError(f"{where}: target: unknown key(s) {', '.join(unknown)}"
                           f"{_did_you_mean(sorted(set(unknown) - other), MESH_KEYS + (key,))} for a mesh (keys: "
                           f"{', '.join(MESH_KEYS + (key,))}){hint}")
    if not target.get("file"):
        raise SessionError(f"{where}: target: a mesh needs its file (file: flange.stl, beside session.yaml)")
    unit = str(target.get("unit", ""))
    if unit not in ("m", "mm"):
        raise SessionError(f"{where}: target: a mesh's unit is m or mm (the unit its file's coordinates are in), got "
                           f"{shown(target.get('unit'))}")
    path = session_file(folder, folder / str(target["file"]), "the mesh file")
    if not path.is_file():
        raise SessionError(f"{where}: target: no mesh file {path}")
    placement = None if target.get(key) is None else _placement(target[key], unit, f"{where}: target: {key}")
    return MeshTarget(path, unit, placement)



def _radii(target: Any, where: str) -> list[float] | None:
    if not isinstance(target, dict) or str(target.get("type", "")).lower() != "sphere":
        return None
    d = target.get("diameter", target.get("diameters"))
    values = np.atleast_1d(np.asarray(d, dtype=float)) if d is not None else np.array([])
    if len(values) == 0 or not np.isfinite(values).all() or np.any(values <= 0):
        raise SessionError(f"{where}: target: a sphere needs its diameter (metres; several: a list), got {shown(d)}")
    if np.any(values > 1.0):
        raise SessionError(f"{where}: target: sphere diameter {values.max():g} m: give it in metres (e.g. 0.05)")
    if len(values) > 1 and np.min(np.diff(np.sort(values))) < 0.005:
        raise SessionError(f"{where}: target: spheres are told apart by their diameters; {values.tolist()} differ by "
                           "less than 5 mm: use balls of clearly different sizes")
    return (values / 2).tolist()


def _depth_spec(spec: Any, where: str) -> tuple[str, tuple[float, float] | None]:
    if not isinstance(spec, dict):
        raise SessionError(f"{where}: depth must be a mapping (unit: m | mm, range: [near, far] in metres)")
    unit = str(spec.get("unit", "m"))
    if unit not in ("m", "mm"):
        raise SessionError(f"{where}: depth: unit is m or mm, not {shown(unit)}")
    rng = spec.get("range")
    if rng is None:
        return unit, None
    try:
        lo, hi = (float(v) for v in rng)
    except (TypeError, ValueError):
        raise SessionError(f"{where}: depth: range is [near, far] in metres, got {shown(rng)}") from None
    if not 0 <= lo < hi or hi > 50:
        raise SessionError(f"{where}: depth: range [near, far] must be metres with near < far, got {shown(rng)}")
    return unit, (lo, hi)


def _clouds_of(folder: Path, names: list[str], table: Path) -> list[Path]:
    """Per view the cloud in ``clouds/`` named ``name`` (spheres) or with the image's stem (boards)."""
    clouds = folder / "clouds"
    out = []
    for found, name in zip(files_of_views(clouds, names, CLOUD_SUFFIXES, folder), names):
        if found is None:
            raise SessionError(f"{table}: no cloud for {shown(name)} in {clouds} (expected {Path(name).stem}.npy, .ply or .pcd)")
        out.append(found)
    return out


def load_depth_session(folder: str | Path, arm: str | None = None) -> DepthSession:
    """Read and check a depth session folder (the module's docstring); nothing is measured yet.

    A ``joints:`` table (as for image sessions: ``file``, ``unit``, ``arm``; its first column
    ``image`` or ``cloud``) gives each view's joint angles: the calibration then fits the arm's table
    with X; ``arm`` (``--arm``) overrides the table's arm. Without ``poses:`` the flange poses are
    the nominal table's. ``target: {type: arm}`` (:class:`ArmTarget`): the arm itself is the target
    (markerless, eye_to_hand only); the ``joints:`` table is then required: it poses the arm's meshes.

    Raises :class:`SessionError` naming the file: no ``depth:`` mapping, a bad target, a missing
    pose table, image or cloud, a pose table whose first column is neither ``image`` nor ``cloud``.
    """
    folder, spec, where, notes = read_session_yaml(folder)
    if spec.get("depth") is None:
        raise SessionError(f"{where}: no depth: mapping; a depth session says its clouds' unit there")
    check_session_keys(spec, ("setup", "target", "camera", "depth", "poses", "joints", "unknowns"),
                       {"depth": ("unit", "range"), "poses": POSES_KEYS, "camera": CAMERA_KEYS, "joints": JOINTS_KEYS}, where)
    setup = check_setup(str(spec.get("setup", "")))
    target = spec.get("target")
    radii = _radii(target, where)
    mesh = _mesh(target, folder, setup, where)
    arm_target = _arm_target(target, setup, spec, where)
    scene = _scene(target, where)
    board = radii is None and mesh is None and arm_target is None and scene is None
    if board:
        target_from_spec(target, where=f"{where}: target")
    unit, working = _depth_spec(spec["depth"], where)
    K, dist = read_camera(spec.get("camera"), where)
    joints = read_joints(folder, spec["joints"], where, notes, arm, ("image", "cloud")) if spec.get("joints") else None
    posed = not (spec.get("poses") is None and joints is not None)
    if not posed:  # joint angles alone: the nominal table's flange poses
        names, table, f2b, pose_input = joints[0], joints[3], joints[2].forward(joints[1]), None
    else:
        f2b, names, table, pose_input = read_robot_poses(folder, spec.get("poses"), where, notes, ("image", "cloud"),
                                                         FIRST_COLUMN)
    q = None if joints is None else joints_of_views(joints, names, f2b if posed else None, notes)
    clouds = _clouds_of(folder, names, table)
    images = None
    if board:
        images = [session_file(folder, folder / "images" / n, f"the image of {shown(n)}") for n in names]
        missing = [str(p.name) for p in images if not p.is_file()]
        if missing:
            raise SessionError(f"{folder / 'images'}: image file(s) missing: {', '.join(missing[:10])}")
    return DepthSession(folder, setup, dict(target), list(names), clouds, images, f2b, K, dist, unit, working, radii, notes,
                        None if joints is None else q, None if joints is None else joints[2],
                        None if joints is None else joints[3], mesh, arm_target, pose_input, read_unknowns(spec, where),
                        scene)


#: The keys of a rig's depth camera (:mod:`handeye.pipelines.rig.session`).
RIG_DEPTH_KEYS = ("depth", "camera", "clouds", "images", "target")


def _files_of(root: Path, folder: Path, names: list[str], suffixes) -> list[Path]:
    """Per view its file in ``folder`` (inside the session folder ``root``) with one of ``suffixes``;
    a path that does not exist when there is none (a view the sensor missed)."""
    return [found or folder / (name + suffixes[0]) for found, name in zip(files_of_views(folder, names, suffixes, root), names)]


def rig_depth(folder: Path, setup: str, names: list[str], flange2base: NDArray[np.float64], block: dict, name: str,
              target: Any, where: str) -> DepthSession:
    """A rig's depth camera (:mod:`handeye.pipelines.rig.session`) as a depth session over the rig's views
    ``names``: its ``depth:`` mapping (unit, range), the intensity image's ``camera:`` (K, dist;
    optional), its folder of ``clouds`` and, for a board, of intensity ``images``, both named by view
    (``v01.npy`` and ``v01.png``; default the sensor's name, one folder for both) and its ``target``
    (a board or spheres; default the session's). A view with no cloud (or, for a board, no image) is
    one it did not see. Raises :class:`SessionError` naming the key."""
    unit, working = _depth_spec(block.get("depth"), where)
    radii = _radii(target, where)
    if isinstance(target, dict) and str(target.get("type", "")).lower() in ("mesh", "arm", "scene"):
        raise SessionError(f"{where}: target: a {cut(str(target['type']), 40)} target is not taken in a rig yet: calibrate that depth "
                           "camera in a depth session of its own (a board or spheres are taken here)")
    if radii is None:
        target_from_spec(target, where=f"{where}: target")
    K, dist = read_camera(block.get("camera"), where)
    clouds = folder / str(block.get("clouds", name))
    images = folder / str(block.get("images", block.get("clouds", name)))
    for sub, what in [(clouds, "clouds")] + ([] if radii is not None else [(images, "intensity images")]):
        session_file(folder, sub, f"its {what}' folder")
        if not sub.is_dir():
            raise SessionError(f"{where}: no folder {sub} (its {what}, named by view: v01{'.npy' if what == 'clouds' else '.png'}, ...)")
    cloud_paths = _files_of(folder, clouds, names, CLOUD_SUFFIXES)
    image_paths = None if radii is not None else _files_of(folder, images, names, IMAGE_ORDER)
    return DepthSession(folder, setup, dict(target or {}), list(names), cloud_paths, image_paths, flange2base, K, dist, unit,
                        working, radii)


def extras(spec: dict[str, Any], folder: Path, needs: dict[str, dict[str, str]]) -> None:
    """The optional extras a depth session needs (its registration's ``extras`` hook): its mesh
    target's reader, the arm's meshes when the arm itself is the target, its clouds' readers."""
    target = spec.get("target") if isinstance(spec.get("target"), dict) else {}
    kind = str(target.get("type", ""))
    if kind == "mesh":
        mesh_extras(target, needs)
    elif kind == "arm":
        needed("markerless", "the arm itself as the target (its link meshes)", needs)
    cloud_extras(folder / "clouds", "clouds/", needs)


def rig_extras(block: dict[str, Any], name: str, folder: Path, needs: dict[str, dict[str, str]]) -> None:
    """The optional extras a rig's depth camera needs: its clouds' readers (``block``: its block under ``sensors:``)."""
    clouds = block.get("clouds", name)
    cloud_extras(folder / str(clouds), f"{clouds}/ (sensor {name})", needs)
