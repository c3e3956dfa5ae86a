"""What a sensor model is: the one contract the estimation core (:mod:`handeye.estimation.core`) fits.

A sensor model holds what the views of one capture measured (points, centres, profiles, ...) and
says how to predict each measurement from X, the sensor's own unknowns ``p`` (the target's pose or
centre, a depth scale, a sphere's radius, ...) and the flange pose of its view. The core does the
rest for every sensor alike: the robust fit with the robot model's unknowns, cross-validation over
held-out views, the jackknife, the robot's accuracy, what the capture leaves undetermined, the
verdict and the result.

The contract is declared here, as protocols a type checker holds every model to (mypy, run by
tests/test_types.py): :class:`SensorModel`, the members every sensor has, and one small protocol
per optional capability (its own members only), which the core asks for by ``isinstance`` (each is
``runtime_checkable``) and never by a member's name. :class:`handeye.sensors.depth.model.SphereCentres` is the smallest
model.

Required (:class:`SensorModel`)
-------------------------------
``kind``, ``target``
    The sensor and the target in words (``'depth camera'``, ``'spheres'``).
``setup``
    ``'eye_in_hand'`` or ``'eye_to_hand'``.
``names``
    Per view its name (the file it came from).
``owner``
    Per measurement row its view (M,).
``shape``, ``groups``
    Per measurement row its noise's shape (M, c: relative std of each residual column, fixed by
    the measurement), and which columns share one noise scale (the core fits each group's scale
    to the data). With the capabilities below that concern noise, gathered in one :class:`Noise`.
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

Capabilities (optional, one protocol each)
------------------------------------------
:class:`Differentiable`
    ``jacobian(X, p, flange2base, rows)``: the residuals' derivatives (M, c, 6 + k) for a left
    increment of X and the sensor's unknowns: one evaluation per step instead of one per unknown.
:class:`SpansMotion`
    ``residuals(..., motion=)``: a view that spans a move (a line-scan camera's rows, each exposed at
    its own time) takes ``motion``, the flange's pose at robot times (M,) -> (M, 4, 4), from a robot
    model that follows the move (:class:`~handeye.robot.models.FollowsMotion`); the core passes it
    only from such a robot, and the sensor then takes every row's pose from it instead of its view's.
:class:`SeesLinks`
    ``sees_links`` true, ``residuals(..., table=)``, ``jacobian(..., table=)``: the target is the arm
    itself (its links posed at each view's joint angles); from a robot that fits the arm's table
    (:class:`~handeye.robot.models.FittedTable`) it takes ``table``, the table corrected by the
    robot's unknowns, and its ``jacobian`` adds the derivatives (M, c, E) by every entry of it
    (natural units), which the robot model takes to its unknowns
    (:meth:`~handeye.robot.models.JointAngles.entry_columns`). A depth camera's
    :class:`~handeye.sensors.depth.arm.ArmSurface` with its joint angles.
:class:`CorrelatedNoise`
    ``noise_terms``, ``noise_shapes(X, p, flange2base, rows)``, ``noise_start(residuals)``: residuals
    within a row are correlated (a row is a view's whole pose: its 6 residuals share the robot's
    rotation error through the lever arm to the target): per row its covariance is a sum of terms
    (``noise_terms``, names), each term's shape for a unit variance (K, M, c, c) at the given
    unknowns, and the variances to start from. The core then whitens each row by its covariance and
    fits the terms' variances by maximum likelihood (instead of ``shape`` and ``groups``), keeps every
    row, and needs ``jacobian``; ``estimate`` refuses such a sensor (its noise fitted, it has none
    stated to judge the fit against): ``fit`` and ``downdated`` take it.
    :class:`~handeye.sensors.camera.poses.PoseDifferences`, the pose refinement's noise model.
:class:`GroupedEntries`
    ``noise_groups``: per entry (M, c) its noise group, given whole (a rig of sensors whose residuals
    differ in width: each sensor's groups its own, the padding's entries, always 0, in one more).
:class:`PaddedEntries`
    ``entry_mask``: per entry (M, c) whether it is a measurement (None: all are): a rig pads a narrower
    sensor's rows with zeros, which the fit leaves out.
:class:`PixelResiduals`
    ``pixel_size(rows)``: per row the size (m) of one pixel of its residual, when the residuals are
    pixels times a size (an area camera's corners): held-out errors then in pixels beside millimetres.
:class:`HasNuisances`
    ``nuisances``: the sensor's unknowns beside X and Z that a capture may leave undetermined (a depth
    scale and bias, a ball's radius, a line-scan camera's focal length and clock offset), each a
    :class:`Nuisance`: its position in ``p``, its nominal value and a real device's tolerance about
    it. The core fits each only where the capture determines it (its std from the data below half
    the tolerance), else holds it at the nominal value, names it, and adds the tolerance's effect to
    X's std; a value the session gives is held unless freed by name (``hold``/``free``).
:class:`BlockedUnknowns`
    ``param_block``, ``row_block``: per unknown of ``p`` the block of rows it alone moves (-1: every
    row), and per row its block (a rig: per sensor): finite differences step unknowns of different
    blocks at once.
:class:`SharesTarget`
    ``target_params(Z)``: the target's pose ``Z`` as the first of the sensor's unknowns (a rig whose
    sensors see one target fits its pose once).
:class:`DrawsSections`
    ``sections(X, p, flange2base, views)``: per view of ``views`` what the report draws of it in the
    sensor's own plane: the measured points, their residuals and the fitted target's section; or
    its cloud in the frame the views agree in (:class:`~handeye.result.SensorFit`'s ``sections``
    says the keys of both). The report draws what the sections hold, without knowing the kind.
:class:`JointFigures`
    ``joint_figures(X, p, cov, flange2base, rows)``: figures that need X's covariance with the
    sensor's unknowns (``cov`` over X's increment and ``p``) or the fit's residuals on its ``rows``: a
    rig's per-sensor X, its std and residual.
:class:`NamesItsFix`
    ``undetermined_fix``: what would determine what the capture leaves undetermined of X, in words
    (else the core's own: turn the flange about that axis, or give it).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from ..robot.kinematics import Chain

__all__ = ["SensorModel", "Nuisance", "Noise", "HOLD_MODES", "Differentiable", "SpansMotion", "SeesLinks", "CorrelatedNoise",
           "GroupedEntries", "PaddedEntries", "PixelResiduals", "HasNuisances", "BlockedUnknowns", "SharesTarget",
           "DrawsSections", "JointFigures", "NamesItsFix"]

#: How a session or a user may ask for a nuisance: fitted where the capture determines it (``auto``),
#: held at its nominal or given value (``hold``), or fitted whatever the capture (``free``).
HOLD_MODES = ("auto", "hold", "free")

Array = NDArray[np.float64]
Rows = NDArray[np.intp]


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
    """The members every sensor model has (the module docstring says what each is). Read-only here:
    the core reads them, a model may keep them as plain attributes."""

    @property
    def kind(self) -> str: ...

    @property
    def target(self) -> str: ...

    @property
    def setup(self) -> str: ...

    @property
    def names(self) -> list[str]: ...

    @property
    def owner(self) -> Rows: ...

    @property
    def shape(self) -> Array: ...

    @property
    def groups(self) -> tuple[tuple[int, ...], ...]: ...

    @property
    def param_names(self) -> list[str]: ...

    @property
    def param_scale(self) -> Array: ...

    def view_poses(self) -> Array | None: ...

    def start(self, flange2base: Array, X: Array | None, Z: Array | None,
              rows: Rows | None = None) -> tuple[Array, Array]: ...

    def residuals(self, X: Array, p: Array, flange2base: Array, rows: Rows) -> Array: ...

    def Z(self, X: Array, p: Array) -> Array: ...

    def Z_std(self, p: Array, cov_p: Array) -> Array: ...

    def figures(self, p: Array, cov_p: Array) -> dict[str, Any]: ...

    def notes(self, p: Array, cov_p: Array) -> list[str]: ...

    def noise_mm(self, rows: Rows) -> Array: ...


@runtime_checkable
class Differentiable(Protocol):
    """The residuals' own derivatives (M, c, 6 + k): X's left increment, then ``p``."""

    def jacobian(self, X: Array, p: Array, flange2base: Array, rows: Rows) -> Array: ...


class SpansMotion(Protocol):
    """A view that spans a move: each row's pose from ``motion`` (robot times -> flange poses) when
    given. Not checked at run time: the robot decides (:class:`~handeye.robot.models.FollowsMotion`)."""

    def residuals(self, X: Array, p: Array, flange2base: Array, rows: Rows,
                  motion: Callable[[Array], Array] | None = None) -> Array: ...


@runtime_checkable
class SeesLinks(Protocol):
    """The arm itself the target: its links posed through ``table`` (a corrected arm's table) when given;
    ``jacobian`` then adds a column per entry of it. ``sees_links``: whether it can (joint angles given)."""

    @property
    def sees_links(self) -> bool: ...

    def residuals(self, X: Array, p: Array, flange2base: Array, rows: Rows,
                  table: Chain | None = None) -> Array: ...

    def jacobian(self, X: Array, p: Array, flange2base: Array, rows: Rows,
                 table: Chain | None = None) -> Array: ...


@runtime_checkable
class CorrelatedNoise(Protocol):
    """Each row's residuals correlated: its covariance a sum of ``noise_terms``, their shapes (K, M, c, c)
    for unit variances at the given unknowns, and the variances to start from (the fit needs
    :class:`Differentiable` too, and says so)."""

    @property
    def noise_terms(self) -> tuple[str, ...]: ...

    def noise_shapes(self, X: Array, p: Array, flange2base: Array, rows: Rows) -> Array: ...

    def noise_start(self, residuals: Array) -> Array: ...


@runtime_checkable
class GroupedEntries(Protocol):
    """Per entry (M, c) its noise group, given whole."""

    @property
    def noise_groups(self) -> NDArray[np.intp]: ...


@runtime_checkable
class PaddedEntries(Protocol):
    """Per entry (M, c) whether it is a measurement (None: every entry is)."""

    @property
    def entry_mask(self) -> NDArray[np.bool_] | None: ...


@runtime_checkable
class PixelResiduals(Protocol):
    """Residuals that are pixels times a size: per row the size (m) of one pixel."""

    def pixel_size(self, rows: Rows) -> Array: ...


@runtime_checkable
class HasNuisances(Protocol):
    """Unknowns beside X and Z that a capture may leave undetermined (:class:`Nuisance`)."""

    @property
    def nuisances(self) -> tuple[Nuisance, ...]: ...


@runtime_checkable
class BlockedUnknowns(Protocol):
    """Per unknown of ``p`` the block of rows it alone moves (-1: every row), and per row its block."""

    @property
    def param_block(self) -> NDArray[np.intp]: ...

    @property
    def row_block(self) -> NDArray[np.intp]: ...


@runtime_checkable
class SharesTarget(Protocol):
    """The target's pose ``Z`` as the first of the sensor's unknowns."""

    def target_params(self, Z: Array) -> Array: ...


@runtime_checkable
class DrawsSections(Protocol):
    """Per view what the report draws of it in the sensor's own plane."""

    def sections(self, X: Array, p: Array, flange2base: Array, views: Rows | Sequence[int]) -> list[dict[str, Any]]: ...


@runtime_checkable
class JointFigures(Protocol):
    """Figures that need X's covariance with the sensor's unknowns, or the fit's residuals."""

    def joint_figures(self, X: Array, p: Array, cov: Array, flange2base: Array,
                      rows: Rows) -> dict[str, Any]: ...


@runtime_checkable
class NamesItsFix(Protocol):
    """What would determine what the capture leaves undetermined of X, in words."""

    @property
    def undetermined_fix(self) -> str: ...


@dataclass(frozen=True)
class Noise:
    """A sensor's noise as the core weighs its residuals, in one object (:meth:`of` gathers it from the
    sensor's members, when the core asks: a camera's shape is set at its first start).

    ``shape`` (M, c): each entry's relative std; ``groups`` (M, c): each entry's noise group, whose
    scale the core fits (``noise_groups`` when the sensor gives them, else its column groups);
    ``mask`` (M, c): the entries that are measurements (None: all); ``stated_mm(rows)``: the noise
    each row may have before any fit (mm); ``pixel_size(rows)``: per row one pixel's size (m), or None;
    ``correlated``: the sensor itself when its rows' residuals are correlated (then its noise terms
    are fitted instead of the groups' scales), else None.
    """

    shape: Array
    groups: NDArray[np.intp]
    mask: NDArray[np.bool_] | None
    stated_mm: Callable[[Rows], Array]
    pixel_size: Callable[[Rows], Array] | None
    correlated: CorrelatedNoise | None

    @classmethod
    def of(cls, sensor: SensorModel) -> Noise:
        """The noise of ``sensor``, from its members (the module docstring)."""
        shape = np.asarray(sensor.shape)
        if isinstance(sensor, GroupedEntries):  # per entry, from the sensor (a rig of sensors with residuals of different widths)
            groups = np.asarray(sensor.noise_groups, dtype=np.intp)
        else:
            column = np.zeros(shape.shape[1], dtype=np.intp)
            for g, cols in enumerate(sensor.groups):
                column[list(cols)] = g
            groups = np.broadcast_to(column, shape.shape)
        mask = sensor.entry_mask if isinstance(sensor, PaddedEntries) else None
        return cls(shape, groups, None if mask is None else np.asarray(mask, bool), sensor.noise_mm,
                   sensor.pixel_size if isinstance(sensor, PixelResiduals) else None,
                   sensor if isinstance(sensor, CorrelatedNoise) else None)
