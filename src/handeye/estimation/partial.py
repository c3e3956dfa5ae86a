"""Calibration when the robot cannot rotate freely (SCARA, planar, 4-axis, Cartesian robots).

The thesis names it as future work (§6.1: a calibration that stays accurate with planar motions
only). With every rotation about one axis, ``A X = X B`` determines X except its translation along
that axis; with pure translations, X's rotation only (:mod:`handeye.solvers.low_dof`). What the
data cannot see, the user may know: the camera's offset from a drawing (``cam2flange.z``), the
board's height on the table (``target2base.z``). :func:`calibrate_partial` refines the
determined part on the poses (the noise-model refinement of :func:`handeye.estimation.refinement.refine_pose`),
with each known value as one more measurement, and names what stays open.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from typing import cast

import numpy as np
from numpy.typing import NDArray

from ..errors import InputMismatchError
from ..frames.metrics import std_deg_mm
from ..frames.motions import MotionSet, Pairs
from ..frames.setups import constant_transforms, robot_world_A, setup_info
from ..geometry.se3 import mean_transform
from ..result import Calibration, Observability, Unobservable
from ..solvers.low_dof import GAUGE_STD, ONE_AXIS, TRANSLATION_ONLY, gauge_rows, solve_low_dof
from ..solvers.refine import TranslationPriors
from .refinement import refine_pose

__all__ = ["KNOWN_EXACT_STD", "Known", "calibrate_partial", "known_on_complete", "parse_known"]

#: A known value given without a std is taken as exact to this (m).
KNOWN_EXACT_STD = 1e-6
#: A known value fixes an undetermined direction when its axis is within ~70 deg of it (|cos| above this).
MIN_COUPLING = 0.35
#: A translation component of X whose axis is within this cosine of an undetermined direction gets an infinite std.
_OPEN_COMPONENT = 1e-3


@dataclass(frozen=True)
class Known:
    """One value given with ``known=``: a translation component of X or Z, metres."""

    name: str  #: as given, e.g. "target2base.z"
    of_x: bool  #: a component of X (else of Z)
    axis: int  #: 0, 1, 2 for x, y, z
    value: float
    std: float

    @property
    def row(self) -> NDArray[np.float64]:
        """The measurement over ``[t_X, t_Z]``."""
        g = np.zeros(6)
        g[self.axis + (0 if self.of_x else 3)] = 1.0
        return g


_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def _known_value(name: str, given) -> tuple[float, float]:
    if isinstance(given, str):
        m = re.fullmatch(rf"\s*({_NUMBER})\s*(?:(?:\+-|\+/-|±)\s*({_NUMBER}))?\s*", given)
        if not m:
            raise InputMismatchError(f"known {name}={given!r}: give metres, e.g. 0.012 or 0.012+-0.001")
        value, std = float(m.group(1)), float(m.group(2)) if m.group(2) else KNOWN_EXACT_STD
    elif isinstance(given, (tuple, list)) and len(given) == 2:
        value, std = (float(v) for v in given)
    else:
        try:
            value, std = float(given), KNOWN_EXACT_STD
        except (TypeError, ValueError):
            raise InputMismatchError(f"known {name}={given!r}: give metres, e.g. 0.012, (0.012, 0.001) or "
                                     "'0.012+-0.001'") from None
    if not (np.isfinite(value) and np.isfinite(std) and std >= 0):
        raise InputMismatchError(f"known {name}: value {value!r} +- {std!r}: give a finite value and a non-negative std")
    if abs(value) > 10:
        raise InputMismatchError(f"known {name}={value:g}: {value:g} m is beyond any robot cell; give metres "
                                 f"({value / 1000:g} if that was mm)")
    return value, max(std, KNOWN_EXACT_STD)


def parse_known(known: dict | None, setup: str) -> list[Known]:
    """The ``known=`` values checked: keys ``<transform>.<x|y|z>`` with the transform named after the
    setup's X or Z (``cam2flange``/``target2base`` eye-in-hand, ``cam2base``/``target2flange``
    eye-to-hand), values in metres: a number (exact), ``(value, std)`` or ``"value+-std"``."""
    if not known:
        return []
    info = setup_info(setup)
    out = []
    for name, given in dict(known).items():
        m = re.fullmatch(r"\s*(\w+)\.([xyzXYZ])\s*", str(name))
        transform = m.group(1) if m else None
        if m is None or transform not in (info.x_name, info.z_name):
            hint = ""
            other = setup_info("eye_to_hand" if info.camera_on_flange else "eye_in_hand")
            if transform in (other.x_name, other.z_name):
                hint = f" ({transform} belongs to {other.name}; this is {setup})"
            raise InputMismatchError(
                f"known {name!r}{hint}: name a translation component of {info.x_name} or {info.z_name}, e.g. "
                f"'{info.x_name}.z' or '{info.z_name}.z' (metres, along that frame's axis)")
        value, std = _known_value(str(name), given)
        out.append(Known(f"{transform}.{m.group(2).lower()}", transform == info.x_name, "xyz".index(m.group(2).lower()),
                         value, std))
    return out


def _frame_words(direction: NDArray[np.float64], frame: str) -> str:
    k = int(np.argmax(np.abs(direction)))
    if abs(direction[k]) > np.cos(np.radians(5.0)):
        return f"the {frame} {'xyz'[k]} axis"
    return f"the {frame} direction {np.array2string(direction, precision=3, suppress_small=True)}"


def _z_frame(setup: str) -> str:
    return "base" if setup_info(setup).camera_on_flange else "flange"


def _open_directions(D: NDArray[np.float64], used: list[Known]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Of the undetermined shifts ``D`` (m, 6) over ``[t_X, t_Z]``: the combinations the known values
    fix and those they leave open, each as coefficient rows over the m directions."""
    if not used:
        return np.zeros((0, len(D))), np.eye(len(D))
    C = np.array([k.row for k in used]) @ D.T  # (p, m): how each known value moves along each direction
    _, s, Vt = np.linalg.svd(C)
    rank = int(np.sum(s > MIN_COUPLING * 0.5))
    return Vt[:rank], Vt[rank:]


