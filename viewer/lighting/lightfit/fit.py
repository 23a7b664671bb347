"""Fitting N area lights to an environment map: the paper's optimization and a fast default.

Four methods (error against run time in docs/lights.md, from ``relight bench lights``):

``median-cut``
    Initialization only: :func:`viewer.lighting.median_cut.median_cut_lights` (directions and intensities
    straight from the map, sigma each region's size).
``instant`` (the default)
    ``fast`` on small views (a 32-pixel sphere, 512 map samples) with ``INSTANT_STEPS`` Adam steps:
    about half a second per map, so the viewer and the command line never make the user wait on a fit.
``fast``
    Median cut, then a short Step 2 (``FAST_STEPS`` Adam steps on directions and log-intensities,
    learning rate cosine-annealed to 0, the paper's diffuse + specular sRGB L1 loss). Each light's
    sigma is then its size on the map (:func:`viewer.lighting.light_size.region_sizes`: the angular
    spread of the part of the map nearest it), which carries over to a person's shadows better than
    a search on the sphere-on-plane scene's (docs/lights.md, ``relight bench light-sizes``).
``paper``
    The paper's procedure: Step 1 directions on a Fibonacci sphere, constant intensities, sigma 10;
    Step 2, 1000 Adam steps (betas 0.5, 0.999; learning rate cosine-annealed from 1 to 1e-5 with
    T_max 20, i.e. oscillating with period 40 steps) on directions and softplus intensities, loss =
    L1 of diffuse and specular in sRGB + 0.01 x repulsion (pairwise dot products above tau = 0.65);
    Step 3, 300 Adam steps on sigma = 20 sigmoid(s), directions and intensities fixed, loss = L1
    between Laplacians (kernels 15, 21, 33 at 256 px, scaled to the view) of the sRGB shadowed
    diffuse shading. As in the authors' script, each step returns its lowest-loss iterate. The soft shadows of
    the (fixed-direction) lights are tabulated at the sigmas of ``SIGMA_TABLE`` with the twin's
    convolutional shadow maps and interpolated linearly in between: one exact pre-filter per step
    would cost ~1.3 s here (300 steps: 7 minutes), the table costs ~0.4 s per node once (its
    interpolation error is measured in the tests).

The repulsion as printed in the paper, |max(tau, <l, m> - tau)|^2, has no gradient (its argument
never exceeds tau); the intent stated in the text, dot products "not greater than tau", is
``max(0, <l, m> - tau)^2`` and that is what is used.

All methods fit the normalized reference (:mod:`.problem`) and scale the intensities back, so a
map's brightness does not change the optimization. A black map gives N lights of zero intensity
and a warning. Every method reports progress through ``progress(stage, done, total)`` and can be
interrupted (KeyboardInterrupt) at any point without side effects.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
import torch

from viewer.errors import InputError
from viewer.lighting.envmap import EnvMap
from viewer.lighting.light_size import SIGMA_MAX, region_sizes
from viewer.lighting.lightfit.adam import CosineAdam
from viewer.lighting.lightfit.methods import DEFAULT_METHOD, METHODS, check_light_count
from viewer.lighting.lightfit.problem import FitSettings, Problem, VisibilityTable, build_problem, report, shadowed_views
from viewer.lighting.median_cut import median_cut_lights
from viewer.scene.area_lights import AreaLights
from viewer.twin.srgb import srgb_encode

DEFAULT_SETTINGS = FitSettings()  # frozen: one default shared by every call

FAST_STEPS = 300
FAST_LR = 0.15
# instant: the fast method's steps on small views (docs/lights.md), so a new map is lit while the user waits
INSTANT_SETTINGS = FitSettings(sphere_resolution=32, samples=512)
INSTANT_STEPS = 150
# sigmas at which the soft shadows of the paper's fixed-direction lights are tabulated for its Step 3
# (interpolated linearly between them)
SIGMA_TABLE = (0.0, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 12.0, 14.0, 16.0,
              18.0, 20.0)
PAPER_STEP2 = 1000
PAPER_STEP3 = 300
PAPER_LR = 1.0
PAPER_T_MAX = 20
PAPER_ETA_MIN = 1e-5
PAPER_SIGMA_INIT = 10.0
REPULSION_WEIGHT = 0.01
TAU = 0.65
LAPLACIAN_KERNELS = (15, 21, 33)  # at 256 px (the paper's view size)


def fit_lights(env: EnvMap, n: int, method: str = DEFAULT_METHOD, settings: FitSettings = DEFAULT_SETTINGS,
               progress=None, problem: Problem | None = None) -> AreaLights:
    """``n`` area lights approximating ``env`` with ``method`` (see the module docstring).

    ``problem`` reuses references already built for this map (the benchmark fits several methods)."""
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
    if method in ("instant", "fast"):
        if method == "instant":  # its own small views, whatever was passed
            problem = build_problem(env, INSTANT_SETTINGS, progress, shadows=False)
        elif problem is None:
            problem = build_problem(env, settings, progress, shadows=False)
        steps = INSTANT_STEPS if method == "instant" else FAST_STEPS
        direction, intensity = _refine_fast(problem, median_cut_lights(env, n), progress, steps)
        sigma = region_sizes(env, direction)
    else:
        if problem is None:
            problem = build_problem(env, settings, progress)
        direction, intensity = _paper_step2(problem, n, progress)
        sigma = _paper_step3(problem, direction, intensity, progress)
    return AreaLights(direction, sigma, intensity * problem.scale).validate(env.source)


def fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` nearly uniform unit directions (the paper's Step 1)."""
    i = np.arange(n) + 0.5
    y = 1.0 - 2.0 * i / n
    r = np.sqrt(np.maximum(0.0, 1.0 - y * y))
    phi = np.pi * (3.0 - np.sqrt(5.0)) * i
    return np.stack([r * np.cos(phi), y, r * np.sin(phi)], axis=1)


