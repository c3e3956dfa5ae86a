"""Rigid-body geometry: batched SE(3) helpers and dual quaternions."""

from . import se3
from .dualquat import DualQuaternion

__all__ = ["se3", "DualQuaternion"]
