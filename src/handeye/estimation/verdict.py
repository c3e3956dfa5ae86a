"""The verdict on a calibration and its reasons, decided in one place from one record of evidence.

:func:`handeye.diagnose` looks at the poses alone (degenerate motions, inconsistent poses and the
conventions that explain them, outliers, weak rotation); a calibration adds what only a fit can
show: the std of X (too wide to promise the thesis's acceptance of 5 mm / 1 deg) and the spread of
the closed forms about X (wider than the std allows). The estimation core's fit adds how far the
fit and its held-out views are from what the noise allows (:func:`fit_verdict`; the core measures,
this module decides). The check's own rules are here too (:func:`count_verdict`, :func:`motion_verdict`,
:func:`reading_verdict`, :func:`agreement_verdict`, :func:`scale_verdict`, :func:`weak_motions`,
:func:`weakened`), and what a capture that determines only part of X gets (:func:`undetermined_verdict`,
:func:`partial_pose_verdict`): :mod:`handeye.estimation.diagnostics` measures the poses, these decide, and a test
keeps every verdict assigned here. :func:`judge` combines them; ``calibrate``,
``check``, the report, ``fleet`` and ``acquire`` all take the verdict and the exit status from here,
so the same data get the same verdict whichever command looked at them.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import cast

import numpy as np
from numpy.typing import NDArray

from ..result import Calibration, Diagnostics

__all__ = ["ACCEPT_DEG", "ACCEPT_MM", "AXIS_SHARE_WEAK", "CONSISTENT", "EXIT_STATUS", "Evidence", "FAR_TARGET_M", "FEW_POSES",
           "FIT_FACTOR", "FitEvidence", "HEADLINES", "HELDOUT_FACTOR", "Judgement", "MANY_OUTLIERS", "MIN_INLIERS", "MIN_POSES",
           "MISPAIRED", "SCALE_SIGMAS", "SCALE_TOLERANCE", "SMALL_ROTATION_DEG", "agreement_verdict", "count_verdict",
           "disagreement_verdict", "exit_status", "fit_verdict", "headline", "judge", "judged", "many_outliers", "motion_verdict",
           "pairing_verdict", "partial_pose_verdict", "reading_verdict", "scale_is_off", "scale_verdict", "solver_spread",
           "undetermined_verdict", "weak_motions", "weakened"]

#: X is "weak" when 3 std of it exceed the thesis's acceptance (§5: 5 mm and 1 deg).
ACCEPT_MM, ACCEPT_DEG = 5.0, 1.0
#: The exit status of ``check`` and of the commands that calibrate: 0 good (or not checked), 1 weak or
#: partial (an answer, to be trusted less), 2 degenerate or inconsistent (fix the data first).
EXIT_STATUS = {"good": 0, "not checked": 0, "weak": 1, "partial": 1, "degenerate": 2, "inconsistent": 2}


@dataclass(frozen=True)
class Evidence:
    """What the verdict is decided from.

    ``check``: the diagnostics of the poses (None: not checked); ``std``: X's reported std (3 deg,
    3 mm); ``std_sources``: its parts by source (``jackknife``, ``intrinsics``, ...); ``spread``:
    the median distance (deg, mm) of the closed forms from X.
    """

    check: Diagnostics | None
    std: NDArray[np.float64] | None = None
    std_sources: dict | None = None
    spread: tuple[float, float] | None = None
    #: the median distance (deg, mm) from X of the closed forms left out of ``spread`` because they predict
    #: held-out views worse than X, and by what factor (their best held-out error over X's)
    unfair_spread: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class Judgement:
    """The verdict and every reason for it (the check's advice first, then what the fit added)."""

    verdict: str
    reasons: list[str] = field(default_factory=list)
    added: list[str] = field(default_factory=list)  #: the reasons the fit added to the check's


def _norms(v: NDArray[np.float64]) -> tuple[float, float]:
    return float(np.linalg.norm(v[:3])), float(np.linalg.norm(v[3:]))


#: From this many poses, more of the same kind hardly narrow a std that leaving one pose out makes wide.
MANY_POSES = 20

#: How an arm handeye does not ship is given (the advice that says to record joint angles says it too).
OWN_ARM = ("an arm handeye does not ship (handeye.robot.kinematics.arm_names() lists those it does: a FANUC with an "
           "extended axis is not one) is named by a file: its URDF (joints: arm: robot.urdf, with base_link and tip_link "
           "when its chain has other ends; pip install 'handeye[urdf]') or a DH table of your own (joints: arm: "
           "my_arm.yaml: name, convention dh or mdh, joints: one row [a_m, alpha_rad, d_m, theta_offset_rad] per "
           "revolute joint, flange: the flange in the last joint's frame, a 4x4; handeye/data/arms/*.yaml are examples, "
           "docs/guide.md 'Joint angles'); an extended axis (a linear track or a positioner) is not modelled: hold it "
           "still during the capture and give the arm's own joints")


def _beyond(part: NDArray[np.float64] | None) -> bool:
    """Whether a part of X's std (deg, mm per axis) alone puts 3 std beyond the acceptance."""
    return part is not None and bool(3 * np.linalg.norm(part[3:]) > ACCEPT_MM or 3 * np.linalg.norm(part[:3]) > ACCEPT_DEG)


def _fixed_cause(sources: dict) -> tuple[str, str] | None:
    """When a part of X's std that no number of views narrows alone exceeds the acceptance: that part
    in words and its fix in a few words (the advice says how); else None."""
    if _beyond(sources.get("arm_table")):
        return ("the tolerance of the arm's table the camera's links are placed by, not by these views",
                "calibrate the arm's table and name it as the arm (the advice gives the commands)")
    if _beyond(sources.get("robot_accuracy")):
        return ("the robot's absolute accuracy, not by these views",
                "record the arm's joint angles, or use a more accurate robot (the advice says how)")
    if _beyond(sources.get("held_unknowns")):
        return ("the tolerance of the sensor's unknowns held at their nominal values (a depth scale, a radius)",
                "give their calibrated values, or capture views that determine them (the advice says how)")
    return None


def _std_reason(std: NDArray[np.float64], sources: dict, n_used: int) -> str | None:
    """Why 3 std of X cannot promise the acceptance, or None when they can."""
    rot, mm = (3 * v for v in _norms(std))
    if rot <= ACCEPT_DEG and mm <= ACCEPT_MM:
        return None
    jack, intr, robot = sources.get("jackknife"), sources.get("intrinsics"), sources.get("robot_accuracy")
    table = sources.get("arm_table")
    if table is not None and _beyond(table):
        return (f"3 std of X are {mm:.1f} mm / {rot:.2f} deg, beyond {ACCEPT_MM:g} mm / {ACCEPT_DEG:g} deg, and the arm's "
                f"table alone gives {np.linalg.norm(table[3:]):.1f} mm / {np.linalg.norm(table[:3]):.2f} deg per std: the "
                "links the camera sees are placed by the joint angles through the arm's table, whose tolerance X takes "
                "whole (the note on the arm's table gives it), so more views will not narrow it. Calibrate the arm's "
                "table: capture a board with the same arm and its joint angles (a session with a joints: block, "
                "docs/guide.md 'Joint angles'), run handeye calibrate BOARD_SESSION --out CAL (it writes "
                "CAL/arm_corrected.yaml), then handeye calibrate THIS_SESSION --arm CAL/arm_corrected.yaml (or "
                "joints: arm: arm_corrected.yaml in session.yaml): a calibrated table is taken at a tenth of the "
                "nominal one's tolerance; or use a board")
    if robot is not None and _beyond(robot):
        return (f"3 std of X are {mm:.1f} mm / {rot:.2f} deg, beyond {ACCEPT_MM:g} mm / {ACCEPT_DEG:g} deg, and the robot's "
                f"accuracy alone gives {np.linalg.norm(robot[3:]):.1f} mm / {np.linalg.norm(robot[:3]):.2f} deg per std: "
                "a robot error constant over the capture moves X whole and no number of poses removes it; record the "
                "arm's joint angles with each pose (joints.csv and a joints: block naming the arm in session.yaml, "
                "then handeye calibrate SESSION --out OUT): handeye then fits the arm's table with X from the same "
                "views (docs/guide.md, 'Joint angles'; on a real Panda capture that predicted held-out views 12x "
                f"better than any pose-only method); {OWN_ARM}; or use a more accurate robot, or give its accuracy if "
                "it is better (--robot-accuracy DEG,MM)")
    held = sources.get("held_unknowns")
    if held is not None and (np.linalg.norm(held[3:]) >= 0.5 * np.linalg.norm(std[3:])
                             or np.linalg.norm(held[:3]) >= 0.5 * np.linalg.norm(std[:3])):  # the largest part
        return (f"3 std of X are {mm:.1f} mm / {rot:.2f} deg, beyond {ACCEPT_MM:g} mm / {ACCEPT_DEG:g} deg, and the sensor's "
                f"unknowns held at their nominal values give {np.linalg.norm(held[3:]):.1f} mm / "
                f"{np.linalg.norm(held[:3]):.2f} deg per std (the capture does not determine them: the note on each names "
                "it and the tolerance X takes): give each one's calibrated value in session.yaml (a depth camera's "
                "depth_scale from its own calibration; a ball's diameter measured), or take views that determine it "
                "(for a depth scale: the flange translated 10 cm or more toward and away from the object between "
                "views), then free it (--free NAME)")
    why = (f"3 std of X are {mm:.1f} mm / {rot:.2f} deg, beyond {ACCEPT_MM:g} mm / {ACCEPT_DEG:g} deg"
           + (f" (leaving one pose out moves X by {np.linalg.norm(jack[3:]):.1f} mm / {np.linalg.norm(jack[:3]):.2f} deg "
              "per std)" if jack is not None else ""))
    if intr is not None and _beyond(intr):
        return why + (f"; the intrinsics estimated from these images alone give {np.linalg.norm(intr[3:]):.1f} mm / "
                      f"{np.linalg.norm(intr[:3]):.2f} deg per std: calibrate the camera on its own (views filling the "
                      "image, the target tilted) and give K and dist in session.yaml, or take more views that do")
    if n_used >= MANY_POSES:
        return why + (f": {n_used} poses disagree more than their noise, and more of the same will not pin X down; "
                      "rotations of 30 deg or more about varied axes, and the robot's accuracy (a kinematic error that "
                      "depends on the pose; --robot-accuracy), decide it")
    return why + ": the poses do not pin X down; take more (10-20), with rotations of 30 deg or more about varied axes"


def _spread_reason(std: NDArray[np.float64], spread: tuple[float, float]) -> str | None:
    """Why the closed forms' spread about X says the std promises too much, or None."""
    lim_rot, lim_mm = (3 * v for v in _norms(std))
    rot, mm = spread
    if rot <= lim_rot and mm <= lim_mm:
        return None
    return (f"the closed-form solvers land a median {mm:.2f} mm / {rot:.3f} deg from X, beyond its 3 std "
            f"({lim_mm:.2f} mm / {lim_rot:.3f} deg): the solvers disagree more than the noise explains; check the "
            "poses and take more, with larger rotations")


def _unfair_reason(std: NDArray[np.float64], unfair: tuple[float, float, float]) -> str | None:
    """What a good verdict says when the closed forms that predict held-out views worse than X land
    beyond its 3 std, or None."""
    lim_rot, lim_mm = (3 * v for v in _norms(std))
    rot, mm, factor = unfair
    if rot <= lim_rot and mm <= lim_mm:
        return None
    return (f"the closed-form solvers land a median {mm:.2f} mm / {rot:.3f} deg from X, beyond its 3 std ({lim_mm:.2f} mm / "
            f"{lim_rot:.3f} deg), but they predict held-out views {factor:.1f}x worse than X does (they read the camera's "
            "PnP poses, which these views determine less well than X's fit to the pixels): X is kept")


#: The verdicts' headlines (the report's banner); 'weak' is worded by how weak (:func:`headline`).
HEADLINES = {"good": "the data determine X well", "partial": "the motions determine only part of X",
             "degenerate": "the motions cannot determine X", "inconsistent": "the poses do not agree on one X",
             "not checked": "the data were not checked"}


def headline(cal: Calibration) -> str:
    """The verdict in a few words: for 'weak', how weak, from 3 std of X against the acceptance
    (:data:`ACCEPT_MM`, :data:`ACCEPT_DEG`): up to 2x beyond it usable with care, up to 5x poorly
    determined, beyond that not usable as it is."""
    verdict = cal.verdict
    if verdict == "inconsistent" and cal.sensor is not None:
        return "the robot poses and the measurements do not agree on one X"
    if verdict != "weak":
        return HEADLINES.get(verdict, "")
    pair = cal.sensor.figures.get("disagreeing_pair") if cal.sensor is not None else None
    if pair:  # a rig's two sensors disagree: which is wrong no number says, and more views will not tell
        return (f"check {pair['sensor']} before using X: it fits the rig {pair['ratio']:.1f}x worse than {pair['other']} "
                "(a wrong intrinsic, or a sensor that moved); the advice says how")
    if cal.std is None or not np.all(np.isfinite(cal.std)):
        return "the data leave X poorly determined"
    rot, mm = (3 * v for v in _norms(cal.std))
    beyond = max(mm / ACCEPT_MM, rot / ACCEPT_DEG)
    known = f"X known to {mm:.1f} mm / {rot:.2f} deg (3 std)"
    fixed = _fixed_cause(cal.std_sources or {})
    if fixed is not None:  # more views will not help: say what does, not "capture again"
        known += f", set by {fixed[0]}"
    if beyond <= 2:
        return (f"usable with care: {known}, a little beyond the {ACCEPT_MM:g} mm / {ACCEPT_DEG:g} deg a calibration should "
                "promise" + (f"; {fixed[1]}" if fixed else ""))
    if beyond <= 5:
        return (f"poorly determined: {known}, {beyond:.1f}x the {ACCEPT_MM:g} mm / {ACCEPT_DEG:g} deg a calibration "
                "should promise; " + (fixed[1] if fixed else "read the advice before using X"))
    return (f"not usable as it is: {known}, {beyond:.0f}x the {ACCEPT_MM:g} mm / {ACCEPT_DEG:g} deg a calibration should "
            "promise; " + (fixed[1] if fixed else "follow the advice and capture again"))


def judge(evidence: Evidence) -> Judgement:
    """The verdict on ``evidence``.

    The check's verdict stands unless it is 'good': then X's std must promise the acceptance
    (3 std within :data:`ACCEPT_MM` and :data:`ACCEPT_DEG`), and the closed forms must land within
    3 std of X; the first rule that fails makes the verdict 'weak', with its reason. Closed forms
    that predict held-out views worse than X (``unfair_spread``) and land beyond its 3 std leave a
    good verdict good, and say so.
    """
    check = evidence.check
    if check is None:
        return Judgement("not checked")
    reasons = list(check.advice)
    if check.verdict != "good" or evidence.std is None:
        return Judgement(check.verdict, reasons)
    why = _std_reason(evidence.std, evidence.std_sources or {}, check.n_poses - len(check.outliers))
    if why is None and evidence.spread is not None:
        why = _spread_reason(evidence.std, evidence.spread)
    if why is not None:
        return Judgement("weak", reasons + [why], [why])
    said = None if evidence.unfair_spread is None else _unfair_reason(evidence.std, evidence.unfair_spread)
    return Judgement("good", reasons + [said], [said]) if said else Judgement("good", reasons)


def judged(cal: Calibration, spread: tuple[float, float] | None = None,
           unfair_spread: tuple[float, float, float] | None = None) -> Calibration:
    """``cal`` with the verdict :func:`judge` gives on its evidence (its diagnostics, std,
    ``spread`` and ``unfair_spread``); the reasons a fit adds go into the advice and the notes."""
    found = judge(Evidence(cal.diagnostics, cal.std, cal.std_sources, spread, unfair_spread))
    if not found.added:
        return cal
    diag = replace(cast(Diagnostics, cal.diagnostics), verdict=found.verdict, advice=found.reasons)  # judge() needs them
    return replace(cal, diagnostics=diag, notes=list(cal.notes) + found.added)


def solver_spread(rows: list[dict], methods) -> tuple[float, float] | None:
    """The median distance (deg, mm) from X of the closed forms ``methods`` among the solver
    comparison ``rows`` (:func:`handeye.estimation.diagnostics.compare_solvers`); None when none solved."""
    solved = [r for r in rows if r["method"] in methods and "error" not in r]
    if not solved:
        return None
    return float(np.median([r["dX_deg"] for r in solved])), float(np.median([r["dX_mm"] for r in solved]))


def exit_status(verdict: str) -> int:
    """The exit status of a command that reached ``verdict`` (:data:`EXIT_STATUS`)."""
    return EXIT_STATUS[verdict]


#: A fit whose RMS residual exceeds this many times what the sensor's noise and the robot's accuracy
#: allow explains nothing: the verdict is inconsistent.
FIT_FACTOR = 5.0
#: Held-out views predicted this many times worse than the fit's residual: the verdict is inconsistent.
HELDOUT_FACTOR = 4.0


@dataclass(frozen=True)
class FitEvidence:
    """What a fit shows of the data's agreement (the estimation core measures it, :func:`fit_verdict`
    decides): ``fit_mm`` the fit's RMS residual, ``allowed_mm`` what the sensor's stated noise and the
    robot's stated accuracy allow on this capture, ``heldout_mm`` the held-out views' RMS by folds
    fitted from a start of their own and ``stepped_mm`` by steps from the fit on all views (None: no
    cross-validation), ``n_out`` of ``n`` views left out, ``errors_fitted``: each pose's error was fitted
    (the residual then holds none of the robot's error, which held-out views carry whole)."""

    fit_mm: float
    allowed_mm: float
    heldout_mm: float | None
    stepped_mm: float | None
    n_out: int
    n: int
    errors_fitted: bool = False


def fit_verdict(e: FitEvidence) -> tuple[str, list[str], float]:
    """The verdict a fit's evidence gives ('good', to be judged on X's std by :func:`judge`; 'weak' when
    only folds fitted from a start of their own predict their views badly; or 'inconsistent'), its
    advice and the consistency score (the fit's RMS over what is allowed)."""
    fit_mm, allowed, heldout_mm, stepped_mm = e.fit_mm, e.allowed_mm, e.heldout_mm, e.stepped_mm
    n_out, n = e.n_out, e.n
    score = fit_mm / max(allowed, 1e-9)
    if fit_mm > FIT_FACTOR * max(allowed, 0.05):
        return "inconsistent", [
            f"the views' measurements are {fit_mm:.2f} mm (RMS) from the fit, far beyond the {allowed:.2f} mm the "
            "sensor's noise and the robot's accuracy allow: the robot poses and the measurements disagree (their "
            "order, the pose format or unit, the setup, the measurements' unit), or the fit started in another basin and "
            "stayed there"], score
    # with each pose's error fitted the fit's residual holds none of it, while held-out views (predicted
    # from the robot alone) carry it whole: held against what the robot's accuracy allows instead
    reference = max(fit_mm, allowed) if e.errors_fitted else fit_mm
    limit = HELDOUT_FACTOR * max(reference, 0.1)
    if heldout_mm is not None and heldout_mm > limit and stepped_mm is not None and stepped_mm <= limit:
        # the fit on all views fits and predicts its views; only subsets started on their own land
        # elsewhere: a capture whose X rests on its start (few turns), not data that disagree
        return "weak", [
            f"held-out views are predicted {heldout_mm:.2f} mm (RMS) off by folds fitted from a start of their own, "
            f"{heldout_mm / reference:.1f}x the fit's {reference:.2f} mm, though the fit on all views predicts them "
            f"{stepped_mm:.2f} mm off: fewer of these views land elsewhere from their own start, so this X rests on "
            "its start; take more views, with the flange turned 10 deg or more about two or three axes, so that any "
            "subset finds the same X"], score
    if heldout_mm is not None and heldout_mm > limit:
        return "inconsistent", [
            f"held-out views are predicted {heldout_mm:.2f} mm (RMS) off, {heldout_mm / reference:.1f}x the fit's "
            f"{reference:.2f} mm: the robot poses and the measurements disagree (the setup, the pose format or unit, a "
            "target that moved, or the order of the views), or the fit lands elsewhere from another start (folds are fitted "
            "from a start of their own: more views, turned about more axes, make the fit one)"], score
    if n_out > n // 3:
        return "inconsistent", [f"{n_out} of {n} views are not explained by the fit: too many to leave out; check the "
                                "poses' format and unit, the setup, and that the target did not move"], score
    return "good", [], score


#: When this share of the views (and at least 2) agree better with another view's robot data than with
#: their own, the views and the robot's data are not paired one to one: the data are inconsistent.
MISPAIRED = 0.25


def pairing_verdict(check: Diagnostics, mispaired: int, n: int, advice: str) -> Diagnostics:
    """``check`` with the verdict 'inconsistent' and ``advice`` first when ``mispaired`` of ``n`` views
    (at least :data:`MISPAIRED` of them, and 2) agree better with another view's robot data than with
    their own; else ``check`` as it is."""
    if mispaired < max(2, MISPAIRED * n):
        return check
    return replace(check, verdict="inconsistent", advice=[advice] + list(check.advice))


def disagreement_verdict(check: Diagnostics, advice: str) -> Diagnostics:
    """``check`` with ``advice`` first and its verdict at most 'weak': two sensors of a rig disagree,
    and which one is wrong no fit can tell (the answer stands, not as good)."""
    return replace(check, verdict="weak" if check.verdict == "good" else check.verdict, advice=[advice] + list(check.advice))


# The check's rules: handeye.diagnose (handeye.estimation.diagnostics) measures the poses, these decide.

#: Fewer poses give one motion at most, which observes nothing: the verdict 'degenerate'.
MIN_POSES = 3
#: Consistency score (:func:`handeye.estimation.diagnostics.consistency_score`) up to which poses agree.
CONSISTENT = 3.0
#: The share of the poses (and at least :data:`MIN_POSES`) that must be inliers for the poses to agree.
MIN_INLIERS = 0.6
#: More than this share of the poses outliers: the rest may share their fault, the verdict at most 'weak'.
MANY_OUTLIERS = 0.2
#: Weak-data thresholds: median motion angle (deg), smallest share of the rotation-axis scatter, usable
#: poses, median distance of the target from the camera (m).
SMALL_ROTATION_DEG = 5.0
AXIS_SHARE_WEAK = 0.03
FEW_POSES = 6
FAR_TARGET_M = 1.2
#: A board scale off by more than this fraction, and by more than SCALE_SIGMAS standard deviations,
#: names the target's size (or the units) as the likely mistake.
SCALE_TOLERANCE = 0.01
SCALE_SIGMAS = 4.0


def count_verdict(n_poses: int) -> str:
    """'degenerate' for fewer than :data:`MIN_POSES` poses, else 'good' (the verdict the checks that
    follow start from)."""
    return "degenerate" if n_poses < MIN_POSES else "good"


def motion_verdict(partial_kind: str | None) -> str:
    """The verdict on motions the general solvers cannot use: 'partial' when they determine part of X
    (``partial_kind``, one axis or translations only), else 'degenerate'."""
    return "partial" if partial_kind else "degenerate"


def reading_verdict(hint: str) -> str:
    """The verdict when another reading of the inputs (``hint``: a convention, a unit, the setup) makes
    inconsistent poses consistent: 'inconsistent' (the data as given are wrong; the advice names the fix)."""
    return "inconsistent"


def agreement_verdict(consistency: float, n_inliers: int, n_poses: int) -> str | None:
    """'inconsistent' when the inliers' ``consistency`` score exceeds :data:`CONSISTENT` or fewer than
    :data:`MIN_INLIERS` of the poses (or :data:`MIN_POSES`) are inliers; None when the poses agree."""
    if consistency <= CONSISTENT and n_inliers >= max(MIN_INLIERS * n_poses, MIN_POSES):
        return None
    return "inconsistent"


def scale_is_off(scale: float, std: float) -> bool:
    """Whether a board scale (:func:`handeye.estimation.diagnostics.board_scale`) names the target's size
    as wrong: off by more than :data:`SCALE_TOLERANCE` and by more than :data:`SCALE_SIGMAS` of its std."""
    return abs(scale - 1.0) > max(SCALE_TOLERANCE, SCALE_SIGMAS * std)


def scale_verdict(off: bool, agreeing: int, subsets: int) -> str | None:
    """'inconsistent' when the board scale names the target's size as wrong (``off``) and all ``subsets``
    of the poses (each without a fold) agree (``agreeing`` of them); else None (a scale that turns on
    which poses are in is said, and makes a good verdict weak: :func:`weakened`)."""
    return "inconsistent" if off and agreeing == subsets else None


def many_outliers(n_outliers: int, n_poses: int) -> bool:
    """Whether more than :data:`MANY_OUTLIERS` of the poses are outliers (the rest may share their fault)."""
    return n_outliers > MANY_OUTLIERS * n_poses


def weak_motions(median_angle_deg: float, weakest_share: float, n_used: int, median_distance_m: float) -> list[str]:
    """The weak-data rules the capture breaks, in the order the advice gives them: 'small_rotations'
    (median motion below :data:`SMALL_ROTATION_DEG`), 'weak_axis' (an axis with less than
    :data:`AXIS_SHARE_WEAK` of the rotation), 'few_poses' (fewer than :data:`FEW_POSES` usable),
    'far_target' (beyond :data:`FAR_TARGET_M`). Any of them makes a good verdict weak."""
    rules = {"small_rotations": median_angle_deg < SMALL_ROTATION_DEG, "weak_axis": weakest_share < AXIS_SHARE_WEAK,
             "few_poses": n_used < FEW_POSES, "far_target": median_distance_m > FAR_TARGET_M}
    return [name for name, broken in rules.items() if broken]


def weakened(verdict: str, weak: bool) -> str:
    """``verdict`` made 'weak' when ``weak`` and it was 'good'; else as it is (a worse verdict stands)."""
    return "weak" if weak and verdict == "good" else verdict


def undetermined_verdict(verdict: str, undetermined: bool) -> str:
    """A fit's ``verdict`` made 'partial' when the capture leaves part of X ``undetermined`` (held at the
    start's value, its std infinite) and it was 'good'; a worse verdict stands."""
    return "partial" if undetermined and verdict == "good" else verdict


def partial_pose_verdict(check: Diagnostics | None, n_poses: int, complete: bool) -> Diagnostics:
    """The check of motions that determine part of X (one rotation axis, or translations only):
    ``check`` (unchecked: a record that says 'partial'), its 'partial' made 'good' when the known values
    complete X (``complete``: then the std judges it, as any answer's)."""
    check = check if check is not None else Diagnostics(verdict="partial", n_poses=n_poses)
    return replace(check, verdict="good") if complete and check.verdict == "partial" else check
