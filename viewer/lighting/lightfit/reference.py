"""Reference shading of the fitting views under an environment map: the ground truth lights are fitted to.

The paper ray-traces these images; for a sphere and for an object on a plane the visibility is
analytic (:mod:`.views`), so the reference here is the sum over the map's samples (:mod:`.samples`)
of flux x BRDF x visibility, vectorized (chunks of pixels x samples), over the ``ROTATIONS`` of the map:

- sphere view: unshadowed diffuse ``sum flux max(0, n.d) / pi`` and specular with
  specular = roughness = 0.5 (the paper's Step 2 target), in numpy with the lobes the default fits
  differentiate (:func:`.sphere_lobes.sphere_reference`);
- plane views (here, in torch with the twin's BRDF, :mod:`viewer.twin.brdf`): shadowed diffuse
  (albedo 1) on the plane and the object (Step 3 target, and the error measurements).

Accuracy against the brute-force sum over every texel of the full-resolution map is in
docs/lights.md (measured by ``tests/test_lightfit.py``).
"""

from __future__ import annotations

import torch

from viewer.lighting.lightfit.samples import MapSamples
from viewer.lighting.lightfit.sphere_lobes import CHUNK, ROTATIONS, rotation_matrices
from viewer.lighting.lightfit.views import PlaneView
from viewer.twin.brdf import diffuse_shading


def _blocks(n_pixels: int, n_samples: int):
    rows = max(1, CHUNK // max(n_samples, 1))
    for start in range(0, n_pixels, rows):
        yield slice(start, min(start + rows, n_pixels))


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
