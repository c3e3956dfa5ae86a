"""Laser line profilers' captures: profiles of a ball, with the profiler's and the robot's errors.

A profiler (laser triangulation) measures along its laser plane (``y = 0`` of its frame): for each
of ``points`` positions ``x`` across its field of view, the depth ``z`` where the plane meets the
scene, within its measuring range. :func:`laser_scene` puts a ball in front of it from directions
within a cone, the laser plane cutting the ball off its centre on either side, and returns the
profiles with noise along ``z``, points without a return (dropouts), spikes (a multiple
reflection's stray points) and the robot's reported poses; :func:`write_laser_session` writes them
as a laser session folder.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..._shared.io import atomic_write, check_output_folder
from ...errors import HandEyeError, InputMismatchError
from ...frames.setups import check_setup, predicted_target2cam, setup_info
from ...geometry.se3 import invert, make_transform
from ...io.session import write_joint_table, write_pose_table
from ...robot.kinematics import Chain, load_arm
from ...simulate import arm_mount, reaching, real_chain, reported_poses
from ...simulate.scenes import Scene, scene_from_viewpoints
from ..kinds import SimulateRequest

__all__ = ["LaserScene", "laser_scene", "pendant_laser_scene", "write_laser_session", "write_profile",
           "profiler_views", "profile_reading", "PROFILER", "TARGETS", "FANUC_PROFILER_X", "simulate_command"]

#: The simulated profiler: field of view along x (m), measuring range along z (m), points per profile.
PROFILER = {"fov": 0.08, "near": 0.08, "far": 0.16, "points": 2000}


@dataclass(frozen=True)
class LaserScene(Scene):
    """A simulated laser capture: per view the profile (``profiles``: (n, 3) points in the sensor
    frame, metres, NaN where there is no return) of a ball of ``radius`` at the target frame's
    origin (``Z``'s translation: the centre in the base frame eye-in-hand, in the flange frame
    eye-to-hand; ``target2cam`` is the ball's pose in the sensor frame)."""

    profiles: list = None  # type: ignore[assignment]
    radius: float = 0.02
    noise_m: float = 2e-5
    flange2base_true: NDArray[np.float64] | None = None
    #: with an arm: the joint angles the controller reports (rad), the arm's name, its nominal and real tables
    joints: NDArray[np.float64] | None = None
    arm: str | None = None
    chain: Chain | None = None
    chain_true: Chain | None = None
    #: 'sphere' (a ball of ``radius``), 'plane' (a plate at the target frame's z = 0), 'edge' or 'step'
    #: (:data:`BLOCK`'s, along the target frame's x axis) or 'spheres' (:data:`FIXTURE`'s balls)
    target: str = "sphere"


def _sensor_views(n: int, radius: float, rng: np.random.Generator, cone_deg: float, roll_deg: float = 180.0
                  ) -> NDArray[np.float64]:
    """(n, 4, 4) sensor2target: the ball (at the target's origin) in front of the profiler, the laser
    plane cutting it off its centre (either side), the chord inside the field of view and the range,
    the sensor looking from within ``cone_deg`` of the target's +z with any roll."""
    near, far, fov = PROFILER["near"], PROFILER["far"], PROFILER["fov"]
    out = np.empty((n, 4, 4))
    for k in range(n):
        h = rng.uniform(-0.8, 0.8) * radius  # the laser plane's offset from the centre
        rho = np.sqrt(radius**2 - h**2)
        cx = rng.uniform(-1.0, 1.0) * max(0.5 * fov - rho, 0.0) * 0.8
        cz = rng.uniform(near + rho + 0.1 * (far - near), far - 0.1 * (far - near))
        centre = np.array([cx, h, cz])  # the ball's centre in the sensor frame
        tilt = np.radians(cone_deg) * np.sqrt(rng.uniform())
        axis = rng.normal(size=2)
        axis /= np.linalg.norm(axis)
        # the sensor's z axis points down at the ball (towards -z of the target), tilted, any roll
        R = (Rotation.from_rotvec(tilt * np.r_[axis, 0.0]) * Rotation.from_euler("x", 180, degrees=True)
             * Rotation.from_euler("z", rng.uniform(-roll_deg, roll_deg), degrees=True)).as_matrix()
        out[k] = make_transform(R, -R @ centre)
    return out


def _measured(x: NDArray[np.float64], z: NDArray[np.float64], rng: np.random.Generator, noise_m: float,
              dropout: float, spikes: float) -> NDArray[np.float64]:
    """The profile (n, 3) the profiler reports of the true depths ``z`` at ``x``: ``noise_m`` along
    z, a share ``spikes`` of stray points 0.5-3 mm off, a share ``dropout`` without return, and
    nothing (NaN) outside the measuring range."""
    near, far, n = PROFILER["near"], PROFILER["far"], len(x)
    z = z + rng.normal(0.0, noise_m, n)
    stray = rng.random(n) < spikes
    z[stray] += rng.choice([-1.0, 1.0], int(stray.sum())) * rng.uniform(5e-4, 3e-3, int(stray.sum()))
    z[(rng.random(n) < dropout) | (z < near) | (z > far)] = np.nan
    return np.c_[x, np.zeros(n), z]


def _profile(target2sensor: NDArray[np.float64], radius: float, rng: np.random.Generator, noise_m: float,
             dropout: float, spikes: float) -> NDArray[np.float64]:
    """What the profiler measures of the ball at ``target2sensor``: per x across its field of view the
    nearest point of the ball in its laser plane, with ``noise_m`` along z, a share ``dropout`` without
    return and a share ``spikes`` of stray points 0.5-3 mm off; outside the range or the ball: NaN."""
    fov, n = PROFILER["fov"], PROFILER["points"]
    cx, h, cz = target2sensor[:3, 3]
    x = np.linspace(-0.5 * fov, 0.5 * fov, n)
    inside = radius**2 - h**2 - (x - cx) ** 2
    z = np.where(inside > 0, cz - np.sqrt(np.maximum(inside, 0.0)), np.nan)
    return _measured(x, z, rng, noise_m, dropout, spikes)


#: The simulated plate: a square of this side (m) at the target frame's z = 0.
PLATE_M = 0.2


def _plate_views(n: int, rng: np.random.Generator, cone_deg: float, roll_deg: float = 180.0) -> NDArray[np.float64]:
    """(n, 4, 4) sensor2target: the profiler above the plate (the target frame's z = 0, its +z up),
    looking down from within ``cone_deg`` of the plate's normal with any roll, the laser line's
    centre on the plate's middle half, at a distance within the measuring range."""
    near, far = PROFILER["near"], PROFILER["far"]
    out = np.empty((n, 4, 4))
    for k in range(n):
        tilt = np.radians(cone_deg) * np.sqrt(rng.uniform())
        axis = rng.normal(size=2)
        axis /= np.linalg.norm(axis)
        R = (Rotation.from_rotvec(tilt * np.r_[axis, 0.0]) * Rotation.from_euler("x", 180, degrees=True)
             * Rotation.from_euler("z", rng.uniform(-roll_deg, roll_deg), degrees=True)).as_matrix()
        hit = np.r_[rng.uniform(-0.25, 0.25, 2) * PLATE_M, 0.0]
        out[k] = make_transform(R, hit - R[:, 2] * rng.uniform(near + 0.2 * (far - near), far - 0.2 * (far - near)))
    return out


def _plate_profile(target2sensor: NDArray[np.float64], rng: np.random.Generator, noise_m: float, dropout: float,
                   spikes: float) -> NDArray[np.float64]:
    """What the profiler measures of the plate at ``target2sensor``: per x across its field of view
    the point where its laser plane meets the plate (``n . p = d`` in the sensor frame), with the
    ball's noise, dropouts and spikes (:func:`_profile`); off the plate or outside the range: NaN."""
    fov, n = PROFILER["fov"], PROFILER["points"]
    normal, d = target2sensor[:3, 2], target2sensor[:3, 2] @ target2sensor[:3, 3]
    x = np.linspace(-0.5 * fov, 0.5 * fov, n)
    z = (d - normal[0] * x) / normal[2]
    on_plate = invert(target2sensor)[:3, :3] @ np.c_[x, np.zeros(n), z].T + invert(target2sensor)[:3, 3:]
    z = np.where(np.all(np.abs(on_plate[:2]) <= 0.5 * PLATE_M, axis=0), z, np.nan)
    return _measured(x, z, rng, noise_m, dropout, spikes)


#: The simulated block (``target='edge'``): its top (the target frame's z = 0, y <= 0) and its side
#: meet along the target's x axis at ``angle_deg``; ``depth`` (m) back and down, ``width`` along the
#: edge. A step (``target='step'``): the top's level, a riser at y = 0 and a lower level ``step`` (m)
#: below, as far out. The views: within ``cone_deg`` (at most) of the faces' bisector (a step's normal),
#: the laser line within ``roll_deg`` of across the edge, either way.
BLOCK = {"angle_deg": 90.0, "depth": 0.1, "width": 0.2, "step": 0.01, "cone_deg": 30.0, "roll_deg": 40.0}
#: The simulated ball fixture (``target='spheres'``): each ball's centre in the target frame (m) and diameter.
FIXTURE = {"centres": [[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.09, 0.0]], "diameters": [0.04, 0.03, 0.05]}


def _block_faces(target: str) -> list[tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.intp]]]:
    """The block (or the step's two blocks) as half-spaces ``n . q <= d`` in the target frame, each
    with its label: 0 the top (the upper level), 1 the side (the lower level), 2 a step's riser, -1
    the block's other faces (not measured)."""
    a, depth, width, step = np.radians(BLOCK["angle_deg"]), BLOCK["depth"], BLOCK["width"], BLOCK["step"]
    ends = [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]
    if target == "edge":
        N = np.array([[0.0, 0.0, 1.0], [0.0, np.sin(a), -np.cos(a)], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]] + ends)
        return [(N, np.array([0.0, 0.0, depth, depth, width / 2, width / 2]), np.array([0, 1, -1, -1, -1, -1]))]
    N = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]] + ends)
    upper = (N, np.array([0.0, 0.0, depth, depth, width / 2, width / 2]), np.array([0, 2, -1, -1, -1, -1]))
    lower = (N, np.array([-step, depth, depth, depth, width / 2, width / 2]), np.array([1, -1, -1, -1, -1, -1]))
    return [upper, lower]


