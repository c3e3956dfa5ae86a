"""URDF in and out: a serial arm's kinematics read from a URDF into a :class:`~handeye.robot.kinematics.Chain`,
and a chain written as a URDF.

Reading uses yourdfpy (``pip install 'handeye[urdf]'``): a maintained, pure-Python URDF parser
that needs no ROS install and loads no meshes here. The chain from the base link to the tip link
(by default ``tool0``, ``flange`` or the last link after the last revolute joint) becomes Craig's
modified Denavit-Hartenberg table (each joint's axis and the common normals between consecutive
axes), with the base link's transform to the first joint and the tip link's from the last kept
whole, so that the chain's forward kinematics equal the URDF's to rounding (1e-12 m on common
arms). Fixed joints along the chain fold into those transforms; prismatic joints are refused.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..errors import InputMismatchError
from .kinematics import Chain

__all__ = ["chain_from_urdf", "chain_urdf", "TIP_LINKS"]

#: The tip link taken when none is named, the first found: ROS-Industrial's and Franka's names.
TIP_LINKS = ("tool0", "flange", "panda_link8", "fr3_link8")


def _load(path: Path):
    """The URDF read by yourdfpy (no meshes, no scene graph), or a one-line error."""
    try:
        import yourdfpy  # noqa: PLC0415  (an optional extra)
    except ImportError:
        raise InputMismatchError(f"{path}: reading a URDF needs yourdfpy: pip install 'handeye[urdf]'") from None
    if not path.is_file():
        raise InputMismatchError(f"{path}: no such URDF file")
    try:
        return yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False, load_collision_meshes=False)
    except Exception as exc:  # lxml and yourdfpy raise many kinds: one line naming the file
        raise InputMismatchError(f"{path}: not a readable URDF ({type(exc).__name__}: {exc})") from None


def _rot(axis: str, angle: float) -> NDArray[np.float64]:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler(axis, angle).as_matrix()
    return T


def _shift(axis: int, length: float) -> NDArray[np.float64]:
    T = np.eye(4)
    T[axis, 3] = length
    return T


def _serial_joints(robot, base: str, tip: str, path: Path) -> list:
    """The joints from ``base`` to ``tip``, in order (each link has one parent joint in a URDF)."""
    by_child = {j.child: j for j in robot.robot.joints}
    joints, link = [], tip
    while link != base:
        if link not in by_child:
            raise InputMismatchError(f"{path}: link {tip!r} does not descend from {base!r}")
        joints.append(by_child[link])
        link = by_child[link].parent
    return joints[::-1]


def _default_tip(robot, base: str) -> str:
    links = {link.name for link in robot.robot.links}
    for name in TIP_LINKS:
        if name in links:
            return name
    # the link after the last revolute joint of the longest chain from the base
    children: dict[str, list] = {}
    for j in robot.robot.joints:
        children.setdefault(j.parent, []).append(j)
    best, stack = (0, base), [(base, 0)]
    while stack:
        link, n = stack.pop()
        for j in children.get(link, []):
            m = n + (j.type in ("revolute", "continuous"))
            if j.type in ("revolute", "continuous") and m > best[0]:
                best = (m, j.child)
            stack.append((j.child, m))
    return best[1]


def chain_from_urdf(path: str | Path, base_link: str | None = None, tip_link: str | None = None) -> Chain:
    """A serial arm's :class:`~handeye.robot.kinematics.Chain` from a URDF file.

    Parameters
    ----------
    path : path
        The URDF (plain XML; expand a xacro first: ``xacro robot.urdf.xacro > robot.urdf``).
    base_link, tip_link : str, optional
        The chain's ends: by default the URDF's root link, and the first of :data:`TIP_LINKS`
        present (else the link after the last revolute joint).

    Returns
    -------
    Chain
        Modified DH (one row per revolute joint, in the chain's order, ``joint_names`` the URDF's),
        with ``base`` and ``flange`` so that its forward kinematics equal the URDF's.

    Raises
    ------
    InputMismatchError
        No yourdfpy, an unreadable file, links not on one chain, prismatic joints, no revolute joint.
    """
    path = Path(path)
    robot = _load(path)
    children = {j.child for j in robot.robot.joints}
    roots = [link.name for link in robot.robot.links if link.name not in children]
    base = base_link or (roots[0] if roots else "")
    tip = tip_link or _default_tip(robot, base)
    links = {link.name for link in robot.robot.links}
    for name, what in ((base, "base_link"), (tip, "tip_link")):
        if name not in links:
            raise InputMismatchError(f"{path}: no link {name!r} ({what}); its links: {', '.join(sorted(links))}")
    frames, axes, names, limits = [], [], [], []
    T = np.eye(4)
    for j in _serial_joints(robot, base, tip, path):
        T = T @ (np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=float))
        if j.type in ("revolute", "continuous"):
            axis = np.asarray(j.axis if j.axis is not None else [1.0, 0.0, 0.0], dtype=float)
            frames.append(T.copy())
            axes.append(T[:3, :3] @ (axis / np.linalg.norm(axis)))
            names.append(j.name)
            lim = getattr(j, "limit", None)
            lower, upper = (getattr(lim, "lower", None), getattr(lim, "upper", None)) if lim is not None else (None, None)
            limits.append([-np.inf if lower is None or j.type == "continuous" else float(lower),
                           np.inf if upper is None or j.type == "continuous" else float(upper)])
        elif j.type != "fixed":
            raise InputMismatchError(f"{path}: joint {j.name!r} is {j.type}; handeye's chains take revolute joints "
                                     "(and fixed ones between them)")
    if not frames:
        raise InputMismatchError(f"{path}: no revolute joint between {base!r} and {tip!r}")
    points = [F[:3, 3] for F in frames]
    dh_frames = _mdh_frames(points, axes)
    table = np.array([_mdh_row(dh_frames[k - 1] if k else dh_frames[0], dh_frames[k]) if k else [0.0, 0.0, 0.0, 0.0]
                      for k in range(len(dh_frames))])
    chain = Chain(name=robot.robot.name or path.stem, convention="mdh", table=table,
                  flange=np.linalg.inv(dh_frames[-1]) @ T, source=f"URDF {path.name} ({base} to {tip})",
                  base=dh_frames[0], joint_names=tuple(names), limits=np.array(limits))
    _check_same(chain, frames, axes, T, path)
    return chain


def _mdh_frames(points: list, axes: list) -> list[NDArray[np.float64]]:
    """Per joint the modified-DH frame at zero joint angles: z along the joint's axis, x along the
    common normal to the next axis (the last one's x continues the one before), origin where that
    normal leaves the axis."""
    n = len(axes)
    frames: list[NDArray[np.float64]] = []
    x_prev = None
    for k in range(n):
        z = axes[k]
        if k + 1 < n:
            z2, p, p2 = axes[k + 1], points[k], points[k + 1]
            cross = np.cross(z, z2)
            if np.linalg.norm(cross) > 1e-9:  # skew or intersecting: the common perpendicular
                w = p2 - p
                # closest points p + s z and p2 + u z2
                A = np.array([[z @ z, -(z @ z2)], [z @ z2, -(z2 @ z2)]])
                s, u = np.linalg.solve(A, [w @ z, w @ z2])
                origin, to = p + s * z, p2 + u * z2
                x = to - origin
                x = cross / np.linalg.norm(cross) if np.linalg.norm(x) < 1e-9 else x / np.linalg.norm(x)
            else:  # parallel: the normal through the previous frame's origin height on this axis
                base_pt = p if not frames else frames[-1][:3, 3]
                origin = p + ((base_pt - p) @ z) * z
                d = (p2 - origin) - ((p2 - origin) @ z) * z
                if np.linalg.norm(d) > 1e-9:
                    x = d / np.linalg.norm(d)
                else:  # the same line: any x normal to it
                    x = _normal_to(z, x_prev)
        else:
            origin = points[k]
            x = _normal_to(z, x_prev)
        F = np.eye(4)
        F[:3, 0], F[:3, 1], F[:3, 2], F[:3, 3] = x, np.cross(z, x), z, origin
        frames.append(F)
        x_prev = x
    return frames


def _normal_to(z: NDArray[np.float64], hint: NDArray[np.float64] | None) -> NDArray[np.float64]:
    """A unit vector normal to ``z``: ``hint`` made normal when it can be, else any."""
    for v in ([hint] if hint is not None else []) + [np.array([1.0, 0, 0]), np.array([0, 1.0, 0])]:
        x = v - (v @ z) * z
        if np.linalg.norm(x) > 1e-6:
            return x / np.linalg.norm(x)
    raise AssertionError("no normal")  # unreachable: two independent candidates


def _mdh_row(F_prev: NDArray[np.float64], F: NDArray[np.float64]) -> list[float]:
    """``a, alpha, d, theta`` with ``F = F_prev Rx(alpha) Tx(a) Rz(theta) Tz(d)``."""
    T = np.linalg.inv(F_prev) @ F
    alpha = np.arctan2(-T[1, 2], T[2, 2])
    theta = np.arctan2(-T[0, 1], T[0, 0])
    a = T[0, 3]
    d = T[2, 3] * np.cos(alpha) - T[1, 3] * np.sin(alpha)
    return [float(a), float(alpha), float(d), float(theta)]


def _check_same(chain: Chain, frames, axes, tip, path: Path) -> None:
    """The chain's forward kinematics equal the URDF's at random joint angles (composed here from
    the joints' origins and axes), else an error: a construction the table cannot hold."""
    rng = np.random.default_rng(0)
    q = rng.uniform(-np.pi, np.pi, (5, len(frames)))
    ours = chain.forward(q)
    # the URDF's: each joint's rotation about its axis, at its frame, applied in order
    relative = [np.linalg.inv(frames[k - 1]) @ frames[k] if k else frames[0] for k in range(len(frames))]
    local_axes = [frames[k][:3, :3].T @ axes[k] for k in range(len(frames))]
    for i in range(len(q)):
        T = np.eye(4)
        for k in range(len(frames)):
            R = np.eye(4)
            R[:3, :3] = Rotation.from_rotvec(q[i, k] * local_axes[k]).as_matrix()
            T = T @ relative[k] @ R
        T = T @ np.linalg.inv(frames[-1]) @ tip
        if np.abs(T - ours[i]).max() > 1e-9:
            raise InputMismatchError(f"{path}: its chain could not be expressed as a DH table "
                                     f"({np.abs(T - ours[i]).max():.2g} apart); please report it")


def chain_urdf(chain: Chain, base_link: str = "base_link", tip_link: str = "tool0") -> str:
    """``chain`` as a URDF (links ``base_link``, ``link1`` ... ``link<n>``, ``tip_link``; revolute
    joints ``joint1`` ... or the chain's ``joint_names``) whose forward kinematics equal the chain's;
    full precision, no geometry. :func:`chain_from_urdf` reads it back."""
    names = list(chain.joint_names or [f"joint{k + 1}" for k in range(chain.n_joints)])
    fixed_before, fixed_after = [], []
    for a, alpha, d, theta in chain.table:
        if chain.convention == "mdh":  # Rx(alpha) Tx(a) Rz(theta) Tz(d), then the joint's Rz(q)
            fixed_before.append(_rot("x", alpha) @ _shift(0, a) @ _rot("z", theta) @ _shift(2, d))
            fixed_after.append(np.eye(4))
        else:  # the joint's Rz(q), then Rz(theta) Tz(d) Tx(a) Rx(alpha)
            fixed_before.append(np.eye(4))
            fixed_after.append(_rot("z", theta) @ _shift(2, d) @ _shift(0, a) @ _rot("x", alpha))
    lines = ['<?xml version="1.0"?>', f'<robot name="{chain.name}">',
             f"  <!-- written by handeye from {chain.source or chain.name}: kinematics only -->"]
    if chain.compliance is not None:  # URDF has no element for it
        lines.append("  <!-- without the joints' compliance, which a URDF cannot hold (the DH table in YAML has it): "
                     f"{', '.join(f'{np.degrees(c):.6g}' for c in chain.compliance)} deg per metre of moment arm -->")
    lines += [f'  <link name="{base_link}"/>']
    parent, pending = base_link, chain.base
    limits = chain.limits if chain.limits is not None else np.tile([-2 * np.pi, 2 * np.pi], (chain.n_joints, 1))
    lower, upper = (np.clip(limits[:, 0], -1e3, 1e3).tolist(), np.clip(limits[:, 1], -1e3, 1e3).tolist())
    for k in range(chain.n_joints):
        origin = pending @ fixed_before[k]
        lines += [f'  <link name="link{k + 1}"/>', f'  <joint name="{names[k]}" type="revolute">',
                  f"    {_origin(origin)}", f'    <parent link="{parent}"/>', f'    <child link="link{k + 1}"/>',
                  '    <axis xyz="0 0 1"/>', f'    <limit lower="{lower[k]!r}" upper="{upper[k]!r}" effort="0" velocity="0"/>',
                  "  </joint>"]
        parent, pending = f"link{k + 1}", fixed_after[k]
    lines += [f'  <link name="{tip_link}"/>', f'  <joint name="{tip_link}_joint" type="fixed">',
              f"    {_origin(pending @ chain.flange)}", f'    <parent link="{parent}"/>', f'    <child link="{tip_link}"/>',
              "  </joint>", "</robot>"]
    return "\n".join(lines) + "\n"


def _origin(T: NDArray[np.float64]) -> str:
    rpy = Rotation.from_matrix(T[:3, :3]).as_euler("xyz")  # URDF's roll, pitch, yaw about the fixed x, y, z
    return (f'<origin xyz="{" ".join(repr(float(v)) for v in T[:3, 3])}" '
            f'rpy="{" ".join(repr(float(v)) for v in rpy)}"/>')
