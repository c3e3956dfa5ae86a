"""Markerless colour sessions read and checked: a fixed camera sees the robot; no target.

```yaml
setup: eye_to_hand                  # the camera is fixed and sees the arm: X = cam2base
target: {type: robot}               # optional: hand: true (the maker's gripper, default), finger_opening: 0.0 (m)
camera: {K: [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], dist: [k1, k2, p1, p2, k3]}   # required; dist optional
silhouette: {masks: masks}          # the masks' folder (default masks); optional images: images
joints: {file: joints.csv, unit: rad, arm: panda}   # an arm handeye has meshes of
```
``joints.csv``: a header ``image,q1,...,q7``, then per view the mask's file name (in ``masks/``)
and its joint angles. A mask is an 8-bit image (PNG, ...), the arm's pixels set (any value above
127); the colour images in ``images/`` (same names) are optional: the report draws on them.
Nothing is measured here (:mod:`handeye.pipelines.silhouette.pipeline` does that).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..._shared.lazy import lazy_module
from ..._shared.text import shown
from ...errors import InputMismatchError, SessionError
from ...frames.setups import check_setup, setup_info
from ...io.extras import needed
from ...io.session import (
    CAMERA_KEYS,
    JOINTS_KEYS,
    check_keys,
    check_session_keys,
    read_camera,
    read_joints,
    read_session_yaml,
    session_file,
)
from ...robot.kinematics import Chain
from ...robot.meshes import ArmMeshes, meshes_for
from ..depth.session import ARM_KEYS, arm_hand

cv2 = lazy_module("cv2")

__all__ = ["SilhouetteSession", "load_silhouette_session", "read_mask", "read_masks", "SILHOUETTE_KEYS",
           "ROBOT_TARGET_KEYS", "extras"]

#: The keys of ``silhouette:``.
SILHOUETTE_KEYS = ("masks", "images")
#: The keys of ``target:`` (``type: robot``).
ROBOT_TARGET_KEYS = ARM_KEYS


@dataclass(frozen=True)
class SilhouetteSession:
    """A markerless colour session's inputs, read and checked (masks not read yet)."""

    folder: Path
    setup: str
    names: list[str]  #: per view: the mask's file name
    mask_paths: list[Path]
    image_paths: list[Path | None]  #: the colour image of each view, where there is one
    joints: NDArray[np.float64]  #: (N, n) rad
    arm: Chain
    meshes: ArmMeshes
    K: NDArray[np.float64]
    dist: NDArray[np.float64] | None
    joints_path: Path
    notes: list[str] = field(default_factory=list)

    @property
    def flange2base(self) -> NDArray[np.float64]:
        """The nominal table's flange poses."""
        return self.arm.forward(self.joints)

    @property
    def input_files(self) -> list[Path]:
        """Every file the session is read from."""
        return [self.folder / "session.yaml", self.joints_path] + list(self.mask_paths) + [p for p in self.image_paths if p]



def read_mask(path: Path, size: tuple[int, int] | None = None) -> NDArray[np.bool_]:
    """A mask file as booleans (pixels above 127 of its first channel), checked against the image
    ``size`` (width, height) when given."""
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise SessionError(f"{path}: not an image OpenCV can read (a mask is an 8-bit PNG, the arm's pixels 255)")
    if image.ndim == 3:
        image = image[..., 0]
    if size is not None and (image.shape[1], image.shape[0]) != tuple(size):
        raise SessionError(f"{path}: the mask is {image.shape[1]}x{image.shape[0]} and its image {size[0]}x{size[1]}: give "
                           "each mask at its image's size")
    if image.dtype != np.uint8:
        image = (image > 0).astype(np.uint8) * 255
    return image > 127


def _target(spec: Any, where: str) -> tuple[bool, float]:
    if spec is None:
        return True, 0.0
    if not isinstance(spec, dict) or str(spec.get("type", "")).lower() != "robot":
        raise SessionError(f"{where}: target: a silhouette session's target is the robot itself: target: {{type: robot}}")
    check_keys(spec, ROBOT_TARGET_KEYS, f"{where}: target")
    return arm_hand(spec, where)


def _folder(folder: Path, spec: dict, key: str, default: str, where: str) -> Path:
    value = spec.get(key, default)
    if not isinstance(value, str) or not value:
        raise SessionError(f"{where}: silhouette: {key} is a folder name beside session.yaml, not {shown(value)}")
    return session_file(folder, folder / value, f"the {key}' folder")


