"""The parts of X's std that no single fit sees: the robot's absolute accuracy (a constant error of
the robot's poses, which X absorbs whole) and the jackknife's widening of a noise model.

Every estimator reports its std through :func:`widened_uncertainty`: the noise model's covariance,
each axis widened to the jackknife spread where that is larger, plus the robot's accuracy
(:func:`robot_accuracy_cov`, raised to what the views show: :func:`robot_accuracy_from_data`) and
the intrinsics' error when they were estimated from the same images.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ..frames.metrics import std_deg_mm
from ..geometry.se3 import skew
from ..options import ROBOT_ACCURACY
from ..result import Calibration

__all__ = ["robot_accuracy_cov", "robot_accuracy_from_data", "widened_uncertainty", "consider_cov", "UNSEEN_FACTOR"]


def _std(cov_X: NDArray[np.float64]) -> NDArray[np.float64]:
    """Standard deviations of X's six parameters in degrees and millimetres."""
    return std_deg_mm(cov_X)


def robot_accuracy_cov(X: NDArray[np.float64], accuracy: tuple[float, float]) -> NDArray[np.float64]:
    """Covariance of X (as ``Calibration.cov``) from a constant robot pose error of ``accuracy``
    (deg, mm per axis), which X absorbs whole: ``X' = exp(d) X`` in the flange (eye-in-hand) or base
    (eye-to-hand) frame, so X's translation also moves by ``d_rot x t_X``."""
    s_rot, s_t = np.radians(accuracy[0]), 1e-3 * accuracy[1]
    J = np.eye(6)
    J[3:, :3] = -skew(X[:3, 3])
    return J @ np.diag([s_rot**2] * 3 + [s_t**2] * 3) @ J.T


def consider_cov(jacobian: NDArray[np.float64], sigma: NDArray[np.float64], held: NDArray[np.float64],
                 held_std: NDArray[np.float64]) -> NDArray[np.float64]:
    """The covariance of a fit's unknowns from quantities it holds at their nominal values (Schmidt's
    consider covariance): ``jacobian`` (M, P) of the residuals in the unknowns, ``sigma`` (M,) each
    residual's relative noise, ``held`` (M, E) the residuals' derivatives in the held quantities, of
    std ``held_std`` (E,). A held quantity off by ``e`` moves the least-squares answer by ``-S e``,
    ``S = (J^T W J)^-1 J^T W H``: (P, P) ``S diag(held_std^2) S^T``."""
    w = 1.0 / np.asarray(sigma, float)[:, None]
    S = np.linalg.lstsq(jacobian * w, held * w, rcond=None)[0]
    return (S * np.asarray(held_std, float) ** 2) @ S.T


#: The robot's error that X absorbs unseen (its part constant over the capture) is taken as this many
#: times the error the views show (:func:`~handeye.estimation.validation.robot_error_seen`) when that is more than
#: the stated accuracy. Rendered and pose-only sessions of a 6-axis arm whose kinematic error sweeps from
#: ~0.1 to ~3.5 mm (30 per level and setup, 8-20 views): the views show 0.1-0.7 mm per axis while X
#: takes up to 8 mm. At ~3 mm, X was within 3 std in 77% / 63% of the rendered eye-in-hand / eye-to-hand
#: sessions with the calibrated arm's default alone, 93% / 90% with 2x what the views show, 100% / 97%
#: with 3x (pose-only: 85% / 51%, 97% / 93%, 99% / 99%); at a calibrated arm (~0.3 mm) the std of X's
#: translation grows from 0.7 to 1.0 mm (eye-in-hand) and 1.1 to 1.2 mm (eye-to-hand).
UNSEEN_FACTOR = 3.0


def robot_accuracy_from_data(stated: tuple[float, float] | None, seen_mm: float | None) -> tuple[float, float] | None:
    """The robot accuracy (deg, mm per axis) X's std takes: the ``stated`` one, or when the views show
    a larger robot error (``seen_mm`` per axis, :func:`~handeye.estimation.validation.robot_error_seen`)
    :data:`UNSEEN_FACTOR` times that, with the rotation in the stated proportion (the default's,
    0.1 deg per mm, when the stated is zero). None when ``stated`` is None: the robot is exact."""
    if stated is None or seen_mm is None or UNSEEN_FACTOR * seen_mm <= stated[1]:
        return stated
    mm = UNSEEN_FACTOR * seen_mm
    deg_per_mm = stated[0] / stated[1] if stated[1] > 0 else ROBOT_ACCURACY[0] / ROBOT_ACCURACY[1]
    return max(stated[0], deg_per_mm * mm), mm


