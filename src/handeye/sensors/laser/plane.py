"""Profiles of a flat plate: the plane target of a laser line profiler (:mod:`handeye.sensors.base`).

Each profile is a straight line where the laser plane meets the plate; mapped through the flange
pose and X (``q = A_i X p``, :func:`~handeye.frames.setups.robot_world_A`) every point must lie on
one plane ``n . q = d`` fixed in the base (eye-in-hand) or on the flange (eye-to-hand). A profile
gives two equations (its line's offset and slope), so a plane needs more profiles than a ball and
the flange turned about two or three axes between them; what the capture leaves undetermined the
estimation core pins and names.

The unknowns are the plane's normal, in a chart about the first start's normal ``n0`` (``n``
proportional to ``n0 + a e1 + b e2`` with ``e1``, ``e2`` perpendicular to ``n0``: smooth for every
plane within 90 deg of it), and its distance ``d`` from the frame's origin.

Examples
--------
>>> from handeye.pipelines.laser.simulate import laser_scene
>>> sc = laser_scene(20, "eye_in_hand", rng=3, target="plane")
>>> model = PlaneProfiles("eye_in_hand", [f"p{k}" for k in range(20)], sc.profiles)
>>> X0, p0 = model.start(sc.flange2base, None, None)   # the closed form: a start, which the fit refines
>>> bool(np.degrees(np.arccos((np.trace(X0[:3, :3].T @ sc.X[:3, :3]) - 1) / 2)) < 0.5)
True
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ...errors import DegenerateMotionError
from ...frames.setups import robot_world_A
from ...geometry.se3 import make_transform, perpendicular_basis
from .model import LASER_NOISE_M, Profiles, rotation_from_columns, x_increment_columns

__all__ = ["PlaneProfiles", "plane_profiles_start", "searched_start"]

#: The searched start tries this many rotations of X (fixed, spread over all rotations), each
#: polished on at most SEARCH_POINTS points; a best fit worse than SEARCH_GIVE_UP_M refuses.
SEARCH_ROTATIONS, SEARCH_POINTS, SEARCH_GIVE_UP_M = 60, 600, 1e-3
#: Searched starts as good as the best whose rotations differ by more than this (deg): X is ambiguous.
AMBIGUOUS_DEG = 1.0
#: The closed form's null space must stand out by this factor (its smallest singular value against
#: the next): else the profiles' poses do not determine X's rotation and the plane.
SEPARATION = 5.0


class PlaneProfiles(Profiles):
    """Profiles of a plate: per view (``names``) the profile's points (n_i, 3) in the sensor frame
    (NaN rows: no return), metres. The unknowns: the plane's normal (two, in a chart about the
    first start's) and its distance from the origin of the frame it is fixed in."""

    target = "plane"
    param_names = ["normal.a", "normal.b", "distance"]

    def __init__(self, setup: str, names: list[str], profiles: list[NDArray[np.float64]],
                 noise_m: float = LASER_NOISE_M) -> None:
        super().__init__(setup, names, profiles, noise_m)
        self.param_scale = np.array([1e-3, 1e-3, 1e-3])
        #: the anchor: the normal's chart, from the whole capture's start (the first poses started on), kept
        self._chart: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None = None

    def _anchor(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The normal's chart, fixed by the first start (refused by name before it)."""
        if self._chart is None:
            raise DegenerateMotionError("the plate's normal has no start yet: its unknowns are in a chart the first start fixes")
        return self._chart

    def _normal(self, p) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The unit normal of ``p`` and the chart's unnormalised vector ``n0 + a e1 + b e2``."""
        n0, e1, e2 = self._anchor()
        m = n0 + p[0] * e1 + p[1] * e2
        return m / np.linalg.norm(m), m

    def start(self, flange2base, X, Z, rows=None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """:func:`plane_profiles_start` on ``rows`` (default all; at most :data:`START_POINTS`), the
        normal expressed in the chart of the whole capture's start. Too few turns for the closed form
        (about one axis only, or fewer than 16 profiles): the fit may still determine part of X or all
        of it; a part of the profiles (a fold of cross-validation) is polished from the whole's start
        when that fits them, else searched (:func:`searched_start`), or refused."""
        A = robot_world_A(np.asarray(flange2base, dtype=float), self.setup)
        whole = self._whole_start(A)
        if rows is None or len(rows) == len(self.points):
            X0, n, d = whole
        else:
            X0, n, d = self._started(A, self._start_rows(rows), whole)
        if self._chart is None:
            self._chart = (whole[1], *perpendicular_basis(whole[1]))
        n0, e1, e2 = self._chart
        if n @ n0 < 0:  # the same plane with the normal the chart's way
            n, d = -n, -d
        k = n / (n @ n0)  # n0 + a e1 + b e2, proportional to n
        return X0, np.array([k @ e1, k @ e2, d])

    def _whole_start(self, A) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
        """The start on every profile from the robot-world poses ``A``: the same answer whenever asked
        (remembered per poses)."""
        return self._remembered(A, lambda: self._started(A, self._start_rows(), None))

    def _started(self, A, rows, near) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
        """:func:`plane_profiles_start` on ``rows``, else a polish from ``near`` (the whole's start,
        when it fits them), else :func:`searched_start`."""
        try:
            return plane_profiles_start(A, self.points[rows], self.owner[rows])
        except DegenerateMotionError:
            A_rows, points = A[self.owner[rows]], self.points[rows]
            if near is not None:
                few = np.linspace(0, len(points) - 1, min(len(points), SEARCH_POINTS)).astype(np.intp)
                rms, X0, n, d = _polished(A_rows[few], points[few], near[0][:3, :3])
                if rms <= 5 * self.noise_m:
                    return X0, n, d
            return searched_start(A_rows, points, 5 * self.noise_m)

    def residuals(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """Each point's signed distance from the plane (m)."""
        n, _ = self._normal(p)
        return (self._mapped(X, robot_world_A(flange2base, self.setup), rows) @ n - p[2])[:, None]

    def jacobian(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """The residuals' derivatives (M, 1, 9): X's as the ball's with the plane's normal; the
        normal's chart ``(I - n n^T) e_k / |m| . q``; ``-1`` with the distance."""
        A = robot_world_A(flange2base, self.setup)
        n, m = self._normal(p)
        q = self._mapped(X, A, rows)
        _, e1, e2 = self._anchor()
        project = (np.eye(3) - np.outer(n, n)) / np.linalg.norm(m)
        J = np.c_[self._x_jacobian(X, A, rows, np.broadcast_to(n, q.shape)), q @ (project @ e1), q @ (project @ e2),
                  -np.ones(len(rows))]
        return J[:, None, :]

    def _section(self, sensor2target, p, x) -> NDArray[np.float64]:
        """The plane's line in the laser plane at ``x`` (z, m): ``n_s . (x, 0, z) = d_s`` with the
        normal and distance in the sensor frame."""
        n, _ = self._normal(p)
        R, t = sensor2target[:3, :3], sensor2target[:3, 3]
        n_s, d_s = R.T @ n, p[2] - n @ t
        return (d_s - n_s[0] * x) / n_s[2] if abs(n_s[2]) > 1e-9 else np.full(len(x), np.nan)

    def Z(self, X, p) -> NDArray[np.float64]:
        """The plane as a frame: its z axis the normal, its origin the plane's point nearest the
        frame's origin (a plane has no in-plane position nor turn about its normal)."""
        n, _ = self._normal(p)
        e1, e2 = perpendicular_basis(n)
        return make_transform(np.column_stack([e1, e2, n]), p[2] * n)

    def Z_std(self, p, cov_p) -> NDArray[np.float64]:
        """The normal's tilt (deg, two axes; about the normal NaN) and the distance's std (mm, along
        the normal; in the plane NaN)."""
        _, m = self._normal(p)
        tilt = np.degrees(np.sqrt(np.clip(np.diag(cov_p)[:2], 0.0, None)) / np.linalg.norm(m))
        return np.r_[tilt, np.nan, np.nan, np.nan, 1e3 * np.sqrt(max(cov_p[2, 2], 0.0))]

    def figures(self, p, cov_p) -> dict[str, Any]:
        """The plane's unit normal and distance from the origin of the frame it is fixed in."""
        n, _ = self._normal(p)
        return {"normal": [float(v) for v in n], "distance_m": float(p[2]),
                "distance_std_mm": float(1e3 * np.sqrt(max(cov_p[2, 2], 0.0)))}

    def notes(self, p, cov_p) -> list[str]:
        """Nothing beyond the core's own notes."""
        return []


def plane_profiles_start(A: NDArray[np.float64], points: NDArray[np.float64], owner: NDArray[np.intp]
                         ) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """X, the plane's unit normal and distance from points ``p`` (M, 3; y = 0) of one plane, point
    ``m`` seen from the robot-world pose ``A[owner[m]]``, in closed form.

    ``n . (R_A (x c1 + z c3 + t_X) + t_A) = d`` (``c1``, ``c3`` X's first and third columns) is
    linear and homogeneous in the products ``n c1^T``, ``n c3^T``, ``n t_X^T`` (27), ``n`` and ``d``:
    the null vector of the stacked equations gives them up to scale (``|n| = 1``), then ``c_k =
    (n c_k^T)^T n``. Raises DegenerateMotionError when the null space is not one vector (the
    flange did not turn about two axes or more between profiles)."""
    R, tA = A[owner, :3, :3], A[owner, :3, 3]
    x, z = points[:, 0], points[:, 2]
    m = len(points)
    Rf = R.reshape(m, 9)  # R[j, k] at 3 j + k, as (n c^T)[j, k] = n_j c_k
    M = np.column_stack([x[:, None] * Rf, z[:, None] * Rf, Rf, tA, -np.ones(m)])
    scale = np.linalg.norm(M, axis=0)
    scale[scale == 0] = 1.0
    _, s, Vt = np.linalg.svd(M / scale, full_matrices=False)
    v = Vt[-1] / scale
    n = v[27:30]
    size = np.linalg.norm(n)
    R_X = None
    if s[-2] > SEPARATION * s[-1] and size > 0:
        v, n = v / size, n / size
        c1, c3, t_X = (v[k:k + 9].reshape(3, 3).T @ n for k in (0, 9, 18))
        R_X = rotation_from_columns(c1, c3)
    if R_X is None:
        raise DegenerateMotionError(
            "the profiles of the plane do not determine the sensor's rotation in closed form: capture 16 or more "
            "profiles with the flange turned 10 deg or more about two or three axes between them (a plane's profiles "
            "at one orientation of the flange only slide along it)")
    return make_transform(R_X, t_X), n, float(v[30])


def _polished(A: NDArray[np.float64], points: NDArray[np.float64], R0: NDArray[np.float64]
              ) -> tuple[float, NDArray[np.float64], NDArray[np.float64], float]:
    """From X's rotation ``R0`` (translation 0): the plane through the mapped points, then X, the
    normal and the distance fitted together (soft L1 of 1 mm): (robust RMS in m, X, n, d)."""
    R, tA = A[:, :3, :3], A[:, :3, 3]
    q = np.einsum("mij,mj->mi", R, points @ R0.T) + tA
    centre = q.mean(axis=0)
    n0 = np.linalg.svd(q - centre, full_matrices=False)[2][2]
    e1, e2 = perpendicular_basis(n0)

    def unpack(u):
        m = n0 + u[6] * e1 + u[7] * e2
        return Rotation.from_rotvec(u[:3]).as_matrix() @ R0, u[3:6], m / np.linalg.norm(m), n0 @ centre + u[8]

    def fun(u):
        Rx, t, n, d = unpack(u)
        return (np.einsum("mij,mj->mi", R, points @ Rx.T + t) + tA) @ n - d

    def jac(u):  # analytic: the 60 searches' finite differences cost 10 evaluations a step
        Rx, t, n, _ = unpack(u)
        v = points @ Rx.T
        q = np.einsum("mij,mj->mi", R, v + t) + tA
        g = np.einsum("mji,j->mi", R, n)  # R_A^T n: the residual's gradient by the point before R_A
        m = n0 + u[6] * e1 + u[7] * e2
        dn = (np.eye(3) - np.outer(n, n)) / np.linalg.norm(m)  # the unit normal by its chart's vector
        return np.column_stack([x_increment_columns(v, g, u[:3]), q @ dn @ np.c_[e1, e2], -np.ones(len(q))])

    res = least_squares(fun, np.zeros(9), jac, loss="soft_l1", f_scale=1e-3, x_scale=1e-3, max_nfev=60)
    Rx, t, n, d = unpack(res.x)
    return float(np.sqrt(np.median(res.fun**2))), make_transform(Rx, t), n, float(d)


def searched_start(A: NDArray[np.float64], points: NDArray[np.float64], good_m: float
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """X, the plane's normal and distance from points ``p`` (point ``m`` seen from ``A[m]``) when the
    closed form cannot give them: from each of :data:`SEARCH_ROTATIONS` rotations of X, the plane
    and X polished together on :data:`SEARCH_POINTS` of the points; the best. What the profiles
    leave undetermined is then the fit's to name (it pins it). Raises DegenerateMotionError when
    none fits within :data:`SEARCH_GIVE_UP_M`, or when fits as good as the best (within ``good_m``
    RMS of it) put X's rotation more than :data:`AMBIGUOUS_DEG` apart: such profiles (the flange
    turned about one axis, or not at all) fit a mirrored or turned X as well, which no local std
    shows."""
    few = np.linspace(0, len(points) - 1, min(len(points), SEARCH_POINTS)).astype(np.intp)
    found = [_polished(A[few], points[few], R0) for R0 in Rotation.random(SEARCH_ROTATIONS, random_state=0).as_matrix()]
    best = min(found, key=lambda f: f[0])
    turns = "turned 10 deg or more about two or three axes between them"
    if best[0] > SEARCH_GIVE_UP_M:
        raise DegenerateMotionError(
            f"the profiles of the plane do not determine the sensor's rotation: capture 16 or more profiles with the "
            f"flange {turns} (a plane's profiles at one orientation of the flange only slide along it)")
    rivals = [f for f in found if f[0] <= best[0] + good_m]
    apart = max(np.degrees(np.linalg.norm(Rotation.from_matrix(f[1][:3, :3] @ best[1][:3, :3].T).as_rotvec()))
                for f in rivals)
    if apart > AMBIGUOUS_DEG:
        raise DegenerateMotionError(
            f"the profiles of the plane fit sensor rotations {apart:.0f} deg apart equally well ({best[0] * 1e3:.3f} mm "
            f"RMS): X is ambiguous; capture profiles with the flange {turns} (turns about one axis only, or none, leave "
            "a turned or mirrored X as good a fit)")
    return best[1], best[2], best[3]
