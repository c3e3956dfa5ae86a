"""Exceptions raised by handeye.

Every error says what is wrong, where, and what to do about it. They all derive from
:class:`HandEyeError`, so a caller (and the CLI) can catch one type.
"""

from __future__ import annotations

__all__ = ["HandEyeError", "PoseFormatError", "DegenerateMotionError", "InputMismatchError", "SessionError", "UnusableViewError",
           "TargetError"]


class HandEyeError(Exception):
    """Base class of every error handeye raises on purpose."""


class PoseFormatError(HandEyeError, ValueError):
    """Pose values that cannot be read in the declared format (shape, NaN, non-unit, ...)."""


class InputMismatchError(HandEyeError, ValueError):
    """Inputs that do not fit together (different counts, wrong shapes, unknown setup)."""


class DegenerateMotionError(HandEyeError):
    """The robot motions do not determine the unknown transform (parallel axes, no rotation).

    ``diagnostics``: the check's findings when the check raised it (None otherwise).
    """

    def __init__(self, *args: object, diagnostics: object = None) -> None:
        super().__init__(*args)
        self.diagnostics = diagnostics


class SessionError(HandEyeError):
    """A capture folder that cannot be read: missing files or keys, malformed tables."""


class UnusableViewError(SessionError):
    """One view's file holds nothing to measure (empty, binary or corrupt, no point with a depth, an
    array of no cloud's shape): a session's pipeline skips that view and names it, as it skips an
    image without the target; read on its own, the file is refused."""


class TargetError(HandEyeError):
    """A target description that cannot be used (unknown type, bad size, unknown dictionary)."""