def _ray_depths(origins: NDArray[np.float64], direction: NDArray[np.float64], blocks) -> tuple[NDArray[np.float64],
                                                                                              NDArray[np.intp]]:
    """Where rays from ``origins`` (n, 3) along ``direction`` first enter one of the convex ``blocks``
    (:func:`_block_faces`): the distance (inf: no hit) and the label of the face entered."""
    depth, label = np.full(len(origins), np.inf), np.full(len(origins), -1, dtype=np.intp)
    for N, d, labels in blocks:
        nv, no = N @ direction, origins @ N.T
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (d - no) / nv
        enter = np.where(nv < 0, t, -np.inf)
        leave = np.where(nv > 0, t, np.inf).min(axis=1)
        t_in, face = enter.max(axis=1), enter.argmax(axis=1)
        hit = (t_in <= leave) & (t_in > 0) & ~np.any((nv == 0) & (no > d), axis=1) & (t_in < depth)
        depth[hit], label[hit] = t_in[hit], labels[face[hit]]
    return depth, label


def _block_views(target: str, n: int, rng: np.random.Generator, cone_deg: float, roll_deg: float = 180.0
                 ) -> NDArray[np.float64]:
    """(n, 4, 4) sensor2target: the profiler looking at the block's edge (a step's riser) along the
    faces' bisector (the step's normal), tilted within ``cone_deg`` (at most ``BLOCK['cone_deg']``),
    the laser line across the edge within ``roll_deg`` (at most ``BLOCK['roll_deg']``) either way,
    aimed within 10 mm of the edge, at a distance within the measuring range."""
    near, far = PROFILER["near"], PROFILER["far"]
    a = np.radians(BLOCK["angle_deg"]) if target == "edge" else np.pi
    bisector = np.array([0.0, 0.0, 1.0]) + np.array([0.0, np.sin(a), -np.cos(a)])
    bisector = bisector / np.linalg.norm(bisector) if target == "edge" else np.array([0.0, 0.0, 1.0])
    across = np.cross([1.0, 0.0, 0.0], bisector)  # in the faces' bisector plane, across the edge
    base = np.column_stack([across, np.cross(-bisector, across), -bisector])  # the sensor looking along -bisector
    cone, roll = np.radians(min(cone_deg, BLOCK["cone_deg"])), min(roll_deg, BLOCK["roll_deg"])
    out = np.empty((n, 4, 4))
    for k in range(n):
        turn = rng.uniform(-roll, roll) + rng.choice([0.0, 180.0])
        axis = rng.normal(size=2) @ np.array([[1.0, 0.0, 0.0], across])
        tilt = cone * np.sqrt(rng.uniform()) * axis / np.linalg.norm(axis)
        R = Rotation.from_rotvec(tilt).as_matrix() @ base @ Rotation.from_euler("z", turn, degrees=True).as_matrix()
        aim = np.array([rng.uniform(-0.25, 0.25) * BLOCK["width"], 0.0, 0.0]) + rng.uniform(-0.01, 0.01) * across
        out[k] = make_transform(R, aim - R[:, 2] * rng.uniform(near + 0.3 * (far - near), far - 0.3 * (far - near)))
    return out