def _unobservable(u_x: NDArray[np.float64], u_z: NDArray[np.float64], X: NDArray[np.float64], setup: str,
                  kind: str) -> Unobservable:
    info = setup_info(setup)
    frame = "flange" if info.camera_on_flange else "base"
    sign = np.sign(u_x[np.argmax(np.abs(u_x))])  # point the direction along the positive axis
    u_x, u_z = sign * u_x, sign * u_z
    where = _frame_words(u_x, frame)
    z_where = _frame_words(u_z, _z_frame(setup))
    axis = "xyz"[int(np.argmax(np.abs(u_x)))]
    z_axis = "xyz"[int(np.argmax(np.abs(u_z)))]
    if kind == ONE_AXIS:
        choice = (f"0 (the least-norm translation): the camera origin placed in the plane through the {frame} origin "
                  f"across the rotation axis; no data can tell")
        capture = "or add rotations of >= 30 deg about a second axis (a robot that can tilt the flange)"
    else:
        choice = f"0: the camera origin placed at the {frame} origin; no data can tell"
        capture = "or add rotations of >= 30 deg about two axes (a robot that can turn the flange)"
    return Unobservable(
        parameter=f"translation of {info.x_name} along {where}",
        transform=info.x_name, frame=frame, direction=u_x, value=float(u_x @ X[:3, 3]), choice=choice,
        coupled=(f"the data determine {info.z_name}'s translation along {z_where} minus {info.x_name}'s along "
                 f"{where}: fixing one fixes the other"),
        fix=(f"give known={{'{info.x_name}.{axis}': metres}} (e.g. from the drawing) or "
             f"known={{'{info.z_name}.{z_axis}': metres}} (--known {info.z_name}.{z_axis}=VALUE), {capture}"))


def _z_directions(null_x: NDArray[np.float64], flange2base: NDArray[np.float64], setup: str) -> NDArray[np.float64]:
    """Where a shift of X's translation along each row of ``null_x`` moves Z's: ``R_A_i`` (the same
    for every pose when the robot turns about that axis only), averaged, orthonormalised."""
    R_A = robot_world_A(flange2base, setup)[:, :3, :3].mean(axis=0)
    U, _, Vt = np.linalg.svd(R_A)
    return null_x @ (U @ Vt).T


def _known_notes(unused: list[Known], X: NDArray[np.float64], Z: NDArray[np.float64], cov_X, setup: str) -> tuple[list[str], dict]:
    info = setup_info(setup)
    notes, table = [], {}
    for k in unused:
        data = float((X if k.of_x else Z)[k.axis, 3])
        std = float(np.sqrt(cov_X[3 + k.axis, 3 + k.axis])) if (k.of_x and cov_X is not None) else None
        off = f"{1e3 * abs(data - k.value):.2f} mm off" + (f" ({abs(data - k.value) / std:.1f} std)" if std else "")
        notes.append(f"known {k.name} = {k.value:.4f} m is not needed (the data determine it: {data:.4f} m, {off}); "
                     f"the data's value is kept" + (f"; check the {info.x_name if k.of_x else info.z_name} you measured"
                                                     if std and abs(data - k.value) > 3 * std + k.std else ""))
        table[k.name] = {"value_m": k.value, "std_m": k.std, "used": False, "data_m": data}
    return notes, table


