"""The arm itself in a depth camera's clouds (markerless, eye-to-hand), through the core.

A depth session whose target is ``{type: arm}`` (the arm, its meshes and each cloud's joint
angles from ``joints: {file: joints.csv, unit: deg, arm: panda}``) is calibrated in named steps:

1. :func:`arm_of_session`: the arm's meshes (:func:`~handeye.robot.meshes.meshes_for`) posed at
   every view's joint angles through the arm's table (:class:`~handeye.sensors.depth.arm.PosedArm`);
2. :func:`read_arm_clouds`: the clouds read and thinned (a view whose cloud cannot be read is
   skipped, named);
3. :func:`start_arm`: X without any guess: every view's moving points searched at once (what
   moved between the views: the camera is fixed, the table, the floor and a box stay where they
   were; X's rotation from the views' centroids and 60 spread ones, its translation from the
   centroids, each pulled in by ICP from 30 cm), the one that puts most points on the arm kept
   when most views agree with it (step 4); else the views' joint angles checked against their
   clouds (:func:`joints_agreement`: the distances between the views' moving points against those
   between the links at their angles; refused, named, when they do not agree), then a few views'
   posed arm found in their clouds by the global registration
   (:func:`~handeye.sensors.depth.registration.find_shape`) among their moving points (all the
   cloud's points when that fails), each candidate (and the runners-up) pulled in by ICP over every
   view's points, then the next few clouds;
4. :func:`consistent_arm_views`: each view's own X (ICP from the common one) checked against the
   others': a view that disagrees (another arm pose than its joint angles say) or shows too little
   of the arm is skipped, named;
5. :func:`segment_arm`: each view's points within a band of its posed arm at X (the arm's, not the
   table's, the floor's or a box's), and :class:`~handeye.sensors.depth.arm.ArmSurface` through
   :func:`~handeye.estimation.core.estimate`: X, the depth scale and bias, the std, the verdict; with
   ``fit_table=True`` the arm's table with them (:func:`calibrate_arm_depth_session`).

Examples
--------
>>> import tempfile
>>> from handeye.pipelines.depth.arm import arm_of_session, calibrate_arm_depth_session, read_arm_clouds
>>> from handeye.pipelines.depth.session import load_depth_session
>>> from handeye.options import CalibrationOptions
>>> from handeye.pipelines.depth.simulate_arm import arm_depth_scene, write_arm_depth_session
>>> folder = write_arm_depth_session(tempfile.mkdtemp() + "/arm", arm_depth_scene(4, rng=2, image_size=(128, 96)))
>>> s = load_depth_session(folder)
>>> s.kind, arm_of_session(s).n_views, len(read_arm_clouds(s).index)
('arm', 4, 4)
>>> cal = calibrate_arm_depth_session(s, CalibrationOptions())  # doctest: +SKIP
>>> cal.sensor.target, cal.X                                     # doctest: +SKIP
('arm', array([[...]]))
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from ..._shared.progress import Progress
from ..._shared.threads import one_blas_thread
from ...errors import DegenerateMotionError, InputMismatchError, SessionError
from ...estimation.core import estimate
from ...frames.metrics import rotation_error, translation_error
from ...geometry.se3 import invert, make_transform
from ...options import CalibrationOptions
from ...result import Calibration
from ...robot.meshes import BASE, meshes_for
from ...robot.models import ControllerPoses, JointAngles
from ...sensors.depth.arm import COARSE_TAU, SPACING, ArmSurface, PosedArm, fit_cam2base, on_arm, to_base, within
from ...sensors.depth.clouds import depth_sigma
from ...sensors.depth.registration import MIN_INLIERS, find_shape
from ...sensors.depth.shape import search_tree, voxel_pick
from .._arm import arm_table, table_tolerance
from .._sensor import held_and_freed, session_robot_input
from .mesh import read_scene
from .session import DepthSession

__all__ = ["ArmClouds", "arm_of_session", "read_arm_clouds", "start_arm", "pooled_start", "consistent_arm_views", "segment_arm",
           "calibrate_arm_depth_session", "joints_agreement", "pooled_points", "AGREE_DEG", "AGREE_M", "MAX_POINTS", "GLOBAL_VIEWS",
           "JOINTS_AGREE"]

#: A view's own X (ICP from the common one) agrees with the others' within this (deg) ...
AGREE_DEG = 2.0
#: ... and this (m).
AGREE_M = 0.02
#: Each view's points on the arm fitted, at most (drawn at random).
MAX_POINTS = 2000
#: The views whose clouds the global registration searches (the first ones read; more when none is found).
GLOBAL_VIEWS = 2
#: Each cloud thinned to this many points (random, fixed seed) before anything else.
THINNED = 30000
#: A point of one view with nothing within this (m) in most other views has moved: the arm's.
MOVED_M = 0.01
#: Points per view for the ICP of X ...
ICP_POINTS = 6000
#: ... and for scoring the global registration's candidates ...
SCORE_POINTS = 1500
#: ... and the moving points per view of the search over every view at once, whose candidates go on
#: from the ICP's wide rounds to its fine ones (and are scored) only these many, those with the most
#: points within the wide rounds' last threshold: on the simulated Panda the candidate that won among
#: all 61 was among the first 2 of them in each of 4 sessions (its basin's 3,000-3,600 points within
#: that threshold, another basin's at most 2,450).
POOLED_POINTS = 300
POOLED_KEPT = 8
#: The views' moving points' centroids (camera frame) and their moving links' centroids (base frame,
#: at each view's joint angles) are a rigid motion apart when each view's angles are its cloud's: the
#: distances between views agree, up to what the camera does not see. Their correlation was 0.50-0.75
#: on the simulated Panda (seeds 1-5), -0.17-0.08 with every view's angles the next view's: below this,
#: with the search over every view at once failed, the angles are refused as not the clouds' (the
#: search of every group of clouds took 17-19 s to say the same).
JOINTS_AGREE = 0.25


@dataclass
class ArmClouds:
    """A session's clouds for the arm: per view kept its index, its thinned points (camera frame)."""

    index: list[int] = field(default_factory=list)  #: into the session's views
    points: list[NDArray[np.float64]] = field(default_factory=list)
    skipped: list[tuple[str, str]] = field(default_factory=list)  #: (view, why)
    notes: list[str] = field(default_factory=list)

    def stacked(self, limit: int | None = None) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
        """Every view's points stacked (at most ``limit`` per view, the first ones: they are in random
        order) and each one's view (its index into the session's views)."""
        parts = [p[:limit] for p in self.points]
        return np.repeat(np.asarray(self.index, dtype=np.intp), [len(p) for p in parts]), np.concatenate(parts)

    def only(self, keep: list[int]) -> ArmClouds:
        """The views at positions ``keep``."""
        return ArmClouds([self.index[k] for k in keep], [self.points[k] for k in keep], list(self.skipped), list(self.notes))