def _block_profile(target: str, target2sensor: NDArray[np.float64], rng: np.random.Generator, noise_m: float,
                   dropout: float, spikes: float) -> NDArray[np.float64]:
    """What the profiler measures of the block (the step) at ``target2sensor``: per x across its field
    of view where its ray first enters the block, on the top and the side (a step's levels and riser),
    with the ball's noise, dropouts and spikes (:func:`_profile`); elsewhere NaN."""
    fov, n = PROFILER["fov"], PROFILER["points"]
    sensor2target = invert(target2sensor)
    x = np.linspace(-0.5 * fov, 0.5 * fov, n)
    depth, label = _ray_depths(sensor2target[:3, 3] + x[:, None] * sensor2target[:3, 0], sensor2target[:3, 2],
                               _block_faces(target))
    return _measured(x, np.where(label >= 0, depth, np.nan), rng, noise_m, dropout, spikes)


def _fixture_views(n: int, rng: np.random.Generator, cone_deg: float, roll_deg: float = 180.0) -> NDArray[np.float64]:
    """(n, 4, 4) sensor2target: each view one ball of :data:`FIXTURE`'s, chosen at random, seen as
    :func:`_sensor_views` sees a ball."""
    centres, radii = np.asarray(FIXTURE["centres"], float), 0.5 * np.asarray(FIXTURE["diameters"], float)
    balls = rng.integers(0, len(radii), n)
    return np.array([make_transform(np.eye(3), centres[b]) @ _sensor_views(1, radii[b], rng, cone_deg, roll_deg)[0]
                     for b in balls])


