"""What a sensor model is: the one interface the estimation core (:mod:`handeye.estimation.core`) fits.

A sensor model holds what the views of one capture measured (points, centres, profiles, ...) and
says how to predict each measurement from X, the sensor's own unknowns ``p`` (the target's pose or
centre, a depth scale, a sphere's radius, ...) and the flange pose of its view. The core does the
rest for every sensor alike: the robust fit with the robot model's unknowns, cross-validation over
held-out views, the jackknife, the robot's accuracy, what the capture leaves undetermined, the
verdict and the result.

A new sensor is one package under ``sensors/`` whose model class has these members (see
:class:`SensorModel`; :class:`handeye.sensors.depth.model.SphereCentres` is the smallest one):

``kind``, ``target``
    The sensor and the target in words (``'depth camera'``, ``'spheres'``).
``setup``
    ``'eye_in_hand'`` or ``'eye_to_hand'``.
``names``
    Per view its name (the file it came from).
``owner``, ``shape``, ``groups``
    Per measurement row its view (M,), its noise's shape (M, c: relative std of each residual
    column, fixed by the measurement), and which columns share one noise scale (the core fits each
    group's scale to the data).
``param_names``, ``param_scale``
    The sensor's unknowns in order, and a typical size of each (the solver's scaling).
``start(flange2base, X, Z, rows)``
    X and ``p`` to start from: from the closed form's X and Z when :meth:`view_poses` gave per-view
    poses, else the sensor's own closed form on the measurement rows ``rows`` (raises
    :class:`~handeye.errors.DegenerateMotionError` when they cannot determine X).
``view_poses()``
    Per view the target's pose in the sensor frame (N, 4, 4), when one view measures a whole pose
    (a board); None otherwise.
``residuals(X, p, flange2base, rows)``
    The measured minus the predicted value of measurement rows ``rows`` (len(rows), c), metres;
    ``flange2base`` holds every view's pose.
``Z(X, p)``, ``Z_std(p, cov_p)``
    The target's pose (target2base eye-in-hand, target2flange eye-to-hand) and its std (deg, mm; 6).
``figures(p, cov_p)``, ``notes(p, cov_p)``
    The sensor's own results (a depth scale with its std, the spheres' centres, ...), plain numbers;
    and what of them a user must hear (a depth scale beyond 3 std of 1), sentences.
``noise_mm(rows)``
    The noise each row's residual may have before any fit (the sensor's stated noise, mm): what
    the verdict holds the fit's residual against.
``nuisances`` (optional)
    The sensor's unknowns beside X and Z that a capture may leave undetermined (a depth scale and
    bias, a ball's radius, a line-scan camera's focal length and clock offset), each a
    :class:`Nuisance`: its position in ``p``, its nominal value and a real device's tolerance about
    it. The core fits each only where the capture determines it (its std from the data below half
    the tolerance), else holds it at the nominal value, names it, and adds the tolerance's effect to
    X's std; a value the session gives is held unless freed by name (``hold``/``free``).
``jacobian(X, p, flange2base, rows)`` (optional)
    The residuals' derivatives (M, c, 6 + k) for a left increment of X and the sensor's unknowns:
    with it the fit needs one evaluation per step instead of one per unknown (the laser's has it).
``joint_figures(X, p, cov, flange2base, rows)`` (optional)
    Figures that need X's covariance with the sensor's unknowns (``cov`` over X's increment and
    ``p``) or the fit's residuals on its ``rows``: a rig's per-sensor X, its std and residual.
``row_groups`` (optional)
    Per measurement row (M,) a set of rows whose noise is their own (a rig: one per sensor): each
    noise group's scale is then fitted per row set too.
``noise_groups`` (optional)
    Per entry (M, c) its noise group, given whole (a rig of sensors whose residuals differ in
    width: the padding's entries, always 0, in a group of their own).
``sections(X, p, flange2base, views)`` (optional)
    Per view of ``views`` what the report draws of it in the sensor's own plane: the measured
    points, their residuals and the fitted target's section (:class:`~handeye.result.SensorFit`'s
    ``sections``; the laser's has it).
``residuals(X, p, flange2base, rows, motion=...)`` (optional)
    A sensor whose view spans a move (a line-scan camera's rows, each exposed at its own time) takes
    ``motion``, the flange's pose at robot times (M,) -> (M, 4, 4), from a robot model that follows
    the move (:class:`~handeye.robot.models.JointTrajectory`); the core passes it only from such a
    robot, and the sensor then takes every row's pose from it instead of its view's pose.
``sees_links``, ``residuals(..., table=...)``, ``jacobian(..., table=...)`` (optional)
    A sensor whose target is the arm itself (its links posed at each view's joint angles) with
    ``sees_links`` true takes ``table``, the arm's table corrected by the robot's unknowns, from
    :class:`~handeye.robot.models.JointAngles`; its ``jacobian`` then adds the residuals' derivatives
    (M, c, E) by every entry of it (natural units), which the robot model takes to its unknowns
    (:meth:`~handeye.robot.models.JointAngles.entry_columns`). A depth camera's
    :class:`~handeye.sensors.depth.arm.ArmSurface` with its joint angles.
``noise_terms``, ``noise_shapes(X, p, flange2base, rows)``, ``noise_start(residuals)`` (optional)
    A sensor whose residuals within a row are correlated (a row is a view's whole pose: its 6
    residuals share the robot's rotation error through the lever arm to the target): per row its
    covariance is a sum of terms (``noise_terms``, names), each term's shape for a unit variance
    (K, M, c, c) at the given unknowns, and the variances to start from. The core then whitens each
    row by its covariance and fits the terms' variances by maximum likelihood (instead of ``shape``
    and ``groups``), keeps every row, and needs ``jacobian``; ``estimate`` refuses such a sensor (its
    noise fitted, it has none stated to judge the fit against): ``fit`` and ``downdated`` take it.
    :class:`~handeye.sensors.camera.poses.PoseDifferences`, the pose refinement's noise model.
``pixel_size(rows)`` (optional)
    Per measurement row the size (m) of one pixel of its residual, when the residuals are pixels
    times a size (an area camera's corners): cross-validation then gives held-out errors in pixels
    beside millimetres.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

__all__ = ["SensorModel", "Nuisance", "HOLD_MODES"]

#: How a session or a user may ask for a nuisance: fitted where the capture determines it (``auto``),
#: held at its nominal or given value (``hold``), or fitted whatever the capture (``free``).
HOLD_MODES = ("auto", "hold", "free")


@dataclass(frozen=True)
class Nuisance:
    """An unknown of a sensor model beside X and Z (:class:`SensorModel`'s ``nuisances``).

    ``name`` is what a session and the command line call it (``depth_scale``, ``radius``, ...);
    ``index`` its position in ``p``; ``nominal`` its value when held (in ``p``'s units; None: it has
    none and is always fitted, a ball whose diameter nobody gave); ``tolerance`` how far a real
    device may be from it (one std, ``p``'s units); ``given``: the session states the value (held
    unless freed by name); the value a user reads is ``offset + scale * p[index]`` in ``unit``.
    """

    name: str
    index: int
    nominal: float | None
    tolerance: float
    given: bool = False
    unit: str = ""
    scale: float = 1.0
    offset: float = 0.0

    def shown(self, value: float) -> float:
        """``value`` (``p``'s units) as a user reads it."""
        return self.offset + self.scale * float(value)


@runtime_checkable
class SensorModel(Protocol):
    """The interface of a sensor model (the module docstring says what each member is)."""

    kind: str
    target: str
    setup: str
    names: list[str]
    owner: NDArray[np.intp]
    shape: NDArray[np.float64]
    groups: tuple[tuple[int, ...], ...]
    param_names: list[str]
    param_scale: NDArray[np.float64]

    def view_poses(self) -> NDArray[np.float64] | None: ...

    def start(self, flange2base: NDArray[np.float64], X: NDArray[np.float64] | None, Z: NDArray[np.float64] | None,
              rows: NDArray[np.intp] | None = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...

    def residuals(self, X: NDArray[np.float64], p: NDArray[np.float64], flange2base: NDArray[np.float64],
                  rows: NDArray[np.intp]) -> NDArray[np.float64]: ...

    def Z(self, X: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.float64]: ...

    def Z_std(self, p: NDArray[np.float64], cov_p: NDArray[np.float64]) -> NDArray[np.float64]: ...

    def figures(self, p: NDArray[np.float64], cov_p: NDArray[np.float64]) -> dict[str, Any]: ...

    def notes(self, p: NDArray[np.float64], cov_p: NDArray[np.float64]) -> list[str]: ...

    def noise_mm(self, rows: NDArray[np.intp]) -> NDArray[np.float64]: ...