def widened_uncertainty(cal: Calibration, cv_jack: NDArray[np.float64] | None,
                        robot_accuracy: tuple[float, float] | None = ROBOT_ACCURACY,
                        intrinsics: NDArray[np.float64] | None = None, seen_mm: float | None = None,
                        seen_in_pixels: bool = True, sensor: str = "camera") -> Calibration:
    """``cal`` with a std that covers both sources: the refinement's noise model (``cal.cov``, None for
    a closed form) and the jackknife spread (X refitted without each pose). Each of X's six
    parameters gets the larger of the two (the model's correlations kept); a note says when the
    spread widened the model's. Errors common to every pose, which neither sees, are added: the
    robot's absolute accuracy (raised to what the views show of the robot's error, ``seen_mm``:
    :func:`robot_accuracy_from_data`; ``seen_in_pixels``: measured beyond the camera's own error, else
    from poses alone; ``sensor`` names what saw, in the note), and ``intrinsics`` (X's covariance from intrinsics estimated
    from the same images, :func:`handeye.estimation.estimators.intrinsics_cov`)."""
    model = cal.cov
    accuracy = robot_accuracy_from_data(robot_accuracy, seen_mm)
    robot = None if accuracy is None else robot_accuracy_cov(cal.X, accuracy)
    sources = {"model": None if model is None else _std(model), "jackknife": None if cv_jack is None else _std(cv_jack),
               "robot_accuracy": None if robot is None else _std(robot)}
    intrinsics_std = None if intrinsics is None else _std(intrinsics)
    if intrinsics_std is not None:
        sources["intrinsics"] = intrinsics_std
    notes = list(cal.notes)
    if model is None or cv_jack is None:
        cov = model if cv_jack is None else cv_jack
    else:
        ratio = np.sqrt(np.maximum(np.diag(cv_jack), 1e-300) / np.maximum(np.diag(model), 1e-300))
        D = np.diag(np.maximum(ratio, 1.0))
        cov = D @ model @ D
        if ratio.max() > 1.5:
            notes.append(f"the std of X is widened up to {ratio.max():.1f}x the noise model's: X moves more without "
                         "one pose than the model predicts (robot errors that depend on the pose, such as kinematic "
                         "errors, or outliers the check did not catch)")
    if robot is not None and accuracy is not None and robot_accuracy is not None:  # all three or none
        cov = robot if cov is None else cov + robot
        if accuracy == robot_accuracy:
            notes.append(f"the std of X includes the robot's absolute accuracy, assumed {accuracy[0]:g} deg / "
                         f"{accuracy[1]:g} mm per axis (robot_accuracy=(deg, mm), --robot-accuracy DEG,MM): a "
                         "constant robot error is invisible in the data and X takes it whole")
        else:
            seen = (f"the robot's poses miss what the {sensor} saw by {seen_mm:.2f} mm per axis beyond the {sensor}'s "
                    "own error" if seen_in_pixels else
                    f"the robot's and the camera's poses disagree by {seen_mm:.2f} mm per axis at the target (pose "
                    "pairs alone cannot tell whose error it is; images can)")
            notes.append(f"the std of X includes the robot's absolute accuracy taken as {accuracy[0]:.3g} deg / "
                         f"{accuracy[1]:.3g} mm per axis, not the {robot_accuracy[0]:g} deg / {robot_accuracy[1]:g} mm "
                         f"assumed: {seen} (an error that depends on the pose, as an arm's kinematic errors do), and "
                         f"the part of such an error that is constant over the capture, which X takes whole and no data "
                         f"show, is taken as {UNSEEN_FACTOR:g}x that; give the arm's accuracy if you know it "
                         "(robot_accuracy=(deg, mm), --robot-accuracy DEG,MM)")
    if intrinsics is not None and intrinsics_std is not None:
        cov = intrinsics if cov is None else cov + intrinsics
        notes.append(f"the std of X includes the error of the intrinsics estimated from these images (up to "
                     f"{np.max(intrinsics_std[:3]):.3g} deg / {np.max(intrinsics_std[3:]):.3g} mm), "
                     f"which the {cal.estimator or cal.method} estimate holds fixed: give K and dist in session.yaml "
                     "from a calibration of their own to remove it")
    if cov is None:
        return replace(cal, std_sources=sources, notes=notes, robot_accuracy=accuracy)
    return replace(cal, cov=cov, std=_std(cov), std_sources=sources, notes=notes, robot_accuracy=accuracy)
