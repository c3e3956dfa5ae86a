"""Markerless hand-eye from colour images: the arm's meshes' silhouette against its masks, through the core.

A silhouette session (:mod:`handeye.pipelines.silhouette.session`: masks of the arm, its joint angles, the
camera matrix) is calibrated in named steps:

1. :func:`arm_views`: the arm's meshes (rtb-data's, :mod:`handeye.robot.meshes`) posed at every
   view's joint angles through the nominal table, and the masks' distance fields;
2. :func:`global_start`: the camera's pose without any guess
   (:func:`~handeye.sensors.silhouette.start.coarse_cam2base`: orientations over the sphere, the
   position from the masks' centroids and spreads, scored by IoU on downscaled masks), the best few
   each refined by a few outline rounds and the best kept by its IoU at full size;
3. :func:`outline_rounds`: rounds of the outline points found at the current X (the meshes'
   occluding contour on the rendered silhouette's outer boundary), each fitted to the masks'
   boundaries (robust least squares), until X moves less than 0.5 mm / 0.02 deg (the points found
   again move it by ~0.3 mm each round, a tenth of its std);
4. :class:`~handeye.sensors.silhouette.model.SilhouetteContours` with the last round's points and
   :func:`~handeye.estimation.core.estimate`: X, its std (the jackknife over views widens the noise
   model, whose neighbouring points are not independent), cross-validation, the verdict;
5. the masks' agreement: per view the IoU of the fitted silhouette with its mask, and on every view
   left out of the fit (X fitted to the others; :func:`heldout_ious`); and a check that each mask
   agrees best with its own view's joint angles (a shuffled pairing of masks and joint angles shows).

Residuals are millimetres at the arm (pixels times the point's depth over the focal length); the
result's figures give pixels too.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares, linear_sum_assignment

from ..._shared.threads import on_one_blas_thread
from ...errors import DegenerateMotionError
from ...estimation.core import estimate
from ...estimation.verdict import MISPAIRED, pairing_verdict
from ...frames.metrics import rotation_error, translation_error
from ...geometry.se3 import perturb
from ...options import CalibrationOptions
from ...result import Calibration
from ...robot.models import ControllerPoses
from ...sensors.silhouette.model import ArmViews, SilhouetteContours
from ...sensors.silhouette.start import coarse_cam2base, surface_samples
from .._arm import arm_table
from .._sensor import sensor_options, session_robot_input
from .session import SilhouetteSession, load_silhouette_session, read_masks

__all__ = ["arm_views", "global_start", "outline_rounds", "heldout_ious", "pairing_notes", "calibrate_silhouette_session",
           "ROUNDS", "CANDIDATES", "SAMPLES"]

#: The outline rounds at most.
ROUNDS = 8
#: The coarse search's best candidates refined before one is chosen.
CANDIDATES = 3
#: Points sampled over the arm's surface for the coarse search.
SAMPLES = 3000
#: A coarse candidate refined to this mean IoU is taken without trying the others.
GOOD_IOU = 0.75
#: The robust rounds' soft-L1 scale (pixels).
F_SCALE_PX = 2.0
#: A mask whose IoU with another view's joint angles beats its own by this much is named ...
PAIRING_MARGIN = 0.05
#: ... and when this share of the masks (and at least 2) are, the data are inconsistent
#: (:func:`~handeye.estimation.verdict.pairing_verdict` decides).
MISPAIRED_SHARE = MISPAIRED


def arm_views(s: SilhouetteSession, masks: NDArray[np.bool_]) -> ArmViews:
    """The session's arm posed at every view's joint angles, with the camera and the masks."""
    vertices = s.meshes.posed_vertices(s.meshes.link2base(s.arm, s.joints))
    _, faces, _ = s.meshes.merged()
    return ArmViews(vertices, faces, s.K, s.dist, masks)


def _round(views: ArmViews, X: NDArray[np.float64], spacing: float) -> tuple[NDArray[np.float64], SilhouetteContours]:
    """One round: the outline points at ``X``, fitted robustly; the new X and the round's model."""
    points, owner = views.outline_points(X, spacing=spacing)
    model = SilhouetteContours([str(k) for k in range(len(views.masks))], points, owner, views.K, views.dist, views.sdf, X)
    return _fitted(model, X, np.arange(len(owner)), "soft_l1"), model


