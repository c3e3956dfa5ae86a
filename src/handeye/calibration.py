"""``calibrate_poses``: from robot and camera poses to a :class:`Calibration`."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Iterable

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from .errors import DegenerateMotionError, InputMismatchError
from .geometry.se3 import invert, make_transform, skew
from .metrics import rotation_error, translation_error
from .motions import MotionSet, Pairs, check_setup, screw_congruence, validate_poses
from . import solvers

if TYPE_CHECKING:
    from .diagnostics import Diagnostics, RobotPoseInput

__all__ = ["Calibration", "calibrate", "calibrate_poses"]


@dataclass
class Calibration:
    """The result of a hand-eye calibration.

    Attributes
    ----------
    X : ndarray (4, 4)
        ``cam2flange`` (eye_in_hand) or ``cam2base`` (eye_to_hand), metres.
    Z : ndarray (4, 4)
        ``target2base`` (eye_in_hand) or ``target2flange`` (eye_to_hand): the mean over poses.
    setup, method : str
    flange2base, target2cam : ndarray (N, 4, 4)
        The (validated) inputs.
    pairs : ndarray (K, 2)
        The pose index pairs of the motions used.
    cov : ndarray (6, 6) or None
        Covariance of X over [rotation vector (rad), translation (m)]; None when not computed.
    std : ndarray (6,) or None
        Standard deviations of the same six, in degrees and millimetres.
    motion_residuals : ndarray (K, 2)
        Screw congruence per motion: ``|theta_A - theta_B|`` (deg), ``|d_A - d_B|`` (mm). Computed
        on first access.
    pose_residuals : ndarray (N, 2)
        Per pose, how far its own ``Z_i`` (through X) is from Z: rotation (deg), translation (mm).
    """

    X: NDArray[np.float64]
    Z: NDArray[np.float64]
    setup: str
    method: str
    flange2base: NDArray[np.float64] = field(repr=False)
    target2cam: NDArray[np.float64] = field(repr=False)
    pairs: NDArray[np.intp] = field(repr=False)
    cov: NDArray[np.float64] | None = None
    std: NDArray[np.float64] | None = None
    _motions: MotionSet | None = field(default=None, repr=False)
    # filled by calibrate() from images
    image_names: list[str] | None = None
    reprojection_rms: NDArray[np.float64] | None = None  #: per used image, px
    skipped: list[tuple[str, str]] = field(default_factory=list)  #: (image, reason)
    camera_matrix: NDArray[np.float64] | None = None
    dist_coeffs: NDArray[np.float64] | None = None
    intrinsics_source: str | None = None  #: "session.yaml" or "estimated"
    intrinsics_rms: float | None = None
    refinement: str = "none"  #: "none", "pose" or "reprojection"
    refined_rms: float | None = None  #: RMS reprojection error (px) of all points after refinement
    #: pose refinement's noise estimates: robot rotation (deg), camera rotation (deg), translation (mm)
    pose_noise: dict[str, float] | None = None
    diagnostics: "Diagnostics | None" = field(default=None, repr=False)  #: from handeye.diagnose (check=True)
    #: indices (into the poses given) of the poses used: outliers are left out
    pose_indices: NDArray[np.intp] | None = field(default=None, repr=False)
    notes: list[str] = field(default_factory=list)
    #: the robot poses as written (format and units), for results in the user's own convention
    robot_input: "RobotPoseInput | None" = field(default=None, repr=False)
    #: SHA-256 of the inputs: the session's files (calibrate) or the pose arrays (calibrate_poses)
    inputs_sha256: str | None = None
    #: per used image: its path, and the target points (target frame, m) with their detections (px)
    image_paths: list[Path] | None = field(default=None, repr=False)
    object_points: list[NDArray[np.float64]] | None = field(default=None, repr=False)
    image_points: list[NDArray[np.float64]] | None = field(default=None, repr=False)
    report_path: Path | None = None  #: report.html, once written (:meth:`write`)

    @cached_property
    def motion_residuals(self) -> NDArray[np.float64]:
        motions = self._motions
        if motions is None:
            motions = MotionSet.from_poses(self.flange2base, self.target2cam, self.setup, self.pairs)
        dtheta, dd = screw_congruence(motions)
        return np.stack([np.degrees(dtheta), 1e3 * dd], axis=1)

    @cached_property
    def pose_residuals(self) -> NDArray[np.float64]:
        Zi = constant_transforms(self.X, self.flange2base, self.target2cam, self.setup)
        return np.stack([np.degrees(rotation_error(Zi, self.Z)), 1e3 * translation_error(Zi, self.Z)], axis=1)

    def predict_error(self, point: ArrayLike) -> NDArray[np.float64]:
        """Standard deviation (m, per axis) of a point mapped through X, from ``cov``.

        ``point`` is in the camera frame (e.g. a point the camera sees); its image ``X @ point``
        in the flange (or base) frame has the covariance ``J cov J^T`` with
        ``J = [-[R p]x, I]``. Raises ValueError when no covariance was computed.
        """
        if self.cov is None:
            raise ValueError("no covariance for this calibration (it comes with refinement: refine='pose' or 'reprojection')")
        p = np.asarray(point, dtype=float).reshape(3)
        Rp = self.X[:3, :3] @ p
        J = np.hstack([-skew(Rp), np.eye(3)])
        return np.sqrt(np.diag(J @ self.cov @ J.T))

    def write(self, out_dir: str | Path, protect: "Iterable[str | Path]" = (), report: bool = True,
              parent_frame: str | None = None, child_frame: str | None = None) -> list[Path]:
        """Write ``result.json``, ``result.yaml`` and (``report``) ``report.html`` into ``out_dir``.

        Every file is written atomically. ``protect``: paths never to overwrite; the input images
        are always protected. ``parent_frame`` / ``child_frame`` name the frames of the ROS
        snippets (default ``tool0`` or ``base_link``, and ``camera_optical_frame``). Sets
        :attr:`report_path`; returns the paths written.
        """
        from .report import write_report
        from .results import write_results

        out_dir = Path(out_dir)
        protect = list(protect) + list(self.image_paths or [])
        paths = write_results(self, out_dir, protect, parent_frame, child_frame)
        if report:
            self.report_path = write_report(self, out_dir / "report.html", protect, parent_frame, child_frame)
            paths.append(self.report_path)
        return paths

    @property
    def cam2flange(self) -> NDArray[np.float64]:
        """X for an eye-in-hand calibration."""
        if self.setup != "eye_in_hand":
            raise AttributeError("cam2flange is the eye_in_hand result; this is eye_to_hand: use cam2base")
        return self.X

    @property
    def cam2base(self) -> NDArray[np.float64]:
        """X for an eye-to-hand calibration."""
        if self.setup != "eye_to_hand":
            raise AttributeError("cam2base is the eye_to_hand result; this is eye_in_hand: use cam2flange")
        return self.X

    @property
    def target2base(self) -> NDArray[np.float64]:
        """Z for an eye-in-hand calibration (where the target stands in the robot base frame)."""
        if self.setup != "eye_in_hand":
            raise AttributeError("target2base is the eye_in_hand Z; this is eye_to_hand: use target2flange")
        return self.Z

    @property
    def target2flange(self) -> NDArray[np.float64]:
        """Z for an eye-to-hand calibration (where the target sits on the flange)."""
        if self.setup != "eye_to_hand":
            raise AttributeError("target2flange is the eye_to_hand Z; this is eye_in_hand: use target2base")
        return self.Z


def constant_transforms(
    X: NDArray[np.float64], flange2base: NDArray[np.float64], target2cam: NDArray[np.float64], setup: str
) -> NDArray[np.float64]:
    """Per pose, the transform that must be constant given X: ``Z_i`` (DESIGN §2)."""
    if setup == "eye_in_hand":
        return flange2base @ X @ target2cam  # target2base
    return invert(flange2base) @ X @ target2cam  # target2flange


def robot_world_inputs(
    flange2base: NDArray[np.float64], target2cam: NDArray[np.float64], setup: str
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(A_i, B_i)`` of ``A_i X = Z B_i`` for a setup (DESIGN §2, robot-world form).

    Eye-in-hand: ``flange2base_i X = Z inv(target2cam_i)`` (X = cam2flange, Z = target2base).
    Eye-to-hand: ``inv(flange2base_i) X = Z inv(target2cam_i)`` (X = cam2base, Z = target2flange).
    """
    A = flange2base if setup == "eye_in_hand" else invert(flange2base)
    return A, invert(target2cam)


