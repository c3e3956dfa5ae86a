"""``handeye study``: the thesis's simulation study of chapter 5."""

from __future__ import annotations

import argparse
import time

from ..errors import HandEyeError
from ..frames.setups import SETUPS
from ..workflows.study import headline, preset, study, write_study
from ._common import out_folder, whole_arg


def _cmd_study(args: argparse.Namespace) -> int:
    settings, figures = preset(args.preset, setup=args.setup)
    if args.figures:
        unknown = sorted(set(args.figures) - set(figures))
        if unknown:
            raise HandEyeError(f"unknown figure(s) {', '.join(unknown)} in preset {args.preset}; "
                               f"available: {', '.join(figures)}")
        wanted = set(args.figures)
        # a histogram figure needs the curve figure its data come from
        wanted |= {figures[f].source_figure for f in args.figures if figures[f].source_figure}
        settings = [s for s in settings if s.figure in wanted]
        figures = {k: v for k, v in figures.items() if k in wanted}
    out = out_folder(args.out)
    start = time.perf_counter()
    result = study(settings, runs=args.runs, seed=args.seed, jobs=args.jobs, progress=not args.no_progress,
                   figures=figures, preset_name=args.preset, scheduler=args.scheduler)
    elapsed = time.perf_counter() - start
    print(headline(result))
    print()
    for path in write_study(result, out):
        print(f"wrote {path}")
    print(f"{len(settings)} settings x {args.runs} runs ({args.setup}, seed {args.seed}) in {elapsed:.1f} s")
    return 0


def register(sub) -> None:
    """Add the ``study`` command's parser to the sub-parsers ``sub``."""
    p = sub.add_parser(
        "study",
        help="the Monte-Carlo study of the thesis's chapter 5 (every solver, any noise)",
        description="Simulate hand-eye captures with known X under a grid of noise levels and motion counts, "
        "run every solver on the same data and write study.csv, study.md, study.json and one PNG per figure.",
    )
    p.add_argument("--preset", default="seed-chapter5", help="study grid (default: seed-chapter5)")
    p.add_argument("-o", "--out", required=True, help="output folder (created; other files in it are left alone)")
    p.add_argument("--runs", type=whole_arg(1), default=200, help="simulations per setting (default 200, as the thesis)")
    p.add_argument("--seed", type=whole_arg(0), default=0, help="random seed: same seed, same numbers (default 0)")
    p.add_argument("--setup", default="eye_in_hand", choices=list(SETUPS))
    p.add_argument("--figures", nargs="+", metavar="ID", help="only these figures of the preset (e.g. 5.1 5.4)")
    p.add_argument("--jobs", type=whole_arg(1), default=None, help="worker processes (default: all cores)")
    p.add_argument("--scheduler", metavar="ADDRESS|local",
                   help="run on Dask distributed (pip install 'handeye[cluster]'): a scheduler's address, or 'local' "
                   "for a LocalCluster of --jobs workers; same seed, same numbers as without")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_study)
