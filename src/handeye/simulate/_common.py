"""What the simulators share: the default targets and camera, a 6-axis arm's nominal table, the
layout of a cell, joint angles that see the target, the camera's and the robot's readings, and the
files every simulated session gets."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from .._shared.io import atomic_write, check_output_folder
from .._shared.lazy import lazy_module
from ..errors import HandEyeError
from ..frames.setups import predicted_target2cam, setup_info
from ..geometry.se3 import invert, make_transform, perturb
from ..robot.kinematics import Chain, absorbed_parameters
from ..sensors.camera.pnp import project_points
from ..sensors.camera.render import Renderer

cv2 = lazy_module("cv2")




#: Targets that ``simulate_session`` renders by default (sizes in metres).
DEFAULT_TARGETS: dict[str, dict] = {
    "chessboard": {"type": "chessboard", "cols": 9, "rows": 6, "square": 0.03},
    "charuco": {"type": "charuco", "cols": 7, "rows": 5, "square": 0.04, "marker": 0.03, "dictionary": "DICT_6X6_250"},
    "circles": {"type": "circles", "cols": 7, "rows": 5, "square": 0.04},
    "asymmetric_circles": {"type": "asymmetric_circles", "cols": 4, "rows": 11, "square": 0.025},
    "apriltag": {"type": "apriltag", "square": 0.12, "id": 3, "dictionary": "DICT_APRILTAG_36h11"},
}


def default_camera(image_size: tuple[int, int]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A plausible camera for an image size: ~50 deg horizontal field of view, mild distortion."""
    w, h = image_size
    f = 1.07 * w
    K = np.array([[f, 0.0, 0.5 * w + 3.7], [0.0, f * 1.001, 0.5 * h - 2.9], [0.0, 0.0, 1.0]])
    dist = np.array([-0.11, 0.09, 3e-4, -2e-4, 0.0])
    return K, dist


#: The smallest image side simulate_session renders (a target must fit in it with a margin).
MIN_IMAGE_SIDE = 64


SIMULATED_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")


def _new_session_folder(out_dir) -> Path:
    """The output folder of a simulated session, checked, and holding no session yet."""
    out = check_output_folder(out_dir)
    if (out / "session.yaml").exists() or (out / "images").exists():
        raise HandEyeError(f"{out} already holds a session; choose an empty folder")
    return out


def _write_images(out: Path, renderer: Renderer, texture, target2cam, rng: np.random.Generator, noise_px: float,
                  blur: float = 0.0, image_ext: str = ".png") -> list[str]:
    """Render the target at each pose into ``out/images`` (000.png, 001.png, ...); their names."""
    (out / "images").mkdir(parents=True, exist_ok=True)
    params = [cv2.IMWRITE_JPEG_QUALITY, 92] if image_ext.lower() in (".jpg", ".jpeg") else []
    names = []
    for k, T in enumerate(target2cam):
        name = f"{k:03d}{image_ext}"
        if not cv2.imwrite(str(out / "images" / name), renderer.render(texture, T, rng=rng, noise_px=noise_px, blur=blur),
                           params):
            raise HandEyeError(f"cannot write {out / 'images' / name}")
        names.append(name)
    return names


def _write_truth(out: Path, setup: str, X, Z, K, dist, seed, **extra) -> None:
    """``ground_truth.yaml``: X and Z under the setup's names, the camera, ``extra``, the seed."""
    info = setup_info(setup)
    truth = {"setup": setup, info.x_name: np.asarray(X).tolist(), info.z_name: np.asarray(Z).tolist(),
             "K": np.asarray(K).tolist(), "dist": np.asarray(dist).tolist(), **extra, "seed": seed}
    atomic_write(out / "ground_truth.yaml", yaml.safe_dump(truth, sort_keys=False))


