"""Synthetic hand-eye scenes with ground truth, for tests, examples and the simulation study.

A scene is a set of camera viewpoints of the target (the camera looks at the target from a cone
of directions about its normal, as in the thesis's §5.2 set-up), turned into robot poses through
the ground-truth ``X`` and ``Z``:

* eye-in-hand: ``X = cam2flange``, ``Z = target2base``; ``flange2base_i = Z @ cam2target_i @ inv(X)``.
* eye-to-hand: ``X = cam2base``, ``Z = target2flange``; ``flange2base_i = X @ target2cam_i @ inv(Z)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from .geometry.se3 import invert, make_transform, random_rotations
from .motions import check_setup

__all__ = ["Scene", "random_scene", "look_at_viewpoints", "perturb_poses"]


@dataclass(frozen=True)
class Scene:
    """Ground truth and noise-free measurements of a simulated capture."""

    setup: str
    X: NDArray[np.float64]  #: cam2flange (eye_in_hand) or cam2base (eye_to_hand)
    Z: NDArray[np.float64]  #: target2base (eye_in_hand) or target2flange (eye_to_hand)
    flange2base: NDArray[np.float64]
    target2cam: NDArray[np.float64]


def look_at_viewpoints(
    n: int,
    rng: np.random.Generator,
    distance: tuple[float, float] = (0.5, 1.0),
    tilt_max_deg: float = 45.0,
    aim_jitter: float = 0.05,
) -> NDArray[np.float64]:
    """``cam2target`` poses of a camera looking at the target's origin.

    The viewing direction lies within ``tilt_max_deg`` of the target normal (+z), the distance is
    uniform in ``distance`` (m), the roll about the optical axis is free, and the aim point is
    jittered by ``aim_jitter`` (m) so that the target is not always in the image centre.
    """
    # Directions uniform over the spherical cap of half-angle tilt_max about +z.
    cos_max = np.cos(np.radians(tilt_max_deg))
    cz = rng.uniform(cos_max, 1.0, n)
    phi = rng.uniform(0.0, 2 * np.pi, n)
    sz = np.sqrt(1.0 - cz**2)
    direction = np.stack([sz * np.cos(phi), sz * np.sin(phi), cz], axis=1)
    centre = direction * rng.uniform(*distance, n)[:, None]
    aim = rng.uniform(-aim_jitter, aim_jitter, (n, 3)) * [1.0, 1.0, 0.0]
    z = aim - centre
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    # Any x orthogonal to z, then a free roll about z.
    helper = np.where(np.abs(z[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(z, x)
    R = np.stack([x, y, z], axis=2)
    roll = Rotation.from_rotvec(np.outer(rng.uniform(-np.pi, np.pi, n), [0.0, 0.0, 1.0])).as_matrix()
    return make_transform(R @ roll, centre)


def random_scene(
    n_poses: int,
    setup: str = "eye_in_hand",
    rng: np.random.Generator | int | None = None,
    *,
    x_translation: float = 0.05,
    distance: tuple[float, float] = (0.5, 1.0),
    tilt_max_deg: float = 45.0,
) -> Scene:
    """A random noise-free scene.

    Parameters
    ----------
    n_poses : int
    setup : {'eye_in_hand', 'eye_to_hand'}
    rng : numpy Generator or seed
    x_translation : float
        Eye-in-hand: the camera offset on the flange is uniform in +-``x_translation`` (m) per axis
        with a uniformly random rotation (thesis §5.2: +-50 mm). Eye-to-hand: the target offset on
        the flange, likewise.
    distance, tilt_max_deg
        Viewpoint distribution, see :func:`look_at_viewpoints`.
    """
    check_setup(setup)
    rng = np.random.default_rng(rng)
    cam2target = look_at_viewpoints(n_poses, rng, distance=distance, tilt_max_deg=tilt_max_deg)
    target2cam = invert(cam2target)
    offset = make_transform(random_rotations(1, rng)[0], rng.uniform(-x_translation, x_translation, 3))
    if setup == "eye_in_hand":
        X = offset
        Z = make_transform(random_rotations(1, rng)[0], rng.uniform(-0.5, 0.5, 3) + [0.6, 0.0, 0.0])
        flange2base = Z @ cam2target @ invert(X)
    else:
        Z = offset
        X = make_transform(random_rotations(1, rng)[0], rng.uniform(-0.5, 0.5, 3) + [1.0, 0.0, 0.5])
        flange2base = X @ target2cam @ invert(Z)
    return Scene(setup, X, Z, flange2base, target2cam)


def perturb_poses(
    T: NDArray[np.float64],
    rot_sigma_rad: float,
    trans_sigma_m: float,
    rng: np.random.Generator,
) -> NDArray[np.float64]:
    """Poses with Gaussian noise: a random rotation vector (sigma per axis) and translation offset."""
    T = np.asarray(T, dtype=float)
    n = T.reshape(-1, 4, 4).shape[0]
    dR = Rotation.from_rotvec(rng.normal(0.0, rot_sigma_rad, (n, 3))).as_matrix()
    noisy = T.reshape(-1, 4, 4).copy()
    noisy[:, :3, :3] = dR @ noisy[:, :3, :3]
    noisy[:, :3, 3] += rng.normal(0.0, trans_sigma_m, (n, 3))
    return noisy.reshape(T.shape)
