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

from ..._shared.lazy import lazy_module
from ...geometry.se3 import invert
from .pnp import project_points
from .targets import Target, Texture

cv2 = lazy_module("cv2")  # OpenCV loads on first use: `import handeye` stays light

__all__ = ["Texture", "target_texture", "Renderer"]

def target_texture(target: Target, texels_per_m: float = 4000.0) -> Texture:
    """Draw a target's pattern (with a white quiet zone around it): its :meth:`Target.texture`."""
    return target.texture(texels_per_m)


def _undistorted_grid(K, dist, w: int, h: int, ss: int) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """x and y (h ss * w ss,), float32: the undistorted normalized coordinates of every supersampled
    pixel centre, row by row.

    Undistortion is iterative and costly (7-17 s for 1600x1200 at 3x3 samples): it is solved on the
    whole pixels (and one beyond the border) and interpolated bilinearly in between, off the
    iterative solution by < 5e-5 px, float32 rounding included (measured at 640x480 and 1280x1024
    with the simulator's lens)."""
    cu, cv = np.arange(-1.0, w + 1.0), np.arange(-1.0, h + 1.0)
    uu, vv = np.meshgrid(cu, cv)
    pix = np.stack([uu.ravel(), vv.ravel()], axis=1).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-10)
    if hasattr(cv2, "undistortPointsIter"):  # OpenCV 4
        xy = cv2.undistortPointsIter(pix, K, dist, None, None, crit)
    else:  # OpenCV 5 folded the criteria into undistortPoints
        xy = cv2.undistortPoints(pix, K, dist, None, None, None, crit)
    grid = xy.reshape(len(cv), len(cu), 2)

    def weights(n: int) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
        pos = (np.arange(n * ss) + 0.5) / ss - 0.5 + 1.0  # supersampled centres, on the grid's index scale
        i0 = np.clip(np.floor(pos).astype(np.intp), 0, n)
        return i0, pos - i0
    i0, tx = weights(w)
    j0, ty = weights(h)
    out = []
    for c in (0, 1):  # one coordinate at a time: a 12 MP image has 108 million samples
        rows = grid[:, i0, c] * (1.0 - tx) + grid[:, i0 + 1, c] * tx
        out.append((rows[j0] * (1.0 - ty)[:, None] + rows[j0 + 1] * ty[:, None]).astype(np.float32).ravel())
    return out[0], out[1]


class Renderer:
    """Renders textures seen by one camera; the undistorted rays are computed once."""

    def __init__(self, K: NDArray[np.float64], dist: NDArray[np.float64], image_size: tuple[int, int], supersample: int = 3):
        self.K, self.dist = np.asarray(K, float), np.asarray(dist, float)
        self.size = (int(image_size[0]), int(image_size[1]))
        self.ss = int(supersample)
        w, h = self.size
        # the rays (x, y, 1) in the camera frame, in float32 (texture coordinates need ~1e-4 px,
        # float32 gives ~1e-7 relative)
        self._rx, self._ry = _undistorted_grid(self.K, self.dist, w, h, self.ss)

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