def mean_transform(T: NDArray[np.float64]) -> NDArray[np.float64]:
    """Chordal mean of rotations (scipy's ``Rotation.mean``) and arithmetic mean of translations."""
    R = Rotation.from_matrix(T[:, :3, :3]).mean().as_matrix()
    return make_transform(R, T[:, :3, 3].mean(axis=0))


def calibrate_poses(
    flange2base: ArrayLike,
    target2cam: ArrayLike,
    setup: str = "eye_in_hand",
    method: str = "daniilidis",
    refine: str = "auto",
    pairs: Pairs = "all",
    check: bool = True,
    robot_input: "RobotPoseInput | None" = None,
) -> Calibration:
    """Hand-eye calibration from robot poses and camera-to-target poses.

    Parameters
    ----------
    flange2base : array_like, shape (N, 4, 4)
        Flange poses reported by the robot (metres); see :func:`handeye.parse_poses`.
    target2cam : array_like, shape (N, 4, 4)
        Target poses in the camera frame (``solvePnP``'s rvec/tvec), metres.
    setup : {'eye_in_hand', 'eye_to_hand'}
    method : str
        A solver from ``handeye.solvers.available()``: an AX = XB solver (Z is then the mean of
        the per-pose Z_i), or a robot-world one (``shah``, ``li``), which estimates X and Z together.
    refine : {'auto', 'pose', 'none'}
        'pose' (and 'auto', the default, which is the same here): X and Z refined jointly from the
        ``method`` solution by :func:`handeye.solvers.refine.refine_pose` (Strobl-Hirzinger's
        optimal correction with noise variances estimated from the data), which also gives
        ``cov``, ``std`` and ``pose_noise``. 'none': the closed form as is (no uncertainty).
    pairs : {'all', 'consecutive'} or (K, 2) array
        Which pose pairs form the motions.
    check : bool
        Run :func:`handeye.diagnose` first (default): degenerate motions and inconsistent data
        (with the convention that fixes them, when one does) raise an error; outlier poses are
        left out, with a note; weak data get the advice as notes. ``check=False`` calibrates the
        poses as they are.
    robot_input : RobotPoseInput, optional
        The robot poses as written, so that the check can try other Euler sequences, quaternion
        orders and units (sessions pass it).

    Returns
    -------
    Calibration
        With ``diagnostics`` (when checked) and ``pose_indices``, the input poses used.

    Raises
    ------
    DegenerateMotionError
        The motions cannot determine X (advice in the message).
    InputMismatchError
        The poses do not agree on one X; the message names the likely mistake.
    """
    check_setup(setup)
    if refine not in ("auto", "pose", "none"):
        hint = " (pixel refinement needs the detections: use handeye.calibrate on a session)" if refine == "reprojection" else ""
        raise InputMismatchError(f"refine={refine!r}; use 'auto', 'pose' or 'none'{hint}")
    flange2base, target2cam = validate_poses(flange2base, target2cam)
    flange2base_in, target2cam_in = flange2base, target2cam
    n_input = len(flange2base)
    keep = np.arange(n_input)
    diag, notes = None, []
    if check:
        from .diagnostics import diagnose

        diag = diagnose(flange2base, target2cam, setup, robot_input=robot_input)
        if diag.verdict == "degenerate":
            raise DegenerateMotionError(" ".join(diag.advice))
        if diag.verdict == "inconsistent":
            raise InputMismatchError(f"{diag.advice[0]} (check=False calibrates the poses as given)")
        if diag.outliers:
            keep = np.setdiff1d(keep, diag.outliers)
            flange2base, target2cam = flange2base[keep], target2cam[keep]
            if not isinstance(pairs, str):  # explicit pairs: drop those with an outlier, renumber
                old_to_new = np.full(n_input, -1)
                old_to_new[keep] = np.arange(len(keep))
                p = old_to_new[np.asarray(pairs)]
                pairs = p[(p >= 0).all(axis=1)]
        notes.extend(diag.advice)
    motions = MotionSet.from_poses(flange2base, target2cam, setup, pairs)
    if solvers.get(method).kind == "robot_world":
        X, Z = solvers.solve_robot_world(*robot_world_inputs(flange2base, target2cam, setup), method=method)
    else:
        X = solvers.solve_motions(motions, method=method)
        Z = mean_transform(constant_transforms(X, flange2base, target2cam, setup))
    cal = Calibration(
        X=X,
        Z=Z,
        setup=setup,
        method=method,
        flange2base=flange2base,
        target2cam=target2cam,
        pairs=motions.pairs,
        _motions=motions,
        diagnostics=diag,
        pose_indices=keep,
        notes=notes,
        robot_input=robot_input,
        inputs_sha256=_array_digest(flange2base_in, target2cam_in),
    )
    if refine != "none":
        apply_pose_refinement(cal)
    return cal


