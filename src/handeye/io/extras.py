"""The optional extras a session needs, named all at once before anything is read (:func:`check_extras`).

A session reads its files one by one, and each reader asks for its own extra when its package is
missing: a mesh target's session with ``.ply`` clouds asked for ``mesh``, then, installed, for
``depth``. :func:`session_extras` says from session.yaml and the names of the files it points at
what the whole session needs (a mesh: ``mesh``; ``.ply`` or ``.pcd`` clouds: ``depth``; the arm
itself as the target, or its silhouette: ``markerless``; a URDF as the arm: ``urdf``), and
:func:`check_extras` refuses a session whose extras are not all installed, with one ``pip install``
line that names every one.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from typing import Any

from ..errors import HandEyeError, SessionError
from .session import SESSION_FILE, load_yaml

__all__ = ["EXTRA_MODULES", "session_extras", "missing_extras", "check_extras"]

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


def _clouds(folder: Path, where: str, needs: dict[str, dict[str, str]]) -> None:
    for suffix in sorted(_suffixes(folder)):
        if suffix in CLOUD_MODULES:
            module, extra = CLOUD_MODULES[suffix]
            needs.setdefault(extra, {})[module] = f"{suffix} clouds in {where}"


def _arm(spec: Any, needs: dict[str, dict[str, str]]) -> None:
    """A ``joints:`` block whose arm is a URDF."""
    arm = spec.get("arm") if isinstance(spec, dict) else None
    if isinstance(arm, str) and arm.lower().endswith(".urdf"):
        needs.setdefault("urdf", {})["yourdfpy"] = f"the arm's URDF {arm}"


def session_extras(folder: str | Path) -> dict[str, dict[str, str]]:
    """Per extra the modules the session in ``folder`` needs and why (in words), from its
    session.yaml and the suffixes of the files it points at; empty when it needs none, or when its
    description cannot be read (its reader then says why).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (folder / "session.yaml").write_text("depth: {unit: m}\\ntarget: {type: mesh, file: flange.stl, unit: mm}\\n")
    >>> (folder / "clouds").mkdir(); _ = (folder / "clouds" / "v01.ply").write_bytes(b"")
    >>> sorted(session_extras(folder))
    ['depth', 'mesh']
    """
    folder = Path(folder)
    try:
        spec = load_yaml(folder / SESSION_FILE)
    except HandEyeError:
        return {}
    needs: dict[str, dict[str, str]] = {}
    target = spec.get("target") if isinstance(spec.get("target"), dict) else {}
    kind = str(target.get("type", ""))
    if spec.get("depth") is not None:
        if kind == "mesh":
            suffix = Path(str(target.get("file", ""))).suffix.lower()
            if suffix in MESH_MODULES:
                module, extra = MESH_MODULES[suffix]
                needs.setdefault(extra, {})[module] = f"the mesh target {target.get('file')}"
        elif kind == "arm":
            needs["markerless"] = {m: "the arm itself as the target (its link meshes)" for m in EXTRA_MODULES["markerless"]}
        _clouds(folder / "clouds", "clouds/", needs)
    if spec.get("silhouette") is not None:
        needs["markerless"] = {m: "the arm's silhouette (its link meshes)" for m in EXTRA_MODULES["markerless"]}
    sensors = spec.get("sensors")
    if isinstance(sensors, dict):  # a rig: each depth camera's clouds
        for name, block in sensors.items():
            if isinstance(block, dict) and block.get("depth") is not None:
                _clouds(folder / str(block.get("clouds", name)), f"{block.get('clouds', name)}/ (sensor {name})", needs)
    _arm(spec.get("joints"), needs)
    return needs


def _installed(module: str) -> bool:
    if module in sys.modules:
        return sys.modules[module] is not None
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def missing_extras(folder: str | Path) -> dict[str, dict[str, str]]:
    """:func:`session_extras` of the modules that are not installed."""
    out = {}
    for extra, modules in session_extras(folder).items():
        gone = {m: why for m, why in modules.items() if not _installed(m)}
        if gone:
            out[extra] = gone
    return out


def check_extras(folder: str | Path) -> None:
    """Refuse, before anything is read, a session whose optional extras are not all installed,
    naming every one in one ``pip install`` line (:func:`session_extras`).

    Raises
    ------
    SessionError
        What is missing, what of the session needs it, and the one command that installs it all.
    """
    missing = missing_extras(folder)
    if missing:
        what = "; ".join(f"{m} ({why})" for modules in missing.values() for m, why in modules.items())
        raise SessionError(f"{folder}: this session needs {what}: pip install 'handeye[{','.join(sorted(missing))}]'")
