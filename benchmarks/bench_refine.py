"""Reprojection refinement on 30 images x 54 points (goal < 1 s); pose refinement on 30 poses.

30 images of a 28 x 17 board with the intrinsics refined: the analytic Jacobians against scipy's
differences (``sparse=False``, the refinement as it was before it had them): goal >= 3x faster,
the same X and Z to 1e-6.

    python benchmarks/bench_refine.py [--repeat 5]

With the robot poses taken as exact, every residual depends on all unknowns (X and Z, 12
numbers; 21 with the intrinsics): that Jacobian is dense. Timed: plain least squares, the robust
variant (two passes), and with the intrinsics refined too.

With ``robot_noise`` (robot poses off by 0.05 deg / 0.2 mm here), every image gets 6 unknowns of
its own (12 + 180 in all) and its residuals depend on X, Z and those 6 only: handeye eliminates
them (each image's 6 solved for given X, Z; ``least_squares`` on the 12 globals, variable
projection) against the joint problem with scipy's dense differences (192 columns), same optimum;
the ratio is printed. Then a large capture, 100 images x 522 points (29 x 18 corners): the
eliminated form's time and peak memory (the joint Jacobian alone would be 2M x 612 doubles), and
the same for the pipeline's robot-aware candidate, the estimation core's fit of the corners with
each pose's error eliminated view by view (``corners_fit(..., robot_sigma=)``), with their ratio.

Pose refinement (``refine_pose``, analytic Jacobian, noise re-estimated until stable) on the same
30 poses with robot and camera pose noise, against OpenCV's closed-form calibrateHandEye
(Daniilidis) on the same poses: what the optimal estimate and its uncertainty cost.
"""

from __future__ import annotations

import argparse

import numpy as np

