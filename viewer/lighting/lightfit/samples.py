"""An environment map as a list of directional samples: the texel sums the reference shading uses.

Integrating over every texel of a 1k map (524 288 texels) for every pixel of every view is exact
but slow. Most texels are dim sky whose light arrives from a wide, smooth region; a few (a sun, a
lamp) hold most of the energy in a tiny one. :func:`map_samples` therefore builds a hierarchy of
texel blocks (2 x 2 sums, from the working map up to a coarse grid) and keeps a *cut* through it:
starting from the coarse grid it splits, greedily, the block with the largest luminance x angular
size (the bound on what treating a block as one direction can get wrong) until ``budget`` samples.
Each kept block becomes one sample:

- ``flux``: the exact sum of L x solid angle of its texels, per RGB channel (the map's energy is
  preserved exactly, whatever the budget);
- ``direction``: its energy-weighted mean direction, normalized (the solid-angle weighted mean for a
  block without energy).

A sun stays at the working map's resolution while the sky is summed in large blocks; the accuracy
of the result against a brute-force sum over every texel is measured in tests and docs/lights.md.
The working map is the input area-averaged (energy-preserving) to at most ``max_width`` texels, a
power of two wide so that the hierarchy halves cleanly; maps smaller than the coarse grid are used
texel by texel.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np

from viewer.lighting.envmap import EnvMap, pixel_directions, solid_angles
from viewer.lighting.median_cut import LUMINANCE

COARSE_WIDTH = 16  # the hierarchy's top grid is 16 x 8 blocks (coarser when the budget is smaller)
MAX_WIDTH = 512  # working resolution: 0.7 degree texels


@dataclass(frozen=True)
class MapSamples:
    """Directional samples of a map: ``direction`` (T, 3) unit float64, ``flux`` (T, 3) float64 >= 0."""

    direction: np.ndarray
    flux: np.ndarray

    def __len__(self) -> int:
        return int(self.direction.shape[0])

    def energy(self) -> np.ndarray:
        return self.flux.sum(axis=0)

    def rotated(self, matrix: np.ndarray) -> MapSamples:
        """The samples of the map rotated by ``matrix`` (L'(R d) = L(d), :meth:`EnvMap.rotated`)."""
        return MapSamples(self.direction @ np.asarray(matrix, dtype=np.float64).T, self.flux)


def working_map(env: EnvMap, max_width: int = MAX_WIDTH) -> EnvMap:
    """``env`` area-averaged to the largest power of two no wider than it and ``max_width``."""
    width = 1 << int(np.floor(np.log2(min(env.width, max_width))))
    return env.downsampled(max(width, 2))


def all_texels(env: EnvMap) -> MapSamples:
    """Every texel as its own sample (the brute-force sum the hierarchy approximates)."""
    omega = solid_angles(env.height, env.width)
    flux = env.pixels.astype(np.float64) * omega[:, None, None]
    return MapSamples(pixel_directions(env.height, env.width).reshape(-1, 3), flux.reshape(-1, 3))


def map_samples(env: EnvMap, budget: int = 2048, max_width: int = MAX_WIDTH) -> MapSamples:
    """At most ``budget`` samples of ``env`` (see the module docstring); all texels if fewer."""
    work = working_map(env, max_width)
    h, w = work.height, work.width
    if budget >= h * w:
        return all_texels(work)
    omega = solid_angles(h, w)[:, None]
    flux = work.pixels.astype(np.float64) * omega[..., None]
    dirs = pixel_directions(h, w)
    lum = flux @ LUMINANCE
    # level 0 = the working map; level k sums 2^k x 2^k blocks, up to the coarse grid
    levels = [(flux, lum, dirs * lum[..., None], dirs * omega[..., None])]
    def too_fine(a):
        return a.shape[1] > COARSE_WIDTH or a.shape[0] * a.shape[1] > budget

    while too_fine(levels[-1][0]) and levels[-1][0].shape[0] >= 2:
        levels.append(tuple(_pool(a) for a in levels[-1]))
    top = len(levels) - 1
    extent = [np.pi / levels[k][0].shape[0] for k in range(len(levels))]  # block height in radians

    def entry(k, i, j):
        return (-levels[k][1][i, j] * extent[k], k, i, j)

    heap = [entry(top, i, j) for i in range(levels[top][0].shape[0]) for j in range(levels[top][0].shape[1])]
    heapq.heapify(heap)
    kept = []
    while heap and len(heap) + len(kept) + 3 <= budget:
        item = heapq.heappop(heap)
        _, k, i, j = item
        if k == 0 or item[0] == 0.0:
            kept.append(item)  # a single texel, or a block without energy: nothing to gain by splitting
            continue
        for di in (0, 1):
            for dj in (0, 1):
                heapq.heappush(heap, entry(k - 1, 2 * i + di, 2 * j + dj))
    blocks = [(k, i, j) for _, k, i, j in kept + heap]
    f = np.array([levels[k][0][i, j] for k, i, j in blocks])
    moment = np.array([levels[k][2][i, j] if levels[k][1][i, j] > 0 else levels[k][3][i, j] for k, i, j in blocks])
    length = np.linalg.norm(moment, axis=1, keepdims=True)
    direction = np.where(length > 1e-300, moment / np.maximum(length, 1e-300), np.array([0.0, 1.0, 0.0]))
    return MapSamples(direction, f)


def _pool(a: np.ndarray) -> np.ndarray:
    """Sum 2 x 2 blocks of an (h, w, ...) array."""
    h, w = a.shape[0] // 2, a.shape[1] // 2
    return a[: 2 * h, : 2 * w].reshape(h, 2, w, 2, *a.shape[2:]).sum(axis=(1, 3))
