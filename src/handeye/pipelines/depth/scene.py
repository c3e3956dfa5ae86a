"""Whatever a depth camera sees as the target: X from its clouds' agreement through the robot, through the core.

A depth session whose target is ``{type: scene}`` (no board, no mesh: any rigid object the camera
sees from every view, fixed in the cell eye-in-hand or on the flange eye-to-hand) is calibrated in
named steps:

1. :func:`read_scene_views`: every cloud read and prepared (normals, query and reference points:
   :func:`~handeye.sensors.depth.scene.prepare_view`); a cloud with too few points is skipped, named;
2. :func:`~handeye.sensors.depth.scene_start.scene_start`: X with no guess (the clouds' centroids'
   closed form and a search over X's rotation, each pulled in by a coarse registration);
3. :func:`register_scene`: robust point-to-plane ICP of all views at once with X, from a tenth of
   the scene's size down to a few times the pairs' spread;
4. :func:`check_views`: a view whose points do not lie on the others' surfaces (a cloud of another
   scene, an object that moved, a cloud that moved with the camera) is named and left out, and the
   rest registered again;
5. :class:`~handeye.sensors.depth.scene.SceneSurface` with the last pairs, and
   :func:`~handeye.estimation.core.estimate`: X, what the capture leaves undetermined,
   cross-validation (each view's points against the others' surfaces, X fitted without it), the
   jackknife, the std and the verdict.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from ...errors import DegenerateMotionError, InputMismatchError
from ...estimation.core import estimate
from ...frames.metrics import rotation_error, translation_error
from ...frames.setups import robot_world_A, setup_info
from ...options import CalibrationOptions
from ...result import Calibration
from ...sensors.depth.scene import Pairs, SceneSurface, SceneView, pair_spread, prepare_view, register, scene_free, view_overlap
from ...sensors.depth.scene_start import StartCandidate, agreement, centroid_start, scene_start
from .._sensor import held_and_freed, measure_views, robot_model
from .mesh import read_scene
from .session import DepthSession

__all__ = ["SceneViews", "read_scene_views", "register_scene", "check_views", "calibrate_scene_session", "Registered",
           "AGREE_SHARE", "SAME_CLOUD"]

#: A view whose share of points on the other views' surfaces is below this share of the median
#: view's is one the others do not explain (another scene, an object that moved).
AGREE_SHARE = 0.5
#: A view whose cloud, in the camera's own frame, has this share of its points on another view's
#: cloud (taken in the camera frame too) though the robot moved between them moved with the camera.
SAME_CLOUD = 0.8


@dataclass
class SceneViews:
    """A scene session's clouds, prepared: per usable view its index into the session and its
    prepared cloud; the views skipped with why; notes."""

    index: list[int] = field(default_factory=list)
    views: list[SceneView] = field(default_factory=list)
    skipped: list[tuple[str, str]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def read_scene_views(s: DepthSession, progress: bool = False, jobs: int | None = None) -> SceneViews:
    """Every cloud of ``s`` read and prepared (``jobs`` at a time, threads; default 2); a cloud with
    too few usable points skipped with why."""
    def prepared(k: int) -> SceneView:
        return prepare_view(read_scene(s.cloud_paths[k], s.unit), s.names[k], rng=k)

    index, views, skipped = measure_views(prepared, s.names, (InputMismatchError,), "reading clouds", progress, jobs)
    return SceneViews(index=index, views=views, skipped=skipped)


@dataclass(frozen=True)
class Registered:
    """The views registered with X: X, the depth's scale and bias (None: held), the last pairs, the
    threshold they were found within (m), the start's candidates and the one chosen."""

    X: NDArray[np.float64]
    depth: NDArray[np.float64] | None
    pairs: Pairs
    tau: float
    candidates: list[StartCandidate]
    start: StartCandidate | None = None


def register_scene(views: list[SceneView], A: NDArray[np.float64], *, fit_depth: bool = False,
                   X0: NDArray[np.float64] | None = None) -> Registered:
    """X (and the depth's scale and bias with ``fit_depth``) registering ``views`` (robot-world poses
    ``A``): from :func:`~handeye.sensors.depth.scene_start.scene_start`'s X (or ``X0``), ICP from a
    tenth of the scene's size down to a fiftieth, then at 5 times the pairs' robust spread (at least
    3 points' spacing) until it settles: the pairs the fit takes."""
    size = float(np.median([2.0 * v.radius for v in views]))
    candidates: list[StartCandidate] = []
    start = None
    if X0 is None:
        start, candidates = scene_start(views, A)
        X0 = start.X
    depth0 = np.zeros(2) if fit_depth else None
    X, depth, pairs = register(views, A, X0, np.geomspace(0.1 * size, 0.02 * size, 4), depth=depth0, full_last=False)
    spacing = float(np.median([v.spacing for v in views]))
    tau = max(5.0 * pair_spread(views, A, X, pairs, depth), 3.0 * spacing)
    X, depth, pairs = register(views, A, X, np.array([tau]), depth=depth, steps=8, rounds=8, settle=1e-3)
    return Registered(X, depth, pairs, tau, candidates, start)


def _same_as(views: list[SceneView], k: int, A: NDArray[np.float64], voxel: float) -> tuple[int, float, float] | None:
    """The view whose cloud, in the camera's frame, holds :data:`SAME_CLOUD` of view ``k``'s points
    (voxels of ``voxel``) though the robot moved between them, with how far it moved (deg, mm);
    None when there is none."""
    I = np.broadcast_to(np.eye(4), (len(views), 4, 4))
    for j in range(len(views)):
        if j == k:
            continue
        pair = [views[k], views[j]]
        share = agreement(pair, I[:2], np.eye(4)[None], voxel)[0]
        angle, shift = float(np.degrees(rotation_error(A[k], A[j]))), 1e3 * float(translation_error(A[k], A[j]))
        if share > SAME_CLOUD and angle + shift > 1.0:
            return j, angle, shift
    return None


