"""X and Z fitted together with an arm's kinematic parameters, from its joint angles.

A black-box calibration takes the flange poses the controller reports as given and can only widen
X's std by the robot's absolute accuracy. With the joint angles and the arm's kinematic chain
(:class:`handeye.robot.kinematics.Chain`), the chain's table entries are unknowns too: the flange pose of
view i is the chain's forward kinematics at ``q_i`` with the table corrected by ``delta``, and X, Z
and ``delta`` are fitted to what the camera saw. Every entry has a Gaussian prior about its nominal
value (the manufacturer's tolerance: ``prior_std``), so the entries the capture cannot determine (a
joint never moved, lengths along parallel axes of which only the sum shows) stay near nominal and
their uncertainty reaches X's covariance; the entries that only move the base or the flange frame
(:func:`handeye.robot.kinematics.absorbed_parameters`) are left to X and Z.

With ``compliance``, each joint's compliance (:meth:`handeye.robot.kinematics.Chain.moment_arms`) is an
unknown too, about 0 with the prior :data:`COMPLIANCE_PRIOR` (joints whose axis the load never
turns, such as a vertical first joint's, have none to fit).

Residuals: with images, the pixel errors of the target's points (``image_points``); with poses
alone, the error of the predicted viewing rays of a virtual target's points, across the ray (in
metres at the target's distance: what pixels measure, without PnP's depth error).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from ..errors import HandEyeError, InputMismatchError
from ..frames.setups import predicted_target2cam
from ..robot.kinematics import Chain
from ..robot.models import ANGLE_PRIOR_RAD, COMPLIANCE_PRIOR, LENGTH_PRIOR_M, entry_priors, fitted_entries
from ..sensors.camera.pnp import project_points_many
from ._common import _normal_inverse, _xz_increment

__all__ = ["KinematicRefinement", "refine_kinematic", "DETERMINED", "LENGTH_PRIOR_M", "ANGLE_PRIOR_RAD",
           "COMPLIANCE_PRIOR"]

#: An entry is determined by the capture when its posterior std is below this share of its prior's.
DETERMINED = 0.5
#: Points of the virtual target (target frame, m) whose viewing rays carry the residuals of pose-only data.
_VIRTUAL = np.array([[x, y, 0.0] for x in np.linspace(0.0, 0.2, 5) for y in np.linspace(0.0, 0.15, 4)])


@dataclass(frozen=True)
class KinematicRefinement:
    """What :func:`refine_kinematic` found.

    Attributes
    ----------
    X, Z : ndarray (4, 4)
    deltas : ndarray (n, 4)
        Corrections to the chain's table (a, alpha, d, theta per joint); 0 for the entries left to X and Z.
    names : list of str
        The table entries estimated (then ``joint<k>.compliance``, when fitted), in the order of
        ``cov``'s last rows.
    cov : ndarray (12 + m, 12 + m)
        Over [X rotation, X translation, Z rotation, Z translation, the entries ``names``].
    prior_std : ndarray (m,)
    sigma : float
        The residuals' std per coordinate (px with images, m at the target without).
    rms : float
        RMS residual per point (px or m).
    success : bool
    compliance : ndarray (n,) or None
        Each joint's compliance (rad per metre; 0 where not fitted), when fitted.
    """

    X: NDArray[np.float64]
    Z: NDArray[np.float64]
    deltas: NDArray[np.float64]
    names: list[str]
    cov: NDArray[np.float64]
    prior_std: NDArray[np.float64]
    sigma: float
    rms: float
    success: bool
    compliance: NDArray[np.float64] | None = None

    @property
    def cov_X(self) -> NDArray[np.float64]:
        """6x6 over X's rotation vector (rad) and translation (m)."""
        return self.cov[:6, :6]

    @property
    def parameter_std(self) -> NDArray[np.float64]:
        """Posterior std of each entry of ``names``."""
        return np.sqrt(np.diag(self.cov)[12:])

    @property
    def determined(self) -> NDArray[np.bool_]:
        """Per entry of ``names``: whether the capture determines it (posterior std below
        :data:`DETERMINED` of the prior's); the others stay near nominal."""
        return self.parameter_std < DETERMINED * self.prior_std