def arm_of_session(s: DepthSession) -> PosedArm:
    """The session's arm posed at every view's joint angles.

    Raises
    ------
    SessionError
        The session has no joint angles, or its arm's table is not one handeye has meshes for (the
        shipped table of an arm with meshes, or one a calibration corrected from it:
        :func:`~handeye.robot.meshes.meshes_for`; a URDF's or another arm's would place the links wrong).
    """
    where = s.folder / "session.yaml"
    if s.arm is None or s.joints is None or s.arm_target is None:
        raise SessionError(f"{where}: the arm as the target needs joints: (file, unit, arm) and target: {{type: arm}}")
    try:
        meshes = meshes_for(s.arm, s.arm_target.hand, s.arm_target.finger_opening)
    except InputMismatchError as exc:
        raise SessionError(f"{where}: joints: arm {s.arm.name!r}: {exc}") from None
    return PosedArm(meshes, meshes.link2base(s.arm, s.joints))


def read_arm_clouds(s: DepthSession, progress: bool = False) -> ArmClouds:
    """Every cloud of ``s`` read and thinned to :data:`THINNED` points (random, fixed seed);
    a cloud that cannot be read or has too few points is skipped, named."""
    out = ArmClouds()
    rng = np.random.default_rng(0)
    bar = Progress(len(s.cloud_paths), "reading the clouds", progress)
    for k, path in enumerate(s.cloud_paths):
        bar.update()
        try:
            q = read_scene(path, s.unit)
        except InputMismatchError as exc:
            out.skipped.append((s.names[k], str(exc)))
            continue
        if len(q) < MIN_INLIERS:
            out.skipped.append((s.names[k], f"{path}: {len(q)} points with depth: the arm cannot be in it"))
            continue
        out.index.append(k)
        out.points.append(q[rng.permutation(len(q))[:THINNED]])
    bar.close()
    return out