# ---------------------------------------------------------------- losses
def step2_loss(problem: Problem, direction: torch.Tensor, intensity: torch.Tensor) -> torch.Tensor:
    """The paper's L_diff + L_spec: L1 in sRGB of the sphere's diffuse and specular shading."""
    diff, spec = problem.sphere_shading(direction, intensity)
    return ((srgb_encode(diff) - srgb_encode(problem.sphere_diffuse)).abs().mean()
            + (srgb_encode(spec) - srgb_encode(problem.sphere_specular)).abs().mean())


def repulsion(direction: torch.Tensor, tau: float = TAU) -> torch.Tensor:
    """Mean over ordered pairs of max(0, <l, m> - tau)^2."""
    n = direction.shape[0]
    if n < 2:
        return direction.sum() * 0.0
    dots = direction @ direction.T
    off = ~torch.eye(n, dtype=torch.bool)
    return (dots[off] - tau).clamp(min=0.0).pow(2).mean()


def laplacian_kernels(resolution: int) -> tuple[int, ...]:
    """The paper's kernel sizes scaled from 256 px to ``resolution``, odd and >= 3."""
    return tuple(max(3, 2 * round((k * resolution / 256 - 1) / 2) + 1) for k in LAPLACIAN_KERNELS)


def laplacian(images: torch.Tensor, k: int) -> torch.Tensor:
    """Normalized k x k Laplacian of (B, H, W) images, as kornia's: (box sum - k^2 centre) / (2 (k^2 - 1)),
    reflected borders; the box sum by cumulative sums (cost independent of k)."""
    r = k // 2
    padded = torch.nn.functional.pad(images[:, None], (r, r, r, r), mode="reflect")[:, 0]
    c = torch.nn.functional.pad(padded.cumsum(dim=1), (0, 0, 1, 0))
    rows = c[:, k:] - c[:, :-k]
    c = torch.nn.functional.pad(rows.cumsum(dim=2), (1, 0))
    box = c[:, :, k:] - c[:, :, :-k]
    return (box - k * k * images) / (2.0 * (k * k - 1))


def _as_images(problem: Problem, shading: torch.Tensor) -> torch.Tensor:
    res = problem.plane.resolution
    return shading.permute(0, 2, 1).reshape(-1, res, res)


@dataclass(frozen=True)
class Step3Target:
    """The reference side of the Step 3 loss, computed once: Laplacians of the reference shading."""

    kernels: tuple
    laplacians: tuple

    @staticmethod
    def of(problem: Problem) -> Step3Target:
        kernels = laplacian_kernels(problem.plane.resolution)
        ref = srgb_encode(_as_images(problem, problem.plane_shadowed))
        return Step3Target(kernels, tuple(laplacian(ref, k) for k in kernels))

    def loss(self, problem: Problem, shading: torch.Tensor) -> torch.Tensor:
        """Sum over kernels of the L1 between Laplacians of the sRGB shadowed diffuse shading (K, P, 3)."""
        model = srgb_encode(_as_images(problem, shading))
        return sum((laplacian(model, k) - ref).abs().mean() for k, ref in zip(self.kernels, self.laplacians))