def refine_kinematic(
    X0: NDArray[np.float64],
    Z0: NDArray[np.float64],
    chain: Chain,
    joints: NDArray[np.float64],
    setup: str,
    *,
    object_points: list[NDArray[np.float64]] | None = None,
    image_points: list[NDArray[np.float64]] | None = None,
    K: NDArray[np.float64] | None = None,
    dist: NDArray[np.float64] | None = None,
    target2cam: NDArray[np.float64] | None = None,
    sigma: float | None = None,
    length_prior: float = LENGTH_PRIOR_M,
    angle_prior: float = ANGLE_PRIOR_RAD,
    rounds: int = 3,
    deltas0: NDArray[np.float64] | None = None,
    tol: float = 1e-12,
    compliance: bool = False,
    compliance_prior: float = COMPLIANCE_PRIOR,
    compliance0: NDArray[np.float64] | None = None,
) -> KinematicRefinement:
    """X, Z and the chain's table corrections fitted to what the camera saw.

    Parameters
    ----------
    X0, Z0 : (4, 4)
        Start (a black-box calibration on the nominal chain's flange poses).
    chain : Chain
    joints : (N, n)
        Joint angles (rad) per view.
    setup : {'eye_in_hand', 'eye_to_hand'}
    object_points, image_points, K, dist
        Per view the target's points (M_i, 3) and their detections (M_i, 2), and the intrinsics:
        residuals in pixels. Without them, ``target2cam`` (N, 4, 4): residuals across the viewing rays.
    sigma : float, optional
        The residuals' std per coordinate; by default estimated from the fit (``rounds`` fits,
        each weighting the prior against the data's last estimate).
    length_prior, angle_prior : float
        Prior std of the table's lengths (m) and angles (rad) about their nominal values.
    deltas0 : (n, 4), optional
        Table corrections to start from (a refit on part of the views starts at the fit on all).
    tol : float
        The solver's tolerances (a refit near its start needs fewer digits).
    compliance : bool
        Fit each joint's compliance too (the chain's own, if any, is the start and the prior's centre).
    compliance_prior : float
        Its prior std (rad per metre).
    compliance0 : (n,), optional
        The joints' compliance to start from (a refit's: the fit on all's).
    """
    joints = np.asarray(joints, dtype=float)
    if joints.ndim != 2 or joints.shape[1] != chain.n_joints:
        raise InputMismatchError(f"{chain.name} has {chain.n_joints} joints; the joint angles have shape {joints.shape}")
    every, names, index = fitted_entries(chain, joints, compliance)
    prior_std = entry_priors(names, length_prior, angle_prior, compliance_prior)
    residual = _residual_function(chain, joints, setup, object_points, image_points, K, dist, target2cam)
    p0 = np.zeros(len(every))
    n_data = len(residual(X0, Z0, p0))

    def unpack(x):
        X, Z = _xz_increment(x, X0, Z0)
        p = np.zeros(len(every))
        p[index] = x[12:] * prior_std  # the entries in units of their prior std, about nominal
        return X, Z, p

    x = np.r_[np.zeros(12), _start(chain, len(every), deltas0, compliance0 if compliance else None)[index] / prior_std]
    dof = max(n_data - 12 - len(names), 1)
    s = sigma if sigma is not None else max(float(np.sqrt(np.sum(residual(X0, Z0, p0) ** 2) / dof)), 1e-12)
    for _ in range(1 if sigma is not None else rounds):
        def whitened(x, s=s):
            X, Z, p = unpack(x)
            return np.concatenate([residual(X, Z, p) / s, x[12:]])  # the prior: unit std in these units
        res = least_squares(whitened, x, method="trf", x_scale=np.r_[np.full(12, 1e-3), np.ones(len(names))],
                            xtol=tol, ftol=tol, gtol=tol)
        if not np.isfinite(res.x).all():
            raise HandEyeError("the kinematic refinement failed (no finite solution)")
        x, used = res.x, s
        if sigma is None:  # the data's own std, for the next fit's balance of data and prior
            s = max(float(np.sqrt(np.sum((res.fun[:n_data] * used) ** 2) / dof)), 1e-12)
    X, Z, p = unpack(x)
    J = res.jac.copy()
    J[:n_data] *= used / s  # whitened by the final std
    # covariance in natural units: X's and Z's increments as they are, the entries times their prior std
    scale = np.r_[np.ones(12), prior_std]
    cov = _normal_inverse(J) * np.outer(scale, scale)
    rms = float(np.sqrt(np.mean(residual(X, Z, p).reshape(-1, 2) ** 2) * 2))
    size = chain.table.size
    own = np.zeros(chain.n_joints) if chain.compliance is None else chain.compliance
    return KinematicRefinement(X, Z, p[:size].reshape(chain.table.shape), names, cov, prior_std, float(s), rms,
                               bool(res.success), own + p[size:] if compliance else None)


def _start(chain: Chain, size: int, deltas0, compliance0) -> NDArray[np.float64]:
    """The parameter vector (``size`` long) to start from: the table's corrections ``deltas0`` and
    the joints' compliance ``compliance0`` (as corrections to the chain's own), 0 where not given."""
    start = np.zeros(size)
    if deltas0 is not None:
        start[:chain.table.size] = np.asarray(deltas0, dtype=float).ravel()
    if compliance0 is not None:
        start[chain.table.size:] = np.asarray(compliance0, dtype=float).ravel() - (
            0.0 if chain.compliance is None else chain.compliance)
    return start


def _residual_function(chain, joints, setup, object_points, image_points, K, dist, target2cam):
    """``residual(X, Z, p) -> (2 M,)``: pixels with images, else metres across the viewing rays; ``p``
    the parameter vector of ``chain.forward_with``."""
    if image_points is not None:
        if object_points is None or K is None or dist is None or len(image_points) != len(joints):
            raise InputMismatchError("pixel residuals need object_points, image_points (one per view), K and dist")
        owner = np.concatenate([np.full(len(p), i) for i, p in enumerate(object_points)])
        points = np.concatenate([np.asarray(p, dtype=float) for p in object_points])
        seen = np.concatenate([np.asarray(p, dtype=float) for p in image_points])

        def residual(X, Z, p):
            T = predicted_target2cam(X, Z, chain.forward_with(joints, p), setup)
            return (project_points_many(T, points, owner, K, dist) - seen).ravel()
        return residual
    if target2cam is None or len(target2cam) != len(joints):
        raise InputMismatchError("give the detections (image_points ...) or target2cam, one per view")
    measured = np.einsum("nij,mj->nmi", target2cam[:, :3, :3], _VIRTUAL) + target2cam[:, None, :3, 3]
    depth = measured[..., 2]

    def residual(X, Z, p):
        T = predicted_target2cam(X, Z, chain.forward_with(joints, p), setup)
        seen = np.einsum("nij,mj->nmi", T[:, :3, :3], _VIRTUAL) + T[:, None, :3, 3]
        across = (seen[..., :2] / seen[..., 2:3] - measured[..., :2] / depth[..., None]) * depth[..., None]
        return across.ravel()
    return residual

