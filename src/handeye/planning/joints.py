"""Which joint configurations would determine what a capture did not: the kinematic part of
``handeye plan``.

A calibration from joint angles (:func:`handeye.calibrate_joints`) names the table entries its
capture does not determine. :func:`suggest_joint_views` proposes a few more views that would (or,
when the capture determines them all but moved the joints so little that X's std is mostly the
table's, views that shrink X's std, the joints moved further):
joint configurations near the capture's, with the joints of those entries moved further, where the
calibrated camera sees the whole target and (where the arm's table gives them) inside the joints'
limits, chosen one at a time by how much each shrinks the entries' posterior std (the fit's
Gauss-Newton information, with the pixel noise the capture showed, plus the entries' prior).
Collisions (with the cell, the cables, the arm itself) are not checked: look before the arm moves.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import InputMismatchError
from ..frames.setups import predicted_target2cam
from ..geometry.se3 import perturb
from ..result import Calibration
from ..robot.kinematics import absorbed_parameters, along_parallel_axes
from ..sensors.camera.pnp import project_points_many

__all__ = ["JointViews", "suggest_joint_views", "TABLE_DOMINATES"]


@dataclass(frozen=True)
class JointViews:
    """Views :func:`suggest_joint_views` proposes.

    Attributes
    ----------
    joints : ndarray (k, n)
        Joint angles (rad), in the order to capture them.
    targets : list of str
        The undetermined entries they are chosen for (those along parallel joint axes excluded:
        no capture separates them); empty when they are chosen for X (``aim``).
    ratio_before, ratio_after : ndarray (len(targets),)
        Each target entry's posterior std over its prior's, with the capture as it is and with
        these views added (predicted): below 0.5 counts as determined.
    aim : {'entries', 'X'}
        What the views are for: the undetermined entries, or (when every entry views can determine
        is determined but X's std is mostly the table's: :data:`TABLE_DOMINATES`) X's std.
    x_std_before, x_std_after : float
        X's translation std (m, the norm over the axes; predicted by the fit's information) with
        the capture as it is and with these views added.
    x_std_table_known : float
        X's translation std the capture would give with the arm's table known.
    """

    joints: NDArray[np.float64]
    targets: list[str]
    ratio_before: NDArray[np.float64]
    ratio_after: NDArray[np.float64]
    aim: str = "entries"
    x_std_before: float = float("nan")
    x_std_after: float = float("nan")
    x_std_table_known: float = float("nan")

    @property
    def needed(self) -> bool:
        """Whether views have something to add: undetermined entries they can determine, or X's std
        mostly the table's (:data:`TABLE_DOMINATES`); when not, ``joints`` is empty."""
        return bool(self.targets) or self.x_std_before > TABLE_DOMINATES * self.x_std_table_known

    @property
    def determined_after(self) -> list[str]:
        """The target entries these views are predicted to determine."""
        return [t for t, r in zip(self.targets, self.ratio_after) if r < 0.5]


#: Views are proposed for X when its translation std is more than this many times what the same
#: capture gives with the arm's table known: the joints moved too little to tell the table's
#: errors from X. Measured (simulated UR5 and Panda, 1-3 mm off their tables, 25 views): see
#: docs/benchmarks.md (bench_kinematic.py).
TABLE_DOMINATES = 5.0


