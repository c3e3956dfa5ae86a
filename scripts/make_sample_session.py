"""Regenerate the bundled sample session (src/handeye/data/sample_session).

    python scripts/make_sample_session.py

12 rendered eye-in-hand chessboard images (640x480, JPEG), 0.2 px feature noise, robot poses with
0.01 deg / 0.05 mm noise per axis (a repeatable arm; the 0.02 deg / 0.1 mm of the first sample made
the robot's errors seen in the views 0.26 mm per axis, which X's std now takes as an arm's kinematic
error), written as a KUKA controller reports them (mm, A B C = intrinsic ZYX in
degrees), intrinsics in session.yaml; ground truth in ground_truth.yaml.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from handeye.simulate import simulate_session

OUT = Path(__file__).resolve().parents[1] / "src" / "handeye" / "data" / "sample_session"


def main() -> None:
    shutil.rmtree(OUT, ignore_errors=True)
    simulate_session(OUT, setup="eye_in_hand", n_poses=12, target="chessboard", noise_px=0.2, seed=20261122,
                     pose_format="euler:ZYX", length_unit="mm", angle_unit="deg", image_ext=".jpg",
                     robot_noise=(0.01, 0.05))
    size = sum(p.stat().st_size for p in OUT.rglob("*") if p.is_file())
    print(f"wrote {OUT} ({size / 1e6:.2f} MB)")


if __name__ == "__main__":
    main()
