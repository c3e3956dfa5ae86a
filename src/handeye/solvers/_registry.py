"""The solver registry: every solver family registers its functions here under one signature.

``AX = XB`` solvers take a :class:`~handeye.frames.motions.MotionSet` of validated motions and return
``X``; robot-world solvers take absolute stacks ``(N, 4, 4)`` with ``A_i X = Z B_i`` and return
``(X, Z)``. Every solver is vectorised over leading (run) axes of its inputs, ``(S, K, ...)`` in,
one result per run out: :func:`handeye.solve_batch` relies on it, and a single problem is a batch
of one.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Literal

from ..errors import InputMismatchError

Kind = Literal["hand_eye", "robot_world"]


@dataclass(frozen=True)
class SolverInfo:
    """A registered solver: its name, kind, function and the paper/seed section it implements."""

    name: str
    kind: Kind
    func: Callable
    reference: str
    #: the optional extra it needs (``pip install handeye[extra]``), or None; such solvers run only
    #: when asked for by name (not among the candidates of ``refine='auto'`` or the solver comparison)
    extra: str | None = None


_REGISTRY: dict[str, SolverInfo] = {}


def register(name: str, kind: Kind = "hand_eye", reference: str = "", extra: str | None = None) -> Callable[[Callable], Callable]:
    """Decorator that registers a solver function under ``name`` (see the module docstring)."""

    def deco(func: Callable) -> Callable:
        if name in _REGISTRY:
            raise InputMismatchError(f"solver {name!r} registered twice: give the new one another name")
        _REGISTRY[name] = SolverInfo(name, kind, func, reference, extra)
        return func

    return deco


def available(kind: Kind | None = None, closed_forms: bool = False) -> list[str]:
    """Names of the registered solvers (of one kind when given), sorted; ``closed_forms``: only
    those that need no optional extra (the candidates and the comparison of a calibration)."""
    return sorted(n for n, s in _REGISTRY.items()
                  if (kind is None or s.kind == kind) and not (closed_forms and s.extra))


def get(name: str, kind: Kind | None = None) -> SolverInfo:
    """The registered solver ``name``; a clear error lists the valid names otherwise."""
    info = _REGISTRY.get(name)
    if info is None or (kind is not None and info.kind != kind):
        names = ", ".join(available(kind))
        what = {"hand_eye": "AX = XB solver", "robot_world": "robot-world solver", None: "solver"}[kind]
        hint = ""
        if info is not None and info.kind == "robot_world":
            hint = f" ({name!r} solves A_i X = Z B_i: use solve_robot_world)"
        elif info is not None:
            hint = f" ({name!r} solves AX = XB: use solve)"
        raise InputMismatchError(f"unknown {what} {name!r}{hint}; available: {names}")
    return info
