"""The pipelines: robot and camera poses (``calibrate_poses``), or a capture session of images and
robot poses (``calibrate``), to a :class:`~handeye.result.Calibration`.

``calibrate`` runs named steps, each returning a new result (``dataclasses.replace``), never
editing one: :func:`observe` (detection, intrinsics, PnP, symmetric targets), the closed form and
check of :func:`calibrate_poses`, then :func:`refine_on_pixels` or :func:`refine_on_poses`, and
last the image fields.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._shared.io import array_digest, files_digest
from .diagnostics import closed_form, diagnose
from .errors import DegenerateMotionError, InputMismatchError
from .geometry.se3 import invert
from .motions import MotionSet, Pairs, validate_poses
from .poses import RobotPoseInput
from .result import Calibration, Diagnostics
from .session import POSEPAIRS_FILE, Session, SessionError, load_pose_pairs, load_session
from .setups import check_setup
from .solvers.refine import ReprojectionResult, refine_pose, refine_reprojection
from .vision import calibrate_intrinsics, detect_images, resolve_symmetries, solve_pnp, target_from_spec

__all__ = ["Calibration", "FolderCheck", "Observations", "calibrate", "calibrate_poses", "check_folder", "observe",
           "pixel_fit", "refine_on_pixels", "refine_on_poses"]

#: Fewest usable poses for a calibration (two motions, as the solvers need).
MIN_POSES = 3
#: Above this RMS (px) of the intrinsic calibration, the result is flagged.
INTRINSICS_RMS_WARN = 1.0
#: refine='auto' keeps the pixel refinement only if its RMS stays within this factor of the
#: per-image PnP RMS (median), or below REFINE_RMS_FLOOR px: otherwise robot errors dominate.
REFINE_RMS_FACTOR = 3.0
REFINE_RMS_FLOOR = 1.0


def _checked_poses(flange2base, target2cam, setup, pairs, check, robot_input):
    """The poses to calibrate on after :func:`handeye.diagnose` (outliers left out, explicit pairs
    renumbered): ``(flange2base, target2cam, pairs, keep, diagnostics, notes)``."""
    keep = np.arange(len(flange2base))
    if not check:
        return flange2base, target2cam, pairs, keep, None, []
    diag = diagnose(flange2base, target2cam, setup, robot_input=robot_input)
    if diag.verdict == "degenerate":
        raise DegenerateMotionError(" ".join(diag.advice))
    if diag.verdict == "inconsistent":
        raise InputMismatchError(f"{diag.advice[0]} (check=False calibrates the poses as given)")
    if diag.outliers:
        n_input = len(flange2base)
        keep = np.setdiff1d(keep, diag.outliers)
        flange2base, target2cam = flange2base[keep], target2cam[keep]
        if not isinstance(pairs, str):  # explicit pairs: drop those with an outlier, renumber
            old_to_new = np.full(n_input, -1)
            old_to_new[keep] = np.arange(len(keep))
            p = old_to_new[np.asarray(pairs)]
            pairs = p[(p >= 0).all(axis=1)]
    return flange2base, target2cam, pairs, keep, diag, list(diag.advice)


def calibrate_poses(
    flange2base: ArrayLike,
    target2cam: ArrayLike,
    setup: str = "eye_in_hand",
    method: str = "daniilidis",
    refine: str = "auto",
    pairs: Pairs = "all",
    check: bool = True,
    robot_input: RobotPoseInput | None = None,
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
    flange2base_in, target2cam_in = validate_poses(flange2base, target2cam)
    flange2base, target2cam, pairs, keep, diag, notes = _checked_poses(
        flange2base_in, target2cam_in, setup, pairs, check, robot_input)
    X, Z, motions = closed_form(flange2base, target2cam, setup, method, pairs)
    cal = Calibration(
        X=X, Z=Z, setup=setup, method=method, flange2base=flange2base, target2cam=target2cam, pairs=motions.pairs,
        motions=motions, diagnostics=diag, pose_indices=keep, notes=notes, robot_input=robot_input,
        inputs_sha256=array_digest(flange2base_in, target2cam_in),
    )
    return refine_on_poses(cal) if refine != "none" else cal


def _std(cov_X: NDArray[np.float64]) -> NDArray[np.float64]:
    """Standard deviations of X's six parameters in degrees and millimetres."""
    return np.r_[np.degrees(np.sqrt(np.diag(cov_X)[:3])), 1e3 * np.sqrt(np.diag(cov_X)[3:])]