import handeye
from _timing import best_time
from handeye._shared.threads import on_one_blas_thread
from handeye.estimation.estimators import corners_fit
from handeye.estimation.refinement import refine_pose
from handeye.estimation.validation import Views
from handeye.sensors.camera import Detection, solve_pnp, target_from_spec
from handeye.sensors.camera.render import Renderer, target_texture
from handeye.simulate import default_camera, perturb_poses, scene_from_viewpoints, visible_viewpoints
from handeye.solvers.refine import refine_reprojection


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    rng = np.random.default_rng(1)
    size = (1280, 1024)
    K, dist = default_camera(size)
    renderer = Renderer(K, dist, size, supersample=1)
    target = target_from_spec({"type": "chessboard", "cols": 9, "rows": 6, "square": 0.03})
    obj = target.object_points()
    scene = scene_from_viewpoints(visible_viewpoints(30, rng, renderer, target_texture(target).outline()), "eye_in_hand", rng)
    img = [renderer.project(obj, T) + rng.normal(0, 0.3, (len(obj), 2)) for T in scene.target2cam]
    poses = np.array([solve_pnp(Detection(np.arange(len(obj)), p, obj), K, dist)[0] for p in img])
    cal = handeye.calibrate_poses(scene.flange2base, poses, refine="none")
    objs = [obj] * len(img)
    for label, kw in (("least squares", {}), ("robust (2 passes)", {"robust": True}),
                      ("with intrinsics", {"refine_intrinsics": True})):
        t = best_time(lambda: refine_reprojection(cal.X, cal.Z, scene.flange2base, objs, img, K, dist,
                                                  "eye_in_hand", **kw), args.repeat)
        print(f"{label:<20} 30 images x {len(obj)} points: {t:.3f} s (goal < 1 s)")

    _large_board(rng, K, dist, args.repeat)

    f2b_noisy = perturb_poses(scene.flange2base, np.radians(0.05), 0.2e-3, rng)
    cal_r = handeye.calibrate_poses(f2b_noisy, poses, refine="none", check=False)
    times, evals = {}, {}
    for sparse in (True, False):
        res = []
        times[sparse] = best_time(lambda: res.append(refine_reprojection(
            cal_r.X, cal_r.Z, f2b_noisy, objs, img, K, dist, "eye_in_hand", robot_noise=(np.radians(0.05), 0.2e-3),
            sparse=sparse)), max(1, args.repeat // 2))
        evals[sparse] = res[-1].n_evaluations
    print(f"robot-aware          30 images, 12 + 180 unknowns: eliminated {times[True]:.3f} s ({evals[True]} evaluations), "
          f"joint dense {times[False]:.3f} s ({evals[False]} evaluations): {times[False] / times[True]:.1f}x faster")
    _large_capture(rng, K, dist)

    import cv2

    f2b = perturb_poses(scene.flange2base, np.radians(0.05), 0.2e-3, rng)
    t2c = perturb_poses(scene.target2cam, np.radians(0.1), 0.5e-3, rng)
    cal = handeye.calibrate_poses(f2b, t2c, refine="none")
    t_pose = best_time(lambda: refine_pose(cal.X, cal.Z, f2b, t2c, "eye_in_hand"), args.repeat)
    t_cv = best_time(lambda: cv2.calibrateHandEye(list(f2b[:, :3, :3]), list(f2b[:, :3, 3]), list(t2c[:, :3, :3]),
                                                  list(t2c[:, :3, 3]), method=cv2.CALIB_HAND_EYE_DANIILIDIS), args.repeat)
    print(f"pose refinement      30 poses: {1e3 * t_pose:.1f} ms; OpenCV Daniilidis (closed form, no uncertainty) "
          f"{1e3 * t_cv:.1f} ms: ratio {t_pose / t_cv:.1f}x its time")


def _large_board(rng, K, dist, repeat: int, n: int = 30) -> None:
    """The pixel refinement with the intrinsics refined, ``n`` images of a 28 x 17 board: analytic
    Jacobians against scipy's differences (the refinement before it had them; goal >= 3x, the same
    X to 1e-6)."""
    board = target_from_spec({"type": "chessboard", "cols": 28, "rows": 17, "square": 0.012})
    obj = board.object_points()
    renderer = Renderer(K, dist, (1280, 1024), supersample=1)
    scene = scene_from_viewpoints(visible_viewpoints(n, rng, renderer, target_texture(board).outline()),
                                  "eye_in_hand", rng)
    img = [renderer.project(obj, T) + rng.normal(0, 0.3, (len(obj), 2)) for T in scene.target2cam]
    poses = np.array([solve_pnp(Detection(np.arange(len(obj)), p, obj), K, dist)[0] for p in img])
    cal = handeye.calibrate_poses(scene.flange2base, poses, refine="none", check=False)
    times, fits = {}, {}
    for sparse in (True, False):
        out = []
        times[sparse] = best_time(lambda: out.append(refine_reprojection(
            cal.X, cal.Z, scene.flange2base, [obj] * n, img, K, dist, "eye_in_hand", refine_intrinsics=True,
            sparse=sparse)), max(1, repeat // 2))
        fits[sparse] = out[-1]
    speed = times[False] / times[True]
    dx = max(np.abs(fits[True].X - fits[False].X).max(), np.abs(fits[True].Z - fits[False].Z).max())
    print(f"with intrinsics      {n} images x {len(obj)} points (28 x 17): analytic {times[True]:.3f} s, differences "
          f"{times[False]:.3f} s: {speed:.1f}x faster (goal >= 3x: {'met' if speed >= 3 else 'NOT met'}); X and Z "
          f"differ by {dx:.1e} (goal <= 1e-6: {'met' if dx <= 1e-6 else 'NOT met'})")


def _large_capture(rng, K, dist, n: int = 100) -> None:
    """Robot-aware pixel refinement of ``n`` images of 29 x 18 corners: time and peak memory."""
    import time
    import tracemalloc

    obj = target_from_spec({"type": "chessboard", "cols": 29, "rows": 18, "square": 0.01}).object_points()
    renderer = Renderer(K, dist, (1280, 1024), supersample=1)
    outline = target_texture(target_from_spec({"type": "chessboard", "cols": 29, "rows": 18, "square": 0.01})).outline()
    scene = scene_from_viewpoints(visible_viewpoints(n, rng, renderer, outline), "eye_in_hand", rng)
    img = [renderer.project(obj, T) + rng.normal(0, 0.3, (len(obj), 2)) for T in scene.target2cam]
    f2b = perturb_poses(scene.flange2base, np.radians(0.05), 0.2e-3, rng)
    poses = np.array([solve_pnp(Detection(np.arange(len(obj)), p, obj), K, dist)[0] for p in img])
    cal = handeye.calibrate_poses(f2b, poses, refine="none", check=False)
    sigma = (np.radians(0.05), 0.2e-3)

    def measured(run):
        tracemalloc.start()
        start = time.perf_counter()
        X = run()
        elapsed = time.perf_counter() - start
        peak = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
        return X, elapsed, peak

    views = Views(f2b, poses, "eye_in_hand", [obj] * n, img, K, dist)
    joint = 8 * (2 * n * len(obj) + 6 * n) * (12 + 6 * n) / 2**20
    # both on one BLAS thread (narrow matrices: a second thread waits more than it works)
    solver = measured(lambda: on_one_blas_thread(refine_reprojection)(cal.X, cal.Z, f2b, [obj] * n, img, K, dist, "eye_in_hand",
                                                                      robot_noise=sigma, robust=True).X)
    core = measured(lambda: on_one_blas_thread(corners_fit)(views, np.arange(n), cal.X, cal.Z, robot_sigma=sigma).result.X)
    for label, (X, elapsed, peak) in (("solver's elimination", solver), ("the core's", core)):
        print(f"robot-aware, robust  {n} images x {len(obj)} points, 12 + {6 * n} unknowns, {label}: {elapsed:.2f} s, "
              f"peak {peak:.0f} MiB of arrays (the joint Jacobian alone: {joint:.0f} MiB); X off the truth by "
              f"{1e3 * np.linalg.norm(X[:3, 3] - scene.X[:3, 3]):.3f} mm")
    print(f"robot-aware, robust  the core's fit (the pipeline's candidate) takes {core[1] / solver[1]:.1f}x the solver's time")


if __name__ == "__main__":
    main()