def suggest_joint_views(cal: Calibration, joints: ArrayLike | None = None, n_views: int = 5,
                        image_size: tuple[int, int] | None = None, candidates: int = 3000,
                        rng: int | np.random.Generator | None = 0) -> JointViews:
    """Joint configurations to capture next, so that the entries of the arm's table that ``cal``
    left undetermined become determined, or, when it left none that views can determine and X's
    std is mostly the table's (:data:`TABLE_DOMINATES`), so that X's std shrinks.

    Parameters
    ----------
    cal : Calibration
        A calibration from joint angles with pixels (``cal.kinematic``, ``cal.object_points``,
        ``cal.image_points``, the intrinsics).
    joints : array_like (N, n), optional
        The joint angles (rad) of the views ``cal`` used (default ``cal.kinematic.joints``).
    n_views : int
    image_size : (width, height), optional
        Where the target must be seen whole (default: twice the principal point).
    candidates : int
        Joint configurations drawn about the capture's to choose from.

    Returns
    -------
    JointViews
        Empty ``joints`` when views have nothing to add (every entry views can determine is
        determined, X's std not mostly the table's) or no candidate sees the target.
    """
    k = cal.kinematic
    if k is None or cal.image_points is None or cal.object_points is None or cal.camera_matrix is None:
        raise InputMismatchError("suggest_joint_views needs a calibration from joint angles with its detections "
                                 "(handeye.calibrate_joints with image_points, or a joint session)")
    q = np.asarray(k.joints if joints is None else joints, dtype=float)
    if q.shape != (len(cal.image_points), k.nominal.n_joints):
        raise InputMismatchError(f"joints must be the ({len(cal.image_points)}, {k.nominal.n_joints}) joint angles of the "
                                 f"views the calibration used; got shape {q.shape}")
    parallel = along_parallel_axes(k.nominal)
    targets = [n for n in k.undetermined if n not in parallel]
    K, dist = np.asarray(cal.camera_matrix, dtype=float), np.asarray(cal.dist_coeffs, dtype=float).ravel()
    size = image_size or (int(round(2 * K[0, 2])), int(round(2 * K[1, 2])))
    model = _Model(cal, q, K, dist)
    sigma = model.sigma()
    info = model.information_per_view(q).sum(axis=0) / sigma**2 + np.diag(np.r_[np.zeros(12), np.ones(len(k.names))])
    x_before, x_known = _x_std(info), _x_std(info[:12, :12])
    aim = "entries" if targets else "X"
    empty = JointViews(np.empty((0, q.shape[1])), targets, np.empty(0), np.empty(0), aim, x_before, x_before, x_known)
    if not empty.needed:
        return empty
    pick = [k.names.index(t) + 12 for t in targets]
    before = np.sqrt(np.diag(np.linalg.inv(info))[pick])
    wide = ({int(t.split(".")[0].removeprefix("joint")) - 1 for t in targets} if targets
            else set(range(q.shape[1])))
    pool = _candidates(q, wide, candidates, np.random.default_rng(rng))
    if k.nominal.limits is not None:  # inside the joints' limits, 2 deg from them
        margin = np.radians(2.0)
        pool = pool[((pool >= k.nominal.limits[:, 0] + margin) & (pool <= k.nominal.limits[:, 1] - margin)).all(axis=1)]
    pool = pool[model.sees_whole_target(pool, size)]
    if not len(pool):
        return empty
    info, chosen = _greedy(info, model.information_per_view(pool) / sigma**2, pick, n_views, model.lever())
    after = np.sqrt(np.diag(np.linalg.inv(info))[pick])
    return JointViews(pool[chosen], targets, before, after, aim, x_before, _x_std(info), x_known)


def _x_std(info: NDArray[np.float64]) -> float:
    """X's translation std (m, norm over the axes) from the information matrix over [X, Z, ...]."""
    return float(np.sqrt(np.trace(np.linalg.inv(info)[3:6, 3:6])))


def _greedy(info, per_view, pick: list[int], n_views: int, lever: float) -> tuple[NDArray[np.float64], list[int]]:
    """Views chosen one at a time, each the one that most shrinks the summed posterior variance of
    the entries ``pick`` (or, when none, X's: its translation's and its rotation's at ``lever``)."""
    per_view = per_view.copy()
    chosen = []
    for _ in range(min(n_views, len(per_view))):
        trial = np.linalg.inv(info[None] + per_view)
        if pick:
            score = np.sum(trial[:, pick, pick], axis=1)
        else:
            d = np.diagonal(trial[:, :6, :6], axis1=1, axis2=2)
            score = d[:, 3:].sum(axis=1) + lever**2 * d[:, :3].sum(axis=1)
        best = int(np.argmin(score))
        info = info + per_view[best]
        chosen.append(best)
        per_view[best] = 0.0  # not twice
    return info, chosen


def _candidates(q, wide: set[int], count: int, rng: np.random.Generator) -> NDArray[np.float64]:
    """Joint angles about the capture's: a captured view's, every joint moved by up to its
    capture's spread, the joints ``wide`` (and their neighbours) by more."""
    spread = np.maximum(q.max(axis=0) - q.min(axis=0), np.radians(5.0))
    wide = set(wide) | {j + 1 for j in wide if j + 1 < q.shape[1]} | {j - 1 for j in wide if j > 0}
    scale = 0.5 * spread
    for j in wide:
        scale[j] = 0.5 * spread[j] + np.radians(30.0)
    base = q[rng.integers(0, len(q), count)]
    return base + rng.normal(0.0, 1.0, base.shape) * scale


