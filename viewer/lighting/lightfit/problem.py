"""One map's fitting problem: its reference shading and the fitted lights' shading of the same views.

:func:`build_problem` computes, once per map, the references of :mod:`.reference` (normalized so
the sphere's mean diffuse luminance is 1, which keeps a 1e6 sun and a dim night map in the same
numeric range). :class:`Problem` then renders any light set on the same views, differentiably:

- ``sphere_shading``: unshadowed diffuse and specular of the sphere view (Step 2);
- ``ShadowedViews``: a plane view under fixed light directions, with each light's convolutional
  shadow map basis computed once (directions are fixed while sigma is fitted), so that trying a
  sigma costs one Gaussian pre-filter: the twin's own (:mod:`viewer.twin.csm`), exactly what the GL
  engine draws;
- ``VisibilityTable``: those soft visibilities at every sigma of a grid, computed once, and
  interpolated linearly in sigma (differentiably), which makes a sigma step of the optimization
  cost a lookup instead of a pre-filter of every basis map (its accuracy is tested).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import torch

from viewer.lighting.envmap import EnvMap
from viewer.lighting.lightfit.reference import plane_reference
from viewer.lighting.lightfit.samples import MapSamples, map_samples
from viewer.lighting.lightfit.settings import DEFAULT_SETTINGS, FitSettings, report
from viewer.lighting.lightfit.sphere_fit import SphereTarget, sphere_target
from viewer.lighting.lightfit.sphere_lobes import ROTATIONS, STEP2_MATERIAL, SphereView, rotation_matrices
from viewer.lighting.lightfit.views import PlaneView, plane_view
from viewer.scene import shadow_space as rule
from viewer.twin import csm
from viewer.twin.brdf import diffuse_shading, specular_shading
from viewer.twin.relight import SceneTensors
from viewer.twin.shadow_geometry import light_frames, receiver_coordinates
from viewer.twin.shadow_map import shadow_maps


@dataclass(frozen=True)
class Problem:
    settings: FitSettings
    samples: MapSamples
    scale: float  # reference / scale is what is fitted; fitted intensities are multiplied back
    target: SphereTarget  # the sphere view and its normalized references (numpy)
    plane: PlaneView | None  # None: built without the shadowed plane (build_problem's ``shadows``)
    plane_shadowed: torch.Tensor | None  # (K, P, 3) normalized
    rotations: tuple = ROTATIONS

    @property
    def sphere(self) -> SphereView:
        return self.target.view

    @cached_property
    def sphere_diffuse(self) -> torch.Tensor:
        """(K, P, 3) normalized reference diffuse of the sphere view, for torch."""
        return torch.as_tensor(self.target.diffuse, dtype=torch.float32)

    @cached_property
    def sphere_specular(self) -> torch.Tensor:
        return torch.as_tensor(self.target.specular, dtype=torch.float32)

    def sphere_shading(self, direction: torch.Tensor, intensity: torch.Tensor):
        """Normalized (diffuse, specular) (K, P, 3) of the sphere view under the lights (unit directions)."""
        normal = torch.as_tensor(self.sphere.normal, dtype=torch.float32)
        k, n = len(self.rotations), direction.shape[0]
        dirs = rotated_directions(direction, self.rotations).reshape(k * n, 3)
        material = torch.full((normal.shape[0],), STEP2_MATERIAL)
        diff = diffuse_shading(normal, dirs).reshape(k, n, -1)
        spec = specular_shading(normal, dirs, material, material).reshape(k, n, -1)
        return torch.einsum("knp,nc->kpc", diff, intensity), torch.einsum("knp,nc->kpc", spec, intensity)


def build_problem(env: EnvMap, settings: FitSettings = DEFAULT_SETTINGS, progress=None, shadows: bool = True) -> Problem:
    """References of ``env`` on the fitting views (raises nothing for a black map: scale is then 0);
    ``shadows`` False leaves out the shadowed plane (``plane`` and ``plane_shadowed`` None: only the
    paper's Step 3 and the benchmark's errors read them)."""
    report(progress, "reference", 0, 2)
    samples = map_samples(env, settings.samples)
    target, scale = sphere_target(samples, settings.sphere_resolution)
    report(progress, "reference", 1, 2)
    plane = plane_view("sphere", settings.plane_resolution) if shadows else None
    shadowed = plane_reference(samples, plane) if shadows else None
    report(progress, "reference", 2, 2)
    inv = 1.0 / scale if scale > 0 else 0.0
    return Problem(settings, samples, scale, target, plane, None if shadowed is None else shadowed * inv)


def rotated_directions(direction: torch.Tensor, rotations=ROTATIONS) -> torch.Tensor:
    """(K, N, 3) light directions (N, 3) under each of the K rotations of the map."""
    mats = torch.as_tensor(np.stack(rotation_matrices(rotations)), dtype=direction.dtype)
    return torch.einsum("kij,nj->kni", mats, direction)


@dataclass(frozen=True)
class ShadowedViews:
    """A plane view's shadow data for N lights of fixed directions under the K rotations (flattened K*N).

    ``basis`` (K*N, 2M, R, R) unfiltered CSM basis; ``u, v, d`` (K*N, P) receivers; ``diffuse``
    (K*N, P) Lambert shading per unit intensity.
    """

    view: PlaneView
    rotations: int
    lights: int
    basis: torch.Tensor
    u: torch.Tensor
    v: torch.Tensor
    d: torch.Tensor
    diffuse: torch.Tensor
    terms: int

    def soft_visibility(self, sigma: torch.Tensor) -> torch.Tensor:
        """(K*N, P) convolutional-shadow-map visibility for per-light sigma (N,) (256-px units)."""
        res = self.basis.shape[-1]
        sigma_px = sigma.repeat(self.rotations) * (res / rule.SIGMA_REFERENCE_RESOLUTION)
        filtered = csm.gaussian_filter(self.basis, sigma_px)
        return csm.reconstruct_visibility(csm.sample_bilinear(filtered, self.u, self.v), self.d, self.terms)

    def shading(self, visibility: torch.Tensor, intensity: torch.Tensor) -> torch.Tensor:
        """(K, P, 3) shadowed diffuse from visibility (K*N, P) and intensities (N, 3)."""
        k, n = self.rotations, self.lights
        weighted = (visibility * self.diffuse).reshape(k, n, -1)
        return torch.einsum("knp,nc->kpc", weighted, intensity)


def shadowed_views(view: PlaneView, direction: np.ndarray, rotations=ROTATIONS, resolution: int = 128,
                   terms: int = 4) -> ShadowedViews:
    """Precompute :class:`ShadowedViews` of ``view`` for unit light directions (N, 3)."""
    st = SceneTensors.from_scene(view.scene)
    dirs = rotated_directions(torch.as_tensor(direction, dtype=torch.float32), rotations).reshape(-1, 3)
    frames = light_frames(st.casters, dirs, resolution, terms)
    depth = shadow_maps(st.mesh, frames, resolution)
    u, v, d, _ = receiver_coordinates(st.points, st.normal, frames, resolution)
    return ShadowedViews(view, len(rotations), int(direction.shape[0]), csm.fourier_basis(depth, terms), u, v, d,
                         diffuse_shading(st.normal, dirs), terms)


@dataclass(frozen=True)
class VisibilityTable:
    """Soft visibility of fixed-direction lights at the sigmas of ``grid`` (G,): ``values`` (G, K*N, P)."""

    views: ShadowedViews
    grid: torch.Tensor
    values: torch.Tensor

    @property
    def lights(self) -> int:
        return self.views.lights

    @staticmethod
    def of(views: ShadowedViews, grid) -> VisibilityTable:
        grid = torch.as_tensor(grid, dtype=torch.float32)
        with torch.no_grad():
            values = torch.stack([views.soft_visibility(torch.full((views.lights,), float(g))) for g in grid])
        return VisibilityTable(views, grid, values)

    def __call__(self, sigma: torch.Tensor) -> torch.Tensor:
        """(K*N, P) visibility at per-light ``sigma`` (N,), linear between grid nodes, clamped to the grid."""
        g = self.grid
        s = sigma.clamp(float(g[0]), float(g[-1]))
        i0 = (torch.searchsorted(g, s.detach(), right=True) - 1).clamp(0, len(g) - 2)
        w = (s - g[i0]) / (g[i0 + 1] - g[i0])  # (N,)
        rows = torch.arange(self.values.shape[1])
        light = rows % self.lights
        lo = self.values[i0[light], rows]
        hi = self.values[i0[light] + 1, rows]
        return lo + w[light, None] * (hi - lo)
