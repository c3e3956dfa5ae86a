"""A small renderer of planar targets through a pinhole camera with OpenCV distortion.

Inverse mapping: for every (supersampled) pixel, the undistorted viewing ray is intersected with
the target plane and the target's texture is sampled there; the supersampled image is then
area-averaged down (anti-aliasing). Optional blur, a random displacement field (feature position
noise of a given size in pixels, nearly independent from feature to feature) and intensity noise
make the images realistic.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .._shared.lazy import lazy_module
from ..geometry.se3 import invert
from .pnp import project_points
from .targets import Target, Texture

cv2 = lazy_module("cv2")  # OpenCV loads on first use: `import handeye` stays light

__all__ = ["Texture", "target_texture", "Renderer"]

def target_texture(target: Target, texels_per_m: float = 4000.0) -> Texture:
    """Draw a target's pattern (with a white quiet zone around it): its :meth:`Target.texture`."""
    return target.texture(texels_per_m)


class Renderer:
    """Renders textures seen by one camera; the undistorted rays are computed once."""

    def __init__(self, K: NDArray[np.float64], dist: NDArray[np.float64], image_size: tuple[int, int], supersample: int = 3):
        self.K, self.dist = np.asarray(K, float), np.asarray(dist, float)
        self.size = (int(image_size[0]), int(image_size[1]))
        self.ss = int(supersample)
        w, h = self.size
        ss = self.ss
        u = (np.arange(w * ss) + 0.5) / ss - 0.5
        v = (np.arange(h * ss) + 0.5) / ss - 0.5
        uu, vv = np.meshgrid(u, v)
        pix = np.stack([uu.ravel(), vv.ravel()], axis=1).reshape(-1, 1, 2)
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-10)
        if hasattr(cv2, "undistortPointsIter"):  # OpenCV 4
            xy = cv2.undistortPointsIter(pix, self.K, self.dist, None, None, crit)
        else:  # OpenCV 5 folded the criteria into undistortPoints
            xy = cv2.undistortPoints(pix, self.K, self.dist, None, None, None, crit)
        xy = xy.reshape(-1, 2)
        self.rays = np.concatenate([xy, np.ones((len(xy), 1))], axis=1)  # camera frame, z = 1
        # the ray components in float32 (texture coordinates need ~1e-4 px, float32 gives ~1e-7 relative)
        self._rx = np.ascontiguousarray(xy[:, 0], dtype=np.float32)
        self._ry = np.ascontiguousarray(xy[:, 1], dtype=np.float32)

    def project(self, points_target: NDArray[np.float64], target2cam: NDArray[np.float64]) -> NDArray[np.float64]:
        """Pixel positions of target-frame points (with distortion)."""
        return project_points(target2cam, points_target, self.K, self.dist)

    def render(
        self,
        texture: Texture,
        target2cam: NDArray[np.float64],
        rng: np.random.Generator | None = None,
        noise_px: float = 0.0,
        intensity_noise: float = 2.0,
        blur: float = 0.0,
        background: int = 110,
    ) -> NDArray[np.uint8]:
        """The grayscale image of the textured target plane at pose ``target2cam``."""
        cam2target = invert(target2cam)
        R, o = cam2target[:3, :3].astype(np.float32), cam2target[:3, 3].astype(np.float32)
        x, y = self._rx, self._ry
        # where each ray (x, y, 1), turned into the target frame, meets the target plane z = 0
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = -o[2] / (R[2, 0] * x + R[2, 1] * y + R[2, 2])
        miss = ~(lam > 0)
        w, h = self.size
        ss = self.ss
        s = np.float32(texture.scale)
        mu = np.float32(texture.u0) + s * (o[0] + lam * (R[0, 0] * x + R[0, 1] * y + R[0, 2]))
        mv = np.float32(texture.v0) + s * (o[1] + lam * (R[1, 0] * x + R[1, 1] * y + R[1, 2]))
        mu[miss] = -10.0
        mv[miss] = -10.0
        mu, mv = mu.reshape(h * ss, w * ss), mv.reshape(h * ss, w * ss)
        hi = cv2.remap(texture.image, mu, mv, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=background)
        img = cv2.resize(hi, self.size, interpolation=cv2.INTER_AREA).astype(np.float32)
        if blur > 0:
            img = cv2.GaussianBlur(img, (0, 0), blur)
        rng = np.random.default_rng() if rng is None else rng
        if noise_px > 0:
            # Feature position noise: a random displacement field on an 8 px grid, so that features
            # (>= ~15 px apart) move nearly independently, as Gaussian noise on projected points;
            # scaled so its measured standard deviation is noise_px per axis.
            gh, gw = h // 8 + 2, w // 8 + 2
            field = [cv2.resize(rng.normal(0.0, 1.0, (gh, gw)).astype(np.float32), self.size,
                                interpolation=cv2.INTER_CUBIC) for _ in range(2)]
            dx, dy = (noise_px * f / f.std() for f in field)
            gx, gy = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
            img = cv2.remap(img, gx + dx, gy + dy, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
        if intensity_noise > 0:
            img = img + rng.normal(0.0, intensity_noise, img.shape).astype(np.float32)
        return np.clip(np.round(img), 0, 255).astype(np.uint8)
