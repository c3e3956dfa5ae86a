"""How well a calibration predicts views it was not fitted on: the number a user can trust.

A hand-eye calibration is good when, from the robot pose alone, it says where the target will
appear in the camera. Cross-validation measures exactly that on the user's own data: the poses are
split into K folds; each fold is held out in turn, X and Z are fitted on the others, and the held-out
views are predicted (``target2cam_i = inv(X) @ inv(A_i) @ Z``, :func:`handeye.frames.setups.predicted_target2cam`)
and compared with what the camera saw:

* with images: the RMS pixel distance between the predicted and the detected target points;
* with poses only: the angle between the predicted and the measured viewing rays of the target's
  points (what pixels measure, without the PnP depth error), as millimetres at the target's
  distance.

Both are also given as millimetres at the target's distance (pixels through the focal length), so
that estimators and data sets compare in one unit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence, cast

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..errors import HandEyeError
from ..frames.setups import predicted_target2cam
from ..sensors.camera.pnp import project_points

__all__ = ["Views", "Fit", "default_folds", "fold_indices", "held_out", "jackknife_groups", "jackknife_spread", "view_errors",
           "cross_validate", "CrossValidation", "jackknife_cov", "jackknife_covs", "pnp_errors", "robot_error_seen",
           "VIRTUAL_TARGET", "FAILED_FIT"]

#: Points of a virtual 0.2 m x 0.15 m target (target frame, metres): the held-out error of pose-only
#: data is measured on them.
VIRTUAL_TARGET = np.array([[x, y, 0.0] for x in np.linspace(0.0, 0.2, 5) for y in np.linspace(0.0, 0.15, 4)])

#: A fit: (flange2base, target2cam, setup, the training views' indices) -> (X, Z), or (X, Z, K, dist)
#: when it also refines the intrinsics (the held-out views are then projected with those), or
#: (X, Z, K, dist, scale) when it also corrects the target's size (the held-out views' points scaled).
Fit = Callable[[NDArray[np.float64], NDArray[np.float64], str, NDArray[np.intp]], tuple]


@dataclass(frozen=True)
class Views:
    """The data a calibration is scored on: poses, and per view the target's points with their
    detections when there are images.

    ``object_points`` / ``image_points``: lists of per-view arrays (M_i, 3) in the target frame and
    (M_i, 2) in pixels; both None for pose-only data (then :data:`VIRTUAL_TARGET` is used).
    """

    flange2base: NDArray[np.float64]
    target2cam: NDArray[np.float64]
    setup: str
    object_points: Sequence[NDArray[np.float64]] | None = None
    image_points: Sequence[NDArray[np.float64]] | None = None
    K: NDArray[np.float64] | None = None
    dist: NDArray[np.float64] | None = None

    def __len__(self) -> int:
        return len(self.flange2base)

    @property
    def has_pixels(self) -> bool:
        return self.image_points is not None and self.K is not None


def default_folds(n: int) -> int:
    """Folds for ``n`` views: one per view up to 10 (few views: every one counts, and a fit on all
    but one is closest to the fit on all), else 5."""
    return n if n <= 10 else 5


def fold_indices(n: int, folds: int = 5, seed: int = 0) -> list[NDArray[np.intp]]:
    """The held-out indices of each fold: a seeded permutation of ``range(n)`` cut into ``folds``
    nearly equal parts (leave-one-out when ``folds >= n``)."""
    if n < 4:
        raise HandEyeError(f"cross-validation needs at least 4 views, got {n}")
    folds = min(int(folds), n)
    order = np.random.default_rng(seed).permutation(n)
    return [np.sort(order[k::folds]) for k in range(folds)]


#: What a fit on part of the views may raise when that part cannot determine it (degenerate motions,
#: a singular system, too few points): its fold's views are then not predicted.
FAILED_FIT = (HandEyeError, np.linalg.LinAlgError, ValueError)


def held_out(n: int, held: Sequence[NDArray[np.intp]], predict: Callable[[NDArray[np.intp], NDArray[np.intp]], NDArray],
             columns: int, catch: tuple[type[BaseException], ...] = FAILED_FIT) -> NDArray[np.float64]:
    """Per view (n, ``columns``) its error predicted from the robot alone by a fit on the other views:
    for each fold ``test`` of ``held``, ``predict(train, test)`` fits on the positions ``train`` (all
    but ``test``) and gives the errors (len(test), ``columns``) of the views ``test``. A fold whose
    fit raises one of ``catch`` leaves its views at infinity. The cross-validation of every
    estimator (:func:`cross_validate`) and of the estimation core's fit
    (:func:`handeye.estimation.core.estimate`)."""
    out = np.full((n, columns), np.inf)
    for test in held:
        try:
            out[test] = predict(np.setdiff1d(np.arange(n), test), test)
        except catch:
            continue
    return out


def jackknife_groups(n: int, max_groups: int) -> list[NDArray[np.intp]]:
    """The positions a jackknife leaves out in turn: each view alone up to ``max_groups`` views, else
    ``max_groups`` folds (:func:`fold_indices`)."""
    return [np.array([i]) for i in range(n)] if n <= max_groups else fold_indices(n, max_groups)


def jackknife_spread(estimates: NDArray[np.float64]) -> NDArray[np.float64]:
    """The jackknife covariance of ``g`` estimates (g, k), each from the data less one group:
    ``(g - 1) / g * sum_k (e_k - mean e)(e_k - mean e)^T``."""
    d = np.asarray(estimates, float) - np.mean(estimates, axis=0)
    g = len(d)
    return (g - 1) / g * d.T @ d


_TINY = np.finfo(float).tiny


def view_errors(X: NDArray[np.float64], Z: NDArray[np.float64], views: Views,
                idx: NDArray[np.intp] | None = None, K: NDArray[np.float64] | None = None,
                dist: NDArray[np.float64] | None = None,
                scale: float = 1.0) -> tuple[NDArray[np.float64] | None, NDArray[np.float64]]:
    """Prediction error of views ``idx`` (default all) from X, Z and their robot poses.

    Returns ``(px, mm)``: per view the RMS pixel error of the target's points (None without
    images) and the RMS error in millimetres at the target's distance. ``K``, ``dist``: the
    intrinsics to project with (default the views'); ``scale``: the target's size relative to the
    views' points (a calibration that found the given size wrong predicts them at its own).
    """
    idx = np.arange(len(views)) if idx is None else np.asarray(idx)
    T = predicted_target2cam(X, Z, views.flange2base[idx], views.setup)
    return _errors_at(T, views, idx, views.K if K is None else K, views.dist if dist is None else dist, scale)


def pnp_errors(views: Views) -> tuple[NDArray[np.float64] | None, NDArray[np.float64]]:
    """:func:`view_errors` of the camera's own poses (``views.target2cam``, PnP's): per view the
    RMS pixel error of PnP's fit (None without images) and its millimetres at the target's distance,
    the camera's noise that no X and Z can go below."""
    return _errors_at(views.target2cam, views, np.arange(len(views)), views.K, views.dist, 1.0)


