"""Old import paths of modules that moved, kept working for one release with a DeprecationWarning.

``import handeye.pipelines.calibration`` (and ``from handeye.pipelines.calibration import calibrate``) finds a stand-in
module whose names are looked up, on first use, in the modules that now hold them; the warning says
where to import from instead. Nothing is copied: the stand-in forwards every name.

A package that stays but whose names moved (``from handeye.simulate import laser_scene``, the laser's
simulator now in its kind's folder; ``handeye.pipelines.laser``, once a module, now the laser's folder)
forwards them the same way: its ``__getattr__`` is :func:`forward_names`, and the table of what went
where is :func:`install`'s ``names``.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import types
import warnings
from typing import Any

__all__ = ["install", "moved_module", "forward_names"]


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


#: Per package that stays, the names that left it and the module that holds each now (``install``'s ``names``).
_MOVED_NAMES: dict[str, dict[str, str]] = {}


def install(table: dict[str, tuple[str, ...]], names: dict[str, dict[str, str]] | None = None) -> None:
    """Make the old paths of ``table`` (old name -> the modules that now hold its names) importable,
    and the names of ``names`` (package -> {name: the module that now holds it}) found from the
    packages they left (each package's ``__getattr__`` is :func:`forward_names`)."""
    _MOVED_NAMES.update(names or {})
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.insert(0, _Finder(table))


def forward_names(package: str):
    """A module ``__getattr__`` for ``package``: a name that moved out of it comes from its new module,
    with a DeprecationWarning naming that module; any other missing name is an AttributeError."""

    def __getattr__(name: str) -> Any:
        moved = _MOVED_NAMES.get(package, {})
        target = moved.get(name)
        if target is None and "*" in moved and not name.startswith("__") and hasattr(importlib.import_module(moved["*"]), name):
            target = moved["*"]  # a module that became a folder: every name of the module it became
        if target is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        warnings.warn(f"{package}.{name} has moved: import it from {target} (the old path goes in the next release)",
                      DeprecationWarning, stacklevel=2)
        return getattr(importlib.import_module(target), name)

    return __getattr__
