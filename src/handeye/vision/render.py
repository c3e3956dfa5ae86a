"""A small renderer of planar targets through a pinhole camera with OpenCV distortion.

Inverse mapping: for every (supersampled) pixel, the undistorted viewing ray is intersected with
the target plane and the target's texture is sampled there; the supersampled image is then
area-averaged down (anti-aliasing). Optional blur, a random displacement field (feature position
noise of a given size in pixels, nearly independent from feature to feature) and intensity noise
make the images realistic.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .._shared.lazy import lazy_module
from ..errors import TargetError
from ..geometry.se3 import invert
from .pnp import project_points
from .targets import AprilTag, ArucoGrid, Charuco, Chessboard, CircleGrid, Target, aruco_dictionary

cv2 = lazy_module("cv2")  # OpenCV loads on first use: `import handeye` stays light

__all__ = ["Texture", "target_texture", "Renderer"]

DARK, LIGHT = 25, 225


@dataclass(frozen=True)
class Texture:
    """A target's printed pattern: ``u = u0 + x * scale``, ``v = v0 + y * scale`` (x, y in metres)."""

    image: NDArray[np.uint8]
    u0: float
    v0: float
    scale: float  #: texels per metre

    def outline(self) -> NDArray[np.float64]:
        """The sheet's four corners in the target frame (metres, z = 0)."""
        h, w = self.image.shape
        us = np.array([0, w, w, 0], dtype=float)
        vs = np.array([0, 0, h, h], dtype=float)
        return np.stack([(us - self.u0) / self.scale, (vs - self.v0) / self.scale, np.zeros(4)], axis=1)


def target_texture(target: Target, texels_per_m: float = 4000.0) -> Texture:
    """Draw a target's pattern (with a white quiet zone around it)."""
    s = texels_per_m
    if isinstance(target, Chessboard):
        sq = target.square
        nx, ny = target.cols + 1, target.rows + 1  # squares
        margin = sq
        w, h = int(round((nx * sq + 2 * margin) * s)), int(round((ny * sq + 2 * margin) * s))
        img = np.full((h, w), LIGHT, np.uint8)
        u0 = v0 = (margin + sq) * s  # the first inner corner is one square in from the board's corner
        for b in range(ny):
            for a in range(nx):
                if (a + b) % 2 == 0:  # the board's corner square is dark
                    x0, y0 = (a - 1) * sq, (b - 1) * sq
                    pts = np.array([[x0, y0], [x0 + sq, y0], [x0 + sq, y0 + sq], [x0, y0 + sq]]) * s + [u0, v0]
                    cv2.fillConvexPoly(img, np.round(pts * 16).astype(np.int32), DARK, cv2.LINE_AA, 4)
        return Texture(img, u0, v0, s)
    if isinstance(target, Charuco):
        margin = target.square
        bw, bh = target.cols * target.square, target.rows * target.square
        w, h = int(round((bw + 2 * margin) * s)), int(round((bh + 2 * margin) * s))
        m = int(round(margin * s))
        img = target.board.generateImage((w, h), marginSize=m, borderBits=1)
        img = np.where(img > 127, LIGHT, DARK).astype(np.uint8)
        scale = (w - 2 * m) / bw
        return Texture(img, float(m), float(m), scale)
    if isinstance(target, ArucoGrid):
        margin = target.square / 2
        w, h = int(round((target.width + 2 * margin) * s)), int(round((target.height + 2 * margin) * s))
        m = int(round(margin * s))
        img = target.board.generateImage((w, h), marginSize=m, borderBits=1)
        img = np.where(img > 127, LIGHT, DARK).astype(np.uint8)
        return Texture(img, float(m), float(m), (w - 2 * m) / target.width)
    if isinstance(target, CircleGrid):
        pts = target.object_points()[:, :2]
        r = 0.3 * target.square
        margin = 1.5 * target.square
        lo = pts.min(axis=0) - margin
        hi = pts.max(axis=0) + margin
        w, h = (np.round((hi - lo) * s)).astype(int)
        img = np.full((h, w), LIGHT, np.uint8)
        for x, y in pts:
            c = np.round(((np.array([x, y]) - lo) * s) * 16).astype(int)
            cv2.circle(img, (int(c[0]), int(c[1])), int(round(r * s * 16)), DARK, -1, cv2.LINE_AA, 4)
        return Texture(img, -lo[0] * s, -lo[1] * s, s)
    if isinstance(target, AprilTag):
        side = int(round(target.square * s))
        tag = cv2.aruco.generateImageMarker(aruco_dictionary(target.dictionary), target.tag_id or 0, side, borderBits=1)
        m = side // 3
        img = np.full((side + 2 * m, side + 2 * m), LIGHT, np.uint8)
        img[m : m + side, m : m + side] = np.where(tag > 127, LIGHT, DARK)
        return Texture(img, float(m), float(m), side / target.square)
    raise TargetError(f"cannot render a {type(target).__name__}: the renderer draws the types of TARGET_TYPES")


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