def _tight(q: NDArray[np.float64]) -> float:
    """The ICP's last threshold (m): 3 of the points' median depth noise and two sample spacings."""
    return 3.0 * float(np.median(depth_sigma(q[:, 2]))) + 2.0 * SPACING


def _found(arm: PosedArm, view: int, q: NDArray[np.float64], where: str) -> list[NDArray[np.float64]] | str:
    """The candidates for X (cam2base) from one view's cloud (the global registration's pose of its
    posed arm, then its runners-up), or why none."""
    try:
        match = find_shape(arm.shape(view), q, where=where, rng=view)
    except InputMismatchError as exc:
        return str(exc)
    return [invert(match.target2cam)] + [invert(T) for T in match.others]


def _thresholds(q: NDArray[np.float64], steps: int, reach: float) -> NDArray[np.float64]:
    """The ICP's thresholds (m): from ``reach`` down to the tight one in ``steps``, and twice the tight one."""
    tight = _tight(q)
    return np.r_[np.geomspace(reach, tight, steps), tight, tight]


def _explained(arm: PosedArm, X: NDArray[np.float64], owner: NDArray[np.intp], q: NDArray[np.float64], steps: int = 10,
               reach: float = 0.05) -> tuple[NDArray[np.float64], int]:
    """Candidate X pulled in by ICP over every view's points (thresholds from ``reach`` (m) down to
    the tight one, in ``steps``), and how many of the points it puts on the arm."""
    X = fit_cam2base(arm, X, owner, q, _thresholds(q, steps, reach))
    return X, int(on_arm(arm, X, owner, q).sum())


def _distinct(candidates: list[NDArray[np.float64]]) -> list[NDArray[np.float64]]:
    """The candidates more than 2 deg or 20 mm from every one before them."""
    out: list[NDArray[np.float64]] = []
    for X in candidates:
        if all(np.degrees(rotation_error(X, Y)) > 2.0 or translation_error(X, Y) > 0.02 for Y in out):
            out.append(X)
    return out


def _moving(c: ArmClouds, j: int, trees: list[cKDTree], limit: int | None = None) -> NDArray[np.float64]:
    """View ``j``'s points (its first ``limit``: they are in random order) that at least half of the
    other views have nothing within :data:`MOVED_M` of: what moved between the views (the arm's
    moving links, not the table, the floor or a box, which the camera fixed in the cell sees in the
    same place every time)."""
    q = c.points[j][:limit]
    others = [t for i, t in enumerate(trees) if i != j]
    away = sum(np.isinf(t.query(q, distance_upper_bound=MOVED_M)[0]).astype(int) for t in others)
    return q[away >= 0.5 * len(others)]


