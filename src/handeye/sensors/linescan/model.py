"""A line-scan camera's scans of a planar target as a sensor model (:mod:`handeye.sensors.base`).

A line-scan camera has one row of pixels: its view plane is ``y = 0`` of its frame (the plane
through the optical centre and the row; a row off the principal point is a turn of that frame, which
X holds), and a point ``(x, 0, z)`` of it is imaged at ``u = cx + f (x_n + k1 x_n^3)``, ``x_n = x / z``.
A scan is a pushbroom image: row ``r`` was exposed at ``start + r / line_rate`` on the camera's
clock, while the robot moved the camera (eye-in-hand) or the target on its flange (eye-to-hand)
through the view plane; the robot's clock reads ``delta`` later (the clock offset, an unknown).

Each corner of the target found in a scan at ``(u, r)`` must, at that time, lie in the view plane
and project to ``u``. Its residuals (metres, at the target): its distance from the view plane at the
time of its row (``y`` in the camera frame), and its pixel error along the line times the pixels'
size at its depth (fixed at the start, so that the fit cannot shrink it by moving the focal
length). The unknowns besides X: the target's pose (a chart about its start), ``f``, ``cx``, ``k1``
and ``delta``.

The flange's pose during a scan comes from the robot's time-stamped trajectory
(:class:`Trajectory`): each scan's reference pose (at its middle row; the robot model's pose of the
view, where the robot's error enters) times the trajectory's motion relative to it, interpolated at
each row's time; or, from joint angles along the trajectory, every row's pose through the arm's
fitted table (:class:`~handeye.robot.models.JointTrajectory`'s ``motion``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ...errors import DegenerateMotionError, InputMismatchError
from ...frames.setups import check_setup, predicted_target2cam, robot_world_A
from ...geometry.se3 import invert, make_transform
from ..base import Nuisance
from ..target_pose import ChartedTarget, grid_curve
from .resection import pushbroom_resection, resolve_mirrors

__all__ = ["LineScanCorners", "Trajectory", "LINESCAN_NOISE_PX", "TRAJECTORY_MARGIN_S"]

#: A line-scan corner's noise to state before any fit (px along the line).
LINESCAN_NOISE_PX = 0.2
#: How far a line-scan camera's intrinsics may be off their nominal values (one std): the focal length
#: (a share of the nominal: a lens's tolerance and the focus), the principal point (a share of the
#: line's width: the sensor's placement behind the lens) and the radial distortion k1.
FOCAL_TOLERANCE, CX_TOLERANCE, K1_TOLERANCE = 0.02, 0.02, 0.05
#: Each scan keeps the trajectory's samples this far (s) beyond its first and last row: the room the
#: clock offset has.
TRAJECTORY_MARGIN_S = 0.5


@dataclass(frozen=True)
class Trajectory:
    """The robot's time-stamped flange poses (its own clock): ``times`` (T,) increasing seconds,
    ``flange2base`` (T, 4, 4)."""

    times: NDArray[np.float64]
    flange2base: NDArray[np.float64]

    def __post_init__(self) -> None:
        t = np.asarray(self.times, float)
        if t.ndim != 1 or len(t) != len(self.flange2base) or len(t) < 2:
            raise InputMismatchError(f"trajectory: {t.size} times for {len(self.flange2base)} poses: one time per pose, "
                                     "two or more")
        if not np.all(np.diff(t) > 0):
            k = int(np.flatnonzero(np.diff(t) <= 0)[0])
            raise InputMismatchError(f"trajectory: time does not increase at row {k + 1}: sort the samples, drop repeats")

    def at(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """The flange's pose at times ``t`` (slerp and linear between samples; the ends held)."""
        return _interpolated(self.times, self.flange2base, np.asarray(t, float))


def _interpolated(times, poses, t) -> NDArray[np.float64]:
    k = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2)
    frac = np.clip((t - times[k]) / (times[k + 1] - times[k]), 0.0, 1.0)
    R0 = Rotation.from_matrix(poses[k, :3, :3])
    step = (R0.inv() * Rotation.from_matrix(poses[k + 1, :3, :3])).as_rotvec()
    R = (R0 * Rotation.from_rotvec(frac[:, None] * step)).as_matrix()
    return make_transform(R, (1 - frac)[:, None] * poses[k, :3, 3] + frac[:, None] * poses[k + 1, :3, 3])


