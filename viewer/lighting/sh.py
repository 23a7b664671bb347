"""Second-order spherical-harmonics lighting without shadows: the lighting model of the methods the
paper compares against, used as the evaluation's baseline (``relight bench networks``).

The map is projected onto the 9 real SH functions up to l = 2 (exact texel solid angles); the
irradiance at normal n is E(n) = sum_lm A_l L_lm Y_lm(n) with A = (pi, 2 pi / 3, pi / 4)
(Ramamoorthi and Hanrahan 2001), and a Lambertian surface reflects albedo E(n) / pi: no shadows, no
specular.
"""

from __future__ import annotations

import numpy as np

from viewer.lighting.envmap import EnvMap, pixel_directions, solid_angles

BAND_FACTORS = np.array([np.pi] + [2.0 * np.pi / 3.0] * 3 + [np.pi / 4.0] * 5)


def sh_basis(dirs: np.ndarray) -> np.ndarray:
    """(..., 9) real SH basis functions up to l = 2 at unit directions (..., 3)."""
    x, y, z = dirs[..., 0], dirs[..., 1], dirs[..., 2]
    return np.stack([
        np.full_like(x, 0.282095),
        0.488603 * y, 0.488603 * z, 0.488603 * x,
        1.092548 * x * y, 1.092548 * y * z, 0.315392 * (3.0 * z * z - 1.0), 1.092548 * x * z,
        0.546274 * (x * x - y * y),
    ], axis=-1)


def project(env: EnvMap) -> np.ndarray:
    """(9, 3) SH coefficients of the map's radiance."""
    h, w = env.height, env.width
    weights = sh_basis(pixel_directions(h, w)) * solid_angles(h, w)[:, None, None]
    return np.einsum("hwk,hwc->kc", weights, env.pixels.astype(np.float64))


def irradiance(coeffs: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(..., 3) irradiance E(n) at unit normals (..., 3), clamped at 0 (the truncation can ring below)."""
    return np.maximum(sh_basis(normals.astype(np.float64)) @ (BAND_FACTORS[:, None] * coeffs), 0.0)


def relight(albedo: np.ndarray, normal: np.ndarray, mask: np.ndarray, env: EnvMap) -> np.ndarray:
    """(H, W, 3) float32 Lambertian image under ``env`` (already turned), zero outside the mask."""
    img = albedo * irradiance(project(env), normal) / np.pi
    return np.where(mask[..., None], img, 0.0).astype(np.float32)
