"""Timing shared by the benchmarks (run them from the repository root: python benchmarks/NAME.py)."""

from __future__ import annotations

import time
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
