"""Line-scan cameras (issue 61): X, the focal length and the clock offset from scans of a chessboard.

    python benchmarks/bench_linescan.py [--sessions 20] [--scans 12]
    python benchmarks/bench_linescan.py --rendered [--sessions 5]
    python benchmarks/bench_linescan.py --arm ur5 [--sessions 10]

Each session (``handeye.pipelines.linescan.simulate.linescan_scene``): a 2,048-pixel line-scan camera (f =
2,400 px, k1 = -0.03) scanning a 9 x 6 chessboard of 20 mm squares from 0.4 m, ``--scans`` scans
each from within 30 deg of the board's normal, moving at 0.2 m/s across the view plane, forth and
back; the corners with 0.1 px of noise along the line and across, the rows with 20 us of timing
jitter, the robot's clock 12 ms after the camera's; the nominal focal length given 3% off. Both
setups. Rows:

* exact robot: X's median error (goal: 0.2 mm / 0.05 deg), the focal length's (goal: 0.1%), within
  3 std (goal >= 95%);
* a calibrated arm's error (0.01 deg / 0.05 mm per axis: a constant and a heavy-tailed error per
  scan), that accuracy stated, each scan's pose error fitted with it as the prior (as the pipeline
  does, :func:`handeye.pipelines.linescan.pipeline.linescan_robot`): the same figures, and X's error with
  the poses taken as exact (the fit before);
* in every row the held-out error of the fit against its closed-form start (the linear pushbroom
  resection and the closed form): the fit must beat it.

``--arm ur5``: the scans are a real arm's (``linescan_scene(arm=...)``: its table 1-3 mm off the
nominal one at the flange, the joint angles reported along the trajectory with encoder noise): X,
the focal length and held-out scans from the joint angles through the arm's table fitted with X
(:func:`handeye.pipelines.linescan.pipeline.linescan_joints`, every row's pose through the table) against
the controller's poses (the nominal table's, each scan's pose error fitted with the default
accuracy stated, as a session with poses only is calibrated), and against one pose per scan through
the fitted table times the nominal move (the table's error taken as rigid over a scan).

``--rendered``: the same capture as a user has it: each scan rendered as a pushbroom image
(``handeye simulate --sensor line_scan``), the chessboard found by OpenCV, ``handeye calibrate`` on the
folder (the robot's default accuracy stated): the same figures, and the seconds of the whole command.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from handeye.estimation.core import estimate
from handeye.frames.metrics import rotation_error, translation_error, within_std
from handeye.pipelines.linescan.pipeline import linescan_joints, linescan_robot
from handeye.pipelines.linescan.simulate import linescan_scene
from handeye.robot.models import ControllerPoses, JointAngles
from handeye.sensors.linescan.model import LineScanCorners


def run(sessions: int, scans: int) -> None:
    rows = [("exact robot", None), ("arm error 0.01 deg / 0.05 mm", (0.01, 0.05))]
    for setup in ("eye_in_hand", "eye_to_hand"):
        for label, error in rows:
            rot, tra, focal, within, beats, secs, offset, plain = [], [], [], [], [], [], [], []
            for k in range(sessions):
                sc = linescan_scene(scans, setup, rng=1000 + k, robot_error=error)
                t0 = time.perf_counter()
                model = LineScanCorners(setup, sc.names, sc.corners, sc.target_points, sc.starts, sc.line_rate,
                                        sc.trajectory, 1.03 * sc.focal, sc.width)
                cal = estimate(model, linescan_robot(model.flange2base_ref, error))  # as the pipeline does
                secs.append(time.perf_counter() - t0)
                if error is not None:  # the poses taken as exact, their accuracy only in the std: the former fit
                    plain.append(1e3 * translation_error(estimate(model, ControllerPoses(model.flange2base_ref, error),
                                                                  uncertainty=False).X, sc.X))
                rot.append(np.degrees(rotation_error(cal.X, sc.X)))
                tra.append(1e3 * translation_error(cal.X, sc.X))
                fig = cal.sensor.figures
                focal.append(100 * abs(fig["focal_px"]["value"] / sc.focal - 1))
                offset.append(1e3 * abs(fig["clock_offset_s"]["value"] - sc.clock_offset))
                within.append(within_std(cal.X, sc.X, cal.std))
                held = cal.cross_validation.errors
                beats.append(held["fit"]["mm"] < held["closed-form start"]["mm"])
            print(f"{setup:11s} {label:29s} X median {np.median(tra):.4f} mm / {np.median(rot):.4f} deg "
                  f"(max {np.max(tra):.3f} mm / {np.max(rot):.4f} deg); focal {np.median(focal):.4f}% (max "
                  f"{np.max(focal):.4f}%); clock {np.median(offset):.3f} ms; within 3 std {100 * np.mean(within):.0f}%; "
                  f"fit beats start {sum(beats)}/{sessions}; {np.median(secs):.2f} s/session"
                  + (f"; the poses as exact (each scan's error not fitted): X median {np.median(plain):.4f} mm" if plain else ""))


def run_arm(sessions: int, scans: int, arm: str) -> None:
    """X and held-out scans by an arm 1-3 mm off its table: joint angles through the fitted table
    against the controller's poses (the module docstring)."""
    rows = {"joint trajectory through the table": [], "controller's poses": [], "one pose per scan, nominal move": []}
    for setup in ("eye_in_hand", "eye_to_hand"):
        for rows_of in rows.values():
            rows_of.clear()
        arm_mm, secs = [], []
        for k in range(sessions):
            sc = linescan_scene(scans, setup, rng=3000 + k, arm=arm)
            arm_mm.append(np.median(1e3 * np.linalg.norm(sc.trajectory.flange2base[:, :3, 3]
                                                         - sc.trajectory_true.flange2base[:, :3, 3], axis=1)))
            model = LineScanCorners(setup, sc.names, sc.corners, sc.target_points, sc.starts, sc.line_rate, sc.trajectory,
                                    1.03 * sc.focal, sc.width)
            t0 = time.perf_counter()
            robot = linescan_joints(sc.chain, sc.trajectory.times, sc.joints, model)
            fits = {"joint trajectory through the table": estimate(model, robot)}
            secs.append(time.perf_counter() - t0)
            fits["controller's poses"] = estimate(model, linescan_robot(model.flange2base_ref, (0.1, 1.0)))
            fits["one pose per scan, nominal move"] = estimate(model, JointAngles(sc.chain, robot.joints))
            for name, cal in fits.items():
                held = next(iter(cal.cross_validation.errors.values()))["mm"]
                rows[name].append((1e3 * translation_error(cal.X, sc.X), np.degrees(rotation_error(cal.X, sc.X)),
                                   within_std(cal.X, sc.X, cal.std), held,
                                   100 * abs(cal.sensor.figures["focal_px"]["value"] / sc.focal - 1)))
        print(f"{setup}, {arm} {np.median(arm_mm):.2f} mm off its table (median over sessions), {sessions} sessions of "
              f"{scans} scans; the joint fit {np.median(secs):.1f} s per session")
        for name, values in rows.items():
            v = np.array(values, float)
            print(f"  {name:36s} X median {np.median(v[:, 0]):.3f} mm / {np.median(v[:, 1]):.4f} deg (max {v[:, 0].max():.3f}"
                  f" mm / {v[:, 1].max():.4f} deg); within 3 std {100 * v[:, 2].mean():.0f}%; held-out {np.median(v[:, 3]):.3f}"
                  f" mm; focal {np.median(v[:, 4]):.3f}%")


