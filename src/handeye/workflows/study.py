"""The Monte-Carlo study of the thesis's chapter 5, for every solver, batched over runs.

A *setting* fixes the number of motions, the noise on the robot and on the camera and the setup;
each setting is simulated ``runs`` times (200 in the thesis) from random scenes of the §5.2 set-up
(:func:`handeye.simulate.seed_scenes`), every solver is run on the same noisy data, and the error
of each estimate against the ground truth is measured with the metric of §5.1:

* rotation: the angle of ``R_est^T R_true`` (degrees);
* translation: ``|t_est - t_true|`` (millimetres). The thesis prints
  ``(|t~_X| + |t~_X|) / 2``, a slip for the "simple Euclidean distance" its text describes.

Statistics are reported both as the thesis did (outliers trimmed with the triangle method on a
smoothed histogram, then mean and standard deviation) and untrimmed (median, 10th and 90th
percentiles), with the acceptance rate of §5.2 (error < 5 mm and < 1 deg).

Closed-form solvers run vectorised over all runs of a setting at once
(:func:`handeye.solvers.solve_batch`); the nonlinear ones loop, and settings run in parallel
processes. Every setting draws from its own seeded generator, so the numbers depend on the seed
only, not on the number of processes or the order.
"""

from __future__ import annotations

import csv
import io
import json
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from .._shared.cluster import dask_client, dask_completed, single_threaded
from .._shared.io import atomic_write
from .._shared.processes import exit_with_parent
from .._shared.progress import Progress
from ..errors import HandEyeError, InputMismatchError
from ..frames.motions import motion_matrices, pair_indices
from ..frames.setups import check_setup, robot_world_A
from ..geometry.se3 import invert
from ..pipelines.calibration import calibrate_poses
from ..simulate import Noise, add_noise, seed_scenes
from ..solvers import available, solve_batch, solve_robot_world_batch

__all__ = ["Setting", "Figure", "SettingResult", "StudyResult", "run_setting", "study", "preset", "PRESETS",
           "triangle_threshold", "trim_outliers", "pose_errors", "write_study", "METHODS", "log_error_bars", "THESIS"]

#: Every solver the study knows: the AX = XB solvers, the robot-world ones, and ``refined``
#: (``calibrate_poses`` with the pose refinement from Daniilidis, what a handeye user gets).
METHODS = ("tsai_lenz", "park_martin", "horaud", "horaud_nonlinear", "daniilidis", "andreff", "shah", "li", "refined")
#: The thesis's acceptance limits (§5.2).
ACCEPT_MM, ACCEPT_DEG = 5.0, 1.0


@dataclass(frozen=True)
class Setting:
    """One cell of a study grid."""

    figure: str  #: the figure it belongs to, e.g. "5.4"
    series: str  #: the curve it belongs to within the figure
    x: float  #: its abscissa in that figure
    n_motions: int  #: consecutive motions, i.e. ``n_motions + 1`` poses
    robot: Noise = Noise()
    camera: Noise = Noise()
    setup: str = "eye_in_hand"
    methods: tuple[str, ...] = METHODS

    def __post_init__(self) -> None:
        object.__setattr__(self, "setup", check_setup(self.setup))
        if self.n_motions < 2:
            raise InputMismatchError(f"n_motions={self.n_motions}: AX = XB needs at least 2 motions")
        unknown = [m for m in self.methods if m not in METHODS]
        if unknown:
            raise InputMismatchError(f"unknown study method(s) {unknown}; available: {', '.join(METHODS)}")


@dataclass(frozen=True)
class Figure:
    """How a figure of the preset is drawn."""

    id: str
    title: str
    xlabel: str
    kind: str = "curve"  #: "curve" (error vs x, one line per series) or "histogram"
    log_x: bool = False
    source: tuple[str, float] | None = None  #: histogram: (series, x) of the setting it shows, in figure ``source_figure``
    source_figure: str | None = None