def _array_digest(*arrays: NDArray[np.float64]) -> str:
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a, dtype="<f8").tobytes())
    return h.hexdigest()


def files_digest(paths: list[Path], root: Path) -> str:
    """SHA-256 over the names (relative to ``root``) and bytes of ``paths``, in the order given."""
    h = hashlib.sha256()
    for p in paths:
        h.update(str(Path(p).relative_to(root)).encode("utf-8") + b"\0")
        with open(p, "rb") as fh:
            for chunk in iter(lambda: fh.read(1 << 20), b""):
                h.update(chunk)
    return h.hexdigest()


def apply_pose_refinement(cal: Calibration) -> None:
    """Refine ``cal.X`` and ``cal.Z`` on its poses (``refine_pose``) and set the uncertainty fields."""
    from .solvers.refine import refine_pose

    ref = refine_pose(cal.X, cal.Z, cal.flange2base, cal.target2cam, cal.setup)
    cal.X, cal.Z = ref.X, ref.Z
    cal.__dict__.pop("pose_residuals", None)  # cached for the closed-form X
    set_covariance(cal, ref.cov_X)
    cal.refinement, cal.method = "pose", f"{cal.method}+pose"
    cal.pose_noise = {
        "robot_rotation_deg": float(np.degrees(ref.noise["robot_rotation"])),
        "camera_rotation_deg": float(np.degrees(ref.noise["camera_rotation"])),
        "translation_mm": 1e3 * ref.noise["translation"],
    }
    if not ref.converged:
        cal.notes.append(f"pose refinement: the noise estimates did not settle in {ref.rounds} rounds; "
                         "the reported uncertainty is approximate")


