"""The paper's light fit (Steps 1-3, in torch): see :mod:`.fit` for the procedure and its constants' sources.

The repulsion as printed in the paper, |max(tau, <l, m> - tau)|^2, has no gradient (its argument
never exceeds tau); the intent stated in the text, dot products "not greater than tau", is
``max(0, <l, m> - tau)^2`` and that is what is used. The soft shadows of the (fixed-direction)
lights of Step 3 are tabulated at the sigmas of ``SIGMA_TABLE`` with the twin's convolutional
shadow maps and interpolated linearly in between: one exact pre-filter per step would cost ~1.3 s
here (300 steps: 7 minutes), the table costs ~0.4 s per node once (its interpolation error is
measured in the tests).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from viewer.lighting.envmap import EnvMap
from viewer.lighting.light_size import SIGMA_MAX
from viewer.lighting.lightfit.adam import CosineAdam
from viewer.lighting.lightfit.problem import Problem, VisibilityTable, build_problem, shadowed_views
from viewer.lighting.lightfit.settings import FitSettings, report
from viewer.scene.area_lights import AreaLights
from viewer.twin.srgb import srgb_encode

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


def fit_paper(env: EnvMap, start: np.ndarray, settings: FitSettings, progress=None,
              problem: Problem | None = None) -> AreaLights:
    """The paper's Steps 2-3 on ``env`` from Step 1's directions ``start`` (N, 3) (its references built
    with ``settings`` unless ``problem`` is given)."""
    if problem is None:
        problem = build_problem(env, settings, progress)
    direction, intensity = _paper_step2(problem, start, progress)
    sigma = _paper_step3(problem, direction, intensity, progress)
    return AreaLights(direction, sigma, intensity * problem.scale).validate(env.source)


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


# ---------------------------------------------------------------- paper
def _visibility_table(problem: Problem, direction: np.ndarray, progress, sigmas=SIGMA_TABLE) -> VisibilityTable:
    """Soft shadows of fixed-direction lights on the sphere-on-plane views at every sigma of ``sigmas``."""
    s = problem.settings
    report(progress, "shadows", 0, 2)
    views = shadowed_views(problem.plane, direction, problem.rotations, s.shadow_resolution, s.terms)
    report(progress, "shadows", 1, 2)
    table = VisibilityTable.of(views, sigmas)
    report(progress, "shadows", 2, 2)
    return table


def _paper_optimizer(params, lr=PAPER_LR) -> CosineAdam:
    """Adam on the tensors' numpy views (they share the tensors' memory)."""
    return CosineAdam([p.detach().numpy() for p in params], lr=lr, betas=(0.5, 0.999), t_max=PAPER_T_MAX,
                      eta_min=PAPER_ETA_MIN)


def _step(opt: CosineAdam, params) -> None:
    opt.step([p.grad.numpy() for p in params])
    for p in params:
        p.grad = None


def _inverse_softplus(y: float) -> float:
    return y + math.log(-math.expm1(-y))


def _paper_step2(problem: Problem, start: np.ndarray, progress):
    n = len(start)
    direction = torch.tensor(start, dtype=torch.float32, requires_grad=True)
    energy = float(problem.samples.energy().mean()) / problem.scale
    raw = torch.full((n, 3), _inverse_softplus(energy / n), dtype=torch.float32, requires_grad=True)
    opt = _paper_optimizer([direction, raw])
    best = (math.inf, None)
    for step in range(PAPER_STEP2):
        unit = _unit(direction)
        intensity = torch.nn.functional.softplus(raw)
        loss = step2_loss(problem, unit, intensity) + REPULSION_WEIGHT * repulsion(unit)
        if loss.item() < best[0]:  # the learning rate never settles (T_max 20): keep the best iterate
            best = (loss.item(), (unit.detach().clone(), intensity.detach().clone()))
        loss.backward()
        _step(opt, [direction, raw])
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
        sigma = SIGMA_MAX * torch.sigmoid(logit)
        loss = target.loss(problem, table.views.shading(table(sigma), inten))
        if loss.item() < best[0]:
            best = (loss.item(), sigma.detach().clone())
        loss.backward()
        _step(opt, [logit])
        report(progress, "sigma", step + 1, PAPER_STEP3)
    return best[1].numpy().astype(np.float64)


def _unit(v: torch.Tensor) -> torch.Tensor:
    return v / v.norm(dim=1, keepdim=True).clamp(min=1e-12)
