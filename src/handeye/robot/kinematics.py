"""Serial arms' kinematics: Denavit-Hartenberg chains, batched forward kinematics, and their
parameters as unknowns of a calibration.

A :class:`Chain` holds one row per joint, ``a`` (m), ``alpha`` (rad), ``d`` (m) and the ``theta``
offset (rad), in the standard convention (``dh``: ``Rz(theta) Tz(d) Tx(a) Rx(alpha)``) or Craig's
modified one (``mdh``: ``Rx(alpha) Tx(a) Rz(theta) Tz(d)``, the row's ``a`` and ``alpha`` those of
the link before the joint), then a constant ``flange`` transform. The tables of common arms ship as
data (:func:`arm_names`, :func:`load_arm`), each with its source.

A kinematic error that only moves the base or the flange frame is not the arm's to estimate: a
calibration that also finds X and Z takes it into them (:func:`absorbed_parameters`).

Joint compliance (optional, ``Chain.compliance``): each joint gives way under the load it holds,
by its compliance (rad per metre) times the moment arm of the flange's load about the joint's axis
(:meth:`Chain.moment_arms`; the load lumped at the flange, gravity along ``Chain.gravity``, the
base frame's -z by default): an arm reaching out sags more than one held close.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray

from .._shared.text import shown
from ..errors import InputMismatchError

if TYPE_CHECKING:  # Python 3.11's place for it
    from importlib.resources.abc import Traversable

__all__ = ["Chain", "PARAMETERS", "GRAVITY", "arm_names", "load_arm", "absorbed_parameters",
           "along_parallel_axes", "check_joints_against_poses", "chain_yaml", "display_unit", "joints_at"]

#: A joint's parameters, in the order of a chain's table columns (and of its parameter vector).
PARAMETERS = ("a", "alpha", "d", "theta")
#: Gravity's direction in an arm's base frame unless the chain says otherwise (a floor-mounted
#: arm, z up: the shipped tables' and ROS's convention).
GRAVITY = (0.0, 0.0, -1.0)


@dataclass(frozen=True)
class Chain:
    """A serial arm of revolute joints.

    Attributes
    ----------
    name : str
    convention : {'dh', 'mdh'}
        Standard (Denavit-Hartenberg) or modified (Craig) parameters.
    table : ndarray (n, 4)
        Per joint ``a`` (m), ``alpha`` (rad), ``d`` (m), ``theta`` offset (rad).
    flange : ndarray (4, 4)
        The flange in the last joint's frame.
    source : str
        Where the table comes from.
    home : dict
        Per setup, joint angles (rad) where a capture centres (the simulator's).
    spread : ndarray (n,) or None
        How far (rad) the simulator's captures move each joint from home.
    base : ndarray (4, 4)
        The first joint's frame in the base frame (identity for the shipped tables; a URDF's base
        link to its first joint, :func:`handeye.robot.urdf.chain_from_urdf`).
    joint_names : tuple of str or None
        The joints' names (a URDF's), in the table's order: columns of a joints table named so are
        read in this order whatever theirs.
    limits : ndarray (n, 2) or None
        Each joint's lower and upper limit (rad), where known: the views handeye proposes stay inside.
    compliance : ndarray (n,) or None
        Each joint's deflection (rad) per metre of the moment arm of the flange's load about its
        axis (:meth:`moment_arms`); None: a rigid arm.
    gravity : ndarray (3,)
        Gravity's direction in the base frame (a unit vector; :data:`GRAVITY` by default).
    pendant_coupling : (int, int, float) or None
        ``(j, i, f)``: the teach pendant shows joint ``j`` (1-based) as the table's joint ``j``
        minus ``f`` times joint ``i`` (:meth:`from_pendant`). FANUC's pendant measures J3 against
        the horizon: ``(3, 2, 1.0)``, ROS-Industrial's ``J23_factor`` of 1.
    """

    name: str
    convention: str
    table: NDArray[np.float64]
    flange: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))
    source: str = ""
    home: dict = field(default_factory=dict)
    spread: NDArray[np.float64] | None = None
    base: NDArray[np.float64] = field(default_factory=lambda: np.eye(4))
    joint_names: tuple[str, ...] | None = None
    limits: NDArray[np.float64] | None = None
    compliance: NDArray[np.float64] | None = None
    gravity: NDArray[np.float64] = field(default_factory=lambda: np.array(GRAVITY))
    pendant_coupling: tuple[int, int, float] | None = None

    def __post_init__(self) -> None:
        if self.convention not in ("dh", "mdh"):
            raise InputMismatchError(f"{self.name}: convention {shown(self.convention)}; use 'dh' or 'mdh'")
        table = np.asarray(self.table, dtype=float)
        if table.ndim != 2 or table.shape[1] != 4 or not np.isfinite(table).all():
            raise InputMismatchError(f"{self.name}: the table must be finite rows of a, alpha, d, theta; got shape "
                                     f"{table.shape}")
        object.__setattr__(self, "table", table)
        for key in ("flange", "base"):
            T = np.asarray(getattr(self, key), dtype=float)
            if T.shape != (4, 4) or not np.isfinite(T).all():
                raise InputMismatchError(f"{self.name}: {key} must be a finite 4x4 transform")
            object.__setattr__(self, key, T)
        if self.limits is not None:
            limits = np.asarray(self.limits, dtype=float)
            if limits.shape != (len(table), 2) or np.isnan(limits).any() or (limits[:, 0] > limits[:, 1]).any():
                raise InputMismatchError(f"{self.name}: limits must be one [lower, upper] row per joint")
            object.__setattr__(self, "limits", limits)
        if self.compliance is not None:
            c = np.asarray(self.compliance, dtype=float)
            if c.shape != (len(table),) or not np.isfinite(c).all():
                raise InputMismatchError(f"{self.name}: compliance must be one finite number per joint (rad per metre)")
            object.__setattr__(self, "compliance", c)
        g = np.asarray(self.gravity, dtype=float)
        if g.shape != (3,) or not np.isfinite(g).all() or np.linalg.norm(g) < 1e-9:
            raise InputMismatchError(f"{self.name}: gravity must be a direction in the base frame, e.g. [0, 0, -1]")
        object.__setattr__(self, "gravity", g / np.linalg.norm(g))
        if self.joint_names is not None and len(self.joint_names) != len(table):
            raise InputMismatchError(f"{self.name}: {len(self.joint_names)} joint names for {len(table)} joints")
        if self.pendant_coupling is not None:
            object.__setattr__(self, "pendant_coupling", _coupling(self.pendant_coupling, len(table), self.name))

    def from_pendant(self, q: ArrayLike) -> NDArray[np.float64]:
        """Joint angles (N, n) as the teach pendant shows them, as the table takes them (the same
        when the arm has no :attr:`pendant_coupling`)."""
        return self._coupled(q, 1.0)

    def to_pendant(self, q: ArrayLike) -> NDArray[np.float64]:
        """The inverse of :meth:`from_pendant`."""
        return self._coupled(q, -1.0)

    def _coupled(self, q: ArrayLike, sign: float) -> NDArray[np.float64]:
        q = np.array(q, dtype=float)
        if self.pendant_coupling is not None:
            j, i, f = self.pendant_coupling
            q[..., j - 1] += sign * f * q[..., i - 1]
        return q

    @property
    def n_joints(self) -> int:
        """Number of joints."""
        return len(self.table)

    def parameter_names(self, compliance: bool = False) -> list[str]:
        """``joint<k>.<a|alpha|d|theta>`` for every entry of the table, row by row, then (with
        ``compliance``) ``joint<k>.compliance`` for every joint: the order of :meth:`forward_with`'s
        parameter vector."""
        names = [f"joint{k + 1}.{p}" for k in range(self.n_joints) for p in PARAMETERS]
        return names + ([f"joint{k + 1}.compliance" for k in range(self.n_joints)] if compliance else [])

    def forward_with(self, q: ArrayLike, p: ArrayLike) -> NDArray[np.float64]:
        """:meth:`forward` with the parameter vector ``p`` of :meth:`parameter_names` added: the
        table's corrections and, when ``p`` is that long, the compliance's (to the chain's own, or 0)."""
        p = np.asarray(p, dtype=float).ravel()
        size = self.table.size
        if len(p) == size:
            return self.forward(q, p)
        own = np.zeros(self.n_joints) if self.compliance is None else self.compliance
        return self.forward(q, p[:size], own + p[size:])

    def corrected(self, deltas: ArrayLike) -> "Chain":
        """The chain with ``deltas`` (n, 4) added to its table."""
        return replace(self, table=self.table + np.asarray(deltas, dtype=float).reshape(self.table.shape))

    def forward(self, q: ArrayLike, deltas: ArrayLike | None = None,
                compliance: ArrayLike | None = None) -> NDArray[np.float64]:
        """``flange2base`` (N, 4, 4) of joint angles ``q`` (N, n) in radians, the table changed by
        ``deltas`` (n, 4) and the joints' compliance (n,) replaced by ``compliance`` when given.
        Compliance turns each joint by its value times :meth:`moment_arms` at the commanded angles
        (first order: the deflections are small)."""
        q = np.asarray(q, dtype=float)
        if q.ndim != 2 or q.shape[1] != self.n_joints:
            raise InputMismatchError(f"{self.name} has {self.n_joints} joints; the joint angles have shape {q.shape}")
        table = self.table if deltas is None else self.table + np.asarray(deltas, dtype=float).reshape(self.table.shape)
        c = self.compliance if compliance is None else np.asarray(compliance, dtype=float)
        if c is not None and np.any(c != 0):
            q = q + c * self._moment_arms(q, table)
        return self._frames(q, table)[-1] @ self.flange

    def joint_frames(self, q: ArrayLike, deltas: ArrayLike | None = None) -> list[NDArray[np.float64]]:
        """Each joint's frame after its rotation, in the base frame: n stacks (N, 4, 4) for joint
        angles ``q`` (N, n), the table changed by ``deltas`` (n, 4) when given (the links' meshes
        ride on them: :mod:`handeye.robot.meshes`). Compliance is not applied."""
        q = np.asarray(q, dtype=float)
        if q.ndim != 2 or q.shape[1] != self.n_joints:
            raise InputMismatchError(f"{self.name} has {self.n_joints} joints; the joint angles have shape {q.shape}")
        table = self.table if deltas is None else self.table + np.asarray(deltas, dtype=float).reshape(self.table.shape)
        return self._frames(q, table)

    def moment_arms(self, q: ArrayLike, deltas: ArrayLike | None = None) -> NDArray[np.float64]:
        """(N, n): per joint the torque (N m) a 1 N load at the flange's origin makes about the
        joint's axis under gravity (``Chain.gravity``), i.e. the load's moment arm (m), signed
        along the axis: the direction the joint gives way."""
        q = np.asarray(q, dtype=float)
        table = self.table if deltas is None else self.table + np.asarray(deltas, dtype=float).reshape(self.table.shape)
        return self._moment_arms(q, table)

    def _moment_arms(self, q: NDArray[np.float64], table: NDArray[np.float64]) -> NDArray[np.float64]:
        frames = self._frames(q, table)
        flange = (frames[-1] @ self.flange)[:, :3, 3]
        # the joint's axis: z of the frame before its rotation (standard DH: the previous frame's)
        axes = [np.broadcast_to(self.base, frames[0].shape)] + frames[:-1] if self.convention == "dh" else frames
        return np.stack([np.einsum("ni,ni->n", np.cross(flange - A[:, :3, 3], self.gravity), A[:, :3, 2]) for A in axes],
                        axis=1)

    def _frames(self, q: NDArray[np.float64], table: NDArray[np.float64]) -> list[NDArray[np.float64]]:
        """Each joint's frame after its rotation in the base frame: n stacks (N, 4, 4)."""
        a, alpha, d, theta = (table[:, k] for k in range(4))
        th = q + theta
        ct, st = np.cos(th), np.sin(th)
        ca, sa = np.cos(alpha), np.sin(alpha)
        A = np.zeros(q.shape + (4, 4))
        if self.convention == "dh":  # Rz(theta) Tz(d) Tx(a) Rx(alpha)
            A[..., 0, 0], A[..., 0, 1], A[..., 0, 2], A[..., 0, 3] = ct, -st * ca, st * sa, a * ct
            A[..., 1, 0], A[..., 1, 1], A[..., 1, 2], A[..., 1, 3] = st, ct * ca, -ct * sa, a * st
            A[..., 2, 1], A[..., 2, 2], A[..., 2, 3] = sa, ca, d
        else:  # Rx(alpha) Tx(a) Rz(theta) Tz(d)
            A[..., 0, 0], A[..., 0, 1], A[..., 0, 3] = ct, -st, a
            A[..., 1, 0], A[..., 1, 1], A[..., 1, 2], A[..., 1, 3] = st * ca, ct * ca, -sa, -sa * d
            A[..., 2, 0], A[..., 2, 1], A[..., 2, 2], A[..., 2, 3] = st * sa, ct * sa, ca, ca * d
        A[..., 3, 3] = 1.0
        frames = [self.base @ A[:, 0]]
        for k in range(1, self.n_joints):
            frames.append(frames[-1] @ A[:, k])
        return frames


def _coupling(value, n: int, name: str) -> tuple[int, int, float]:
    """A pendant coupling ``(j, i, f)`` checked against an arm of ``n`` joints."""
    try:
        j, i, f = value
        j, i, f = int(j), int(i), float(f)
    except (TypeError, ValueError):
        raise InputMismatchError(f"{name}: pendant_coupling must be [joint, joint it adds, factor], e.g. [3, 2, 1.0]"
                                 ) from None
    if not (1 <= j <= n and 1 <= i <= n and j != i and np.isfinite(f)):
        raise InputMismatchError(f"{name}: pendant_coupling {list(value)}: two different joints of 1..{n} and a finite "
                                 "factor")
    return j, i, f


def joints_at(times: ArrayLike, joints: ArrayLike, at: ArrayLike) -> NDArray[np.float64]:
    """Joint angles (N, n) sampled at increasing ``times`` (N,), at the times ``at`` (M,): each joint
    linear between samples, held at the ends."""
    q = np.asarray(joints, dtype=float)
    at, times = np.asarray(at, dtype=float), np.asarray(times, dtype=float)
    return np.stack([np.interp(at, times, q[:, j]) for j in range(q.shape[1])], axis=1)


def display_unit(name: str) -> tuple[float, str]:
    """How a parameter of :meth:`Chain.parameter_names` is shown: (factor from SI, unit); lengths
    in mm, angles in deg, compliance in deg per metre of the load's moment arm."""
    if name.endswith(".compliance"):
        return float(np.degrees(1.0)), "deg/m"
    return (float(np.degrees(1.0)), "deg") if name.endswith((".alpha", ".theta")) else (1e3, "mm")


def absorbed_parameters(chain: Chain) -> list[str]:
    """The table entries whose errors only move the base or the flange frame: a calibration with
    X and Z as unknowns takes them into X and Z (which of the two depends on the setup), so they
    are not the arm's to estimate. The first joint's ``theta`` offset and ``d`` (and, modified
    convention, the ``a`` and ``alpha`` before it), and everything after the last joint's rotation:
    its ``theta`` offset and ``d`` (standard convention: also its ``a`` and ``alpha``)."""
    n = chain.n_joints
    first = ["theta", "d"] + (["a", "alpha"] if chain.convention == "mdh" else [])
    last = ["theta", "d"] + (["a", "alpha"] if chain.convention == "dh" else [])
    return [f"joint1.{p}" for p in first] + [f"joint{n}.{p}" for p in last]


def along_parallel_axes(chain: Chain) -> set[str]:
    """The offsets along joint axes parallel to the next or the previous one: a shift along two
    parallel axes moves the flange the same way, so only the offsets' sum can be determined."""
    alpha = chain.table[:, 1]
    n = chain.n_joints
    # standard DH: joint k's alpha is between axes k and k+1; modified: row k's alpha is between k-1 and k
    between = [abs(np.sin(alpha[k])) < 1e-9 for k in range(n - 1)] if chain.convention == "dh" else \
        [abs(np.sin(alpha[k + 1])) < 1e-9 for k in range(n - 1)]
    out = set()
    for k, parallel in enumerate(between):
        if parallel:
            out |= {f"joint{k + 1}.d", f"joint{k + 2}.d"}
    return out


def _arm_files() -> dict[str, Traversable]:
    folder = resources.files("handeye") / "data" / "arms"
    return {p.name[:-5]: p for p in folder.iterdir() if p.name.endswith(".yaml")}


def arm_names() -> list[str]:
    """The arms whose kinematics ship with handeye (``load_arm``'s names)."""
    return sorted(_arm_files())


def load_arm(name: str | Path) -> Chain:
    """The nominal kinematics of a common arm by name (case-insensitive; :func:`arm_names`), or of
    any arm from a YAML file in the shipped tables' format (``name``, ``convention``, ``joints``:
    rows of ``a`` (m), ``alpha`` (rad), ``d`` (m), ``theta`` offset (rad), optional ``flange``: its
    offset along the last frame (m)), such as :func:`chain_yaml` writes."""
    path = Path(str(name))
    if path.suffix.lower() in (".yaml", ".yml"):
        if not path.is_file():
            raise InputMismatchError(f"{path}: no such arm file (a DH table in YAML: name, convention, joints)")
        return _chain_from_yaml(path.read_text(encoding="utf-8"), str(path))
    files = _arm_files()
    key = str(name).lower().replace("-", "").replace("_", "")
    if key not in files:
        raise InputMismatchError(f"unknown arm {shown(name)}; handeye has the kinematics of: {', '.join(sorted(files))} "
                                 "(or give a YAML file of your arm's DH table, or build a handeye.robot.kinematics.Chain)")
    return _chain_from_yaml(files[key].read_text(encoding="utf-8"), key)


def _chain_from_yaml(text: str, where: str) -> Chain:
    try:
        data = yaml.safe_load(text)
        source = " ".join(line.lstrip("# ").strip() for line in text.splitlines() if line.startswith("#"))
        flange = np.asarray(data.get("flange", [0.0, 0.0, 0.0]), dtype=float)
        if flange.shape == (3,):
            flange = np.vstack([np.hstack([np.eye(3), flange[:, None]]), [0, 0, 0, 1]])
        names = data.get("joint_names")
        return Chain(name=str(data["name"]), convention=str(data["convention"]),
                     table=np.array(data["joints"], dtype=float), flange=flange, source=source,
                     base=np.asarray(data.get("base", np.eye(4)), dtype=float),
                     joint_names=None if names is None else tuple(str(n) for n in names),
                     limits=np.radians(data["limits_deg"]) if "limits_deg" in data else None,
                     home={k: np.radians(v) for k, v in (data.get("home_deg") or {}).items()},
                     spread=np.radians(data["spread_deg"]) if "spread_deg" in data else None,
                     compliance=data.get("compliance_rad_per_m"), gravity=data.get("gravity", GRAVITY),
                     pendant_coupling=data.get("pendant_coupling"))
    except (KeyError, TypeError, ValueError, AttributeError, yaml.YAMLError) as exc:
        raise InputMismatchError(f"{where}: not an arm table ({exc}); give name, convention (dh or mdh) and joints: "
                                 "one row [a_m, alpha_rad, d_m, theta_offset_rad] per joint") from None


def chain_yaml(chain: Chain, comment: str = "") -> str:
    """``chain`` as a YAML arm table that :func:`load_arm` reads back (full precision), with
    ``comment`` lines on top."""
    lines = [f"# {line}" for line in (comment or chain.source).splitlines() if line.strip()]
    lines += [f"name: {chain.name}", f"convention: {chain.convention}", "columns: [a_m, alpha_rad, d_m, theta_offset_rad]",
              "joints:"]
    lines += [f"  - [{', '.join(repr(float(v)) for v in row)}]" for row in chain.table]
    for key in ("base", "flange"):
        T = getattr(chain, key)
        if key == "flange" or not np.array_equal(T, np.eye(4)):
            lines.append(f"{key}: [[{'], ['.join(', '.join(repr(float(v)) for v in r) for r in T)}]]")
    if chain.joint_names is not None:
        lines.append(f"joint_names: [{', '.join(chain.joint_names)}]")
    if chain.compliance is not None:
        lines.append(f"compliance_rad_per_m: [{', '.join(repr(float(v)) for v in chain.compliance)}]")
    if not np.allclose(chain.gravity, GRAVITY, atol=0.0):
        lines.append(f"gravity: [{', '.join(repr(float(v)) for v in chain.gravity)}]")
    if chain.pendant_coupling is not None:
        j, i, f = chain.pendant_coupling
        lines.append(f"pendant_coupling: [{j}, {i}, {f!r}]")
    if chain.limits is not None:
        lines.append(f"limits_deg: [[{'], ['.join(', '.join(repr(float(v)) for v in r) for r in np.degrees(chain.limits))}]]")
    return "\n".join(lines) + "\n"


#: Joint angles and flange poses of the same views agree when the flange poses differ by less than
#: this (median, mm; deg): a controller's own model of the arm (UR's factory calibration) differs
#: from the nominal table by a few millimetres, a wrong reading by far more.
POSE_AGREEMENT = (20.0, 2.0)


def _row_gaps(a: NDArray[np.float64], b: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per pose, the translation (mm) and rotation (deg) between two stacks of poses."""
    dt = 1e3 * np.linalg.norm(a[..., :3, 3] - b[..., :3, 3], axis=-1)
    cos = (np.einsum("...ij,...ij->...", a[..., :3, :3], b[..., :3, :3]) - 1) / 2
    return dt, np.degrees(np.arccos(np.clip(cos, -1, 1)))


def _pose_gap(a: NDArray[np.float64], b: NDArray[np.float64]) -> tuple[float, float]:
    """Median translation (mm) and rotation (deg) between two stacks of poses."""
    dt, dr = _row_gaps(a, b)
    return float(np.median(dt)), float(np.median(dr))


def _rows_apart(chain: Chain, q: NDArray[np.float64], flange2base: NDArray[np.float64], where: str,
                names: list[str] | None) -> None:
    """Raise, naming them, for rows whose joint angles put the flange beyond :data:`POSE_AGREEMENT`
    of their own view's controller pose while the rest agree: two rows swapped (said so when each
    agrees with the other's pose), a row of another view, a pose typed wrong. A fit would take them
    as the robot's error and call the data inconsistent, without saying which rows."""
    forward = chain.forward(q)
    dt, dr = _row_gaps(forward, flange2base)
    bad = np.flatnonzero((dt > POSE_AGREEMENT[0]) | (dr > POSE_AGREEMENT[1]))
    if not len(bad):
        return
    label = (lambda k: repr(names[k])) if names is not None else (lambda k: f"row {k + 1}")
    swapped, alone = [], set(bad.tolist())
    for i in bad:
        for j in bad:
            if i < j and i in alone and j in alone:
                gi, gj = _row_gaps(forward[[i, j]], flange2base[[j, i]])
                if np.all(gi <= POSE_AGREEMENT[0]) and np.all(gj <= POSE_AGREEMENT[1]):
                    swapped.append((int(i), int(j)))
                    alone -= {i, j}
    told = [f"{label(i)} and {label(j)} are swapped (each one's joint angles are the other's view)" for i, j in swapped]
    rest = sorted(alone)
    if rest:
        far = ", ".join(f"{label(k)} ({dt[k]:.0f} mm / {dr[k]:.1f} deg)" for k in rest[:5])
        told.append(f"{far}{f' and {len(rest) - 5} more' if len(rest) > 5 else ''} put the flange far from "
                    "the controller's pose of the same view")
    raise InputMismatchError(f"{where} through {chain.name}'s table agree with the controller's flange poses in "
                             f"{len(q) - len(bad)} of {len(q)} views, not in these: {'; '.join(told)}: give each view its "
                             "own joint angles and pose (or leave the view out)")


def check_joints_against_poses(chain: Chain, q: ArrayLike, flange2base: ArrayLike, where: str = "joint angles",
                               names: list[str] | None = None) -> str:
    """Check that joint angles ``q`` (N, n; radians) and the controller's ``flange2base`` (N, 4, 4)
    describe the same views through ``chain``.

    Returns the finding as a sentence (how far apart they are) when they agree within
    :data:`POSE_AGREEMENT`, view by view. Otherwise raises, naming what makes them agree when one
    of the usual slips does: the joints in degrees read as radians (or the reverse), the joint
    columns in reverse order, the flange poses inverted (base in flange), another of the shipped
    arms; or, when most views agree, the views that do not (``names``: the views' names, else
    their rows), two of them swapped.

    Raises
    ------
    InputMismatchError
    """
    q = np.asarray(q, dtype=float)
    flange2base = np.asarray(flange2base, dtype=float)
    gap = _pose_gap(chain.forward(q), flange2base)
    if gap[0] <= POSE_AGREEMENT[0] and gap[1] <= POSE_AGREEMENT[1]:
        _rows_apart(chain, q, flange2base, where, names)
        return (f"{where} through {chain.name}'s table and the controller's flange poses agree to {gap[0]:.2f} mm / "
                f"{gap[1]:.3f} deg (median): the arm's error the calibration fits, and the controller's own model")
    trials = {"the joint angles are in degrees, not radians (give the unit as deg)": (chain, np.radians(q), flange2base),
              "the joint angles are in radians, not degrees (give the unit as rad)": (chain, np.degrees(q), flange2base),
              "the joint columns are in reverse order (joint 1 first)": (chain, q[:, ::-1], flange2base),
              "the flange poses are inverted (base in flange: give flange2base)": (chain, q, np.linalg.inv(flange2base))}
    if chain.pendant_coupling is not None:
        j, i, _ = chain.pendant_coupling
        trials[f"the joint angles are as the teach pendant shows them (J{j} coupled with J{i}): write pendant: true "
               "under joints:"] = (chain, chain.from_pendant(q), flange2base)
        trials[f"the joint angles are {chain.name}'s own, not the teach pendant's (remove pendant: true)"] = (
            chain, chain.to_pendant(q), flange2base)
    for other in arm_names():
        arm = load_arm(other)
        if arm.n_joints == chain.n_joints and arm.name != chain.name:
            trials[f"the arm is {arm.name}, not {chain.name}"] = (arm, q, flange2base)
    found = []
    for fix, (arm, qq, f2b) in trials.items():
        if np.abs(qq).max() > 1e3:
            continue
        g = _pose_gap(arm.forward(qq), f2b)
        if g[0] <= POSE_AGREEMENT[0] and g[1] <= POSE_AGREEMENT[1]:
            found.append(fix)
    hint = (f"they agree if {found[0]}" if found else
            "none of the usual slips explains it (degrees/radians, joint order, inverted poses, another arm): check "
            "the arm's table (or URDF) and that each row's joints and pose are of the same view")
    raise InputMismatchError(f"{where} through {chain.name}'s table put the flange {gap[0]:.1f} mm / {gap[1]:.1f} deg "
                             f"(median) from the controller's flange poses: {hint}")