#: A 6-axis arm (Universal Robots UR5's published standard DH parameters): per joint
#: ``(a, alpha, d, theta offset)``, metres and radians.
ARM_DH = np.array([
    [0.0, np.pi / 2, 0.089159, 0.0],
    [-0.425, 0.0, 0.0, 0.0],
    [-0.39225, 0.0, 0.0, 0.0],
    [0.0, np.pi / 2, 0.10915, 0.0],
    [0.0, -np.pi / 2, 0.09465, 0.0],
    [0.0, 0.0, 0.0823, 0.0],
])


#: Joint angles (rad) where the realistic scenes centre: the flange looks down (eye-in-hand, camera
#: above a table target) or sideways (eye-to-hand, board towards a camera on a stand).
ARM_HOME = {"eye_in_hand": np.radians([0.0, -110.0, 110.0, -90.0, -90.0, 0.0]),
            "eye_to_hand": np.radians([0.0, -110.0, 110.0, -180.0, -90.0, 0.0])}


def arm_forward_kinematics(q: NDArray[np.float64], dh: NDArray[np.float64] = ARM_DH) -> NDArray[np.float64]:
    """``flange2base`` (..., 4, 4) of joint angles ``q`` (..., 6) for standard DH parameters
    ``dh`` (6, 4) or (..., 6, 4) (``a, alpha, d, theta offset`` per joint)."""
    q = np.asarray(q, dtype=float)
    dh = np.broadcast_to(dh, q.shape + (4,))
    th = q + dh[..., 3]
    ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(dh[..., 1]), np.sin(dh[..., 1])
    A = np.zeros(q.shape + (4, 4))
    A[..., 0, 0], A[..., 0, 1], A[..., 0, 2], A[..., 0, 3] = ct, -st * ca, st * sa, dh[..., 0] * ct
    A[..., 1, 0], A[..., 1, 1], A[..., 1, 2], A[..., 1, 3] = st, ct * ca, -ct * sa, dh[..., 0] * st
    A[..., 2, 1], A[..., 2, 2], A[..., 2, 3] = sa, ca, dh[..., 2]
    A[..., 3, 3] = 1.0
    T = A[..., 0, :, :]
    for k in range(1, 6):
        T = T @ A[..., k, :, :]
    return T


@dataclass(frozen=True)
class RealisticErrors:
    """The errors of a real capture (defaults: a calibrated industrial arm, a good camera).

    * kinematics: the robot reports the forward kinematics of its nominal DH parameters while the
      arm follows perturbed ones (``dh_length_mm``, ``dh_angle_deg`` per parameter, joint zero
      offsets included): a systematic error that depends on the pose, ~0.5-1 mm at the flange;
    * ``joint_wave_deg``: a smooth joint-dependent error on top (gear eccentricity, compliance): each
      joint turns ``joint_wave_deg * sin(q + phase)`` more than commanded, a random phase per joint;
    * ``robot_rot_deg``, ``robot_mm``: random pose noise on top, Student-t with ``robot_dof``
      degrees of freedom (heavy tails; the scale is the t's, not a standard deviation);
    * ``jitter_ms``: the pose is read that long (Gaussian, std) before or after the image while the
      arm still moves at ``speed_mm_s`` / ``speed_deg_s`` along a random direction;
    * camera: the target's points are projected with ``pixel_px`` Gaussian pixel noise and the pose
      is solved by PnP (IPPE + Levenberg-Marquardt), so its error grows along the optical axis as a
      real PnP's does; with probability ``flip_probability`` the other planar solution is kept (the
      flipped-pose outlier of planar targets).
    """

    dh_length_mm: float = 0.3
    dh_angle_deg: float = 0.02
    robot_rot_deg: float = 0.01
    robot_mm: float = 0.03
    robot_dof: float = 3.0
    jitter_ms: float = 3.0
    speed_mm_s: float = 50.0
    speed_deg_s: float = 10.0
    pixel_px: float = 0.3
    flip_probability: float = 0.02
    joint_wave_deg: float = 0.0

    def scaled(self, factor: float) -> "RealisticErrors":
        """The same errors with the robot's kinematic part (DH errors and joint waves) ``factor`` times
        as large: the sweep from a calibrated arm (~0.2 mm absolute error at 0.25) to an
        uncalibrated one (~3 mm at 3; measured by :func:`robot_accuracy_of`)."""
        if not (np.isfinite(factor) and factor >= 0):
            raise HandEyeError(f"factor={factor!r}: give a finite factor >= 0")
        return replace(self, dh_length_mm=factor * self.dh_length_mm, dh_angle_deg=factor * self.dh_angle_deg,
                       joint_wave_deg=factor * self.joint_wave_deg)


