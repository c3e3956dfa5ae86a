"""Regenerate the bundled pose-pair example (src/handeye/data/example_posepairs).

    python scripts/make_example_posepairs.py

12 simulated eye-in-hand poses with realistic noise (robot 0.05 deg / 0.2 mm, camera 0.1 deg /
0.5 mm per axis). Robot poses are written as a KUKA controller reports them (x y z in mm, then
A B C in degrees = intrinsic ZYX Euler angles); camera poses as OpenCV's rvec/tvec (metres).
The ground truth goes to ground_truth.yaml beside them.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import yaml

from handeye.poses import format_poses, pose_columns
from handeye.simulate import perturb_poses, random_scene

OUT = Path(__file__).resolve().parents[1] / "src" / "handeye" / "data" / "example_posepairs"
SEED = 20261122


def write_csv(path: Path, fmt: str, values: np.ndarray) -> None:
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["id"] + pose_columns(fmt))
        for k, row in enumerate(values):
            w.writerow([f"pose{k:02d}"] + [f"{v:.6f}" for v in row])


def main() -> None:
    rng = np.random.default_rng(SEED)
    scene = random_scene(12, "eye_in_hand", rng=rng)
    f2b = perturb_poses(scene.flange2base, np.radians(0.05), 0.2e-3, rng)
    t2c = perturb_poses(scene.target2cam, np.radians(0.1), 0.5e-3, rng)
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
        "note": "ground truth of the simulation; the poses carry robot 0.05 deg / 0.2 mm and camera 0.1 deg / 0.5 mm noise",
        "cam2flange": scene.X.round(12).tolist(),
        "target2base": scene.Z.round(12).tolist(),
    }
    (OUT / "ground_truth.yaml").write_text(yaml.safe_dump(truth, sort_keys=False), encoding="utf-8")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
