"""The browser tests' skips: where chromium is installed, ``.ci/run`` sets ``HANDEYE_REQUIRE_BROWSER=1`` and
the browser tests then run or fail, never skip (a missing selenium, aiohttp or driver is a red run, not a
quiet skip: issue 80's "the browser test passes on every landing")."""

from __future__ import annotations

import importlib
import os
from types import ModuleType

import pytest

REQUIRED = os.environ.get("HANDEYE_REQUIRE_BROWSER") == "1"


def importorskip(name: str, reason: str) -> ModuleType:
    """``pytest.importorskip(name)``, or the plain import when the browser tests are required."""
    return importlib.import_module(name) if REQUIRED else pytest.importorskip(name, reason=reason)


def skip_unless(present: bool, reason: str) -> pytest.MarkDecorator:
    """``skipif(not present)``, unless the browser tests are required (then they run, and fail without it)."""
    return pytest.mark.skipif(not present and not REQUIRED, reason=reason)
