"""Shared fixtures and helpers for the handeye test suite."""

from __future__ import annotations

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


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
