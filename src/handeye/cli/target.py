"""``handeye target``: a printable target and its spec."""

from __future__ import annotations

import argparse

import numpy as np
import yaml

from .._shared.io import atomic_write
from ..errors import HandEyeError
from ..sensors.camera.printing import PAPERS, largest_square_mm, scaled_spec, write_target
from ..sensors.camera.targets import print_kinds, target_from_spec, target_origin
from ._common import number_arg, whole_arg

#: handeye target: per printable kind that handeye ships, the session.yaml type and the defaults (mm,
#: counts, dictionary); a registered target type adds its own (:func:`handeye.sensors.camera.targets.print_kinds`).
TARGET_KINDS = print_kinds()


def _cmd_target(args: argparse.Namespace) -> int:
    kind, defaults = print_kinds()[args.type]
    given = {"cols": args.cols, "rows": args.rows, "square": args.square_mm, "marker": args.marker_mm,
             "separation": args.separation_mm, "dictionary": args.dictionary, "id": args.id}
    values = {k: given[k] if given[k] is not None else v for k, v in defaults.items()}
    unused = [f"--{k.replace('_', '-')}" + ("-mm" if k in ("square", "marker", "separation") else "")
              for k, v in given.items() if v is not None and k not in defaults]
    if unused:
        raise HandEyeError(f"{args.type} takes no {', '.join(unused)}")
    small = [(k, given[k]) for k in ("square", "marker", "separation") if given[k] is not None and given[k] < 1.0]
    if small:  # a side or gap under 1 mm cannot be printed and read: metres given where millimetres are asked
        k, v = small[0]
        raise HandEyeError(f"--{k}-mm {v:g} looks like metres: the sizes are in millimetres here (--{k}-mm "
                           f"{v * 1e3:g} for {v:g} m)")
    spec = {"type": kind}
    for k, v in values.items():
        spec[k] = round(v / 1e3, 9) if k in ("square", "marker", "separation") else v
    target = target_from_spec(spec)
    if args.origin == "centre":  # before the fit: one more line of text below the board
        spec["origin"] = "centre"
    fitted = None
    if args.square_mm is None:  # the board as large as the paper allows (larger squares: better poses)
        fitted = max(1.0, float(np.floor(largest_square_mm(spec, args.paper))))
        mine = {k: spec[k] for k in ("marker", "separation") if given[k] is not None}
        spec = {**scaled_spec(spec, fitted), **mine}
    path = write_target(spec, args.out, args.paper)
    print(f"wrote {path}: print it at 100% (no 'fit to page') and check the ruler measures 100 mm")
    if fitted is not None:
        print(f"{target.size_name} of {fitted:g} mm: the largest whole millimetre that fits {args.paper} (--square-mm sets the size)")
    block = yaml.safe_dump({"target": spec}, sort_keys=False)
    beside = path.with_suffix(".yaml")  # the block as a file: --target-spec of acquire and plan take it
    atomic_write(beside, block)
    print(f"wrote {beside}: the target: block below, for session.yaml (acquire and plan take it as --target-spec)")
    print("for session.yaml:")
    print("  " + block.replace("\n", "\n  ").rstrip())
    frame = target.frame
    if args.origin == "centre":
        centre = 1e3 * target_origin(spec)
        frame = (f"origin at the centre of the board, ({centre[0]:g}, {centre[1]:g}) mm in handeye's corner frame, whose "
                 f"axes it keeps ({frame})")
    print(f"target frame (Z and the target poses are given in it): {frame}")
    return 0


def register(sub) -> None:
    """Add the ``target`` command's parser to the sub-parsers ``sub``."""
    p = sub.add_parser(
        "target",
        help="write a printable calibration target (PDF or SVG, true to scale) and its session.yaml block",
        description="A board to print, drawn as vector shapes at its true size (ChArUco and marker grids from "
        "OpenCV's own layout), with a 100 mm ruler to check the print and the target: block for session.yaml. "
        "Sizes in millimetres. cols/rows count: chessboard inner corners; charuco squares; circle grids circles "
        "(asymmetric: circles per row, rows); grids markers. Symmetric boards (chessboard, circles) can be read "
        "from either end: handeye resolves that from the robot motion, but a ChArUco board, a marker grid or an "
        "asymmetric circle grid removes the doubt.",
    )
    p.add_argument("--type", required=True, choices=list(print_kinds()))
    p.add_argument("-o", "--out", required=True, help="board.pdf or board.svg")
    p.add_argument("--cols", type=whole_arg(1), help="see above (default per type: chessboard 9, charuco 7, ...)")
    p.add_argument("--rows", type=whole_arg(1), help="see above (default per type: chessboard 6, charuco 5, ...)")
    p.add_argument("--square-mm", type=number_arg(0.0, above=True),
                   help="square side (chessboard, charuco), circle spacing, marker side (grids) or tag side, mm")
    p.add_argument("--marker-mm", type=number_arg(0.0, above=True), help="charuco: marker side, mm")
    p.add_argument("--origin", choices=["corner", "centre"], default="corner",
                   help="where the target frame's origin is: corner (default: each type's first feature, see docs/guide.md) "
                   "or centre (the board's centre, as ViSP and the AprilTag library put it); written to the target: block")
    p.add_argument("--separation-mm", type=number_arg(0.0, above=True), help="marker grids: gap between markers, mm")
    p.add_argument("--dictionary", help="charuco and marker grids: an OpenCV aruco dictionary (e.g. DICT_5X5_100)")
    p.add_argument("--id", type=whole_arg(0), help="apriltag: the tag id (default 0)")
    p.add_argument("--paper", default="A4", help=f"{', '.join(PAPERS)} or WIDTHxHEIGHT in mm (default A4; landscape "
                   "when the board needs it)")
    p.set_defaults(func=_cmd_target)