def refine_on_poses(cal: Calibration) -> Calibration:
    """``cal`` with X and Z refined on its poses (:func:`~handeye.solvers.refine.refine_pose`) and the
    uncertainty fields set."""
    ref = refine_pose(cal.X, cal.Z, cal.flange2base, cal.target2cam, cal.setup)
    notes = list(cal.notes)
    if not ref.converged:
        notes.append(f"pose refinement: the noise estimates did not settle in {ref.rounds} rounds; "
                     "the reported uncertainty is approximate")
    return replace(
        cal, X=ref.X, Z=ref.Z, cov=ref.cov_X, std=_std(ref.cov_X), refinement="pose", method=f"{cal.method}+pose",
        notes=notes, pose_noise={
            "robot_rotation_deg": float(np.degrees(ref.noise["robot_rotation"])),
            "camera_rotation_deg": float(np.degrees(ref.noise["camera_rotation"])),
            "translation_mm": 1e3 * ref.noise["translation"],
        },
    )


@dataclass(frozen=True)
class Observations:
    """What the images of a session say, before any hand-eye solve (:func:`observe`).

    ``used`` indexes the session's images that gave a target pose; the per-image fields follow it.
    """

    session: Session
    used: list[int]
    flange2base: NDArray[np.float64]  #: robot poses of the used images
    target2cam: NDArray[np.float64]  #: PnP poses, symmetric targets relabelled to agree with the robot
    pnp_rms: list[float]  #: PnP reprojection RMS per used image (px)
    object_points: list[NDArray[np.float64]]  #: per used image, in the (relabelled) target frame (m)
    image_points: list[NDArray[np.float64]]  #: per used image, detections (px)
    K: NDArray[np.float64]
    dist: NDArray[np.float64]
    intrinsics_source: str  #: "session.yaml" or "estimated"
    intrinsics_rms: float | None
    skipped: list[tuple[str, str]]  #: (image, reason)
    notes: list[str]
    robot_input: RobotPoseInput | None  #: the robot poses of the used images as written


def _detect(session: Session, jobs: int | None, progress: bool):
    """Detections per image, the image size and the images skipped (target not found)."""
    target = target_from_spec(session.target_spec)
    results = detect_images(session.image_paths, target, jobs=jobs, progress=progress)
    unreadable = [r.path.name for r in results if r.image_size is None]
    if unreadable:
        raise SessionError(f"{session.folder / 'images'}: cannot read image(s) {', '.join(unreadable)} (corrupt or not an image)")
    sizes = {r.image_size for r in results}
    if len(sizes) > 1:
        raise SessionError(f"{session.folder / 'images'}: images differ in size {sorted(sizes)}; one camera and resolution per session")
    skipped = [(name, r.error) for name, r in zip(session.image_names, results) if r.detection is None]
    found = [k for k, r in enumerate(results) if r.detection is not None]
    if len(found) < MIN_POSES:
        raise SessionError(
            f"the {target.type} target was found in only {len(found)} of {len(results)} images "
            f"(at least {MIN_POSES} are needed); check the target description in session.yaml"
        )
    return target, {k: results[k].detection for k in found}, sizes.pop(), skipped


def observe(session: Session, jobs: int | None = None, progress: bool = True) -> Observations:
    """Detect the target in every image of ``session`` (in parallel), take the intrinsics from
    session.yaml or estimate them from the same images, solve PnP per image and relabel symmetric
    targets so that every camera motion agrees with its robot motion.

    Raises
    ------
    SessionError
        An unreadable image; images of different sizes; fewer than 3 images with the target found.
    """
    target, detections, image_size, skipped = _detect(session, jobs, progress)
    notes: list[str] = []
    if session.camera_matrix is not None:
        K, dist, source, k_rms = session.camera_matrix, session.dist_coeffs, "session.yaml", None
    else:
        K, dist, k_rms = calibrate_intrinsics(list(detections.values()), image_size)
        source = "estimated"
        if k_rms > INTRINSICS_RMS_WARN:
            notes.append(f"intrinsics estimated from the images have an RMS reprojection error of {k_rms:.2f} px "
                         f"(> {INTRINSICS_RMS_WARN} px): calibrate the camera separately and put K and dist in session.yaml")
    used, poses, rms = [], [], []
    for k, det in detections.items():
        sol = solve_pnp(det, K, dist)
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
    obj, img = [], []  # per image: target points in the relabelled target frame (new = F^-1 old), detections
    for k, c in zip(used, choice):
        det, F_inv = detections[k], invert(symmetries[c])
        obj.append(det.object_points @ F_inv[:3, :3].T + F_inv[:3, 3])
        img.append(det.image_points)
    robot_input = session.robot_input
    if robot_input is not None:
        robot_input = replace(robot_input, values=robot_input.values[used_arr])
    return Observations(session, used, flange2base, target2cam, rms, obj, img, K, dist, source, k_rms, skipped,
                        notes, robot_input)