# --- the error metric and the statistics -------------------------------------------------------

def pose_errors(X_est: NDArray[np.float64], X_true: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per run ``[translation error (mm), rotation error (deg)]`` (thesis §5.1), shape (S, 2).

    A run without an estimate (NaN) gets ``inf`` for both.
    """
    R = np.einsum("sji,sjk->sik", X_est[:, :3, :3], X_true[:, :3, :3])  # R_est^T R_true
    cos = np.clip((np.trace(R, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    # arccos loses precision near 0: use the norm of the skew part for small angles
    sin = 0.5 * np.linalg.norm(np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], axis=1), axis=1)
    angle = np.degrees(np.arctan2(sin, cos))
    trans = 1e3 * np.linalg.norm(X_est[:, :3, 3] - X_true[:, :3, 3], axis=1)
    err = np.stack([trans, angle], axis=1)
    err[~np.isfinite(err).all(axis=1)] = np.inf
    return err


def _moving_average(counts: NDArray, window: int) -> NDArray[np.float64]:
    """Centred moving average of histogram counts, edges extended (same length as ``counts``)."""
    return np.convolve(np.pad(counts.astype(float), window // 2, mode="edge"), np.ones(window) / window, mode="valid")


def triangle_threshold(values: NDArray[np.float64], smooth: int = 5, max_bins: int = 400) -> float:
    """The triangle-method threshold of a sample of errors (thesis §5.2, footnote 1).

    A histogram of the values is smoothed with a centred moving average of ``smooth`` bins; a line
    is drawn from its peak to the farthest non-empty bin (the largest value), and the bin whose
    smoothed height lies farthest below that line gives the threshold (its upper edge). Values above
    it are outliers. The thesis does not give the bin width or the axis scaling: bins follow the
    Freedman-Diaconis rule (at most ``max_bins``) and distances are measured with both axes scaled
    to [0, 1] between the peak and the far end (Zack et al.'s construction, made independent of
    the units). Returns ``inf`` when there is nothing to cut (fewer than 10 finite values, no spread).
    """
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if len(v) < 10 or not v.max() > v.min():
        return np.inf
    lo, hi = float(v.min()), float(v.max())
    q75, q25 = np.percentile(v, [75, 25])
    width = 2.0 * (q75 - q25) / len(v) ** (1 / 3)
    bins = int(np.clip(np.ceil((hi - lo) / width) if width > 0 else max_bins, smooth, max_bins))
    counts, edges = np.histogram(v, bins=bins, range=(lo, hi))
    h = _moving_average(counts, smooth)
    peak = int(np.argmax(h))
    end = int(np.flatnonzero(counts)[-1])
    if end - peak < 2:
        return np.inf
    i = np.arange(peak, end + 1)
    xs = (i - peak) / (end - peak)
    ys = (h[peak:end + 1] - h[end]) / max(h[peak] - h[end], 1e-300)
    # distance below the line from (0, 1) to (1, 0): (1 - x - y) / sqrt(2), up to the constant
    k = int(np.argmax(1.0 - xs - ys))
    return float(edges[peak + k + 1])


def trim_outliers(err: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Runs kept by the triangle method, applied to the translation and the rotation errors alike
    (a run beyond either threshold is a wrong calibration)."""
    keep = np.isfinite(err).all(axis=1)
    for c in range(2):
        keep &= err[:, c] <= triangle_threshold(err[keep, c])
    return keep


def summarize(err: NDArray[np.float64]) -> dict[str, float]:
    """The statistics of one method in one setting (see the module docstring)."""
    keep = trim_outliers(err)
    kept = err[keep]
    out: dict[str, float] = {}
    for c, (name, unit) in enumerate((("trans", "mm"), ("rot", "deg"))):
        e = err[:, c]
        out[f"{name}_median_{unit}"] = float(np.median(e))
        out[f"{name}_p10_{unit}"] = float(np.percentile(e, 10))
        out[f"{name}_p90_{unit}"] = float(np.percentile(e, 90))
        out[f"{name}_trimmed_mean_{unit}"] = float(kept[:, c].mean()) if len(kept) else np.nan
        out[f"{name}_trimmed_std_{unit}"] = float(kept[:, c].std(ddof=1)) if len(kept) > 1 else np.nan
    out["trimmed"] = int((~keep).sum())
    out["accepted"] = float(np.mean((err[:, 0] < ACCEPT_MM) & (err[:, 1] < ACCEPT_DEG)))
    out["failed"] = int((~np.isfinite(err).all(axis=1)).sum())
    return out


# --- running one setting -----------------------------------------------------------------------

@dataclass
class SettingResult:
    """The errors of every solver over the runs of one setting of the study."""

    setting: Setting
    runs: int
    errors: dict[str, NDArray[np.float64]]  #: method -> (runs, 2) [mm, deg]
    stats: dict[str, dict[str, float]] = field(default_factory=dict)


def _motions(flange2base, target2cam, setup, pairs="consecutive"):
    """Motions ``(S, K, 4, 4)`` of every run of a batch of poses ``(S, N, 4, 4)``."""
    return motion_matrices(flange2base, target2cam, setup, pair_indices(flange2base.shape[1], pairs))


def _one_by_one(fn, runs: int) -> NDArray[np.float64]:
    X = np.full((runs, 4, 4), np.nan)
    for s in range(runs):
        try:
            X[s] = fn(s)
        except (HandEyeError, np.linalg.LinAlgError, ValueError):
            pass  # no estimate: counted as a failure
    return X


def run_setting(setting: Setting, runs: int = 200, seed: int | Sequence[int] = 0) -> SettingResult:
    """Simulate one setting ``runs`` times and run every method of it on the same data.

    ``seed`` seeds this setting's generator (the study passes ``(seed, index)``).
    """
    rng = np.random.default_rng(seed)
    scenes = seed_scenes(runs, setting.n_motions + 1, setting.setup, rng)
    flange2base = add_noise(scenes.flange2base, setting.robot, rng)
    target2cam = add_noise(scenes.target2cam, setting.camera, rng)
    A, B = _motions(flange2base, target2cam, setting.setup)
    robot_abs = robot_world_A(flange2base, setting.setup)
    cam_abs = invert(target2cam)
    errors: dict[str, NDArray[np.float64]] = {}
    for method in setting.methods:
        if method == "refined":
            def fn(s):
                return calibrate_poses(flange2base[s], target2cam[s], setting.setup, method="daniilidis",
                                       refine="pose", pairs="consecutive", check=False, uncertainty=False).X
            X = _one_by_one(fn, runs)
        elif method in available("robot_world"):
            X = solve_robot_world_batch(robot_abs, cam_abs, method)[0]
        else:
            X = solve_batch(A, B, method)
        errors[method] = pose_errors(X, scenes.X)
    result = SettingResult(setting, runs, errors)
    result.stats = {m: summarize(e) for m, e in errors.items()}
    return result


# --- the study --------------------------------------------------------------------------------

@dataclass
class StudyResult:
    """A whole study: each setting's results and the figures drawn from them."""

    settings: list[SettingResult]
    figures: dict[str, Figure]
    runs: int
    seed: int
    preset: str | None = None

    def table_rows(self) -> list[dict]:
        """One row per (setting, method) with the setting's parameters and the statistics."""
        rows = []
        for r in self.settings:
            s = r.setting
            for m, st in r.stats.items():
                rows.append({
                    "figure": s.figure, "series": s.series, "x": s.x, "setup": s.setup, "n_motions": s.n_motions,
                    "robot_rot_deg": s.robot.rot_deg, "robot_trans_mm": s.robot.trans_mm,
                    "robot_rot_bias_deg": s.robot.rot_bias_deg, "robot_trans_bias_mm": s.robot.trans_bias_mm,
                    "robot_noise_frame": s.robot.frame,
                    "camera_rot_deg": s.camera.rot_deg, "camera_trans_mm": s.camera.trans_mm,
                    "camera_rot_bias_deg": s.camera.rot_bias_deg, "camera_trans_bias_mm": s.camera.trans_bias_mm,
                    "camera_noise_frame": s.camera.frame,
                    "method": m, "runs": r.runs, **st,
                })
        return rows

    def get(self, figure: str, series: str, x: float) -> SettingResult:
        for r in self.settings:
            if r.setting.figure == figure and r.setting.series == series and np.isclose(r.setting.x, x):
                return r
        raise InputMismatchError(f"no setting {figure!r} / {series!r} / x={x} in this study")


def _clean_context():
    """Worker processes from a fork server where there is one: a child forked from a process whose
    OpenCV thread pool runs (after any detection there) hangs in its first OpenCV call."""
    return multiprocessing.get_context("forkserver") if "forkserver" in multiprocessing.get_all_start_methods() else None


def _single_threaded_blas() -> None:
    """Worker initializer: the study's arrays are small, and two processes each running a
    multi-threaded BLAS on two cores fight over them (measured: 1.3x slower overall)."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)


def _run_indexed(args):
    index, setting, runs, seed = args
    return index, run_setting(setting, runs, (seed, index))


def _run_single_threaded(args):
    """:func:`_run_indexed` on a Dask worker, with one BLAS and one OpenCV thread (as the local
    worker processes)."""
    with single_threaded():
        return _run_indexed(args)


def study(
    settings: Sequence[Setting],
    runs: int = 200,
    seed: int = 0,
    jobs: int | None = 1,
    progress: bool = True,
    figures: dict[str, Figure] | None = None,
    preset_name: str | None = None,
    scheduler: str | None = None,
) -> StudyResult:
    """Run a grid of settings.

    Parameters
    ----------
    settings : sequence of Setting
        E.g. ``preset("seed-chapter5")[0]``.
    runs : int
        Simulations per setting (the thesis: 200).
    seed : int
        Same seed, same numbers (whatever ``jobs`` is).
    jobs : int or None
        Worker processes (None: all cores); with ``scheduler='local'``, the LocalCluster's workers.
    progress : bool
        Progress bar on stderr.
    scheduler : str, optional
        Run the settings on Dask distributed (``pip install handeye[cluster]``): ``'local'`` starts a
        LocalCluster for the call, anything else is a scheduler's address (``tcp://host:8786``).
        The numbers are the same as in local processes with the same seed.
    """
    if runs < 10:
        raise InputMismatchError(f"runs={runs}: the statistics need at least 10 runs per setting")
    settings = list(settings)
    jobs = (os.cpu_count() or 1) if jobs is None else max(1, int(jobs))
    results: list[SettingResult | None] = [None] * len(settings)
    bar = Progress(len(settings), "simulating", progress)
    tasks = [(k, s, runs, seed) for k, s in enumerate(settings)]
    # the heaviest settings (refined, many motions) first keeps every worker busy to the end
    order = sorted(tasks, key=lambda t: -(("refined" in t[1].methods) * 100 + t[1].n_motions))
    try:
        if scheduler is not None:
            with dask_client(scheduler, jobs) as client:
                futures = client.map(_run_single_threaded, order, pure=False)
                for fut in dask_completed(futures):
                    k, res = fut.result()
                    results[k] = res
                    bar.update()
        elif jobs == 1:
            for t in tasks:
                k, res = _run_indexed(t)
                results[k] = res
                bar.update()
        else:
            pool_options = {"initializer": exit_with_parent, "initargs": (_single_threaded_blas,), "mp_context": _clean_context()}
            with ProcessPoolExecutor(max_workers=jobs, **pool_options) as pool:
                for fut in as_completed([pool.submit(_run_indexed, t) for t in order]):
                    k, res = fut.result()
                    results[k] = res
                    bar.update()
    finally:
        bar.close()
    return StudyResult(list(results), dict(figures or {}), runs, seed, preset_name)


# --- presets ----------------------------------------------------------------------------------

def _level(n: float) -> Noise:
    return Noise(rot_deg=n, trans_mm=n)


def _seed_chapter5(setup: str = "eye_in_hand") -> tuple[list[Setting], dict[str, Figure]]:
    closed = ("tsai_lenz", "park_martin", "horaud", "horaud_nonlinear", "daniilidis", "andreff", "shah", "li")
    motions = [2, 3, 4, 5, 6, 8, 10, 15, 20]
    levels = [0.1, 0.25, 0.5, 1.0, 2.0]
    S: list[Setting] = []

    def add(fig, series, x, n, robot=Noise(), camera=Noise(), methods=closed):
        S.append(Setting(fig, series, float(x), n, robot, camera, setup, tuple(methods)))

    for n in motions:
        add("5.1", "no noise", n, n)
        add("5.1", "robot 0.3 mm / 0.3 deg", n, n, robot=_level(0.3))
        add("5.3", "robot 0.5 mm / 0.5 deg", n, n, robot=_level(0.5))
        add("5.3", "robot 1 mm / 1 deg", n, n, robot=_level(1.0))
    for lv in [0.1, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0]:
        # the pose refinement costs ~30 ms a run: on four of the levels only (the preset's time budget)
        add("5.4", "robot only", lv, 15, robot=_level(lv), methods=METHODS if lv in (0.1, 0.3, 1.0, 2.0) else closed)
    for lv in levels:
        add("5.5", "robot only", lv, 15, robot=_level(lv))
        add("5.5", "camera only", lv, 15, camera=_level(lv))
        add("5.5", "both", lv, 15, robot=_level(lv), camera=_level(lv))
        for fixed in (0.1, 0.5, 1.0):
            add("5.6", f"camera {fixed:g} mm / {fixed:g} deg", lv, 15, robot=_level(lv), camera=_level(fixed))
    for rot in (0.1, 0.5, 1.0):
        for tr in [0.1, 0.5, 1.0, 2.0, 5.0, 10.0]:
            add("5.7", f"robot rotation {rot:g} deg", tr, 15, robot=Noise(rot_deg=rot, trans_mm=tr))
    for frame, label in (("reference", "bias in the base frame"), ("local", "bias in the flange frame")):
        for bias in [0.0, 1.0, 2.0, 5.0, 10.0]:
            add("S", label, bias, 15, robot=Noise(rot_deg=0.1, trans_mm=0.1, trans_bias_mm=bias, frame=frame))
    figures = {
        "5.1": Figure("5.1", "Error vs number of motions, no noise and robot noise 0.3 mm / 0.3 deg",
                      "number of motions"),
        "5.2": Figure("5.2", "Triangle-method outlier removal: 3 motions, robot noise 0.3 mm / 0.3 deg",
                      "translation error (mm)", kind="histogram", source=("robot 0.3 mm / 0.3 deg", 3.0),
                      source_figure="5.1"),
        "5.3": Figure("5.3", "Error vs number of motions, larger robot noise", "number of motions"),
        "5.4": Figure("5.4", "Error vs noise level (robot, mm and deg alike), 15 motions",
                      "robot noise sigma (mm and deg)"),
        "5.5": Figure("5.5", "Noise on the robot, the camera or both, 15 motions", "noise sigma (mm and deg)"),
        "5.6": Figure("5.6", "Robot noise growing with the camera noise fixed, 15 motions",
                      "robot noise sigma (mm and deg)"),
        "5.7": Figure("5.7", "Translation noise vs rotation noise (robot), 15 motions",
                      "robot translation noise sigma (mm)", log_x=True),
        "S": Figure("S", "Systematic robot translation error (sigma 0.1 mm / 0.1 deg plus a bias), 15 motions",
                    "bias per component (mm)"),
    }
    return S, figures


PRESETS = {"seed-chapter5": _seed_chapter5}


def preset(name: str, setup: str = "eye_in_hand") -> tuple[list[Setting], dict[str, Figure]]:
    """The settings and figures of a named study (``seed-chapter5``: the thesis's chapter 5)."""
    if name not in PRESETS:
        raise InputMismatchError(f"unknown study preset {name!r}; available: {', '.join(PRESETS)}")
    return PRESETS[name](setup)


# --- output -----------------------------------------------------------------------------------

def _fmt(v: float) -> str:
    if not np.isfinite(v):
        return "inf" if v > 0 else "nan"
    if 0 < abs(v) < 1e-9:  # rounding error of an exact solve: its digits say nothing
        return "<1e-9"
    return f"{v:.3g}" if abs(v) >= 1e-3 or v == 0 else f"{v:.1e}"


def markdown_table(result: StudyResult, methods: Sequence[str] | None = None) -> str:
    """Per figure, three narrow markdown tables: each method's median error, its 10th-90th
    percentiles, and the runs the triangle method trimmed with the share accepted."""
    lines = [f"# Simulation study ({result.preset or 'custom'}): {result.runs} runs per setting, seed {result.seed}", "",
             "Errors: translation mm / rotation deg (thesis §5.1). trimmed = runs removed by the triangle method; "
             f"ok = share of runs under {ACCEPT_MM:g} mm and {ACCEPT_DEG:g} deg.", ""]
    by_fig: dict[str, list[SettingResult]] = {}
    for r in result.settings:
        by_fig.setdefault(r.setting.figure, []).append(r)
    tables = (
        ("median, mm / deg", lambda st: f"{_fmt(st['trans_median_mm'])} / {_fmt(st['rot_median_deg'])}"),
        ("10th-90th percentile, mm / deg", lambda st: f"{_fmt(st['trans_p10_mm'])}-{_fmt(st['trans_p90_mm'])} / "
                                                      f"{_fmt(st['rot_p10_deg'])}-{_fmt(st['rot_p90_deg'])}"),
        ("trimmed runs, ok", lambda st: f"{st['trimmed']}, {100 * st['accepted']:.0f}%"),
    )
    for fig, rs in by_fig.items():
        title = result.figures[fig].title if fig in result.figures else fig
        meths = [m for m in (methods or METHODS) if any(m in r.stats for r in rs)]
        lines += [f"## Figure {fig}: {title}", ""]
        for caption, cell in tables:
            lines += [f"{caption}:", "", "| series | x | " + " | ".join(meths) + " |", "|---|---|" + "---|" * len(meths)]
            for r in rs:
                cells = ["" if r.stats.get(m) is None else cell(r.stats[m]) for m in meths]
                lines.append(f"| {r.setting.series} | {r.setting.x:g} | " + " | ".join(cells) + " |")
            lines.append("")
    return "\n".join(lines)


#: What the thesis states in numbers for its Daniilidis runs (§5.3): per (figure, series, x), the
#: statistic and its translation (mm) / rotation (deg) error.
THESIS = {
    ("5.1", "no noise", 2.0): (("median", 31.3, 2.45), ("p10", 3.98, 0.379)),
    ("5.3", "robot 1 mm / 1 deg", 15.0): (("p10", 12.9, 1.84),),
    ("5.4", "robot only", 1.0): (("p10", 12.9, 1.84),),
}


def _thesis_text(key: tuple[str, str, float], own: dict[str, float] | None) -> str:
    """The thesis's stated numbers for a setting beside ours (daniilidis), or ''."""
    stated = THESIS.get(key)
    if not stated or own is None:
        return ""
    return "; thesis " + ", ".join(f"{stat} {mm:g} / {deg:g} (ours {_fmt(own[f'trans_{stat}_mm'])} / "
                                   f"{_fmt(own[f'rot_{stat}_deg'])})" for stat, mm, deg in stated)


def headline(result: StudyResult, method: str = "daniilidis") -> str:
    """The study for a terminal: per figure a table of every solver's median error of X per setting
    (translation mm / rotation deg), the share of runs under 5 mm and 1 deg for ``method`` (the
    thesis's choice) and the best solver there, and where the thesis states a number
    (:data:`THESIS`) it beside ours; study.md has the percentiles too."""
    lines = [f"median error of X per solver, translation mm / rotation deg (ok = share of {method}'s runs under "
             f"{ACCEPT_MM:g} mm and {ACCEPT_DEG:g} deg; best = the solver with the smallest median)"]
    by_fig: dict[str, list[SettingResult]] = {}
    for r in result.settings:
        by_fig.setdefault(r.setting.figure, []).append(r)
    for fig, rs in by_fig.items():
        title = result.figures[fig].title if fig in result.figures else fig
        methods = [m for m in METHODS if any(m in r.stats for r in rs)]
        lines.append(f"Figure {fig}: {title}")
        lines.append(f"  {'setting':<30} " + " ".join(f"{m[:11]:>11}" for m in methods))
        for r in rs:
            if not r.stats:
                continue
            best = min(r.stats, key=lambda m: (r.stats[m]["trans_median_mm"], r.stats[m]["rot_median_deg"]))
            cells = " ".join(f"{'' if r.stats.get(m) is None else _cell(r.stats[m]):>11}" for m in methods)
            own = r.stats.get(method)
            ok = "" if own is None else f" ok {100 * own['accepted']:.0f}%"
            thesis = _thesis_text((fig, r.setting.series, r.setting.x), r.stats.get("daniilidis"))
            lines.append(f"  {r.setting.series:<22.22} x={r.setting.x:<5g} {cells}{ok}; best {best}{thesis}")
    return "\n".join(lines)


def _cell(stats: dict[str, float]) -> str:
    """A solver's median translation / rotation error in a few characters."""
    return f"{_fmt(stats['trans_median_mm'])}/{_fmt(stats['rot_median_deg'])}"


def log_error_bars(mean: NDArray[np.float64], std: NDArray[np.float64]) -> NDArray[np.float64]:
    """``yerr`` (2, n) for mean +- std on a logarithmic axis: a lower end at or below zero, which the
    axis cannot show (matplotlib draws it to minus infinity), is cut at a tenth of the mean."""
    mean, std = np.asarray(mean, float), np.asarray(std, float)
    lower = np.where(mean - std > 0, std, 0.9 * mean)
    return np.stack([lower, std])


def _plot(result: StudyResult, fig_id: str, path: Path) -> None:
    from matplotlib.figure import Figure  # off-screen, no pyplot: no backend chosen for the user

    spec = result.figures[fig_id]
    if spec.kind == "histogram":
        series, x = spec.source
        r = result.get(spec.source_figure, series, x)
        e = r.errors["daniilidis"][:, 0]
        e = e[np.isfinite(e)]
        thr = triangle_threshold(e)
        fig = Figure(figsize=(13, 3.6))
        axes = fig.subplots(1, 3)
        cap = np.percentile(e, 97)
        bins = np.linspace(0, cap, 60)
        axes[0].hist(e[e <= cap], bins=bins, color="0.5")
        axes[0].set_title(f"(a) Daniilidis, {len(e)} runs ({int((e > cap).sum())} beyond the axis, max {e.max():.0f} mm)",
                          fontsize=9)
        counts, edges = np.histogram(e[e <= cap], bins=bins)
        h = _moving_average(counts, 5)
        axes[1].plot(0.5 * (edges[1:] + edges[:-1]), h, color="k")
        axes[1].axvline(thr, color="r", ls="--", label=f"triangle threshold {thr:.1f} mm")
        axes[1].set_title("(b) moving average, threshold", fontsize=9)
        axes[1].legend(fontsize=8)
        kept = e[e <= thr]
        axes[2].hist(kept, bins=40, color="0.3")
        axes[2].set_title(f"(c) after removing {len(e) - len(kept)} outliers", fontsize=9)
        for ax in axes:
            ax.set_xlabel(spec.xlabel)
        fig.suptitle(f"Figure {fig_id}: {spec.title}", fontsize=10)
        fig.tight_layout()
    else:
        rs = [r for r in result.settings if r.setting.figure == fig_id]
        series = list(dict.fromkeys(r.setting.series for r in rs))
        fig = Figure(figsize=(12, 8))
        axes = fig.subplots(2, 2)
        for c, (unit, label) in enumerate((("mm", "translation error (mm)"), ("deg", "rotation error (deg)"))):
            name = "trans" if c == 0 else "rot"
            ax = axes[0, c]
            for sname in series:
                pts = sorted((r.setting.x, r.stats["daniilidis"]) for r in rs if r.setting.series == sname)
                xs = np.array([p[0] for p in pts])
                mean = np.array([p[1][f"{name}_trimmed_mean_{unit}"] for p in pts])
                std = np.array([p[1][f"{name}_trimmed_std_{unit}"] for p in pts])
                ax.errorbar(xs, mean, yerr=log_error_bars(mean, std), marker="o", ms=3, capsize=3, label=sname)
            ax.set_title("Daniilidis (the thesis's method): trimmed mean +- std (a bar below zero: cut at mean/10)",
                         fontsize=9)
            ax.set_ylabel(label)
            ax = axes[1, c]
            first = series[0]
            for m in METHODS:
                pts = sorted((r.setting.x, r.stats[m]) for r in rs if r.setting.series == first and m in r.stats)
                if not pts:
                    continue
                ax.plot([p[0] for p in pts], [p[1][f"{name}_median_{unit}"] for p in pts], marker="o", ms=3, label=m)
            ax.set_title(f"every solver, median ({first})", fontsize=9)
            ax.set_ylabel(label)
            for a in (axes[0, c], axes[1, c]):
                a.set_xlabel(spec.xlabel)
                a.set_yscale("log")
                if spec.log_x:
                    a.set_xscale("log")
                a.grid(True, which="both", alpha=0.3)
        axes[0, 0].legend(fontsize=8)
        axes[1, 0].legend(fontsize=7, ncol=2)
        fig.suptitle(f"Figure {fig_id}: {spec.title}", fontsize=10)
        fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    atomic_write(path, buf.getvalue())


def write_study(result: StudyResult, out_dir: str | Path, plots: bool = True) -> list[Path]:
    """Write ``study.csv`` (one row per setting and method), ``study.md`` (tables per figure),
    ``study.json`` (the same rows plus run parameters) and one PNG per figure; returns the paths.
    Files are written atomically; an existing ``out_dir`` is reused, other files in it untouched."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputMismatchError(f"--out {out} exists and is not a folder")
    rows = result.table_rows()
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    written = []
    for name, data in (
        ("study.csv", buf.getvalue()),
        ("study.md", markdown_table(result)),
        ("study.json", json.dumps({"preset": result.preset, "runs": result.runs, "seed": result.seed,
                                   "figures": {k: asdict(v) for k, v in result.figures.items()},
                                   "rows": [{k: (v if not isinstance(v, float) or np.isfinite(v) else None)
                                             for k, v in row.items()} for row in rows]}, indent=1)),
    ):
        atomic_write(out / name, data)
        written.append(out / name)
    if plots:
        for fig_id in result.figures:
            p = out / f"fig{fig_id.replace('.', '_')}.png"
            _plot(result, fig_id, p)
            written.append(p)
    return written