# ---------------------------------------------------------------- fast
def _refine_fast(problem: Problem, start: AreaLights, progress, steps: int = FAST_STEPS):
    """Short Step 2 from a good start: ``steps`` Adam steps on directions and log-intensities."""
    direction = torch.tensor(start.direction, dtype=torch.float32, requires_grad=True)
    base = torch.as_tensor(start.intensity, dtype=torch.float32) / problem.scale
    floor = 1e-6 * float(base.sum(dim=1).max())  # lights without energy may grow from a small seed
    log_int = torch.log(base.clamp(min=floor)).requires_grad_(True)
    opt = CosineAdam([direction, log_int], lr=FAST_LR, betas=(0.5, 0.999), t_max=steps)
    report(progress, "directions", 0, steps)
    for step in range(steps):
        opt.zero_grad()
        loss = step2_loss(problem, _unit(direction), torch.exp(log_int))
        loss.backward()
        opt.step()
        report(progress, "directions", step + 1, steps)
    with torch.no_grad():
        return _unit(direction).numpy().astype(np.float64), torch.exp(log_int).numpy().astype(np.float64)


def _visibility_table(problem: Problem, direction: np.ndarray, progress, sigmas=SIGMA_TABLE) -> VisibilityTable:
    """Soft shadows of fixed-direction lights on the sphere-on-plane views at every sigma of ``sigmas``."""
    s = problem.settings
    report(progress, "shadows", 0, 2)
    views = shadowed_views(problem.plane, direction, problem.rotations, s.shadow_resolution, s.terms)
    report(progress, "shadows", 1, 2)
    table = VisibilityTable.of(views, sigmas)
    report(progress, "shadows", 2, 2)
    return table


# ---------------------------------------------------------------- paper
def _paper_optimizer(params, lr=PAPER_LR) -> CosineAdam:
    return CosineAdam(params, lr=lr, betas=(0.5, 0.999), t_max=PAPER_T_MAX, eta_min=PAPER_ETA_MIN)


def _inverse_softplus(y: float) -> float:
    return y + math.log(-math.expm1(-y))


def _paper_step2(problem: Problem, n: int, progress):
    direction = torch.tensor(fibonacci_sphere(n), dtype=torch.float32, requires_grad=True)
    energy = float(problem.samples.energy().mean()) / problem.scale
    raw = torch.full((n, 3), _inverse_softplus(energy / n), dtype=torch.float32, requires_grad=True)
    opt = _paper_optimizer([direction, raw])
    best = (math.inf, None)
    for step in range(PAPER_STEP2):
        opt.zero_grad()
        unit = _unit(direction)
        intensity = torch.nn.functional.softplus(raw)
        loss = step2_loss(problem, unit, intensity) + REPULSION_WEIGHT * repulsion(unit)
        if loss.item() < best[0]:  # the learning rate never settles (T_max 20): keep the best iterate
            best = (loss.item(), (unit.detach().clone(), intensity.detach().clone()))
        loss.backward()
        opt.step()
        report(progress, "directions", step + 1, PAPER_STEP2)
    unit, intensity = best[1]
    return unit.numpy().astype(np.float64), intensity.numpy().astype(np.float64)


def _paper_step3(problem: Problem, direction: np.ndarray, intensity: np.ndarray, progress) -> np.ndarray:
    table = _visibility_table(problem, direction, progress)
    inten = torch.as_tensor(intensity, dtype=torch.float32)
    target = Step3Target.of(problem)
    n = len(direction)
    start = math.log(PAPER_SIGMA_INIT / (SIGMA_MAX - PAPER_SIGMA_INIT))  # sigma = 20 sigmoid(s) starts at 10
    logit = torch.full((n,), start, requires_grad=True)
    opt = _paper_optimizer([logit])
    best = (math.inf, None)
    for step in range(PAPER_STEP3):
        opt.zero_grad()
        sigma = SIGMA_MAX * torch.sigmoid(logit)
        loss = target.loss(problem, table.views.shading(table(sigma), inten))
        if loss.item() < best[0]:
            best = (loss.item(), sigma.detach().clone())
        loss.backward()
        opt.step()
        report(progress, "sigma", step + 1, PAPER_STEP3)
    return best[1].numpy().astype(np.float64)


def _unit(v: torch.Tensor) -> torch.Tensor:
    return v / v.norm(dim=1, keepdim=True).clamp(min=1e-12)
