"""From images to target poses: targets, parallel detection, intrinsics, PnP."""

from .detect import ImageResult, detect_images
from .pnp import ambiguous_labels, calibrate_intrinsics, resolve_symmetries, solve_pnp, unmatched_labels
from .targets import TARGET_TYPES, Detection, Target, target_from_spec

__all__ = [
    "Detection",
    "ImageResult",
    "TARGET_TYPES",
    "Target",
    "calibrate_intrinsics",
    "detect_images",
    "resolve_symmetries",
    "ambiguous_labels",
    "unmatched_labels",
    "solve_pnp",
    "target_from_spec",
]