def _group_start(s: DepthSession, arm: PosedArm, c: ArmClouds, views: list[int], trees: list[cKDTree], jobs: int | None
                 ) -> tuple[NDArray[np.float64], int, int] | str:
    """The best X of the candidates from the clouds ``views`` (positions in ``c``): each cloud's
    moving points searched (all its points when that fails), each candidate scored on a few points
    of every view and the best pulled in on more: (X, its points on the arm, the candidates); or why none."""

    def found(j: int) -> list[NDArray[np.float64]] | str:
        where = str(s.cloud_paths[c.index[j]])
        moving = _moving(c, j, trees)
        first = _found(arm, c.index[j], moving, where) if len(moving) >= MIN_INLIERS else "too few points moved"
        return _found(arm, c.index[j], c.points[j], where) if isinstance(first, str) else first

    few_owner, few = c.stacked(SCORE_POINTS)  # each candidate scored on a few points per view, the best refined
    with ThreadPoolExecutor(max_workers=max(1, jobs or 2)) as pool, one_blas_thread():
        results = list(pool.map(found, views))
        candidates = _distinct([X for f in results if not isinstance(f, str) for X in f])
        scored = list(pool.map(lambda X: _explained(arm, X, few_owner, few, 6), candidates))
    if not candidates:
        return "; ".join(f for f in results if isinstance(f, str))
    owner, q = c.stacked(ICP_POINTS)
    X, seen = _explained(arm, max(scored, key=lambda r: r[1])[0], owner, q, 4)
    return X, seen, len(candidates)


def pooled_points(c: ArmClouds, trees: list[cKDTree]) -> list[NDArray[np.float64]]:
    """Each view's first :data:`POOLED_POINTS` moving points (:func:`_moving` of its first 8 times as many)."""
    return [_moving(c, j, trees, 8 * POOLED_POINTS)[:POOLED_POINTS] for j in range(len(c.index))]


def _centroids(arm: PosedArm, c: ArmClouds, moving: list[NDArray[np.float64]]
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per view the centroid of its moving points (camera frame) and of its moving links (base frame,
    at its joint angles)."""
    links = np.array([link.frame != BASE for link in arm.meshes.links])[arm.sample_link]
    cam = np.array([m.mean(axis=0) if len(m) else np.full(3, np.nan) for m in moving])
    base = np.array([arm.points[k][links].mean(axis=0) for k in c.index])
    return cam, base


def joints_agreement(arm: PosedArm, c: ArmClouds, moving: list[NDArray[np.float64]]) -> float | None:
    """How well the views' joint angles agree with their clouds, whatever X: the correlation of the
    distances between views' moving points' centroids (camera frame) with those between their moving
    links' centroids (base frame, at the angles): near 1 when each view's angles are its cloud's (a
    rigid motion keeps distances; what the camera does not see of the links lowers it), near 0 when
    they are another view's (:data:`JOINTS_AGREE`). None with fewer than 4 views that show enough
    moving points."""
    cam, base = _centroids(arm, c, moving)
    seen = np.array([len(m) >= MIN_INLIERS for m in moving])
    if seen.sum() < 4:
        return None
    cam, base = cam[seen], base[seen]
    upper = np.triu_indices(len(cam), 1)
    d_cam = np.linalg.norm(cam[:, None] - cam[None], axis=2)[upper]
    d_base = np.linalg.norm(base[:, None] - base[None], axis=2)[upper]
    if np.std(d_cam) == 0 or np.std(d_base) == 0:
        return None
    return float(np.corrcoef(d_cam, d_base)[0, 1])


def pooled_start(arm: PosedArm, c: ArmClouds, trees: list[cKDTree], jobs: int | None = None,
                 moving: list[NDArray[np.float64]] | None = None) -> tuple[NDArray[np.float64], int, int] | str:
    """The best X from every view at once: the moving points' centroid of each view (camera frame)
    against its moving links' centroid (base frame), X's rotation from those pairs (Kabsch, when the
    centroids spread) and from 60 evenly spread ones (the icosahedral group), its translation
    matching the centroids' means; each candidate pulled in by the ICP's wide rounds over a few moving
    points per view from 30 cm down (``jobs`` at a time, threads; default 2), the :data:`POOLED_KEPT`
    with most points within their last threshold through the fine rounds, the one of those that puts
    most points on the arm refined: (X, its points on the arm, the candidates); or why none.
    ``moving``: each view's moving points (:func:`pooled_points`), when found already."""
    moving = pooled_points(c, trees) if moving is None else moving
    if sum(len(m) >= MIN_INLIERS for m in moving) < 3:
        return "fewer than 3 clouds in which enough of the arm moved"
    cam, base = _centroids(arm, c, moving)
    rotations = list(Rotation.create_group("I").as_matrix())
    if np.linalg.svd(cam - cam.mean(axis=0), compute_uv=False)[1] > 0.02:  # the centroids span a plane
        rotations.insert(0, Rotation.align_vectors(base - base.mean(axis=0), cam - cam.mean(axis=0))[0].as_matrix())
    owner = np.repeat(np.asarray(c.index, dtype=np.intp), [len(m) for m in moving])
    q = np.concatenate(moving)
    thresholds = _thresholds(q, 8, 0.3)
    wide, fine = thresholds[thresholds > COARSE_TAU], thresholds[thresholds <= COARSE_TAU]

    def pulled(R: NDArray[np.float64]) -> tuple[NDArray[np.float64], int]:
        X = fit_cam2base(arm, make_transform(R, base.mean(axis=0) - R @ cam.mean(axis=0)), owner, q, wide)
        return X, within(arm, X, owner, q, wide[-1], coarse=True)

    def finished(X: NDArray[np.float64]) -> tuple[NDArray[np.float64], int]:  # as _explained's last rounds
        X = fit_cam2base(arm, X, owner, q, fine)
        return X, int(on_arm(arm, X, owner, q).sum())

    with ThreadPoolExecutor(max_workers=max(1, jobs or 2)) as pool, one_blas_thread():
        wide_X = list(pool.map(pulled, rotations))
        kept = np.sort(np.argsort([-n for _, n in wide_X], kind="stable")[:POOLED_KEPT])  # in the candidates' order
        scored = list(pool.map(finished, [wide_X[k][0] for k in kept]))
    few_owner, few = c.stacked(ICP_POINTS)
    X, seen = _explained(arm, max(scored, key=lambda r: r[1])[0], few_owner, few, 4)
    return X, seen, len(rotations)


