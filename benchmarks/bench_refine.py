"""Reprojection refinement on 30 images x 54 points (goal < 1 s); pose refinement on 30 poses.

The pixel refinement (``refine_reprojection``) is the estimation core's fit of the corners
(CameraCorners times ControllerPoses, or PoseErrors with each pose's error fitted): one engine.

30 images of a 28 x 17 board with the intrinsics refined: the core's analytic Jacobians against
scipy's differences of the same residuals (goal >= 3x faster, the same X and Z to 1e-6).

    python benchmarks/bench_refine.py [--repeat 5]

With the robot poses taken as exact, every residual depends on all unknowns (X and the target, 12
numbers; 21 with the intrinsics): that Jacobian is dense. Timed: plain least squares, the robust
fit (a soft-L1 round, outliers set aside, plain rounds), and with the intrinsics refined too.

With ``robot_noise`` (robot poses off by 0.05 deg / 0.2 mm here), every image gets 6 unknowns of
its own (12 + 180 in all) and its residuals depend on X, the target and those 6 only: the core
eliminates them (each image's 6 solved for given X and the target; ``least_squares`` on the 12,
variable projection) against the joint problem (192 columns), same optimum; the ratio is printed.
Then a large capture, 100 images x 522 points (29 x 18 corners): the eliminated fit's time and peak
memory (the joint Jacobian alone would be 2M x 612 doubles).

Pose refinement (``refine_pose``, analytic Jacobian, noise re-estimated until stable) on the same
30 poses with robot and camera pose noise, against OpenCV's closed-form calibrateHandEye
(Daniilidis) on the same poses: what the optimal estimate and its uncertainty cost.
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.optimize import least_squares

import handeye
from _timing import best_time
from handeye._shared.threads import on_one_blas_thread
from handeye.estimation import core
from handeye.estimation.refinement import corners_problem, refine_pose, refine_reprojection
from handeye.sensors.camera import Detection, solve_pnp, target_from_spec
from handeye.sensors.camera.render import Renderer, target_texture
from handeye.simulate import default_camera, perturb_poses, scene_from_viewpoints, visible_viewpoints


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
    for label, kw in (("least squares", {}), ("robust", {"robust": True}),
                      ("with intrinsics", {"refine_intrinsics": True})):
        t = best_time(lambda: refine_reprojection(cal.X, cal.Z, scene.flange2base, objs, img, K, dist,
                                                  "eye_in_hand", **kw), args.repeat)
        print(f"{label:<20} 30 images x {len(obj)} points: {t:.3f} s (goal < 1 s)")

    _large_board(rng, K, dist, args.repeat)

    f2b_noisy = perturb_poses(scene.flange2base, np.radians(0.05), 0.2e-3, rng)
    cal_r = handeye.calibrate_poses(f2b_noisy, poses, refine="none", check=False)
    times, fits = {}, {}
    default = core.ELIMINATE_OWN_FROM
    for label, threshold in (("eliminated", default), ("joint", 10**9)):  # the joint Jacobian: elimination off
        res = []
        core.ELIMINATE_OWN_FROM = threshold
        times[label] = best_time(lambda: res.append(refine_reprojection(
            cal_r.X, cal_r.Z, f2b_noisy, objs, img, K, dist, "eye_in_hand", robot_noise=(np.radians(0.05), 0.2e-3))),
            max(1, args.repeat // 2))
        fits[label] = res[-1]
    core.ELIMINATE_OWN_FROM = default
    dx = 1e3 * np.abs(fits["eliminated"].X[:3, 3] - fits["joint"].X[:3, 3]).max()
    print(f"robot-aware          30 images, 12 + 180 unknowns: eliminated {times['eliminated']:.3f} s, joint "
          f"{times['joint']:.3f} s: {times['joint'] / times['eliminated']:.1f}x faster, X the same to {dx:.1e} mm")
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
    """The pixel refinement with the intrinsics refined, ``n`` images of a 28 x 17 board: the core's
    analytic Jacobians against scipy's differences of the same residuals (goal >= 3x, the same X to 1e-6)."""
    board = target_from_spec({"type": "chessboard", "cols": 28, "rows": 17, "square": 0.012})
    obj = board.object_points()
    renderer = Renderer(K, dist, (1280, 1024), supersample=1)
    scene = scene_from_viewpoints(visible_viewpoints(n, rng, renderer, target_texture(board).outline()),
                                  "eye_in_hand", rng)
    img = [renderer.project(obj, T) + rng.normal(0, 0.3, (len(obj), 2)) for T in scene.target2cam]
    poses = np.array([solve_pnp(Detection(np.arange(len(obj)), p, obj), K, dist)[0] for p in img])
    cal = handeye.calibrate_poses(scene.flange2base, poses, refine="none", check=False)
    out = []
    analytic = best_time(lambda: out.append(refine_reprojection(cal.X, cal.Z, scene.flange2base, [obj] * n, img, K, dist,
                                                               "eye_in_hand", refine_intrinsics=True)), max(1, repeat // 2))
    fit = out[-1]
    # the same least squares with scipy's differences of the core's residuals (its noise scale as the fit found it)
    problem = corners_problem("eye_in_hand", [str(i) for i in range(n)], scene.flange2base, [obj] * n, img, K, dist, cal.X,
                              cal.Z, refine_intrinsics=True)
    rows = np.arange(len(problem.sensor.owner))
    fun = core._function(problem, rows, np.array([fit.sigma_px]))
    got = []
    differences = best_time(lambda: got.append(least_squares(fun, np.zeros(sum(problem.sizes)), method="trf",
                                                             x_scale=problem.scale(), xtol=1e-10, ftol=1e-10, gtol=1e-10)),
                            max(1, repeat // 2))
    X, p, _ = problem.unpack(got[-1].x)
    speed = differences / analytic
    dx = max(np.abs(fit.X - X).max(), np.abs(fit.Z - problem.sensor.Z(X, p)).max())
    times = {True: analytic, False: differences}
    print(f"with intrinsics      {n} images x {len(obj)} points (28 x 17): analytic {times[True]:.3f} s, differences "
          f"{times[False]:.3f} s: {speed:.1f}x faster (goal >= 3x: {'met' if speed >= 3 else 'NOT met'}); X and Z "
          f"differ by {dx:.1e} (goal <= 1e-6: {'met' if dx <= 1e-6 else 'NOT met'})")


def _large_capture(rng, K, dist, n: int = 100) -> None:
    """Robot-aware robust pixel refinement of ``n`` images of 29 x 18 corners: time and peak memory."""
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

    joint = 8 * (2 * n * len(obj) + 6 * n) * (12 + 6 * n) / 2**20
    # on one BLAS thread (narrow matrices: a second thread waits more than it works)
    X, elapsed, peak = measured(lambda: on_one_blas_thread(refine_reprojection)(cal.X, cal.Z, f2b, [obj] * n, img, K, dist,
                                                                                "eye_in_hand", robot_noise=sigma, robust=True).X)
    print(f"robot-aware, robust  {n} images x {len(obj)} points, 12 + {6 * n} unknowns, each pose's error eliminated: "
          f"{elapsed:.2f} s, peak {peak:.0f} MiB of arrays (the joint Jacobian alone: {joint:.0f} MiB); X off the truth by "
          f"{1e3 * np.linalg.norm(X[:3, 3] - scene.X[:3, 3]):.3f} mm")


if __name__ == "__main__":
    main()
