"""Laser line profilers (issue 61): X from profiles of a ball, against the simulator's truth.

    python benchmarks/bench_laser.py [--sessions 20] [--profiles 20] [--target sphere|plane|edge|step|spheres]
    python benchmarks/bench_laser.py --speed [--profiles 100]
    python benchmarks/bench_laser.py --joints [--sessions 8] [--profiles 40]

Each session (``handeye.pipelines.laser.simulate.laser_scene``): a 40 mm ball, ``--profiles`` profiles from within
45 deg of its top, the laser plane up to 0.8 of the radius off the centre on either side (or, with
``--target plane``, a 200 mm plate seen from within 45 deg of its normal; ``--target edge``, a square
block's edge seen within 30 deg of its faces' bisector, the laser line across it; ``--target step``,
a 10 mm step seen within 30 deg of its normal; ``--target spheres``, a fixture of 40, 30 and 50 mm
balls, each profile of one chosen at random); 0.02 mm noise along z,
2% of the points without return, 0.2% spikes of 0.5-3 mm; both setups. Rows:

* exact robot: X's median error (goal: 0.01 mm / 0.005 deg), within 3 std;
* a calibrated arm's error (0.01 deg / 0.05 mm per axis: a constant and a heavy-tailed error per
  pose), that accuracy stated: X within 3 std (goal >= 95%), and X's error against a plain robust
  least-squares fit of the same points (soft L1, X and the target's unknowns from the same start, no
  noise model, no points set aside), session by session: no worse (the median ratio within 5%);
* in every row the held-out error of the fit against its closed-form start (the fit must beat it).

``--joints``: the same profiles with the controller's poses and with joint angles through the arm's
table fitted with X (a UR5 whose real table is off its nominal one by 0.7 mm / 0.07 deg per entry,
1-3 mm at the flange; joints reported with 0.002 deg of encoder noise): X's error and the held-out
error (goal: both at least 3x better with joint angles).

``--speed``: one session of ``--profiles`` profiles of ~2,500 points written as a session folder,
then ``handeye calibrate`` on it as a user runs it (a whole process, handeye's modules compiled once
as an installed package's are, after one untimed run; goal: 100 profiles in under 3 s, memory under
1 GB), timed here with ``/usr/bin/time``-style figures from ``resource``.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy.optimize import least_squares

from handeye.estimation.core import estimate
from handeye.frames.metrics import rotation_error, translation_error, within_std
from handeye.geometry.se3 import perturb
from handeye.options import ROBOT_ACCURACY
from handeye.pipelines.laser import simulate as simulated_laser
from handeye.pipelines.laser.simulate import laser_scene, write_laser_session
from handeye.robot.models import ControllerPoses, JointAngles
from handeye.sensors.laser.edge import EdgeProfiles, StepProfiles
from handeye.sensors.laser.model import SphereProfiles, SpheresProfiles
from handeye.sensors.laser.plane import PlaneProfiles


def _plain(model, flange2base) -> np.ndarray:
    """A plain robust least-squares fit of the same points: X and the target's unknowns from the model's start."""
    X0, p0 = model.start(flange2base, None, None)
    rows = np.arange(len(model.points))

    def fun(x):
        return model.residuals(perturb(X0, x[:3], x[3:6]), p0 + x[6:], flange2base, rows)[:, 0]

    res = least_squares(fun, np.zeros(6 + len(p0)), loss="soft_l1", f_scale=1e-4, x_scale=1e-3)
    return perturb(X0, res.x[:3], res.x[3:6])


def _model(target: str, setup: str, sc):
    names = [f"p{i}" for i in range(len(sc.profiles))]
    if target == "spheres":
        return SpheresProfiles(setup, names, sc.profiles, 0.5 * np.asarray(simulated_laser.FIXTURE["diameters"]))
    models = {"plane": PlaneProfiles, "edge": EdgeProfiles, "step": StepProfiles}
    return SphereProfiles(setup, names, sc.profiles, radius=sc.radius) if target == "sphere" else models[target](
        setup, names, sc.profiles)


def accuracy(args) -> None:
    for error in (None, (0.01, 0.05)):
        for setup in ("eye_in_hand", "eye_to_hand"):
            err, plain, within, beats = [], [], [], []
            for seed in range(args.sessions):
                sc = laser_scene(args.profiles, setup, 100 + seed, robot_error=error, target=args.target)
                cal = estimate(_model(args.target, setup, sc), ControllerPoses(sc.flange2base, error))
                err.append((1e3 * translation_error(cal.X, sc.X), np.degrees(rotation_error(cal.X, sc.X))))
                within.append(within_std(cal.X, sc.X, cal.std))
                cv = cal.cross_validation
                beats.append(cv["fit"]["mm"] < cv["closed-form start"]["mm"])
                if error is not None:
                    Xp = _plain(_model(args.target, setup, sc), sc.flange2base)
                    plain.append((1e3 * translation_error(Xp, sc.X), np.degrees(rotation_error(Xp, sc.X))))
            m = np.median(err, axis=0)
            head = "exact robot" if error is None else f"arm error {error[0]} deg / {error[1]} mm (stated)"
            line = (f"{args.target} {setup:<11} {head}: X median {m[0]:.4f} mm / {m[1]:.5f} deg, within 3 std "
                    f"{100 * np.mean(within):.0f}%, the fit beats its closed-form start (held out) in {sum(beats)}/{len(beats)}")
            if error is None:
                line += f" (goal 0.01 mm / 0.005 deg: {'met' if m[0] <= 0.01 and m[1] <= 0.005 else 'NOT met'})"
            else:
                mp = np.median(plain, axis=0)
                paired = float(np.median(np.array(err)[:, 0] / np.array(plain)[:, 0]))  # per session, the same points
                closer = int(np.sum(np.array(err)[:, 0] <= np.array(plain)[:, 0]))
                line += (f"; plain robust least squares {mp[0]:.4f} mm / {mp[1]:.5f} deg, per session the fit's translation "
                         f"error {paired:.2f}x the plain fit's (median), closer in {closer}/{len(err)} (goal: no worse, "
                         f"within 3 std >= 95%: {'met' if paired <= 1.05 and np.mean(within) >= 0.95 else 'NOT met'})")
            print(line, flush=True)


def joints(args) -> None:
    """X and the held-out error from the controller's poses against joint angles through the fitted table."""
    print(f"UR5 off its table by 0.7 mm / 0.07 deg per entry, {args.profiles} profiles; controller's poses -> joint "
          f"angles (median over {args.sessions} sessions; ratio = poses / joints)")
    for setup in ("eye_in_hand", "eye_to_hand"):
        rows = []
        for seed in range(args.sessions):
            sc = laser_scene(args.profiles, setup, 500 + seed, arm="ur5", length_mm=0.7, angle_deg=0.07)
            names = [f"p{i}" for i in range(args.profiles)]
            arm_mm = 1e3 * np.median(np.linalg.norm(sc.chain_true.forward(sc.joints)[:, :3, 3]
                                                    - sc.chain.forward(sc.joints)[:, :3, 3], axis=1))
            poses = estimate(SphereProfiles(setup, names, sc.profiles, radius=sc.radius),
                             ControllerPoses(sc.flange2base, ROBOT_ACCURACY))
            fitted = estimate(SphereProfiles(setup, names, sc.profiles, radius=sc.radius), JointAngles(sc.chain, sc.joints))
            rows.append([arm_mm, 1e3 * translation_error(poses.X, sc.X), np.degrees(rotation_error(poses.X, sc.X)),
                         poses.prediction_error["mm"], 1e3 * translation_error(fitted.X, sc.X),
                         np.degrees(rotation_error(fitted.X, sc.X)), fitted.prediction_error["mm"],
                         within_std(fitted.X, sc.X, fitted.std)])
        r = np.array(rows, dtype=float)
        m = np.median(r, axis=0)
        ratio_x, ratio_held = np.median(r[:, 1] / r[:, 4]), np.median(r[:, 3] / r[:, 6])
        print(f"{setup:<11} arm {m[0]:.2f} mm: X {m[1]:.3f} mm / {m[2]:.4f} deg, held-out {m[3]:.3f} mm -> X {m[4]:.3f} mm "
              f"/ {m[5]:.4f} deg, held-out {m[6]:.3f} mm; ratios X {ratio_x:.1f}x, held-out {ratio_held:.1f}x (goal >= 3x: "
              f"{'met' if min(ratio_x, ratio_held) >= 3 else 'NOT met'}); joint fit's X within 3 std "
              f"{100 * np.mean(r[:, 7]):.0f}%; per session X {np.min(r[:, 1] / r[:, 4]):.1f}-{np.max(r[:, 1] / r[:, 4]):.1f}x, "
              f"held-out {np.min(r[:, 3] / r[:, 6]):.1f}-{np.max(r[:, 3] / r[:, 6]):.1f}x", flush=True)


