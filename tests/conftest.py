"""Shared fixtures and helpers for the handeye test suite."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import cv2  # noqa: F401  (loaded before the BLAS limit below: OpenCV brings an OpenBLAS of its own)
import numpy as np
import pytest
import scipy.linalg  # noqa: F401  (SciPy's OpenBLAS, another than NumPy's, loaded before the limit)
from threadpoolctl import threadpool_limits

#: Real captures made by others live beside the repository (../shared/data/real), never copied in.
REAL_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"


def require_real(*parts: str) -> Path:
    """Path under ../shared/data/real, or skip the test (with the reason) when it is absent."""
    path = REAL_DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"real data not available at {path}")
    return path


@pytest.fixture(scope="session", autouse=True)
def _detection_cache():
    """Detections are cached for this run only, in a folder removed at its end (never the user's
    cache folder): the sample session's images, detected by many tests, are detected once."""
    before = os.environ.get("HANDEYE_CACHE_DIR")
    with tempfile.TemporaryDirectory(prefix="handeye-test-cache-") as folder:
        os.environ["HANDEYE_CACHE_DIR"] = folder
        yield
    if before is None:
        os.environ.pop("HANDEYE_CACHE_DIR", None)
    else:
        os.environ["HANDEYE_CACHE_DIR"] = before


@pytest.fixture(scope="session", autouse=True)
def _one_blas_thread():
    """BLAS on one thread in every test process, as the pipelines run their estimations
    (handeye._shared.threads) and as realdata.worker_pool's workers do: with ``-n 2`` two processes
    each running OpenBLAS's two threads on 2 cores spin more than they work. Measured: a laser
    start (core._start, called directly by tests/test_captures.py) 2.0 -> 0.25 s CPU, X the same to
    the last digit. Tests of the thread settings themselves set theirs inside."""
    with threadpool_limits(1, user_api="blas"):
        yield


@pytest.fixture
def no_detection_cache(monkeypatch):
    """Detection runs on every image (tests comparing detection modes, or timing it)."""
    monkeypatch.setenv("HANDEYE_CACHE_DIR", "")


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