#: The preset that mixes every error above at its default level.
REALISTIC = RealisticErrors()


#: No error at all (the same scenes, for ground-truth checks).
EXACT = RealisticErrors(0.0, 0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def scene_layout(setup: str, object_points: NDArray[np.float64], rng: np.random.Generator,
                  home: NDArray[np.float64] | None = None):
    """X and Z of a realistic cell: the camera 5-10 cm off the flange looking along it (eye-in-hand)
    or on a stand 0.6-0.8 m in front of the board on the flange (eye-to-hand). ``home``: the arm's
    flange pose at the centre of the capture (default :data:`ARM_DH`'s at :data:`ARM_HOME`)."""
    home = arm_forward_kinematics(ARM_HOME[setup]) if home is None else home
    centre = 0.5 * (object_points.min(axis=0) + object_points.max(axis=0))
    tilt = make_transform(Rotation.from_rotvec(rng.normal(0.0, np.radians(5.0), 3)).as_matrix(), np.zeros(3))
    if setup_info(setup).camera_on_flange:
        X = make_transform(Rotation.from_euler("z", rng.uniform(-180, 180), degrees=True).as_matrix()
                           @ tilt[:3, :3], rng.uniform(-0.07, 0.07, 3) * [1, 1, 0.5])
        cam = home @ X
        standoff = rng.uniform(0.35, 0.5)
        # the target centre on the optical axis, printed side towards the camera (z along the view)
        R_t = cam[:3, :3] @ Rotation.from_euler("z", rng.uniform(-180, 180), degrees=True).as_matrix()
        Z = make_transform(R_t, cam[:3, 3] + standoff * cam[:3, 2] - R_t @ centre)
        return X, Z
    Z = make_transform(Rotation.from_euler("x", 180, degrees=True).as_matrix() @ tilt[:3, :3],
                       [rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03), 0.02])
    target = home @ Z
    R_c = target[:3, :3] @ Rotation.from_euler("z", rng.uniform(-180, 180), degrees=True).as_matrix()
    c = target[:3, :3] @ centre + target[:3, 3]
    X = make_transform(R_c, c - rng.uniform(0.6, 0.8) * R_c[:, 2])
    return X, Z


def sample_joints(setup, X, Z, object_points, K, image_size, n, rng, margin_px=10.0, spread_deg=(25, 25, 25, 40, 40, 60),
                   chain=None):
    """Joint angles around the home pose whose views see the whole target, 0.25-1.2 m away and
    less than 60 deg from face-on (``chain``: another arm than :data:`ARM_DH`, its home and spread)."""
    forward = arm_forward_kinematics if chain is None else chain.forward
    out = []
    for _ in range(50):
        if chain is None:
            q = ARM_HOME[setup] + np.radians(rng.uniform(-1, 1, (400, 6)) * spread_deg)
        else:
            q = chain.home[setup] + rng.uniform(-1, 1, (400, chain.n_joints)) * chain.spread
        t2c = predicted_target2cam(X, Z, forward(q), setup)
        out.extend(q[_sees_target(t2c, object_points, K, image_size, margin_px)])
        if len(out) >= n:
            return np.array(out[:n])
    raise HandEyeError(f"could not find {n} views of the target for the realistic {setup} scene")


