"""Depth cameras: X from board corners lifted to 3D from organized clouds (``handeye.sensors.depth``, ``handeye.pipelines.depth.pipeline``)
against the same views through the 2D path (the intensity image's corners, PnP, handeye's
default pose pipeline), on simulated captures with the depth camera's own errors.

    python benchmarks/bench_depth.py [--sessions 40] [--views 15] [--only board|sphere] [--robot-error DEG,MM]
    python benchmarks/bench_depth.py --joints [--sessions 8]

The 3D path takes each corner where its ray meets the board's plane fitted to the cloud
(``plane_points``); the corners lifted alone (``lift_points``, four pixels each) are printed too.
Each session (``handeye.pipelines.depth.simulate_board.depth_scene``): 15 views at 0.5-1 m, depth noise 0.2 mm at
0.5 m to 0.6 mm at 1 m (growing with the square of the distance), depth scale 1.002, 1% holes,
flying pixels on the board's edges, 0.2 px corner noise; both setups. Printed per setup: the
median X error of each path (rotation, translation, and translation along the camera's optical
axis), the share of sessions with X within 3 reported std (the 3D path; per axis) and with the
depth scale within 3 std. Goals (issue 39): 3D path median within 0.3 mm / 0.1 deg, X within 3
std in >= 95%, the depth scale within 3 std; the 3D path better along the optical axis.

Then the target-free mode (``handeye.pipelines.depth.simulate_board.sphere_scene``): a 50 mm ball on the flange
(eye-to-hand) or fixed in the cell (eye-in-hand), 15 views at 0.5-1 m from directions within 60 deg,
a tilted wall behind it, the same depth errors and flying pixels on its outline; the ball found in
each cloud (``fit_sphere``) and X fitted to the centres (``calibrate_spheres``). Goals: median
within 0.5 mm / 0.2 deg, X within 3 std in >= 95%, the depth scale within 3 std.

``--joints`` (issue 59): the same clouds with the controller's poses and with joint angles through
the arm's table fitted with X (``handeye.robot.models.JointAngles``). A UR5 whose real table is
off its nominal one by 0.7 mm / 0.07 deg per entry (1-3 mm at the flange), joints reported with
0.002 deg of encoder noise, 20 board views (corners on the fitted plane) or 25 views of a 50 mm
ball; both setups. Printed per row: the arm's median error at the flange, the median X error and
held-out error (5-fold, mm) with the controller's poses and with joint angles, their ratios, and
the joint fit's own residual: the sensor's noise, which no held-out error goes below. Goal: joint
angles at least 3x better in X and in the held-out error.

"Within 3 std" uses the data's std (``std_sources['data']``): the simulated robots are exact, and the std
with the robot's stated accuracy (0.03 deg / 0.3 mm per axis) would hold every time. With
``--robot-error 0.02,0.2`` the reported flange poses are off by a constant and a heavy-tailed
error per pose of that size per axis, and "within 3 std" uses the reported std (the data's and
the stated accuracy's).
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.spatial.transform import Rotation

import handeye
from handeye.errors import TargetError
from handeye.estimation.core import estimate
from handeye.frames.metrics import rotation_error, translation_error
from handeye.options import ROBOT_ACCURACY
from handeye.pipelines.depth.pipeline import calibrate_depth, calibrate_spheres
from handeye.pipelines.depth.simulate_board import depth_scene, sphere_scene
from handeye.robot.models import ControllerPoses, JointAngles
from handeye.sensors.camera import Detection, solve_pnp
from handeye.sensors.depth import find_spheres, fit_sphere, lift_points, plane_points
from handeye.sensors.depth.model import BoardPoints, SphereCentres


def _errors(X, truth, setup):
    """Rotation (deg), translation (mm), and the translation error along the camera's optical axis (mm)."""
    axis = truth[:3, 2]  # the camera's z axis in X's reference frame
    d = X[:3, 3] - truth[:3, 3]
    return np.degrees(rotation_error(X, truth)), 1e3 * translation_error(X, truth), 1e3 * abs(d @ axis)


def _within(cal, truth, exact_robot: bool) -> bool:
    """X within 3 std per axis (rotation about X's reference axes, translation)."""
    rotvec = Rotation.from_matrix(cal.X[:3, :3] @ truth[:3, :3].T).as_rotvec(degrees=True)
    dt = 1e3 * (cal.X[:3, 3] - truth[:3, 3])
    std = cal.std_sources["data"] if exact_robot else cal.std
    return bool(np.all(np.abs(rotvec) <= 3 * std[:3]) and np.all(np.abs(dt) <= 3 * std[3:]))


