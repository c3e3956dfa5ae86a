"""A laser line profiler's profiles as sensor models (:mod:`handeye.sensors.base`).

A laser line profile sensor (laser triangulation) measures, per robot pose, the points where its
laser plane meets the scene: ``p = (x, 0, z)`` in the sensor's frame (``x`` along the laser line,
``z`` along its measuring axis, ``y = 0`` the laser plane). Each point, mapped through the flange
pose and X into the frame the target is fixed in (the base eye-in-hand, the flange eye-to-hand:
``q = A_i X p`` with ``A_i`` :func:`~handeye.frames.setups.robot_world_A`'s), must lie on the
target's surface; the residual is its signed distance from it (metres), every point weighted alike
and the noise's scale fitted to the data.

* :class:`SphereProfiles`: a ball of known (or unknown: estimated) radius; the unknowns are its
  centre (then its radius). Its closed-form start, :func:`sphere_profiles_start`, solves the
  sphere's equation linearly for X's rotation (from profiles at one flange orientation, or from all
  of them through products of the unknowns), then fits X's translation and the centre.

Examples
--------
>>> import numpy as np
>>> from handeye.sensors.laser.model import SphereProfiles
>>> profiles = [np.array([[0.0, 0.0, 0.05], [0.01, 0.0, 0.049]])] * 3
>>> SphereProfiles("eye_in_hand", ["a", "b", "c"], profiles, radius=0.02).param_names
['centre.x', 'centre.y', 'centre.z', 'radius']
"""

from __future__ import annotations

from collections.abc import Callable
from itertools import permutations
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ...errors import DegenerateMotionError, InputMismatchError
from ...frames.setups import check_setup, robot_world_A, setup_info
from ...geometry.se3 import invert, make_transform, so3_left_jacobian
from ..base import Nuisance
from ..depth.model import sphere_start

__all__ = ["Profiles", "SphereProfiles", "SpheresProfiles", "rotation_from_columns", "sphere_profiles_start",
           "spheres_profiles_start", "LASER_NOISE_M"]

#: A profile's section in the report shows at most this many of its points.
SECTION_POINTS = 400
#: The closed-form start uses at most this many points, evenly taken over the profiles.
START_POINTS = 6000
#: A laser profiler's noise along its measuring axis to state before any fit (m): 20 um, a
#: Gocator 2300's or a Keyence LJ-X8000's repeatability at mid-range is a few um, its linearity tens.
LASER_NOISE_M = 2e-5
#: How far a calibration ball's radius may be off the diameter a session gives (one std, m): a
#: precision ball's grade is a few micrometres; a coating or wear adds some.
RADIUS_TOLERANCE_M = 2e-5


