"""An arm's own shape: each link's mesh in its kinematic frame, posed at the joint angles.

Markerless calibration (no target: the camera sees the robot) matches the arm's meshes, placed by
the joint angles through the arm's table, to what the sensor saw (a depth camera's points, a colour
camera's silhouette). This module gives the meshes and their poses; the sensors that match them
live under :mod:`handeye.sensors`.

The meshes come from a maintained package on the package index, not from handeye's own data: the
Franka Emika Panda's (links 0-7, the hand and its two fingers) from ``rtb-data``, the Robotics
Toolbox for Python's data package, which ships Franka's collision meshes (STL, metres, each in its
link's frame: the frames of the modified DH table, ``handeye.robot.kinematics.load_arm("panda")``).
Install them with ``pip install 'handeye[markerless]'``.

Examples
--------
>>> import numpy as np
>>> from handeye.robot.kinematics import load_arm
>>> from handeye.robot.meshes import arm_meshes
>>> panda = load_arm("panda")
>>> meshes = arm_meshes("panda")
>>> q = np.radians([[0, -20, 0, -120, 0, 100, 45]])
>>> meshes.link2base(panda, q).shape
(1, 11, 4, 4)
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from ..errors import InputMismatchError, SessionError
from .kinematics import Chain, load_arm

__all__ = ["LinkMesh", "ArmMeshes", "arm_meshes", "meshes_for", "mesh_arm_names", "BASE", "FLANGE", "CORRECTED_M",
           "CORRECTED_RAD"]

#: A link's ``frame`` when it is fixed to the arm's base (link 0).
BASE = -1
#: A link's ``frame`` when it is fixed to the flange (a hand, a tool): the chain's flange frame.
FLANGE = -2


@dataclass(frozen=True)
class LinkMesh:
    """One rigid part of the arm.

    Attributes
    ----------
    name : str
    frame : int
        The kinematic frame it rides on: :data:`BASE`, ``k`` (0-based) for joint ``k + 1``'s frame
        after its rotation, or :data:`FLANGE`.
    link2frame : ndarray (4, 4)
        The mesh's coordinates in that frame.
    vertices : ndarray (V, 3)
        Metres, in the mesh's own coordinates.
    faces : ndarray (F, 3)
        Vertex indices of each triangle.
    """

    name: str
    frame: int
    link2frame: NDArray[np.float64] = field(repr=False)
    vertices: NDArray[np.float64] = field(repr=False)
    faces: NDArray[np.intp] = field(repr=False)


@dataclass(frozen=True)
class ArmMeshes:
    """An arm's links (:class:`LinkMesh`) and where they come from.

    Attributes
    ----------
    arm : str
        The arm's name, as :func:`handeye.robot.kinematics.load_arm` knows it.
    n_joints : int
        The joints its table must have.
    links : tuple of LinkMesh
    source : str
        The package and files the meshes were read from.
    """

    arm: str
    n_joints: int
    links: tuple[LinkMesh, ...]
    source: str

    def _check(self, chain: Chain) -> None:
        if chain.n_joints != self.n_joints:
            raise InputMismatchError(f"the {self.arm} meshes ride on a {self.n_joints}-joint arm; the arm given "
                                     f"({chain.name}) has {chain.n_joints} joints: give the joint angles of the arm "
                                     "whose meshes these are")

    def link2base(self, chain: Chain, joints: ArrayLike, deltas: ArrayLike | None = None) -> NDArray[np.float64]:
        """Each link's pose (N, L, 4, 4) in the base frame at joint angles ``joints`` (N, n), radians,
        the chain's table changed by ``deltas`` (n, 4) when given."""
        self._check(chain)
        q = np.asarray(joints, dtype=float)
        if q.ndim == 1:
            q = q[None]
        frames = chain.joint_frames(q, deltas)
        flange2base = frames[-1] @ chain.flange
        base = np.broadcast_to(chain.base, flange2base.shape)
        out = np.empty((len(q), len(self.links), 4, 4))
        for j, link in enumerate(self.links):
            frame2base = base if link.frame == BASE else flange2base if link.frame == FLANGE else frames[link.frame]
            out[:, j] = frame2base @ link.link2frame
        return out

    def merged(self) -> tuple[NDArray[np.float64], NDArray[np.intp], NDArray[np.intp]]:
        """All links as one mesh: vertices (V, 3) in their links' coordinates, faces (F, 3) indexing
        them, and each vertex's link (V,): pose it with :meth:`posed_vertices`."""
        offsets = np.cumsum([0] + [len(link.vertices) for link in self.links])
        vertices = np.concatenate([link.vertices for link in self.links])
        faces = np.concatenate([link.faces + o for link, o in zip(self.links, offsets[:-1])])
        owner = np.repeat(np.arange(len(self.links)), np.diff(offsets))
        return vertices, faces, owner

    def table_twists(self, chain: Chain, joints: ArrayLike, step: float = 1e-6) -> NDArray[np.float64]:
        """How every link moves per unit of each entry of the chain's table (E, N, L, 6; E the
        table's entries row by row, joint k's ``a``, ``alpha``, ``d``, ``theta``): a rotation ``w``
        and a translation ``v`` in the base frame, a point ``p`` of the link moving by ``w x p + v``
        per metre or radian of the entry (central differences of :meth:`link2base`)."""
        q = np.atleast_2d(np.asarray(joints, dtype=float))
        T0 = self.link2base(chain, q)
        out = np.empty((chain.table.size,) + T0.shape[:2] + (6,))
        for e in range(chain.table.size):
            d = np.zeros(chain.table.size)
            d[e] = step
            shape = chain.table.shape
            dT = (self.link2base(chain, q, d.reshape(shape)) - self.link2base(chain, q, -d.reshape(shape))) / (2 * step)
            W = dT[..., :3, :3] @ np.swapaxes(T0[..., :3, :3], -1, -2)  # skew(w) to first order
            w = 0.5 * np.stack([W[..., 2, 1] - W[..., 1, 2], W[..., 0, 2] - W[..., 2, 0], W[..., 1, 0] - W[..., 0, 1]], axis=-1)
            out[e] = np.concatenate([w, dT[..., :3, 3] - np.cross(w, T0[..., :3, 3])], axis=-1)
        return out

    def nearest_link(self, link2base: NDArray[np.float64], points: NDArray[np.float64]) -> NDArray[np.intp]:
        """The link (index into ``links``) each of ``points`` (M, 3, base frame) lies on, for one
        view's link poses ``link2base`` (L, 4, 4): the link of its nearest posed vertex."""
        vertices, _, owner = self.merged()
        posed = self.posed_vertices(np.asarray(link2base, float)[None])[0]
        return owner[cKDTree(posed).query(np.asarray(points, float))[1]]

    def posed_vertices(self, link2base: NDArray[np.float64]) -> NDArray[np.float64]:
        """The merged vertices (N, V, 3) in the base frame for poses ``link2base`` (N, L, 4, 4)
        from :meth:`link2base`."""
        vertices, _, owner = self.merged()
        T = link2base[:, owner]  # (N, V, 4, 4)
        return np.einsum("nvij,vj->nvi", T[..., :3, :3], vertices) + T[..., :3, 3]


