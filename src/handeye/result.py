"""The results of handeye, as data: :class:`Calibration` and :class:`Diagnostics`.

Nothing here computes a calibration or writes a file: the pipeline (``handeye.pipelines.calibration``)
builds these records step by step, each step returning a new one (``dataclasses.replace``), and
``handeye.report`` turns them into files for robots and people.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._shared.text import summarize
from .errors import InputMismatchError
from .frames.metrics import rotation_error, translation_error
from .frames.motions import MotionSet, screw_congruence
from .frames.poses import RobotPoseInput
from .frames.setups import constant_transforms, setup_info
from .geometry.se3 import PITCH_ANGLE, rotation_angle, skew
from .robot.kinematics import Chain, display_unit
from .solvers.certifiable import Certificate

__all__ = ["Calibration", "Diagnostics", "Unobservable", "Observability", "HeldOutErrors", "StreamSync", "Certificate",
           "KinematicModel", "SensorFit"]


@dataclass(frozen=True)
class Unobservable:
    """A part of X the data cannot determine (robots that cannot rotate freely: SCARA, planar,
    Cartesian; :mod:`handeye.solvers.low_dof`).

    Attributes
    ----------
    parameter : str
        In words, e.g. "translation of cam2flange along the flange z axis".
    transform, frame : str
        The transform (``cam2flange``...) and the frame its direction is given in (``flange``...).
    direction : ndarray (3,)
        Unit vector in ``frame``: X's translation along it is undetermined.
    value : float
        The value chosen for it (m): X's translation along ``direction``.
    choice : str
        Why that value.
    coupled : str
        What the data do determine about it (e.g. its difference with the target's height).
    fix : str
        How to determine it: the ``known=`` keys that would, or what to capture.
    """

    parameter: str
    transform: str
    frame: str
    direction: NDArray[np.float64]
    value: float
    choice: str
    coupled: str
    fix: str

    def as_dict(self) -> dict:
        return {"parameter": self.parameter, "transform": self.transform, "frame": self.frame,
                "direction": [float(v) for v in self.direction], "value_m": float(self.value), "choice": self.choice,
                "coupled": self.coupled, "fix": self.fix}


@dataclass(frozen=True)
class Observability:
    """What the robot's motions determine of X (:mod:`handeye.estimation.partial`), and what was given for the rest.

    Attributes
    ----------
    motion_kind : {'general', 'one_axis', 'translation_only'}
        The robot's motions: general, all rotations about one axis (SCARA, planar) or none (Cartesian).
    unobservable : list of Unobservable
        What the data cannot determine of X (empty when X is complete); ``Calibration.std`` is inf there.
    known : dict
        The values given with ``known=``: name -> {'value_m', 'std_m', 'used' (it fixed what the data
        could not), 'data_m' (the data's own value when they determine it, else None)}.
    """

    motion_kind: str = "general"
    unobservable: list[Unobservable] = field(default_factory=list)
    known: dict[str, dict] = field(default_factory=dict)


@dataclass(frozen=True)
class HeldOutErrors(Mapping):
    """Held-out prediction error per estimator tried, from K-fold cross-validation: a mapping name ->
    {'px': RMS pixels (None without images), 'mm': RMS at the target's distance}.

    Attributes
    ----------
    errors : dict
        The mapping itself.
    folds : int or None
        K, the number of folds (None when not recorded).
    """

    errors: dict[str, dict[str, float | None]]
    folds: int | None = None

    def __getitem__(self, name: str) -> dict[str, float | None]:
        return self.errors[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self.errors)

    def __len__(self) -> int:
        return len(self.errors)


@dataclass(frozen=True)
class KinematicModel:
    """The arm's kinematics a calibration from joint angles found (:func:`handeye.calibrate_joints`).

    Attributes
    ----------
    nominal, chain : Chain
        The arm's table as given, and corrected.
    names : list of str
        The table entries estimated (``joint<k>.<a|alpha|d|theta>``; the others move only the base or
        the flange frame and are X's and Z's), then ``joint<k>.compliance`` when fitted.
    correction, std, prior_std : ndarray (m,)
        Per entry its correction to the nominal value, its std and its prior's (m or rad).
    determined : ndarray (m,) of bool
        Whether the capture determines it (else it stays near nominal and its prior reaches X's std).
    """

    nominal: Chain
    chain: Chain
    names: list[str]
    correction: NDArray[np.float64]
    std: NDArray[np.float64]
    prior_std: NDArray[np.float64]
    determined: NDArray[np.bool_]
    #: how far the corrected table moves the flange from the nominal one over the capture's joint
    #: angles (mm: median, largest): the arm's absolute error as the calibration found it
    flange_shift_mm: tuple[float, float] | None = None
    #: the arm's absolute accuracy at the flange (mm, median over joint angles drawn within the
    #: capture's range of each joint): 'before' the nominal table's error as the fit found it,
    #: 'after' the corrected table's predicted error (1 std: its entries' covariance, widened to
    #: their jackknife spread, propagated; on 12 simulated captures the true error was 0.41-1.07x
    #: it, median 0.65x); with the ``workspace_`` keys the same over the joints' whole range (the
    #: chain's limits, when known)
    accuracy_mm: dict[str, float] | None = None
    #: the joint angles (rad) of the views fitted, in the calibration's order
    joints: NDArray[np.float64] | None = None

    @property
    def undetermined(self) -> list[str]:
        """The entries the capture does not determine."""
        return [n for n, d in zip(self.names, self.determined) if not d]

    def as_dict(self) -> dict:
        """The model as result.json writes it (lengths in mm, angles in degrees, compliance in
        degrees per metre of the load's moment arm)."""
        entries = {}
        for name, c, s, p, d in zip(self.names, self.correction, self.std, self.prior_std, self.determined):
            f, u = display_unit(name)
            entries[name] = {"correction": float(f * c), "std": float(f * s), "prior_std": float(f * p), "unit": u,
                             "determined": bool(d)}
        return {"arm": self.nominal.name, "convention": self.nominal.convention,
                "flange_shift_mm": None if self.flange_shift_mm is None else
                {"median": float(self.flange_shift_mm[0]), "max": float(self.flange_shift_mm[1])},
                "accuracy_mm": self.accuracy_mm,
                "table": {"columns": ["a_m", "alpha_rad", "d_m", "theta_offset_rad"], "nominal": self.nominal.table.tolist(),
                          "corrected": self.chain.table.tolist()},
                "compliance_rad_per_m": None if self.chain.compliance is None else self.chain.compliance.tolist(),
                "entries": entries, "undetermined": self.undetermined}


@dataclass(frozen=True)
class SensorFit:
    """What the fit of a sensor model found beside X (:mod:`handeye.estimation.core`): the sensor,
    the target, each view's residual and the sensor's own figures.

    Attributes
    ----------
    sensor, target : str
        In words (``'depth camera'``, ``'spheres'``; ``'laser line profiler'``, ``'sphere'`` ...).
    views : list of str
        The views the fit used, in the calibration's order.
    residual_mm : ndarray (len(views),)
        Per view, the RMS of its measurements' residuals (mm).
    fit_rms_mm : float
        The same over every view.
    figures : dict
        The sensor's own results (a depth scale and bias with their std, the target's centres or
        radius, ...), plain numbers as result.json writes them.
    points, rejected : int
        Measurements fitted, and set aside as outliers (beyond 5 of their std).
    heldout_mm : ndarray (len(views),) or None
        Per view its error when held out of the fit (cross-validation), mm.
    sections : list of dict or None
        Per view, what the report draws of it, in the sensor's own plane (a profiler's laser plane):
        ``points_mm`` (n, 2) measured, ``residual_mm`` (n,) theirs, ``curve_mm`` (m, 2) the fitted
        target's section there (NaN where it has none), optional ``plane`` (what it is drawn in, in
        words), ``label``, ``rms_mm``; or, for 3D clouds registered in one frame (a scene's),
        ``cloud_mm`` (n, 3), ``residual_mm`` (n,) and ``frame`` (that frame in words). None when the
        sensor draws nothing. Not in result.json (the raw measurements stay in the session).
    params : ndarray or None
        The sensor's unknowns as fitted (its model's ``param_names``, in order): what a later fit
        starts from (a rig starts from each sensor's own). Not in result.json (``figures`` says
        what of them a user reads).
    unknowns : list of dict
        The sensor's unknowns beside X and Z that a capture may leave undetermined (a depth scale and
        bias, a ball's radius, a focal length, a clock offset): per unknown its ``name``, ``value``
        and ``std`` as a user reads them (std None when held), ``unit``, ``status`` ('fitted',
        'held': not determined by the capture, or asked; 'given': the session's value) and ``why``.
        X holds with these values.
    """

    sensor: str
    target: str
    views: list[str]
    residual_mm: NDArray[np.float64]
    fit_rms_mm: float
    figures: dict[str, Any] = field(default_factory=dict)
    points: int = 0
    rejected: int = 0
    heldout_mm: NDArray[np.float64] | None = None
    sections: list[dict[str, NDArray[np.float64]]] | None = None
    params: NDArray[np.float64] | None = None
    unknowns: list[dict[str, Any]] = field(default_factory=list)


@dataclass(frozen=True)
class StreamSync:
    """How :func:`handeye.calibrate_streams` put the robot and the camera on one clock.

    Attributes
    ----------
    time_offset, time_offset_std : float
        The camera clock minus the robot clock (s), and its std.
    details : dict
        Rates, samples, the coarse offset and its correlation, the joint fit, and the keyframes'
        camera times (``handeye.estimation.sync``), as written to result.json's ``time_sync``.
    """

    time_offset: float
    time_offset_std: float
    details: dict = field(default_factory=dict)


@dataclass
class Diagnostics:
    """What :func:`diagnose` found (the public API).

    Attributes
    ----------
    verdict : {'good', 'weak', 'partial', 'degenerate', 'inconsistent'}
        'partial': the motions determine only part of X (all rotations about one axis, or none at
        all): :func:`handeye.calibrate_poses` returns that part and names the rest
        (``Calibration.unobservable``).
    advice : list of str
        Sentences saying what is wrong and what to do.
    convention_hint : str or None
        The reading that makes inconsistent data consistent: ``'invert_robot_poses'``,
        ``'invert_camera_poses'``, ``'length_unit:mm'``, ``'length_unit:m'``, ``'angle_unit:deg'``,
        ``'angle_unit:rad'``, ``'quat_xyzw'``, ``'quat_wxyz'``, ``'euler:SEQ'``, ``'camera:...'`` (the
        same for the camera poses) or ``'setup:eye_in_hand'`` / ``'setup:eye_to_hand'`` (the other setup,
        which reads the same data as inverted robot poses; chosen when it places the camera and the
        target more plausibly).
    outliers : list of int
        Indices of the poses judged bad.
    outlier_residuals : dict
        Per outlier: (rotation deg, translation mm) from the consensus target pose.
    consistency : float
        Unit-free score of the data (inliers) as given: the larger of the median per-pose rotation
        residual over 1 deg and the median translation residual over 2% of the camera's motion
        scale; up to 3 is consistent.
    axis_shares : ndarray (3,)
        Eigenvalues (descending, sum 1) of the scatter of the camera motions' rotation axes, weighted
        by rotation; all near 1/3 is ideal, a small last one means a missing rotation axis.
    weakest_axis : ndarray (3,)
        The camera-frame direction with the least rotation about it.
    rotation_angles_deg : ndarray (K,)
        Rotation angle of every camera motion.
    singular_values : ndarray (8,) or None
        Of the Daniilidis system (two near zero expected).
    translation_condition : float or None
        Condition number of the translation system ``sum (I - R_A)^T (I - R_A)``.
    leave_one_out : ndarray (N, 2) or None
        How far X moves (deg, mm) when each pose is left out (NaN for outliers).
    """

    verdict: str
    advice: list[str] = field(default_factory=list)
    convention_hint: str | None = None
    outliers: list[int] = field(default_factory=list)
    outlier_residuals: dict[int, tuple[float, float]] = field(default_factory=dict)
    consistency: float = float("nan")
    axis_shares: NDArray[np.float64] | None = None
    weakest_axis: NDArray[np.float64] | None = None
    rotation_angles_deg: NDArray[np.float64] | None = None
    singular_values: NDArray[np.float64] | None = None
    translation_condition: float | None = None
    leave_one_out: NDArray[np.float64] | None = None
    pose_residuals: NDArray[np.float64] | None = None  #: (N, 2) deg, mm from the consensus target pose
    n_poses: int = 0
    #: consistency score up to which data count as consistent (handeye.estimation.diagnostics.CONSISTENT)
    consistency_limit: float = 3.0
    #: the factor that maps the camera's translations onto the robot's (1 when the target's size and
    #: the units are right), and its standard deviation; None when not estimated
    scale: float | None = None
    scale_std: float | None = None
    #: 'general', or the low-DOF motions the check found ('one_axis', 'translation_only'; see
    #: :mod:`handeye.estimation.partial`), which stay so when the verdict is 'inconsistent'
    motion_kind: str = "general"
    #: each pose's name (its image file, or its row id in a pose table); None: poses are numbered
    names: list[str] | None = None

    def pose_name(self, i: int) -> str:
        """Pose ``i`` as people know it: its image file or row id (else ``pose i``)."""
        return self.names[i] if self.names else f"pose {i}"

    def pose_names(self, idx) -> str:
        """Poses ``idx`` by name, summarised when many."""
        return summarize(self.pose_name(int(i)) for i in idx)

    def pose_table(self, names: list[str] | None = None) -> str:
        """Per pose: residual from the consensus and how far X moves without it."""
        names = names or self.names
        rows = [f"{'pose':>5} {'name':<24} {'resid deg':>9} {'resid mm':>9} {'loo deg':>8} {'loo mm':>8}  flag"]
        for i in range(self.n_poses):
            name = names[i] if names else ""
            r = self.pose_residuals[i] if self.pose_residuals is not None else (np.nan, np.nan)
            lo = self.leave_one_out[i] if self.leave_one_out is not None else (np.nan, np.nan)
            rows.append(f"{i:>5} {name:<24.24} {r[0]:>9.3f} {r[1]:>9.2f} {lo[0]:>8.3f} {lo[1]:>8.2f}  "
                        f"{'OUTLIER' if i in self.outliers else ''}")
        return "\n".join(rows)

    def summary(self) -> str:
        """A few lines for people: verdict, outliers, advice."""
        consistency = (f"consistency {self.consistency:.2f}: the median pose residual in units of 1 deg or 2% of the "
                       f"camera's motion, whichever is larger; up to {self.consistency_limit:g} is consistent"
                       if np.isfinite(self.consistency) else "consistency not computed")
        lines = [f"verdict: {self.verdict} ({self.n_poses} poses, {consistency})"]
        if self.convention_hint:
            lines.append(f"convention hint: {self.convention_hint}")
        if self.scale is not None:
            lines.append(f"scale of the camera translations to the robot's: {self.scale:.4f} +- {self.scale_std:.4f} "
                         "(1 when the target size and the units are right)")
        for i in self.outliers:
            r, t = self.outlier_residuals.get(i, (float("nan"), float("nan")))
            lines.append(f"outlier {self.pose_name(i)}: {r:.3f} deg / {t:.2f} mm from the consensus")
        if self.leave_one_out is not None and np.isfinite(self.leave_one_out).any():
            loo = np.where(np.isfinite(self.leave_one_out), self.leave_one_out, -1.0)
            worst = np.argsort(-loo[:, 1])[:3]
            lines.append("leaving one pose out moves X most for " + ("" if self.names else "poses ") + ", ".join(
                f"{self.names[i] if self.names else i} ({loo[i, 0]:.3f} deg / {loo[i, 1]:.2f} mm)" for i in worst))
        lines += [f"advice: {a}" for a in self.advice]
        return "\n".join(lines)


@dataclass
class Calibration:
    """The result of a hand-eye calibration.

    Attributes
    ----------
    X : ndarray (4, 4)
        ``cam2flange`` (eye_in_hand) or ``cam2base`` (eye_to_hand), metres; the sensor's frame for
        other sensors (``sensor2flange``, ``sensor2base``: the same matrix).
    Z : ndarray (4, 4)
        ``target2base`` (eye_in_hand) or ``target2flange`` (eye_to_hand): the mean over poses.
    setup, method : str
    flange2base, target2cam : ndarray (N, 4, 4)
        The (validated) inputs; ``target2cam`` is None for sensors whose views measure no whole
        pose of the target (a ball's centre, a laser profile), and both are None for a result read
        back from its file (:func:`handeye.load_result`).
    pairs : ndarray (K, 2)
        The pose index pairs of the motions used (none without ``target2cam``).
    cov : ndarray (6, 6) or None
        Covariance of X over [rotation vector (rad), translation (m)]; None when not computed.
    std : ndarray (6,) or None
        Standard deviations of the same six, in degrees and millimetres.
    motion_residuals : ndarray (K, 2)
        Screw congruence per motion: ``|theta_A - theta_B|`` (deg), ``|d_A - d_B|`` (mm). Computed
        on first access.
    pose_residuals : ndarray (N, 2)
        Per pose, how far its own ``Z_i`` (through X) is from Z: rotation (deg), translation (mm).
    cross_validation : HeldOutErrors or None
        Held-out prediction error per estimator tried (a mapping); ``prediction_error`` is the chosen one's.
    observability : Observability
        What the motions determine of X (``motion_kind``, ``unobservable``, ``known``, also read directly).
    certificate : Certificate or None
        From :func:`handeye.certify_calibration`.
    sync : StreamSync or None
        From :func:`handeye.calibrate_streams` (``time_offset``, ``time_offset_std``, ``streams``, also read
        directly).
    """

    X: NDArray[np.float64]
    Z: NDArray[np.float64]
    setup: str
    method: str
    flange2base: NDArray[np.float64] | None = field(default=None, repr=False)
    target2cam: NDArray[np.float64] | None = field(default=None, repr=False)
    pairs: NDArray[np.intp] = field(default_factory=lambda: np.zeros((0, 2), dtype=np.intp), repr=False)
    cov: NDArray[np.float64] | None = None
    std: NDArray[np.float64] | None = None
    #: the motions the solver saw (built from the poses and pairs when not given)
    motions: MotionSet | None = field(default=None, repr=False)
    # filled by calibrate() from images
    image_names: list[str] | None = None
    reprojection_rms: NDArray[np.float64] | None = None  #: per used image, px
    skipped: list[tuple[str, str]] = field(default_factory=list)  #: (image, reason)
    camera_matrix: NDArray[np.float64] | None = None
    dist_coeffs: NDArray[np.float64] | None = None
    intrinsics_source: str | None = None  #: "session.yaml" or "estimated"
    #: the factor the target's given size was multiplied by: the scale the robot's motions give when the
    #: check found the given size wrong (the target's points, Z and the camera's poses are at that size)
    target_scale: float = 1.0
    intrinsics_rms: float | None = None
    #: how X was refined: "none" (a closed form), "pose", "reprojection", "kinematic" (joint angles: the arm's
    #: table fitted with X) or "sensor fit" (a sensor model fitted by handeye.estimation.core.estimate)
    refinement: str = "none"
    refined_rms: float | None = None  #: RMS reprojection error (px) of all points after refinement
    #: pose refinement's noise estimates: robot rotation (deg), camera rotation (deg), translation (mm), camera depth (mm)
    pose_noise: dict[str, float] | None = None
    diagnostics: Diagnostics | None = field(default=None, repr=False)  #: from handeye.diagnose (check=True)
    #: indices (into the poses given) of the poses used: outliers are left out
    pose_indices: NDArray[np.intp] | None = field(default=None, repr=False)
    notes: list[str] = field(default_factory=list)
    #: the robot poses as written (format and units), for results in the user's own convention
    robot_input: RobotPoseInput | None = field(default=None, repr=False)
    #: SHA-256 of the inputs: the session's files (calibrate) or the pose arrays (calibrate_poses)
    inputs_sha256: str | None = None
    #: per used image: its path, and the target points (target frame, m) with their detections (px)
    image_paths: list[Path] | None = field(default=None, repr=False)
    #: the folder the inputs were read from (a session, a pose-pair folder): results never go into it
    input_folder: Path | None = field(default=None, repr=False)
    object_points: list[NDArray[np.float64]] | None = field(default=None, repr=False)
    image_points: list[NDArray[np.float64]] | None = field(default=None, repr=False)
    #: per solver: its closed-form X on the same poses, from handeye.estimation.diagnostics.compare_solvers
    solver_comparison: list[dict] | None = field(default=None, repr=False)
    #: the estimator that gave X (a solver name, 'pose', 'reprojection', ...: handeye.estimation.estimators;
    #: 'kinematic' for joint angles, 'fit' or 'fit with the arm's table' for a sensor fit)
    estimator: str | None = None
    #: held-out prediction error per estimator tried (a mapping name -> {'px', 'mm'}); None when not cross-validated
    cross_validation: HeldOutErrors | None = None
    #: the std of X's six parameters (deg, mm) from each source: 'model' (the refinement's noise
    #: model, None for a closed form), 'jackknife' (the spread of X refitted without each pose),
    #: 'robot_accuracy', 'intrinsics' (estimated from the same images and held fixed), 'board_scale',
    #: and for a sensor fit 'data' (its noise model widened by the jackknife), 'held_unknowns' (the held
    #: nuisances' tolerances), 'arm_table' (a markerless fit's arm table)
    std_sources: dict[str, NDArray[np.float64] | None] | None = None
    #: the robot's absolute accuracy (deg, mm per axis) that X's std took: the stated one, or raised to
    #: what the views show of the robot's error; None when none was added (an exact robot)
    robot_accuracy: tuple[float, float] | None = None
    #: SHA-256 of each image in ``image_names`` (verify refuses a calibration's own images), None without images
    image_sha256: list[str] | None = None
    #: the std of Z's six parameters (deg, mm; rotation about and translation along Z's parent axes): the
    #: jackknife spread of Z refitted without each pose, plus the robot's absolute accuracy; None when not computed
    std_Z: NDArray[np.float64] | None = None
    #: what the motions determine of X (robots that cannot rotate freely), and the values given for the rest
    observability: Observability = field(default_factory=Observability)
    #: from handeye.certify_calibration: whether X is the global minimum of the stated motion cost; None when
    #: not certified
    certificate: Certificate | None = None
    #: from handeye.calibrate_streams: the clock offset and how the streams were synchronised; None for pairs
    sync: StreamSync | None = None
    #: from handeye.calibrate_joints: the arm's kinematics, corrected with X and Z; None for flange poses
    kinematic: KinematicModel | None = None
    #: from a sensor model's fit (depth clouds, laser profiles, ...; handeye.estimation.core): the sensor's
    #: own figures and each view's residual; None for images and pose pairs
    sensor: SensorFit | None = None

    # the sub-records' parts by their documented names -------------------------------------------
    @property
    def motion_kind(self) -> str:
        """The robot's motions: 'general', 'one_axis' (SCARA, planar) or 'translation_only' (Cartesian)."""
        return self.observability.motion_kind

    @property
    def unobservable(self) -> list[Unobservable]:
        """What the data cannot determine of X (empty when X is complete); ``std`` is inf there."""
        return self.observability.unobservable

    @property
    def known(self) -> dict[str, dict]:
        """The values given with ``known=`` (:class:`Observability`)."""
        return self.observability.known

    @property
    def time_offset(self) -> float | None:
        """The camera clock minus the robot clock (s), from :func:`handeye.calibrate_streams`; None for pairs."""
        return None if self.sync is None else self.sync.time_offset

    @property
    def time_offset_std(self) -> float | None:
        """The std of :attr:`time_offset` (s); None for pairs."""
        return None if self.sync is None else self.sync.time_offset_std

    @property
    def streams(self) -> dict | None:
        """How the streams were synchronised (:attr:`StreamSync.details`); None for pairs."""
        return None if self.sync is None else self.sync.details

    @property
    def verdict(self) -> str:
        """The check's verdict ('good', 'weak', 'partial', 'inconsistent'), or 'not checked'; 'partial'
        whenever part of X is undetermined (:attr:`unobservable`), checked or not, unless the check
        found the data inconsistent."""
        if self.unobservable and (self.diagnostics is None or self.diagnostics.verdict != "inconsistent"):
            return "partial"
        return self.diagnostics.verdict if self.diagnostics is not None else "not checked"

    def pose_name(self, j: int) -> str:
        """The name of this calibration's pose ``j`` (row ``j`` of ``flange2base``): its image file,
        or the check's name of the input pose it came from, else ``pose j``."""
        if self.image_names is not None and len(self.image_names) == len(self.flange2base):
            return self.image_names[j]
        if self.sensor is not None:
            return self.sensor.views[j]
        d, idx = self.diagnostics, self.pose_indices
        if d is not None and d.names and idx is not None and len(idx) == len(self.flange2base):
            return d.names[int(idx[j])]
        return f"pose {j}"

    def outliers_split(self) -> tuple[list[int], list[int]]:
        """The check's outlier poses (indices of the input poses): those left out of X, and those put
        back because the robust pixel refinement judges their points one by one."""
        if self.diagnostics is None:
            return [], []
        used = set(self.pose_indices.tolist()) if self.pose_indices is not None else set()
        outliers = self.diagnostics.outliers
        return [i for i in outliers if i not in used], [i for i in outliers if i in used]

    @property
    def prediction_error(self) -> dict[str, float | None] | None:
        """The cross-validated held-out error of the estimator used: ``{'px', 'mm'}`` (see
        :attr:`cross_validation`): how far off, from the robot pose alone, this calibration puts the
        target in a view it was not fitted on. The number to trust."""
        if self.cross_validation is None or self.estimator not in self.cross_validation:
            return None
        return self.cross_validation[self.estimator]

    @cached_property
    def motion_residuals(self) -> NDArray[np.float64]:
        """Screw congruence per motion (:class:`Calibration`'s attributes); none without camera poses."""
        if self.target2cam is None and self.motions is None:
            return np.zeros((0, 2))
        motions = self.motions
        if motions is None:
            motions = MotionSet.from_poses(self.flange2base, self.target2cam, self.setup, self.pairs)
        dtheta, dd = screw_congruence(motions)
        return np.stack([np.degrees(dtheta), 1e3 * dd], axis=1)

    @cached_property
    def motion_pitch_share(self) -> NDArray[np.float64]:
        """Per motion, ``|d_A - d_B|`` (:attr:`motion_residuals`) over the larger of the robot's and the
        camera's translation in it: the pitch difference as a share of the motion (a millimetre figure
        alone means little). NaN where the robot or the camera turns by less than
        :data:`~handeye.geometry.se3.PITCH_ANGLE`: the screw axis of a motion that hardly turns, and with it
        its pitch, is set by the poses' noise (a pure translation has none)."""
        motions = self.motions
        if motions is None and self.target2cam is None:
            return np.zeros(0)
        if motions is None:
            motions = MotionSet.from_poses(self.flange2base, self.target2cam, self.setup, self.pairs)
        scale = np.maximum(np.linalg.norm(motions.A[..., :3, 3], axis=-1), np.linalg.norm(motions.B[..., :3, 3], axis=-1))
        turn = np.minimum(rotation_angle(motions.A), rotation_angle(motions.B))
        return np.where(turn >= PITCH_ANGLE, 1e-3 * self.motion_residuals[:, 1] / np.maximum(scale, 1e-6), np.nan)

    @cached_property
    def pitch_where_turning(self) -> dict[str, float]:
        """The pitch difference over the motions that turn :data:`~handeye.geometry.se3.PITCH_ANGLE`
        or more (:attr:`motion_pitch_share` is NaN for the others): ``min_turn_deg``, ``motions`` (how
        many), and when there are any their ``median_mm``, ``max_mm``, ``median_share`` and ``max_share``."""
        share = self.motion_pitch_share
        turning = np.isfinite(share)
        out: dict[str, float] = {"min_turn_deg": float(np.degrees(PITCH_ANGLE)), "motions": int(turning.sum())}
        if turning.any():
            mm = self.motion_residuals[turning, 1]
            out |= {"median_mm": float(np.median(mm)), "max_mm": float(mm.max()),
                    "median_share": float(np.median(share[turning])), "max_share": float(share[turning].max())}
        return out

    def screw_congruence_text(self) -> str:
        """The screw congruence in words: the median and worst angle difference (deg) and pitch
        difference (% of the motion) over the motions, the pitch over those that turn enough."""
        angle, pitch = self.motion_residuals[:, 0], self.pitch_where_turning
        if not pitch["motions"]:
            return (f"median {np.median(angle):.3f} deg, worst {angle.max():.3f} deg (no motion turns "
                    f"{pitch['min_turn_deg']:.0f} deg or more: pitches not compared)")
        text = (f"median {np.median(angle):.3f} deg / {100 * pitch['median_share']:.2f}%, "
                f"worst {angle.max():.3f} deg / {100 * pitch['max_share']:.1f}%")
        if pitch["motions"] < len(angle):
            text += (f" (the pitch over the {pitch['motions']} of {len(angle)} motions that turn "
                     f"{pitch['min_turn_deg']:.0f} deg or more)")
        return text

    def pose_noise_text(self) -> str:
        """The pose refinement's noise estimates in words, per axis; one the data do not resolve (an
        estimate that reached zero) said so, not printed as a zero that looks like a fault."""
        nz = self.pose_noise or {}

        def amount(key: str, unit: str, digits: int) -> str:
            v = float(nz.get(key, 0.0))
            return f"{v:.{digits}f} {unit}" if v >= 0.5 * 10.0**-digits else "below what the data resolve"
        return (f"robot rotation {amount('robot_rotation_deg', 'deg', 4)}, camera rotation "
                f"{amount('camera_rotation_deg', 'deg', 4)}, translation {amount('translation_mm', 'mm', 3)}, camera depth "
                f"(along its optical axis) {amount('camera_depth_mm', 'mm', 3)}")

    @cached_property
    def pose_residuals(self) -> NDArray[np.float64]:
        """Per pose how far its own Z_i is from Z (deg, mm); none without camera poses."""
        if self.target2cam is None:
            return np.zeros((0, 2))
        Zi = constant_transforms(self.X, self.flange2base, self.target2cam, self.setup)
        return np.stack([np.degrees(rotation_error(Zi, self.Z)), 1e3 * translation_error(Zi, self.Z)], axis=1)

    def predict_error(self, point: ArrayLike) -> NDArray[np.float64]:
        """Standard deviation (m, per axis) of a point mapped through X, from ``cov``.

        ``point`` is in the camera frame (e.g. a point the camera sees); its image ``X @ point``
        in the flange (or base) frame has the covariance ``J cov J^T`` with
        ``J = [-[R p]x, I]``. Raises ValueError when no covariance was computed.
        """
        if self.cov is None:
            raise InputMismatchError("no covariance for this calibration (it comes with refinement: refine='pose' or 'reprojection')")
        p = np.asarray(point, dtype=float).reshape(3)
        Rp = self.X[:3, :3] @ p
        J = np.hstack([-skew(Rp), np.eye(3)])
        return np.sqrt(np.diag(J @ self.cov @ J.T))

    def _named(self, wanted: str) -> NDArray[np.float64]:
        info = setup_info(self.setup)
        if wanted == info.x_name:
            return self.X
        if wanted == info.z_name:
            return self.Z
        other = setup_info("eye_to_hand" if info.camera_on_flange else "eye_in_hand")
        kind = "X" if wanted == other.x_name else "Z"
        raise AttributeError(f"{wanted} is the {other.name} {kind}; this is {self.setup}: use "
                             f"{info.x_name if kind == 'X' else info.z_name}")

    @property
    def cam2flange(self) -> NDArray[np.float64]:
        """X for an eye-in-hand calibration."""
        return self._named("cam2flange")

    @property
    def cam2base(self) -> NDArray[np.float64]:
        """X for an eye-to-hand calibration."""
        return self._named("cam2base")

    @property
    def target2base(self) -> NDArray[np.float64]:
        """Z for an eye-in-hand calibration (where the target stands in the robot base frame)."""
        return self._named("target2base")

    @property
    def target2flange(self) -> NDArray[np.float64]:
        """Z for an eye-to-hand calibration (where the target sits on the flange)."""
        return self._named("target2flange")
