"""A rig: several sensors on one robot, fitted as one sensor model (:mod:`handeye.sensors.base`).

Sensor 0's X is the core's X; every other sensor ``k`` has its pose in sensor 0's frame,
``sensor_k2sensor_0`` (6 unknowns each, a left increment about its start), so that ``X_k = X @
sensor_k2sensor_0``. Sensors that see one target share its pose (``shared_target``: the first
sensor's target unknowns, mapped into each sensor's own with its ``target_params``); else each
keeps its own. Every sensor's measurements keep their own noise scale (``noise_groups``; a sensor
with fewer residual columns, a laser's one beside a camera's two, padded with zeros). The robot's
poses are the rig's: one table, each sensor's views a subset of it (a view where a sensor saw
nothing has no rows of it).

The relative poses come out of the joint fit with their covariance: two sensors calibrated from the
same robot poses share the robot's error, which cancels in their relative pose.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from ...errors import InputMismatchError
from ...frames.metrics import std_deg_mm
from ...frames.setups import pose_name
from ...geometry.se3 import invert, perturb, skew, so3_left_jacobian
from ..base import Differentiable, DrawsSections, HasNuisances, Nuisance, SensorModel, SharesTarget

__all__ = ["Rig", "DifferentiableRig"]


class Rig:
    """Several sensor models as one (the module docstring).

    Parameters
    ----------
    members : list of SensorModel
        One per sensor, each over all the rig's views (``names`` alike).
    sensor_names : list of str
        The sensors' names (distinct).
    starts : list of (X, p)
        Each sensor's X and unknowns to start from (its own calibration).
    shared_target : bool
        Whether the sensors see one target (its pose then one set of unknowns).
    """

    kind = "rig"

    def __new__(cls, members: list[SensorModel] | None = None, *args: Any, **kwargs: Any) -> Rig:
        """A :class:`DifferentiableRig` when every member has its own derivatives (the core then takes the rig's
        from theirs), else a rig whose fit takes finite differences."""
        if cls is Rig and members is not None and all(isinstance(m, Differentiable) for m in members):
            cls = DifferentiableRig
        return super().__new__(cls)

    def __init__(self, members: list[SensorModel], sensor_names: list[str], starts: list[tuple[NDArray[np.float64],
                 NDArray[np.float64]]], shared_target: bool = True) -> None:
        if len(members) < 2 or not len(members) == len(sensor_names) == len(starts):
            raise InputMismatchError(f"a rig of {len(members)} sensors, {len(sensor_names)} names and {len(starts)} starts: "
                                     "two sensors or more, one name and one start each")
        if len(set(sensor_names)) != len(sensor_names):
            raise InputMismatchError(f"sensor names {sensor_names}: each sensor needs its own name")
        first = members[0]
        for m, name in zip(members, sensor_names):
            if list(m.names) != list(first.names) or m.setup != first.setup:
                raise InputMismatchError(f"sensor {name}: every sensor of a rig is over the rig's views and setup")

        if shared_target and not all(isinstance(m, SharesTarget) for m in members):
            raise InputMismatchError("a shared target needs sensors that map its pose into their unknowns (target_params)")
        if shared_target and len({m.target for m in members}) > 1:
            raise InputMismatchError(f"sensors that see different targets ({', '.join(sorted({m.target for m in members}))}) "
                                     "share none: give shared_target=False")
        self.members, self.sensor_names, self.shared_target = list(members), list(sensor_names), shared_target
        self.setup, self.names, self.groups = first.setup, list(first.names), first.groups
        self.target = first.target if shared_target else " + ".join(dict.fromkeys(m.target for m in members))
        self.owner = np.concatenate([np.asarray(m.owner) for m in members]).astype(np.intp)
        self.width = max(np.asarray(m.shape).shape[1] for m in members)
        # a narrower sensor's rows are padded with 0 residuals (shape 1) in a noise group of their own
        self.shape = np.concatenate([np.pad(np.asarray(m.shape, float), ((0, 0), (0, self.width - np.asarray(m.shape).shape[1])),
                                            constant_values=1.0) for m in members])
        self.member = np.concatenate([np.full(len(m.owner), k) for k, m in enumerate(members)]).astype(np.intp)
        # the entries that are measurements (none of the padding), for the core to fit those alone
        widths = np.array([np.asarray(m.shape).shape[1] for m in members])
        self.entry_mask = None if np.all(widths == self.width) else np.arange(self.width)[None, :] < widths[self.member][:, None]
        self.noise_groups = self._noise_groups()
        self.local = np.concatenate([np.arange(len(m.owner)) for m in members]).astype(np.intp)
        X0 = self._X_start = np.asarray(starts[0][0], float)
        self.rel0 = [invert(X0) @ X for X, _ in starts[1:]]  # sensor_k2sensor_0 to start from
        p_starts = [np.asarray(p, float) for _, p in starts]
        # per sensor how many of its unknowns are its target's pose: with a shared target the first
        # sensor's, mapped into each other's terms (target_params); what follows is the sensor's own
        # (a depth camera's scale and bias), fitted per sensor
        Z0 = first.Z(X0, p_starts[0]) if shared_target else None
        self._n_target = ([len(cast(SharesTarget, m).target_params(Z0)) for m in members] if Z0 is not None else
                          [0] * len(members))
        self._p_starts = [p if k == 0 or not shared_target else p[self._n_target[k]:] for k, p in enumerate(p_starts)]
        n_rel = 6 * (len(members) - 1)
        self._slices: list[slice] = []
        at = n_rel
        for p0 in self._p_starts:
            self._slices.append(slice(at, at + len(p0)))
            at += len(p0)
        own_names = [list(m.param_names)[self._n_target[k] if k else 0:] for k, m in enumerate(members)]
        self.param_names = [f"{s}.{a}" for s in sensor_names[1:] for a in ("rx", "ry", "rz", "x", "y", "z")] + [
            f"{sensor_names[k]}.{n}" for k in range(len(members)) for n in own_names[k]]
        self.param_scale = np.concatenate([np.full(n_rel, 1e-3)] + [np.asarray(m.param_scale, float)[self._n_target[k] if k else 0:]
                                                                     for k, m in enumerate(members)])
        # per unknown the sensor whose rows alone it moves (-1: every sensor's, the shared target), per
        # row its sensor: the core's finite differences step unknowns of different sensors at once
        self.row_block = self.member
        blocks = [np.repeat(np.arange(1, len(members)), 6)]
        for k, p0 in enumerate(self._p_starts):
            block = np.full(len(p0), k)
            if k == 0 and shared_target:
                block[:self._n_target[0]] = -1
            blocks.append(block)
        self.param_block = np.concatenate(blocks).astype(np.intp)

    def _noise_groups(self) -> NDArray[np.intp]:
        """Per entry its noise group: each sensor's column groups its own, the padding one more."""
        blocks, at = [], 0
        for m in self.members:
            c = np.asarray(m.shape).shape[1]
            column = np.zeros(self.width, dtype=np.intp)
            for g, cols in enumerate(m.groups):
                column[list(cols)] = at + g
            at += len(m.groups)
            column[c:] = -1
            blocks.append(np.broadcast_to(column, (len(m.owner), self.width)))
        out = np.concatenate(blocks)
        return np.where(out < 0, at, out)

    # the unknowns ------------------------------------------------------------------------------
    @property
    def nuisances(self) -> tuple[Nuisance, ...]:
        """Every sensor's nuisances (a depth camera's scale and bias, a ball's radius) in the rig's
        unknowns, named ``<sensor>.<name>``; a shared target's are the first sensor's."""
        out = []
        for k, m in enumerate(self.members):
            skip = self._n_target[k] if (self.shared_target and k > 0) else 0
            for n in m.nuisances if isinstance(m, HasNuisances) else ():
                if n.index >= skip:
                    out.append(replace(n, name=f"{self.sensor_names[k]}.{n.name}", index=self._slices[k].start + n.index - skip))
        return tuple(out)

    def relative(self, p, k: int) -> NDArray[np.float64]:
        """Sensor ``k``'s pose in sensor 0's frame (``sensor_k2sensor_0``)."""
        if k == 0:
            return np.eye(4)
        u = p[6 * (k - 1):6 * k]
        return perturb(self.rel0[k - 1], u[:3], u[3:])

    def member_params(self, X, p, k: int) -> NDArray[np.float64]:
        """Sensor ``k``'s own unknowns: its slice, after the shared target's pose in its terms."""
        if self.shared_target and k > 0:
            shared = cast(SharesTarget, self.members[k]).target_params(self.members[0].Z(X, p[self._slices[0]]))
            return np.r_[shared, p[self._slices[k]]]
        return p[self._slices[k]]

    def _member_cov(self, cov_p, k: int) -> NDArray[np.float64]:
        """The covariance of sensor ``k``'s unknowns (:meth:`member_params`) from ``cov_p`` (over the rig's
        unknowns): a shared target's block is the first sensor's (in its terms: for the figures and
        notes of the sensor's own unknowns, a depth scale; its Z's std is the first's)."""
        s = self._slices[k]
        own = cov_p[s, s]
        if not (self.shared_target and k > 0):
            return own
        n = self._n_target[k]
        out = np.zeros((n + own.shape[0],) * 2)
        out[n:, n:] = own
        if n == self._n_target[0]:
            t = slice(self._slices[0].start, self._slices[0].start + n)
            out[:n, :n] = cov_p[t, t]
        return out

    def view_poses(self) -> None:
        """A rig starts from its sensors' own calibrations."""
        return None

    def start(self, flange2base, X, Z, rows=None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Sensor 0's X and, for the others, their start relative to it; the target's (or each
        sensor's) unknowns from the sensors' own calibrations."""
        return self._X_start, np.concatenate([np.zeros(6 * (len(self.members) - 1))] + self._p_starts)

    def residuals(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """Each row's residual from its own sensor, with ``X_k = X @ sensor_k2sensor_0``."""
        rows = np.asarray(rows)
        out = np.zeros((len(rows), self.width))
        for k, m in enumerate(self.members):
            at = np.flatnonzero(self.member[rows] == k)
            if at.size:
                out[at, :np.asarray(m.shape).shape[1]] = m.residuals(X @ self.relative(p, k), self.member_params(X, p, k), flange2base,
                                      self.local[rows[at]])
        return out

    def noise_mm(self, rows) -> NDArray[np.float64]:
        """Each row's stated noise, from its own sensor."""
        rows = np.asarray(rows)
        out = np.empty(len(rows))
        for k, m in enumerate(self.members):
            at = np.flatnonzero(self.member[rows] == k)
            if at.size:
                out[at] = m.noise_mm(self.local[rows[at]])
        return out

    def Z(self, X, p) -> NDArray[np.float64]:
        """Sensor 0's target."""
        return self.members[0].Z(X, self.member_params(X, p, 0))

    def Z_std(self, p, cov_p) -> NDArray[np.float64]:
        """Sensor 0's target's std."""
        s = self._slices[0]
        return self.members[0].Z_std(p[s], cov_p[s, s])

    def figures(self, p, cov_p) -> dict[str, Any]:
        """Each other sensor's pose in sensor 0's frame with its std (deg, mm), from the joint fit."""
        out: dict[str, Any] = {"sensors": list(self.sensor_names), "relative": {}}
        for k in range(1, len(self.members)):
            s = slice(6 * (k - 1), 6 * k)
            out["relative"][pose_name(self.sensor_names[k], self.sensor_names[0])] = {
                "matrix": self.relative(p, k).tolist(), "std_deg_mm": std_deg_mm(cov_p[s, s]).tolist()}
        return out

    def joint_figures(self, X, p, cov, flange2base, rows) -> dict[str, Any]:
        """Each sensor's X with its std (deg, mm) and covariance (as ``Calibration.cov``) from the joint covariance ``cov`` of X's increment
        and ``p`` (first order: ``X_k = X @ rel_k``, a left increment ``(a, b)`` of X and ``(c, e)``
        of ``rel_k`` move X_k by ``a + R_X c`` and ``b + R_X e - [R_X t_rel]x a``), and each
        sensor's RMS residual (mm) over the fit's ``rows``, over all and per view (``view_rms_mm_per_sensor``:
        per view of the rig, None where the sensor has no row in the fit)."""
        out = {}
        R_X = X[:3, :3]
        for k in range(len(self.members)):
            rel = self.relative(p, k)
            J = np.zeros((6, cov.shape[0]))
            J[:3, :3] = np.eye(3)
            J[3:, 3:6] = np.eye(3)
            J[3:, :3] = -skew(R_X @ rel[:3, 3])
            if k > 0:
                c = 6 + 6 * (k - 1)
                J[:3, c:c + 3] = R_X
                J[3:, c + 3:c + 6] = R_X
            cov_k = J @ cov @ J.T
            out[self.sensor_names[k]] = {"X": (X @ rel).tolist(), "std_deg_mm": std_deg_mm(cov_k).tolist(), "cov": cov_k.tolist(),
                                         "kind": self.members[k].kind, "target": self.members[k].target} | self._own(X, p, cov, k)
        rows = np.asarray(rows)
        r = self.residuals(X, p, flange2base, rows)
        rms = [float(1e3 * np.sqrt(np.mean(np.sum(r[self.member[rows] == k] ** 2, axis=1))))
               if np.any(self.member[rows] == k) else None for k in range(len(self.members))]
        per_view = {}
        for k, name in enumerate(self.sensor_names):  # per view of the rig: the sensor's RMS (mm), None where it has no row
            at = self.member[rows] == k
            views = np.asarray(self.owner)[rows[at]]
            sq = np.bincount(views, np.sum(r[at] ** 2, axis=1), minlength=len(self.names))
            n = np.bincount(views, minlength=len(self.names))
            per_view[name] = [float(1e3 * np.sqrt(a / b)) if b else None for a, b in zip(sq, n)]
        return {"X_per_sensor": out, "rms_mm_per_sensor": rms, "view_rms_mm_per_sensor": per_view}

    def _own(self, X, p, cov, k: int) -> dict[str, Any]:
        """Sensor ``k``'s target pose (``Z``, with its std) and its own figures (a ball's radius, a depth
        scale), from its unknowns in the joint fit: the shared target's when the sensors share one."""
        m = self.members[k]
        own, cov_own = self.member_params(X, p, k), self._member_cov(cov[6:, 6:], k)
        figures = m.figures(own, cov_own)
        if self.shared_target and k > 0:  # the first sensor's target, in this sensor's terms: its Z and std are the first's
            s = self._slices[0]
            return {"Z": self.Z(X, p).tolist(), "Z_std_deg_mm": _listed(self.members[0].Z_std(p[s], cov[6 + s.start:6 + s.stop,
                                                                                                      6 + s.start:6 + s.stop])),
                    "figures": figures}
        X_k = X @ self.relative(p, k)
        return {"Z": m.Z(X_k, own).tolist(), "Z_std_deg_mm": _listed(m.Z_std(own, cov_own)), "figures": figures}

    def sections(self, X, p, flange2base, views) -> list[dict[str, Any]]:
        """What the report draws (:class:`~handeye.result.SensorFit`'s ``sections``): per view of
        ``views``, each sensor's own section of it where it has one (its sensor model's ``sections``
        at its X and unknowns in the joint fit), labelled by view and sensor, with its RMS (mm)."""
        out = []
        for k, (m, name) in enumerate(zip(self.members, self.sensor_names)):
            if not isinstance(m, DrawsSections):
                continue
            seen = [v for v in views if np.any(np.asarray(m.owner) == v)]
            for v, sec in zip(seen, m.sections(X @ self.relative(p, k), self.member_params(X, p, k), flange2base, seen)):
                res = np.asarray(sec["residual_mm"], float)
                out.append(dict(sec, label=f"{self.names[v]} {name}", view=int(v),
                                rms_mm=float(np.sqrt(np.mean(res**2))) if res.size else float("nan")))
        return sorted(out, key=lambda sec: sec["view"])

    def notes(self, p, cov_p) -> list[str]:
        """Each sensor's pose in sensor 0's frame, with its std; what each sensor's own unknowns say
        (a depth scale beyond 3 std of 1), named by sensor."""
        out = []
        for name, f in self.figures(p, cov_p)["relative"].items():
            s = np.asarray(f["std_deg_mm"])
            out.append(f"{name}: the sensors' relative pose known to {s[:3].max():.4f} deg / {s[3:].max():.4f} mm (std, "
                       "largest axis; the robot's error common to every pose cancels in it, each pose's own error only where "
                       "both sensors saw that pose)")
        for k, (m, name) in enumerate(zip(self.members, self.sensor_names)):
            # no sensor's target depends on X (the argument of Z is the protocol's): the start's serves
            out += [f"sensor {name}: {n}" for n in m.notes(self.member_params(self._X_start, p, k), self._member_cov(cov_p, k))]
        return out


class DifferentiableRig(Rig):
    """A :class:`Rig` whose members all have their own derivatives (:class:`~handeye.sensors.base.Differentiable`):
    its Jacobian is theirs, chained through ``X_k = X @ sensor_k2sensor_0`` and the shared target (:meth:`jacobian`)."""

    def jacobian(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """The residuals' derivatives (M, width, 6 + k; zero at padded entries) from each member's own
        (M_k, c_k, 6 + k_k) at its ``X_k`` and unknowns. A left increment ``(a, b)`` of X moves ``X_k`` by
        ``(a, b - [R_X t_rel]x a)``; one ``(c, e)`` of ``sensor_k2sensor_0`` (its unknowns ``u``: ``c =
        J_l(u_r) du_r``) moves it by ``(R_X c, R_X e)``; the shared target's unknowns reach sensor ``k``'s
        through the first sensor's Z and ``target_params`` (their derivatives by central differences of
        that map alone: no residual is evaluated for them)."""
        rows = np.asarray(rows)
        p = np.asarray(p, float)
        out = np.zeros((len(rows), self.width, 6 + len(p)))
        R_X = X[:3, :3]
        for k, m in enumerate(self.members):
            at = np.flatnonzero(self.member[rows] == k)
            if not at.size:
                continue
            rel = self.relative(p, k)
            J = cast(Differentiable, m).jacobian(X @ rel, self.member_params(X, p, k), flange2base, self.local[rows[at]])
            c = J.shape[1]
            block = np.zeros((len(at), c, 6 + len(p)))
            block[..., :3] = J[..., :3] - J[..., 3:6] @ skew(R_X @ rel[:3, 3])
            block[..., 3:6] = J[..., 3:6]
            if k > 0:
                u = 6 + 6 * (k - 1)
                block[..., u:u + 3] = J[..., :3] @ R_X @ so3_left_jacobian(p[u - 6:u - 3])
                block[..., u + 3:u + 6] = J[..., 3:6] @ R_X
            s, n = self._slices[k], (self._n_target[k] if self.shared_target and k > 0 else 0)
            block[..., 6 + s.start:6 + s.stop] = J[..., 6 + n:]
            if n:
                t = slice(6 + self._slices[0].start, 6 + self._slices[0].start + self._n_target[0])
                block[..., t] += J[..., 6:6 + n] @ self._target_map(X, p, k)
            out[at, :c] = block
        return out

    def _target_map(self, X, p, k: int, h: float = 1e-4) -> NDArray[np.float64]:
        """The derivatives (n_k, n_0) of sensor ``k``'s target unknowns (``target_params`` of the first sensor's Z)
        by the first sensor's, central differences in units of their scales."""
        first, other = self.members[0], cast(SharesTarget, self.members[k])
        s = self._slices[0]
        scale = np.asarray(first.param_scale, float)[:self._n_target[0]]
        columns = []
        for j in range(self._n_target[0]):
            step = np.zeros(len(p))
            step[s.start + j] = h * max(float(scale[j]), 1e-300)
            plus = other.target_params(first.Z(X, (p + step)[s]))
            minus = other.target_params(first.Z(X, (p - step)[s]))
            columns.append((plus - minus) / (2.0 * step[s.start + j]))
        return np.stack(columns, axis=1)


def _listed(values) -> list | None:
    """A std as result.json holds it (None when the sensor gives none)."""
    return None if values is None else np.asarray(values, float).tolist()