class _Model:
    """The joint fit's prediction of pixels around its solution, for information (J^T J)."""

    def __init__(self, cal: Calibration, q, K, dist) -> None:
        self.cal, self.q, self.K, self.dist = cal, q, K, dist
        k = cal.kinematic
        compliance = any(n.endswith(".compliance") for n in k.names)
        every = k.nominal.parameter_names(compliance)
        if set(k.names) & set(absorbed_parameters(k.nominal)) or not set(k.names) <= set(every):
            raise InputMismatchError("the calibration's table entries do not match its arm's")
        self.index = np.array([every.index(n) for n in k.names])
        # the fit's parameter vector (Chain.forward_with) about which the entries move
        own = np.zeros(k.nominal.n_joints) if k.nominal.compliance is None else k.nominal.compliance
        self.p = np.r_[(k.chain.table - k.nominal.table).ravel(), k.chain.compliance - own if compliance else []]
        self.prior = np.asarray(k.prior_std, dtype=float)
        self.points = np.asarray(cal.object_points[0], dtype=float)

    def _project(self, T) -> NDArray[np.float64]:
        """The target's points seen from the target2cam poses ``T``: (V, 2M) pixels."""
        owner = np.repeat(np.arange(len(T)), len(self.points))
        return project_points_many(T, np.tile(self.points, (len(T), 1)), owner, self.K, self.dist).reshape(len(T), -1)

    def _pixels(self, x, joints) -> NDArray[np.float64]:
        k = self.cal.kinematic
        # any local parametrization of X and Z: the entries' posterior does not depend on which
        X, Z = perturb(self.cal.X, x[:3], x[3:6]), perturb(self.cal.Z, x[6:9], x[9:12])
        p = self.p.copy()
        p[self.index] += x[12:] * self.prior
        return self._project(predicted_target2cam(X, Z, k.nominal.forward_with(joints, p), self.cal.setup))

    def _jacobian(self, joints) -> NDArray[np.float64]:
        """(V, 2M, P): per view the pixels' derivatives over [X, Z increments, entries in prior units]."""
        P = 12 + len(self.index)
        x0 = np.zeros(P)
        base = self._pixels(x0, joints)
        J = np.empty(base.shape + (P,))
        for p in range(P):
            h = 1e-6 if p < 12 else 1e-4
            x = x0.copy()
            x[p] = h
            J[:, :, p] = (self._pixels(x, joints) - base) / h
        return J

    def information_per_view(self, joints) -> NDArray[np.float64]:
        J = self._jacobian(joints)
        return np.einsum("vmp,vmq->vpq", J, J)

    def lever(self) -> float:
        """The target's median distance from the camera (m): how far X's rotation moves what it sees."""
        return float(np.median(np.linalg.norm(self.cal.target2cam[:, :3, 3], axis=1)))

    def sigma(self) -> float:
        """The pixel noise the capture showed (RMS per coordinate at the solution; the same points in each view)."""
        seen = self.cal.image_points
        if any(len(p) != len(self.points) for p in seen):  # partial views: the fit's points differ by view
            return float(self.cal.refined_rms or 0.3) / np.sqrt(2.0)
        r = self._pixels(np.zeros(12 + len(self.index)), self.q) - np.concatenate(
            [np.asarray(p, dtype=float).reshape(1, -1) for p in seen])
        return max(float(np.sqrt(np.mean(r**2))), 1e-3)

    def sees_whole_target(self, joints, size: tuple[int, int], margin: float = 10.0) -> NDArray[np.bool_]:
        """Whether each configuration shows every target point inside the image, in front of the
        camera, the target's normal within 60 deg of the line of sight."""
        k = self.cal.kinematic
        T = predicted_target2cam(self.cal.X, self.cal.Z, k.chain.forward(joints), self.cal.setup)
        cam_points = np.einsum("vij,mj->vmi", T[:, :3, :3], self.points) + T[:, None, :3, 3]
        in_front = (cam_points[..., 2] > 0.05).all(axis=1)
        px = self._project(T).reshape(len(joints), -1, 2)
        inside = ((px[..., 0] > margin) & (px[..., 0] < size[0] - margin) & (px[..., 1] > margin)
                  & (px[..., 1] < size[1] - margin)).all(axis=1)
        sight = T[:, :3, 3] / np.linalg.norm(T[:, :3, 3], axis=1, keepdims=True)
        facing = np.abs(np.einsum("vi,vi->v", T[:, :3, 2], sight)) > np.cos(np.radians(60.0))
        return in_front & inside & facing
