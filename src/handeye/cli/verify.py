"""``handeye verify``: a calibration against views it was not made from."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..pipelines.verify import NOT_THIS, verify
from ..report import write_verification
from ._common import add_detection_options, out_folder


def _cmd_verify(args: argparse.Namespace) -> int:
    session = Path(args.session)
    out_folder(args.out, [session])
    v = verify(args.result, session, jobs=args.jobs, progress=not args.no_progress)
    for name, reason in v.skipped:
        print(f"skipped {name}: {reason}")
    print(v.table())
    print()
    print(v.summary())
    if args.out:
        for path in write_verification(v, args.out):
            print(f"wrote {path}")
    return {"worse than promised": 1, NOT_THIS: 2}.get(v.verdict, 0)


def register(sub) -> None:
    """Add the ``verify`` command's parser to the sub-parsers ``sub``."""
    p = sub.add_parser(
        "verify",
        help="check a calibration on a second capture: each view predicted from its robot pose",
        description="Predict where the target appears in every image of SESSION from its robot pose through the "
        "calibration in RESULT (a result folder, result.json or result.yaml), and compare with the detections: "
        "per view the RMS pixel error and the error in millimetres at the target. Exit 0 when the errors stay "
        "within 2x of what the calibration's own cross-validation promised, 1 when they do not, 2 when the views "
        "do not belong to this calibration or are its own images.",
    )
    p.add_argument("result", help="result folder, result.json or result.yaml written by handeye calibrate --out")
    p.add_argument("session", help="a session folder (images + robot poses) the calibration has not seen")
    p.add_argument("-o", "--out", help="write verify.json and verify.html into this folder")
    add_detection_options(p)
    p.set_defaults(func=_cmd_verify)