def _fixture_profile(target2sensor: NDArray[np.float64], rng: np.random.Generator, noise_m: float, dropout: float,
                     spikes: float) -> NDArray[np.float64]:
    """What the profiler measures of :data:`FIXTURE`'s balls at ``target2sensor``: per x the nearest of
    the balls' near sides (:func:`_profile`'s, with its noise, dropouts and spikes)."""
    fov, n = PROFILER["fov"], PROFILER["points"]
    x = np.linspace(-0.5 * fov, 0.5 * fov, n)
    z = np.full(n, np.inf)
    for c, d in zip(FIXTURE["centres"], FIXTURE["diameters"]):
        cx, h, cz = target2sensor[:3, :3] @ np.asarray(c, float) + target2sensor[:3, 3]
        inside = (d / 2) ** 2 - h**2 - (x - cx) ** 2
        z = np.minimum(z, np.where(inside > 0, cz - np.sqrt(np.maximum(inside, 0.0)), np.inf))
    return _measured(x, np.where(np.isfinite(z), z, np.nan), rng, noise_m, dropout, spikes)


def profiler_views(target: str, n: int, radius: float, rng: np.random.Generator, cone_deg: float,
                   roll_deg: float = 180.0) -> NDArray[np.float64]:
    """(n, 4, 4) sensor2target: ``n`` views of the ``target`` ('sphere' of ``radius``, 'plane', 'edge',
    'step' or 'spheres') from within ``cone_deg`` of its +z (an edge's: of its faces' bisector), turned
    within ``roll_deg`` about the view direction, as :func:`laser_scene` draws them (the planner's too)."""
    if target == "sphere":
        return _sensor_views(n, radius, rng, cone_deg, roll_deg)
    if target in ("edge", "step"):
        return _block_views(target, n, rng, cone_deg, roll_deg)
    if target == "spheres":
        return _fixture_views(n, rng, cone_deg, roll_deg)
    return _plate_views(n, rng, cone_deg, roll_deg)


