"""Robot models: where the flange was at each view, and what of it a calibration may fit.

A calibration is a sensor model times a robot model times a setup (:mod:`handeye.estimation.core`).
The robot model says how the flange pose of view ``i`` follows from its own unknowns ``d``:

* :class:`ControllerPoses`: the poses the controller reported, taken as they are (no unknowns); the
  robot's absolute accuracy, which X absorbs unseen, is added to X's std.
* :class:`PoseErrors`: the controller's poses with each pose's own error an unknown (a prior of the
  robot's stated accuracy): what several sensors that saw the same pose share, so that a rig's
  relative poses are free of it.
* :class:`JointAngles`: the joint angles through the arm's kinematic table, whose entries are
  unknowns with a Gaussian prior about their nominal values (the arm's tolerances); the entries
  that only move the base or the flange frame are left to X and the target's pose
  (:func:`~handeye.robot.kinematics.absorbed_parameters`). The fit then removes the arm's error
  instead of widening X's std by it.
* :class:`JointTrajectory`: joint angles along a time-stamped trajectory, for a sensor whose view
  spans a move (a line-scan camera's scan, each row at its own time): the same table, and the
  flange's pose at any time of the move through it (``motion(d)``).

All four are immutable (frozen dataclasses); ``flange2base(d)`` gives every view's pose (N, 4, 4) for
the unknowns ``d``. ``accuracy`` (deg, mm per axis) is, for :class:`ControllerPoses`, the robot's absolute
accuracy that X's std takes; for :class:`PoseErrors`, also the prior std of each pose's error (the pixel
refinement of images passes its ``robot_noise`` there); the joint-angle models have none.

:class:`RobotModel` is the contract every robot model meets (a protocol, checked by mypy); what a model
can do beyond it, the estimation core asks by ``isinstance`` of one small protocol each:
:class:`ReportedPoses` (the controller's poses, as reported), :class:`PerViewErrors` (each unknown
moves one view's pose), :class:`ChainedPoses` (the poses' derivatives by the unknowns),
:class:`FollowsMotion` (the flange's pose at any time of a move) and :class:`FittedTable` (the arm's
table, corrected by the unknowns).

Examples
--------
>>> import numpy as np
>>> from handeye.robot.kinematics import load_arm
>>> from handeye.robot.models import ControllerPoses, JointAngles
>>> ur5 = load_arm("ur5")
>>> q = np.radians([[0, -90, 90, -90, -90, 0], [10, -80, 85, -95, -90, 20], [-15, -100, 95, -80, -85, -30]])
>>> robot = JointAngles(ur5, q)
>>> robot.flange2base(np.zeros(robot.n_params)).shape
(3, 4, 4)
>>> ControllerPoses(ur5.forward(q)).n_params
0
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Protocol, cast, runtime_checkable

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..errors import InputMismatchError
from ..geometry.se3 import perturb
from .kinematics import Chain, absorbed_parameters, joints_at

__all__ = ["RobotModel", "ReportedPoses", "PerViewErrors", "ChainedPoses", "FollowsMotion", "FittedTable", "ControllerPoses",
           "PoseErrors", "JointAngles", "JointTrajectory", "fitted_entries", "entry_priors",
           "LENGTH_PRIOR_M", "ANGLE_PRIOR_RAD", "COMPLIANCE_PRIOR", "MIN_MOMENT_ARM", "ACCURACY_SAMPLES"]

#: The default prior std of a table entry: a length (m) and an angle (rad, 0.1 deg), an uncalibrated
#: arm's tolerances.
LENGTH_PRIOR_M = 1e-3
ANGLE_PRIOR_RAD = float(np.radians(0.1))
#: The default prior std of a joint's compliance (rad per metre of the load's moment arm): 0.2 deg
#: per metre, a collaborative arm's shoulder (~3e4 N m/rad) under its links and a camera (~100 N):
#: ~1 mm at reach.
COMPLIANCE_PRIOR = float(np.radians(0.2))
#: A joint whose load's moment arm stays below this (m) over the capture has no compliance to fit.
MIN_MOMENT_ARM = 1e-3
#: Joint configurations the arm's accuracy is predicted over (:meth:`JointAngles.accuracy_mm`).
ACCURACY_SAMPLES = 500


def fitted_entries(chain: Chain, joints: NDArray[np.float64], compliance: bool = False
                   ) -> tuple[list[str], list[str], NDArray[np.intp]]:
    """Every parameter of ``chain.forward_with``'s vector, the ones a calibration fits (not absorbed
    by X and the target's pose; a compliance only for joints the load turns over the capture), and
    their positions in that vector."""
    absorbed = set(absorbed_parameters(chain))
    every = chain.parameter_names(compliance)
    loaded = np.abs(chain.moment_arms(joints)).max(axis=0) >= MIN_MOMENT_ARM if compliance else np.zeros(0, bool)
    names = [name for name in every if name not in absorbed
             and (not name.endswith(".compliance") or loaded[int(name.split(".")[0].removeprefix("joint")) - 1])]
    return every, names, np.array([every.index(name) for name in names], dtype=np.intp)


def entry_priors(names: list[str], length: float = LENGTH_PRIOR_M, angle: float = ANGLE_PRIOR_RAD,
                 compliance: float = COMPLIANCE_PRIOR) -> NDArray[np.float64]:
    """The prior std of each table entry of ``names`` (m, rad, or rad per metre)."""
    return np.array([compliance if name.endswith(".compliance") else angle if name.endswith((".alpha", ".theta"))
                     else length for name in names])


@runtime_checkable
class RobotModel(Protocol):
    """What every robot model has (see the module docstring): ``n_views``, ``n_params``, ``names`` (its
    unknowns), ``flange2base(d)``, ``prior(d)`` (whitened residual rows that hold ``d`` near its
    prior; empty without unknowns), ``accuracy`` ((deg, mm) that X absorbs unseen, None when the fit
    models the robot's error) and ``describe`` (in words)."""

    @property
    def n_views(self) -> int: ...

    @property
    def n_params(self) -> int: ...

    @property
    def names(self) -> list[str]: ...

    @property
    def accuracy(self) -> tuple[float, float] | None: ...

    @property
    def describe(self) -> str: ...

    def flange2base(self, d: NDArray[np.float64]) -> NDArray[np.float64]: ...

    def prior(self, d: NDArray[np.float64]) -> NDArray[np.float64]: ...


@runtime_checkable
class ReportedPoses(RobotModel, Protocol):
    """The controller's flange poses (N, 4, 4), as reported: what the fit starts from and, without
    unknowns, takes as they are."""

    @property
    def poses(self) -> NDArray[np.float64]: ...


@runtime_checkable
class PerViewErrors(RobotModel, Protocol):
    """Unknowns that each move one view's pose: per unknown its view (``param_view``) and the size of
    one of its units (``param_size``, rad or m), for finite differences that step every view's at once."""

    @property
    def param_view(self) -> NDArray[np.intp]: ...

    @property
    def param_size(self) -> NDArray[np.float64]: ...


@runtime_checkable
class ChainedPoses(RobotModel, Protocol):
    """Per view how its flange pose moves with each unknown (N, 6, n_params), for the chain rule."""

    def pose_jacobian(self, d: NDArray[np.float64]) -> NDArray[np.float64]: ...


@runtime_checkable
class FollowsMotion(RobotModel, Protocol):
    """The flange's pose at any robot time of a move, for the unknowns ``d``: ``motion(d)(t)`` (M, 4, 4)."""

    def motion(self, d: NDArray[np.float64]) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]: ...