def known_on_complete(cal: Calibration, known: list[Known]) -> Calibration:
    """``cal`` (X complete: the data determine all of it) with the known values compared, not used."""
    if not known:
        return cal
    notes, table = _known_notes(known, cal.X, cal.Z, cal.cov, cal.setup)
    return replace(cal, notes=list(cal.notes) + notes, observability=replace(cal.observability, known=table))


def calibrate_partial(flange2base: NDArray[np.float64], target2cam: NDArray[np.float64], setup: str, kind: str,
                      pairs: Pairs, known: list[Known], refine: bool = True) -> Calibration:
    """X from motions that determine only part of it (``kind``: ``'one_axis'`` or
    ``'translation_only'``), the undetermined directions fixed by the ``known`` values that
    measure them, the others held at zero and listed in ``unobservable`` (their std is inf).

    ``refine``: the noise-model pose refinement with the known values as measurements (gives
    ``cov``, ``std``); else the closed form with the known values applied exactly.

    Raises
    ------
    DegenerateMotionError
        The motions do not determine even that part.
    """
    motions = MotionSet.from_poses(flange2base, target2cam, setup, pairs)
    sol = solve_low_dof(motions, kind)
    null_x = sol.null_space
    null_z = _z_directions(null_x, flange2base, setup)
    D = np.concatenate([null_x, null_z], axis=1)  # (m, 6): each undetermined shift of [t_X, t_Z]
    coupling = np.abs(np.array([k.row for k in known]) @ D.T).max(axis=1) if known else np.zeros(0)
    used = [k for k, c in zip(known, coupling) if c >= MIN_COUPLING]
    unused = [k for k, c in zip(known, coupling) if c < MIN_COUPLING]
    _, open_ = _open_directions(D, used)
    X0 = sol.X
    Z0 = mean_transform(constant_transforms(X0, flange2base, target2cam, setup))
    G = np.concatenate([np.array([k.row for k in used]).reshape(-1, 6), open_ @ gauge_rows(null_x)])
    values = np.concatenate([[k.value for k in used], np.zeros(len(open_))])
    stds = np.concatenate([[k.std for k in used], np.full(len(open_), GAUGE_STD)])
    if refine:
        ref = refine_pose(X0, Z0, flange2base, target2cam, setup, priors=TranslationPriors(G, values, stds))
        X, Z, cov = ref.X, ref.Z, ref.cov_X
        noise = {"robot_rotation_deg": float(np.degrees(ref.noise["robot_rotation"])),
                 "camera_rotation_deg": float(np.degrees(ref.noise["camera_rotation"])),
                 "translation_mm": 1e3 * ref.noise["translation"],
                 "camera_depth_mm": 1e3 * ref.noise["camera_depth"]}
    else:
        # shift along the undetermined directions so that the known values hold (least squares)
        shift, *_ = np.linalg.lstsq(G @ D.T, values - G @ np.concatenate([X0[:3, 3], Z0[:3, 3]]), rcond=None)
        step = shift @ D
        X, Z = X0.copy(), Z0.copy()
        X[:3, 3] += step[:3]
        Z[:3, 3] += step[3:]
        cov, noise = None, None
    u_x = open_ @ null_x
    u_z = open_ @ null_z
    unobservable = [_unobservable(a, b, X, setup, kind) for a, b in zip(u_x, u_z)]
    std = None
    if cov is not None:
        std = std_deg_mm(cov)
        if len(u_x):
            std[3:][np.abs(u_x).max(axis=0) > _OPEN_COMPONENT] = np.inf
    notes, table = _known_notes(unused, X, Z, cov, setup)
    for k in used:
        table[k.name] = {"value_m": k.value, "std_m": k.std, "used": True, "data_m": None}
    what = {ONE_AXIS: "every rotation is about one axis (a SCARA, planar or 4-axis robot)",
            TRANSLATION_ONLY: "the robot only translates (a Cartesian robot)"}[kind]
    if unobservable:
        notes.insert(0, f"{what}: the data determine only part of X; " + "; ".join(
            f"{u.parameter} is undetermined, set to {u.choice}" for u in unobservable))
    else:
        notes.insert(0, f"{what}: the data determine only part of X; the rest is given: "
                     + ", ".join(f"{k.name} = {k.value:.4f} +- {k.std:.4f} m" for k in used))
    return Calibration(
        X=X, Z=Z, setup=setup, method=f"low_dof_{kind}", flange2base=flange2base, target2cam=target2cam,
        pairs=cast(NDArray[np.intp], motions.pairs), cov=cov, std=std, motions=motions, refinement="pose" if refine else "none",
        pose_noise=noise, notes=notes, estimator=f"low_dof_{kind}" + ("+pose" if refine else ""),
        observability=Observability(kind, unobservable, table))
