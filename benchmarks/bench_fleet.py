"""A fleet: 50 rendered sessions through :func:`handeye.workflows.fleet.calibrate_many` on a 2-worker Dask
LocalCluster, against the plain sequential loop over the same folders (goal: <= 0.6x its wall time, issue 81),
with the same results.

    python benchmarks/bench_fleet.py [--sessions 50] [--workers 2]

Each session: 12 rendered 640x480 images of a 9x6 chessboard, K given, both setups alternating.
Sequential loop: ``handeye.calibrate(folder)`` then ``write_calibration`` per folder, in this
process, detection on all cores (its default). Dask: ``calibrate_many(..., scheduler='local',
jobs=workers)``, the cluster's start-up and shutdown included. The local processes of
``calibrate_many`` without Dask are timed too. No detection cache (``HANDEYE_CACHE_DIR`` empty): every
run detects. The X of every session must agree across the three to 1e-9.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

import handeye
from handeye.simulate import simulate_session
from handeye.workflows.fleet import calibrate_many

GOAL = 0.6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sessions", type=int, default=50)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    os.environ["HANDEYE_CACHE_DIR"] = ""
    root = Path(tempfile.mkdtemp(prefix="handeye-bench-fleet-"))
    try:
        folders = []
        for k in range(args.sessions):
            folder = root / "sessions" / f"cell{k:02d}"
            simulate_session(folder, ("eye_in_hand", "eye_to_hand")[k % 2], 12, "chessboard", seed=100 + k)
            folders.append(folder)
        print(f"{args.sessions} sessions rendered; {os.cpu_count()} cores, {args.workers} workers")

        start = time.perf_counter()
        loop = {}
        for folder in folders:
            cal = handeye.calibrate(folder, progress=False)
            handeye.write_calibration(cal, root / "loop" / folder.name)
            loop[folder.name] = cal.X
        t_loop = time.perf_counter() - start

        times, Xs = {}, {}
        for name, scheduler in (("local processes", None), ("Dask LocalCluster", "local")):
            out = root / name.split()[0]
            start = time.perf_counter()
            items = calibrate_many(folders, out, scheduler=scheduler, jobs=args.workers, progress=False)
            times[name] = time.perf_counter() - start
            assert all(it.error is None for it in items), [it.error for it in items if it.error]
            Xs[name] = {Path(it.session).name: np.array(json.loads((Path(it.out) / "result.json").read_text())["X"]["matrix"])
                        for it in items}
    finally:
        shutil.rmtree(root, ignore_errors=True)
    print(f"  sequential loop (calibrate + write, detection on all cores): {t_loop:7.2f} s")
    for name, t in times.items():
        diff = max(np.abs(Xs[name][k] - loop[k]).max() for k in loop)
        goal = f" (goal <= {GOAL}: {'met' if t / t_loop <= GOAL else 'NOT met'})" if "Dask" in name else ""
        print(f"  calibrate_many, {name:<18} {t:7.2f} s  {t / t_loop:.2f}x the loop{goal}; "
              f"X differs from the loop's by at most {diff:.1e}")


if __name__ == "__main__":
    main()