def _sees_target(t2c: NDArray[np.float64], object_points: NDArray[np.float64], K: NDArray[np.float64],
                 image_size: tuple[int, int], margin_px: float = 10.0) -> NDArray[np.bool_]:
    """Per view: the whole target in the image (``margin_px`` from the border), 0.25-1.2 m away
    and less than 60 deg from face-on."""
    w, h = image_size
    p = np.einsum("nij,mj->nmi", t2c[:, :3, :3], object_points) + t2c[:, None, :3, 3]
    z = p[..., 2]
    ok = (z.min(axis=1) > 0.25) & (z.max(axis=1) < 1.2) & (t2c[:, 2, 2] > np.cos(np.radians(60)))
    uv = np.einsum("ij,nmj->nmi", K[:2, :2], p[..., :2] / np.where(z > 0, z, 1.0)[..., None]) + K[:2, 2]
    return ok & ((uv[..., 0] > margin_px) & (uv[..., 0] < w - margin_px) & (uv[..., 1] > margin_px)
                 & (uv[..., 1] < h - margin_px)).all(axis=1)


def _camera_reading(target2cam_true, object_points, K, dist, errors: RealisticErrors, rng):
    """Noisy detections, and the PnP pose of each (sometimes the flipped planar solution)."""
    obj = np.ascontiguousarray(object_points, dtype=np.float64)
    n = len(target2cam_true)
    image_points = np.stack([project_points(T, obj, K, dist) for T in target2cam_true])
    image_points = image_points + rng.normal(0.0, errors.pixel_px, image_points.shape)
    flipped = rng.random(n) < errors.flip_probability
    poses = np.empty((n, 4, 4))
    for i in range(n):
        img = np.ascontiguousarray(image_points[i])
        if errors.pixel_px == 0 and not flipped[i]:
            poses[i] = target2cam_true[i]
            continue
        _, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, img, K, dist, flags=cv2.SOLVEPNP_IPPE)
        k = 1 if flipped[i] and len(rvecs) > 1 else 0
        flipped[i] = k == 1
        rvec, tvec = rvecs[k], tvecs[k]
        if k == 0:  # refined from the other solution, LM would often slide back to this one
            rvec, tvec = cv2.solvePnPRefineLM(obj, img, K, dist, rvec, tvec)
        poses[i] = make_transform(Rotation.from_rotvec(rvec.ravel()).as_matrix(), tvec.ravel())
    return poses, image_points, flipped


def real_chain(chain: Chain, rng: np.random.Generator, length_mm: float, angle_deg: float,
                compliance_deg_per_m: float = 0.0) -> Chain:
    """The arm as built: every entry of ``chain``'s table it owns (not one X or Z absorbs) off by
    Gaussian ``length_mm`` or ``angle_deg``, and each joint's compliance 0.5-1.5x
    ``compliance_deg_per_m`` (uniform) when that is positive."""
    deltas = np.zeros(chain.table.size)
    absorbed = set(absorbed_parameters(chain))
    for k, name in enumerate(chain.parameter_names()):
        if name not in absorbed:
            deltas[k] = (np.radians(rng.normal(0.0, angle_deg)) if name.endswith((".alpha", ".theta"))
                         else 1e-3 * rng.normal(0.0, length_mm))
    true = chain.corrected(deltas)
    if compliance_deg_per_m > 0:
        true = replace(true, compliance=np.radians(compliance_deg_per_m) * rng.uniform(0.5, 1.5, chain.n_joints))
    return true


#: A sensor on the flange (eye-in-hand) or a target on it (eye-to-hand) sits this far (m) out along the
#: flange's axis, and up to this far (m) off it (:func:`arm_mount`).
MOUNT_M = (0.05, 0.10)