@runtime_checkable
class FittedTable(ChainedPoses, Protocol):
    """Joint angles through the arm's table, whose entries the unknowns correct (in units of their prior std)."""

    chain: Chain
    joints: NDArray[np.float64]
    prior_std: NDArray[np.float64]
    length_prior: float
    angle_prior: float
    compliance: bool
    compliance_prior: float

    def corrected(self, d: NDArray[np.float64]) -> Chain: ...

    def entry_columns(self, by_entry: NDArray[np.float64]) -> NDArray[np.float64]: ...

    def accuracy_mm(self, d: NDArray[np.float64], cov_d: NDArray[np.float64],
                    views: NDArray[np.intp] | None = None) -> dict[str, float]: ...


@dataclass(frozen=True)
class ControllerPoses:
    """The flange poses the controller reported (N, 4, 4), with the robot's stated absolute
    accuracy per axis (deg, mm; None: exact), which X absorbs unseen."""

    poses: NDArray[np.float64]
    accuracy: tuple[float, float] | None = None
    describe: str = "the controller's flange poses"

    @property
    def n_views(self) -> int:
        """Number of views."""
        return len(self.poses)

    @property
    def n_params(self) -> int:
        """None: the poses are taken as they are."""
        return 0

    @property
    def names(self) -> list[str]:
        """No unknowns."""
        return []

    def flange2base(self, d: NDArray[np.float64]) -> NDArray[np.float64]:
        """The poses as reported (there are no unknowns)."""
        return self.poses

    def prior(self, d: NDArray[np.float64]) -> NDArray[np.float64]:
        """No prior rows (no unknowns)."""
        return np.zeros(0)


