"""Spheres found in organized point clouds: a target-free hand-eye calibration's measurements.

A sphere of known diameter (a precision ball on the flange, or a few in the cell) is found in a
depth camera's cloud without any image: RANSAC on triples of nearby pixels (three points and the
radius give the centre, on the side away from the camera), scored on a grid of pixels around each
candidate's image, then a robust least-squares fit of the centre to every point of the cap the
camera sees, weighted by the depth noise. The centre's covariance comes with it: most of its
uncertainty lies along the ray, where a cap pins a sphere least.

Functions
---------
fit_sphere
    The centre of a sphere of known radius in an organized cloud, with its covariance.
find_spheres
    Several spheres of known radii in one cloud, each named by its radius.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from ...errors import TargetError
from .clouds import cloud_pinhole, depth_sigma

__all__ = ["Sphere", "fit_sphere", "find_spheres"]

#: Candidates drawn per cloud, how many the first pass keeps, and the grid (per side) that scores
#: each around its image.
CANDIDATES = 20000
SHORTLIST = 300
GRID = 15
_G = np.linspace(-1.0, 1.0, GRID) ** 2
RING = int(np.sum((_G[:, None] + _G >= 0.25) & (_G[:, None] + _G <= 0.8)))


@dataclass(frozen=True)
class Sphere:
    """A sphere found in a cloud (camera frame, metres)."""

    centre: NDArray[np.float64]
    radius: float  #: the radius it was fitted with (the one given)
    cov: NDArray[np.float64]  #: (3, 3) of the centre, from the fit's residuals
    n_points: int  #: points of the cap the centre was fitted to
    rms: float  #: RMS distance of those points from the sphere, metres
    mask: NDArray[np.bool_]  #: (H, W): its points


def _candidates(cloud, valid, radius, f, rng, n):
    """Centres (n, 3) from triples of pixels close to a seed (within ~ the sphere's image)."""
    h, w = cloud.shape[:2]
    vs, us = np.nonzero(valid)
    pick = rng.integers(0, len(us), n)
    u0, v0 = us[pick], vs[pick]
    half = np.maximum(2.0, 0.7 * radius * f / cloud[v0, u0, 2])
    offsets = rng.uniform(-1, 1, (n, 2, 2)) * half[:, None, None]
    uu = np.clip(np.rint(u0[:, None] + offsets[..., 0]).astype(int), 0, w - 1)
    vv = np.clip(np.rint(v0[:, None] + offsets[..., 1]).astype(int), 0, h - 1)
    a, b, c = cloud[v0, u0], cloud[vv[:, 0], uu[:, 0]], cloud[vv[:, 1], uu[:, 1]]
    ab, ac = b - a, c - a
    normal = np.cross(ab, ac)
    nn = np.einsum("ij,ij->i", normal, normal)
    with np.errstate(invalid="ignore", divide="ignore"):
        # the triangle's circumcentre, and the centre at the radius's distance from its corners
        circ = a + (np.cross(normal, ab) * np.einsum("ij,ij->i", ac, ac)[:, None]
                    + np.cross(ac, normal) * np.einsum("ij,ij->i", ab, ab)[:, None]) / (2 * nn[:, None])
        rho2 = np.einsum("ij,ij->i", circ - a, circ - a)
        height = np.sqrt(radius**2 - rho2)
        unit = normal / np.sqrt(nn)[:, None]
        unit *= np.sign(np.einsum("ij,ij->i", unit, circ))[:, None]  # away from the camera
        centre = circ + height[:, None] * unit
    ok = np.isfinite(centre).all(axis=1) & (rho2 < radius**2) & (nn > (0.05 * radius) ** 4)
    return centre[ok]


def _score(cloud, valid, centres, radius, pinhole, exclude, step: int = 1):
    """Per candidate, the points on its sphere among a grid of pixels over its image (every
    ``step``-th of them: a first, cheap pass)."""
    h, w = cloud.shape[:2]
    fx, fy, cx, cy = pinhole
    z = centres[:, 2]
    grid = np.linspace(-1.0, 1.0, GRID)
    gu, gv = np.meshgrid(grid, grid)
    # only the ring where a sphere's cap leaves any plane through its front (by > 0.1 radius): a
    # wall with a candidate behind it matches near the centre only
    ring = (gu**2 + gv**2 >= 0.25) & (gu**2 + gv**2 <= 0.8)
    gu, gv = gu[ring][::step], gv[ring][::step]
    uu = np.rint(fx * centres[:, 0] / z)[:, None] + cx + (gu * radius * fx / z[:, None])
    vv = np.rint(fy * centres[:, 1] / z)[:, None] + cy + (gv * radius * fy / z[:, None])
    inside = (uu > -0.5) & (uu < w - 0.5) & (vv > -0.5) & (vv < h - 0.5)  # outside the image counts nothing
    uu = np.clip(np.rint(uu).astype(int), 0, w - 1)
    vv = np.clip(np.rint(vv).astype(int), 0, h - 1)
    p = cloud[vv, uu]
    with np.errstate(invalid="ignore"):
        dist = np.abs(np.linalg.norm(p - centres[:, None], axis=2) - radius)
        near = inside & valid[vv, uu] & ~exclude[vv, uu] & (dist < 2 * depth_sigma(p[..., 2]) + 0.04 * radius)
    return near.sum(axis=1)


def _refine(cloud, valid, centre, radius, pinhole, where: str):
    """The centre fitted to every point of the cap near ``centre`` (robust, weighted), its cov, mask."""
    h, w = cloud.shape[:2]
    fx, fy, cx, cy = pinhole
    for gate in (0.3, 0.1, 0.0):  # a candidate is a few mm off: gather its cap loosely first
        z = centre[2]
        uc, vc, rp = fx * centre[0] / z + cx, fy * centre[1] / z + cy, 1.2 * radius * max(fx, fy) / (z - radius)
        u0, u1 = int(max(0, np.floor(uc - rp))), int(min(w, np.ceil(uc + rp) + 1))
        v0, v1 = int(max(0, np.floor(vc - rp))), int(min(h, np.ceil(vc + rp) + 1))
        patch, ok = cloud[v0:v1, u0:u1], valid[v0:v1, u0:u1]
        sigma = depth_sigma(patch[..., 2])
        with np.errstate(invalid="ignore"):
            dist = np.abs(np.linalg.norm(patch - centre, axis=2) - radius)
            near = ok & (dist < np.maximum(4 * sigma, gate * radius))
        q, s = patch[near], sigma[near]
        if len(q) < 10:
            break

        def residuals(c, q=q, s=s):
            return (np.linalg.norm(q - c, axis=1) - radius) / s

        fit = least_squares(residuals, centre, loss="soft_l1", f_scale=2.0, x_scale=np.full(3, 1e-3))
        centre = fit.x
    if len(q) < 10:
        raise TargetError(f"{where}: the sphere's cap has only {len(q)} points with depth: is it in view?")
    inlier = np.abs(fit.fun) < 3.5
    J = fit.jac[inlier]
    s2 = float(np.sum(fit.fun[inlier] ** 2)) / max(int(inlier.sum()) - 3, 1)
    cov = s2 * np.linalg.pinv(J.T @ J)
    mask = np.zeros((h, w), dtype=bool)
    mask[v0:v1, u0:u1] = near
    rms = float(np.sqrt(np.mean((np.linalg.norm(q[inlier] - centre, axis=1) - radius) ** 2)))
    return centre, cov, int(inlier.sum()), rms, mask


def fit_sphere(cloud: NDArray[np.float64], radius: float, rng: np.random.Generator | int | None = 0, *,
               exclude: NDArray[np.bool_] | None = None, where: str = "cloud") -> Sphere:
    """The sphere of ``radius`` (m) in an organized ``cloud`` (H, W, 3; metres, NaN: no depth).

    Raises :class:`~handeye.errors.TargetError` naming ``where`` when no sphere of that size is
    seen: no candidate with a quarter of its ring's points on it, or a best fit with fewer than half
    the points a ball there shows or further off them than 1.5x the depth noise (a wall, an edge).
    """
    rng = np.random.default_rng(rng)
    valid = np.isfinite(cloud).all(axis=2) & (cloud[..., 2] > 0)
    if exclude is not None:
        valid &= ~exclude
    else:
        exclude = np.zeros(valid.shape, dtype=bool)
    if valid.sum() < 20:
        raise TargetError(f"{where}: too few points with depth to look for a sphere")
    pinhole, _ = cloud_pinhole(cloud, rng=rng)
    centres = _candidates(cloud, valid, radius, float(np.mean(pinhole[:2])), rng, CANDIDATES)
    if len(centres) == 0:
        raise TargetError(f"{where}: no sphere of diameter {2e3 * radius:.1f} mm in the cloud")
    # a cheap pass on every 6th point of the ring keeps the best few hundred for the full count
    rough = _score(cloud, valid, centres, radius, pinhole, exclude, step=6)
    centres = centres[np.argsort(rough)[::-1][:SHORTLIST]]
    score = _score(cloud, valid, centres, radius, pinhole, exclude)
    best = int(np.argmax(score))
    if score[best] < 0.25 * RING:  # a sphere in view, with holes and noise, shows most of them
        raise TargetError(f"{where}: no sphere of diameter {2e3 * radius:.1f} mm in the cloud (the best candidate "
                          f"has {score[best]} of {RING} points on it): is the sphere in view, and its diameter right?")
    centre, cov, n, rms, mask = _refine(cloud, valid, centres[best], radius, pinhole, where)
    # a sphere in view fills ~pi (r f / z)^2 pixels, most with depth, its points as close to it as
    # the depth noise allows; a patch of wall or an edge that fooled the search does neither
    expected = np.pi * (radius * float(np.mean(pinhole[:2])) / centre[2]) ** 2
    noise = float(depth_sigma(np.array([centre[2]]))[0])
    if n < 0.5 * expected or rms > 1.5 * noise:
        raise TargetError(f"{where}: no sphere of diameter {2e3 * radius:.1f} mm in the cloud (the best fit has {n} of "
                          f"~{expected:.0f} points, {1e3 * rms:.2f} mm RMS off the sphere against {1e3 * noise:.2f} mm of "
                          "depth noise): is the sphere in view, and its diameter right?")
    return Sphere(centre, float(radius), cov, n, rms, mask)


def find_spheres(cloud: NDArray[np.float64], radii: list[float] | NDArray[np.float64],
                 rng: np.random.Generator | int | None = 0, *, where: str = "cloud") -> list[Sphere | None]:
    """Each sphere of ``radii`` in ``cloud``, or None where it is not seen. Spheres are told apart
    by their radii (give balls whose diameters differ by a few mm): each is searched for with its
    own radius, the points of those already found left out, largest first."""
    rng = np.random.default_rng(rng)
    out: dict[int, Sphere | None] = {}
    taken = np.zeros(cloud.shape[:2], dtype=bool)
    for k in np.argsort(radii)[::-1]:
        try:
            sphere = fit_sphere(cloud, float(radii[k]), rng, exclude=taken, where=where)
        except TargetError:
            out[int(k)] = None
            continue
        out[int(k)] = sphere
        taken |= sphere.mask
    return [out[k] for k in range(len(radii))]