def profile_reading(target: str, target2sensor: NDArray[np.float64], radius: float, rng: np.random.Generator,
                    noise_m: float, dropout: float = 0.0, spikes: float = 0.0) -> NDArray[np.float64]:
    """What the profiler of :data:`PROFILER` measures of the ``target`` at ``target2sensor`` ((n, 3)
    points, NaN without return), with the noise, dropouts and spikes of :func:`laser_scene`."""
    if target == "sphere":
        return _profile(target2sensor, radius, rng, noise_m, dropout, spikes)
    if target in ("edge", "step"):
        return _block_profile(target, target2sensor, rng, noise_m, dropout, spikes)
    if target == "spheres":
        return _fixture_profile(target2sensor, rng, noise_m, dropout, spikes)
    return _plate_profile(target2sensor, rng, noise_m, dropout, spikes)


#: The targets the simulator scans.
TARGETS = ("sphere", "plane", "edge", "step", "spheres")


def laser_scene(n_views: int = 20, setup: str = "eye_in_hand", rng: np.random.Generator | int | None = None, *,
                radius: float = 0.02, noise_m: float = 2e-5, dropout: float = 0.02, spikes: float = 0.002,
                cone_deg: float = 45.0, robot_error: tuple[float, float] | None = None, arm: str | None = None,
                length_mm: float = 0.5, angle_deg: float = 0.05, joint_noise_deg: float = 0.002,
                target: str = "sphere") -> LaserScene:
    """A laser profiler's capture of a ball of ``radius`` (m): fixed in the cell and scanned by the
    profiler on the flange (eye-in-hand), or on the flange in front of a fixed profiler (eye-to-hand).

    ``n_views`` profiles (:data:`PROFILER`: 80 mm field of view, 80-160 mm range, 2,000 points), each
    from a direction within ``cone_deg`` of the ball's top, the laser plane cutting the ball up to
    0.8 of its radius off its centre on either side; depth noise ``noise_m`` (m), a share ``dropout``
    of points without return, a share ``spikes`` of stray points 0.5-3 mm off. ``robot_error`` (deg,
    mm): the reported flange poses are off by a constant and a heavy-tailed error per pose of that
    size per axis (``flange2base`` is what the controller reports; None: exact). ``arm`` (a shipped
    arm's name): the profiles are the arm's at joint angles that reach those views, its real table
    off the nominal one by ``length_mm`` / ``angle_deg`` per entry (1-3 mm at the flange at the
    defaults), the joint angles reported with ``joint_noise_deg`` of encoder noise, ``flange2base``
    the nominal table's poses at them (:func:`_arm_laser_scene`; give no ``robot_error`` then: the
    arm's own error replaces it). ``target``: 'sphere' (the ball), 'plane' (a 200 mm plate at the
    target frame's z = 0, seen from within ``cone_deg`` of its normal), 'edge' (a block's top and side
    meeting at :data:`BLOCK`'s angle along the target's x axis, seen along their bisector, the laser
    line across the edge), 'step' (two levels :data:`BLOCK`'s step apart, the riser between them
    along the target's x axis) or 'spheres' (:data:`FIXTURE`'s balls, each profile of one chosen at
    random).

    Examples
    --------
    >>> sc = laser_scene(5, "eye_in_hand", rng=0)
    >>> len(sc.profiles), sc.profiles[0].shape
    (5, (2000, 3))
    """
    setup = check_setup(setup)
    if target not in TARGETS:
        raise InputMismatchError(f"target={target!r}: the simulator scans one of {', '.join(TARGETS)}")
    rng = np.random.default_rng(rng)
    if arm is not None:
        if robot_error is not None:
            raise InputMismatchError("laser_scene: give arm (its table's error) or robot_error (an error of the poses), "
                                     "not both")
        return _arm_laser_scene(n_views, setup, rng, radius, noise_m, dropout, spikes, cone_deg, arm, length_mm,
                                angle_deg, joint_noise_deg, target)
    sensor2target = profiler_views(target, n_views, radius, rng, cone_deg)
    scene = scene_from_viewpoints(sensor2target, setup, rng)
    profiles = [profile_reading(target, T, radius, rng, noise_m, dropout, spikes) for T in invert(sensor2target)]
    return LaserScene(setup, scene.X, scene.Z, reported_poses(scene.flange2base, robot_error, rng), scene.target2cam,
                      profiles=profiles, radius=radius, noise_m=noise_m, flange2base_true=scene.flange2base, target=target)