#: The flange's motions at given times a line-scan model remembers (:meth:`LineScanCorners._relative`).
RELATIVE_MEMO = 8


class LineScanCorners(ChartedTarget):
    """Scans of a planar target by a line-scan camera (the module docstring).

    Parameters
    ----------
    setup : str
    names : list of str
        Per scan its name (the image file).
    corners : list of (n_i, 2) arrays
        Per scan the corners found: the pixel along the line ``u`` and the row ``r``.
    target_points : list of (n_i, 3) arrays
        Their points in the target frame (m; z = 0).
    starts : (N,) array
        Per scan the time of its row 0 (s, the camera's clock).
    line_rate : float
        Rows per second.
    trajectory : Trajectory
        The robot's flange poses (its clock), covering every scan.
    focal : float
        The focal length's nominal value (px): the start.
    width : int
        Pixels along the line (the principal point starts at its middle).
    noise_px : float
        The corners' noise to state (px).
    target : str
        The target in words.
    orderings : list of index arrays, optional
        The orders of a scan's corners a symmetric target allows (index arrays into each scan's
        points; every scan then sees all of them): a detector reads a mirrored scan's grid in
        mirrored order. Default: the points as given.
    """

    kind = "line-scan camera"
    groups: tuple[tuple[int, ...], ...] = ((0,), (1,))
    # not weighted by the pixel's size: on 20 simulated sessions the fit was no nearer with it (0.096 /
    # 0.189 mm against 0.100 / 0.180), and with 6 scans farther in 3 of 3, its std 2-5x wider
    pixel_columns: tuple[int, ...] = ()
    param_names = ["target.rx", "target.ry", "target.rz", "target.x", "target.y", "target.z", "focal", "cx", "k1",
                   "clock offset"]

    def __init__(self, setup: str, names: list[str], corners: list[NDArray[np.float64]],
                 target_points: list[NDArray[np.float64]], starts: NDArray[np.float64], line_rate: float,
                 trajectory: Trajectory, focal: float, width: int, noise_px: float = LINESCAN_NOISE_PX,
                 target: str = "chessboard", orderings: list[NDArray[np.intp]] | None = None) -> None:
        self.setup = check_setup(setup)
        n = len(names)
        if not (len(corners) == len(target_points) == len(starts) == n):
            raise InputMismatchError(f"{n} scans, {len(corners)} corner sets, {len(target_points)} point sets and "
                                     f"{len(starts)} start times: give one of each per scan")
        if not line_rate > 0 or not focal > 0 or not width > 0:
            raise InputMismatchError(f"line_rate {line_rate:g}, focal {focal:g} px and width {width}: all must be positive")
        self.names, self.target = list(names), target
        self.line_rate, self.focal0, self.width, self.noise_px = float(line_rate), float(focal), int(width), float(noise_px)
        self.uv = np.concatenate([np.asarray(c, float).reshape(-1, 2) for c in corners])
        self._given = np.concatenate([np.asarray(p, float).reshape(-1, 3) for p in target_points])
        self.owner = np.concatenate([np.full(len(c), k) for k, c in enumerate(corners)]).astype(np.intp)
        if len(self._given) != len(self.uv):
            raise InputMismatchError("each scan needs one target point per corner")
        starts = np.asarray(starts, float)
        rows_of = [np.asarray(c, float).reshape(-1, 2)[:, 1] for c in corners]
        #: per scan its reference time (camera clock): the middle of its rows' span
        self.t_ref = np.array([s + 0.5 * (r.min() + r.max()) / line_rate if len(r) else s for s, r in zip(starts, rows_of)])
        #: per corner its time relative to its scan's reference (camera clock)
        self.s = starts[self.owner] + self.uv[:, 1] / line_rate - self.t_ref[self.owner]
        self.trajectory = trajectory
        self.flange2base_ref = trajectory.at(self.t_ref)
        self._relative_samples(starts, rows_of)
        self.param_scale = np.r_[np.full(6, 1e-3), 1.0, 1.0, 1e-3, 1e-3]
        speed = np.linalg.norm(self._sensor_velocity(np.arange(len(names)))[self.owner], axis=1)
        # a row's error moves the corner by the speed over the line rate
        self.shape = np.c_[np.ones(len(self.uv)), speed / np.median(speed)]
        self._resolved: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        self.orderings = None if orderings is None else [np.asarray(o, dtype=np.intp) for o in orderings]

    # -- the trajectory ------------------------------------------------------------------------------
    def _relative_samples(self, starts, rows_of) -> None:
        """Per scan the trajectory's samples around it, relative to its reference pose: their times
        (relative to the reference, robot clock with no offset), rotations and translations."""
        T, F = self.trajectory.times, self.trajectory.flange2base
        keys, R, t = [], [], []
        for k, (start, r) in enumerate(zip(starts, rows_of)):
            lo = start + (r.min() if len(r) else 0.0) / self.line_rate - TRAJECTORY_MARGIN_S
            hi = start + (r.max() if len(r) else 0.0) / self.line_rate + TRAJECTORY_MARGIN_S
            inside = np.flatnonzero((T >= lo) & (T <= hi))
            a, b = max(inside.min() - 1, 0) if inside.size else 0, min(inside.max() + 2, len(T)) if inside.size else len(T)
            first, last = (start + r.min() / self.line_rate, start + r.max() / self.line_rate) if len(r) else (start, start)
            if b - a < 2 or T[a] > first or T[b - 1] < last:
                raise InputMismatchError(f"scan {self.names[k]}: the robot's trajectory does not cover its rows "
                                         f"({first:.3f}-{last:.3f} s on the camera's clock; "
                                         f"the trajectory runs {T[0]:.3f}-{T[-1]:.3f} s): give the trajectory around every "
                                         "scan, on a clock within a fraction of a second of the camera's")
            rel = invert(self.flange2base_ref[k]) @ F[a:b]
            keys.append(T[a:b] - self.t_ref[k] + 1e6 * k)  # one sorted key over every scan's samples
            R.append(rel[:, :3, :3])
            t.append(rel[:, :3, 3])
        self._key = np.concatenate(keys)
        self._R = np.concatenate(R)
        self._t = np.concatenate(t)
        counts = np.array([len(x) for x in keys])
        self._first = np.r_[0, np.cumsum(counts)[:-1]]
        self._last = self._first + counts - 1
        self._step = (Rotation.from_matrix(self._R[:-1]).inv() * Rotation.from_matrix(self._R[1:])).as_rotvec()

    def _relative(self, owner, s) -> NDArray[np.float64]:
        """The flange's motion from its scan's reference pose at times ``s`` (relative, robot clock), the
        last few remembered: a fit's steps of X, the target, the intrinsics and the poses' errors leave
        the times as they were (3/4 of a line-scan calibration's CPU went to this interpolation)."""
        owner, s = np.asarray(owner), np.asarray(s, float)
        memo = self.__dict__.setdefault("_relative_memo", {})
        at = (owner.tobytes(), s.tobytes())
        if at not in memo:
            if len(memo) >= RELATIVE_MEMO:
                memo.pop(next(iter(memo)))
            memo[at] = self._interpolated(owner, s)
        return memo[at].copy()

    def _interpolated(self, owner, s) -> NDArray[np.float64]:
        """:meth:`_relative`, computed."""
        key = s + 1e6 * owner
        k = np.clip(np.searchsorted(self._key, key, side="right") - 1, self._first[owner], self._last[owner] - 1)
        frac = (key - self._key[k]) / (self._key[k + 1] - self._key[k])
        R = (Rotation.from_matrix(self._R[k]) * Rotation.from_rotvec(frac[:, None] * self._step[k])).as_matrix()
        return make_transform(R, self._t[k] + frac[:, None] * (self._t[k + 1] - self._t[k]))

    def _sensor_velocity(self, views, X=None) -> NDArray[np.float64]:
        """Per scan of ``views`` the sensor's velocity relative to the target in ``A``'s frame (m/s),
        over the middle of its rows: ``R_A^T dt_A/dt`` (X's translation ignored: for the start)."""
        h = 0.05
        s = np.array([[-h], [h]]) * np.ones((2, len(views)))
        A = [robot_world_A(self.flange2base_ref[views] @ self._relative(np.asarray(views), si), self.setup) for si in s]
        return np.einsum("nji,nj->ni", A[0][:, :3, :3], (A[1][:, :3, 3] - A[0][:, :3, 3]) / (2 * h))

    # -- the sensor model ------------------------------------------------------------------------------
    @property
    def points(self) -> NDArray[np.float64]:  # type: ignore[override]  # read-only: resolved on first use
        """The target's point (M, 3) of every corner: as given, or, with ``orderings``, each scan's in
        the order that agrees with the robot (:meth:`view_poses`; resolved on first use, whichever
        member asks first)."""
        return self._given if self.orderings is None else self._resolution()[1]

    def view_poses(self) -> NDArray[np.float64]:
        """Per scan the target's pose in the camera frame at its reference time: the linear pushbroom
        resection with the nominal intrinsics, for each ordering of its corners (``orderings``) and
        both mirror images, the one that agrees with the robot
        (:mod:`~handeye.sensors.linescan.resection`); the scans' target points (:attr:`points`) are in
        the order chosen. Solved once."""
        return self._resolution()[0]

    def _resolution(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The scans' poses and the target's points in the order chosen (:meth:`view_poses`), solved
        once from the measurements alone (the same whichever member asks first)."""
        if self._resolved is not None:
            return self._resolved
        n = len(self.names)
        w = self._sensor_velocity(np.arange(n))
        orders = cast(list[NDArray[np.intp] | None], self.orderings or [None])
        k = 2 * len(orders)
        poses, velocities = np.empty((n, k, 4, 4)), np.empty((n, k, 3))
        for v in range(n):
            rows = np.flatnonzero(self.owner == v)
            for j, order in enumerate(orders):
                order = np.arange(len(rows)) if order is None else order
                if len(order) != len(rows):
                    raise InputMismatchError(f"scan {self.names[v]}: {len(rows)} corners, an ordering of {len(order)}")
                try:
                    poses[v, 2 * j:2 * j + 2], velocities[v, 2 * j:2 * j + 2], _ = pushbroom_resection(
                        self._given[rows[order], :2], self.uv[rows, 0], self.s[rows], self.focal0, 0.5 * self.width,
                        float(np.linalg.norm(w[v])))
                except DegenerateMotionError as e:
                    raise DegenerateMotionError(f"scan {self.names[v]}: {e}") from None
        choice, _ = resolve_mirrors(poses, velocities, robot_world_A(self.flange2base_ref, self.setup), w)
        points = self._given.copy()
        for v in range(n):
            rows = np.flatnonzero(self.owner == v)
            if orders[choice[v] // 2] is not None:
                points[rows] = self._given[rows[orders[choice[v] // 2]]]
        self._resolved = (poses[np.arange(n), choice], points)
        return self._resolved

    def start(self, flange2base, X, Z, rows=None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """X and the target from the closed form; the nominal focal length, the principal point at the
        line's middle, no distortion, no clock offset. The first start fixes the target's chart and
        each corner's pixel size."""
        if X is None or Z is None:
            raise DegenerateMotionError("a line-scan camera's start needs the scans' poses (at least 3 scans)")
        self._first_start(X, Z, flange2base, self.focal0)  # at each corner's scan's reference pose
        return X, np.r_[self.target_params(Z), self.focal0, 0.5 * self.width, 0.0, 0.0]

    def _in_camera(self, X, p, flange2base, rows, motion=None) -> NDArray[np.float64]:
        """The corners of ``rows`` in the camera frame at their rows' times: the flange's pose there
        from the robot's ``motion`` (its pose at robot times) when given, else each scan's pose in
        ``flange2base`` times the trajectory's move from it."""
        owner = self.owner[rows]
        if motion is not None:  # a row's robot time: its scan's reference, the row's offset from it, the clocks'
            F = motion(self.t_ref[owner] + self.s[rows] + p[9])
        else:
            F = np.asarray(flange2base, float)[owner] @ self._relative(owner, self.s[rows] + p[9])
        target2cam = predicted_target2cam(X, self._target2world(p), F, self.setup)
        return np.einsum("mij,mj->mi", target2cam[:, :3, :3], self.points[rows]) + target2cam[:, :3, 3]

    def project(self, p, xn) -> NDArray[np.float64]:
        """The pixel along the line of normalised coordinates ``xn = x / z``."""
        return p[7] + p[6] * (xn + p[8] * xn**3)

    def residuals(self, X, p, flange2base, rows, motion=None) -> NDArray[np.float64]:
        """Per corner (m): its pixel error along the line times the pixel's size at its depth, and its
        distance from the view plane at its row's time (``motion``: the flange's pose at robot times,
        from a robot model that follows the move, :class:`~handeye.robot.models.JointTrajectory`)."""
        c = self._in_camera(X, p, flange2base, rows, motion)
        du = self.project(p, c[:, 0] / c[:, 2]) - self.uv[rows, 0]
        return np.c_[du * self._pixel_size(rows), c[:, 1]]

    @property
    def nuisances(self) -> tuple[Nuisance, ...]:
        """The line's intrinsics about their nominal values (the focal length the session states, the
        principal point at the line's middle, no distortion), each fitted where the capture determines
        it; the clock offset, which has no nominal value, always fitted."""
        return (Nuisance("focal", 6, self.focal0, FOCAL_TOLERANCE * self.focal0, unit="px"),
                Nuisance("cx", 7, 0.5 * self.width, CX_TOLERANCE * self.width, unit="px"),
                Nuisance("k1", 8, 0.0, K1_TOLERANCE),
                Nuisance("clock_offset", 9, None, 0.01, unit="ms", scale=1e3))

    def figures(self, p, cov_p) -> dict[str, Any]:
        """The fitted intrinsics along the line and the clock offset, with their std."""
        std = np.sqrt(np.clip(np.diag(cov_p), 0.0, None))
        return {"focal_px": {"value": float(p[6]), "std": float(std[6]), "nominal": self.focal0},
                "cx_px": {"value": float(p[7]), "std": float(std[7])},
                "k1": {"value": float(p[8]), "std": float(std[8])},
                "clock_offset_s": {"value": float(p[9]), "std": float(std[9])},
                "line_rate_hz": self.line_rate, "width_px": self.width}

    def notes(self, p, cov_p) -> list[str]:
        """The focal length against its nominal value, and the clock offset."""
        std = np.sqrt(np.clip(np.diag(cov_p), 0.0, None))
        out = [f"the line's intrinsics fitted: focal length {p[6]:.2f} +- {std[6]:.2f} px (nominal {self.focal0:g}: "
               f"{100 * (p[6] / self.focal0 - 1):+.2f}%), principal point {p[7]:.2f} +- {std[7]:.2f} px, k1 {p[8]:.4f} "
               f"+- {std[8]:.4f}; the robot's clock reads {1e3 * p[9]:.2f} +- {1e3 * std[9]:.2f} ms after the camera's"]
        if abs(p[6] / self.focal0 - 1) > 0.2:
            out.append(f"the focal length is {100 * (p[6] / self.focal0 - 1):+.0f}% off its nominal {self.focal0:g} px: "
                       "check the lens and the pixel size the session states")
        return out

    def sections(self, X, p, flange2base, views) -> list[dict[str, Any]]:
        """Per scan of ``views`` what the report draws of it (:class:`~handeye.result.SensorFit`'s
        ``sections``), in the scan's own plane in mm at the target: along the line, each pixel times
        the scan's median pixel size; along the move, each row times the distance the robot moves the
        scan per row. Its corners as found, their residual's size (mm), and the board's grid through
        the corners where the fit puts them: each moved along the line by its pixel error, and to the
        row where it crosses the view plane (its distance from the plane over the rate at which that
        distance changes, first order; the clock offset stepped by 1 ms gives the rate)."""
        F = np.asarray(flange2base, float)
        views = np.asarray(views, dtype=np.intp)
        speed = np.linalg.norm(self._sensor_velocity(views), axis=1)
        q = np.array(p, float)
        q[9] += 1e-3
        out = []
        for v, vel in zip(views, speed):
            rows = np.flatnonzero(self.owner == v)
            r = self.residuals(X, p, F, rows)
            rate = (self.residuals(X, q, F, rows) - r) / 1e-3  # d(residual)/dt, m/s
            dt = -r[:, 1] / np.where(np.abs(rate[:, 1]) > 1e-9, rate[:, 1], np.inf)  # to the view plane
            mpp, step = float(np.median(self._pixel_size(rows))), vel / self.line_rate
            u, row = self.uv[rows, 0], self.uv[rows, 1]
            fitted = np.c_[(u + (r[:, 0] + rate[:, 0] * dt) / self._pixel_size(rows)) * mpp, (row + dt * self.line_rate) * step]
            out.append({"points_mm": 1e3 * np.c_[u * mpp, row * step], "residual_mm": 1e3 * np.linalg.norm(r, axis=1),
                        "curve_mm": 1e3 * grid_curve(self.points[rows], fitted),
                        "plane": "its scan (along the line, along the move; mm at the target)"})
        return out