def _trimesh():
    try:
        return importlib.import_module("trimesh")
    except ImportError:
        raise SessionError("an arm's meshes need trimesh and rtb-data: pip install 'handeye[markerless]'") from None


def _panda_folder() -> Path:
    try:
        folder = resources.files("rtbdata") / "meshes" / "FRANKA-EMIKA" / "Panda"
    except ModuleNotFoundError:
        raise SessionError("the Panda's meshes come from the rtb-data package, which is not installed: "
                           "pip install 'handeye[markerless]'") from None
    return Path(str(folder))


def _read(path: Path) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    if not path.is_file():
        raise SessionError(f"{path}: the arm's mesh is missing from its package; reinstall it "
                           "(pip install --force-reinstall rtb-data)")
    mesh = _trimesh().load(str(path), force="mesh", process=True)
    return np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, dtype=np.intp)


def _shift(x: float = 0.0, y: float = 0.0, z: float = 0.0, yaw: float = 0.0) -> NDArray[np.float64]:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, z], [0, 0, 0, 1.0]])


def _panda(hand: bool, finger_opening: float) -> ArmMeshes:
    folder = _panda_folder()
    links = [LinkMesh("link0", BASE, np.eye(4), *_read(folder / "link0.stl"))]
    links += [LinkMesh(f"link{k + 1}", k, np.eye(4), *_read(folder / f"link{k + 1}.stl")) for k in range(7)]
    if hand:
        # franka_description: the hand turned -45 deg about the flange's z; each finger 58.4 mm out
        # along the hand's z and half the opening along +-y, the right one turned half a turn
        hand2flange = _shift(yaw=-np.pi / 4)
        half = finger_opening / 2
        links.append(LinkMesh("hand", FLANGE, hand2flange, *_read(folder / "hand.stl")))
        finger = _read(folder / "finger.stl")
        links.append(LinkMesh("leftfinger", FLANGE, hand2flange @ _shift(0, half, 0.0584), *finger))
        links.append(LinkMesh("rightfinger", FLANGE, hand2flange @ _shift(0, -half, 0.0584, np.pi), *finger))
    return ArmMeshes("panda", 7, tuple(links), f"rtb-data: {folder}")


