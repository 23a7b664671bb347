"""Reference shading of the fitting views under an environment map: the ground truth lights are fitted to.

The paper ray-traces these images; for a sphere and for an object on a plane the visibility is
analytic (:mod:`.views`), so the reference here is the sum over the map's samples (:mod:`.samples`)
of flux x BRDF x visibility, vectorized in torch (chunks of pixels x samples). The BRDF is the
twin's (:mod:`viewer.twin.brdf`), so the reference and the fitted lights' shading share one
implementation. Reference quantities, each over the ``ROTATIONS`` of the map:

- sphere view: unshadowed diffuse ``sum flux max(0, n.d) / pi`` and specular with
  specular = roughness = 0.5 (the paper's Step 2 target);
- plane views: shadowed diffuse (albedo 1) on the plane and the object (Step 3 target, and the
  error measurements).

Accuracy against the brute-force sum over every texel of the full-resolution map is in
docs/lights.md (measured by ``tests/test_lightfit.py``).
"""

from __future__ import annotations

import numpy as np
import torch

from viewer.lighting.lightfit.samples import MapSamples
from viewer.lighting.lightfit.views import PlaneView, SphereView
from viewer.scene.area_lights import rotation_matrix
from viewer.twin.brdf import diffuse_shading, specular_shading

# the paper's seven views of the map: five yaws 72 degrees apart, and tilted +-90 degrees
ROTATIONS = tuple((72.0 * k, 0.0) for k in range(5)) + ((0.0, 90.0), (0.0, -90.0))
STEP2_MATERIAL = 0.5  # specular = roughness = 0.5 on the sphere (the paper)
CHUNK = 1 << 22  # pixel x sample pairs per block


def rotation_matrices(rotations=ROTATIONS) -> list[np.ndarray]:
    return [rotation_matrix(yaw, tilt) for yaw, tilt in rotations]


def _blocks(n_pixels: int, n_samples: int):
    rows = max(1, CHUNK // max(n_samples, 1))
    for start in range(0, n_pixels, rows):
        yield slice(start, min(start + rows, n_pixels))


def sphere_reference(samples: MapSamples, view: SphereView, rotations=ROTATIONS,
                     dtype=torch.float32) -> tuple[torch.Tensor, torch.Tensor]:
    """(diffuse, specular), each (K, P, 3) for the K rotations of the map and the P sphere pixels."""
    normal = torch.as_tensor(view.normal, dtype=dtype)
    material = torch.full((normal.shape[0],), STEP2_MATERIAL, dtype=dtype)
    flux = torch.as_tensor(samples.flux, dtype=dtype)
    diff, spec = [], []
    for r in rotation_matrices(rotations):
        dirs = torch.as_tensor(samples.rotated(r).direction, dtype=dtype)
        d_parts, s_parts = [], []
        for rows in _blocks(normal.shape[0], len(samples)):
            n = normal[rows]
            d_parts.append(diffuse_shading(n, dirs).T @ flux)
            s_parts.append(specular_shading(n, dirs, material[rows], material[rows]).T @ flux)
        diff.append(torch.cat(d_parts))
        spec.append(torch.cat(s_parts))
    return torch.stack(diff), torch.stack(spec)


def plane_reference(samples: MapSamples, view: PlaneView, rotations=ROTATIONS, dtype=torch.float32) -> torch.Tensor:
    """Shadowed diffuse shading (K, P, 3) of every pixel of a plane view, per rotation of the map."""
    normal = torch.as_tensor(view.normal, dtype=dtype)
    flux = torch.as_tensor(samples.flux, dtype=dtype)
    out = []
    for r in rotation_matrices(rotations):
        dirs = torch.as_tensor(samples.rotated(r).direction, dtype=dtype)
        parts = []
        for rows in _blocks(normal.shape[0], len(samples)):
            weight = diffuse_shading(normal[rows], dirs).T * view.visibility(dirs, rows)  # (p, T)
            parts.append(weight @ flux)
        out.append(torch.cat(parts))
    return torch.stack(out)
