"""Regenerate the bundled pose-pair example (src/handeye/data/example_posepairs).

    python scripts/make_example_posepairs.py

12 simulated eye-in-hand poses of a calibrated 6-axis arm (handeye.simulate.realistic_scene with
REALISTIC.scaled(0.25): kinematic errors of ~0.3 mm that depend on the pose, heavy-tailed noise and
timing jitter) and the camera's poses from PnP on noisy points (their error mostly along the optical
axis), no flipped poses. The first example's isotropic noise (robot 0.05 deg / 0.2 mm, camera 0.1
deg / 0.5 mm per axis) was no arm's and no camera's: X's std, which takes the error the poses show
as the robot's, made it weak. Robot poses are written as a KUKA controller reports them (x y z in mm, then
A B C in degrees = intrinsic ZYX Euler angles); camera poses as OpenCV's rvec/tvec (metres).
The ground truth goes to ground_truth.yaml beside them.
"""

from __future__ import annotations

import csv
from dataclasses import replace
from pathlib import Path

import numpy as np
import yaml

from handeye.frames.poses import format_poses, pose_columns
from handeye.simulate import REALISTIC, realistic_scene

OUT = Path(__file__).resolve().parents[1] / "src" / "handeye" / "data" / "example_posepairs"
SEED = 20261122


def write_csv(path: Path, fmt: str, values: np.ndarray) -> None:
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["id"] + pose_columns(fmt))
        for k, row in enumerate(values):
            w.writerow([f"pose{k:02d}"] + [f"{v:.6f}" for v in row])


def main() -> None:
    scene = realistic_scene(12, "eye_in_hand", SEED, errors=replace(REALISTIC.scaled(0.25), flip_probability=0.0))
    f2b, t2c = scene.flange2base, scene.target2cam
    OUT.mkdir(parents=True, exist_ok=True)
    write_csv(OUT / "robot_poses.csv", "euler:ZYX", format_poses(f2b, "euler:ZYX", "mm", "deg"))
    write_csv(OUT / "target2cam.csv", "rotvec", format_poses(t2c, "rotvec", "m", "rad"))
    spec = {
        "setup": "eye_in_hand",
        "robot_poses": {"file": "robot_poses.csv", "format": "euler:ZYX", "length_unit": "mm", "angle_unit": "deg"},
        "camera_poses": {"file": "target2cam.csv", "format": "rotvec", "length_unit": "m", "angle_unit": "rad"},
    }
    (OUT / "posepairs.yaml").write_text(
        "# Simulated eye-in-hand capture (scripts/make_example_posepairs.py). Robot poses as a KUKA\n"
        "# controller reports them (mm, A B C = intrinsic ZYX in degrees); camera poses as OpenCV rvec/tvec.\n"
        + yaml.safe_dump(spec, sort_keys=False),
        encoding="utf-8",
    )
    truth = {
        "note": "ground truth of the simulation: a calibrated arm's kinematic errors (~0.3 mm) and noise, camera poses "
                "from PnP on points with 0.3 px of noise",
        "cam2flange": scene.X.round(12).tolist(),
        "target2base": scene.Z.round(12).tolist(),
    }
    (OUT / "ground_truth.yaml").write_text(yaml.safe_dump(truth, sort_keys=False), encoding="utf-8")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