def _fitted(model: SilhouetteContours, X: NDArray[np.float64], rows: NDArray[np.intp], loss: str = "linear"
            ) -> NDArray[np.float64]:
    """X fitted to ``model``'s ``rows`` from ``X`` (pixels; robust with ``loss='soft_l1'``)."""
    if len(rows) < 6:
        raise DegenerateMotionError(f"{len(rows)} outline points: the arm's silhouette is not on the masks (check the "
                                    "camera matrix and that the masks show the arm)")

    def fun(x):
        return model.residuals_px(perturb(X, x[:3], x[3:]), rows)

    def jac(x):
        return model.jacobian(perturb(X, x[:3], x[3:]), None, None, rows)[:, 0] / model.scale[rows, None]
    res = least_squares(fun, np.zeros(6), jac, method="trf" if loss != "linear" else "lm", loss=loss, f_scale=F_SCALE_PX,
                        x_scale=np.full(6, 1e-2))
    return perturb(X, res.x[:3], res.x[3:])


def outline_rounds(views: ArmViews, X: NDArray[np.float64], rounds: int = ROUNDS, spacing: float = 2.0,
                   tol: tuple[float, float] = (0.02, 0.5)) -> tuple[NDArray[np.float64], int]:
    """X refined by rounds of outline points (the module's step 3) from ``X``, one point per
    ``spacing`` pixels of outline, until a round moves it less than ``tol`` (deg, mm): X and the
    rounds run."""
    for k in range(rounds):
        new, _ = _round(views, X, spacing)
        moved = (float(np.degrees(rotation_error(new, X))), 1e3 * float(translation_error(new, X)))
        X = new
        if moved[0] < tol[0] and moved[1] < tol[1]:
            break
    return X, k + 1


def global_start(views: ArmViews, candidates: int = CANDIDATES, rng: int = 0) -> tuple[NDArray[np.float64], float]:
    """The camera's pose from the masks alone (the module's step 2): cam2base and its mean IoU. The
    coarse search's candidates are refined in turn (two rounds, a point every 4 pixels) until one
    reaches :data:`GOOD_IOU`; else the best."""
    vertices, faces = views.vertices, views.faces
    face, bary = surface_samples(vertices[0], faces, SAMPLES, rng)
    points = np.einsum("nskd,sk->nsd", vertices[:, faces[face]], bary)
    coarse, _ = coarse_cam2base(points, views.masks, views.K, keep=candidates)
    best, score = coarse[0], -1.0
    for X in coarse:
        for _ in range(2):
            X, _ = _round(views, X, spacing=4.0)
        iou = float(np.mean(views.ious(X)))
        if iou > score:
            best, score = X, iou
        if score >= GOOD_IOU:
            break
    return best, score


