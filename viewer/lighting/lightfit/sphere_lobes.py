"""The sphere view and its shading in numpy, with its slopes: what the instant and fast fits differentiate.

The sphere view (the paper's Step 2) is a unit sphere seen orthographically along -z, so the view
vector is exactly the shading convention's (0, 0, 1); only its normals matter (a lone convex
sphere shadows nothing but its own back, which n.l already removes).

The paper's Step 2 target is the unshadowed diffuse and specular shading of a sphere
(specular = roughness = ``STEP2_MATERIAL``, view vector (0, 0, 1)) under the map, and the fit
moves N directional lights until their shading matches it. This module is that shading for one
fixed material, written in numpy with its derivatives by hand, so the default fit runs without
torch (importing torch alone costs about 2 s here, more than the fit: docs/lights.md). It is the
same Lambert + Disney specular lobe as :mod:`viewer.twin.brdf` and ``shaders/brdf.glsl``;
``tests/test_lightfit.py`` checks values and slopes against the twin's autograd.

With v = (0, 0, 1) the lobe depends on the light only through c = n.l and l_z:
l.h = sqrt((1 + l_z) / 2) and n.h = (c + n_z) / (2 l.h), which keeps the slopes short.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from viewer.constants import MIN_ALPHA, SPECULAR_SCALE
from viewer.lighting.lightfit.samples import MapSamples
from viewer.scene.area_lights import rotation_matrix

# the paper's seven views of the map: five yaws 72 degrees apart, and tilted +-90 degrees
ROTATIONS = tuple((72.0 * k, 0.0) for k in range(5)) + ((0.0, 90.0), (0.0, -90.0))
STEP2_MATERIAL = 0.5  # specular = roughness = 0.5 on the sphere (the paper)
CHUNK = 1 << 22  # pixel x sample pairs per block of the reference


@dataclass(frozen=True)
class SphereView:
    """Orthographic view of the unit sphere: ``normal`` (P, 3) of the P pixels inside its disk."""

    resolution: int
    normal: np.ndarray
    pixel_index: np.ndarray  # (P,) flat index into resolution x resolution

    def to_image(self, values: np.ndarray) -> np.ndarray:
        """Scatter (..., P) values into (..., R, R) images, zero off the sphere."""
        out = np.zeros(values.shape[:-1] + (self.resolution * self.resolution,), dtype=values.dtype)
        out[..., self.pixel_index] = values
        return out.reshape(values.shape[:-1] + (self.resolution, self.resolution))


def sphere_view(resolution: int) -> SphereView:
    t = (np.arange(resolution) + 0.5) / resolution * 2.0 - 1.0
    x, y = np.meshgrid(t, -t)
    r2 = x * x + y * y
    inside = r2 < 1.0
    normal = np.stack([x[inside], y[inside], np.sqrt(1.0 - r2[inside])], axis=1)
    return SphereView(resolution, normal, np.flatnonzero(inside.reshape(-1)))


def rotation_matrices(rotations=ROTATIONS) -> list[np.ndarray]:
    return [rotation_matrix(yaw, tilt) for yaw, tilt in rotations]


class SphereLobes:
    """Diffuse and specular per unit intensity of lights (L, 3) on pixels with normals (P, 3), in
    ``dtype`` (float32 for the fits, as the twin's; float64 where a test compares slopes)."""

    def __init__(self, normal: np.ndarray, material: float = STEP2_MATERIAL, dtype=np.float32):
        self.normal = np.asarray(normal, dtype=dtype)
        self.nz = self.normal[:, 2]
        alpha = max(material * material, MIN_ALPHA)
        self.a2 = alpha * alpha
        self.f0 = SPECULAR_SCALE * material
        nv = np.maximum(self.nz, 0.0)
        # Smith's G1 of n.v, fixed per pixel; 0 where the pixel faces away (the lobe is zero there)
        self.g1_view = np.where(self.nz > 0.0, self._g1(nv, np.sqrt(self.a2 + nv * nv * (1.0 - self.a2))), 0.0)

    @staticmethod
    def _g1(x, root):
        """Smith G1 in the form holding 1 / (2 x): ``1 / (x + sqrt(a2 + x^2 - a2 x^2))``, ``root`` the square root."""
        return 1.0 / (x + root)

    def _parts(self, light: np.ndarray):
        """n.l (L, P), its positive part, l.h and 1 / (2 l.h) (L, 1), n.h, GGX's t and D (L, P)."""
        light = np.asarray(light, dtype=self.normal.dtype)
        c = light @ self.normal.T
        lz = light[:, 2:3]
        # l.h with h = normalize(l + v): the twin floors |l + v| at 1e-6 so a light from behind stays finite
        lh = (1.0 + lz) / np.sqrt(np.maximum(2.0 + 2.0 * lz, 1e-12))
        half_inv = 0.5 / np.maximum(lh, 1e-6)
        nh = np.maximum((c + self.nz) * half_inv, 0.0)
        t = nh * nh * (self.a2 - 1.0) + 1.0
        d = self.a2 / (math.pi * t * t)
        return c, np.maximum(c, 0.0), lh, half_inv, nh, t, d

    def shading(self, light: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(diffuse, specular), each (L, P); the lobe is zero where n.l <= 0 or n.v <= 0, as the twin's."""
        _, cp, lh, _, _, _, d = self._parts(light)
        fresnel = self.f0 + (1.0 - self.f0) * (1.0 - lh) ** 5
        g1 = self._g1(cp, np.sqrt(self.a2 + cp * cp * (1.0 - self.a2)))
        return cp / math.pi, cp * fresnel * d * g1 * self.g1_view

    def shading_and_slopes(self, light: np.ndarray):
        """(diffuse, specular, dspec/dc, dspec/dl_z), each (L, P), c = n.l; d diffuse / dc is [c > 0] / pi."""
        c, cp, lh, half_inv, nh, t, d = self._parts(light)
        a2, f0, gv = self.a2, self.f0, self.g1_view
        one_minus = 1.0 - lh
        fresnel = f0 + (1.0 - f0) * one_minus**5  # (L, 1)
        dfresnel_dlz = -2.5 * (1.0 - f0) * one_minus**4 * half_inv  # dl.h/dl_z = 1 / (4 l.h)
        root = np.sqrt(a2 + cp * cp * (1.0 - a2))
        g1 = self._g1(cp, root)
        dg1 = -g1 * g1 * (1.0 + cp * (1.0 - a2) / root)
        dd_dnh = (-4.0 * (a2 - 1.0)) * d * nh / t
        cgv = cp * g1 * gv
        spec = cgv * fresnel * d
        # dn.h/dc = 1 / (2 l.h); dn.h/dl_z = -n.h / (4 l.h^2)
        ds_dc = (c > 0.0) * (fresnel * gv) * (d * (g1 + cp * dg1) + cp * g1 * dd_dnh * half_inv)
        ds_dlz = cgv * (dfresnel_dlz * d - fresnel * dd_dnh * nh * half_inv * half_inv)
        return cp / math.pi, spec, ds_dc, ds_dlz


def sphere_reference(samples: MapSamples, normal: np.ndarray, rotations=ROTATIONS) -> tuple[np.ndarray, np.ndarray]:
    """(diffuse, specular), each (K, P, 3) float64: the map's samples on the sphere's P pixels, per rotation."""
    lobes = SphereLobes(normal)
    rows = max(1, CHUNK // max(len(normal), 1))
    diff, spec = [], []
    for r in rotation_matrices(rotations):
        dirs = samples.rotated(r).direction
        d_sum = np.zeros((len(normal), 3))
        s_sum = np.zeros((len(normal), 3))
        for start in range(0, len(dirs), rows):
            d, s = lobes.shading(dirs[start : start + rows])
            flux = samples.flux[start : start + rows]
            d_sum += d.T @ flux
            s_sum += s.T @ flux
        diff.append(d_sum)
        spec.append(s_sum)
    return np.stack(diff), np.stack(spec)
