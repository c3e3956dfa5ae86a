"""Shared fixtures and helpers for the handeye test suite."""

from __future__ import annotations

import os

# One BLAS thread per process, set before NumPy loads: the tests' matrices are small, and the
# suite's process pools and OpenCV's threads already use both cores; a second BLAS thread per
# process only adds contention (measured: tests/test_uncertainty.py 74 -> 66 s on 2 cores).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402

#: Real captures made by others live beside the repository (../shared/data/real), never copied in.
REAL_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"


def require_real(*parts: str) -> Path:
    """Path under ../shared/data/real, or skip the test (with the reason) when it is absent."""
    path = REAL_DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"real data not available at {path}")
    return path


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