def set_covariance(cal: Calibration, cov_X: NDArray[np.float64]) -> None:
    cal.cov = cov_X
    cal.std = np.r_[np.degrees(np.sqrt(np.diag(cov_X)[:3])), 1e3 * np.sqrt(np.diag(cov_X)[3:])]


#: Fewest usable poses for a calibration (two motions, as the solvers need).
MIN_POSES = 3
#: Above this RMS (px) of the intrinsic calibration, the result is flagged.
INTRINSICS_RMS_WARN = 1.0
#: refine='auto' keeps the pixel refinement only if its RMS stays within this factor of the
#: per-image PnP RMS (median), or below REFINE_RMS_FLOOR px: otherwise robot errors dominate.
REFINE_RMS_FACTOR = 3.0
REFINE_RMS_FLOOR = 1.0


def calibrate(
    session_dir: str | Path,
    method: str = "daniilidis",
    refine: str = "auto",
    jobs: int | None = None,
    progress: bool = True,
    pairs: Pairs = "all",
    check: bool = True,
    robot_noise: tuple[float, float] | None = None,
) -> Calibration:
    """Hand-eye calibration from a capture session folder (images + robot poses, DESIGN §4).

    Detects the target in every image (in parallel), takes the intrinsics from session.yaml or
    estimates them from the same images, solves PnP per image, and calibrates.

    Parameters
    ----------
    session_dir : path
    method, pairs, check
        As :func:`calibrate_poses` (outlier poses' images are listed in ``skipped``).
    refine : {'auto', 'reprojection', 'pose', 'none'}
        'reprojection': X and Z (and the intrinsics, when estimated) refined jointly on the pixel
        errors of every target point (:func:`handeye.solvers.refine.refine_reprojection`), starting
        from ``method``, with the robot poses taken as exact. 'pose': refined on the robot and PnP
        poses (:func:`handeye.solvers.refine.refine_pose`), which allows for robot pose errors.
        'auto' (default): 'reprojection', unless its fit is much worse than the per-image PnP
        fits (robot pose errors dominate); then 'pose', with a note.
    robot_noise : (deg, mm), optional
        Standard deviation per axis of the robot's pose errors (its accuracy where the images were
        taken; the data sheet's repeatability is a lower bound). The reprojection refinement then
        gives every robot pose a small correction with that prior instead of taking the poses as
        exact, so robot errors no longer bias X and the uncertainty accounts for them.
    jobs : int, optional
        Detection processes (default: the available cores).
    progress : bool
        Progress bar on stderr.

    Returns
    -------
    Calibration
        With ``image_names`` (the images used), ``skipped`` (image, reason), per-image PnP
        ``reprojection_rms``, ``refined_rms`` (all points, after refinement), the intrinsics used
        (refined together with X and Z when they were estimated) and ``notes`` (warnings).

    Raises
    ------
    SessionError
        Bad session folder; an unreadable image; fewer than 3 images with the target found.
    """
    from .session import SessionError, load_session
    from .vision import calibrate_intrinsics, detect_images, resolve_symmetries, solve_pnp, target_from_spec

    if refine not in ("auto", "reprojection", "pose", "none"):
        raise InputMismatchError(f"refine={refine!r}; use 'auto', 'reprojection', 'pose' or 'none'")
    robot_sigma = None
    if robot_noise is not None:
        if refine not in ("auto", "reprojection"):
            raise InputMismatchError(f"robot_noise is used by the pixel refinement; refine={refine!r} would ignore it "
                                     "(use refine='auto' or 'reprojection', or leave robot_noise out)")
        try:
            deg, mm = (float(v) for v in robot_noise)
        except (TypeError, ValueError):
            raise InputMismatchError(f"robot_noise {robot_noise!r}: give (degrees, millimetres)") from None
        if not (deg > 0 and mm > 0 and np.isfinite(deg) and np.isfinite(mm)):
            raise InputMismatchError(f"robot_noise ({deg:g}, {mm:g}): give positive standard deviations (deg, mm)")
        robot_sigma = (np.radians(deg), 1e-3 * mm)
    session = load_session(session_dir)
    target = target_from_spec(session.target_spec)
    results = detect_images(session.image_paths, target, jobs=jobs, progress=progress)
    unreadable = [r.path.name for r in results if r.image_size is None]
    if unreadable:
        raise SessionError(f"{session.folder / 'images'}: cannot read image(s) {', '.join(unreadable)} (corrupt or not an image)")
    sizes = {r.image_size for r in results}
    if len(sizes) > 1:
        raise SessionError(f"{session.folder / 'images'}: images differ in size {sorted(sizes)}; one camera and resolution per session")
    image_size = sizes.pop()
    skipped = [(name, r.error) for name, r in zip(session.image_names, results) if r.detection is None]
    found = [k for k, r in enumerate(results) if r.detection is not None]
    notes: list[str] = []

    if len(found) < MIN_POSES:
        raise SessionError(
            f"the {target.type} target was found in only {len(found)} of {len(results)} images "
            f"(at least {MIN_POSES} are needed); check the target description in session.yaml"
        )
    if session.camera_matrix is not None:
        K, dist, source, k_rms = session.camera_matrix, session.dist_coeffs, "session.yaml", None
    else:
        K, dist, k_rms = calibrate_intrinsics([results[k].detection for k in found], image_size)
        source = "estimated"
        if k_rms > INTRINSICS_RMS_WARN:
            notes.append(f"intrinsics estimated from the images have an RMS reprojection error of {k_rms:.2f} px "
                         f"(> {INTRINSICS_RMS_WARN} px): calibrate the camera separately and put K and dist in session.yaml")
    used, poses, rms = [], [], []
    for k in found:
        sol = solve_pnp(results[k].detection, K, dist)
        if sol is None:
            skipped.append((session.image_names[k], "pose could not be estimated (fewer than 4 features)"))
            continue
        used.append(k)
        poses.append(sol[0])
        rms.append(sol[1])
    if len(used) < MIN_POSES:
        raise SessionError(f"only {len(used)} usable images (at least {MIN_POSES} are needed)")
    used_arr = np.array(used)
    flange2base = session.flange2base[used_arr]
    symmetries = target.symmetries()
    target2cam, choice = resolve_symmetries(np.array(poses), flange2base, session.setup, symmetries)
    points = {}  # per image: target points in the relabelled target frame (new = F^-1 old), detections
    for k, c in zip(used, choice):
        det, F_inv = results[k].detection, invert(symmetries[c])
        points[k] = (det.object_points @ F_inv[:3, :3].T + F_inv[:3, 3], det.image_points)
    robot_input = session.robot_input
    if robot_input is not None:
        robot_input = replace(robot_input, values=robot_input.values[used_arr])
    cal = calibrate_poses(flange2base, target2cam, setup=session.setup, method=method, pairs=pairs, refine="none",
                          check=check, robot_input=robot_input)
    pose_outliers = sorted(set(range(len(used))) - set(cal.pose_indices.tolist()))
    pixels_decide = False
    if refine in ("auto", "reprojection"):
        from .solvers.refine import refine_reprojection

        # all images, pose-level outliers included: a pose can be off because its PnP is weak (a
        # far or fronto-parallel view) while its pixels fit; the robust pixel fit judges them
        obj, img = [points[k][0] for k in used], [points[k][1] for k in used]
        ref = refine_reprojection(cal.X, cal.Z, flange2base, obj, img, K, dist, session.setup,
                                  refine_intrinsics=(source == "estimated"), robust=True, robot_noise=robot_sigma)
        # The refinement trusts the robot poses. If even the best X, Z leave the pixels far worse
        # fitted than a free pose per image does, robot errors dominate and pixel refinement would
        # trade them for a biased X: refine on the poses instead ('auto') and say so.
        limit = max(REFINE_RMS_FACTOR * float(np.median(rms)), REFINE_RMS_FLOOR)
        pixels_decide = refine == "reprojection" or ref.rms_px <= limit
        if ref.rms_px > limit:
            notes.append(
                f"the robot poses and the images disagree: with the robot poses taken as exact the best fit "
                f"leaves {ref.rms_px:.2f} px RMS, while each image alone fits to {np.median(rms):.2f} px; the robot "
                f"pose errors dominate" + ("; refined on the poses instead of the pixels" if refine == "auto" else "")
            )
        if pixels_decide:
            if pose_outliers:  # back in: the pixel fit weighs them point by point
                cal.notes = [n for n in cal.notes if "left out" not in n]
                notes.append(f"image(s) {', '.join(session.image_names[used[k]] for k in pose_outliers)} looked like "
                             f"outliers by their PnP poses but are kept: the robust pixel refinement judges their points")
                motions = MotionSet.from_poses(flange2base, target2cam, session.setup, pairs)
                cal.flange2base, cal.target2cam, cal.pairs, cal._motions = flange2base, target2cam, motions.pairs, motions
                cal.pose_indices = np.arange(len(used))
                cal.__dict__.pop("motion_residuals", None)
            cal.X, cal.Z = ref.X, ref.Z
            K, dist = ref.K, ref.dist
            cal.__dict__.pop("pose_residuals", None)  # cached for the closed-form X
            cal.refinement, cal.refined_rms = "reprojection", ref.rms_px
            if ref.n_rejected:
                notes.append(f"reprojection refinement set aside {ref.n_rejected} of {ref.n_points + ref.n_rejected} "
                             f"detected points as outliers (beyond 5 sigma)")
            if ref.cov_X is not None:
                set_covariance(cal, ref.cov_X)
            cal.method = f"{method}+reprojection" + (
                f" (robot poses corrected, prior {robot_noise[0]:g} deg / {robot_noise[1]:g} mm)" if robot_noise else "")
            if source == "estimated":
                source = "estimated, refined with the robot poses"
    if not pixels_decide:
        if pose_outliers:  # the poses decide: outlier poses stay out, their images are listed as skipped
            diag = cal.diagnostics
            for k in pose_outliers:
                r, t = diag.outlier_residuals[k]
                skipped.append((session.image_names[used[k]], f"outlier: its robot pose and target pose disagree "
                                f"with the others by {r:.2f} deg / {t:.1f} mm"))
            used = [used[k] for k in cal.pose_indices]
            rms = [rms[k] for k in cal.pose_indices]
        if refine in ("auto", "pose"):
            apply_pose_refinement(cal)
    cal.image_names = [session.image_names[k] for k in used]
    cal.reprojection_rms = np.array(rms)
    cal.skipped = sorted(skipped, key=lambda item: session.image_names.index(item[0]))
    cal.camera_matrix, cal.dist_coeffs = np.asarray(K, dtype=float), np.asarray(dist, dtype=float).ravel()
    cal.intrinsics_source, cal.intrinsics_rms = source, k_rms
    cal.image_paths = [session.image_paths[k] for k in used]
    cal.object_points, cal.image_points = [points[k][0] for k in used], [points[k][1] for k in used]
    cal.inputs_sha256 = files_digest(session.input_files, session.folder)
    cal.notes.extend(notes)
    return cal
