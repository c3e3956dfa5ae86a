"""Robot and camera streams on separate clocks: interpolation, the clock offset, keyframes.

A robot controller publishes poses at 100-500 Hz, a camera at 10-60 Hz, each stamped by its own
clock and read out with its own delay. Pairing samples by nearest stamp then pairs a camera view
with where the robot was some milliseconds earlier or later: a pose error of speed x offset.

Convention: ``time_offset`` is the camera clock minus the robot clock, in seconds: the camera
sample stamped ``t`` shows the robot as it was at robot time ``t - time_offset``.

The offset is found in two steps:

1. :func:`coarse_offset`: ``A(t) X = Z inv(target2cam(t))`` at every instant, so the angular
   velocity of the flange (in its own frame) is that of the camera relative to the target (in
   the camera's frame) turned by X's rotation, whatever X is. Per lag, the rotation that maps one
   velocity curve onto the other best is found in closed form, and the lag it maps best wins.
2. :func:`refine_offset`: X, Z and the offset fitted jointly to every camera sample, the robot pose
   interpolated at ``t - offset`` (scipy's Slerp for rotations, linear for positions), with a
   robust loss; the offset's std is the larger of the fit's and a jackknife over blocks of time
   (errors of neighbouring samples are correlated, which the fit's own std ignores).

:func:`select_keyframes` then picks well-spread samples where the robot moves slowly, so that
what is left of the timing error costs little, for an ordinary calibration.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import cast

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation, Slerp
from scipy.special import ndtri, stdtrit

from .._shared.text import sentences, summarize
from ..errors import DegenerateMotionError, InputMismatchError
from ..frames.metrics import rotation_error
from ..frames.poses import validate_transforms
from ..frames.setups import constant_transforms, robot_world_A, setup_info
from ..geometry.se3 import invert, make_transform, perturb, rotation_of_valid, to_rotvec_translation
from ..options import KEYFRAMES
from .diagnostics import closed_form, diagnose
from .refinement import refine_pose

__all__ = ["PoseStream", "CoarseOffset", "OffsetFit", "Synchronisation", "check_stream", "interpolate",
           "motion_speeds", "coarse_offset", "refine_offset", "select_keyframes", "search_range", "synchronise",
           "keyframes_at", "offset_cov", "MIN_SAMPLES", "DEFAULT_SEARCH", "KEYFRAMES", "FINE_SPAN", "WEAK_ALIGNMENT"]

#: Fewest samples in a stream.
MIN_SAMPLES = 10
#: Offsets searched by default (s): a second either way covers readout, network and buffering delays.
DEFAULT_SEARCH = (-1.0, 1.0)
#: The robot stream is interpolated only between samples at most this many periods apart (a gap in
#: the recording is not bridged).
MAX_GAP_PERIODS = 3.5
#: Samples of the joint fit (spread evenly in time); more add time, not information about the offset.
FIT_SAMPLES = 600
#: Blocks of time of the offset's jackknife.
JACKKNIFE_BLOCKS = 10
#: How far (s) the joint fit may move the offset from the coarse one: on smooth motions the angular
#: velocities align almost as well tens of milliseconds off (measured: 0.998 against 0.997 at 64 ms),
#: while the joint fit, which also sees the translations, converges from that far.
FINE_SPAN = 0.25
#: Below this alignment of the angular velocities the coarse offset is doubtful (a note says so).
WEAK_ALIGNMENT = 0.5


@dataclass(eq=False)
class PoseStream:
    """Time-stamped poses of one clock: ``times`` (N,) strictly increasing seconds, ``poses`` (N, 4, 4)."""

    times: NDArray[np.float64]
    poses: NDArray[np.float64]
    name: str = "stream"

    @property
    def period(self) -> float:
        """The median time between samples (s)."""
        return float(np.median(np.diff(self.times)))

    @cached_property
    def slerp(self) -> Slerp:
        """scipy's Slerp of the rotations, built once (the joint fit interpolates often)."""
        return Slerp(self.times, rotation_of_valid(self.poses[:, :3, :3]))

    def __len__(self) -> int:
        return len(self.times)


