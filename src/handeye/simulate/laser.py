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

from .._shared.io import atomic_write, check_output_folder
from ..frames.setups import check_setup, setup_info
from ..geometry.se3 import invert, make_transform
from ..io.session import write_pose_table
from ._common import _reported
from .scenes import Scene, scene_from_viewpoints

__all__ = ["LaserScene", "laser_scene", "write_laser_session", "PROFILER"]

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


def _sensor_views(n: int, radius: float, rng: np.random.Generator, cone_deg: float) -> NDArray[np.float64]:
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
             * Rotation.from_euler("z", rng.uniform(-180, 180), degrees=True)).as_matrix()
        out[k] = make_transform(R, -R @ centre)
    return out


def _profile(target2sensor: NDArray[np.float64], radius: float, rng: np.random.Generator, noise_m: float,
             dropout: float, spikes: float) -> NDArray[np.float64]:
    """What the profiler measures of the ball at ``target2sensor``: per x across its field of view the
    nearest point of the ball in its laser plane, with ``noise_m`` along z, a share ``dropout`` without
    return and a share ``spikes`` of stray points 0.5-3 mm off; outside the range or the ball: NaN."""
    near, far, fov, n = PROFILER["near"], PROFILER["far"], PROFILER["fov"], PROFILER["points"]
    cx, h, cz = target2sensor[:3, 3]
    x = np.linspace(-0.5 * fov, 0.5 * fov, n)
    inside = radius**2 - h**2 - (x - cx) ** 2
    z = np.where(inside > 0, cz - np.sqrt(np.maximum(inside, 0.0)), np.nan)
    z = z + rng.normal(0.0, noise_m, n)
    stray = rng.random(n) < spikes
    z[stray] += rng.choice([-1.0, 1.0], int(stray.sum())) * rng.uniform(5e-4, 3e-3, int(stray.sum()))
    z[(rng.random(n) < dropout) | (z < near) | (z > far)] = np.nan
    return np.c_[x, np.zeros(n), z]


def laser_scene(n_views: int = 20, setup: str = "eye_in_hand", rng: np.random.Generator | int | None = None, *,
                radius: float = 0.02, noise_m: float = 2e-5, dropout: float = 0.02, spikes: float = 0.002,
                cone_deg: float = 45.0, robot_error: tuple[float, float] | None = None) -> LaserScene:
    """A laser profiler's capture of a ball of ``radius`` (m): fixed in the cell and scanned by the
    profiler on the flange (eye-in-hand), or on the flange in front of a fixed profiler (eye-to-hand).

    ``n_views`` profiles (:data:`PROFILER`: 80 mm field of view, 80-160 mm range, 2,000 points), each
    from a direction within ``cone_deg`` of the ball's top, the laser plane cutting the ball up to
    0.8 of its radius off its centre on either side; depth noise ``noise_m`` (m), a share ``dropout``
    of points without return, a share ``spikes`` of stray points 0.5-3 mm off. ``robot_error`` (deg,
    mm): the reported flange poses are off by a constant and a heavy-tailed error per pose of that
    size per axis (``flange2base`` is what the controller reports; None: exact).

    Examples
    --------
    >>> sc = laser_scene(5, "eye_in_hand", rng=0)
    >>> len(sc.profiles), sc.profiles[0].shape
    (5, (2000, 3))
    """
    check_setup(setup)
    rng = np.random.default_rng(rng)
    sensor2target = _sensor_views(n_views, radius, rng, cone_deg)
    scene = scene_from_viewpoints(sensor2target, setup, rng)
    profiles = [_profile(T, radius, rng, noise_m, dropout, spikes) for T in invert(sensor2target)]
    return LaserScene(setup, scene.X, scene.Z, _reported(scene.flange2base, robot_error, rng), scene.target2cam,
                      profiles=profiles, radius=radius, noise_m=noise_m, flange2base_true=scene.flange2base)


def write_laser_session(folder: str | Path, scene: LaserScene, unit: str = "mm", diameter: bool = True) -> Path:
    """Write a simulated laser capture as a laser session folder (the format in docs/guide.md):
    ``profiles/pNN.csv`` (``x,z`` in ``unit``, NaN left empty), ``poses.csv`` (first column
    ``profile``; quat_wxyz, mm, deg), ``session.yaml`` (``laser:`` with the unit and the noise, the
    ball's diameter unless ``diameter`` is False) and ``ground_truth.yaml``. Returns the folder."""
    out = check_output_folder(folder)
    (out / "profiles").mkdir(parents=True, exist_ok=True)
    f = 1e3 if unit == "mm" else 1.0
    names = [f"p{k + 1:02d}.csv" for k in range(len(scene.profiles))]
    for name, p in zip(names, scene.profiles):
        rows = "".join(f"{float(f * x)!r},{'' if not np.isfinite(z) else repr(float(f * z))}\n" for x, z in p[:, [0, 2]])
        atomic_write(out / "profiles" / name, "x,z\n" + rows)
    write_pose_table(out / "poses.csv", names, scene.flange2base, "quat_wxyz", "mm", "deg", id_column="profile")
    target: dict = {"type": "sphere"} | ({"diameter": 2 * scene.radius} if diameter else {})
    spec = {"setup": scene.setup, "target": target, "laser": {"unit": unit, "noise": f * scene.noise_m},
            "poses": {"file": "poses.csv", "format": "quat_wxyz", "length_unit": "mm", "angle_unit": "deg"}}
    atomic_write(out / "session.yaml", yaml.safe_dump(spec, sort_keys=False))
    info = setup_info(scene.setup)
    truth = {"setup": scene.setup, info.x_name.replace("cam", "sensor"): scene.X.tolist(),
             info.z_name: scene.Z.tolist(), "radius_m": float(scene.radius)}
    atomic_write(out / "ground_truth.yaml", yaml.safe_dump(truth, sort_keys=False))
    return out
