"""Writing output files atomically (no half-written files, never over the user's inputs), and
digests of inputs for the result files."""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path
from typing import Iterable

import numpy as np

from ..errors import HandEyeError


def atomic_write(path: str | Path, data: str | bytes, protect: Iterable[str | Path] = ()) -> None:
    """Write ``data`` (text as UTF-8, or bytes) to ``path`` through a temporary file and a rename.

    Refuses to write over any of the ``protect`` paths (the user's inputs). The file gets the
    permissions a plain ``open`` would give (``mkstemp`` alone makes it private, 0600).
    """
    path = Path(path)
    target = path.resolve()
    for p in protect:
        if Path(p).resolve() == target:
            raise HandEyeError(f"refusing to overwrite the input file {p}; choose another output folder")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.fchmod(fd, 0o666 & ~umask)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data.encode("utf-8") if isinstance(data, str) else data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def array_digest(*arrays: np.ndarray) -> str:
    """SHA-256 over the little-endian float64 bytes of ``arrays``, in order."""
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a, dtype="<f8").tobytes())
    return h.hexdigest()


def files_digest(paths: list[Path], root: Path) -> str:
    """SHA-256 over the names (relative to ``root``) and bytes of ``paths``, in the order given."""
    h = hashlib.sha256()
    for p in paths:
        h.update(str(Path(p).relative_to(root)).encode("utf-8") + b"\0")
        with open(p, "rb") as fh:
            for chunk in iter(lambda: fh.read(1 << 20), b""):
                h.update(chunk)
    return h.hexdigest()