def _errors_at(T: NDArray[np.float64], views: Views, idx: NDArray[np.intp], K, dist,
               scale: float) -> tuple[NDArray[np.float64] | None, NDArray[np.float64]]:
    """Per view ``idx[k]`` the error of the target at ``T[k]`` (its target2cam) against what the camera saw."""
    px = np.empty(len(idx)) if views.has_pixels else None
    mm = np.empty(len(idx))
    for k, i in enumerate(idx):
        p = np.asarray(views.object_points[i] if views.object_points is not None else VIRTUAL_TARGET, dtype=float)
        measured = p @ views.target2cam[i, :3, :3].T + views.target2cam[i, :3, 3]
        depth = np.linalg.norm(measured, axis=1)  # 0 only for a point at the camera centre: it adds no error
        if px is not None:
            seen = cast(Sequence[NDArray[np.float64]], views.image_points)  # has_pixels
            d = project_points(T[k], scale * p, K, dist) - np.asarray(seen[i], dtype=float)
            px[k] = np.sqrt(np.mean(np.sum(d**2, axis=1)))
            f = 0.5 * (K[0, 0] + K[1, 1])
            mm[k] = 1e3 * np.sqrt(np.mean(np.sum(d**2, axis=1) * (depth / f) ** 2))
        else:
            predicted = scale * p @ T[k, :3, :3].T + T[k, :3, 3]
            u = measured / np.maximum(depth, _TINY)[:, None]
            v = predicted / np.maximum(np.linalg.norm(predicted, axis=1, keepdims=True), _TINY)
            angle = 2.0 * np.arcsin(np.clip(0.5 * np.linalg.norm(u - v, axis=1), 0.0, 1.0))
            mm[k] = 1e3 * np.sqrt(np.mean((angle * depth) ** 2))
    return px, mm