def _robot_sigma(robot_noise, refine: str) -> tuple[float, float] | None:
    """``robot_noise`` (deg, mm) checked and converted to (rad, m)."""
    if robot_noise is None:
        return None
    if refine not in ("auto", "reprojection"):
        raise InputMismatchError(f"robot_noise is used by the pixel refinement; refine={refine!r} would ignore it "
                                 "(use refine='auto' or 'reprojection', or leave robot_noise out)")
    try:
        deg, mm = (float(v) for v in robot_noise)
    except (TypeError, ValueError):
        raise InputMismatchError(f"robot_noise {robot_noise!r}: give (degrees, millimetres)") from None
    if not (deg > 0 and mm > 0 and np.isfinite(deg) and np.isfinite(mm)):
        raise InputMismatchError(f"robot_noise ({deg:g}, {mm:g}): give positive standard deviations (deg, mm)")
    return np.radians(deg), 1e-3 * mm


def pixel_fit(cal: Calibration, obs: Observations, robot_sigma: tuple[float, float] | None = None) -> ReprojectionResult:
    """The robust reprojection refinement of ``cal``'s X and Z on every used image (pose-level
    outliers included: a pose can be off because its PnP is weak, a far or fronto-parallel view,
    while its pixels fit; the robust pixel fit judges them)."""
    return refine_reprojection(cal.X, cal.Z, obs.flange2base, obs.object_points, obs.image_points, obs.K, obs.dist,
                               cal.setup, refine_intrinsics=(obs.intrinsics_source == "estimated"), robust=True,
                               robot_noise=robot_sigma)


def refine_on_pixels(cal: Calibration, obs: Observations, ref: ReprojectionResult,
                     robot_noise: tuple[float, float] | None = None, pairs: Pairs = "all") -> Calibration:
    """``cal`` with the pixel refinement ``ref`` (:func:`pixel_fit`) applied: X, Z, the intrinsics
    and the uncertainty from it, and every used image back in (the pixel fit weighed their points)."""
    notes = list(cal.notes)
    n_used = len(obs.used)
    pose_outliers = sorted(set(range(n_used)) - set(cal.pose_indices.tolist()))
    fields: dict = {}
    extra: list[str] = []
    if pose_outliers:  # back in: the pixel fit weighs them point by point
        notes = [n for n in notes if "left out" not in n]
        extra.append(f"image(s) {', '.join(obs.session.image_names[obs.used[k]] for k in pose_outliers)} looked like "
                     f"outliers by their PnP poses but are kept: the robust pixel refinement judges their points")
        motions = MotionSet.from_poses(obs.flange2base, obs.target2cam, cal.setup, pairs)
        fields = dict(flange2base=obs.flange2base, target2cam=obs.target2cam, pairs=motions.pairs, motions=motions,
                      pose_indices=np.arange(n_used))
    if ref.n_rejected:
        extra.append(f"reprojection refinement set aside {ref.n_rejected} of {ref.n_points + ref.n_rejected} "
                     f"detected points as outliers (beyond 5 sigma)")
    if ref.cov_X is not None:
        fields.update(cov=ref.cov_X, std=_std(ref.cov_X))
    method = cal.method + "+reprojection" + (
        f" (robot poses corrected, prior {robot_noise[0]:g} deg / {robot_noise[1]:g} mm)" if robot_noise else "")
    source = obs.intrinsics_source
    if source == "estimated":
        source = "estimated, refined with the robot poses"
    return replace(cal, X=ref.X, Z=ref.Z, refinement="reprojection", refined_rms=ref.rms_px, method=method,
                   notes=notes + extra, camera_matrix=np.asarray(ref.K, dtype=float),
                   dist_coeffs=np.asarray(ref.dist, dtype=float).ravel(), intrinsics_source=source, **fields)


def _drop_pose_outliers(cal: Calibration, obs: Observations) -> tuple[list[int], list[tuple[str, str]]]:
    """When the poses decide: the used images without the outlier poses, and the outliers' images
    as skipped (with why)."""
    skipped = []
    for k in sorted(set(range(len(obs.used))) - set(cal.pose_indices.tolist())):
        r, t = cal.diagnostics.outlier_residuals[k]
        skipped.append((obs.session.image_names[obs.used[k]], f"outlier: its robot pose and target pose disagree "
                        f"with the others by {r:.2f} deg / {t:.1f} mm"))
    return [int(k) for k in cal.pose_indices], skipped