def check_stream(times: ArrayLike, poses: ArrayLike, name: str = "stream") -> PoseStream:
    """A validated :class:`PoseStream`: as many finite, strictly increasing times as rigid poses.

    Raises
    ------
    InputMismatchError
        Counts that differ, too few samples, times not finite or not increasing (the rows named).
    PoseFormatError
        A pose that is not a rigid transform.
    """
    t = np.asarray(times, dtype=float).ravel()
    T = validate_transforms(poses, what=f"{name} poses")
    if T.ndim != 3 or len(t) != len(T):
        raise InputMismatchError(f"{name}: {len(t)} times for {len(T) if T.ndim == 3 else 1} poses; one time per pose")
    if len(t) < MIN_SAMPLES:
        raise InputMismatchError(f"{name}: {len(t)} samples; a stream needs at least {MIN_SAMPLES}")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise InputMismatchError(f"{name}: time not finite at row(s) {summarize(bad)}")
    back = np.flatnonzero(np.diff(t) <= 0)
    if back.size:
        k = int(back[0])
        what = "repeats" if t[k + 1] == t[k] else "goes back"
        raise InputMismatchError(
            f"{name}: time {what} at row {k + 1} ({t[k + 1]!r} after {t[k]!r}; {back.size} such row(s)): "
            "the samples must be in time order with one pose per time stamp; sort them or drop repeats")
    return PoseStream(t, T, name)


def interpolate(stream: PoseStream, t: ArrayLike, max_gap: float | None = None
                ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """The stream's pose at times ``t`` (Slerp for rotations, linear for positions) and, per time,
    whether it lies inside the stream and between samples at most ``max_gap`` apart (default
    :data:`MAX_GAP_PERIODS` periods). Poses outside are those of the nearest end (flagged)."""
    t = np.asarray(t, dtype=float)
    ts = stream.times
    gap = MAX_GAP_PERIODS * stream.period if max_gap is None else max_gap
    k = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2)
    ok = (t >= ts[0]) & (t <= ts[-1]) & (ts[k + 1] - ts[k] <= gap)
    tc = np.clip(t, ts[0], ts[-1])
    R = stream.slerp(tc).as_matrix()
    u = ((tc - ts[k]) / (ts[k + 1] - ts[k]))[:, None]
    p = (1.0 - u) * stream.poses[k, :3, 3] + u * stream.poses[k + 1, :3, 3]
    return make_transform(R, p), ok