def speed(args) -> None:
    simulated_laser.PROFILER["points"] = 5200  # ~2,500 on the ball in each profile
    with tempfile.TemporaryDirectory() as tmp:
        sc = laser_scene(args.profiles, "eye_in_hand", 7)
        folder = write_laser_session(f"{tmp}/s", sc)
        points = int(np.mean([np.isfinite(p[:, 2]).sum() for p in sc.profiles]))
        # as a user's Python runs it: an installed package's modules are compiled once (.pyc; pip does it at
        # install), not at every command as under PYTHONDONTWRITEBYTECODE (set on some build machines: ~0.25 s
        # more here); one untimed run writes them for an editable install
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        command = [sys.executable, "-m", "handeye.cli", "calibrate", str(folder), "--out", f"{tmp}/out", "--no-progress"]
        subprocess.run(command, check=False, stdout=subprocess.DEVNULL, env=env)
        subprocess.run(["rm", "-rf", f"{tmp}/out"], check=True)
        runs = []
        for _ in range(3):
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            t = time.perf_counter()
            subprocess.run(command, check=False, stdout=subprocess.DEVNULL, env=env)
            runs.append(time.perf_counter() - t)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            del before
            peak = after.ru_maxrss / 1024
            subprocess.run(["rm", "-rf", f"{tmp}/out"], check=True)
        print(f"{args.profiles} profiles of ~{points} points: handeye calibrate --out, whole process: "
              f"{min(runs):.2f}-{max(runs):.2f} s (median {np.median(runs):.2f} s; goal < 3 s: "
              f"{'met' if np.median(runs) < 3 else 'NOT met'}); peak memory {peak:.0f} MiB (goal < 1024)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sessions", type=int, default=20)
    parser.add_argument("--profiles", type=int, default=None)
    parser.add_argument("--speed", action="store_true")
    parser.add_argument("--joints", action="store_true", help="controller's poses against joint angles")
    parser.add_argument("--target", default="sphere", choices=list(simulated_laser.TARGETS),
                        help="the target scanned (accuracy rows)")
    args = parser.parse_args()
    if args.joints:
        args.sessions = min(args.sessions, 8) if args.sessions == 20 else args.sessions
        args.profiles = args.profiles or 40
        joints(args)
    elif args.speed:
        args.profiles = args.profiles or 100
        speed(args)
    else:
        args.profiles = args.profiles or 20
        accuracy(args)


if __name__ == "__main__":
    main()