def spheres(args) -> None:
    for setup in ("eye_to_hand", "eye_in_hand"):
        err, within, scale_ok, missed, refused = [], [], [], 0, 0
        for seed in range(args.sessions):
            sc = sphere_scene(args.views, setup, 2000 + seed, robot_error=args.robot_error, stem=args.stem)
            found = []
            for k, c in enumerate(sc.clouds):
                try:
                    found.append(fit_sphere(c, sc.radius, k))
                except TargetError:  # the rod hides the ball: the view is left out, as a session does
                    found.append(None)
            seen = np.array([f is not None for f in found])
            refused += int((~seen).sum())
            centres = np.array([f.centre for f in found if f is not None])
            missed += int(np.sum(np.linalg.norm(centres - sc.target2cam[seen, :3, 3], axis=1) > 5e-3))
            cal = calibrate_spheres(sc.flange2base[seen], centres, setup, np.array([f.cov for f in found if f is not None]),
                                    radii=[sc.radius])
            err.append(_errors(cal.X, sc.X, setup))
            within.append(_within(cal, sc.X, args.robot_error is None))
            scale = cal.sensor.figures['depth_scale']
            scale_ok.append(abs(scale['value'] - sc.depth_scale) <= 3 * scale['std'])
        m = np.median(err, axis=0)
        print(f"{setup}, sphere (no board), {args.sessions} sessions of {args.views} views:")
        print(f"  median {m[0]:.4f} deg / {m[1]:.3f} mm, along the optical axis {m[2]:.3f} mm (goal <= 0.5 mm / 0.2 deg: "
              f"{'met' if m[1] <= 0.5 and m[0] <= 0.2 else 'NOT met'}); balls found elsewhere than the truth: {missed}, "
              f"views refused (ball hidden): {refused}")
        print(f"  X within 3 std: {100 * np.mean(within):.0f}% (goal >= 95%); depth scale within 3 std: "
              f"{100 * np.mean(scale_ok):.0f}%")


