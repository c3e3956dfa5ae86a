"""The pose refinement and the pixel refinement as functions of their inputs, fitted by the one
estimation core (:mod:`handeye.estimation.core`): no second engine.

``refine_pose``: X and Z refined on the poses alone, the optimal correction of Strobl and Hirzinger
(seed §2.2.4) with its noise model's variances estimated from the data: the core's fit of
:class:`~handeye.sensors.camera.poses.PoseDifferences` times
:class:`~handeye.robot.models.ControllerPoses` (:func:`~handeye.estimation.core.fit_poses`).

Both once lived in :mod:`handeye.solvers.refine` as engines of their own; that path still finds
them for one release (with a DeprecationWarning).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

import numpy as np
from numpy.typing import NDArray

from ..errors import InputMismatchError
from ..frames.setups import check_setup
from ..sensors.camera.poses import NOISE_TERMS, pose_residuals
from ..solvers.refine import PoseRefinementResult, TranslationPriors
from .core import Fitted, Problem, fit_poses

__all__ = ["PoseRefinementResult", "TranslationPriors", "refine_pose", "pose_fits_shared", "fit_poses_shared"]

_POSE_FITS: ContextVar[dict | None] = ContextVar("_POSE_FITS", default=None)


@contextmanager
def pose_fits_shared() -> Iterator[None]:
    """Within it, the pose refinement of the same poses from the same start is fitted once
    (:func:`fit_poses_shared`): the check's outlier refit on all the poses (:func:`refine_pose` from
    Daniilidis) is the pose candidate's fit on them (:func:`~handeye.estimation.estimators.poses_fit`
    from the same closed form) whenever the check leaves every pose in, the costliest fit of a
    calibration on poses (a 20-view session: ~0.2 s of ~0.8). Nested: the outermost one keeps them."""
    token = _POSE_FITS.set({}) if _POSE_FITS.get() is None else None
    try:
        yield
    finally:
        if token is not None:
            _POSE_FITS.reset(token)


def fit_poses_shared(flange2base: NDArray[np.float64], target2cam: NDArray[np.float64], setup: str, X0: NDArray[np.float64],
                     Z0: NDArray[np.float64], priors: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
                     ) -> tuple[Problem, Fitted]:
    """:func:`~handeye.estimation.core.fit_poses`, its answer kept within :func:`pose_fits_shared` (keyed by
    the inputs' bytes: the same inputs, the same fit)."""
    memo = _POSE_FITS.get()
    if memo is None:
        return fit_poses(flange2base, target2cam, setup, X0, Z0, priors=priors)
    arrays = (flange2base, target2cam, X0, Z0) + (() if priors is None else tuple(priors))
    key = (setup, priors is None) + tuple((np.shape(a), np.asarray(a, float).tobytes()) for a in arrays)
    if key not in memo:
        memo[key] = fit_poses(flange2base, target2cam, setup, X0, Z0, priors=priors)
    return memo[key]


def refine_pose(
    X0: NDArray[np.float64],
    Z0: NDArray[np.float64],
    flange2base: NDArray[np.float64],
    target2cam: NDArray[np.float64],
    setup: str,
    weighting: str = "noise_model",
    priors: TranslationPriors | None = None,
) -> PoseRefinementResult:
    """Refine X and Z on the poses: the optimal correction of Strobl and Hirzinger (seed §2.2.4),
    fitted by the estimation core (:func:`~handeye.estimation.core.fit_poses`).

    Every pose i says where the target is, ``Z_i`` (target2base for eye-in-hand, target2flange for
    eye-to-hand, through X); the residual is ``Z^-1 Z_i`` as a rotation vector and a translation, in
    the target frame. Poses, not motions, carry the residuals: each measurement enters once, so
    residuals are independent and the covariance is honest. The residual of pose i has the
    covariance ``s_rr M_i + s_rc P_rot + s_t P_tra (+ s_d P_depth)``: robot rotation noise (``M_i``:
    through the lever arm between flange and target), camera rotation noise, translation noise and,
    from 6 poses, the camera's depth noise; the variances are estimated by maximum likelihood from
    the residuals, the fit repeated with the new weights until they are stable.

    Parameters
    ----------
    X0, Z0 : (4, 4)
        Start, e.g. a closed-form solution and the mean of the ``Z_i``.
    flange2base, target2cam : (N, 4, 4)
    setup : {'eye_in_hand', 'eye_to_hand'}
    weighting : {'noise_model'}
        The noise model above (the only one: Strobl and Hirzinger's fixed two-variance metric,
        'strobl', went with the second engine).
    priors : TranslationPriors, optional
        Linear measurements of the translations of X and Z (``G @ [t_X, t_Z] = value +- std``),
        each one more residual: what fixes the directions the poses cannot see (a SCARA's camera
        height, :mod:`handeye.solvers.low_dof`).

    Returns
    -------
    PoseRefinementResult
        ``cov_X`` is scaled by the residual variance factor (chi-square over degrees of freedom).

    Examples
    --------
    >>> import numpy as np
    >>> from handeye.simulate import Noise, add_noise, random_scene
    >>> from handeye.solvers import closed_form
    >>> scene = random_scene(12, "eye_in_hand", rng=0)
    >>> target2cam = add_noise(scene.target2cam, Noise(rot_deg=0.02, trans_mm=0.2), np.random.default_rng(0))
    >>> X0, Z0, _ = closed_form(scene.flange2base, target2cam, "eye_in_hand", "daniilidis")
    >>> ref = refine_pose(X0, Z0, scene.flange2base, target2cam, "eye_in_hand")
    >>> bool(1e3 * np.linalg.norm(ref.X[:3, 3] - scene.X[:3, 3]) < 3e3 * np.sqrt(np.trace(ref.cov_X[3:, 3:])))
    True
    """
    setup = check_setup(setup)
    if weighting != "noise_model":
        raise InputMismatchError(f"weighting={weighting!r}; use 'noise_model' (the noise model's variances estimated "
                                 "from the data; the fixed 'strobl' metric is no longer offered)")
    flange2base = np.asarray(flange2base, dtype=float)
    target2cam = np.asarray(target2cam, dtype=float)
    if len(flange2base) < 3:
        raise InputMismatchError(f"pose refinement needs at least 3 poses, got {len(flange2base)}")
    X0, Z0 = np.asarray(X0, float), np.asarray(Z0, float)
    # the core's unknowns are X's left increment and the target's chart about Z0: the priors' own
    rows = priors.rows(X0, Z0) if priors is not None else None
    problem, fitted = fit_poses_shared(flange2base, target2cam, setup, X0, Z0, priors=rows)
    X = fitted.X
    Z = problem.sensor.Z(X, fitted.p)
    cov = problem.full_cov_xp(fitted.cov)
    found = dict(zip(NOISE_TERMS, map(float, fitted.sigma)))
    noise = {k: found.get(k, 0.0) for k in NOISE_TERMS}
    residuals, _, _ = pose_residuals(X, Z, flange2base, target2cam, setup)
    message = "the core's fit of the poses" + ("" if fitted.success else ": the noise estimates did not settle")
    return PoseRefinementResult(X, Z, cov[:6, :6], cov[6:, 6:], cov, noise, residuals, fitted.rounds, fitted.success,
                                weighting, fitted.success, message)
