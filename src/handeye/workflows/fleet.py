"""Many sessions at once: a fleet of cells recalibrated nightly, in local processes or on Dask.

:func:`calibrate_many` calibrates each session folder as ``handeye calibrate`` does and writes its
files into ``out_dir/<session name>/``; a session that fails (a bad folder, poses that cannot
determine X) is reported with its error and does not stop the others. The work runs in local
worker processes, or on Dask distributed with ``scheduler`` ('local' for a LocalCluster, or a
scheduler's address; ``pip install 'handeye[cluster]'``): the same calibration either way.
"""

from __future__ import annotations

import json
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Sequence

from .._shared.cluster import dask_client, dask_completed, single_threaded
from .._shared.io import atomic_write, check_output_folder
from .._shared.processes import exit_with_parent
from .._shared.progress import Progress
from ..errors import HandEyeError
from ..pipelines.calibration import certify_calibration
from ..pipelines.folders import calibrate_session
from ..report import write_calibration

__all__ = ["FleetItem", "calibrate_many"]


@dataclass(frozen=True)
class FleetItem:
    """One session of :func:`calibrate_many`: where it was, what came of it."""

    session: str
    out: str | None  #: the folder its files went into (None when it failed)
    verdict: str | None  #: the check's verdict, or None when it failed
    translation_mm: list[float] | None  #: X's translation (mm), for a glance across the fleet
    std_mm: list[float] | None  #: X's translation std (mm)
    error: str | None = None  #: why it failed


def _one(task: tuple[str, str, dict, dict, bool]) -> dict:
    """Calibrate one session and write its files (runs in a worker: plain values in and out)."""
    folder, out, options, write_options, certify = task
    try:
        cal = calibrate_session(folder, progress=False, jobs=1, **options)  # joint sessions: the joint fit
        if certify:
            cal = certify_calibration(cal)
        write_calibration(cal, out, **write_options)
    except HandEyeError as exc:
        return asdict(FleetItem(folder, None, None, None, None, str(exc)))
    return asdict(FleetItem(folder, out, cal.verdict, [1e3 * float(v) for v in cal.X[:3, 3]],
                            None if cal.std is None else [float(v) for v in cal.std[3:]]))


def _one_beside_others(task: tuple[str, str, dict, dict, bool]) -> dict:
    """:func:`_one` in a worker process beside others: the sessions side by side use the cores, not
    threads within one."""
    with single_threaded():
        return _one(task)


def _names(folders: Sequence[Path]) -> list[str]:
    """An output name per session: its folder name, made unique with its parent's when two clash."""
    names = [f.name or "session" for f in folders]
    return [f"{f.parent.name}-{n}" if names.count(n) > 1 else n for f, n in zip(folders, names)]


def calibrate_many(folders: Sequence[str | Path], out_dir: str | Path, scheduler: str | None = None,
                   jobs: int | None = None, progress: bool = True, write_options: dict | None = None,
                   certify: bool = False, **options: Any) -> list[FleetItem]:
    """Calibrate every session in ``folders``; each one's files go to ``out_dir/<name>/`` and a
    summary to ``out_dir/fleet.json``.

    Parameters
    ----------
    folders : sequence of paths
        Session folders (images + robot poses).
    scheduler : str, optional
        Dask: 'local' (a LocalCluster of ``jobs`` workers) or a scheduler's address; default local
        worker processes.
    jobs : int, optional
        Worker processes (default: the cores).
    write_options : dict, optional
        :func:`handeye.write_calibration`'s options for every session (frames, exports, tool).
    certify : bool
        Certify each calibration (:func:`handeye.certify_calibration`; ``handeye[certifiable]``).
    options
        :func:`handeye.calibrate`'s options (method, refine, robot_accuracy, ...).

    Returns
    -------
    list of FleetItem
        In the order of ``folders``.
    """
    folders = [Path(f) for f in folders]
    if not folders:
        raise HandEyeError("no session folders given")
    out = check_output_folder(out_dir, folders)
    tasks = [(str(f), str(out / name), dict(options), dict(write_options or {}), certify)
             for f, name in zip(folders, _names(folders))]
    jobs = (os.cpu_count() or 1) if jobs is None else max(1, int(jobs))
    results: list[dict | None] = [None] * len(tasks)
    bar = Progress(len(tasks), "calibrating sessions", progress)
    try:
        if scheduler is not None:
            with dask_client(scheduler, jobs) as client:
                futures = client.map(_one_beside_others, tasks, pure=False)
                index = {f.key: k for k, f in enumerate(futures)}
                for fut in dask_completed(futures):
                    results[index[fut.key]] = fut.result()
                    bar.update()
        elif jobs == 1 or len(tasks) == 1:
            for k, t in enumerate(tasks):
                results[k] = _one(t)
                bar.update()
        else:  # a fork server: a child forked after OpenCV's threads ran in this process would hang
            context = multiprocessing.get_context("forkserver") if "forkserver" in multiprocessing.get_all_start_methods() else None
            with ProcessPoolExecutor(max_workers=min(jobs, len(tasks)), mp_context=context, initializer=exit_with_parent) as pool:
                for k, r in enumerate(pool.map(_one_beside_others, tasks)):
                    results[k] = r
                    bar.update()
    finally:
        bar.close()
    items = [FleetItem(**r) for r in results]
    atomic_write(out / "fleet.json", json.dumps([asdict(i) for i in items], indent=2) + "\n")
    return items
