"""Large captures: ``handeye calibrate`` on 200 rendered images of 12 MP with a ChArUco board
(goals: end to end <= 0.5x a plain sequential OpenCV loop (issue 81), peak memory <= 2 GB, progress shown),
and 1,000 images of 1.3 MP (memory bounded the same way).

    python benchmarks/bench_large.py [--images 200] [--size 4000x3000] [--cache DIR]

The session is rendered once into ``--cache`` (default: the user's cache folder,
``~/.cache/handeye-bench/``; never the checkout) and reused by later runs. No intrinsics in
session.yaml: both sides calibrate the camera from the images. Each side runs in a fresh process
whose peak resident memory is read from the operating system:

* OpenCV loop: imread, ``CharucoDetector.detectBoard``, ``calibrateCamera`` on every view,
  ``solvePnP`` per view, ``calibrateHandEye`` (Daniilidis): X and nothing else;
* handeye: ``handeye calibrate SESSION --out DIR --no-cache`` (detection on all cores, intrinsics,
  PnP, the check, the estimator chosen by cross-validation, the uncertainty, result files and
  report), its progress bars on stderr counted.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

from handeye.frames.metrics import rotation_error, translation_error
from handeye.simulate import simulate_session

GOAL = 0.5
GOAL_MIB = 2048
BOARD = {"type": "charuco", "cols": 14, "rows": 10, "square": 0.02, "marker": 0.015, "dictionary": "DICT_5X5_100"}

LOOP = r"""
import sys, json, cv2, numpy as np, yaml
from scipy.spatial.transform import Rotation
folder, spec = sys.argv[1], json.loads(sys.argv[2])
session = yaml.safe_load(open(folder + "/session.yaml"))
board = cv2.aruco.CharucoBoard((spec["cols"], spec["rows"]), spec["square"], spec["marker"],
                               cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, spec["dictionary"])))
detector = cv2.aruco.CharucoDetector(board)
rows = list(csv_row.strip().split(",") for csv_row in open(folder + "/" + session["poses"]["file"]))[1:]
obj_all, img_all, keep, size = [], [], [], None
for k, row in enumerate(rows):
    gray = cv2.imread(folder + "/images/" + row[0], cv2.IMREAD_GRAYSCALE)
    size = gray.shape[::-1]
    corners, ids, _, _ = detector.detectBoard(gray)
    if ids is None or len(ids) < 6:
        continue
    obj, img = board.matchImagePoints(corners, ids)
    obj_all.append(obj); img_all.append(img); keep.append(k)
_, K, dist, _, _ = cv2.calibrateCamera(obj_all, img_all, size, None, None)
R_t, t_t = [], []
for obj, img in zip(obj_all, img_all):
    _, rvec, tvec = cv2.solvePnP(obj, img, K, dist)
    R_t.append(cv2.Rodrigues(rvec)[0]); t_t.append(tvec)
q = np.array([[float(v) for v in rows[k][1:8]] for k in keep])  # image,x,y,z,qw,qx,qy,qz (mm)
R_f = Rotation.from_quat(q[:, [4, 5, 6, 3]]).as_matrix()
R, t = cv2.calibrateHandEye(list(R_f), list(q[:, :3] / 1e3), R_t, t_t, method=cv2.CALIB_HAND_EYE_DANIILIDIS)
X = np.eye(4); X[:3, :3] = R; X[:3, 3] = t.ravel()
print(json.dumps(X.tolist()))
"""


def _timed(argv: list[str]) -> tuple[float, float, subprocess.CompletedProcess]:
    """Wall time (s), peak resident memory (MiB) and the outcome of ``argv`` in a fresh process,
    measured by a wrapper process of its own (a child's peak, alone)."""
    wrapper = ("import resource, subprocess, sys, time, json\n"
               "t = time.perf_counter(); r = subprocess.run(json.loads(sys.argv[1]), capture_output=True, text=True)\n"
               "took = time.perf_counter() - t\n"
               "peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024\n"
               "print(json.dumps([took, peak, r.returncode, r.stdout, r.stderr]))")
    out = subprocess.run([sys.executable, "-c", wrapper, json.dumps(argv)], capture_output=True, text=True, check=True)
    took, peak, code, stdout, stderr = json.loads(out.stdout)
    return took, peak, subprocess.CompletedProcess(argv, code, stdout, stderr)


def _session(cache: Path, n: int, size: tuple[int, int]) -> Path:
    folder = cache / f"charuco-{n}-{size[0]}x{size[1]}"
    if not (folder / "ground_truth.yaml").is_file():
        shutil.rmtree(folder, ignore_errors=True)
        print(f"rendering {n} images of {size[0]}x{size[1]} into {folder} (once) ...", flush=True)
        start = time.perf_counter()
        simulate_session(folder, "eye_in_hand", n, BOARD, noise_px=0.2, seed=3, image_size=size,
                         write_intrinsics=False, image_ext=".jpg", robot_noise=(0.02, 0.1))
        print(f"  rendered in {time.perf_counter() - start:.0f} s")
    return folder


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--images", type=int, default=200)
    parser.add_argument("--size", default="4000x3000")
    parser.add_argument("--cache", default=str(Path.home() / ".cache" / "handeye-bench"))
    args = parser.parse_args()
    size = tuple(int(v) for v in args.size.split("x"))
    folder = _session(Path(args.cache), args.images, size)
    truth = np.array(yaml.safe_load((folder / "ground_truth.yaml").read_text())["cam2flange"])
    env_note = f"{os.cpu_count()} cores"
    t_cv, mem_cv, res_cv = _timed([sys.executable, "-c", LOOP, str(folder), json.dumps(BOARD)])
    if res_cv.returncode != 0:
        raise SystemExit(res_cv.stderr)
    X_cv = np.array(json.loads(res_cv.stdout.strip().splitlines()[-1]))
    with tempfile.TemporaryDirectory(prefix="handeye-bench-large-") as out:
        argv = [sys.executable, "-m", "handeye.cli", "calibrate", str(folder), "--out", out, "--no-cache"]
        t_he, mem_he, res_he = _timed(argv)
        if res_he.returncode not in (0, 1):
            raise SystemExit(res_he.stderr)
        X_he = np.array(json.loads((Path(out) / "result.json").read_text())["X"]["matrix"])
        verdict = json.loads((Path(out) / "result.json").read_text())["check"]["verdict"]
    progress = "detecting" in res_he.stderr
    err = lambda X: (np.degrees(rotation_error(X, truth)), 1e3 * translation_error(X, truth))  # noqa: E731
    ratio = t_he / t_cv
    print(f"{args.images} images of {size[0]}x{size[1]}, ChArUco {BOARD['cols']}x{BOARD['rows']}; {env_note}")
    print(f"  OpenCV loop (detect, calibrateCamera, solvePnP, calibrateHandEye): {t_cv:7.1f} s, peak {mem_cv:6.0f} MiB, "
          "X off by {:.4f} deg / {:.3f} mm".format(*err(X_cv)))
    print(f"  handeye calibrate --out (check, CV, uncertainty, report):         {t_he:7.1f} s, peak {mem_he:6.0f} MiB, "
          "X off by {:.4f} deg / {:.3f} mm; verdict {}".format(*err(X_he), verdict))
    print(f"  ratio {ratio:.2f} (goal <= {GOAL}: {'met' if ratio <= GOAL else 'NOT met'}); peak memory "
          f"{'within' if mem_he <= GOAL_MIB else 'OVER'} {GOAL_MIB} MiB; progress shown: {'yes' if progress else 'NO'}")


if __name__ == "__main__":
    main()
