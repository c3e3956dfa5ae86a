"""From images to target poses: targets, parallel detection, intrinsics, PnP."""

from .detect import ImageResult, detect_images
from .pnp import calibrate_intrinsics, label_doubts, resolve_symmetries, solve_pnp, symmetry_costs
from .targets import Detection, Target, register_target, target_from_spec, target_origin, target_types

__all__ = [
    "Detection",
    "ImageResult",
    "Target",
    "calibrate_intrinsics",
    "detect_images",
    "resolve_symmetries",
    "symmetry_costs",
    "label_doubts",
    "solve_pnp",
    "target_from_spec",
    "target_origin",
    "target_types",
    "register_target",
]
