"""Large inputs: ``handeye calibrate-poses`` and ``handeye check`` on 1,000 pose pairs against OpenCV's
Daniilidis on the same poses, in the same run (goals, as ratios so that a loaded machine does not
move them: calibrate-poses with its check, estimators, uncertainty and report within
:data:`GOAL_RATIO` times OpenCV's closed form on all 499,500 pairs, check within
:data:`GOAL_RATIO_CHECK`; 10,000 pose pairs < 60 s with the verdict given on 100 of them). The test
suite keeps what load cannot fail: the answer, and the ~10,000 spread pairs taken instead of all
(tests/test_faults.py).

    python benchmarks/bench_scale.py [--poses 1000] [--repeat 2] [--sizes 100,1000,10000]

``--sizes``: ``calibrate-poses`` once on the first 100, 1,000 and 10,000 poses of one capture
(10,000 poses of one scene; the larger sets hold the smaller), printing the time and the verdict
of each: the verdict must not change with the size. One capture per ``--noise`` level (default
three: 0.01 deg / 0.1 mm, 0.02 / 0.2 and 0.05 / 0.5, robot and camera alike). The std of X does not
shrink with the poses: it holds the robot's absolute accuracy, raised from pose pairs to 3x their
disagreement (``handeye.pipelines.calibration.UNSEEN_FACTOR``), which no number of poses removes; at 0.02 deg /
0.2 mm its 3 std lands on the 5 mm line between good and weak (5.0 +- 0.1 mm at every size), so the
verdict there turns on the third digit of a data-derived number, while at the other levels (2.5 mm,
12.5 mm) it is the same at every size. Each level then calibrates 10 other captures of 100 poses at
its noise: at 0.02 deg / 0.2 mm, 5 of them good and 5 weak (3 std 4.40-5.85 mm), so there the
verdict turns on the capture, not on its size; at the other levels all 10 agree.

All pairs of 1,000 poses are 499,500 motions; handeye's default pairing (``pairs='auto'``) takes
every pair up to 141 poses and a spread of ~10,000 beyond, so that the check, the cross-validation
and the uncertainty stay linear in the poses. Timed end to end through the command line (reading
the CSV files, the check, the estimator choice, the report), in this process. For a peer measured
in the same run: ``cv2.calibrateHandEye`` (Daniilidis, all 499,500 pairs, the closed form alone, no
check and no uncertainty) on the same poses, plus the mean target pose; and handeye's own closed
form on all pairs (``calibrate_poses(pairs='all', refine='none', check=False)``), which is what
OpenCV computes.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import shutil
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
import yaml

import handeye
from _timing import best_time
from handeye.cli import main as cli
from handeye.frames.metrics import rotation_error, translation_error
from handeye.frames.setups import constant_transforms
from handeye.geometry.se3 import make_transform, mean_transform
from handeye.io.session import write_pose_table
from handeye.simulate import perturb_poses, random_scene

GOAL_S = 5.0
#: Goal for 10,000 pose pairs (--sizes).
GOAL_LARGE_S = 60.0
#: Goals on 1,000 pose pairs, against OpenCV's closed form on all their pairs timed in the same run:
#: ``calibrate-poses --out`` (2.5x measured on a loaded 2-core machine: 20.8 s against 8.3 s; the 30 s
#: the suite once held it to was ~5x an unloaded run) and ``check`` (0.9x). Work quadratic in the
#: poses (every pair in the check or the cross-validation) would put them at tens.
GOAL_RATIO, GOAL_RATIO_CHECK = 5.0, 2.0


def _folder(root: Path, F, T) -> Path:
    folder = root / "pp"
    folder.mkdir()
    names = [f"p{k:04d}" for k in range(len(F))]
    write_pose_table(folder / "robot.csv", names, F, "quat_wxyz", "m")
    write_pose_table(folder / "cam.csv", names, T, "rotvec", "m", "rad")
    (folder / "posepairs.yaml").write_text(yaml.safe_dump({
        "setup": "eye_in_hand", "robot_poses": {"file": "robot.csv", "format": "quat_wxyz", "length_unit": "m"},
        "camera_poses": {"file": "cam.csv", "format": "rotvec", "length_unit": "m", "angle_unit": "rad"}}))
    return folder


def _opencv(F, T):
    R, t = cv2.calibrateHandEye(F[:, :3, :3], F[:, :3, 3], T[:, :3, :3], T[:, :3, 3],
                                method=cv2.CALIB_HAND_EYE_DANIILIDIS)
    X = make_transform(R, t.ravel())
    return X, mean_transform(constant_transforms(X, F, T, "eye_in_hand"))


def _capture(n: int, noise: tuple[float, float], seed: int):
    """An eye-in-hand scene of ``n`` poses and its robot and camera poses with ``noise`` (deg, mm) each."""
    rng = np.random.default_rng(seed)
    scene = random_scene(n, rng=rng)
    F = perturb_poses(scene.flange2base, np.radians(noise[0]), 1e-3 * noise[1], rng)
    T = perturb_poses(scene.target2cam, np.radians(noise[0]), 1e-3 * noise[1], rng)
    return scene, F, T


def sizes(counts: list[int], noise: tuple[float, float]) -> None:
    """``calibrate-poses --out`` once on the first ``n`` poses of one scene, for each ``n``."""
    _, F, T = _capture(max(counts), noise, 11)
    print(f"one capture of {max(counts)} poses (robot and camera noise {noise[0]:g} deg / {noise[1]:g} mm), "
          "its first n poses:")
    verdicts = []
    for n in counts:
        root = Path(tempfile.mkdtemp(prefix="handeye-bench-scale-"))
        try:
            folder = _folder(root, F[:n], T[:n])
            start = time.perf_counter()
            with contextlib.redirect_stdout(io.StringIO()) as buf, contextlib.redirect_stderr(io.StringIO()):
                status = cli(["calibrate-poses", str(folder), "--out", str(root / "out")])
            took = time.perf_counter() - start
            std = json.loads((root / "out" / "result.json").read_text())["uncertainty"]["std_translation_mm"]
        finally:
            shutil.rmtree(root, ignore_errors=True)
        verdict = next((line.split(":", 1)[1].strip() for line in buf.getvalue().splitlines()
                        if line.startswith("check:")), "?")
        verdicts.append(verdict)
        goal = GOAL_S if n <= 1000 else GOAL_LARGE_S
        print(f"  {n:6d} poses: {took:7.2f} s (goal < {goal:g} s: {'met' if took < goal else 'NOT met'}), "
              f"exit {status}, check: {verdict} (3 std of X's translation {3 * np.linalg.norm(std):.2f} mm; "
              "5 mm is the line between good and weak)")
    print(f"  the same verdict at every size: {'yes' if len(set(verdicts)) == 1 else 'NO'}")
    others(min(counts), noise)


def others(n: int, noise: tuple[float, float], captures: int = 10) -> None:
    """The verdict on ``captures`` other captures of ``n`` poses at the same noise: how far it turns on
    the capture itself, whatever its size."""
    verdicts, spans = [], []
    for seed in range(captures):
        _, F, T = _capture(n, noise, seed)
        cal = handeye.calibrate_poses(F, T, progress=False)
        verdicts.append(cal.verdict)
        spans.append(3 * np.linalg.norm(cal.std[3:]))
    print(f"  {captures} other captures of {n} poses at the same noise: "
          + ", ".join(f"{v} {verdicts.count(v)}" for v in sorted(set(verdicts)))
          + f" (3 std of X's translation {min(spans):.2f}-{max(spans):.2f} mm)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=1000)
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--sizes", help="comma-separated pose counts: calibrate-poses on the first n of one scene")
    parser.add_argument("--noise", action="append",
                        help="with --sizes: robot and camera pose noise, DEG,MM (repeatable; default 0.01,0.1 0.02,0.2 0.05,0.5)")
    args = parser.parse_args()
    if args.sizes:
        for level in args.noise or ["0.01,0.1", "0.02,0.2", "0.05,0.5"]:
            deg, mm = (float(v) for v in level.split(","))
            sizes([int(v) for v in args.sizes.split(",")], (deg, mm))
        return
    scene, F, T = _capture(args.poses, (0.02, 0.2), 11)
    root = Path(tempfile.mkdtemp(prefix="handeye-bench-scale-"))
    try:
        folder = _folder(root, F, T)

        def run(argv):
            out = root / "out"
            shutil.rmtree(out, ignore_errors=True)
            with contextlib.redirect_stdout(io.StringIO()) as buf, contextlib.redirect_stderr(io.StringIO()):
                status = cli(argv + (["--out", str(out)] if argv[0] == "calibrate-poses" else []))
            return status, buf.getvalue()

        t_cal = best_time(lambda: run(["calibrate-poses", str(folder)]), args.repeat, warmup=False)
        status, text = run(["calibrate-poses", str(folder)])
        t_check = best_time(lambda: run(["check", str(folder)]), args.repeat, warmup=False)
        start = time.perf_counter()
        X_cv, _ = _opencv(F, T)
        t_cv = time.perf_counter() - start
        t_solve = best_time(lambda: handeye.calibrate_poses(F, T, pairs="all", refine="none", check=False, progress=False), args.repeat)
        X_he = handeye.calibrate_poses(F, T, progress=False).X
    finally:
        shutil.rmtree(root, ignore_errors=True)
    err = lambda X: (np.degrees(rotation_error(X, scene.X)), 1e3 * translation_error(X, scene.X))  # noqa: E731
    print(f"{args.poses} pose pairs ({args.poses * (args.poses - 1) // 2} pairs in all), eye-in-hand, "
          f"robot and camera noise 0.02 deg / 0.2 mm; best of {args.repeat}")
    print(f"  handeye calibrate-poses --out (check, estimators, uncertainty, report): {t_cal:6.2f} s; exit {status}, "
          f"{'good' if 'check: good' in text else 'not good'}")
    print(f"  handeye check:                                                        {t_check:6.2f} s")
    print(f"  OpenCV calibrateHandEye (Daniilidis, all pairs, closed form only):    {t_cv:6.2f} s")
    print(f"  handeye calibrate_poses(pairs='all', refine='none', check=False):      {t_solve:6.2f} s "
          f"({t_cv / t_solve:.1f}x faster than OpenCV)")
    print(f"  ratio calibrate-poses / OpenCV closed form: {t_cal / t_cv:.2f} (goal < {GOAL_RATIO:g}: "
          f"{'met' if t_cal / t_cv < GOAL_RATIO else 'NOT met'})")
    print(f"  ratio check / OpenCV closed form:           {t_check / t_cv:.2f} (goal < {GOAL_RATIO_CHECK:g}: "
          f"{'met' if t_check / t_cv < GOAL_RATIO_CHECK else 'NOT met'})")
    print("  error of X: handeye calibrate-poses {:.4f} deg / {:.3f} mm, OpenCV {:.4f} deg / {:.3f} mm".format(
        *err(X_he), *err(X_cv)))


if __name__ == "__main__":
    main()
