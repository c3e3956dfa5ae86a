"""``handeye check``: calibrate's verdict on a folder, with the check's tables."""

from __future__ import annotations

import argparse

from ..pipelines.folders import check_folder
from ._common import (
    SAMPLE_SESSION,
    add_calibrate_options,
    add_detection_options,
    calibrate_options,
    input_folder,
)
from ._printing import fmt_vec, print_sensor_views, std_label, wrapped


def _cmd_check(args: argparse.Namespace) -> int:
    folder = input_folder(args.folder, args.sample, SAMPLE_SESSION,
                           "give a session or pose-pair folder, or --sample (not both)")
    found = check_folder(folder, calibrate_options(args), jobs=args.jobs, progress=not args.no_progress)
    for note in found.notes:
        print(f"note: {note}")
    if found.calibration is not None and found.calibration.sensor is not None:  # a sensor's fit: its views
        print_sensor_views(found.calibration)
    else:
        for name, reason in found.skipped:
            print(f"skipped {name}: {reason}")
        print(found.diagnostics.pose_table())
    print()
    print(found.cross_validation_table())
    print()
    cal = found.calibration
    if cal is not None and cal.sensor is not None:  # a sensor's fit: its consistency is its residual against the noise
        d = found.diagnostics
        print(f"verdict: {found.verdict} ({len(cal.sensor.views)} views; the fit's residual is {d.consistency:.2f}x what the "
              f"sensor's stated noise and the robot's accuracy allow, up to {d.consistency_limit:g} is consistent)")
        print("\n".join(wrapped(a, "advice: ") for a in d.advice))
    else:
        print(found.diagnostics.summary())
    if found.calibration is not None and found.calibration.std is not None:  # per axis, as calibrate prints it
        std = found.calibration.std
        print(f"std of X ({std_label(found.calibration)}): rotation {fmt_vec(std[:3], 4)} deg, translation "
              f"{fmt_vec(std[3:], 3)} mm, per axis (as calibrate prints it)")
    return found.exit_status


def register(sub) -> None:
    """Add the ``check`` command's parser to the sub-parsers ``sub``."""
    p = sub.add_parser(
        "check",
        help="check whether the data can give a good calibration (exit 0 good, 1 weak, 2 degenerate/inconsistent)",
        description="Observability, pose-convention mix-ups, outlier poses and leave-one-out stability of a "
        "capture session or a pose-pair folder, with advice. Exit status: 0 good, 1 weak, 2 degenerate or "
        "inconsistent (or bad input).",
    )
    p.add_argument("folder", nargs="?", help="session folder (session.yaml) or pose-pair folder (posepairs.yaml)")
    p.add_argument("--sample", action="store_true", help="check the bundled sample session")
    add_detection_options(p)
    add_calibrate_options(p)
    p.set_defaults(func=_cmd_check)