def arm_mount(chain: Chain, setup: str, rng: np.random.Generator, standoff: float
              ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """X and Z of a cell built about ``chain``'s home for ``setup``: the sensor (eye-in-hand) or the
    target (eye-to-hand, turned to face away from the flange) mounted on the flange
    (:data:`MOUNT_M`, tilted ~5 deg, any turn about the flange's axis), and at home the sensor
    looking down its z axis at the target's origin from ``standoff`` (m)."""
    flange_home = chain.forward(chain.home[setup][None])[0]
    mount = make_transform(Rotation.from_rotvec(rng.normal(0.0, np.radians(5.0), 3)).as_matrix()
                           @ Rotation.from_euler("z", rng.uniform(-180, 180), degrees=True).as_matrix(),
                           rng.uniform(-1, 1, 3) * [MOUNT_M[1], MOUNT_M[1], 0.0] + [0.0, 0.0, MOUNT_M[0]])
    above = make_transform(Rotation.from_euler("x", 180, degrees=True).as_matrix(), [0.0, 0.0, standoff])  # sensor2target
    if setup_info(setup).camera_on_flange:  # X: the sensor on the flange; Z: the target below it at home
        return mount, flange_home @ mount @ invert(above)
    Z = mount @ make_transform(Rotation.from_euler("x", 180, degrees=True).as_matrix(), np.zeros(3))
    return flange_home @ Z @ above, Z  # X: the sensor above the target at home


def reaching(chain: Chain, flange2base: NDArray[np.float64], q0: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """Joint angles from ``q0`` that take ``chain``'s flange to ``flange2base`` (least squares), and
    how far they leave it (rad, and m / 0.1 m)."""
    base2flange = invert(flange2base)

    def gaps(Q):  # (k, n) joint angles at once: one batched forward kinematics
        E = base2flange @ chain.forward(Q)
        return np.c_[Rotation.from_matrix(E[:, :3, :3]).as_rotvec(), E[:, :3, 3] / 0.1]

    def gap(q):
        return gaps(q[None])[0]

    def jac(q):  # forward differences, every joint's step in one call (a line-scan scene spent 5.7 s in single calls)
        h = 1.5e-8 * np.maximum(1.0, np.abs(q))
        G = gaps(np.vstack([q, q + np.diag(h)]))
        return ((G[1:] - G[0]) / h[:, None]).T

    # a redundant arm (7 joints): more unknowns than the pose's 6, which Levenberg-Marquardt refuses
    res = least_squares(gap, q0, jac, method="lm" if len(q0) <= 6 else "trf", xtol=1e-14, ftol=1e-14)
    return res.x, float(np.max(np.abs(res.fun)))


def reported_poses(flange2base: NDArray[np.float64], error: tuple[float, float] | None, rng: np.random.Generator):
    """The controller's flange poses: off by a constant error (the arm's absolute error over a
    small capture) and heavy-tailed noise per pose (Student-t, 3 dof), each of ``error`` (deg, mm)
    per axis; the true ones when ``error`` is None."""
    if error is None:
        return flange2base
    n = len(flange2base)
    rot = np.radians(error[0]) * (rng.normal(0.0, 1.0, 3) + rng.standard_t(3, (n, 3)))
    tra = 1e-3 * error[1] * (rng.normal(0.0, 1.0, 3) + rng.standard_t(3, (n, 3)))
    return perturb(flange2base, rot, tra)


def _robot_reading(q, flange2base_true, errors: RealisticErrors, rng):
    """What the controller reports: nominal kinematics at ``q`` (the arm follows perturbed ones:
    the caller's ``flange2base_true``), read a little off in time, with heavy-tailed noise."""
    reported = arm_forward_kinematics(q)  # nominal parameters
    n = len(q)
    if errors.jitter_ms > 0:
        dt = 1e-3 * rng.normal(0.0, errors.jitter_ms, n)
        direction = rng.normal(size=(n, 2, 3))
        direction /= np.linalg.norm(direction, axis=2, keepdims=True)
        reported = perturb(reported, np.radians(errors.speed_deg_s) * dt[:, None] * direction[:, 0],
                           1e-3 * errors.speed_mm_s * dt[:, None] * direction[:, 1])
    if errors.robot_rot_deg > 0 or errors.robot_mm > 0:
        rot = np.radians(errors.robot_rot_deg) * rng.standard_t(errors.robot_dof, (n, 3))
        tra = 1e-3 * errors.robot_mm * rng.standard_t(errors.robot_dof, (n, 3))
        reported = perturb(reported, rot, tra)
    return reported