def run_rendered(sessions: int, scans: int) -> None:
    import subprocess
    import sys
    import tempfile

    import yaml

    from handeye.io.results import load_result
    for setup in ("eye_in_hand", "eye_to_hand"):
        rot, tra, focal, within, secs = [], [], [], [], []
        for k in range(sessions):
            with tempfile.TemporaryDirectory() as tmp:
                folder = f"{tmp}/s"
                subprocess.run([sys.executable, "-m", "handeye.cli", "simulate", "--sensor", "line_scan", "--setup", setup,
                                "--poses", str(scans), "--seed", str(2000 + k), "--out", folder], check=True,
                               capture_output=True)
                t0 = time.perf_counter()
                subprocess.run([sys.executable, "-m", "handeye.cli", "calibrate", folder, "--out", f"{tmp}/out"], check=True,
                               capture_output=True)
                secs.append(time.perf_counter() - t0)
                truth = yaml.safe_load(open(f"{folder}/ground_truth.yaml"))
                X = np.array(truth["cam2flange" if setup == "eye_in_hand" else "cam2base"])
                cal = load_result(f"{tmp}/out/result.json")
                rot.append(np.degrees(rotation_error(cal.X, X)))
                tra.append(1e3 * translation_error(cal.X, X))
                focal.append(100 * abs(cal.sensor.figures["focal_px"]["value"] / truth["focal_px"] - 1))
                within.append(within_std(cal.X, X, cal.std))
        print(f"{setup:11s} rendered scans, handeye calibrate: X median {np.median(tra):.4f} mm / {np.median(rot):.4f} deg "
              f"(max {np.max(tra):.3f} mm / {np.max(rot):.4f} deg); focal {np.median(focal):.4f}% (max {np.max(focal):.4f}%); "
              f"within 3 std {100 * np.mean(within):.0f}%; {np.median(secs):.1f} s per command")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sessions", type=int, default=20)
    ap.add_argument("--scans", type=int, default=12)
    ap.add_argument("--rendered", action="store_true", help="whole commands on rendered scans")
    ap.add_argument("--arm", help="scans by this arm off its table: joint angles against the controller's poses")
    a = ap.parse_args()
    if a.arm:
        run_arm(a.sessions, a.scans, a.arm)
    elif a.rendered:
        run_rendered(a.sessions, a.scans)
    else:
        run(a.sessions, a.scans)


if __name__ == "__main__":
    main()