def joints(args) -> None:
    """X and the held-out error from the controller's poses against joint angles through the fitted table."""
    print("UR5 off its table by 0.7 mm / 0.07 deg per entry; controller's poses -> joint angles (median over "
          f"{args.sessions} sessions; ratio = poses / joints)")
    for kind in ("board", "sphere"):
        for setup in ("eye_in_hand", "eye_to_hand"):
            rows = []
            for seed in range(args.sessions):
                if kind == "board":
                    sc = depth_scene(20, setup, 3000 + seed, arm="ur5", length_mm=0.7, angle_deg=0.07)
                    points = [plane_points(c, p)[0] for c, p in zip(sc.clouds, sc.image_points)]
                    keep = np.arange(len(points))

                    def model(sc=sc, points=points):
                        return BoardPoints(setup, [f"v{i}" for i in range(len(points))], [sc.object_points] * len(points),
                                           points)
                else:
                    sc = sphere_scene(25, setup, 3000 + seed, arm="ur5", length_mm=0.7, angle_deg=0.07)
                    found = [find_spheres(c, [sc.radius], rng=k)[0] for k, c in enumerate(sc.clouds)]
                    keep = np.array([i for i, f in enumerate(found) if f is not None])

                    def model(sc=sc, found=found, keep=keep):
                        return SphereCentres(setup, [f"v{i}" for i in keep], np.array([found[i].centre for i in keep]),
                                             np.array([found[i].cov for i in keep]), np.array([sc.radius]))
                arm_mm = 1e3 * np.median(np.linalg.norm(sc.chain_true.forward(sc.joints)[:, :3, 3]
                                                        - sc.chain.forward(sc.joints)[:, :3, 3], axis=1))
                poses = estimate(model(), ControllerPoses(sc.flange2base[keep], ROBOT_ACCURACY))
                fitted = estimate(model(), JointAngles(sc.chain, sc.joints[keep]))
                rows.append([arm_mm, *_errors(poses.X, sc.X, setup)[:2], poses.prediction_error["mm"],
                             *_errors(fitted.X, sc.X, setup)[:2], fitted.prediction_error["mm"], fitted.sensor.fit_rms_mm])
            m = np.median(rows, axis=0)
            ratio_x = np.median([x[2] / x[5] for x in rows])
            ratio_rot = np.median([x[1] / x[4] for x in rows])
            ratio_held = np.median([x[3] / x[6] for x in rows])
            print(f"{kind:<6} {setup:<11} arm {m[0]:.2f} mm: X {m[2]:.3f} mm / {m[1]:.4f} deg, held-out {m[3]:.3f} mm -> "
                  f"X {m[5]:.3f} mm / {m[4]:.4f} deg, held-out {m[6]:.3f} mm; ratios X {ratio_x:.1f}x / {ratio_rot:.1f}x, "
                  f"held-out {ratio_held:.1f}x (goal >= 3x: {'met' if min(ratio_x, ratio_held) >= 3 else 'NOT met'}; the "
                  f"joint fit's own residual, the sensor's noise floor: {m[7]:.3f} mm); "
                  f"per session X {min(x[2] / x[5] for x in rows):.1f}-{max(x[2] / x[5] for x in rows):.1f}x, held-out "
                  f"{min(x[3] / x[6] for x in rows):.1f}-{max(x[3] / x[6] for x in rows):.1f}x")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sessions", type=int, default=40)
    parser.add_argument("--views", type=int, default=15)
    parser.add_argument("--only", choices=["board", "sphere"])
    parser.add_argument("--joints", action="store_true", help="controller's poses against joint angles (issue 59)")
    parser.add_argument("--stem", type=float, default=None, metavar="M",
                        help="the ball on a rod of this radius (m), which hides part of it from some views")
    parser.add_argument("--robot-error", type=lambda v: tuple(float(x) for x in v.split(",")), default=None,
                        metavar="DEG,MM", help="the robot's error per axis (constant + heavy-tailed per pose)")
    args = parser.parse_args()
    if args.joints:
        joints(args)
        return
    print(f"robot: {'exact' if args.robot_error is None else f'{args.robot_error[0]} deg / {args.robot_error[1]} mm'}"
          + (f"; the ball on a rod of {1e3 * args.stem:g} mm radius" if args.stem else ""))
    if args.only != "board":
        spheres(args)
    if args.only == "sphere":
        return
    for setup in ("eye_in_hand", "eye_to_hand"):
        e3, e2, e1, within, scale_ok = [], [], [], [], []
        for seed in range(args.sessions):
            sc = depth_scene(args.views, setup, 1000 + seed, robot_error=args.robot_error)
            on_plane = [plane_points(c, p)[0] for c, p in zip(sc.clouds, sc.image_points)]
            cal = calibrate_depth(sc.flange2base, [sc.object_points] * len(on_plane), on_plane, setup)
            e3.append(_errors(cal.X, sc.X, setup))
            lifted = [lift_points(c, p)[0] for c, p in zip(sc.clouds, sc.image_points)]
            e1.append(_errors(calibrate_depth(sc.flange2base, [sc.object_points] * len(lifted), lifted, setup).X,
                              sc.X, setup))
            within.append(_within(cal, sc.X, args.robot_error is None))
            scale = cal.sensor.figures['depth_scale']
            scale_ok.append(abs(scale['value'] - sc.depth_scale) <= 3 * scale['std'])
            obj = sc.object_points
            pnp = np.array([solve_pnp(Detection(np.arange(len(obj)), p, obj), sc.K, np.zeros(5))[0]
                            for p in sc.image_points])
            e2.append(_errors(handeye.calibrate_poses(sc.flange2base, pnp, setup, progress=False).X, sc.X, setup))
        m3, m2, m1 = np.median(e3, axis=0), np.median(e2, axis=0), np.median(e1, axis=0)
        print(f"{setup}, {args.sessions} sessions of {args.views} views:")
        print(f"  3D path (corners on the fitted plane, scale and bias):  median {m3[0]:.4f} deg / {m3[1]:.3f} mm, "
              f"along the optical axis {m3[2]:.3f} mm (goal <= 0.3 mm / 0.1 deg: "
              f"{'met' if m3[1] <= 0.3 and m3[0] <= 0.1 else 'NOT met'})")
        print(f"  3D, corners lifted alone (no plane):                  median {m1[0]:.4f} deg / {m1[1]:.3f} mm, "
              f"along the optical axis {m1[2]:.3f} mm")
        print(f"  2D path (PnP, handeye.calibrate_poses):               median {m2[0]:.4f} deg / {m2[1]:.3f} mm, "
              f"along the optical axis {m2[2]:.3f} mm")
        print(f"  X within 3 std: {100 * np.mean(within):.0f}% (goal >= 95%); depth scale within 3 std: "
              f"{100 * np.mean(scale_ok):.0f}%; 3D better along the axis: {'yes' if m3[2] < m2[2] else 'NO'}")


if __name__ == "__main__":
    main()
