"""Simulated markerless captures: a fixed colour camera sees a Panda; the session holds its masks.

:func:`silhouette_scene` poses the arm (the Franka Panda's meshes from rtb-data, with its hand) at
joint angles spread about its home, puts a camera (640x480 by default) 1-2 m from the arm looking
at it, and renders each view's mask of the arm the way a segmentation gives it: the silhouette
drawn at twice the resolution and averaged down, its boundary moved by a smooth random field of
``boundary_px`` (a ragged edge, off by about a pixel), and a few blobs (``blobs`` per view: false
detections beside the arm and holes in it). With ``table_mm`` / ``table_deg`` the real arm's table
differs from the nominal one by that much (Gaussian, per entry); the session gives the nominal arm.

:func:`write_silhouette_session` writes it as a silhouette session (:mod:`handeye.pipelines.silhouette.session`)
with ``ground_truth.yaml``.

Examples
--------
>>> scene = silhouette_scene(3, rng=0)
>>> scene.masks.shape
(3, 480, 640)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import NDArray

from ..._shared.io import atomic_write, check_output_folder, write_png
from ..._shared.lazy import lazy_module
from ...errors import InputMismatchError
from ...geometry.se3 import make_transform
from ...robot.kinematics import Chain, load_arm
from ...robot.meshes import arm_meshes
from ...sensors.silhouette.render import render_silhouettes, signed_distance
from ..kinds import SimulateRequest

cv2 = lazy_module("cv2")

__all__ = ["SilhouetteScene", "silhouette_scene", "write_silhouette_session", "segmentation_errors", "simulate_command"]


@dataclass(frozen=True)
class SilhouetteScene:
    """A simulated markerless capture: the truth and what the session holds."""

    X: NDArray[np.float64]  #: cam2base, the truth
    joints: NDArray[np.float64]  #: (N, 7) rad, as the controller reports them
    K: NDArray[np.float64]
    image_size: tuple[int, int]
    masks: NDArray[np.bool_] = field(repr=False)  #: (N, height, width)
    chain: Chain = field(repr=False)  #: the nominal arm
    chain_true: Chain = field(repr=False)  #: the arm the masks were drawn with

    @property
    def setup(self) -> str:
        """Always eye-to-hand: the camera is fixed and sees the arm."""
        return "eye_to_hand"


def _look_at(eye: NDArray[np.float64], target: NDArray[np.float64], rng: np.random.Generator) -> NDArray[np.float64]:
    """cam2base of a camera at ``eye`` looking at ``target``, upright (image y down) within a few degrees."""
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    roll = np.radians(rng.uniform(-8, 8))
    x, y = np.cos(roll) * x + np.sin(roll) * y, -np.sin(roll) * x + np.cos(roll) * y
    return make_transform(np.c_[x, y, z], eye)


def segmentation_errors(mask: NDArray[np.bool_], rng: np.random.Generator, boundary_px: float = 1.0, blobs: int = 2,
                        correlation_px: float = 2.0) -> NDArray[np.bool_]:
    """A mask as a segmentation gives it: the boundary moved by a smooth random field of
    ``boundary_px`` (std; correlated over ``correlation_px``) and ``blobs`` small false blobs near the
    arm or holes in it (3-8 px across)."""
    h, w = mask.shape
    noise = rng.normal(0.0, 1.0, (h, w)).astype(np.float32)
    noise = cv2.GaussianBlur(noise, (0, 0), correlation_px)
    noise *= boundary_px / max(float(noise.std()), 1e-9)
    out = (signed_distance(mask) + noise) < 0
    edge = np.argwhere(np.abs(signed_distance(mask)) < 15)
    for _ in range(blobs if len(edge) else 0):
        i, j = edge[rng.integers(len(edge))]
        r = int(rng.integers(3, 9))
        cv2.circle(out.view(np.uint8), (int(j), int(i)), r // 2, int(rng.random() < 0.5), -1)
    return out


#: The exact masks are drawn this many times finer and averaged down ...
SUPERSAMPLE = 4
#: ... a pixel set where this share of it is covered: OpenCV fills half a fine pixel beyond the
#: outline, which a boundary pixel gains in coverage (measured on turned squares: 0.68 leaves the
#: boundary within 0.02 px of the exact one, 0.5 puts it 0.17 px out).
COVERED = 0.68


def _supersampled(vertices: NDArray[np.float64], faces: NDArray[np.intp], K: NDArray[np.float64], size: tuple[int, int]
                  ) -> NDArray[np.bool_]:
    """The exact silhouettes (N, height, width): drawn :data:`SUPERSAMPLE` times finer, averaged down."""
    k, (w, h) = SUPERSAMPLE, size
    Kf = K.copy()
    Kf[:2] *= k
    Kf[:2, 2] += (k - 1) / 2  # the fine image's pixel centres
    fine = render_silhouettes(vertices, faces, Kf, (k * w, k * h))
    return np.array([cv2.resize(m.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA) >= COVERED for m in fine])


def _table(chain: Chain, rng: np.random.Generator, length_mm: float, angle_deg: float) -> Chain:
    if not length_mm and not angle_deg:
        return chain
    d = np.zeros_like(chain.table)
    d[:, [0, 2]] = rng.normal(0.0, 1e-3 * length_mm, (chain.n_joints, 2))
    d[:, [1, 3]] = rng.normal(0.0, np.radians(angle_deg), (chain.n_joints, 2))
    return chain.corrected(d)


def silhouette_scene(n_views: int = 10, rng: np.random.Generator | int | None = None, *, arm: str = "panda",
                     image_size: tuple[int, int] = (640, 480), focal_px: float = 525.0, distance: tuple[float, float] = (1.0, 2.0),
                     spread: float = 0.6, boundary_px: float = 1.0, blobs: int = 2, correlation_px: float = 2.0,
                     table_mm: float = 0.0, table_deg: float = 0.0) -> SilhouetteScene:
    """A simulated markerless capture (the module's docstring).

    Parameters
    ----------
    n_views : int
    rng : Generator or int, optional
    arm : str
        An arm whose meshes handeye has (:func:`handeye.robot.meshes.mesh_arm_names`).
    image_size : (int, int)
        Width, height (pixels).
    focal_px : float
    distance : (float, float)
        The camera's distance from the arm's centre (m), drawn uniformly.
    spread : float
        The share of the arm's simulator spread (``Chain.spread``) the joints move by about home.
    boundary_px, blobs, correlation_px
        The segmentation's errors (:func:`segmentation_errors`).
    table_mm, table_deg
        The real arm's table off by this much per entry (std; 0: exact).
    """
    if n_views < 1:
        raise InputMismatchError(f"{n_views} views: give at least 1")
    rng = np.random.default_rng(rng)
    chain = load_arm(arm)
    meshes = arm_meshes(arm)
    true = _table(chain, rng, table_mm, table_deg)
    home = chain.home["eye_to_hand"]
    spread_rad = chain.spread if chain.spread is not None else np.full(chain.n_joints, 0.5)
    q = home + spread * spread_rad * rng.uniform(-1.0, 1.0, (n_views, chain.n_joints))
    if chain.limits is not None:
        q = np.clip(q, chain.limits[:, 0] + 0.05, chain.limits[:, 1] - 0.05)
    vertices = meshes.posed_vertices(meshes.link2base(true, q))
    centre = vertices.reshape(-1, 3).mean(axis=0)
    azimuth, elevation = rng.uniform(0, 2 * np.pi), np.radians(rng.uniform(5, 35))
    eye = centre + rng.uniform(*distance) * np.array([np.cos(elevation) * np.cos(azimuth),
                                                      np.cos(elevation) * np.sin(azimuth), np.sin(elevation)])
    X = _look_at(eye, centre, rng)
    w, h = int(image_size[0]), int(image_size[1])
    K = np.array([[focal_px, 0.0, (w - 1) / 2], [0.0, focal_px, (h - 1) / 2], [0.0, 0.0, 1.0]])
    fine = _supersampled((vertices - X[:3, 3]) @ X[:3, :3], meshes.merged()[1], K, (w, h))
    masks = np.array([segmentation_errors(m, rng, boundary_px, blobs, correlation_px) for m in fine])
    return SilhouetteScene(X, q, K, (w, h), masks, chain, true)


def write_silhouette_session(folder: str | Path, scene: SilhouetteScene) -> Path:
    """Write ``scene`` as a silhouette session: ``masks/viewNN.png`` (0 and 255), ``joints.csv``
    (rad), ``session.yaml`` and ``ground_truth.yaml``. Returns the folder."""
    out = check_output_folder(folder)
    (out / "masks").mkdir(parents=True, exist_ok=True)
    names = [f"view{k + 1:02d}.png" for k in range(len(scene.masks))]
    for name, mask in zip(names, scene.masks):
        write_png(out / "masks" / name, mask.astype(np.uint8) * 255)
    header = "image," + ",".join(f"q{j + 1}" for j in range(scene.joints.shape[1]))
    rows = [f"{n}," + ",".join(f"{v:.9f}" for v in q) for n, q in zip(names, scene.joints)]
    atomic_write(out / "joints.csv", "\n".join([header] + rows) + "\n")
    spec = {"setup": "eye_to_hand", "target": {"type": "robot"}, "camera": {"K": np.round(scene.K, 9).tolist()},
            "silhouette": {"masks": "masks"}, "joints": {"file": "joints.csv", "unit": "rad", "arm": scene.chain.name.lower()}}
    atomic_write(out / "session.yaml", yaml.safe_dump(spec, sort_keys=False))
    truth = {"setup": "eye_to_hand", "cam2base": scene.X.tolist(),
             "table_error": (scene.chain_true.table - scene.chain.table).tolist()}
    atomic_write(out / "ground_truth.yaml", yaml.safe_dump(truth, sort_keys=False))
    return out


def simulate_command(request: SimulateRequest) -> str:
    """``handeye simulate --sensor silhouette`` (the colour camera's registration's ``simulate`` hook):
    a silhouette session of a Panda written to ``request.out``; returns what was written, in words."""
    if request.robot != "arm" or request.target is not None or request.arm not in (None, "panda"):
        raise InputMismatchError("--sensor silhouette simulates a Panda seen by a fixed camera (eye_to_hand), no target; "
                                 "leave --robot and --target out")
    sc = silhouette_scene(request.poses, request.seed, image_size=request.image_size)
    write_silhouette_session(request.out, sc)
    return (f"wrote silhouette session {request.out} ({request.poses} masks of a Panda, {request.image_size[0]}x"
            f"{request.image_size[1]}, eye_to_hand, the masks' boundary off by ~1 px with a few blobs); ground truth in "
            f"{Path(request.out) / 'ground_truth.yaml'}")