def _with_images(cal: Calibration, obs: Observations, kept: list[int], skipped: list[tuple[str, str]],
                 notes: list[str]) -> Calibration:
    """``cal`` with the fields of the images it used (``kept`` indexes ``obs.used``)."""
    names = obs.session.image_names
    skipped = sorted(obs.skipped + skipped, key=lambda item: names.index(item[0]))
    intrinsics = {}
    if cal.camera_matrix is None:  # not refined with X and Z: as observed
        intrinsics = dict(camera_matrix=np.asarray(obs.K, dtype=float), dist_coeffs=np.asarray(obs.dist, dtype=float).ravel(),
                          intrinsics_source=obs.intrinsics_source)
    return replace(
        cal, image_names=[names[obs.used[k]] for k in kept], reprojection_rms=np.array([obs.pnp_rms[k] for k in kept]),
        skipped=skipped, intrinsics_rms=obs.intrinsics_rms,
        image_paths=[obs.session.image_paths[obs.used[k]] for k in kept],
        object_points=[obs.object_points[k] for k in kept], image_points=[obs.image_points[k] for k in kept],
        inputs_sha256=files_digest(obs.session.input_files, obs.session.folder), notes=list(cal.notes) + notes,
        **intrinsics,
    )


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
        Detection workers (default: the available cores).
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
    if refine not in ("auto", "reprojection", "pose", "none"):
        raise InputMismatchError(f"refine={refine!r}; use 'auto', 'reprojection', 'pose' or 'none'")
    robot_sigma = _robot_sigma(robot_noise, refine)
    obs = observe(load_session(session_dir), jobs=jobs, progress=progress)
    notes = list(obs.notes)
    cal = calibrate_poses(obs.flange2base, obs.target2cam, setup=obs.session.setup, method=method, pairs=pairs,
                          refine="none", check=check, robot_input=obs.robot_input)
    if refine in ("auto", "reprojection"):
        ref = pixel_fit(cal, obs, robot_sigma)
        # The refinement trusts the robot poses. If even the best X, Z leave the pixels far worse
        # fitted than a free pose per image does, robot errors dominate and pixel refinement would
        # trade them for a biased X: refine on the poses instead ('auto') and say so.
        pnp_median = float(np.median(obs.pnp_rms))
        limit = max(REFINE_RMS_FACTOR * pnp_median, REFINE_RMS_FLOOR)
        if ref.rms_px > limit:
            notes.append(
                f"the robot poses and the images disagree: with the robot poses taken as exact the best fit "
                f"leaves {ref.rms_px:.2f} px RMS, while each image alone fits to {pnp_median:.2f} px; the robot "
                f"pose errors dominate" + ("; refined on the poses instead of the pixels" if refine == "auto" else "")
            )
        if refine == "reprojection" or ref.rms_px <= limit:
            # the session's notes before those of the pixel fit, as the steps ran
            cal = refine_on_pixels(replace(cal, notes=cal.notes + notes), obs, ref, robot_noise, pairs)
            return _with_images(cal, obs, list(range(len(obs.used))), [], [])
    kept, outlier_images = _drop_pose_outliers(cal, obs)
    if refine in ("auto", "pose"):
        cal = refine_on_poses(cal)
    return _with_images(cal, obs, kept, outlier_images, notes)


@dataclass(frozen=True)
class FolderCheck:
    """What :func:`check_folder` found: the diagnostics, the name of each pose checked, and the
    images that gave no pose (image, reason)."""

    diagnostics: Diagnostics
    names: list[str]
    skipped: list[tuple[str, str]]


def check_folder(folder: str | Path, jobs: int | None = None, progress: bool = True) -> FolderCheck:
    """:func:`handeye.diagnose` on a capture session (detection and PnP as :func:`calibrate` does them)
    or on a pose-pair folder (``posepairs.yaml``)."""
    folder = Path(folder)
    if (folder / POSEPAIRS_FILE).is_file():
        pairs = load_pose_pairs(folder)
        diag = diagnose(pairs.flange2base, pairs.target2cam, pairs.setup, robot_input=pairs.robot_input)
        return FolderCheck(diag, list(pairs.ids), [])
    obs = observe(load_session(folder), jobs=jobs, progress=progress)
    names = obs.session.image_names
    diag = diagnose(obs.flange2base, obs.target2cam, obs.session.setup, robot_input=obs.robot_input)
    return FolderCheck(diag, [names[k] for k in obs.used], sorted(obs.skipped, key=lambda item: names.index(item[0])))
