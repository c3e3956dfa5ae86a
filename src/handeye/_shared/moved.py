"""Old import paths of modules that moved, kept working for one release with a DeprecationWarning.

``import handeye.pipelines.calibration`` (and ``from handeye.pipelines.calibration import calibrate``) finds a stand-in
module whose names are looked up, on first use, in the modules that now hold them; the warning says
where to import from instead. Nothing is copied: the stand-in forwards every name.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import types
import warnings
from typing import Any

__all__ = ["install", "moved_module"]


class _Forward(types.ModuleType):
    """A stand-in for a moved module: its names come from ``targets``, first match."""

    def __init__(self, name: str, targets: tuple[str, ...]) -> None:
        super().__init__(name, f"Moved: import from {' or '.join(targets)}.")
        self.__path__: list[str] = []  # a package, so that old submodule paths import too
        self._targets = targets

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        for target in self._targets:
            module = importlib.import_module(target)
            if hasattr(module, name):
                return getattr(module, name)
        raise AttributeError(f"module {self.__name__!r} (moved to {' or '.join(self._targets)}) has no attribute {name!r}")

    def __dir__(self) -> list[str]:
        return sorted({n for t in self._targets for n in dir(importlib.import_module(t))})


def moved_module(name: str, targets: tuple[str, ...]) -> types.ModuleType:
    """The stand-in module for the old path ``name`` (its warning given)."""
    warnings.warn(f"{name} has moved: import from {' or '.join(targets)} (the old path goes in the next release)",
                  DeprecationWarning, stacklevel=3)
    return _Forward(name, targets)


class _Finder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    def __init__(self, table: dict[str, tuple[str, ...]]) -> None:
        self.table = table

    def find_spec(self, fullname, path=None, target=None):  # noqa: D102 (importlib's protocol)
        if fullname not in self.table:
            return None
        return importlib.machinery.ModuleSpec(fullname, self, is_package=True)

    def create_module(self, spec):  # noqa: D102
        return moved_module(spec.name, self.table[spec.name])

    def exec_module(self, module):  # noqa: D102
        pass


def install(table: dict[str, tuple[str, ...]]) -> None:
    """Make the old paths of ``table`` (old name -> the modules that now hold its names) importable."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.insert(0, _Finder(table))