def heldout_ious(views: ArmViews, model: SilhouetteContours, X: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per view the IoU of its silhouette through X fitted without it (least squares on the other
    views' outline points from ``X``, their noise alike)."""
    out = np.zeros(len(views.masks))
    for v in range(len(views.masks)):
        rows = np.flatnonzero(model.owner != v)
        out[v] = views.ious(_fitted(model, X, rows), np.array([v]))[0]
    return out


def pairing_notes(views: ArmViews, X: NDArray[np.float64], names: list[str]) -> tuple[list[str], NDArray[np.float64]]:
    """Notes on masks that agree better with another view's joint angles than with their own (by
    more than :data:`PAIRING_MARGIN` of IoU), and the IoU matrix (mask, joint angles)."""
    drawn = views.render(X).reshape(len(names), -1).astype(np.float32)
    masks = views.masks.reshape(len(names), -1).astype(np.float32)
    inter = masks @ drawn.T
    union = masks.sum(axis=1)[:, None] + drawn.sum(axis=1)[None, :] - inter
    M = inter / np.maximum(union, 1.0)
    notes = []
    for v in range(len(names)):
        j = int(np.argmax(M[v]))
        if j != v and M[v, j] > M[v, v] + PAIRING_MARGIN:
            notes.append(f"the mask of {names[v]} agrees better with the joint angles of {names[j]} (IoU {M[v, j]:.2f}) than "
                         f"with its own ({M[v, v]:.2f})")
    if notes:
        notes = [f"{len(notes)} of {len(names)} masks agree better with another view's joint angles than with their own: "
                 "check that the masks and the joint angles are paired in the same order (and taken at the same time)"] + notes
        notes.append(_repairing(M, names))
    return notes, M


def _repairing(M: NDArray[np.float64], names: list[str]) -> str:
    """The one-to-one pairing of masks and joint angles that agrees best (the largest summed IoU of
    ``M``, mask by joint angles: the assignment problem), in words: which masks it moves and the mean
    IoU so paired against as given."""
    masks, angles = linear_sum_assignment(-M)
    moved = [(int(m), int(a)) for m, a in zip(masks, angles) if m != a]
    given, best = float(np.mean(np.diag(M))), float(np.mean(M[masks, angles]))
    pairs = ", ".join(f"{names[m]} with {names[a]}'s" for m, a in moved[:8]) + (f" and {len(moved) - 8} more" if len(moved) > 8 else "")
    return (f"the one-to-one pairing that fits best takes the mask of {pairs} joint angles: mean IoU {best:.2f} so paired, "
            f"{given:.2f} as given (X fitted to the given pairing; re-pair the files and calibrate again if that is how they "
            "were taken)")


@on_one_blas_thread  # narrow matrices throughout: a second BLAS thread spins more than it works
def calibrate_silhouette_session(folder: str | Path | SilhouetteSession, options: CalibrationOptions | None = None, *,
                                 progress: bool = False, jobs: int | None = None,
                                 **changes) -> Calibration:
    """Calibrate a fixed colour camera from the arm's silhouettes (the module's docstring).

    Parameters
    ----------
    folder : path or SilhouetteSession
    options : CalibrationOptions, optional
        ``robot_accuracy`` (the arm's stated accuracy, added to X's std), ``folds`` and ``arm`` are
        used; the options of image sessions are refused when changed.
    progress : bool
        Unused; accepted as every pipeline does.
    jobs : int, optional
        Unused; accepted as every pipeline does.

    Returns
    -------
    Calibration
        X = cam2base, its std, the verdict; ``sensor.figures`` holds the masks' IoU per view on the
        fit and held out (``iou``, ``iou_heldout``), the fit's RMS in pixels and the coarse start's IoU.

    Raises
    ------
    SessionError
        A bad session, mask or joints table, naming the file.
    DegenerateMotionError
        Fewer than 3 views, or no outline of the arm on the masks.

    Examples
    --------
    >>> import tempfile
    >>> from handeye.pipelines.silhouette.simulate import silhouette_scene, write_silhouette_session
    >>> folder = write_silhouette_session(tempfile.mkdtemp() + "/s", silhouette_scene(4, rng=3))
    >>> cal = calibrate_silhouette_session(folder)
    >>> cal.sensor.target, cal.sensor.figures["iou_mean"] > 0.9
    ('arm silhouette', True)
    """
    opts = sensor_options(options, changes, "a silhouette session")
    s = folder if isinstance(folder, SilhouetteSession) else load_silhouette_session(folder, arm=opts.arm)
    if len(s.names) < 3:
        raise DegenerateMotionError(f"{len(s.names)} views: at least 3 are needed, 10 or more with the arm in varied poses "
                                    "to trust X")
    views = arm_views(s, read_masks(s))
    X0, coarse_iou = global_start(views)
    X, n_rounds = outline_rounds(views, X0)
    points, owner = views.outline_points(X, spacing=1.0)
    model = SilhouetteContours(list(s.names), points, owner, s.K, s.dist, views.sdf, X)
    cal = estimate(model, ControllerPoses(s.flange2base, opts.robot_accuracy), opts.folds,
                   method="colour camera (the arm's silhouette) fit",
                   held=arm_table(model, lambda X: model.points, s.meshes, s.arm, s.joints, "colour camera"))
    iou = views.ious(cal.X)
    pairing, _ = pairing_notes(views, cal.X, list(s.names))  # the same rendering as the IoU's
    held = heldout_ious(views, model, cal.X)
    px = model.residuals_px(cal.X, np.arange(len(model.owner)))
    figures = dict(cal.sensor.figures, iou=iou.tolist(), iou_heldout=held.tolist(), iou_mean=float(iou.mean()),
                   iou_heldout_mean=float(held.mean()), fit_rms_px=float(np.sqrt(np.mean(px**2))),
                   fit_median_abs_px=float(np.median(np.abs(px))), start_iou=coarse_iou, rounds=n_rounds,
                   meshes=s.meshes.source)
    notes = [f"the masks' agreement (IoU): {iou.mean():.3f} on the fit, {held.mean():.3f} on views left out of it (X fitted "
             f"to the others); the outline points are {np.median(np.abs(px)):.2f} px (median) from the masks' boundaries"]
    cal = replace(cal, sensor=replace(cal.sensor, figures=figures), notes=list(s.notes) + notes + pairing + list(cal.notes),
                  input_folder=s.folder,
                   robot_input=session_robot_input(s, cal.flange2base))
    return _judged_pairing(cal, pairing, len(s.names))


def _judged_pairing(cal: Calibration, pairing: list[str], n: int) -> Calibration:
    """``cal`` with the verdict on its masks' pairing (``pairing``: the notes, one per mask that agrees
    better with another view's joint angles than with its own, of ``n``): inconsistent when enough
    are (:func:`~handeye.estimation.verdict.pairing_verdict`)."""
    mispaired = sum(note.startswith("the mask of ") for note in pairing)
    if cal.diagnostics is None:
        return cal
    advice = (f"{mispaired} of {n} masks agree better with another view's joint angles than with their own: the masks and "
              "the joint angles are not paired one to one (their order, or joint angles read at another time than the "
              "image); X from them is not to be used")
    return replace(cal, diagnostics=pairing_verdict(cal.diagnostics, mispaired, n, advice))