"""Per-light shading of the area lights, each treated as a directional light (the paper, Stage 1).

Torch twin of ``shaders/brdf.glsl``: Lambert diffuse and the Disney principled specular lobe (GGX),
per unit light intensity, view vector (0, 0, 1). Conventions in docs/conventions.md.

Shapes: normals ``(..., 3)`` (camera space, unit), light directions ``(N, 3)`` (unit, towards the
light); results ``(N, ...)``. Every function is differentiable with respect to the light directions
and stays finite (values and gradients) for roughness 0 and 1, grazing lights and lights below the
horizon or straight from behind, where the shading is zero.
"""

from __future__ import annotations

import math

import torch

from viewer.constants import MIN_ALPHA, SPECULAR_SCALE  # the shaders' values (generated #defines)


def _cosines(normal: torch.Tensor, light_dir: torch.Tensor) -> torch.Tensor:
    """n.l for every light: (N, ...)."""
    flat = normal.reshape(-1, 3)
    return (light_dir.to(flat.dtype) @ flat.T).reshape(light_dir.shape[0], *normal.shape[:-1])


def diffuse_shading(normal: torch.Tensor, light_dir: torch.Tensor) -> torch.Tensor:
    """Lambert shading per unit intensity, ``max(0, n.l) / pi``: (N, ...)."""
    return _cosines(normal, light_dir).clamp(min=0.0) / math.pi


def _smith_g1(x: torch.Tensor, a2: torch.Tensor) -> torch.Tensor:
    """Smith G1 in the form holding 1 / (2 x): ``1 / (x + sqrt(a2 + x^2 - a2 x^2))``."""
    return 1.0 / (x + torch.sqrt(a2 + x * x - a2 * x * x))


def widened_alpha(roughness: torch.Tensor, light_angle: torch.Tensor | None) -> torch.Tensor:
    """GGX alpha ``max(roughness^2, MIN_ALPHA)`` widened by each light's angular sigma (radians, (N,)):
    ``min(sqrt(alpha^2 + light_angle^2 / 2), 1)``, (N, ...) (shaders/brdf.glsl says why); (1, ...)
    without ``light_angle`` (point lights)."""
    alpha = (roughness * roughness).clamp(min=MIN_ALPHA).unsqueeze(0)
    if light_angle is None:
        return alpha
    angle = light_angle.to(alpha.dtype).reshape(-1, *([1] * roughness.dim()))
    return torch.sqrt(alpha * alpha + 0.5 * angle * angle).clamp(max=1.0)


def specular_shading(normal: torch.Tensor, light_dir: torch.Tensor, specular: torch.Tensor,
                     roughness: torch.Tensor, light_angle: torch.Tensor | None = None) -> torch.Tensor:
    """Disney principled specular per unit intensity, ``n.l F D G``: (N, ...).

    ``F0 = 0.08 specular``, Schlick Fresnel on l.h, ``alpha = max(roughness^2, 1e-3)`` widened by
    the lights' angular sigmas ``light_angle`` (N,) where given (:func:`widened_alpha`), GGX D,
    Smith ``G = G1(n.l) G1(n.v)``, view vector v = (0, 0, 1). ``specular`` and ``roughness`` have
    the normals' batch shape. As in ``shaders/brdf.glsl`` the lobe is zero where n.l <= 0, n.v <= 0
    or specular <= 0 (a matte pixel has no specular, not even Schlick's grazing term), and n.h, l.h
    are clamped at 0.
    """
    dtype = normal.dtype
    l = light_dir.to(dtype)
    nl = _cosines(normal, l)  # (N, ...)
    nv = normal[..., 2].unsqueeze(0)  # n.v with v = (0, 0, 1)
    lv = l + torch.tensor([0.0, 0.0, 1.0], dtype=dtype, device=l.device)
    # normalize(l + v) with a floor on the length, so a light straight from behind stays finite
    h = lv * torch.rsqrt((lv * lv).sum(dim=1, keepdim=True).clamp(min=1e-12))
    nh = _cosines(normal, h).clamp(min=0.0)
    lh = (l * h).sum(dim=1).clamp(min=0.0).reshape(-1, *([1] * (normal.dim() - 1)))
    alpha = widened_alpha(roughness, light_angle)
    a2 = alpha * alpha
    f0 = (SPECULAR_SCALE * specular).unsqueeze(0)
    fresnel = f0 + (1.0 - f0) * (1.0 - lh) ** 5
    t = nh * nh * (a2 - 1.0) + 1.0
    d = a2 / (math.pi * t * t)
    nl_pos = nl.clamp(min=0.0)
    nv_pos = nv.clamp(min=0.0)
    g = _smith_g1(nl_pos, a2) * _smith_g1(nv_pos, a2)
    active = (nl > 0.0) & (nv > 0.0) & (specular.unsqueeze(0) > 0.0)
    return torch.where(active, nl_pos * fresnel * d * g, torch.zeros((), dtype=dtype, device=nl.device))