def load_silhouette_session(folder: str | Path, arm: str | None = None) -> SilhouetteSession:
    """Read and check a silhouette session folder (the module's docstring); masks are read later.

    Raises
    ------
    SessionError
        Naming the file: no ``silhouette:`` mapping, a setup other than eye-to-hand, no camera
        matrix, a mask or its folder missing, an unknown key, joint angles of another arm than the
        meshes' (their count), an arm handeye has no meshes of.
    """
    folder, spec, where, notes = read_session_yaml(folder)
    if not isinstance(spec.get("silhouette"), dict):
        raise SessionError(f"{where}: no silhouette: mapping; a markerless colour session says its masks' folder there "
                           "(silhouette: {masks: masks})")
    check_session_keys(spec, ("setup", "target", "camera", "silhouette", "joints"),
                       {"camera": CAMERA_KEYS, "joints": JOINTS_KEYS, "silhouette": SILHOUETTE_KEYS}, where)
    setup = check_setup(str(spec.get("setup", "eye_to_hand")))
    if setup_info(setup).camera_on_flange:
        raise SessionError(f"{where}: setup {setup}: the arm's silhouette calibrates a camera fixed in the cell that sees "
                           "the arm (setup: eye_to_hand)")
    hand, opening = _target(spec.get("target"), where)
    K, dist = read_camera(spec.get("camera"), where)
    if K is None:
        raise SessionError(f"{where}: camera: K is needed (the silhouette is predicted through it); calibrate the camera's "
                           "intrinsics first")
    if spec.get("joints") is None:
        raise SessionError(f"{where}: joints: is needed (file, unit, arm): the arm's shape in each view comes from its joint "
                           "angles")
    names, q, chain, table = read_joints(folder, spec["joints"], where, notes, arm, ("image", "mask"))
    try:  # the meshes of the arm whose table this is (a shipped arm's, or one corrected from it)
        meshes = meshes_for(chain, hand=hand, finger_opening=opening)
    except InputMismatchError as exc:
        raise SessionError(f"{where}: joints: arm {shown(chain.name)}: {exc}") from None
    mask_dir = _folder(folder, spec["silhouette"], "masks", "masks", where)
    image_dir = _folder(folder, spec["silhouette"], "images", "images", where)
    if not mask_dir.is_dir():
        raise SessionError(f"{where}: silhouette: no masks folder {mask_dir}")
    masks = [session_file(folder, mask_dir / n, f"the mask of {shown(n)}") for n in names]
    missing = [p.name for p in masks if not p.is_file()]
    if missing:
        raise SessionError(f"{mask_dir}: mask(s) missing for {', '.join(missing[:10])} (named in {table.name}): give a mask "
                           "per view, named as in the joints table")
    images = [session_file(folder, image_dir / n, f"the image of {shown(n)}") for n in names]
    images = [p if p.is_file() else None for p in images]
    return SilhouetteSession(folder, setup, list(names), masks, images, q, chain, meshes, K,
                             None if dist is None or not np.any(dist) else dist, table, notes)


def read_masks(s: SilhouetteSession) -> NDArray[np.bool_]:
    """Every view's mask (N, height, width), checked: each at its colour image's size (where the
    session has one), all of one size, none empty."""
    out = []
    for mask, image in zip(s.mask_paths, s.image_paths):
        size = None
        if image is not None:
            colour = cv2.imread(str(image), cv2.IMREAD_UNCHANGED)
            if colour is None:
                raise SessionError(f"{image}: not an image OpenCV can read")
            size = (colour.shape[1], colour.shape[0])
        m = read_mask(mask, size)
        if out and m.shape != out[0].shape:
            raise SessionError(f"{mask}: {m.shape[1]}x{m.shape[0]}, and {s.mask_paths[0].name} is {out[0].shape[1]}x"
                               f"{out[0].shape[0]}: every view's mask is of the camera's image size")
        if not m.any():
            raise SessionError(f"{mask}: no pixel is set: the arm is not in this view's mask (leave the view out)")
        if m.all():  # no background: no outline to fit, every distance to it infinite
            raise SessionError(f"{mask}: every pixel is set: the mask marks the whole image, not the arm's silhouette (a "
                               "segmentation that failed, or a mask inverted: the arm's pixels are the set ones); leave "
                               "the view out or segment it again")
        out.append(m)
    return np.array(out)


def extras(spec: dict[str, Any], folder: Path, needs: dict[str, dict[str, str]]) -> None:
    """The optional extras a silhouette session needs (its registration's ``extras`` hook): the arm's link meshes."""
    needed("markerless", "the arm's silhouette (its link meshes)", needs)
