"""The size of each area light from its own part of the map: a softbox's light keeps the softbox's width.

The fits (:mod:`viewer.lighting.lightfit`) chose each light's sigma by searching the shadows of a
small sphere-on-plane scene. A compact bright source (the studio map's lamp, 2.6 degrees across)
is split by the median cut into a cluster of lights, and the search left most of them at 0, point
lights, while a sun could come out at 5 (8 degrees); what suits the small scene's shadows did not
carry over to a person's.

Here every texel of the map belongs to the light nearest it (a Voronoi cell on the sphere). Within
its cell, a light's *size* is the angular Gaussian sigma of the cell's light about the cell's energy
centroid, measured robustly: the angle within which half the cell's energy lies (``r50``) is
``alpha * sqrt(2 ln 2)`` for a 2-D Gaussian of per-axis sigma ``alpha`` (a dim halo far out, the
room's walls, moves the median little while it would dominate a second moment), with the texels'
own width added in quadrature (a light that owns a single texel is a texel wide). In the engine's
unit (:data:`viewer.scene.shadow_space.ANGULAR_SIGMA` radians a sigma unit, the factor the contact
benchmark checks against Mitsuba) that is ``alpha / ANGULAR_SIGMA``.

That size is the sigma the ``instant``, ``fast`` and ``median-cut`` fits give each light (the
``paper`` method keeps its Step 3). Against Mitsuba on the sample person and the ground under the
nine shared maps (``relight bench light-sizes``, docs/lights.md), the sizes beat the sigma search
they replace on the ground's shadow on 8 maps (equal on the 9th) and on the studio map's person
(10.8 -> 9.0 %) and ground (0.134 -> 0.098); half or twice the sizes do worse on the ground, so the
unit takes no extra factor (the person alone would prefer half the sizes on the sky maps).
"""

from __future__ import annotations

import math

import numpy as np

from viewer.lighting.envmap import LUMINANCE, EnvMap, pixel_directions, solid_angles
from viewer.scene.shadow_space import ANGULAR_SIGMA

SIGMA_MAX = 20.0  # the paper's upper bound on sigma (its Step 3's 20 sigmoid(s)); 256-px units
SIZE_MAP_WIDTH = 512  # the map is area-averaged to this width first (the fit's own samples use 512 x 256)
R50_PER_SIGMA = math.sqrt(2.0 * math.log(2.0))  # the radius holding half a 2-D Gaussian's energy, in sigmas


def cell_sigma(directions: np.ndarray, weight: np.ndarray, omega: np.ndarray) -> float:
    """The size of the light spread over unit ``directions`` (M, 3) with energies ``weight`` (M,),
    texels of solid angles ``omega`` (M,): the angle about their energy centroid within which half
    the energy lies, as a Gaussian sigma, and each texel's own spread (a square of side sqrt(omega):
    omega / 12 a axis) added in quadrature (a light that owns one texel is as wide as it); in the
    engine's unit, at most ``SIGMA_MAX``; 0 without energy."""
    total = float(weight.sum())
    if not total > 0.0:
        return 0.0
    centroid = weight @ directions
    length = np.linalg.norm(centroid)
    if length < 1e-12:  # energy all around: as soft as a light gets
        return SIGMA_MAX
    angle = np.arccos(np.clip(directions @ (centroid / length), -1.0, 1.0))
    order = np.argsort(angle)
    half = min(int(np.searchsorted(np.cumsum(weight[order]), 0.5 * total)), len(order) - 1)
    spread = angle[order][half] / R50_PER_SIGMA
    texel = float(weight @ omega) / total / 12.0
    return float(min(SIGMA_MAX, math.sqrt(spread * spread + texel) / ANGULAR_SIGMA))


def cap_sigma(radius: float) -> float:
    """The size of light spread evenly over a cap of angular ``radius`` (radians), by the rule of
    :func:`cell_sigma`: the angle holding half its energy (half its solid angle) as a Gaussian sigma,
    in the engine's unit, at most ``SIGMA_MAX``."""
    half = math.acos(1.0 - 0.5 * (1.0 - math.cos(radius)))
    return float(min(SIGMA_MAX, half / R50_PER_SIGMA / ANGULAR_SIGMA))


def region_sizes(env: EnvMap, direction: np.ndarray, max_width: int = SIZE_MAP_WIDTH) -> np.ndarray:
    """(N,) each light's size (:func:`cell_sigma`) over the map's texels nearer to it than to any
    other light (see the module docstring); a light that owns no texel (stacked on another) takes
    the size of the nearest light that does."""
    direction = np.asarray(direction, np.float64).reshape(-1, 3)
    env = env.downsampled(max_width)
    h, w = env.height, env.width
    dirs = pixel_directions(h, w).reshape(-1, 3)
    omega = np.broadcast_to(solid_angles(h, w)[:, None], (h, w)).reshape(-1)
    energy = (env.pixels.astype(np.float64) @ LUMINANCE).reshape(-1) * omega
    owner = np.argmax(dirs @ direction.T, axis=1)
    owned = np.bincount(owner, minlength=len(direction)) > 0
    sizes = np.array([cell_sigma(dirs[owner == i], energy[owner == i], omega[owner == i]) if owned[i] else 0.0
                      for i in range(len(direction))])
    for i in np.flatnonzero(~owned):
        nearest = np.flatnonzero(owned)[np.argmax(direction[owned] @ direction[i])]
        sizes[i] = sizes[nearest]
    return sizes