def robot_error_seen(X: NDArray[np.float64], Z: NDArray[np.float64], views: Views) -> float:
    """The robot's pose error that the views show (mm per axis, at the target's distance): how far
    X and Z with the robot's poses taken as exact miss what the camera saw, beyond the camera's own
    error. With images, per view the excess of the predicted points' error over the PnP pose's
    error on the same points (the camera's noise); without images the whole error of the predicted
    viewing rays (the camera's error included: an over-estimate). The median over the views, so a
    bad view does not set it; per axis of the image plane (the RMS over both over sqrt 2)."""
    _, mm = view_errors(X, Z, views)
    if views.has_pixels:
        mm = np.sqrt(np.maximum(mm**2 - pnp_errors(views)[1] ** 2, 0.0))
    return float(np.median(mm) / np.sqrt(2.0))


@dataclass(frozen=True)
class CrossValidation:
    """Held-out errors of one estimator, per view (each view predicted by the fit without its fold)."""

    name: str
    px: NDArray[np.float64] | None  #: (N,) RMS pixel error per held-out view; None for pose-only data
    mm: NDArray[np.float64]  #: (N,) RMS error at the target's distance, mm
    folds: int

    @property
    def score(self) -> float:
        """RMS over the views of the per-view errors: pixels with images, else millimetres."""
        e = self.px if self.px is not None else self.mm
        return float(np.sqrt(np.mean(e**2)))

    @property
    def rms_px(self) -> float | None:
        return None if self.px is None else float(np.sqrt(np.mean(self.px**2)))

    @property
    def rms_mm(self) -> float:
        return float(np.sqrt(np.mean(self.mm**2)))


def cross_validate(fit: Fit, views: Views, folds: int | Sequence[NDArray[np.intp]] = 5, name: str = "",
                   seed: int = 0) -> CrossValidation:
    """K-fold cross-validation of ``fit`` on ``views`` (see the module docstring).

    ``folds``: a count (:func:`fold_indices`) or the held-out index arrays themselves. A fold
    whose training part cannot be solved (a :class:`HandEyeError`, e.g. degenerate motions) gives
    its views an infinite error.
    """
    n = len(views)
    held = fold_indices(n, folds, seed) if isinstance(folds, (int, np.integer)) else list(folds)

    def predict(train: NDArray[np.intp], test: NDArray[np.intp]) -> NDArray[np.float64]:
        X, Z, *intrinsics = fit(views.flange2base[train], views.target2cam[train], views.setup, train)
        e_px, e_mm = view_errors(X, Z, views, test, *intrinsics)
        return np.stack([e_mm] + ([] if e_px is None else [e_px]), axis=1)

    errors = held_out(n, held, predict, 2 if views.has_pixels else 1)
    return CrossValidation(name, errors[:, 1] if views.has_pixels else None, errors[:, 0], len(held))


def jackknife_cov(fit: Fit, views: Views, X: NDArray[np.float64], max_groups: int = 10) -> NDArray[np.float64] | None:
    """Jackknife covariance of X (6x6 over the left rotation-vector increment and the translation,
    as ``Calibration.cov``): X refitted without each view (without each of ``max_groups`` groups of
    views when there are more), ``(g - 1) / g * sum_k (d_k - mean d)(d_k - mean d)^T`` with ``d_k``
    the refit's X relative to ``X``. It measures how much X depends on which poses were taken,
    whatever the noise is: robot errors that depend on the pose included. None when fewer than 3
    refits could be solved."""
    return jackknife_covs(fit, views, X, None, max_groups)[0]


def jackknife_covs(fit: Fit, views: Views, X: NDArray[np.float64], Z: NDArray[np.float64] | None,
                   max_groups: int = 10) -> tuple[NDArray[np.float64] | None, NDArray[np.float64] | None]:
    """:func:`jackknife_cov` of X and, from the same refits, of Z (None when ``Z`` is None)."""
    n = len(views)
    Xk, Zk = [], []
    for out in jackknife_groups(n, max_groups):
        train = np.setdiff1d(np.arange(n), out)
        try:
            solved = fit(views.flange2base[train], views.target2cam[train], views.setup, train)
        except FAILED_FIT:
            continue
        Xk.append(solved[0])
        Zk.append(solved[1])
    if len(Xk) < 3:
        return None, None
    return _spread(np.array(Xk), X), None if Z is None else _spread(np.array(Zk), Z)


def _spread(Tk: NDArray[np.float64], T: NDArray[np.float64]) -> NDArray[np.float64]:
    """The jackknife covariance of the refits ``Tk`` about ``T`` (:func:`jackknife_spread`)."""
    return jackknife_spread(np.concatenate([Rotation.from_matrix(Tk[:, :3, :3] @ T[:3, :3].T).as_rotvec(),
                                            Tk[:, :3, 3] - T[:3, 3]], axis=1))
