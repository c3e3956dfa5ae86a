"""The optional extras a session needs, and how to name them all at once before anything is read.

A session reads its files one by one, and each reader asks for its own extra when its package is
missing: a mesh target's session with ``.ply`` clouds asked for ``mesh``, then, installed, for
``depth``. :func:`handeye.pipelines.folders.session_extras` says from session.yaml and the names of
the files it points at what the whole session needs, each kind of sensor adding its own through the
helpers here (a mesh: ``mesh``; ``.ply`` or ``.pcd`` clouds: ``depth``; the arm itself as the target,
or its silhouette: ``markerless``; a URDF as the arm: ``urdf``), and
:func:`handeye.pipelines.folders.check_extras` refuses a session whose extras are not all installed,
with one ``pip install`` line that names every one (:func:`refuse_missing`).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from typing import Any

from .._shared.moved import forward_names
from ..errors import SessionError

__all__ = ["EXTRA_MODULES", "CLOUD_MODULES", "MESH_MODULES", "cloud_extras", "mesh_extras", "arm_extras", "needed",
           "missing", "refuse_missing"]

#: Per extra (pyproject.toml's optional dependencies) the modules a session's files are read with.
EXTRA_MODULES = {"mesh": ("trimesh",), "depth": ("plyfile", "pypcd4"), "markerless": ("trimesh", "rtbdata"),
                 "urdf": ("yourdfpy",)}
#: The module a file of each suffix is read with, and its extra: a cloud (``.ply``, ``.pcd``) or a mesh.
CLOUD_MODULES = {".ply": ("plyfile", "depth"), ".pcd": ("pypcd4", "depth")}
MESH_MODULES = {".stl": ("trimesh", "mesh"), ".obj": ("trimesh", "mesh"), ".ply": ("trimesh", "mesh"),
                ".off": ("trimesh", "mesh"), ".pcd": ("pypcd4", "depth")}


def _suffixes(folder: Path) -> set[str]:
    """The suffixes of the files in ``folder`` (none when it is not one)."""
    try:
        return {p.suffix.lower() for p in folder.iterdir()} if folder.is_dir() else set()
    except OSError:
        return set()


def cloud_extras(folder: Path, where: str, needs: dict[str, dict[str, str]]) -> None:
    """Add to ``needs`` the readers of the clouds in ``folder`` (``.ply``, ``.pcd``; ``where``: the folder in words)."""
    for suffix in sorted(_suffixes(folder)):
        if suffix in CLOUD_MODULES:
            module, extra = CLOUD_MODULES[suffix]
            needs.setdefault(extra, {})[module] = f"{suffix} clouds in {where}"


def mesh_extras(target: dict[str, Any], needs: dict[str, dict[str, str]]) -> None:
    """Add to ``needs`` the reader of a mesh target's file (``target``: its ``target:`` mapping)."""
    suffix = Path(str(target.get("file", ""))).suffix.lower()
    if suffix in MESH_MODULES:
        module, extra = MESH_MODULES[suffix]
        needs.setdefault(extra, {})[module] = f"the mesh target {target.get('file')}"


def needed(extra: str, why: str, needs: dict[str, dict[str, str]]) -> None:
    """Add to ``needs`` every module of ``extra`` (:data:`EXTRA_MODULES`), for ``why``."""
    needs[extra] = {m: why for m in EXTRA_MODULES[extra]}


def arm_extras(spec: Any, needs: dict[str, dict[str, str]]) -> None:
    """Add to ``needs`` the URDF reader when a ``joints:`` block's arm is a URDF."""
    arm = spec.get("arm") if isinstance(spec, dict) else None
    if isinstance(arm, str) and arm.lower().endswith(".urdf"):
        needs.setdefault("urdf", {})["yourdfpy"] = f"the arm's URDF {arm}"


def _installed(module: str) -> bool:
    if module in sys.modules:
        return sys.modules[module] is not None
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def missing(needs: dict[str, dict[str, str]]) -> dict[str, dict[str, str]]:
    """Of ``needs`` (extra -> {module: why}), the modules that are not installed."""
    out = {}
    for extra, modules in needs.items():
        gone = {m: why for m, why in modules.items() if not _installed(m)}
        if gone:
            out[extra] = gone
    return out


def refuse_missing(folder: str | Path, gone: dict[str, dict[str, str]]) -> None:
    """Refuse the session in ``folder`` when ``gone`` (:func:`missing`) names any module.

    Raises
    ------
    SessionError
        What is missing, what of the session needs it, and the one command that installs it all.
    """
    if gone:
        what = "; ".join(f"{m} ({why})" for modules in gone.values() for m, why in modules.items())
        raise SessionError(f"{folder}: this session needs {what}: pip install 'handeye[{','.join(sorted(gone))}]'")


__getattr__ = forward_names(__name__)  # session_extras, missing_extras and check_extras: now pipelines.folders'
