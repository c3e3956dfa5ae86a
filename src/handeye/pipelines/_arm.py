"""What the markerless pipelines share (the arm itself the target: :mod:`handeye.pipelines.depth.arm`,
:mod:`handeye.pipelines.silhouette.pipeline`): the arm's table in X's std.

The links a markerless camera is fitted to are placed by the joint angles through the arm's table,
taken as nominal. A real arm's table is off by its tolerances, which moves every link, and X takes
that error whole: on the simulator, an arm 0.5-1 mm / 0.05 deg off per entry moved X by 5 mm while
the fit's own std promised under 1 mm. :func:`arm_table` has the core add it to X's std: the fit's
sensitivity to each entry (every point moved with its link, :meth:`~handeye.robot.meshes.ArmMeshes.table_twists`)
through Schmidt's consider covariance (:func:`~handeye.estimation.uncertainty.consider_cov`), each
entry with the prior of an uncalibrated arm (:func:`~handeye.robot.models.entry_priors`) for the
shipped nominal table, or of a calibrated one (:data:`CALIBRATED`) for a table calibrated from it
(``arm_corrected.yaml``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from ..estimation.core import Held
from ..estimation.uncertainty import consider_cov
from ..frames.metrics import std_deg_mm
from ..robot.kinematics import Chain, load_arm
from ..robot.meshes import ArmMeshes, mesh_arm_names
from ..robot.models import ANGLE_PRIOR_RAD, LENGTH_PRIOR_M, entry_priors
from ..sensors.base import SensorModel

__all__ = ["arm_table_cov", "arm_table", "table_tolerance", "CALIBRATED"]

#: The tolerance (m, rad) left in a table calibrated with X from joint angles and a board: what
#: such a fit determines its entries to (tenths of a millimetre, hundredths of a degree).
CALIBRATED = (1e-4, float(np.radians(0.01)))


def table_tolerance(chain: Chain) -> tuple[float, float, str]:
    """The tolerance of ``chain``'s entries (m, rad) and its name in words: an uncalibrated arm's for a
    shipped nominal table, a calibrated one's (:data:`CALIBRATED`) for a table corrected from it."""
    # the shipped table read from a URDF or written again differs by rounding (micrometres at most)
    if any(load_arm(name).table.shape == chain.table.shape and np.allclose(load_arm(name).table, chain.table, atol=1e-6)
           for name in mesh_arm_names()):
        return LENGTH_PRIOR_M, ANGLE_PRIOR_RAD, "an uncalibrated arm's: the nominal table"
    return CALIBRATED[0], CALIBRATED[1], "a calibrated arm's: a table calibrated from the nominal one"


def arm_table_cov(model: SensorModel, X: NDArray[np.float64], points: NDArray[np.float64], meshes: ArmMeshes, chain: Chain,
                  joints: NDArray[np.float64]) -> NDArray[np.float64]:
    """X's covariance (6, 6) from the arm's table held at its nominal values: ``model``'s rows are
    ``points`` (M, 3, base frame) on the arm in views ``model.owner`` (of ``joints``), fitted at ``X``."""
    rows = np.arange(len(model.owner))
    F = np.broadcast_to(np.eye(4), (len(joints), 4, 4))
    J = model.jacobian(X, np.zeros(len(model.param_names)), F, rows)[:, 0, :]
    link2base = meshes.link2base(chain, joints)
    links = np.empty(len(rows), dtype=np.intp)
    for v in np.unique(model.owner):
        at = model.owner == v
        links[at] = meshes.nearest_link(link2base[v], points[at])
    twist = meshes.table_twists(chain, joints)[:, model.owner, links]  # (E, M, 6)
    moved = np.cross(twist[..., :3], points) + twist[..., 3:]  # each point carried by its link, per unit of each entry
    # moving the arm's surface by d moves a residual as moving the camera by -d (X's translation columns)
    held = -np.einsum("mi,emi->me", J[:, 3:6], moved)
    length, angle, _ = table_tolerance(chain)
    prior = entry_priors(chain.parameter_names(), length, angle)
    return consider_cov(J, np.asarray(model.shape, float)[:, 0], held, prior)[:6, :6]


def arm_table(model: SensorModel, points: Callable[[NDArray[np.float64]], NDArray[np.float64]], meshes: ArmMeshes,
              chain: Chain, joints: NDArray[np.float64], sensor: str) -> Held:
    """The arm's table as what the core's fit holds (:func:`handeye.estimation.core.estimate`'s
    ``held``): at the fitted X, its covariance from the table (:func:`arm_table_cov`; ``points(X)``
    the model's rows in the base frame), the source ``arm_table`` and a note saying so; the core adds
    it to X's covariance before it judges X's std (``sensor``: the camera in words)."""
    length, angle, words = table_tolerance(chain)

    def held(X: NDArray[np.float64], p: NDArray[np.float64]) -> tuple[str, NDArray[np.float64], str]:
        cov = arm_table_cov(model, X, points(X), meshes, chain, joints)
        part = std_deg_mm(cov)
        return "arm_table", cov, (
            f"the std of X includes the arm's table: the {sensor} sees links the joint angles place through the table "
            f"given, whose entries' tolerance ({1e3 * length:g} mm / {np.degrees(angle):g} deg, {words}) X takes whole: "
            f"up to {part[:3].max():.3f} deg / {part[3:].max():.2f} mm per std")
    return held