def check_views(views: list[SceneView], A: NDArray[np.float64], reg: Registered, setup: str
                ) -> list[tuple[int, str]]:
    """The views (indices) whose query points do not lie on the other views' surfaces where their
    robot pose and X put them (their share of points matched below :data:`AGREE_SHARE` of the
    median view's), each with why: the same cloud as another view's in the camera's frame though the
    robot moved (it moved with the camera: eye-in-hand the object moved with it, eye-to-hand the
    object did not move with the flange), else a cloud of another scene or a moved object."""
    n = len(views)
    if n < 4:
        return []
    share = view_overlap(views, reg.pairs)
    median = float(np.median(share))
    size = float(np.median([2.0 * v.radius for v in views]))
    out = []
    for k in np.flatnonzero(share < AGREE_SHARE * median):
        same = _same_as(views, int(k), A, 0.02 * size)
        if same is not None:
            j, angle, shift = same
            what = ("the object moved with the camera" if setup_info(setup).camera_on_flange else
                    "the object did not move with the flange")
            why = (f"its cloud is {views[j].name}'s in the camera's frame, though the flange moved {shift:.0f} mm and turned "
                   f"{angle:.0f} deg between them: {what} (or one capture was saved twice)")
        else:
            why = (f"{100 * share[k]:.0f}% of its points lie on the other views' surfaces where its robot pose puts them "
                   f"(the median view: {100 * median:.0f}%): a cloud of another scene, an object that moved, or a robot "
                   "pose that is not this cloud's")
        out.append((int(k), why))
    return out if len(out) <= n // 3 else []


def calibrate_scene_session(s: DepthSession, options: CalibrationOptions, *, fit_depth: bool | None = None,
                            progress: bool = False, jobs: int | None = None) -> Calibration:
    """A depth session whose target is the scene itself (the module's docstring): X from the views'
    clouds agreeing through the robot, no target and no guess.

    ``fit_depth``: fit the depth's scale and bias with X (default: the session's ``depth_scale:``,
    held at 1 and 0 unless it says ``fit``).

    Raises
    ------
    DegenerateMotionError
        Fewer than 3 usable views, or views that cannot determine X.

    Examples
    --------
    >>> import tempfile
    >>> from handeye.pipelines.depth.session import load_depth_session
    >>> from handeye.options import CalibrationOptions
    >>> from handeye.pipelines.depth.simulate_scene import scene_capture, write_scene_session
    >>> folder = write_scene_session(tempfile.mkdtemp() + "/s", scene_capture(8, "eye_to_hand", rng=4, image_size=(320, 240)))
    >>> cal = calibrate_scene_session(load_depth_session(folder), CalibrationOptions())
    >>> cal.sensor.target, cal.verdict in ("good", "weak")
    ('scene', True)
    """
    if s.scene is None:
        raise InputMismatchError(f"{s.folder}: the session's target is not a scene")
    fit_depth = s.scene.fit_depth if fit_depth is None else fit_depth
    v = read_scene_views(s, progress, jobs)
    skipped, notes = list(v.skipped), list(v.notes)
    index, views = list(v.index), list(v.views)
    if len(views) < 3:
        raise DegenerateMotionError(
            f"{len(views)} of {len(s.names)} clouds are usable ({'; '.join(f'{n}: {r}' for n, r in skipped[:5])}): at least "
            "3 are needed, 8-15 with the flange turned 30 deg or more about varied axes to trust X")
    A = robot_world_A(s.flange2base[index], s.setup)
    reg = register_scene(views, A, fit_depth=fit_depth)
    bad = check_views(views, A, reg, s.setup)
    if bad:
        skipped += [(views[k].name, why) for k, why in bad]
        keep = np.setdiff1d(np.arange(len(views)), [k for k, _ in bad])
        index, views, A = [index[k] for k in keep], [views[k] for k in keep], A[keep]
        reg = register_scene(views, A, fit_depth=fit_depth)
    if reg.start is not None:
        notes.append(f"start with no guess: {reg.start.source}, chosen of {len(reg.candidates)} candidates by the views' "
                     f"agreement after a coarse registration ({100 * reg.start.share:.0f}% of the points near another view's)")
    free = scene_free(views, reg.pairs, A, reg.X)
    # the depth's scale and bias are the core's to fit where the capture determines them (the session's
    # depth_scale: fit frees them; the registration above fits them only then)
    model = SceneSurface(s.setup, views, reg.pairs, reg.X, fit_depth=True, depth=reg.depth, start=centroid_start,
                         free=free)
    hold, freed = held_and_freed(s, options)
    if fit_depth:
        freed, hold = tuple(dict.fromkeys(freed + ("depth_scale", "depth_bias"))), tuple(n for n in hold if not n.startswith("depth_"))
    cal = estimate(model, robot_model(s, index, options), options.folds, hold=hold, free=freed)
    used = {s.names[index[k]] for k in cal.pose_indices}
    distances = [float(np.median(v.points[:, 2])) for k, v in zip(index, views) if s.names[k] in used]
    figures = dict(cal.sensor.figures, distance_m=distances, start=None if reg.start is None else reg.start.source)
    return replace(cal, sensor=replace(cal.sensor, figures=figures), skipped=skipped + list(cal.skipped),
                   notes=list(s.notes) + notes + list(cal.notes), input_folder=s.folder)