@dataclass(frozen=True)
class PoseErrors(ControllerPoses):
    """The controller's poses (N, 4, 4), each pose's error an unknown: a left rotation and a
    translation (6 per pose, in units of the robot's stated ``accuracy`` per axis, deg and mm: the
    prior). Sensors that saw the same pose share its error (a rig's), which then cancels in their
    relative poses; the error common to all poses stays unseen and X's std still takes the accuracy.

    ``views``: the poses whose error is an unknown (default all): only where the views constrain it
    (several sensors at one pose, or a view that measures a whole pose); a pose one profile of a ball
    saw would take its error from that profile alone (a 6-DOF error at a 2 m lever absorbs a line of
    points whole), so it is left as the controller reported it."""

    describe: str = "the controller's flange poses, each pose's own error fitted (prior: the robot's accuracy)"
    views: NDArray[np.intp] | None = None

    def __post_init__(self) -> None:
        if self.accuracy is None or not all(np.isfinite(a) and a > 0 for a in self.accuracy):
            raise InputMismatchError(f"robot accuracy {self.accuracy}: fitting each pose's error (a line-scan's scans, a "
                                     "rig's views) takes the robot's accuracy as its prior, positive in both (deg, mm), "
                                     "e.g. 0.03,0.3; or 0,0 for an exact robot (--robot-accuracy)")
        views = np.arange(len(self.poses)) if self.views is None else np.unique(np.asarray(self.views, dtype=np.intp))
        if len(views) and (views.min() < 0 or views.max() >= len(self.poses)):
            raise InputMismatchError(f"views {views.tolist()}: each must be one of the {len(self.poses)} poses")
        object.__setattr__(self, "views", views)

    @property
    def _fitted(self) -> tuple[NDArray[np.intp], tuple[float, float]]:
        """``views`` and ``accuracy`` as checked (neither None after it)."""
        return cast(NDArray[np.intp], self.views), cast(tuple[float, float], self.accuracy)

    @property
    def n_params(self) -> int:
        """Six per pose whose error is fitted."""
        return 6 * len(self._fitted[0])

    @property
    def names(self) -> list[str]:
        """Each fitted pose's rotation and translation error."""
        return [f"pose{i}.{a}" for i in self._fitted[0] for a in ("rx", "ry", "rz", "x", "y", "z")]

    @property
    def param_view(self) -> NDArray[np.intp]:
        """Per unknown the view whose pose it moves (the fit's finite differences step every view's at once)."""
        return np.repeat(self._fitted[0], 6)

    @property
    def param_size(self) -> NDArray[np.float64]:
        """Per unknown the size of one of its units (rad, m): the robot's stated accuracy on that axis."""
        views, accuracy = self._fitted
        one = np.r_[np.full(3, np.radians(accuracy[0])), np.full(3, 1e-3 * accuracy[1])]
        return np.tile(one, len(views))

    def flange2base(self, d: NDArray[np.float64]) -> NDArray[np.float64]:
        """The poses moved by their errors ``d`` (in units of the accuracy; the poses without one as reported)."""
        views, accuracy = self._fitted
        e = np.zeros((len(self.poses), 6))
        e[views] = np.asarray(d, float).reshape(-1, 6)
        return perturb(self.poses, np.radians(accuracy[0]) * e[:, :3], 1e-3 * accuracy[1] * e[:, 3:])

    def prior(self, d: NDArray[np.float64]) -> NDArray[np.float64]:
        """The errors in units of their prior std."""
        return np.asarray(d, float)


