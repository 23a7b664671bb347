"""A first, quick extraction of area lights from an environment map: median cut (Debevec 2005).

The map (downsampled to at most ``max_width`` texels wide, energy-preserving) is cut into ``n``
rectangles of texels. Longitude is treated as a ring that starts at the map's darkest column (so no
light straddles the image's left/right seam, and yawing the map by whole texels yaws the lights
exactly). Starting from the whole map, the region holding the most energy (luminance x
solid angle) is split next, along its longer angular side -- its width counts at the cosine of the
latitude of its row nearest the equator, so rows are weighted by cos(latitude) -- at the median of
its energy. Any ``n`` >= 1 works (a power of two gives the classic balanced tree). Each region
becomes one light:

- ``direction``: the energy-weighted mean direction of its texels, normalized (for a region without
  energy: the solid-angle weighted mean, +y if that vanishes);
- ``intensity``: sum over its texels of L x solid angle per RGB channel, so a white Lambertian
  surface facing the light receives the irradiance the region would give it (the sums over all
  lights equal the map's :meth:`~viewer.lighting.envmap.EnvMap.energy`);
- ``sigma``: the region's size (:func:`viewer.lighting.light_size.cell_sigma`): the angular
  Gaussian its light spreads over, in the engine's sigma unit.
"""

from __future__ import annotations

import heapq

import numpy as np

from viewer.errors import InputError
from viewer.lighting.envmap import LUMINANCE, EnvMap, pixel_directions, solid_angles
from viewer.lighting.light_size import cell_sigma
from viewer.scene.area_lights import AreaLights

__all__ = ["LUMINANCE", "median_cut_lights"]


def median_cut_lights(env: EnvMap, n: int, max_width: int = 256) -> AreaLights:
    """``n`` area lights approximating ``env`` (see the module docstring)."""
    if n < 1:
        raise InputError(env.source, f"the number of lights must be >= 1, got {n}")
    env = env.downsampled(max_width)
    h, w = env.height, env.width
    if n > h * w:
        raise InputError(env.source, f"cannot cut {n} lights from a {w}x{h} map ({h * w} texels)")
    omega = solid_angles(h, w)
    flux = env.pixels.astype(np.float64) * omega[:, None, None]  # L x solid angle, (h, w, 3)
    # longitude is a ring: start it at the darkest column, so no light straddles the image's seam
    seam = int(np.argmin((flux @ LUMINANCE).sum(axis=0)))
    flux = np.roll(flux, -seam, axis=1)
    dirs = np.roll(pixel_directions(h, w), -seam, axis=1)
    energy = flux @ LUMINANCE
    table = np.zeros((h + 1, w + 1))  # summed-area table of the energy
    table[1:, 1:] = energy.cumsum(axis=0).cumsum(axis=1)
    cos_lat = np.cos(0.5 * np.pi - np.pi * (np.arange(h) + 0.5) / h)

    def region_energy(i0, i1, j0, j1):
        return table[i1, j1] - table[i0, j1] - table[i1, j0] + table[i0, j0]

    def entry(region):
        i0, i1, j0, j1 = region
        return (-region_energy(*region), -(i1 - i0) * (j1 - j0), region)

    heap, done = [entry((0, h, 0, w))], []
    while len(heap) + len(done) < n:
        _, _, region = heapq.heappop(heap)
        i0, i1, j0, j1 = region
        if i1 - i0 == 1 and j1 - j0 == 1:
            done.append(region)
            continue
        width = (j1 - j0) * 2.0 * np.pi / w * cos_lat[i0:i1].max()
        height = (i1 - i0) * np.pi / h
        along_columns = j1 - j0 > 1 and (width >= height or i1 - i0 == 1)
        if along_columns:
            profile = table[i1, j0 + 1 : j1 + 1] - table[i0, j0 + 1 : j1 + 1]  # energy left of each cut
            cut = j0 + _median_cut(profile - (table[i1, j0] - table[i0, j0]))
            halves = [(i0, i1, j0, cut), (i0, i1, cut, j1)]
        else:
            profile = table[i0 + 1 : i1 + 1, j1] - table[i0 + 1 : i1 + 1, j0]  # energy above each cut
            cut = i0 + _median_cut(profile - (table[i0, j1] - table[i0, j0]))
            halves = [(i0, cut, j0, j1), (cut, i1, j0, j1)]
        for half in halves:
            heapq.heappush(heap, entry(half))
    regions = done + [region for _, _, region in heap]
    return _lights(regions, flux, energy, omega, dirs)


def _median_cut(cumulative: np.ndarray) -> int:
    """Where to cut a run of k >= 2 cells given the energies before each cut (k values, the last the
    total): the cut 1..k-1 whose two sides are most nearly equal; the middle if there is no energy."""
    total = cumulative[-1]
    if total <= 0:
        return len(cumulative) // 2
    return 1 + int(np.argmin(np.abs(cumulative[:-1] - 0.5 * total)))


def _lights(regions, flux, energy, omega, dirs) -> AreaLights:
    direction, sigma, intensity = [], [], []
    for i0, i1, j0, j1 in regions:
        weight = energy[i0:i1, j0:j1]
        if weight.sum() <= 0:
            weight = np.broadcast_to(omega[i0:i1, None], weight.shape)
        d = dirs[i0:i1, j0:j1]
        mean = np.einsum("ij,ijk->k", weight, d) / weight.sum()
        length = np.linalg.norm(mean)
        mean = mean / length if length > 1e-12 else np.array([0.0, 1.0, 0.0])
        direction.append(mean)
        sigma.append(cell_sigma(d.reshape(-1, 3), weight.reshape(-1), np.broadcast_to(omega[i0:i1, None], weight.shape).reshape(-1)))
        intensity.append(flux[i0:i1, j0:j1].sum(axis=(0, 1)))
    return AreaLights(np.array(direction), np.array(sigma), np.array(intensity)).validate()