def _points(profiles: list[NDArray[np.float64]]) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Every profile's finite points as (M, 3) rows in the sensor frame, and each row's profile."""
    rows, owner = [], []
    for k, p in enumerate(profiles):
        p = np.asarray(p, dtype=float)
        keep = np.isfinite(p).all(axis=1)
        rows.append(p[keep])
        owner.append(np.full(int(keep.sum()), k))
    return np.concatenate(rows), np.concatenate(owner).astype(np.intp)


class Profiles:
    """What every laser target's model shares: per view (``names``) the profile's points (n_i, 3) in
    the sensor frame (NaN rows: no return), metres, each row's view (``owner``), one noise scale for
    all points (``noise_m`` stated), and the points mapped through X and the flange poses."""

    kind = "laser line profiler"
    groups: tuple[tuple[int, ...], ...] = ((0,),)
    # each target's own (:class:`~handeye.sensors.base.SensorModel`'s members; the target's section in the laser plane)
    target: str
    param_names: list[str]
    param_scale: NDArray[np.float64]
    start: Callable[..., tuple[NDArray[np.float64], NDArray[np.float64]]]
    residuals: Callable[..., NDArray[np.float64]]
    Z: Callable[..., NDArray[np.float64]]
    Z_std: Callable[..., NDArray[np.float64]]
    figures: Callable[..., dict[str, Any]]
    notes: Callable[..., list[str]]
    _section: Callable[..., NDArray[np.float64]]

    def __init__(self, setup: str, names: list[str], profiles: list[NDArray[np.float64]],
                 noise_m: float = LASER_NOISE_M) -> None:
        self.setup = check_setup(setup)
        if len(names) != len(profiles):
            raise InputMismatchError(f"{len(names)} view names and {len(profiles)} profiles: give one profile per view")
        self.names = list(names)
        self.points, self.owner = _points(profiles)
        if np.any(np.abs(self.points[:, 1]) > 1e-9):
            raise InputMismatchError("profile points must lie in the laser plane (y = 0 in the sensor frame)")
        self.noise_m = noise_m
        self.shape = np.ones((len(self.points), 1))
        self._starts: dict[bytes, Any] = {}  # the whole capture's start per robot-world poses (a pure function's answers)

    def view_poses(self) -> None:
        """A profile measures no whole pose."""
        return None

    def _start_rows(self, rows: NDArray[np.intp] | None = None) -> NDArray[np.intp]:
        """The rows a start uses: ``rows`` (default all), at most :data:`START_POINTS` of them, evenly taken."""
        rows = np.arange(len(self.points)) if rows is None else np.asarray(rows)
        if len(rows) > START_POINTS:
            rows = rows[np.linspace(0, len(rows) - 1, START_POINTS).astype(np.intp)]
        return rows

    def _remembered(self, A: NDArray[np.float64], compute: Callable[[], Any]) -> Any:
        """``compute()``, the start on every profile from the robot-world poses ``A``, remembered per
        poses: the same answer however often and in whatever order it is asked (a fold of
        cross-validation starts from it)."""
        key = np.ascontiguousarray(A).tobytes()
        if key not in self._starts:
            self._starts[key] = compute()
        return self._starts[key]

    def _mapped(self, X, A, rows) -> NDArray[np.float64]:
        """The points of ``rows`` in the target's frame (base eye-in-hand, flange eye-to-hand): with
        ``y = 0``, ``x`` times the first column of ``A_i X`` plus ``z`` times its third plus its
        translation (three gathers per view's pose, not a 4x4 product per point)."""
        M = A @ X
        owner, p = self.owner[rows], self.points[rows]
        first, third, origin = (np.ascontiguousarray(M[:, :3, k]) for k in (0, 2, 3))
        return p[:, :1] * first[owner] + p[:, 2:] * third[owner] + origin[owner]

    def _x_jacobian(self, X, A, rows, normal) -> NDArray[np.float64]:
        """The derivatives (M, 6) of each point's distance along ``normal`` (M, 3; the surface's unit
        normal at the mapped point) for a left increment of X (rotation ``a``, translation ``b``:
        ``X p -> exp(a) R_X p + t_X + b``): ``(R_X p) x w . a + w . b`` with ``w = R_A^T normal``."""
        owner, pts = self.owner[rows], self.points[rows]
        R = A[:, :3, :3]
        w = np.stack([np.einsum("mi,mi->m", normal, np.ascontiguousarray(R[:, :, k])[owner]) for k in range(3)], axis=1)
        v = pts[:, :1] * X[:3, 0] + pts[:, 2:] * X[:3, 2]  # R_X p
        return np.concatenate([np.cross(v, w), w], axis=1)

    def noise_mm(self, rows) -> NDArray[np.float64]:
        """The profiler's stated noise (mm)."""
        return np.full(len(rows), 1e3 * self.noise_m)

    def sections(self, X, p, flange2base, views, max_points: int = SECTION_POINTS) -> list[dict[str, NDArray[np.float64]]]:
        """Per view of ``views`` (:class:`~handeye.result.SensorFit`'s ``sections``): at most
        ``max_points`` of its points (x, z; mm) evenly taken, their residuals (mm), and the fitted
        target's section in the laser plane over the profile's extent (the target's own
        ``_section``: x, z in mm, NaN where the plane misses it)."""
        F = np.asarray(flange2base, dtype=float)
        sensor2target = robot_world_A(F, self.setup) @ X  # the sensor's pose in the target's frame, per view
        out = []
        for v in views:
            rows = np.flatnonzero(self.owner == v)
            rows = rows[np.linspace(0, len(rows) - 1, min(len(rows), max_points)).astype(np.intp)]
            pts = self.points[rows][:, [0, 2]]
            x = np.linspace(pts[:, 0].min(), pts[:, 0].max(), 200)
            out.append({"points_mm": 1e3 * pts, "residual_mm": 1e3 * self.residuals(X, p, F, rows)[:, 0],
                        "curve_mm": 1e3 * np.c_[x, self._section(sensor2target[v], p, x)],
                        "plane": "the laser line profiler's plane (x across, z down)"})
        return out


class SphereProfiles(Profiles):
    """Profiles of a ball: per view (``names``) the profile's points (n_i, 3) in the sensor frame
    (NaN rows: no return), metres; ``radius`` (m) given, or None to estimate it with the centre. The
    unknowns: the centre and the radius (a given radius held at its value unless freed by name:
    :attr:`nuisances`)."""

    target = "sphere"

    def __init__(self, setup: str, names: list[str], profiles: list[NDArray[np.float64]], radius: float | None = None,
                 noise_m: float = LASER_NOISE_M) -> None:
        super().__init__(setup, names, profiles, noise_m)
        self.radius = radius
        self.param_names = ["centre.x", "centre.y", "centre.z", "radius"]
        self.param_scale = np.full(len(self.param_names), 1e-3)

    @property
    def nuisances(self) -> tuple[Nuisance, ...]:
        """The ball's radius: held at the diameter the session gives (a precision ball's, within
        :data:`RADIUS_TOLERANCE_M`) unless freed by name, else fitted."""
        return (Nuisance("radius", 3, self.radius, RADIUS_TOLERANCE_M, given=self.radius is not None, unit="mm", scale=1e3),)

    def start(self, flange2base, X, Z, rows=None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """:func:`sphere_profiles_start` on ``rows`` (default all; at most :data:`START_POINTS` of
        them, evenly taken: a start needs no more); the radius, when unknown, from the start's points."""
        rows = np.arange(len(self.points)) if rows is None else np.asarray(rows)
        if len(rows) > START_POINTS:
            rows = rows[np.linspace(0, len(rows) - 1, START_POINTS).astype(np.intp)]
        F = np.asarray(flange2base, dtype=float)
        # the base's origin moved to the flange's mean position: the closed forms' products are
        # better conditioned, and the sensor's mount lies near the origin in both setups
        shift = make_transform(np.eye(3), -np.mean(F[np.unique(self.owner[rows]), :3, 3], axis=0))
        A = robot_world_A(shift @ F, self.setup)
        X0, centre = sphere_profiles_start(A, self.points[rows], self.owner[rows], self.radius)
        X0, centre = _unshifted(X0, centre, shift, self.setup)
        A = robot_world_A(F, self.setup)
        if self.radius is not None:
            return X0, np.r_[centre, self.radius]
        q = self._mapped(X0, A, rows)
        return X0, np.r_[centre, np.median(np.linalg.norm(q - centre, axis=1))]

    def target_params(self, Z) -> NDArray[np.float64]:
        """The unknowns ``p`` of the ball at ``Z``'s translation (its radius known)."""
        if self.radius is None:
            raise InputMismatchError("the ball's pose alone gives its centre, not its radius: give the diameter")
        return np.r_[np.asarray(Z, float)[:3, 3], self.radius]

    def jacobian(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """The residuals' derivatives (M, 1, 6 + k): for a left increment of X (rotation ``a``,
        translation ``b``: ``X p -> exp(a) R_X p + t_X + b``) ``d = |q - c| - r`` moves by
        ``(R_X p) x w . a + w . b`` with ``w = R_A^T u`` and ``u`` the unit normal at the point; by
        ``-u`` with the centre, ``-1`` with the radius."""
        A = robot_world_A(flange2base, self.setup)
        d = self._mapped(X, A, rows) - p[:3]
        u = d / np.sqrt(np.einsum("mi,mi->m", d, d))[:, None]
        J = np.concatenate([self._x_jacobian(X, A, rows, u), -u, -np.ones((len(rows), 1))], axis=1)
        return J[:, None, :]

    def residuals(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """Each point's distance from the sphere (m; positive outside)."""
        A = robot_world_A(flange2base, self.setup)
        d = self._mapped(X, A, rows) - p[:3]
        return (np.sqrt(np.einsum("mi,mi->m", d, d)) - p[3])[:, None]

    def _section(self, sensor2target, p, x) -> NDArray[np.float64]:
        """The ball's near side in the laser plane at ``x`` (z, m): the centre in the sensor frame
        ``c``, the circle of radius ``sqrt(r^2 - c_y^2)`` about ``(c_x, c_z)``."""
        R, t = sensor2target[:3, :3], sensor2target[:3, 3]
        c = R.T @ (p[:3] - t)
        inside = p[3] ** 2 - c[1] ** 2 - (x - c[0]) ** 2
        return np.where(inside >= 0, c[2] - np.sqrt(np.maximum(inside, 0.0)), np.nan)

    def Z(self, X, p) -> NDArray[np.float64]:
        """The ball's centre (a translation: a ball has no orientation)."""
        return make_transform(np.eye(3), p[:3])

    def Z_std(self, p, cov_p) -> NDArray[np.float64]:
        """The centre's std (mm); a ball's orientation is not defined (NaN)."""
        return np.r_[np.full(3, np.nan), 1e3 * np.sqrt(np.clip(np.diag(cov_p)[:3], 0.0, None))]

    def figures(self, p, cov_p) -> dict[str, Any]:
        """The ball's centre and radius."""
        std = np.sqrt(np.clip(np.diag(cov_p), 0.0, None))
        out: dict[str, Any] = {"centre_m": [float(v) for v in p[:3]], "centre_std_mm": [float(1e3 * v) for v in std[:3]],
                               "radius_mm": {"value": float(1e3 * p[3]), "std": float(1e3 * std[3]), "fitted": True}}
        if self.radius is not None:
            out["radius_mm"]["given"] = float(1e3 * self.radius)
        return out

    def notes(self, p, cov_p) -> list[str]:
        """The radius found, when it was estimated."""
        if self.radius is not None:
            return []
        s = float(np.sqrt(max(cov_p[3, 3], 0.0)))
        return [f"the ball's radius was estimated: {1e3 * p[3]:.3f} +- {1e3 * s:.3f} mm (give its diameter to fix it)"]

class SpheresProfiles(SphereProfiles):
    """Profiles of a fixture of balls, each profile of one of them: per view (``names``) the profile's
    points (n_i, 3) in the sensor frame (NaN rows: no return), metres; ``radii`` (m) one per ball,
    known. The unknowns: every ball's centre. Each point belongs to the ball whose surface it is
    nearest at the current estimate (the balls are apart: smooth but at points between balls)."""

    target = "spheres"
    nuisances: tuple[Nuisance, ...] = ()  # the balls' radii are given, their centres the unknowns

    def __init__(self, setup: str, names: list[str], profiles: list[NDArray[np.float64]], radii,
                 noise_m: float = LASER_NOISE_M) -> None:
        Profiles.__init__(self, setup, names, profiles, noise_m)
        self.radii = np.asarray(radii, dtype=float).ravel()
        if len(self.radii) < 2 or np.any(self.radii <= 0):
            raise InputMismatchError(f"radii {list(self.radii)}: a fixture has 2 or more balls, each of a positive "
                                     "radius (m); one ball is SphereProfiles")
        self.radius = None
        self.param_names = [f"ball{k + 1}.{c}" for k in range(len(self.radii)) for c in "xyz"]
        self.param_scale = np.full(len(self.param_names), 1e-3)
        #: the anchor, from the whole capture's start (the first poses started on), kept: per ball its
        #: profiles there (each profile with the ball most of its points are nearest), and whether any
        #: profile fell on it: a ball listed but never scanned is left out of the fit, its centre not determined
        self.profiles_per_ball: NDArray[np.intp] | None = None
        self.scanned = np.ones(len(self.radii), bool)

    def _nearest(self, q, p) -> tuple[NDArray[np.float64], NDArray[np.intp], NDArray[np.float64]]:
        """Each point's offsets from the balls' centres (M, K, 3), its ball and its distance from that surface."""
        d = q[:, None, :] - p.reshape(-1, 3)[None]
        r = np.sqrt(np.einsum("mki,mki->mk", d, d)) - self.radii
        ball = np.argmin(np.where(self.scanned, np.abs(r), np.inf), axis=1)
        return d, ball, r[np.arange(len(q)), ball]

    def residuals(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """Each point's distance (m; positive outside) from its nearest ball's surface."""
        q = self._mapped(X, robot_world_A(flange2base, self.setup), rows)
        return self._nearest(q, p)[2][:, None]

    def jacobian(self, X, p, flange2base, rows) -> NDArray[np.float64]:
        """The residuals' derivatives (M, 1, 6 + 3K): the ball's (:meth:`SphereProfiles.jacobian`) with the
        point's ball's unit normal; ``-u`` with that ball's centre, nothing with the others'."""
        A = robot_world_A(flange2base, self.setup)
        d, ball, _ = self._nearest(self._mapped(X, A, rows), p)
        u = d[np.arange(len(rows)), ball]
        u /= np.linalg.norm(u, axis=1)[:, None]
        centres = np.zeros((len(rows), len(p)))
        for k in range(3):
            centres[np.arange(len(rows)), 3 * ball + k] = -u[:, k]
        return np.concatenate([self._x_jacobian(X, A, rows, u), centres], axis=1)[:, None, :]

    def _section(self, sensor2target, p, x) -> NDArray[np.float64]:
        """The balls' near sides in the laser plane at ``x`` (z, m): the nearest of them (NaN off all)."""
        R, t = sensor2target[:3, :3], sensor2target[:3, 3]
        z = np.full(len(x), np.inf)
        for c, r in zip(((p.reshape(-1, 3) - t) @ R)[self.scanned], self.radii[self.scanned]):
            inside = r**2 - c[1] ** 2 - (x - c[0]) ** 2
            z = np.minimum(z, np.where(inside >= 0, c[2] - np.sqrt(np.maximum(inside, 0.0)), np.inf))
        return np.where(np.isfinite(z), z, np.nan)

    def _per_ball(self, X, p, A, views) -> NDArray[np.intp]:
        """Per ball the profiles of ``views`` at X and the centres ``p`` (each profile counted with the
        ball most of its points are nearest)."""
        rows = np.flatnonzero(np.isin(self.owner, views))
        ball = self._nearest(self._mapped(X, A, rows), p)[1]
        votes = np.zeros((len(self.names), len(self.radii)), dtype=np.intp)
        np.add.at(votes, (self.owner[rows], ball), 1)
        return np.bincount(np.argmax(votes[np.asarray(views)], axis=1), minlength=len(self.radii))

    def start(self, flange2base, X, Z, rows=None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """:func:`spheres_profiles_start` on ``rows`` (default all; at most :data:`START_POINTS`); a
        part of the profiles (a fold of cross-validation) polished from the whole capture's start when
        that fits them. The whole's start fixes the anchor: the balls scanned and their profiles."""
        A = robot_world_A(np.asarray(flange2base, dtype=float), self.setup)
        every = self._start_rows()
        whole = self._remembered(A, lambda: spheres_profiles_start(A, self.points[every], self.owner[every], self.radii,
                                                                   2 * self.noise_m))
        if self.profiles_per_ball is None:
            ball = whole[2]
            self.scanned = np.bincount(ball[ball >= 0], minlength=len(self.radii)) > 0
            self.profiles_per_ball = self._per_ball(whole[0], self._all_balls(whole[1][self.scanned]), A,
                                                    np.unique(self.owner))
        if rows is None or len(rows) == len(self.points):
            return whole[0], self._all_balls(whole[1][self.scanned])
        rows = self._start_rows(rows)
        on = self.scanned
        rms, X0, centres = _balls_polished(A[self.owner[rows]], self.points[rows], self.radii[on], whole[0], whole[1][on])
        if rms <= 5 * self.noise_m:
            return X0, self._all_balls(centres)
        X0, centres, _ = spheres_profiles_start(A, self.points[rows], self.owner[rows], self.radii, 2 * self.noise_m)
        return X0, self._all_balls(centres[self.scanned])

    def _all_balls(self, centres: NDArray[np.float64]) -> NDArray[np.float64]:
        """The unknowns from the scanned balls' centres (k, 3): a ball never scanned held at the
        scanned ones' mean (no point reaches it: its unknowns are left undetermined)."""
        out = np.repeat(np.mean(centres, axis=0, keepdims=True), len(self.radii), axis=0)
        out[self.scanned] = centres
        return out.ravel()

    def target_params(self, Z) -> NDArray[np.float64]:
        """Refused: the fixture's unknowns are every ball's centre, which one pose (``Z``: the first
        ball's) does not give; a rig's sensors cannot share a fixture through it."""
        raise InputMismatchError("a fixture of balls is fitted as every ball's centre, which one pose of it does not "
                                 "give: sensors that share it in a rig cannot be mapped onto each other's balls; give "
                                 "each sensor its own target (shared_target=False), or scan one ball")

    def Z(self, X, p) -> NDArray[np.float64]:
        """The first scanned ball's centre (a translation, as a ball's)."""
        k = int(np.argmax(self.scanned))
        return make_transform(np.eye(3), p[3 * k:3 * k + 3])

    def Z_std(self, p, cov_p) -> NDArray[np.float64]:
        """The first scanned ball's centre's std (mm); a ball's orientation is not defined (NaN)."""
        k = int(np.argmax(self.scanned))
        return np.r_[np.full(3, np.nan), 1e3 * np.sqrt(np.clip(np.diag(cov_p)[3 * k:3 * k + 3], 0.0, None))]

    def figures(self, p, cov_p) -> dict[str, Any]:
        """Every ball's centre with its std, diameter and profiles."""
        std = np.sqrt(np.clip(np.diag(cov_p), 0.0, None)).reshape(-1, 3)
        centres = p.reshape(-1, 3).copy()
        centres[~self.scanned], std[~self.scanned] = np.nan, np.nan  # a ball never scanned: not determined
        counts = self._counts()
        return {"centres_m": [[float(v) for v in c] for c in centres],
                "centres_std_mm": [[float(1e3 * v) for v in s] for s in std],
                "diameters_mm": [float(2e3 * r) for r in self.radii], "profiles": [int(n) for n in counts]}

    def _counts(self) -> NDArray[np.intp]:
        """Per ball its profiles at the whole capture's start (none before it)."""
        return self.profiles_per_ball if self.profiles_per_ball is not None else np.zeros(len(self.radii), int)

    def notes(self, p, cov_p) -> list[str]:
        """How many profiles each ball got; a ball with fewer than :data:`BALL_PROFILES` said clearly."""
        counts = self._counts()
        balls = [f"ball {k + 1} ({2e3 * r:.1f} mm) {n}" for k, (r, n) in enumerate(zip(self.radii, counts))]
        out = [f"profiles per ball: {', '.join(balls)}"]
        for k, (r, n) in enumerate(zip(self.radii, counts)):
            if not self.scanned[k]:
                out.append(f"ball {k + 1} ({2e3 * r:.1f} mm), listed under target: diameters: no profile was told to be of it, "
                           "so its centre is not determined and it is left out of the fit; X and the other balls' "
                           f"centres rest on their profiles (scan it {BALL_PROFILES} times or more, or list only the "
                           "balls scanned)")
            elif n < BALL_PROFILES:
                out.append(f"ball {k + 1} ({2e3 * r:.1f} mm) got only {n} profile{'' if n == 1 else 's'}: its centre rests on "
                           f"{'them' if n > 1 else 'it'} alone and adds little to X; scan each ball {BALL_PROFILES} times "
                           "or more, from different directions")
        return out


#: A ball of a fixture with fewer profiles than this is named in the notes.
BALL_PROFILES = 3


def _fixture_clusters(A: NDArray[np.float64], views: NDArray[np.intp], k: int, restarts: int = 20) -> NDArray[np.intp]:
    """Each profile's ball (0 .. k-1) of a fixture: a ball is in front of the sensor at about the same
    place in every profile (its circle's centre ``b_i``, within a few centimetres), so ``A_i X b_i``,
    the ball's centre, is about ``R_A v + t_A`` with one unknown ``v`` (X's image of the profiles'
    mean ``b``): k-means of those points with ``v`` fitted too (linear for given balls), from
    ``restarts`` random partitions, the tightest."""
    R, t = A[views, :3, :3], A[views, :3, 3]
    n = len(views)
    rng = np.random.default_rng(0)
    best_cost, best = np.inf, np.zeros(n, dtype=np.intp)
    for _ in range(restarts):
        ball = rng.integers(0, k, n)
        for _ in range(50):
            M = np.zeros((n, 3, 3 + 3 * k))
            M[:, :, :3] = R
            for axis in range(3):
                M[np.arange(n), axis, 3 + 3 * ball + axis] = -1.0
            sol = np.linalg.lstsq(M.reshape(3 * n, -1), -t.ravel(), rcond=None)[0]
            p = np.einsum("nij,j->ni", R, sol[:3]) + t
            C = sol[3:].reshape(k, 3)
            dist = np.linalg.norm(p[:, None] - C[None], axis=2)
            new = np.argmin(dist, axis=1)
            for j in range(k):  # an empty ball takes the profile farthest from its own
                if not np.any(new == j):
                    far = int(np.argmax(dist[np.arange(n), new]))
                    new[far] = j
            if np.array_equal(new, ball):
                break
            ball = new
        cost = float(np.sum(dist[np.arange(n), ball] ** 2))
        if cost < best_cost:
            best_cost, best = cost, ball.copy()
    return best


#: Evaluations a fixture's start polishes each candidate for: enough to tell the right pattern of
#: sides from the wrong ones (measured: RMS within 1% of the polish run to convergence).
POLISH_NFEV = 60


def _balls_polished(A, points, radii, X0, centres0, ball=None) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
    """X and the balls' centres fitted to the points (point ``m`` seen from ``A[m]``) from ``X0`` and
    ``centres0`` (soft L1 of 1 mm; each point its own ``ball``, or the nearest): (robust RMS, X, centres)."""
    R, tA = A[:, :3, :3], A[:, :3, 3]
    K = len(radii)

    def fun(u):
        Rx = Rotation.from_rotvec(u[:3]).as_matrix() @ X0[:3, :3]
        q = np.einsum("mij,mj->mi", R, points @ Rx.T + X0[:3, 3] + u[3:6]) + tA
        r = np.linalg.norm(q[:, None] - (centres0 + u[6:].reshape(K, 3))[None], axis=2) - radii
        return r[np.arange(len(q)), ball] if ball is not None else r[np.arange(len(q)), np.argmin(np.abs(r), axis=1)]

    # a start, polished: the core's fit takes it from here (a wrong pattern of sides would iterate for long)
    res = least_squares(fun, np.zeros(6 + 3 * K), method="trf", loss="soft_l1", f_scale=1e-3, x_scale=1e-3, max_nfev=POLISH_NFEV)
    X = make_transform(Rotation.from_rotvec(res.x[:3]).as_matrix() @ X0[:3, :3], X0[:3, 3] + res.x[3:6])
    return float(np.sqrt(np.median(fun(res.x) ** 2))), X, centres0 + res.x[6:].reshape(K, 3)


def spheres_profiles_start(A: NDArray[np.float64], points: NDArray[np.float64], owner: NDArray[np.intp],
                           radii: NDArray[np.float64], good_m: float = 2 * LASER_NOISE_M
                           ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.intp]]:
    """X, the balls' centres (K, 3; NaN for a ball no profile fell on) and each view's ball (-1: none)
    from points ``p`` (M, 3; y = 0) of a fixture of balls of ``radii``, each profile of one ball, point
    ``m`` seen from ``A[owner[m]]``: the profiles told apart (:func:`_fixture_clusters`), each cluster
    given the ball whose radius its largest circle is nearest (with balls alike, any), then each
    profile's circle put on one side of the laser plane or the other, the patterns that map each
    cluster's centres onto one point best (:func:`_rotation_from_circles`) polished on the points
    (:func:`_balls_polished`), the best. When that fits worse than ``good_m`` (m, robust RMS), a ball
    listed but never scanned is looked for: the same with each ball left out in turn, kept when it
    fits twice as well (one ball's profiles split over two balls fit badly; a ball left out whose
    profiles are there fits worse still). Raises DegenerateMotionError when the profiles fit no X."""
    K = len(radii)
    views, circle_centres, _ = _circles(points, owner, float(np.max(radii)))
    if len(views) < 5:
        raise DegenerateMotionError(f"{len(views)} profiles with a circle of 10 points or more: a fixture of {K} balls "
                                    "needs 5 or more, 3 or more on each ball, with the flange turned between them")
    rho = np.array([np.sqrt(max(float(np.mean(np.sum((points[owner == v][:, [0, 2]] - c[[0, 2]]) ** 2, axis=1))), 0.0))
                    for v, c in zip(views, circle_centres)])
    best = _fixture_start(A, points, owner, views, rho, radii, np.arange(K))
    if K >= 2 and (best is None or best[0] > good_m):
        for j in range(K):
            found = _fixture_start(A, points, owner, views, rho, radii, np.delete(np.arange(K), j))
            if found is not None and (best is None or found[0] < 0.5 * best[0]):
                best = found
    if best is None or best[0] > GOOD_START_M:
        raise DegenerateMotionError(
            f"the profiles of the {K} balls fit no sensor pose ({'none' if best is None else f'{1e3 * best[0]:.2f} mm RMS'}"
            "): check the diameters under target (metres, in the balls' order does not matter) and that the poses are "
            "the profiles'; capture 3 or more profiles of each ball with the flange turned 10 deg or more between them")
    return best[1], best[2], best[3]


def _fixture_start(A, points, owner, views, rho, radii, balls):
    """:func:`spheres_profiles_start` with the profiles on the balls ``balls`` (indices into
    ``radii``) alone: (robust RMS, X, centres (K, 3; NaN off ``balls``), each view's ball), or None
    when no pattern of sides gives an X."""
    K, k = len(radii), len(balls)
    cluster = _fixture_clusters(A, views, k)
    largest = np.array([np.max(rho[cluster == j]) if np.any(cluster == j) else 0.0 for j in range(k)])
    # clusters to balls: the assignment that puts each cluster's largest circle nearest its ball's radius
    orders = [np.array(o) for o in permutations(range(k))]
    order = min(orders, key=lambda o: float(np.sum((largest - radii[balls[o]]) ** 2)))  # cluster j: balls[order[j]]
    local_of_view = np.full(int(owner.max()) + 1, -1, dtype=np.intp)  # each view's ball among ``balls``
    local_of_view[views] = order[cluster]
    radius_of_view = np.where(local_of_view >= 0, radii[balls][np.maximum(local_of_view, 0)], radii[balls[0]])
    rows = np.isin(owner, views)
    candidates = _rotation_from_circles(A, points[rows], owner[rows], radius_of_view, ball=local_of_view)
    few = np.flatnonzero(rows)
    few = few[np.linspace(0, len(few) - 1, min(len(few), 1500)).astype(np.intp)]
    best = None
    for R_X, t_X in candidates:
        X0 = make_transform(R_X, t_X)
        M = A[owner[few]] @ X0
        q = np.einsum("mij,mj->mi", M[:, :3, :3], points[few]) + M[:, :3, 3]
        b = local_of_view[owner[few]]
        centres0 = np.array([np.median(q[b == j], axis=0) if np.any(b == j) else np.zeros(3) for j in range(k)])
        # the points' median lies on the near side: the centre is a radius further from the sensor
        away = centres0 - np.array([np.median(M[b == j, :3, 3], axis=0) if np.any(b == j) else np.zeros(3)
                                    for j in range(k)])
        centres0 += away / np.maximum(np.linalg.norm(away, axis=1), 1e-12)[:, None] * radii[balls][:, None] * 0.8
        found = _balls_polished(A[owner[few]], points[few], radii[balls], X0, centres0, b)
        if best is None or found[0] < best[0]:
            best = found
    if best is None:
        return None
    centres = np.full((K, 3), np.nan)
    centres[balls] = best[2]
    ball_of_view = np.where(local_of_view >= 0, balls[np.maximum(local_of_view, 0)], -1)
    return best[0], best[1], centres, ball_of_view


def _unshifted(X: NDArray[np.float64], centre: NDArray[np.float64], shift: NDArray[np.float64], setup: str
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """X and the centre solved with the base moved by ``shift``, back in the base itself: the
    moved base is the target's frame eye-in-hand (the centre moves back), X's eye-to-hand."""
    back = invert(shift)
    if setup_info(setup).camera_on_flange:
        return X, back[:3, :3] @ centre + back[:3, 3]
    return back @ X, centre


def sphere_profiles_start(A: NDArray[np.float64], points: NDArray[np.float64], owner: NDArray[np.intp],
                          radius: float | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """X and the sphere's centre from points ``p`` (M, 3; y = 0) of a sphere, point ``m`` seen from
    the robot-world pose ``A[owner[m]]`` (:func:`~handeye.frames.setups.robot_world_A`), in closed form.

    X's rotation: from profiles taken at one orientation of the flange (pure translations), where
    the sensor's orientation ``S = R_A R_X`` and ``u = R_A t_X - C`` are constant and every point
    satisfies ``|p|^2 + |t_A|^2 + 2 (S p).t_A + 2 t_A.u + 2 (S p).u + |u|^2 - r^2 = 0``, linear in S's
    first and third columns, ``u``, their products with ``u`` and ``|u|^2 - r^2`` (12 unknowns;
    :func:`_rotation_from_translations`); else, with the radius known, from each profile's circle,
    which puts the ball's centre on either side of the laser plane (:func:`_rotation_from_circles`);
    else from every point through the products of X's columns and translation with the centre
    (:func:`_rotation_lifted`). Then X's translation and the centre
    (:func:`_translation_start`; with the ``radius`` when it is known). Raises DegenerateMotionError
    when neither determines the rotation.
    """
    candidates = []  # (rotation, translation to start from)
    R_T = _rotation_from_translations(A, points, owner)
    if R_T is not None:
        candidates.append((R_T, np.zeros(3)))
    if len(np.unique(owner)) >= LIFTED_PROFILES:
        try:
            candidates.append(_rotation_lifted(A[owner], points))
        except DegenerateMotionError:
            pass
    best = _best_start(A[owner], points, candidates, radius)
    if radius is not None and (best is None or best[3] > GOOD_START_M):  # each profile's circle, both sides
        best = _best_start(A[owner], points, _rotation_from_circles(A, points, owner, radius),
                           radius, best)
    if best is None:
        raise DegenerateMotionError(
            "the profiles do not determine the sensor's rotation in closed form: capture 3 or more profiles at one "
            "orientation of the flange, moving it across the ball (pure translations), or 15 or more profiles with the "
            "flange turned 10 deg or more about two or three axes between them")
    R_X, t_X, C, _ = best
    return make_transform(R_X, t_X), C


#: Flange orientations within this angle (rad) count as one (the profiles between them pure translations).
SAME_TURN = np.radians(0.5)


def rotation_from_columns(c1: NDArray[np.float64], c3: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """The rotation whose first and third columns are nearest ``c1`` and ``c3``, or None when they are
    far from orthonormal (the data did not determine them)."""
    n1, n3 = np.linalg.norm(c1), np.linalg.norm(c3)
    if not (0.5 < n1 < 2.0 and 0.5 < n3 < 2.0 and abs(c1 @ c3) < 0.5 * n1 * n3):
        return None
    U, _, Vt = np.linalg.svd(np.column_stack([c1, np.cross(c3, c1), c3]))
    return U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt


def _rotation_from_translations(A: NDArray[np.float64], points: NDArray[np.float64], owner: NDArray[np.intp]
                                ) -> NDArray[np.float64] | None:
    """X's rotation from the largest group of 3 or more profiles taken at one flange orientation
    (see :func:`sphere_profiles_start`), or None without such a group."""
    R = A[:, :3, :3]
    # turned by less than SAME_TURN: trace(R_i^T R_j) = 1 + 2 cos(angle), for every pair at once
    close = np.einsum("nij,mij->nm", R, R) > 1.0 + 2.0 * np.cos(SAME_TURN)
    groups: list[list[int]] = []
    free = np.ones(len(A), bool)
    for v in range(len(A)):
        if free[v]:
            members = np.flatnonzero(close[v] & free)
            free[members] = False
            groups.append(members.tolist())
    views = [g for g in groups if len(g) >= 3 and np.isin(owner, g).any()]
    if not views:
        return None
    g = max(views, key=len)
    rows = np.isin(owner, g)
    p, tA = points[rows], A[owner[rows], :3, 3]
    x, z = p[:, 0], p[:, 2]
    M = np.column_stack([2 * x[:, None] * tA, 2 * z[:, None] * tA, 2 * tA, 2 * x, 2 * z, np.ones(len(p))])
    rhs = -(x**2 + z**2 + np.sum(tA**2, axis=1))
    scale = np.linalg.norm(M, axis=0)
    scale[scale == 0] = 1.0
    sol = np.linalg.lstsq(M / scale, rhs, rcond=None)[0] / scale
    S = rotation_from_columns(sol[0:3], sol[3:6])
    return None if S is None else R[g[0]].T @ S


#: The products' closed form needs this many profiles (each gives about three of its 42 unknowns).
LIFTED_PROFILES = 15
#: A start whose points lie within this RMS (m) of the sphere is good enough to fit from.
GOOD_START_M = 1e-3


#: Half a turn about the sensor's y axis (the laser plane's normal): x and z reversed.
FLIP_Y = np.diag([-1.0, 1.0, -1.0])


def _best_start(A, points, candidates, radius, best=None):
    """Of the candidate rotations, each with its translation start, the one that leads to the best
    fit: (R_X, t_X, C, rms) as X and the centre fitted to at most 1,500 of the points from them give
    them (:func:`_polished`: the closed form's own translation can lie in another basin of the fit,
    191 mm off on a simulated capture with one turn about two axes, where its polished one was 3 mm
    off), the rms what that fit leaves; or ``best`` when none beats it."""
    few = np.linspace(0, len(points) - 1, min(len(points), 1500)).astype(np.intp)
    # each rotation also turned half a turn about the laser plane's normal: the profiles of pure
    # translations fit both nearly alike (a simulated pendant capture started 176 deg off, and its fit
    # stayed there at 1.6 mm RMS), the turns tell them apart once polished
    ranked = best
    for R_X, t0 in [c for R, t0 in candidates for c in ((R, t0), (R @ FLIP_Y, t0))]:
        t_X, C = _translation_start(A, points, R_X, t0, radius, POLISH_EVALUATIONS)
        rms, R_X, t_X, C = _polished(A[few], points[few], R_X, t_X, C, radius, POLISH_EVALUATIONS)
        if ranked is None or rms < ranked[3]:
            ranked = (R_X, t_X, C, rms)
    if ranked is None or ranked is best:
        return best
    rms, R_X, t_X, C = _polished(A[few], points[few], *ranked[:3], radius)  # the chosen one polished to the end
    return (R_X, t_X, C, rms) if best is None or rms < best[3] else best


def x_increment_columns(v: NDArray[np.float64], g: NDArray[np.float64], rotvec: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per point (M, 6) the derivatives of a residual by X's increment, a rotation vector ``rotvec``
    left of X's rotation then a translation, from the point turned by X (``v = exp(rotvec) R_X p``)
    and the residual's gradient ``g`` by the point in the flange frame (before ``R_A``): with
    ``d(exp(u) w)/du = -[exp(u) w]x J_l(u)``, ``(v x g)^T J_l`` and ``g``."""
    return np.c_[np.cross(v, g) @ so3_left_jacobian(rotvec), g]


#: A candidate's polish is ranked after at most this many evaluations: a start in the right basin
#: converges in 3-15 (a simulated 12-profile capture), one in another crawls to scipy's cap of 900
#: (47 of 51 s a session); the best is then polished to the end.
POLISH_EVALUATIONS = 100


def _polished(A, points, R_X, t_X, C, radius, max_nfev: int | None = None
              ) -> tuple[float, NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """X and the centre (and the radius) fitted together to ``points`` from a start: the robust RMS
    distance (m) the fit leaves, what tells a good start from a bad one, and X's rotation and
    translation and the centre it found."""
    R, tA = A[:, :3, :3], A[:, :3, 3]

    def fun(u):
        Rx = Rotation.from_rotvec(u[:3]).as_matrix() @ R_X
        q = np.einsum("mij,mj->mi", R, points @ Rx.T + u[3:6]) + tA
        r = radius if radius is not None else u[9]
        return np.linalg.norm(q - u[6:9], axis=1) - r

    def jac(u):
        # analytic (finite differences took ~4,000 evaluations a polish, 47 of a 12-profile session's 51 s):
        # d(exp(u) v)/du = -[exp(u) v]x J_l(u); the distance's derivative is the unit vector n along q - C
        v = points @ (Rotation.from_rotvec(u[:3]).as_matrix() @ R_X).T
        q = np.einsum("mij,mj->mi", R, v + u[3:6]) + tA
        d = q - u[6:9]
        n = d / np.maximum(np.linalg.norm(d, axis=1), 1e-300)[:, None]
        nR = np.einsum("mi,mij->mj", n, R)  # n^T R_A
        J = np.empty((len(points), len(u)))
        J[:, :6] = x_increment_columns(v, nR, u[:3])
        J[:, 6:9] = -n
        if radius is None:
            J[:, 9] = -1.0
        return J

    u0 = np.r_[np.zeros(3), t_X, C] if radius is not None else np.r_[np.zeros(3), t_X, C, np.median(np.abs(fun(
        np.r_[np.zeros(3), t_X, C, 0.0])))]
    res = least_squares(fun, u0, jac, method="trf", loss="soft_l1", f_scale=1e-3, x_scale=1e-3, max_nfev=max_nfev)
    u = res.x
    return (float(np.sqrt(np.median(res.fun**2))), Rotation.from_rotvec(u[:3]).as_matrix() @ R_X, u[3:6].copy(),
            u[6:9].copy())


#: Up to this many profiles every pattern of sides is tried (2^n); beyond, the sides are chosen one
#: profile at a time from the best of :data:`SIDE_STARTS` random patterns.
ALL_SIDES, SIDE_STARTS = 12, 64


def _circles(points: NDArray[np.float64], owner: NDArray[np.intp], radius: float | NDArray[np.float64]
             ) -> tuple[NDArray[np.intp], NDArray[np.float64], NDArray[np.float64]]:
    """Per profile with 10 points or more, the circle its points lie on in the laser plane (an
    algebraic fit: ``x^2 + z^2 = 2 a x + 2 b z + c``): the profiles, the circles' centres (x, 0, z)
    and the ball's centre's distance from the plane, ``sqrt(r^2 - rho^2)`` (``radius``: the ball's, or
    per view its ball's)."""
    views, centres, offsets = [], [], []
    for v in np.unique(owner):
        p = points[owner == v]
        if len(p) < 10:
            continue
        x, z = p[:, 0], p[:, 2]
        a, b, c = np.linalg.lstsq(np.c_[2 * x, 2 * z, np.ones(len(p))], x**2 + z**2, rcond=None)[0]
        rho2 = c + a * a + b * b
        r = radius if np.ndim(radius) == 0 else np.asarray(radius)[v]
        views.append(v)
        centres.append([a, 0.0, b])
        offsets.append(np.sqrt(max(r**2 - rho2, 0.0)))
    return np.array(views, dtype=np.intp), np.array(centres), np.array(offsets)


def _rotation_from_circles(A: NDArray[np.float64], points: NDArray[np.float64], owner: NDArray[np.intp],
                           radius: float | NDArray[np.float64], keep: int = 3, ball: NDArray[np.intp] | None = None
                           ) -> list[tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """X's rotation from each profile's circle: the ball's centre is the circle's centre moved
    ``sqrt(r^2 - rho^2)`` along the laser plane's normal, to one side or the other; for each pattern
    of sides the centres must map onto one point, ``A_i X b_i = C``
    (:func:`~handeye.sensors.depth.model.sphere_start`, linear; with ``ball``, per view its ball of a
    fixture, and ``radius`` per view: onto that ball's centre); the ``keep`` patterns that do best
    give the rotations returned, each with the translation its pattern gave (none with fewer than 5
    profiles)."""
    views, centres, offsets = _circles(points, owner, radius)
    n = len(views)
    if n < 5:
        return []
    Av = A[views]
    labels = np.zeros(n, dtype=np.intp) if ball is None else np.asarray(ball)[views]
    n_balls = int(labels.max()) + 1

    def cost(signs):
        b = centres + np.c_[np.zeros(n), signs * offsets, np.zeros(n)]
        try:
            X, C = sphere_start(Av, b, np.arange(n), labels, n_balls)
        except DegenerateMotionError:
            return np.inf, None
        q = np.einsum("nij,nj->ni", (Av @ X)[:, :3, :3], b) + (Av @ X)[:, :3, 3]
        return float(np.sum((q - C[labels]) ** 2)), X
    rng = np.random.default_rng(0)
    patterns = (((np.arange(2**n)[:, None] >> np.arange(n)) & 1) * 2 - 1 if n <= ALL_SIDES
                else rng.choice([-1, 1], (SIDE_STARTS, n)))
    # every pattern scored at once (the same least squares, batched: 4,096 patterns of 12 profiles took
    # 0.9 s one at a time, each fold's start of a laser session again), the best ones solved as before
    order = np.argsort(_pattern_costs(Av, centres, offsets, labels, n_balls, patterns), kind="stable")
    scored = sorted(((cost(patterns[k]), patterns[k]) for k in order[:keep]), key=lambda item: item[0][0])
    out = []
    for (best, X), signs in scored:
        if n > ALL_SIDES:  # one profile's side at a time while that helps
            improved = True
            while improved:
                improved = False
                for k in range(n):
                    trial = signs.copy()
                    trial[k] = -trial[k]
                    c, Xt = cost(trial)
                    if c < best:
                        best, X, signs, improved = c, Xt, trial, True
        if X is not None:
            out.append((X[:3, :3], X[:3, 3]))
    return out


def _pattern_costs(Av: NDArray[np.float64], centres: NDArray[np.float64], offsets: NDArray[np.float64],
                   labels: NDArray[np.intp], n_balls: int, patterns: NDArray[np.intp], batch: int = 1024) -> NDArray[np.float64]:
    """Per pattern of sides (P, n) the cost :func:`_rotation_from_circles` gives it: the balls' centres
    (each circle's centre moved ``offsets`` along the laser plane's normal to the pattern's side) mapped
    through :func:`~handeye.sensors.depth.model.sphere_start`'s X, their squared distances from their
    ball's centre; infinite where that X is not determined. The same least squares for every pattern at
    once, ``batch`` at a time: a QR per pattern (its ``R`` has the matrix's singular values, for the
    check that X is determined), and for X's translation and the centres, whose columns do not depend
    on the sides, one pseudo-inverse for all."""
    n = len(centres)
    R_A, t_A = Av[:, :3, :3], Av[:, :3, 3]
    cols = 12 + 3 * n_balls
    out = np.full(len(patterns), np.inf)
    if 3 * n < cols:
        return out
    rhs = -t_A.reshape(-1)
    fixed = np.zeros((n, 3, cols - 9))  # the columns of X's translation and the centres
    fixed[:, :, :3] = R_A
    for axis in range(3):
        fixed[np.arange(n), axis, 3 + 3 * labels + axis] = -1.0
    fixed_rows = fixed.reshape(3 * n, cols - 9)
    fixed_pinv = np.linalg.pinv(fixed_rows)
    for at in range(0, len(patterns), batch):
        signs = np.asarray(patterns[at:at + batch], float)
        b = centres[None] + (signs * offsets)[..., None] * np.array([0.0, 1.0, 0.0])  # (P, n, 3)
        M = np.empty((len(b), 3 * n, cols))
        M[..., :9] = np.einsum("mij,pmk->pmijk", R_A, b).reshape(len(b), 3 * n, 9)
        M[..., 9:] = fixed_rows
        Q, R = np.linalg.qr(M)
        sv = np.linalg.svd(R, compute_uv=False)
        ok = sv[:, -1] >= 1e-6 * sv[:, 0]
        R[~ok] = np.eye(cols)  # not determined: its cost is infinite, whatever is solved here
        sol = np.linalg.solve(R, np.einsum("pji,j->pi", Q, rhs)[..., None])[..., 0]
        u, _, vt = np.linalg.svd(sol[:, :9].reshape(-1, 3, 3))
        R_X = np.einsum("pij,pjk->pik", u * np.c_[np.ones((len(u), 2)), np.linalg.det(u @ vt)][:, None, :], vt)
        rest = (rhs[None] - np.einsum("pij,pj->pi", M[..., :9], R_X.reshape(-1, 9))) @ fixed_pinv.T
        C = rest[:, 3:].reshape(-1, n_balls, 3)
        q = np.einsum("mij,pjk,pmk->pmi", R_A, R_X, b) + np.einsum("mij,pj->pmi", R_A, rest[:, :3]) + t_A
        out[at:at + batch] = np.where(ok, np.sum((q - C[:, labels]) ** 2, axis=(1, 2)), np.inf)
    return out


def _rotation_lifted(A: NDArray[np.float64], points: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """X's rotation (and a translation) from every point: ``|R_A (R_X p + t_X) + t_A - C|^2 = r^2``
    with ``v = R_X p + t_X`` is ``|p|^2 + 2 p.R_X^T t_X + |t_X|^2 + 2 v.R_A^T (t_A - C) + |t_A - C|^2
    = r^2``, linear in X's first and third columns, ``R_X^T t_X`` (x, z), ``t_X``, ``C``, the
    products of X's columns and of ``t_X`` with ``C`` (27), and ``|t_X|^2 + |C|^2 - r^2``: 42
    unknowns; the flange must turn about two axes or more."""
    x, z = points[:, 0], points[:, 2]
    R, tA = A[:, :3, :3], A[:, :3, 3]
    Rt = np.swapaxes(R, 1, 2)  # R_A^T
    g = np.einsum("mij,mj->mi", Rt, tA)  # R_A^T t_A
    m = len(points)
    Rt_flat = Rt.reshape(m, 9)
    # tau_x, tau_z, kappa; c1, c3, t_X; C; -2 [x c1^T R^T C + z c3^T R^T C + t^T R^T C] (products u_j C_k)
    M = np.column_stack([2 * x, 2 * z, np.ones(m), 2 * x[:, None] * g, 2 * z[:, None] * g, 2 * g, -2 * tA,
                         -2 * x[:, None] * Rt_flat, -2 * z[:, None] * Rt_flat, -2 * Rt_flat])
    rhs = -(x**2 + z**2 + np.sum(tA**2, axis=1))
    scale = np.linalg.norm(M, axis=0)
    scale[scale == 0] = 1.0
    sol = np.linalg.lstsq(M / scale, rhs, rcond=None)[0] / scale
    R_X = rotation_from_columns(sol[3:6], sol[6:9])
    if R_X is None:
        raise DegenerateMotionError(
            "the profiles do not determine the sensor's rotation in closed form: capture 3 or more profiles at one "
            "orientation of the flange, moving it across the ball (pure translations), or turn the flange 10 deg or "
            "more about two or three axes between profiles")
    return R_X, sol[9:12]


#: The start's translation: held near the sensor's mount by a prior of this std (m) where the poses
#: determine it weakly (small turns of the flange), so that the fit starts where a mount can be (the
#: base moved to the flange's mean position: the sensor within a metre of it in both setups).
MOUNT_PRIOR_M = 1.0


def _translation_start(A: NDArray[np.float64], points: NDArray[np.float64], R_X: NDArray[np.float64],
                       t_lifted: NDArray[np.float64], radius: float | None = None, max_nfev: int | None = None
                       ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """X's translation and the centre with X's rotation ``R_X`` given: the products of the lifted
    solution leave them poorly determined when the flange turns little (what is determined then is
    the centre less the flange's turn of X's translation), so they are fitted again, each point's
    distance from a sphere whose radius is fitted too, X's translation held near the flange
    (:data:`MOUNT_PRIOR_M`) along what the points do not determine, started from the lifted one when
    that is within reach of a mount, else from the flange's origin; each round at most ``max_nfev``
    evaluations (a start for the polish, which ranks the candidates)."""
    R, tA = A[:, :3, :3], A[:, :3, 3]
    base = np.einsum("mij,mj->mi", R, points @ R_X.T) + tA  # R_A R_X p + t_A

    t0 = t_lifted if np.linalg.norm(t_lifted) < 2 * MOUNT_PRIOR_M else np.zeros(3)
    q0 = base + np.einsum("mij,j->mi", R, t0)
    # the algebraic sphere through q0: |q|^2 = 2 q.C + (r^2 - |C|^2)
    sol = np.linalg.lstsq(np.c_[2 * q0, np.ones(len(q0))], np.sum(q0**2, axis=1), rcond=None)[0]
    C0, r0 = sol[:3], np.sqrt(max(sol[3] + sol[:3] @ sol[:3], 1e-12))
    sigma = [max(float(np.sqrt(np.mean((np.linalg.norm(q0 - C0, axis=1) - r0) ** 2))), LASER_NOISE_M)]

    def fun(u):  # the points' distances in units of their noise, and the mount's prior
        q = base + np.einsum("mij,j->mi", R, u[:3])
        r = radius if radius is not None else u[6]
        return np.r_[(np.linalg.norm(q - u[3:6], axis=1) - r) / sigma[0], u[:3] / MOUNT_PRIOR_M]

    def jac(u):  # analytic: finite differences took 107,000 evaluations, 39 of a laser plan's 43 s
        q = base + np.einsum("mij,j->mi", R, u[:3])
        d = q - u[3:6]
        n = d / np.maximum(np.linalg.norm(d, axis=1), 1e-300)[:, None]
        J = np.zeros((len(q) + 3, len(u)))
        J[:-3, :3] = np.einsum("mi,mij->mj", n, R) / sigma[0]
        J[:-3, 3:6] = -n / sigma[0]
        if radius is None:
            J[:-3, 6] = -1.0 / sigma[0]
        J[-3:, :3] = np.eye(3) / MOUNT_PRIOR_M
        return J

    x = np.r_[t0, C0, r0] if radius is None else np.r_[t0, C0]
    for _ in range(2):  # the noise from the fit, then the fit again with it
        x = least_squares(fun, x, jac, method="lm", max_nfev=max_nfev).x
        sigma[0] = max(float(np.sqrt(np.mean((fun(x)[:-3] * sigma[0]) ** 2))), 1e-7)
    return x[:3], x[3:6]
