"""``handeye calibrate``: a session folder of images and robot poses (several folders: a fleet)."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from .._shared.io import atomic_write
from .._shared.lazy import lazy_module
from ..errors import HandEyeError
from ..estimation.verdict import exit_status
from ..pipelines.calibration import certify_calibration
from ..pipelines.folders import calibrate_session
from ..sensors.camera import preview
from ._common import (
    SAMPLE_SESSION,
    add_calibrate_options,
    add_detection_options,
    add_out_options,
    calibrate_options,
    input_folder,
    out_folder,
    verdict_status,
    write_options,
    write_outputs,
)
from ._printing import fmt_vec, print_calibration, print_image_summary, print_next_views, print_sensor_views

# Loaded when the session asks for them: a fleet (several folders), a report (--out), a joint fit's next views.
_fleet = lazy_module("handeye.workflows.fleet")
_html = lazy_module("handeye.report.html")
_joint_planning = lazy_module("handeye.planning.joints")


def _cmd_calibrate_many(args: argparse.Namespace) -> int:
    """calibrate with several session folders: each into --out/<name>/, on local processes or Dask."""
    if not args.out:
        raise HandEyeError("several sessions need --out: each session's files go into a folder of its own there")
    items = _fleet.calibrate_many(args.session, args.out, scheduler=args.scheduler, jobs=args.jobs,
                           progress=not args.no_progress, certify=args.certify, write_options=write_options(args),
                           options=calibrate_options(args))
    status = 0
    print(f"{'session':<32} {'verdict':<13} {'X translation (mm)':<30} std (mm)")
    for it in items:
        if it.error is not None:
            print(f"{it.session:<32.32} {'FAILED':<13} {it.error}")
            status = 2
            continue
        std = "—" if it.std_mm is None else fmt_vec(np.array(it.std_mm), 3)
        print(f"{it.session:<32.32} {it.verdict:<13} {fmt_vec(np.array(it.translation_mm), 2):<30} {std}")
        status = max(status, exit_status(it.verdict))
    print(f"wrote {Path(args.out) / 'fleet.json'} and a folder per session")
    return status


def _cmd_calibrate(args: argparse.Namespace) -> int:
    if len(args.session) > 1:
        if args.sample:
            raise HandEyeError("give session folders or --sample, not both")
        return _cmd_calibrate_many(args)
    if args.scheduler:
        raise HandEyeError("--scheduler runs several sessions at once: give more than one session folder")
    session = input_folder(args.session[0] if args.session else None, args.sample, SAMPLE_SESSION,
                            "give a session folder, or --sample for the bundled sample session (not both)")
    out_folder(args.out, [session])
    # the report's thumbnails are cut while detection has the images decoded (not read again)
    with preview.kept(_html.MAX_OVERLAYS if args.out else 0):
        cal = calibrate_session(session, calibrate_options(args), jobs=args.jobs, progress=not args.no_progress)
        if args.strict and cal.verdict == "inconsistent":  # a sensor's fit answers; --strict refuses the answer
            raise HandEyeError(f"{session}: the verdict is inconsistent (--strict): "
                               + "; ".join(cal.diagnostics.advice[:2]))
        if args.certify:
            cal = certify_calibration(cal)
        if cal.sensor is not None:
            print_sensor_views(cal)
        else:
            print_image_summary(cal)
        print_calibration(cal)
        write_outputs(cal, args)
    _suggest_views(cal, args.out)
    return verdict_status(cal)


def _suggest_views(cal, out: str | None) -> None:
    """A joint fit that left entries of the arm's table undetermined (or whose X's std is mostly the
    table's): the views that would determine them (shrink it), printed and (with --out) written as
    next_views.csv (joint angles, degrees)."""
    k = cal.kinematic
    if k is None or cal.image_points is None:
        return
    try:
        views = _joint_planning.suggest_joint_views(cal)
    except HandEyeError as exc:  # a proposal, not the result: say why there is none
        print(f"next views: none proposed ({exc})")
        return
    if not len(views.joints):
        return
    text = print_next_views(cal, views)
    if out:
        path = Path(out) / "next_views.csv"
        atomic_write(path, text, list(cal.image_paths or []))
        print(f"wrote {path}")


def register(sub) -> None:
    """Add the ``calibrate`` command's parser to the sub-parsers ``sub``."""
    p = sub.add_parser(
        "calibrate",
        help="calibrate from a capture session (images + robot poses)",
        description="Detect the target in every image, estimate the camera poses and solve the hand-eye "
        "transform. SESSION holds session.yaml, poses.csv and images/ (see docs/guide.md).",
    )
    p.add_argument("session", nargs="*", help="session folder; several calibrate each into --out/<name>/ (a fleet)")
    p.add_argument("--sample", action="store_true", help="run on the bundled sample session")
    p.add_argument("--scheduler", help="several sessions on Dask: 'local' (a LocalCluster of --jobs workers) or a "
                   "scheduler's address (pip install 'handeye[cluster]'); default local processes")
    add_out_options(p)
    add_calibrate_options(p)
    add_detection_options(p)
    p.set_defaults(func=_cmd_calibrate)
