"""The installed version of handeye (``0+unknown`` when run from a source tree)."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("handeye")
except PackageNotFoundError:  # running from a source tree
    __version__ = "0+unknown"