#: A real profiler's pose on a FANUC's flange (RobCalibrator's answer for its capture, calibration.sec:
#: x, y, z, w, p, r = -149.94 mm, 714.56 mm, 482.43 mm, -0.980, -178.982, 89.710 deg): 0.87 m from the flange.
FANUC_PROFILER_X = make_transform(Rotation.from_euler("xyz", [-0.98031, -178.98232, 89.70972], degrees=True).as_matrix(),
                                  [-0.14994, 0.71456, 0.48243])


def pendant_laser_scene(setup: str = "eye_in_hand", rng: np.random.Generator | int | None = None, *,
                        translations: int = 6, turns: tuple[int, int, int] = (3, 3, 3), turn_deg: tuple[float, float] = (4.0, 15.0),
                        X: NDArray[np.float64] | None = None, radius: float = 0.04, standoff: float = 0.12,
                        noise_m: float = 2e-5, robot_error: tuple[float, float] | None = (0.01, 0.05)) -> LaserScene:
    """A capture of a ball as a user jogs it at the pendant (RobCalibrator's FANUC capture is one):
    ``translations`` profiles at one orientation of the flange, then ``turns[k]`` profiles each with
    the flange turned by ``turn_deg`` (deg, either sign) about the base's x, y and z axes (FANUC's W,
    P and R), the flange moved each time so that the laser line cuts the ball within 0.8 of its
    radius of its centre, ``standoff`` (m) in front of the profiler, within 20 mm across the line.
    ``X``: the profiler's true pose (sensor2flange or sensor2base; default a random one within 50 mm
    of the flange or 1 m of the base's origin). The profile and the robot's error as
    :func:`laser_scene`'s.

    Examples
    --------
    >>> sc = pendant_laser_scene("eye_in_hand", rng=0, translations=4, turns=(1, 1, 1))
    >>> len(sc.profiles), bool(np.all([np.isfinite(p[:, 2]).sum() > 100 for p in sc.profiles]))
    (7, True)
    """
    setup = check_setup(setup)
    rng = np.random.default_rng(rng)
    on_flange = setup_info(setup).camera_on_flange
    base_scene = scene_from_viewpoints(profiler_views("sphere", 1, radius, rng, 0.0), setup, rng)
    X = base_scene.X if X is None else np.asarray(X, float)
    R0 = base_scene.flange2base[0, :3, :3]
    rotations = [R0] * translations
    for axis, n in enumerate(turns):
        for _ in range(n):
            angle = np.radians(rng.uniform(*turn_deg)) * rng.choice([-1.0, 1.0])
            rotations.append(Rotation.from_rotvec(np.eye(3)[axis] * angle).as_matrix() @ R0)
    ball = base_scene.Z[:3, 3]  # in the base eye-in-hand, in the flange eye-to-hand
    F = []
    for R in rotations:
        w = np.array([rng.uniform(-0.02, 0.02), rng.uniform(-0.8, 0.8) * radius, standoff + rng.uniform(-0.01, 0.01)])
        # eye-in-hand: the ball where F X w puts it; eye-to-hand: the ball on the flange where X w is
        t = ball - R @ (X[:3, :3] @ w + X[:3, 3]) if on_flange else X[:3, :3] @ w + X[:3, 3] - R @ ball
        F.append(make_transform(R, t))
    F_true = np.array(F)
    Z = make_transform(np.eye(3), ball)
    target2sensor = predicted_target2cam(X, Z, F_true, setup)
    profiles = [profile_reading("sphere", T, radius, rng, noise_m, 0.02, 0.002) for T in target2sensor]
    return LaserScene(setup, X, Z, reported_poses(F_true, robot_error, rng), target2sensor, profiles=profiles, radius=radius,
                      noise_m=noise_m, flange2base_true=F_true)


