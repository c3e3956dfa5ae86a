"""Frames and conventions: what eye-in-hand and eye-to-hand mean (:mod:`~handeye.frames.setups`), the
robot pose formats controllers write (:mod:`~handeye.frames.poses`), relative motions and their screw
congruence (:mod:`~handeye.frames.motions`), and errors between transforms (:mod:`~handeye.frames.metrics`)."""
