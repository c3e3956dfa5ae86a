"""From images to target poses: targets, parallel detection, intrinsics, PnP."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .detect import ImageResult, detect_images
from .targets import Detection, Target, register_target, target_from_spec, target_origin, target_types

# PnP and the intrinsics need scipy: they load on first use, so that detection (which does not) can
# start while the rest of handeye loads
_PNP = ("calibrate_intrinsics", "label_doubts", "resolve_symmetries", "settled_symmetry_costs", "solve_pnp",
        "symmetry_costs")

if TYPE_CHECKING:
    from .pnp import calibrate_intrinsics, label_doubts, resolve_symmetries, settled_symmetry_costs, solve_pnp, symmetry_costs


def __getattr__(name: str) -> Any:
    if name not in _PNP:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.pnp"), name)


__all__ = [
    "Detection",
    "ImageResult",
    "Target",
    "calibrate_intrinsics",
    "detect_images",
    "resolve_symmetries",
    "symmetry_costs",
    "settled_symmetry_costs",
    "label_doubts",
    "solve_pnp",
    "target_from_spec",
    "target_origin",
    "target_types",
    "register_target",
]
