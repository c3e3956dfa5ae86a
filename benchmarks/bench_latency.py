"""What a user waits for: ``handeye calibrate --sample`` and ``handeye check --sample`` as whole
processes (goals <= 1.5 s and <= 1.0 s on 2 cores), against a plain OpenCV script doing the least
the same job needs, in fresh processes of the same run.

    python benchmarks/bench_latency.py [--repeat 5]

Each command runs ``--repeat`` times in a new ``python`` process (byte-code caching on, as in an
installed package), interleaved with the peer; the best time of each is kept. Two cases for handeye:

* cold: the detection cache is empty (a new ``HANDEYE_CACHE_DIR`` per run): every image detected;
* warm: the same images detected before (``check`` then ``calibrate``, or calibrating again with
  other options): detection read from the cache.

``calibrate --out`` (the result files and report.html, whose figures need matplotlib) is timed warm
for information; the goals are on the commands as the README runs them.

The peer (``opencv script``): import numpy, scipy.spatial and cv2, detect the board in the 12
images with the call handeye makes (findChessboardCornersSB, EXHAUSTIVE | ACCURACY) on 2 threads,
solvePnP per image and calibrateHandEye (Daniilidis): X and nothing else (no check, no
uncertainty, no verdict). The X of the cold and warm runs are compared (they must agree to 1e-9).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

GOALS = {"calibrate": 1.5, "check": 1.0}
SAMPLE = Path(__file__).resolve().parents[1] / "src" / "handeye" / "data" / "sample_session"

PEER = f"""
import glob
from concurrent.futures import ThreadPoolExecutor
import cv2, numpy as np, yaml
from scipy.spatial.transform import Rotation
folder = {str(SAMPLE)!r}
spec = yaml.safe_load(open(folder + "/session.yaml"))
size = (spec["target"]["cols"], spec["target"]["rows"])
K, dist = np.array(spec["camera"]["K"]), np.array(spec["camera"]["dist"])
obj = np.zeros((size[0] * size[1], 3)); obj[:, :2] = np.mgrid[:size[0], :size[1]].T.reshape(-1, 2) * spec["target"]["square"]
cv2.setNumThreads(1)
def detect(path):
    gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    return cv2.findChessboardCornersSB(gray, size, flags=cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY)[1]
paths = sorted(glob.glob(folder + "/images/*.jpg"))
with ThreadPoolExecutor(2) as pool:
    corners = list(pool.map(detect, paths))
rows = np.loadtxt(folder + "/poses.csv", delimiter=",", skiprows=1, usecols=range(1, 7))
R_f = Rotation.from_euler("ZYX", rows[:, 3:], degrees=True).as_matrix()
R_t, t_t = [], []
for c in corners:
    _, rvec, tvec = cv2.solvePnP(obj, c, K, dist)
    R_t.append(cv2.Rodrigues(rvec)[0]); t_t.append(tvec)
R, t = cv2.calibrateHandEye(list(R_f), list(rows[:, :3] / 1e3), R_t, t_t, method=cv2.CALIB_HAND_EYE_DANIILIDIS)
"""


def _run(argv: list[str], env: dict) -> float:
    start = time.perf_counter()
    res = subprocess.run(argv, env=env, capture_output=True, text=True)
    took = time.perf_counter() - start
    if res.returncode not in (0, 1):
        raise SystemExit(f"{' '.join(argv)} failed:\n{res.stderr}")
    return took


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    handeye = [sys.executable, "-m", "handeye.cli"]
    subprocess.run([sys.executable, "-c", "import handeye.cli, handeye.pipelines.calibration"], env=env, check=True)  # byte code
    best = {}
    with tempfile.TemporaryDirectory(prefix="handeye-bench-latency-") as root:
        warm_env = {**env, "HANDEYE_CACHE_DIR": str(Path(root) / "warm")}
        subprocess.run(handeye + ["check", "--sample", "--no-progress"], env=warm_env, capture_output=True)  # fills it
        for k in range(args.repeat):
            cold_env = {**env, "HANDEYE_CACHE_DIR": str(Path(root) / f"cold{k}")}
            runs = {
                "opencv script": ([sys.executable, "-c", PEER], env),
                "calibrate, cold": (handeye + ["calibrate", "--sample", "--no-progress"], cold_env),
                "calibrate, warm": (handeye + ["calibrate", "--sample", "--no-progress"], warm_env),
                "check, cold": (handeye + ["check", "--sample", "--no-progress"], {**cold_env, "HANDEYE_CACHE_DIR": f"{root}/k{k}"}),
                "check, warm": (handeye + ["check", "--sample", "--no-progress"], warm_env),
                "calibrate --out, warm": (handeye + ["calibrate", "--sample", "--no-progress", "--out", f"{root}/o{k}"], warm_env),
            }
            for name, (argv, e) in runs.items():
                best[name] = min(best.get(name, np.inf), _run(argv, e))
        X = {}
        for name, e in (("cold", {**env, "HANDEYE_CACHE_DIR": str(Path(root) / "x")}), ("warm", warm_env)):
            _run(handeye + ["calibrate", "--sample", "--no-progress", "--out", f"{root}/x{name}"], e)
            X[name] = np.array(json.loads((Path(root) / f"x{name}" / "result.json").read_text())["X"]["matrix"])
    peer = best["opencv script"]
    print(f"best of {args.repeat} fresh processes each, {os.cpu_count()} cores")
    for name, t in best.items():
        goal = GOALS.get(name.split(",")[0])  # the bars are on the commands as the README runs them
        verdict = "" if goal is None else f"   (goal <= {goal:g} s: {'met' if t <= goal else 'NOT met'})"
        print(f"  {name:<18} {t:6.2f} s  {t / peer:5.2f}x the OpenCV script{verdict}")
    diff = np.abs(X["cold"] - X["warm"]).max()
    print(f"  X of calibrate cold and warm differ by {diff:.1e} (must be <= 1e-9: {'yes' if diff <= 1e-9 else 'NO'})")


if __name__ == "__main__":
    main()