#: The ball this far (m) from the profiler at the arm's home.
STANDOFF_M = 0.12


def _arm_laser_scene(n: int, setup: str, rng: np.random.Generator, radius, noise_m, dropout, spikes, cone_deg, arm: str,
                     length_mm: float, angle_deg: float, joint_noise_deg: float, target: str = "sphere") -> LaserScene:
    """:func:`laser_scene` by a real arm: at the arm's home the profiler looks down at the ball from
    :data:`STANDOFF_M`; each view of :func:`_sensor_views` is reached by the nominal table's joint
    angles (least squares from home; views out of reach, or more than 1.5 spreads from home, drawn
    again), which the real arm (its table off the nominal one) takes to a slightly other pose: the
    profile is what the profiler sees from there (drawn again when it has fewer than 200 points)."""
    chain = load_arm(arm)
    home = chain.home[setup]
    X, Z = arm_mount(chain, setup, rng, STANDOFF_M)
    true = real_chain(chain, rng, length_mm, angle_deg)
    limit = 1.5 * (chain.spread if chain.spread is not None else np.full(chain.n_joints, np.pi))
    joints, profiles, f_true = [], [], []
    for _ in range(50 * n):
        if len(joints) == n:
            break
        s2t = profiler_views(target, 1, radius, rng, cone_deg)[0]
        wanted = (Z @ s2t @ invert(X) if setup_info(setup).camera_on_flange else X @ invert(s2t) @ invert(Z))
        q, gap = reaching(chain, wanted, home)
        if gap > 1e-6 or np.any(np.abs(q - home) > limit):
            continue
        F = true.forward(q[None])[0]
        profile = profile_reading(target, predicted_target2cam(X, Z, F[None], setup)[0], radius, rng, noise_m, dropout, spikes)
        if np.isfinite(profile[:, 2]).sum() >= 200:
            joints.append(q)
            profiles.append(profile)
            f_true.append(F)
    if len(joints) < n:
        raise HandEyeError(f"the simulated {arm} reached only {len(joints)} of {n} views of the {target}: ask for fewer "
                           "views, or another arm")
    q_true = np.array(joints)
    reported = q_true + np.radians(rng.normal(0.0, joint_noise_deg, q_true.shape))
    F_true = np.array(f_true)
    return LaserScene(setup, X, Z, chain.forward(reported), predicted_target2cam(X, Z, F_true, setup), profiles=profiles,
                      radius=radius, noise_m=noise_m, flange2base_true=F_true, joints=reported, arm=arm, chain=chain,
                      chain_true=true, target=target)


def _target_truth(scene: LaserScene) -> dict:
    """The target's true figures in the frame it is fixed in (the base eye-in-hand, the flange eye-to-hand)."""
    R, t = scene.Z[:3, :3], scene.Z[:3, 3]
    if scene.target == "sphere":
        return {"radius_m": float(scene.radius)}
    if scene.target == "plane":
        return {"normal": R[:, 2].tolist(), "distance_m": float(R[:, 2] @ t)}
    if scene.target == "spheres":
        return {"centres": (np.asarray(FIXTURE["centres"], float) @ R.T + t).tolist(),
                "diameters": [float(d) for d in FIXTURE["diameters"]]}
    faces = [(N[k], d[k]) for N, d, labels in _block_faces(scene.target) for k in range(len(labels)) if labels[k] in (0, 1)]
    out = {"normals": [(R @ n).tolist() for n, _ in faces], "distances_m": [float(d + (R @ n) @ t) for n, d in faces]}
    if scene.target == "edge":
        out["angle_deg"] = float(BLOCK["angle_deg"])
    else:
        out["height_m"] = float(BLOCK["step"])
    return out


def write_profile(path: str | Path, points: NDArray[np.float64], unit: str = "mm") -> Path:
    """Write one profile (n, 3; metres, y = 0) as a profile file: ``x,z`` in ``unit``, a point
    without a return (NaN) left empty; atomically. Returns the path."""
    f = 1e3 if unit == "mm" else 1.0
    rows = "".join(f"{float(f * x)!r},{'' if not np.isfinite(z) else repr(float(f * z))}\n" for x, z in points[:, [0, 2]])
    atomic_write(path, "x,z\n" + rows)
    return Path(path)


