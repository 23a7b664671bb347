"""Fitting N area lights to an environment map: the paper's optimization and a fast default.

Four methods (error against run time in docs/lights.md, from ``relight bench lights``):

``median-cut``
    Initialization only: :func:`viewer.lighting.median_cut.median_cut_lights` (directions and intensities
    straight from the map, sigma each region's size).
``instant`` (the default)
    ``fast`` on small views (a 32-pixel sphere, 512 map samples) with ``INSTANT_STEPS`` Adam steps,
    so the viewer and the command line never make the user wait on a fit (``relight bench timings``).
``fast``
    Median cut, then a short Step 2 (``FAST_STEPS`` Adam steps on directions and log-intensities,
    learning rate cosine-annealed to 0, the paper's diffuse + specular sRGB L1 loss), in numpy with
    the gradient written out (:mod:`.sphere_fit`): instant and fast never import torch. Each light's
    sigma is then its size on the map (:func:`viewer.lighting.light_size.region_sizes`: the angular
    spread of the part of the map nearest it), which carries over to a person's shadows better than
    a search on the sphere-on-plane scene's (docs/lights.md, ``relight bench light-sizes``).
``paper`` (:mod:`.paper`, torch)
    The paper's procedure: Step 1 directions on a Fibonacci sphere, constant intensities, sigma 10;
    Step 2, 1000 Adam steps (betas 0.5, 0.999; learning rate cosine-annealed from 1 to 1e-5 with
    T_max 20, i.e. oscillating with period 40 steps) on directions and softplus intensities, loss =
    L1 of diffuse and specular in sRGB + 0.01 x repulsion (pairwise dot products above tau = 0.65);
    Step 3, 300 Adam steps on sigma = 20 sigmoid(s), directions and intensities fixed, loss = L1
    between Laplacians (kernels 15, 21, 33 at 256 px, scaled to the view) of the sRGB shadowed
    diffuse shading. As in the authors' script, each step returns its lowest-loss iterate (the
    repulsion's reading and Step 3's soft-shadow table: :mod:`.paper`).

All methods fit the normalized reference (the sphere's mean diffuse luminance 1) and scale the intensities back, so a
map's brightness does not change the optimization. A black map gives N lights of zero intensity
and a warning. Every method reports progress through ``progress(stage, done, total)`` and can be
interrupted (KeyboardInterrupt) at any point without side effects.
"""

from __future__ import annotations

import warnings

import numpy as np

from viewer.errors import InputError
from viewer.lighting.envmap import EnvMap
from viewer.lighting.light_size import region_sizes
from viewer.lighting.lightfit.methods import DEFAULT_METHOD, METHODS, check_light_count
from viewer.lighting.lightfit.samples import map_samples
from viewer.lighting.lightfit.settings import DEFAULT_SETTINGS, FitSettings, report
from viewer.lighting.lightfit.sphere_fit import refine, sphere_target
from viewer.lighting.median_cut import median_cut_lights
from viewer.scene.area_lights import AreaLights

FAST_STEPS = 300
FAST_LR = 0.15
# instant: the fast method's steps on small views (docs/lights.md), so a new map is lit while the user waits
INSTANT_SETTINGS = FitSettings(sphere_resolution=32, samples=512)
INSTANT_STEPS = 150


def fit_lights(env: EnvMap, n: int, method: str = DEFAULT_METHOD, settings: FitSettings = DEFAULT_SETTINGS,
               progress=None, problem=None) -> AreaLights:
    """``n`` area lights approximating ``env`` with ``method`` (see the module docstring).

    ``problem`` (a :class:`.problem.Problem`) reuses references already built for this map (the
    benchmark fits several methods)."""
    if method not in METHODS:
        raise InputError(None, f"unknown fitting method {method!r} (choose from {', '.join(METHODS)})")
    if n < 1:
        raise InputError(env.source, f"the number of lights must be >= 1, got {n}")
    check_light_count(method, n, env.source)
    if not np.any(env.pixels > 0):
        warnings.warn(f"{env.source or 'environment map'}: the map is black (every pixel is 0): "
                      f"its {n} lights have zero intensity", stacklevel=2)
        return AreaLights(fibonacci_sphere(n), np.zeros(n), np.zeros((n, 3)))
    if method == "median-cut":
        return median_cut_lights(env, n)
    if method == "paper":
        from viewer.lighting.lightfit.paper import fit_paper  # torch: only the paper's method needs it

        return fit_paper(env, fibonacci_sphere(n), settings, progress, problem)
    if method == "instant" or problem is None:  # instant: its own small views, whatever was passed
        views = INSTANT_SETTINGS if method == "instant" else settings
        report(progress, "reference", 0, 1)
        target, scale = sphere_target(map_samples(env, views.samples), views.sphere_resolution)
        report(progress, "reference", 1, 1)
    else:
        target, scale = problem.target, problem.scale
    start = median_cut_lights(env, n)
    steps = INSTANT_STEPS if method == "instant" else FAST_STEPS
    direction, intensity = refine(target, start.direction, start.intensity / scale, steps, FAST_LR, progress)
    return AreaLights(direction, region_sizes(env, direction), intensity * scale).validate(env.source)


def fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` nearly uniform unit directions (the paper's Step 1)."""
    i = np.arange(n) + 0.5
    y = 1.0 - 2.0 * i / n
    r = np.sqrt(np.maximum(0.0, 1.0 - y * y))
    phi = np.pi * (3.0 - np.sqrt(5.0)) * i
    return np.stack([r * np.cos(phi), y, r * np.sin(phi)], axis=1)