@dataclass(frozen=True)
class JointAngles:
    """Joint angles (N, n; rad) through ``chain``, whose table entries (and, with ``compliance``, the
    joints' compliance) are unknowns with the prior std ``length_prior`` (m), ``angle_prior`` (rad)
    and ``compliance_prior`` (rad/m) about their nominal values. The unknowns ``d`` are in units of
    their prior std, so ``prior(d) = d``."""

    chain: Chain
    joints: NDArray[np.float64]
    length_prior: float = LENGTH_PRIOR_M
    angle_prior: float = ANGLE_PRIOR_RAD
    compliance: bool = False
    compliance_prior: float = COMPLIANCE_PRIOR
    describe: str = "joint angles through the arm's table, fitted"
    _every: list[str] = field(init=False, repr=False)
    _index: NDArray[np.intp] = field(init=False, repr=False)
    names: list[str] = field(init=False)
    prior_std: NDArray[np.float64] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        q = np.asarray(self.joints, dtype=float)
        if q.ndim != 2 or q.shape[1] != self.chain.n_joints:
            raise InputMismatchError(f"{self.chain.name} has {self.chain.n_joints} joints; the joint angles have shape "
                                     f"{q.shape} (one row per view)")
        every, names, index = fitted_entries(self.chain, q, self.compliance)
        object.__setattr__(self, "joints", q)
        object.__setattr__(self, "_every", every)
        object.__setattr__(self, "_index", index)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "prior_std", entry_priors(names, self.length_prior, self.angle_prior,
                                                           self.compliance_prior))

    @property
    def n_views(self) -> int:
        """Number of views."""
        return len(self.joints)

    @property
    def n_params(self) -> int:
        """Number of table entries fitted."""
        return len(self.names)

    @property
    def accuracy(self) -> None:
        """None: the fit models the arm's error (its table), which X then does not absorb unseen."""
        return None

    def vector(self, d: NDArray[np.float64]) -> NDArray[np.float64]:
        """``chain.forward_with``'s whole parameter vector for the unknowns ``d`` (natural units)."""
        p = np.zeros(len(self._every))
        p[self._index] = np.asarray(d, dtype=float) * self.prior_std
        return p

    def flange2base(self, d: NDArray[np.float64]) -> NDArray[np.float64]:
        """Every view's flange pose through the table corrected by ``d``."""
        return self.chain.forward_with(self.joints, self.vector(d))

    def prior(self, d: NDArray[np.float64]) -> NDArray[np.float64]:
        """The prior's whitened residuals: ``d`` itself (unit std in these units)."""
        return np.asarray(d, dtype=float)

    def entry_columns(self, by_entry: NDArray[np.float64]) -> NDArray[np.float64]:
        """Derivatives by every entry of the table (``..., E``: natural units, row by row, as
        :meth:`~handeye.robot.kinematics.Chain.parameter_names`) as derivatives by the unknowns ``d``
        (``..., n_params``: the fitted entries, per unit of their prior std). Raises when the
        joints' compliance is fitted (the links' poses do not take it)."""
        if self.compliance:
            raise InputMismatchError("the links' poses take the table's entries only: fit the arm's table without "
                                     "compliance when the sensor sees the arm itself")
        return np.asarray(by_entry, float)[..., self._index] * self.prior_std

    def pose_jacobian(self, d: NDArray[np.float64]) -> NDArray[np.float64]:
        """Per view how its flange pose moves with each unknown (N, 6, n_params): the left rotation
        and the translation of :func:`~handeye.geometry.se3.perturb` per unit of ``d`` (finite
        differences of the forward kinematics: the estimation core chains them with the sensor's
        derivatives by the flange pose, 6 evaluations of the residuals instead of one per entry)."""
        d = np.asarray(d, dtype=float)
        F = self.flange2base(d)
        out = np.empty((len(F), 6, len(d)))
        h = 1e-6
        for j in range(len(d)):
            step = d.copy()
            step[j] += h
            Fj = self.flange2base(step)
            out[:, :3, j] = Rotation.from_matrix(Fj[:, :3, :3] @ np.swapaxes(F[:, :3, :3], 1, 2)).as_rotvec() / h
            out[:, 3:, j] = (Fj[:, :3, 3] - F[:, :3, 3]) / h
        return out

    def accuracy_mm(self, d: NDArray[np.float64], cov_d: NDArray[np.float64], views: NDArray[np.intp] | None = None
                    ) -> dict[str, float]:
        """The arm's absolute accuracy at the flange (mm) before and after the fit ``d`` (its
        covariance ``cov_d``, in the units of ``d``), over joint angles drawn uniformly within the
        range of each joint over ``views`` (default all: where the fit has seen the arm) and, when the
        chain knows its joints' limits, over the whole workspace (``workspace_`` keys): before, how
        far the nominal table puts the flange from the corrected one; after, the corrected table's
        position std from its entries' covariance (first order, a finite-difference Jacobian).
        Outside the capture's ranges 'before' is the corrected table extrapolated, and 'after' grows
        with the entries the capture left to their prior."""
        q = self.joints if views is None else self.joints[np.asarray(views)]
        cov = np.asarray(cov_d, float) * np.outer(self.prior_std, self.prior_std)  # natural units
        rng = np.random.default_rng(0)
        out = self._accuracy_over(d, cov, rng.uniform(q.min(axis=0), q.max(axis=0), (ACCURACY_SAMPLES, q.shape[1])))
        limits = self.chain.limits
        if limits is not None:
            whole = self._accuracy_over(d, cov, rng.uniform(limits[:, 0], limits[:, 1], (ACCURACY_SAMPLES, q.shape[1])))
            out |= {f"workspace_{k}": v for k, v in whole.items() if k != "samples"}
        return out

    def _accuracy_over(self, d: NDArray[np.float64], cov: NDArray[np.float64], samples: NDArray[np.float64]
                       ) -> dict[str, float]:
        """:meth:`accuracy_mm` at the joint angles ``samples`` (S, n); ``cov`` in natural units."""
        p = self.vector(d)
        corrected = self.chain.forward_with(samples, p)[:, :3, 3]
        before = 1e3 * np.linalg.norm(self.chain.forward(samples)[:, :3, 3] - corrected, axis=1)
        J = np.empty((len(samples), 3, len(self._index)))
        step = 1e-7
        for j, k in enumerate(self._index):
            moved = p.copy()
            moved[k] += step
            J[:, :, j] = (self.chain.forward_with(samples, moved)[:, :3, 3] - corrected) / step
        after = 1e3 * np.sqrt(np.einsum("nij,jk,nik->n", J, cov, J))
        return {"before_median": float(np.median(before)), "before_max": float(before.max()),
                "after_median": float(np.median(after)), "after_max": float(after.max()), "samples": len(samples)}

    def corrected(self, d: NDArray[np.float64]) -> Chain:
        """The chain with the table corrected by ``d`` (and the fitted compliance, when fitted)."""
        p = self.vector(d)
        size = self.chain.table.size
        chain = self.chain.corrected(p[:size].reshape(self.chain.table.shape))
        if self.compliance:
            own = np.zeros(self.chain.n_joints) if self.chain.compliance is None else self.chain.compliance
            chain = replace(chain, compliance=own + p[size:])
        return chain