def write_laser_session(folder: str | Path, scene: LaserScene, unit: str = "mm", diameter: bool = True) -> Path:
    """Write a simulated laser capture as a laser session folder (the format in docs/guide.md):
    ``profiles/pNN.csv`` (``x,z`` in ``unit``, NaN left empty), ``poses.csv`` (first column
    ``profile``; quat_wxyz, mm, deg), ``session.yaml`` (``laser:`` with the unit, the range and the noise, the
    target: the ball's diameter unless ``diameter`` is False, the fixture's balls' diameters) and
    ``ground_truth.yaml`` (X, Z and the target's figures). Returns the folder."""
    out = check_output_folder(folder)
    (out / "profiles").mkdir(parents=True, exist_ok=True)
    f = 1e3 if unit == "mm" else 1.0
    names = [f"p{k + 1:02d}.csv" for k in range(len(scene.profiles))]
    for name, p in zip(names, scene.profiles):
        write_profile(out / "profiles" / name, p, unit)
    write_pose_table(out / "poses.csv", names, scene.flange2base, "quat_wxyz", "mm", "deg", id_column="profile")
    target: dict = {"type": scene.target}
    if scene.target == "sphere" and diameter:
        target["diameter"] = 2 * scene.radius
    elif scene.target == "spheres":
        target["diameters"] = [float(d) for d in FIXTURE["diameters"]]
    # the profiler's measuring range too, as a real one states it: the reader checks the profiles against it
    spec = {"setup": scene.setup, "target": target, "laser": {"unit": unit, "range": [f * PROFILER["near"], f * PROFILER["far"]],
                                                              "noise": f * scene.noise_m},
            "poses": {"file": "poses.csv", "format": "quat_wxyz", "length_unit": "mm", "angle_unit": "deg"}}
    if scene.joints is not None:  # the joint angles the controller reports, degrees, as other sessions have them
        write_joint_table(out / "joints.csv", names, scene.joints, id_column="profile")
        spec["joints"] = {"file": "joints.csv", "unit": "deg", "arm": scene.arm}
    atomic_write(out / "session.yaml", yaml.safe_dump(spec, sort_keys=False))
    info = setup_info(scene.setup)
    truth = {"setup": scene.setup, info.x_name: scene.X.tolist(), info.z_name: scene.Z.tolist()}  # result.json's names
    truth |= _target_truth(scene)
    if scene.chain_true is not None:
        truth |= {"arm": scene.arm, "table_true": scene.chain_true.table.tolist()}
    atomic_write(out / "ground_truth.yaml", yaml.safe_dump(truth, sort_keys=False))
    return out


def simulate_command(request: SimulateRequest) -> str:
    """``handeye simulate --sensor laser_line`` (the laser's registration's ``simulate`` hook): a laser
    session of the target ``request.target`` (:data:`TARGETS`, a ball by default) written to
    ``request.out``; returns what was written, in words."""
    if request.robot != "arm":
        raise InputMismatchError("--sensor laser_line simulates a 6-axis arm (its controller's poses, or with --arm its "
                                 "joint angles too); leave --robot out")
    target = request.target or TARGETS[0]
    if target not in TARGETS:
        raise InputMismatchError(f"--target {target}: a laser line profiler scans one of {', '.join(TARGETS)} (--target "
                                 f"{TARGETS[0]} is the default)")
    write_laser_session(request.out, laser_scene(request.poses, request.setup, request.seed, arm=request.arm, target=target))
    what = {"sphere": "a 40 mm ball", "plane": "a 200 mm plate", "edge": "a block's edge", "step": "a 10 mm step",
            "spheres": "a fixture of 3 balls"}[target]
    arm = f", {request.arm}'s joint angles in joints.csv (the arm 1-3 mm off its nominal table)" if request.arm else ""
    return (f"wrote laser session {request.out} ({request.poses} profiles of {what}, {request.setup}{arm}); ground truth in "
            f"{Path(request.out) / 'ground_truth.yaml'}")
