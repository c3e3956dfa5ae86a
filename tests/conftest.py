"""Shared fixtures and helpers for the handeye test suite."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import pytest

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


@pytest.fixture
def no_detection_cache(monkeypatch):
    """Detection runs on every image (tests comparing detection modes, or timing it)."""
    monkeypatch.setenv("HANDEYE_CACHE_DIR", "")


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
