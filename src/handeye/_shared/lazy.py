"""Heavy optional-at-import dependencies (OpenCV), loaded on first use.

``import handeye`` must stay quick: every CLI call pays it, and most of the library (solvers,
diagnostics, the study) never touches an image. Modules that call OpenCV bind ``cv2 =
lazy_module("cv2")`` and use it as the module itself.
"""

from __future__ import annotations

import importlib
from types import ModuleType
from typing import Any


class LazyModule:
    """A stand-in for a module that imports it on the first attribute access."""

    def __init__(self, name: str) -> None:
        self._name = name
        self._module: ModuleType | None = None

    def __getattr__(self, attr: str) -> Any:
        # only reached for attributes not set in __init__
        if self._module is None:
            self._module = importlib.import_module(self._name)
            if self._name in _ON_LOAD:
                _ON_LOAD[self._name](self._module)
        return getattr(self._module, attr)

    def __repr__(self) -> str:
        return f"<lazy module {self._name!r}{' (loaded)' if self._module is not None else ''}>"


def _quiet_opencv(cv2: ModuleType) -> None:
    """OpenCV's own warnings off (``[ WARN:0@...] imread_(...): can't open/read file``): handeye says
    in its own words which file it skipped and why; OpenCV's errors still show."""
    try:
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
    except AttributeError:  # a build without the logging utilities: nothing to quiet
        pass


#: What to do with a module once it is loaded.
_ON_LOAD = {"cv2": _quiet_opencv}


def lazy_module(name: str) -> LazyModule:
    """``name`` imported on first use (see the module docstring)."""
    return LazyModule(name)