@dataclass(frozen=True)
class JointTrajectory(JointAngles):
    """:class:`JointAngles` at each view's reference time (``joints``), read from a trajectory of
    joint angles ``trajectory`` (T, n; rad) at the robot's ``times`` (T,; s, increasing), whose
    flange pose at any time the fit can ask for through the corrected table: ``motion(d)`` (each
    joint linear between samples). A sensor whose view spans a move (a line-scan camera's rows) takes
    every row's pose from it: the table's error changes along a move as the arm's joints do, which
    one pose per view times the nominal move does not follow (on simulated UR5 line-scan captures,
    an arm 2-3 mm off its table: X's rotation 0.14-0.25 deg off that way, 0.005-0.016 deg this way).

    The estimation core passes ``motion=motion(d)`` to the sensor's ``residuals`` and fits the
    table's columns by finite differences of the residuals (the chain rule through each view's one
    pose does not hold).

    Examples
    --------
    >>> import numpy as np
    >>> from handeye.robot.kinematics import load_arm
    >>> ur5 = load_arm("ur5")
    >>> times = np.array([0.0, 1.0, 2.0])
    >>> q = np.radians([[0, -90, 90, -90, -90, 0], [10, -80, 85, -95, -90, 20], [-15, -100, 95, -80, -85, -30]])
    >>> robot = JointTrajectory(ur5, q[[0, 2]], times=times, trajectory=q)
    >>> bool(np.allclose(robot.motion(np.zeros(robot.n_params))(np.array([1.0])), ur5.forward(q[1:2])))
    True
    """

    times: NDArray[np.float64] | None = None
    trajectory: NDArray[np.float64] | None = None
    describe: str = "joint angles along the trajectory through the arm's table, fitted"
    _last_motion: list = field(default_factory=list, init=False, repr=False, compare=False)  # [(key, poses)] of motion()

    def __post_init__(self) -> None:
        super().__post_init__()
        times = np.asarray(self.times, dtype=float)
        q = np.asarray(self.trajectory, dtype=float)
        if self.times is None or self.trajectory is None or times.ndim != 1 or q.shape != (len(times), self.chain.n_joints):
            raise InputMismatchError(f"a joint trajectory needs times (T,) and joint angles (T, {self.chain.n_joints}); "
                                     f"got {times.shape} and {q.shape}")
        if len(times) < 2 or not np.all(np.diff(times) > 0):
            raise InputMismatchError("a joint trajectory's times must increase, two samples or more")
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "trajectory", q)

    def motion(self, d: NDArray[np.float64]) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
        """The flange's pose at robot times ``t`` (M,) -> (M, 4, 4), through the table corrected by ``d``.

        The last poses are kept: a fit's differences by X and the sensor's unknowns ask again for the
        same ``d`` and times (measured: 45% of a line-scan fit's residual time was this arm's forward
        kinematics)."""
        p = self.vector(d)
        times, trajectory = cast(NDArray[np.float64], self.times), cast(NDArray[np.float64], self.trajectory)  # checked
        last = self._last_motion

        def at(t: NDArray[np.float64]) -> NDArray[np.float64]:
            key = (p.tobytes(), np.asarray(t, dtype=float).tobytes())
            kept = last[0] if last else None  # one read: another thread may replace it meanwhile
            if kept is not None and kept[0] == key:
                return kept[1].copy()
            poses = self.chain.forward_with(joints_at(times, trajectory, t), p)
            last[:] = [(key, poses)]
            return poses.copy()
        return at