def start_arm(s: DepthSession, arm: PosedArm, c: ArmClouds, jobs: int | None = None
              ) -> tuple[ArmClouds, NDArray[np.float64], list[str]]:
    """X (cam2base) with no guess (the module's steps 3 and 4): every view's moving points searched
    at once, then the clouds :data:`GLOBAL_VIEWS` at a time, until the best candidate is one most
    views agree with (:func:`consistent_arm_views`); the views that agree, X refitted on them, notes
    of what it took. (The search over every view first: it costs one group's search, and found the
    simulated Panda where the first group's did not.)

    Raises
    ------
    DegenerateMotionError
        No candidate from any cloud that most views agree with: the arm is not found; or, the search
        over every view failed, the views' joint angles do not agree with their clouds whatever X
        (:func:`joints_agreement` below :data:`JOINTS_AGREE`: another view's angles, another arm).
    """
    trees = [search_tree(q[voxel_pick(q, 0.5 * MOVED_M)]) for q in c.points]
    moving = pooled_points(c, trees)
    why: list[str] = []
    groups = [list(range(first, min(first + GLOBAL_VIEWS, len(c.index)))) for first in range(0, len(c.index), GLOBAL_VIEWS)]
    for views in [None] + groups:  # None: every view's moving points at once
        searched = "every cloud's moving points" if views is None else ", ".join(s.names[c.index[j]] for j in views)
        start = pooled_start(arm, c, trees, jobs, moving) if views is None else _group_start(s, arm, c, views, trees, jobs)
        if isinstance(start, str):
            why.append(f"{searched}: {start}")
        else:
            X, seen, n = start
            agreed, X = consistent_arm_views(s, arm, c, X)
            if len(agreed.index) >= max(3, (len(c.index) + 1) // 2):
                return agreed, X, [f"the arm found with no guess of X in {searched} ({n} candidates; the best put {seen} "
                                   f"points on the arm, and {len(agreed.index)} of {len(c.index)} views agree with it)"]
            why.append(f"{searched}: the best candidate puts {seen} points on the arm, and only {len(agreed.index)} of "
                       f"{len(c.index)} views agree with it")
        agreement = joints_agreement(arm, c, moving) if views is None else None
        if agreement is not None and agreement < JOINTS_AGREE:
            # what moved between the views is not where the angles move the arm: no X can explain it, and
            # searching each group of clouds would only say so in minutes
            raise DegenerateMotionError(
                f"the joint angles do not match the clouds ({why[-1]}; the distances between the views' "
                f"moving points and between the arm's links at their angles correlate {agreement:.2f}, where a view's "
                f"own angles give {JOINTS_AGREE:g} or more): is each cloud's row of the joints' file its own (the "
                "rows' order, the cloud named in it), the joint columns in the arm's order, and the arm the one named "
                "(joints: arm)?")
    raise DegenerateMotionError("the arm is not found in the clouds (" + "; ".join(why[:3]) + "): is it in view, the "
                                "clouds' unit right (depth: unit), and each cloud's joint angles its own?")


def consistent_arm_views(s: DepthSession, arm: PosedArm, c: ArmClouds, X: NDArray[np.float64]
                         ) -> tuple[ArmClouds, NDArray[np.float64]]:
    """``c`` without the views that show too little of the arm where X puts it, or whose own X (ICP
    from X on their points alone) is more than :data:`AGREE_DEG` or :data:`AGREE_M` from it (their
    joint angles are not the arm's pose in their cloud), each named; and X refitted on the rest."""
    def own(j: int) -> tuple[int, NDArray[np.float64] | None]:  # the view's points on the arm at X, and its own X
        q = c.points[j][:ICP_POINTS]
        owner = np.full(len(q), c.index[j], dtype=np.intp)
        seen = int(on_arm(arm, X, owner, q).sum())
        if seen < MIN_INLIERS:
            return seen, None
        tight = _tight(q)
        return seen, fit_cam2base(arm, X, owner, q, np.r_[np.geomspace(4 * tight, tight, 6), tight, tight])

    with ThreadPoolExecutor(max_workers=2) as pool, one_blas_thread():  # each view alone: on both cores
        views = list(pool.map(own, range(len(c.index))))
    keep, skipped = [], list(c.skipped)
    for j, (k, (seen, X_j)) in enumerate(zip(c.index, views)):
        if X_j is None:
            skipped.append((s.names[k], f"the arm is not in this cloud where the other views put the camera: {seen} of its "
                                        f"points lie on it (at least {MIN_INLIERS}); is the arm in view?"))
            continue
        rot, tra = float(np.degrees(rotation_error(X_j, X))), float(translation_error(X_j, X))
        if rot > AGREE_DEG or tra > AGREE_M:
            skipped.append((s.names[k], f"its cloud puts the camera {rot:.1f} deg, {1e3 * tra:.0f} mm from where the other "
                                        "views do: its joint angles are not the arm's pose in it (another row, or the arm "
                                        "moved during the capture)"))
            continue
        keep.append(j)
    out = replace(c.only(keep), skipped=skipped)
    if len(keep) < len(c.index) and len(keep):
        owner, q = out.stacked(ICP_POINTS)
        X = _explained(arm, X, owner, q)[0]
    return out, X


def segment_arm(arm: PosedArm, c: ArmClouds, X: NDArray[np.float64], max_points: int = MAX_POINTS
                ) -> list[NDArray[np.float64]]:
    """Per view its points on the arm at X (:func:`~handeye.sensors.depth.arm.on_arm`), at most ``max_points``."""
    out = []
    for j, k in enumerate(c.index):
        q = c.points[j]
        on = q[on_arm(arm, X, np.full(len(q), k, dtype=np.intp), q)]
        out.append(on[:max_points])
    return out


def calibrate_arm_depth_session(s: DepthSession, options: CalibrationOptions, *, fit_depth: bool = True,
                                progress: bool = False, jobs: int | None = None, fit_table: bool = False) -> Calibration:
    """A depth session with the arm as the target (the module's docstring): X with its std and
    verdict, the depth scale and bias; the views skipped with why.

    Parameters
    ----------
    s : DepthSession
        Read by :func:`~handeye.pipelines.depth.session.load_depth_session`, ``target: {type: arm}``.
    options : CalibrationOptions
        ``robot_accuracy`` and ``folds`` are used.
    fit_depth : bool
        Estimate the depth scale and bias (else 1 and 0).
    fit_table : bool
        Fit the arm's table with X (:class:`~handeye.robot.models.JointAngles`, the entries a board
        calibration fits, each with the table's tolerance as its prior:
        :func:`~handeye.pipelines._arm.table_tolerance`; every point moved with its link); else the
        links are posed by the table as given and its tolerance is added to X's std. Measured
        (``benchmarks/bench_arm_depth.py --fit-table``: the simulated Panda with its hand, 10 clouds of
        640x480): an arm 0.7 mm / 0.07 deg off per entry, X 4.2 mm off with the table held (verdict
        weak, 7-9 mm std) and 0.21 mm fitted (worst 0.57 mm, verdict good; median of 10); 0.3 mm /
        0.03 deg off, 1.8 mm against 0.26 mm (8). Not the default yet: X was within 3 of the fitted
        std in 9 of 10, 8 of 8, and 9 of 10 with the arm exactly on its table, where it is 0.20 mm
        off (worst 0.75) against 0.04 mm held; why X then strays beyond its std is not found yet (the
        solver stops where a point's nearest face changes, but holding each point's face per round,
        as ICP does, did not mend it). About 10 s more per session.
    progress : bool
        Progress on stderr. ``jobs``: clouds searched at a time by the global registration (threads; default 2).

    Raises
    ------
    SessionError
        No meshes of the session's arm, or a table they do not ride on.
    DegenerateMotionError
        The arm not found in the clouds, or in fewer than 3 of them.
    """
    arm = arm_of_session(s)
    c = read_arm_clouds(s, progress)
    if len(c.index) < 3:
        raise DegenerateMotionError(_too_few(s, c))
    c, X, notes = start_arm(s, arm, c, jobs)
    points = segment_arm(arm, c, X)
    names, joints = [s.names[k] for k in c.index], s.joints[c.index]
    hold, free = held_and_freed(s, options)
    if fit_table:
        length, angle, _ = table_tolerance(s.arm)
        model = ArmSurface(s.setup, names, arm.subset(c.index), points, X, fit_depth, joints)
        cal = estimate(model, JointAngles(s.arm, joints, length_prior=length, angle_prior=angle), options.folds, hold=hold,
                       free=free)
    else:
        model = ArmSurface(s.setup, names, arm.subset(c.index), points, X, fit_depth)
        cal = estimate(model, ControllerPoses(s.flange2base[c.index], options.robot_accuracy), options.folds, hold=hold, free=free,
                       held=arm_table(model, lambda X: to_base(X, model.measured), arm.meshes, s.arm, joints, "depth camera"))
    distances = [float(np.median(p[:, 2])) for p in points]
    used = {s.names[c.index[k]] for k in cal.pose_indices}
    figures = dict(cal.sensor.figures, distance_m=[d for k, d in zip(c.index, distances) if s.names[k] in used])
    return replace(cal, sensor=replace(cal.sensor, figures=figures), skipped=list(c.skipped) + list(cal.skipped),
                   notes=list(s.notes) + c.notes + notes + list(cal.notes), input_folder=s.folder,
                   robot_input=session_robot_input(s, cal.flange2base))


def _too_few(s: DepthSession, c: ArmClouds) -> str:
    return (f"the arm is seen in {len(c.index)} of {len(s.names)} clouds "
            f"({'; '.join(f'{n}: {r}' for n, r in c.skipped[:5])}): at least 3 are needed, 10 or more with the arm "
            "in varied poses to trust X")