#: The arms whose meshes handeye can load, each a function of (hand, finger_opening).
_MESH_ARMS = {"panda": _panda}


def mesh_arm_names() -> list[str]:
    """The arms :func:`arm_meshes` knows."""
    return sorted(_MESH_ARMS)


def arm_meshes(name: str, hand: bool = True, finger_opening: float = 0.0) -> ArmMeshes:
    """An arm's link meshes by name (case-insensitive; :func:`mesh_arm_names`).

    Parameters
    ----------
    name : str
        The arm, as :func:`handeye.robot.kinematics.load_arm` names it ("panda").
    hand : bool
        With the maker's gripper on the flange (the Franka Hand), as it is in most captures.
    finger_opening : float
        The gap between the fingers (m), the sum of the two finger joints.

    Raises
    ------
    InputMismatchError
        An arm whose meshes handeye cannot load.
    SessionError
        The package with the meshes is not installed.
    """
    key = str(name).lower().replace("-", "").replace("_", "")
    if key not in _MESH_ARMS:
        raise InputMismatchError(f"handeye has no meshes of the arm {name!r}; it has those of: {', '.join(mesh_arm_names())}")
    if not 0.0 <= finger_opening <= 0.08:
        raise InputMismatchError(f"finger opening {finger_opening} m: the Franka Hand opens 0 to 0.08 m (give metres)")
    return _MESH_ARMS[key](hand, float(finger_opening))


#: A table is a corrected one of a shipped arm's (its meshes ride on it) when no length differs by
#: more than this (m) and no angle by more than :data:`CORRECTED_RAD`: a calibration's corrections
#: are a few millimetres and tenths of a degree, another arm's table differs by centimetres.
CORRECTED_M = 0.01
CORRECTED_RAD = float(np.radians(1.0))


def _close(chain: Chain, shipped: Chain) -> bool:
    """Whether ``chain`` is ``shipped``'s table, or one corrected from it (:data:`CORRECTED_M`)."""
    if chain.n_joints != shipped.n_joints or chain.convention != shipped.convention:
        return False
    gap = np.abs(chain.table - shipped.table)
    lengths, angles = gap[:, [0, 2]], gap[:, [1, 3]]
    frames = np.abs(chain.base - shipped.base)[:3], np.abs(chain.flange - shipped.flange)[:3]
    return bool(lengths.max() <= CORRECTED_M and angles.max() <= CORRECTED_RAD
                and all(f[:, 3].max() <= CORRECTED_M and f[:, :3].max() <= CORRECTED_RAD for f in frames))


def meshes_for(chain: Chain, hand: bool = True, finger_opening: float = 0.0) -> ArmMeshes:
    """The meshes of the arm whose table ``chain`` is: a shipped arm's, by its table (the shipped
    one, or one a calibration corrected from it, ``arm_corrected.yaml``: the links ride on the same
    frames), not by its name.

    Raises
    ------
    InputMismatchError
        No arm handeye has meshes of has that table (another arm's, a URDF's frames).
    """
    for name in mesh_arm_names():
        if _close(chain, load_arm(name)):
            return arm_meshes(name, hand, finger_opening)
    raise InputMismatchError(f"the arm's table ({chain.name}, {chain.n_joints} joints, {chain.convention}) is not one handeye "
                             f"has meshes for ({', '.join(mesh_arm_names())}: the shipped table, or one calibrated from it "
                             f"within {1e3 * CORRECTED_M:g} mm / {np.degrees(CORRECTED_RAD):g} deg): the links would be placed "
                             "wrong; name the arm (joints: arm: panda) or give its corrected table")
