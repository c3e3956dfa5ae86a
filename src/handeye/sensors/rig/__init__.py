"""A rig's mathematics: several sensors on one robot fitted as one sensor model (:mod:`~handeye.sensors.rig.model`).
Everything else of a rig (its session, pipeline, simulator) is :mod:`handeye.pipelines.rig`."""

from __future__ import annotations

from .model import DifferentiableRig, Rig

__all__ = ["Rig", "DifferentiableRig"]
