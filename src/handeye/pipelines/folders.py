"""A folder calibrated the one way, whichever command asked: :func:`calibrate_folder` and
:func:`check_folder`.

``check`` used to run the pose check alone and could call data good that ``calibrate`` then called
weak (a std of tens of millimetres, which only a fit shows). Now both run the same pipeline with
the same :class:`~handeye.options.CalibrationOptions`, and the verdict comes from
:mod:`handeye.estimation.verdict` for both: ``check`` prints the evidence (the pose table, the held-out errors)
and the verdict; ``calibrate`` prints and writes the result.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from .._shared.lazy import lazy_module
from ..errors import DegenerateMotionError, HandEyeError
from ..estimation.validation import default_folds
from ..estimation.verdict import exit_status
from ..io.extras import arm_extras, missing, refuse_missing
from ..io.session import POSEPAIRS_FILE, SESSION_FILE, PosePairs, load_pose_pairs, load_session, load_yaml
from ..options import CalibrationOptions, options_from
from ..result import Calibration, Diagnostics
from .calibration import calibrate, calibrate_poses
from .kinds import session_kind

# The pipelines of joint angles and of streams, loaded when such a folder comes (a kind of sensor's
# pipeline loads through its registration's hook, when a session of that kind comes).
_joints = lazy_module("handeye.pipelines.joints")
_streams = lazy_module("handeye.pipelines.streams")

__all__ = ["FolderCheck", "calibrate_folder", "calibrate_pairs", "calibrate_session", "check_folder", "session_extras",
           "missing_extras", "check_extras"]


def calibrate_folder(folder: str | Path, options: CalibrationOptions | None = None, *, jobs: int | None = None,
                     progress: bool = True, **changes) -> Calibration:
    """Any folder handeye reads, to one :class:`~handeye.result.Calibration`: a capture session
    (:func:`calibrate_session`: images, a depth camera's clouds, with or without joint angles), or
    :func:`calibrate_pairs` on a pose-pair folder (``posepairs.yaml``).

    Examples
    --------
    >>> import tempfile
    >>> from handeye.simulate import simulate_session
    >>> folder = tempfile.mkdtemp() + "/s"
    >>> scene = simulate_session(folder, setup="eye_in_hand", n_poses=8, seed=2)
    >>> cal = calibrate_folder(folder, progress=False)
    >>> cal.verdict in ("good", "weak"), cal.X.shape
    (True, (4, 4))
    """
    opts = options_from(options, changes)
    folder = Path(folder)
    if not (folder / POSEPAIRS_FILE).is_file():
        return calibrate_session(folder, opts, jobs=jobs, progress=progress)
    return calibrate_pairs(load_pose_pairs(folder), opts, progress=progress)


def calibrate_session(folder: str | Path, options: CalibrationOptions | None = None, *, jobs: int | None = None,
                      progress: bool = True, **changes) -> Calibration:
    """:func:`handeye.calibrate` on a capture session of images; when its ``session.yaml`` has a
    ``joints:`` table, :func:`handeye.pipelines.joints.calibrate_joint_session` (the arm's table
    fitted with X); a session of another kind of sensor (its section: ``depth:``, ``laser:``,
    ``linescan:``, ``silhouette:``, a rig's ``sensors:``), that kind's pipeline
    (:mod:`handeye.pipelines.kinds`: the ``calibrate`` hook of its registration)."""
    opts = options_from(options, changes)
    folder = Path(folder)
    check_extras(folder)  # every optional extra the session needs, named at once (a mesh and .ply clouds: mesh,depth)
    spec = _session_spec(folder)
    kind = session_kind(spec)
    if kind is not None:
        return kind.hook("calibrate")(folder, opts, progress=progress, jobs=jobs)
    if opts.arm is not None or spec.get("joints") is not None:
        session = load_session(folder, strict_images=opts.strict_images, arm=opts.arm)
        return _joints.calibrate_joint_session(session, opts, jobs=jobs, progress=progress)
    return calibrate(folder, opts, jobs=jobs, progress=progress)


def _session_spec(folder: Path) -> dict:
    """The folder's session.yaml as a mapping, read once to tell the kinds of session apart (its
    ``depth:``, ``laser:``, ... section: :func:`handeye.pipelines.kinds.session_kind`); empty when there
    is none or it cannot be read (the session's reader then says why)."""
    if not (folder / SESSION_FILE).is_file():
        return {}
    try:
        spec = load_yaml(folder / SESSION_FILE)
    except HandEyeError:
        return {}
    return spec if isinstance(spec, dict) else {}


def session_extras(folder: str | Path) -> dict[str, dict[str, str]]:
    """Per extra the modules the session in ``folder`` needs and why (in words), from its
    session.yaml and the suffixes of the files it points at (its kind's ``extras`` hook, and a URDF
    as the arm); empty when it needs none, or when its description cannot be read (its reader then
    says why).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (folder / "session.yaml").write_text("depth: {unit: m}\\ntarget: {type: mesh, file: flange.stl, unit: mm}\\n")
    >>> (folder / "clouds").mkdir(); _ = (folder / "clouds" / "v01.ply").write_bytes(b"")
    >>> sorted(session_extras(folder))
    ['depth', 'mesh']
    """
    folder = Path(folder)
    spec = _session_spec(folder)
    needs: dict[str, dict[str, str]] = {}
    kind = session_kind(spec)
    if kind is not None and kind.extras is not None:
        kind.hook("extras")(spec, folder, needs)
    arm_extras(spec.get("joints"), needs)
    return needs


def missing_extras(folder: str | Path) -> dict[str, dict[str, str]]:
    """:func:`session_extras` of the modules that are not installed."""
    return missing(session_extras(folder))


def check_extras(folder: str | Path) -> None:
    """Refuse, before anything is read, a session whose optional extras are not all installed,
    naming every one in one ``pip install`` line (:func:`session_extras`).

    Raises
    ------
    SessionError
        What is missing, what of the session needs it, and the one command that installs it all.
    """
    refuse_missing(folder, missing_extras(folder))


def calibrate_pairs(pairs: PosePairs, options: CalibrationOptions | None = None, *, progress: bool = True,
                    **changes) -> Calibration:
    """:func:`handeye.calibrate_poses` on pose pairs as read from their files
    (:func:`handeye.calibrate_streams` when they are two time-stamped streams), with the files'
    notes first and, for streams, a note when the pairing the files imply disagrees with the clock
    offset found."""
    opts = options_from(options, changes)
    if pairs.is_stream:
        cal = _streams.calibrate_streams(pairs.robot_times, pairs.flange2base, pairs.camera_times, pairs.target2cam,
                                pairs.setup, opts, robot_input=pairs.robot_input)
        warning = _streams.paired_delay_note(pairs.paired_delays, cal.time_offset, cal.time_offset_std)
        notes = list(pairs.notes) + ([warning] if warning else [])
    else:
        cal = calibrate_poses(pairs.flange2base, pairs.target2cam, pairs.setup, opts, robot_input=pairs.robot_input,
                              camera_input=pairs.camera_input, names=[str(i) for i in pairs.ids], progress=progress)
        notes = list(pairs.notes)
    return replace(cal, notes=notes + list(cal.notes), input_folder=pairs.source)


@dataclass(frozen=True)
class FolderCheck:
    """What :func:`check_folder` found: the calibration ``calibrate`` would make (None when the data
    cannot determine X), the diagnostics with the verdict, and the images that gave no pose."""

    diagnostics: Diagnostics
    calibration: Calibration | None = None
    skipped: list[tuple[str, str]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    folds: int | None = None

    @property
    def verdict(self) -> str:
        """The verdict, as ``calibrate`` gives it (:mod:`handeye.estimation.verdict`)."""
        return self.diagnostics.verdict

    @property
    def exit_status(self) -> int:
        """``check``'s exit status, the same as ``calibrate``'s on the same data."""
        return exit_status(self.verdict)

    @property
    def names(self) -> list[str]:
        """The name of each pose checked (its image file, or its row id)."""
        d = self.diagnostics
        return list(d.names) if d.names else [str(i) for i in range(d.n_poses)]

    def cross_validation_table(self) -> str:
        """The estimators' held-out errors, best first, for people."""
        cal = self.calibration
        if cal is None or not cal.cross_validation:
            return "held-out prediction error: not computed (fewer than 5 usable poses, or X not fully determined)"
        table = cal.cross_validation
        rows = sorted(table.items(), key=lambda kv: kv[1]["px"] if kv[1]["px"] is not None else kv[1]["mm"])
        if cal.sensor is not None:
            lines = [f"held-out prediction error ({cal.cross_validation.folds}-fold cross-validation; each view's "
                     f"measurements predicted from its robot {'joint angles' if cal.kinematic is not None else 'pose'} by "
                     "the fit to the others, beside the closed-form start refitted the same way):"]
        elif cal.kinematic is not None:
            lines = [f"held-out prediction error ({self.folds}-fold cross-validation; each view predicted from its joint "
                     "angles by X, Z and the arm's table fitted without it, beside the closed-form start and the fit on "
                     "the nominal table's flange poses refitted the same way):"]
        else:
            lines = [f"held-out prediction error ({self.folds}-fold cross-validation; each view predicted from its robot "
                     "pose by X and Z fitted without it; the preferred refinement is replaced only by a candidate better "
                     "by more than one standard error, so the one used need not have the smallest error):"]
        width = max([24] + [len(name) for name, _ in rows])
        for name, r in rows:
            px = f"{r['px']:8.3f} px" if r.get("px") is not None else "           "
            lines.append(f"  {name:<{width}} {px} {r['mm']:8.3f} mm at the target" + ("   <- chosen" if name == cal.estimator
                                                                                       else ""))
        return "\n".join(lines)


def check_folder(folder: str | Path, options: CalibrationOptions | None = None, *, jobs: int | None = None,
                 progress: bool = True, **changes) -> FolderCheck:
    """What ``calibrate`` would say about a session or pose-pair folder, before using its result:
    the diagnostics (pose table, outliers, conventions), the held-out prediction error of every
    estimator ``calibrate`` chooses from, and the same verdict (:func:`calibrate_folder` with the
    same ``options``). Data that cannot determine X get the check's 'degenerate' verdict and its
    advice instead of an error.

    Examples
    --------
    >>> import handeye
    >>> from importlib.resources import files
    >>> found = handeye.check_folder(files("handeye") / "data" / "example_posepairs", progress=False)
    >>> found.verdict, found.exit_status
    ('good', 0)
    """
    opts = options_from(options, changes)
    try:
        cal = calibrate_folder(folder, opts, jobs=jobs, progress=progress)
    except DegenerateMotionError as exc:
        if exc.diagnostics is None:  # not the check's finding (e.g. too few images): the error is the answer
            raise
        return FolderCheck(exc.diagnostics)
    diag = cal.diagnostics if cal.diagnostics is not None else Diagnostics(verdict="not checked")
    kept = diag.n_poses - len(diag.outliers)
    folds = None if kept < 4 else (default_folds(kept) if opts.folds is None else min(opts.folds, kept))
    return FolderCheck(diag, cal, list(cal.skipped), list(cal.notes), folds)
