"""Another tool's markerless capture as a silhouette session (``handeye import easyhec``, this kind's
registration's ``imports``): EasyHeC's colour images, masks and joint angles.

Examples
--------
>>> from handeye.pipelines.kinds import importer_of
>>> importer_of("easyhec") is import_easyhec
True
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from ..._shared.io import atomic_write
from ...errors import HandEyeError
from ...io.importers import ImportSummary, new_folder
from ...io.session import SESSION_FILE
from ...robot.kinematics import load_arm

__all__ = ["import_easyhec"]


def _easyhec_files(folder: Path, sub: str, suffix: str) -> dict[str, Path]:
    found = {p.stem: p for p in sorted((folder / sub).glob(f"*{suffix}"))} if (folder / sub).is_dir() else {}
    if not found:
        raise HandEyeError(f"{folder / sub}: no {suffix} files; EasyHeC's layout is color/, mask/, qpos/ and K.txt")
    return found


def import_easyhec(folder: str | Path, out: str | Path, arm: str = "panda") -> ImportSummary:
    """EasyHeC's markerless capture (``color/NNNNNN.png``, ``mask/NNNNNN.png``, ``qpos/NNNNNN.txt``: the
    arm's joint angles in radians, then its fingers', ``K.txt``) as a silhouette session (masks/,
    images/, joints.csv, session.yaml with ``silhouette:``); the fingers' joints give the hand's opening."""
    folder = Path(folder)
    masks, qpos = _easyhec_files(folder, "mask", ".png"), _easyhec_files(folder, "qpos", ".txt")
    colour = {p.stem: p for p in sorted((folder / "color").glob("*.png"))} if (folder / "color").is_dir() else {}
    missing = sorted(set(qpos) ^ set(masks))
    if missing:
        raise HandEyeError(f"{folder}: {', '.join(missing[:5])} has a mask or joint angles but not both (mask/, qpos/)")
    chain = load_arm(arm)
    K = np.loadtxt(folder / "K.txt") if (folder / "K.txt").is_file() else None
    if K is None or K.shape != (3, 3):
        raise HandEyeError(f"{folder / 'K.txt'}: missing or not a 3x3 camera matrix")
    rows, opening = [], []
    for stem in sorted(qpos):
        q = np.loadtxt(qpos[stem], ndmin=1)
        if len(q) < chain.n_joints:
            raise HandEyeError(f"{qpos[stem]}: {len(q)} joint angles; {chain.name} has {chain.n_joints}")
        rows.append(f"{masks[stem].name}," + ",".join(f"{v:.12g}" for v in q[:chain.n_joints]))
        opening.append(float(np.sum(q[chain.n_joints:chain.n_joints + 2])))
    target = new_folder(out, [folder])
    for sub, files in (("masks", masks), ("images", colour)):
        if files:
            (target / sub).mkdir(parents=True, exist_ok=True)
        for p in files.values():
            atomic_write(target / sub / p.name, p.read_bytes())
    atomic_write(target / "joints.csv", "\n".join(["image," + ",".join(f"q{j + 1}" for j in range(chain.n_joints))] + rows) + "\n")
    spec = {"setup": "eye_to_hand", "target": {"type": "robot", "finger_opening": round(float(np.median(opening)), 6)},
            "camera": {"K": K.tolist()}, "silhouette": {"masks": "masks"},
            "joints": {"file": "joints.csv", "unit": "rad", "arm": arm}}
    atomic_write(target / SESSION_FILE, yaml.safe_dump(spec, sort_keys=False))
    notes = [] if np.ptp(opening) < 1e-3 else [f"the fingers' opening varies ({min(opening):.3f}-{max(opening):.3f} m): the "
                                               "session uses the median for every view"]
    return ImportSummary(target, "silhouette session", len(rows), len(rows), notes)
