"""Timing shared by the benchmarks (run them from the repository root: python benchmarks/NAME.py)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path
from typing import Callable

import numpy as np


def best_time(fn: Callable[[], object], repeat: int, warmup: bool = True) -> float:
    """Best wall time of ``repeat`` calls (the least disturbed by the machine), in seconds."""
    if warmup:
        fn()
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def calibrate_seconds(folder: Path, out: Path) -> tuple[float, int]:
    """Wall time of the whole command ``handeye calibrate FOLDER --out OUT`` in a new process (what a
    user waits for, start-up included), and its exit status (0 good, 1 weak, 2 refused or inconsistent:
    a verdict, said beside the time, not a failure of the benchmark)."""
    t = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "handeye.cli", "calibrate", str(folder), "--out", str(out)],
                          capture_output=True)
    return time.perf_counter() - t, done.returncode