def _window_ends(stream: PoseStream, t: ArrayLike, window: float
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """The stream's poses at ``t - window/2`` and ``t + window/2``, and where both are defined
    (inside the stream, not across a gap)."""
    t = np.asarray(t, dtype=float)
    a, ok_a = interpolate(stream, t - 0.5 * window)
    b, ok_b = interpolate(stream, t + 0.5 * window)
    return a, b, ok_a & ok_b


def motion_speeds(stream: PoseStream, t: ArrayLike, window: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rotation (rad/s) and translation (m/s) speeds at times ``t``: the angle turned and the
    distance moved between ``t - window/2`` and ``t + window/2``, over ``window``; NaN where that
    span leaves the stream or crosses a gap."""
    a, b, ok = _window_ends(stream, t, window)
    w = np.where(ok, rotation_error(b, a) / window, np.nan)
    v = np.where(ok, np.linalg.norm(b[:, :3, 3] - a[:, :3, 3], axis=1) / window, np.nan)
    return w, v


@dataclass(frozen=True)
class CoarseOffset:
    """The offset where the two streams' angular velocities align best (:func:`coarse_offset`)."""

    offset: float  #: camera clock minus robot clock (s)
    correlation: float  #: how well one rotation maps the velocities onto each other there (1 = exactly)
    runner_up: float  #: the best alignment further than one window from the peak
    step: float  #: grid step of the search (s)
    search: tuple[float, float]  #: the offsets searched (s)
    at_edge: bool  #: the peak lies at an end of the search range: the true offset may lie beyond


def _xcorr(x: NDArray[np.float64], y: NDArray[np.float64], max_lag: int) -> NDArray[np.float64]:
    """``sum_i x[i] y[i + L]`` for ``L = -max_lag..max_lag`` (FFT), over the last axis of both."""
    size = 1 << int(np.ceil(np.log2(x.shape[-1] + y.shape[-1])))
    c = np.fft.irfft(np.conj(np.fft.rfft(x, size)) * np.fft.rfft(y, size), size)
    return np.concatenate([c[..., size - max_lag:], c[..., :max_lag + 1]], axis=-1)


def _alignment(a: NDArray[np.float64], b: NDArray[np.float64], max_lag: int) -> NDArray[np.float64]:
    """Per lag ``L``, how well the vectors ``b[i + L]`` map onto ``a[i]`` (both (G, 3), NaN where
    undefined) by one rotation: ``max_R sum a . R b / sqrt(sum |a|^2 sum |b|^2)`` over the samples
    where both are defined (Kabsch: the singular values of ``sum a b^T``, the last one signed by the
    determinant); 1 for vectors that one rotation maps onto each other exactly."""
    ma, mb = cast(NDArray[np.bool_], np.isfinite(a).all(axis=1)), cast(NDArray[np.bool_], np.isfinite(b).all(axis=1))
    a0, b0 = np.where(ma[:, None], a, 0.0).T, np.where(mb[:, None], b, 0.0).T
    M = np.moveaxis(_xcorr(a0[:, None, :], b0[None, :, :], max_lag), -1, 0)  # (lags, 3, 3): sum a_i b_j
    count = np.rint(_xcorr(ma.astype(float), mb.astype(float), max_lag))
    aa = _xcorr(np.sum(a0 * a0, axis=0), mb.astype(float), max_lag)
    bb = _xcorr(ma.astype(float), np.sum(b0 * b0, axis=0), max_lag)
    sv = np.linalg.svd(M, compute_uv=False)
    sign = np.sign(np.linalg.det(M))
    with np.errstate(invalid="ignore", divide="ignore"):
        score = (sv[:, 0] + sv[:, 1] + sign * sv[:, 2]) / np.sqrt(aa * bb)
    return np.where((count >= 0.2 * min(ma.sum(), mb.sum())) & np.isfinite(score), score, -np.inf)


def _body_velocity(stream: PoseStream, t: NDArray[np.float64], window: float, inverse: bool = False
                   ) -> NDArray[np.float64]:
    """Angular velocity (rad/s, (G, 3)) of the stream's rotations (or of their inverses) in their
    own moving frame, over ``window`` about each time; NaN where undefined (:func:`motion_speeds`)."""
    a, b, ok = _window_ends(stream, t, window)
    Ra, Rb = a[:, :3, :3], b[:, :3, :3]
    if inverse:
        Ra, Rb = np.swapaxes(Ra, 1, 2), np.swapaxes(Rb, 1, 2)
    w = rotation_of_valid(np.swapaxes(Ra, 1, 2) @ Rb).as_rotvec() / window
    w[~ok] = np.nan
    return w


def coarse_offset(robot: PoseStream, camera: PoseStream, setup: str, search: tuple[float, float] = DEFAULT_SEARCH
                  ) -> CoarseOffset:
    """The clock offset (camera minus robot, s) where the angular velocities of the two streams
    align best, searched over ``search``.

    ``A(t) X = Z inv(target2cam(t))`` at every instant (docs/guide.md, Conventions), so the angular velocity of
    ``A`` (the flange pose; its inverse eye-to-hand) in its own moving frame is that of
    ``cam2target`` in the camera's, turned by X's rotation. Per lag, the rotation that best maps
    one curve onto the other is solved in closed form (Kabsch), and the lag it maps best wins:
    directions must match, not only speeds, which makes the peak sharp where speed profiles
    alone are broad and repetitive.

    The velocities are taken over six camera periods (at least 0.1 s), which averages the camera's
    pose noise away; samples far off their neighbours' path are dropped first and the largest
    velocities clipped at their 98th percentile, so that a wrong pose (a flipped planar PnP
    solution) makes no spike that dominates the sums.
    """
    lo, hi = float(search[0]), float(search[1])
    if not lo < hi:
        raise InputMismatchError(f"offset search range ({lo:g}, {hi:g}) s: the lower end must be below the upper")
    step = min(robot.period, camera.period) / 4.0
    window = max(6.0 * camera.period, 0.1)
    # lags count from the middle of the range: a range far from 0 (clocks with different origins,
    # 1e6 s apart) would otherwise need lags from 0 out to there (a 30 GB cross-correlation)
    centre = 0.5 * (lo + hi)
    shifted = PoseStream(camera.times - centre, camera.poses, camera.name)
    half = hi - centre
    origin = robot.times[0]  # Unix stamps: the grid is built relative to one origin
    start = min(robot.times[0], shifted.times[0] - half) - origin
    stop = max(robot.times[-1], shifted.times[-1] + half) - origin
    if (stop - start) / step > 2_000_000:
        raise InputMismatchError(f"offset search over {(stop - start):.3g} s at {step * 1e3:.3g} ms steps is too long; "
                                 "give a narrower offset range")
    grid = origin + np.arange(start, stop, step)
    robot_inverse = not setup_info(setup).camera_on_flange  # A = inv(flange2base) eye-to-hand
    w_robot = _clipped(_body_velocity(_despiked(robot), grid, window, inverse=robot_inverse))
    w_camera = _clipped(_body_velocity(_despiked(shifted), grid, window, inverse=True))
    # camera(t) ~ robot(t - offset): the camera grid shifted by L steps against the robot's, L = offset / step
    max_lag = int(np.ceil(half / step))
    r = _alignment(w_robot, w_camera, max_lag)
    lags = centre + np.arange(-max_lag, max_lag + 1) * step
    r = np.where((lags >= lo - 0.5 * step) & (lags <= hi + 0.5 * step), r, -np.inf)
    k = int(np.argmax(r))
    if not np.isfinite(r[k]):
        raise InputMismatchError(
            f"the streams hardly overlap in time for any offset in [{lo:g}, {hi:g}] s (robot {robot.times[0]:.3f}-"
            f"{robot.times[-1]:.3f}, camera {camera.times[0]:.3f}-{camera.times[-1]:.3f}); give the offset range "
            "that brings them together")
    offset = lags[k]
    if 0 < k < len(r) - 1 and np.isfinite(r[k - 1]) and np.isfinite(r[k + 1]):  # parabola through the peak
        den = r[k - 1] - 2 * r[k] + r[k + 1]
        if den < 0:
            offset += step * 0.5 * (r[k - 1] - r[k + 1]) / den
    far = np.abs(lags - lags[k]) > window
    runner_up = float(np.max(r[far])) if np.any(far & np.isfinite(r)) else float("nan")
    at_edge = lags[k] - lo < 1.5 * step or hi - lags[k] < 1.5 * step
    return CoarseOffset(float(offset), float(r[k]), runner_up, step, (lo, hi), bool(at_edge))


def _despiked(stream: PoseStream, factor: float = 8.0) -> PoseStream:
    """The stream without samples far off the path of their neighbours (a flipped planar PnP pose,
    a jerk): each interior sample is compared with the Slerp of its two neighbours at its time; a
    deviation beyond ``factor`` times the median (rotation or position) drops it (its neighbours,
    whose own prediction it spoils, may go too: this is for the speed profile only)."""
    t, T = stream.times, stream.poses
    u = ((t[1:-1] - t[:-2]) / (t[2:] - t[:-2]))
    before = rotation_of_valid(T[:-2, :3, :3])
    step = (before.inv() * rotation_of_valid(T[2:, :3, :3])).as_rotvec()
    mid = (before * Rotation.from_rotvec(u[:, None] * step)).as_matrix()  # Slerp of the two neighbours
    rot = rotation_error(T[1:-1, :3, :3], mid)
    pos = np.linalg.norm(T[1:-1, :3, 3] - ((1 - u)[:, None] * T[:-2, :3, 3] + u[:, None] * T[2:, :3, 3]), axis=1)
    bad = (rot > factor * np.median(rot) + 1e-9) | (pos > factor * np.median(pos) + 1e-9)
    keep = np.r_[True, ~bad, True]
    if keep.sum() < MIN_SAMPLES or keep.all():
        return stream
    return PoseStream(t[keep], T[keep], stream.name)


def _clipped(w: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angular velocities (G, 3) whose norm exceeds the 98th percentile scaled down to it."""
    norm = np.linalg.norm(w, axis=1)
    finite = norm[np.isfinite(norm)]
    if finite.size == 0:
        return w
    cap = np.percentile(finite, 98)
    with np.errstate(invalid="ignore", divide="ignore"):
        return w * np.where(norm > cap, cap / norm, 1.0)[:, None]


@dataclass(frozen=True)
class OffsetFit:
    """X, Z and the clock offset fitted jointly to the camera samples (:func:`refine_offset`)."""

    X: NDArray[np.float64]
    Z: NDArray[np.float64]
    offset: float  #: camera clock minus robot clock (s)
    offset_std: float  #: the larger of the fit's std and the block jackknife's (s)
    offset_std_fit: float  #: from the fit's covariance alone (s)
    offset_std_jackknife: float  #: from refits without each block of time (s), nan when not computed
    samples: NDArray[np.intp]  #: indices (into the camera stream) of the samples fitted
    inliers: NDArray[np.bool_]  #: per fitted sample, within 5 sigma of the fit
    sigma: tuple[float, float]  #: residual scale of the inliers: rotation (rad), translation (m)


class _Residuals:
    """Residuals of ``inv(Z) A(t - offset) X target2cam`` per camera sample, over 13 parameters:
    rotation vector and translation updates of X and of Z, and the offset."""

    def __init__(self, robot, camera_times, target2cam, setup, X0, Z0, offset0):
        self.robot, self.t, self.B, self.setup = robot, camera_times, target2cam, setup
        self.X0, self.Z0, self.offset0 = X0, Z0, offset0
        self.sigma = (1.0, 1.0)
        self._cache: tuple[float, NDArray[np.float64]] | None = None

    def robot_A(self, offset: float) -> NDArray[np.float64]:
        if self._cache is None or self._cache[0] != offset:
            f2b, _ = interpolate(self.robot, self.t - offset, max_gap=np.inf)
            self._cache = (offset, robot_world_A(f2b, self.setup))
        return self._cache[1]

    def transforms(self, x: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
        return perturb(self.X0, x[0:3], x[3:6]), perturb(self.Z0, x[6:9], x[9:12]), self.offset0 + x[12]

    def raw(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """(M, 6): rotation vector (rad) and translation (m) of each sample's mismatch."""
        X, Z, offset = self.transforms(x)
        E = invert(Z) @ self.robot_A(offset) @ X @ self.B
        return np.hstack([rotation_of_valid(E[:, :3, :3]).as_rotvec(), E[:, :3, 3]])

    def __call__(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        r = self.raw(x)
        return (r / np.repeat(self.sigma, 3)).ravel()


def _robust_sigma(r: NDArray[np.float64]) -> tuple[float, float]:
    """Per-component residual scale of rotation and translation, from the median absolute value."""
    s_rot = 1.4826 * float(np.median(np.abs(r[:, :3])))
    s_t = 1.4826 * float(np.median(np.abs(r[:, 3:])))
    return max(s_rot, 1e-7), max(s_t, 1e-7)


def _fit(res: _Residuals, x0: NDArray[np.float64]) -> NDArray[np.float64]:
    """The 13 parameters minimising the robust cost (soft L1 beyond 3 sigma) of the samples."""
    return least_squares(res, x0, loss="soft_l1", f_scale=3.0, x_scale="jac").x


def refine_offset(robot: PoseStream, camera: PoseStream, X0: NDArray[np.float64], Z0: NDArray[np.float64], setup: str,
                  offset0: float, span: float, samples: int = FIT_SAMPLES, jackknife: bool = True) -> OffsetFit:
    """X, Z and the clock offset fitted jointly, from ``X0``, ``Z0`` and ``offset0`` (within
    ``offset0 +- span``), to at most ``samples`` camera samples spread evenly in time.

    Each sample's mismatch ``inv(Z) A(t - offset) X target2cam`` (identity when all is right),
    scaled by the robust residual scales of rotation and translation, enters a soft-L1 loss (a
    flipped PnP pose or a jerk of the robot does not pull the fit); the scales are estimated again
    on the inliers and the fit repeated. The offset's std is the larger of the fit's (Gauss-Newton
    covariance of the inliers) and a jackknife over :data:`JACKKNIFE_BLOCKS` blocks of time.
    """
    origin = robot.times[0]  # stamps of 1.5e9 s (Unix time) keep 0.2 us of precision: differences are taken first
    robot = PoseStream(robot.times - origin, robot.poses, robot.name)
    t_cam = camera.times - origin
    inside = (t_cam - offset0 - span >= robot.times[0]) & (t_cam - offset0 + span <= robot.times[-1])
    _, ok = interpolate(robot, t_cam - offset0)
    idx = np.flatnonzero(inside & ok)
    if len(idx) < MIN_SAMPLES:
        raise InputMismatchError(f"only {len(idx)} camera samples fall inside the robot stream at an offset of "
                                 f"{offset0 * 1e3:.1f} ms; the streams must overlap in time")
    if len(idx) > samples:
        idx = idx[np.unique(np.round(np.linspace(0, len(idx) - 1, samples)).astype(np.intp))]
    res = _Residuals(robot, t_cam[idx], camera.poses[idx], setup, X0, Z0, offset0)
    x = np.zeros(13)
    res.sigma = _robust_sigma(res.raw(x))
    for _ in range(2):  # fit, then again with the inliers' scales
        x = _fit(res, x)
        r = res.raw(x)
        inl = _inliers(r, res.sigma)
        res.sigma = _robust_sigma(r[inl])
    x = _fit(res, x)
    inl = _inliers(res.raw(x), res.sigma)
    std_fit, std_jack = _offset_stds(res, x, inl, jackknife)
    X, Z, offset = res.transforms(x)
    if abs(offset - offset0) > span:
        raise InputMismatchError(
            f"the joint fit moved the clock offset from {offset0 * 1e3:.1f} ms to {offset * 1e3:.1f} ms, beyond the "
            f"+-{span * 1e3:.0f} ms allowed about the coarse estimate: the streams may not show the same motion")
    return OffsetFit(X, Z, float(offset), float(np.nanmax([std_fit, std_jack])), float(std_fit), float(std_jack),
                     idx, inl, res.sigma)


def _inliers(r: NDArray[np.float64], sigma: tuple[float, float], k: float = 5.0) -> NDArray[np.bool_]:
    z = np.hstack([r[:, :3] / sigma[0], r[:, 3:] / sigma[1]])
    return cast(NDArray[np.bool_], (np.abs(z) <= k).all(axis=1))


def _jacobian(res: _Residuals, x: NDArray[np.float64], inl: NDArray[np.bool_]
              ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The inliers' scaled residuals (M, 6) at ``x`` and their Jacobian (M, 6, 13), by forward
    differences (13 columns)."""
    eps = np.r_[np.full(12, 1e-7), 1e-6]
    r0 = res(x).reshape(-1, 6)[inl]
    J = np.empty(r0.shape + (13,))
    for j in range(13):
        xj = x.copy()
        xj[j] += eps[j]
        J[..., j] = (res(xj).reshape(-1, 6)[inl] - r0) / eps[j]
    return r0, J


def _offset_stds(res: _Residuals, x: NDArray[np.float64], inl: NDArray[np.bool_], jackknife: bool,
                 blocks: int = JACKKNIFE_BLOCKS) -> tuple[float, float]:
    """The offset's std from the Gauss-Newton covariance of the inliers, and from a jackknife over
    ``blocks`` consecutive blocks of samples: each refit without a block is one Gauss-Newton step
    from the full fit on the remaining rows (a downdate of the normal equations), which moves the
    parameters as a refit does while the change is small."""
    r, J = _jacobian(res, x, inl)
    H_rows = np.einsum("mip,miq->mpq", J, J)  # per sample: its share of J^T J
    g_rows = np.einsum("mip,mi->mp", J, r)
    H, g = H_rows.sum(axis=0), g_rows.sum(axis=0)
    dof = max(r.size - 13, 1)
    try:
        cov = np.linalg.inv(H) * float(np.sum(r * r)) / dof
    except np.linalg.LinAlgError:
        return float("inf"), float("nan")
    std_fit = float(np.sqrt(max(cov[12, 12], 0.0)))
    if not jackknife:
        return std_fit, float("nan")
    edges = np.linspace(0, len(r), blocks + 1).astype(int)
    offsets = []
    for b in range(blocks):  # one 13x13 solve per block
        Hb = H - H_rows[edges[b]:edges[b + 1]].sum(axis=0)
        gb = g - g_rows[edges[b]:edges[b + 1]].sum(axis=0)
        try:
            offsets.append(-np.linalg.solve(Hb, gb)[12])
        except np.linalg.LinAlgError:
            continue
    if len(offsets) < 3:
        return std_fit, float("nan")
    d = np.asarray(offsets) - np.mean(offsets)
    m = len(d)
    var = (m - 1) / m * float(d @ d)
    # a variance from m blocks has m - 1 degrees of freedom: widened so that 3 std cover what 3 std of
    # a known variance would (Student's t against the normal at 99%; 1.26x for 10 blocks). Measured on
    # 60 simulated streams: 3 of 60 offsets beyond 3 std without it, 1 (at 3.03 std) with it.
    widen = float(stdtrit(m - 1, 0.995) / ndtri(0.995))
    return std_fit, widen * float(np.sqrt(var))


def select_keyframes(poses: NDArray[np.float64], speed: NDArray[np.float64], n: int,
                     candidates: NDArray[np.bool_] | None = None) -> NDArray[np.intp]:
    """``n`` well-spread samples of ``poses`` (N, 4, 4) where the robot moves slowly.

    Candidates are the slower half by ``speed`` (any non-negative per-sample speed; slow samples
    lose least to what remains of the timing error); among them, farthest-point sampling in pose
    space (rotation angle in degrees plus distance in centimetres), starting from the slowest.
    Returns sorted indices into ``poses``.
    """
    ok = np.isfinite(speed) & (np.ones(len(poses), bool) if candidates is None else candidates)
    idx = np.flatnonzero(ok)
    if len(idx) <= n:
        return idx
    slow = idx[speed[idx] <= np.median(speed[idx])]
    if len(slow) <= n:
        slow = idx[np.argsort(speed[idx])[:n]]
    P = poses[slow]
    chosen = [int(np.argmin(speed[slow]))]
    dist = np.full(len(slow), np.inf)
    for _ in range(n - 1):  # n picks, each against every candidate at once
        last = P[chosen[-1]]
        d = np.degrees(rotation_error(P, last)) + 100.0 * np.linalg.norm(P[:, :3, 3] - last[:3, 3], axis=1)
        dist = np.minimum(dist, d)
        chosen.append(int(np.argmax(dist)))
    return np.sort(slow[np.unique(chosen)])


# ----------------------------------------------------------------------------------------------------
# The whole synchronisation: range, coarse offset, a first X on keyframes, the joint fit.

def search_range(robot: PoseStream, camera: PoseStream, search: tuple[float, float] | None
                 ) -> tuple[tuple[float, float], str | None]:
    """The offsets to search, and a note when they are not the ones asked for: with no range given,
    :data:`DEFAULT_SEARCH`, unless the stamps of the two streams do not even overlap (clocks with
    different origins, e.g. one from boot and one Unix time): then around the difference of the
    streams' middles, by half the shorter stream's duration."""
    if search is not None:
        try:
            lo, hi = (float(v) for v in search)
        except (TypeError, ValueError):
            raise InputMismatchError(f"offset range {search!r}: give (lo, hi) in seconds") from None
        if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
            raise InputMismatchError(f"offset range ({lo:g}, {hi:g}) s: give two finite numbers, the lower first")
        return (lo, hi), None
    lo, hi = DEFAULT_SEARCH
    r0, r1, c0, c1 = robot.times[0], robot.times[-1], camera.times[0], camera.times[-1]
    if min(r1, c1 - lo) - max(r0, c0 - hi) > 0:
        return (lo, hi), None
    centre = 0.5 * (c0 + c1) - 0.5 * (r0 + r1)
    half = 0.5 * min(r1 - r0, c1 - c0)
    note = (f"the time stamps of the streams do not overlap (robot {r0:.3f}-{r1:.3f} s, camera {c0:.3f}-{c1:.3f} s): "
            f"clocks with different origins; the offset was searched within {centre:.3f} +- {half:.3f} s")
    return (centre - half, centre + half), note


def timing_cost(robot: PoseStream, t_robot: NDArray[np.float64]) -> NDArray[np.float64]:
    """How much a timing error costs at each robot time: rotation speed (deg/s) plus translation
    speed (cm/s), over four robot periods (NaN outside the stream)."""
    w, v = motion_speeds(robot, t_robot, 4.0 * robot.period)
    return np.degrees(w) + 100.0 * v


@dataclass(frozen=True)
class Synchronisation:
    """The clock offset of two streams (:func:`synchronise`)."""

    offset: float  #: camera clock minus robot clock (s)
    offset_std: float  #: s; 0 when the offset was given
    search: tuple[float, float]  #: the offsets searched (s)
    coarse: CoarseOffset | None  #: None when the offset was given
    fit: OffsetFit | None  #: None when the offset was given
    notes: list[str]

    def info(self, robot: PoseStream, camera: PoseStream, keyframe_times: NDArray[np.float64]) -> dict:
        """A plain description for the result files (``Calibration.streams``)."""
        c, f = self.coarse, self.fit
        return {
            "robot_samples": len(robot), "robot_rate_hz": 1.0 / robot.period,
            "camera_samples": len(camera), "camera_rate_hz": 1.0 / camera.period,
            "search_s": list(self.search),
            "coarse_offset_s": None if c is None else c.offset,
            "coarse_alignment": None if c is None else c.correlation,
            "fit_samples": None if f is None else int(len(f.samples)),
            "fit_outliers": None if f is None else int((~f.inliers).sum()),
            "offset_std_fit_s": None if f is None else f.offset_std_fit,
            "offset_std_jackknife_s": None if f is None else f.offset_std_jackknife,
            "keyframe_camera_times_s": [float(v) for v in keyframe_times],
        }


def synchronise(robot: PoseStream, camera: PoseStream, setup: str, offset_range: tuple[float, float] | None = None,
                time_offset: float | None = None, keyframes: int = KEYFRAMES) -> Synchronisation:
    """The clock offset of a robot and a camera stream (camera minus robot, s), with its std.

    :func:`coarse_offset` over the search range (:func:`search_range`); X and Z from a closed form
    on ``keyframes`` keyframes at that offset, outliers left out by :func:`handeye.diagnose`; then
    :func:`refine_offset` from there. With ``time_offset`` given, nothing is estimated.

    Raises
    ------
    InputMismatchError
        The streams do not overlap for any offset searched, or align best at the end of the range.
    DegenerateMotionError
        The keyframes cannot determine X.
    """
    search, note = search_range(robot, camera, offset_range)
    notes = [note] if note else []
    if time_offset is not None:
        if not np.isfinite(time_offset):
            raise InputMismatchError(f"time_offset={time_offset!r}: give a finite number of seconds")
        return Synchronisation(float(time_offset), 0.0, search, None, None,
                               notes + [f"clock offset (camera minus robot) given: {time_offset * 1e3:.2f} ms"])
    coarse = coarse_offset(robot, camera, setup, search)
    if coarse.at_edge:
        raise InputMismatchError(
            f"the angular velocities of the streams align best at {coarse.offset * 1e3:.1f} ms, the end of the searched "
            f"range [{search[0]:g}, {search[1]:g}] s: the offset may lie beyond; give offset_range (--offset-range LO,HI) "
            "around the offset you expect")
    kf, f2b, _ = keyframes_at(robot, camera, coarse.offset, keyframes)
    t2c = camera.poses[kf]
    diag = diagnose(f2b, t2c, setup)
    if diag.verdict == "degenerate":
        raise DegenerateMotionError(sentences(diag.advice))
    keep = np.setdiff1d(np.arange(len(kf)), diag.outliers)
    X0, Z0, _ = closed_form(f2b[keep], t2c[keep], setup, "daniilidis", "auto")
    fit = refine_offset(robot, camera, X0, Z0, setup, coarse.offset, span=FINE_SPAN)
    notes.append(f"clock offset (camera minus robot): {fit.offset * 1e3:.2f} +- {fit.offset_std * 1e3:.2f} ms; the angular "
                 f"velocities of the streams align best at {coarse.offset * 1e3:.1f} ms (alignment {coarse.correlation:.2f}"
                 f" of 1); refined jointly with X and Z on {len(fit.samples)} camera samples "
                 f"({int((~fit.inliers).sum())} set aside as outliers)")
    if coarse.correlation < WEAK_ALIGNMENT:
        notes.append(f"the angular velocities of the two streams align poorly ({coarse.correlation:.2f} of 1): the "
                     "offset may be wrong; check that both files record the same motion, and record motions that turn "
                     "about varied axes with changing speed")
    return Synchronisation(fit.offset, fit.offset_std, search, coarse, fit, notes)


def keyframes_at(robot: PoseStream, camera: PoseStream, offset: float, n: int, setup: str | None = None,
                 fit: OffsetFit | None = None) -> tuple[NDArray[np.intp], NDArray[np.float64], int]:
    """``n`` keyframes of the camera stream at ``offset`` (:func:`select_keyframes` among the samples
    inside the robot stream; with ``fit`` and ``setup``, only those the joint fit does not call
    outliers): their indices, the robot poses interpolated at their times minus the offset, and
    the number of candidates."""
    t_robot = camera.times - offset
    f2b, ok = interpolate(robot, t_robot)
    if fit is not None and setup is not None:
        mismatch = invert(fit.Z) @ constant_transforms(fit.X, f2b, camera.poses, setup)
        rv, t = to_rotvec_translation(mismatch)
        ok &= (np.abs(rv) <= 5.0 * fit.sigma[0]).all(axis=1) & (np.abs(t) <= 5.0 * fit.sigma[1]).all(axis=1)
    if ok.sum() < 3:
        raise InputMismatchError(f"only {int(ok.sum())} camera samples fall inside the robot stream at an offset of "
                                 f"{offset * 1e3:.1f} ms: the streams must overlap in time")
    kf = select_keyframes(f2b, np.where(ok, timing_cost(robot, t_robot), np.nan), n, ok)
    return kf, f2b[kf], int(ok.sum())


def offset_cov(X: NDArray[np.float64], Z: NDArray[np.float64], setup: str, robot: PoseStream,
               camera_times: NDArray[np.float64], target2cam: NDArray[np.float64], offset: float, std: float
               ) -> NDArray[np.float64]:
    """X's covariance (``Calibration.cov``'s parameters) from the offset's std: X refined on the
    poses with the robot interpolated at the offset +- its std; half the difference is X's
    response to one std."""
    Xs = []
    for d in (offset - std, offset + std):
        f2b, _ = interpolate(robot, camera_times - d)
        Xs.append(refine_pose(X, Z, f2b, target2cam, setup).X)
    rv, _ = to_rotvec_translation(Xs[1] @ invert(Xs[0]))  # X' = exp(rv) X
    dxi = 0.5 * np.r_[rv, Xs[1][:3, 3] - Xs[0][:3, 3]]
    return np.outer(dxi, dxi)
