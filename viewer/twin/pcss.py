"""Contact-hardening soft shadows: torch twin of ``shaders/pcss.glsl``, batched over lights.

Percentage-closer soft shadows on the hard shadow map, with the light's sigma read as an angle
(alpha = sigma x :data:`viewer.scene.shadow_space.ANGULAR_SIGMA` radians):

1. blocker search: PCSS_SEARCH_TAPS :func:`viewer.scene.shadow_space.pcss_taps` offsets scaled to alpha x
   PCSS_SEARCH shadow-map windows; a tap is a blocker when its depth is nearer than the receiver's tangent
   plane there (minus the hard test's bias) and its texel is not empty (``empty_depth``); the gap is the
   mean of (plane - depth) over blockers;
2. no blocker: visibility 1; else the penumbra's sigma is alpha x gap x depth scale metres, at
   least PCSS_MIN_TEXELS texels, and the visibility the fraction of PCSS_TAPS taps, scaled to the
   penumbra, that pass the tangent-plane test.

Texel lookups are the hard test's (the texel containing the point, clamp-to-edge). Not
differentiable in sigma (the tests are steps); the light fitting keeps using the CSM twin.
"""

from __future__ import annotations

import torch

from viewer.scene import shadow_space as rule
from viewer.twin.csm import shadow_depth
from viewer.twin.shadow_geometry import LightFrames


def receiver_gradient(frames: LightFrames, normals: torch.Tensor) -> torch.Tensor:
    """(N, P, 2): normalised depth per unit of shadow-map (u, v) along each receiver's tangent plane,
    n.l floored at 1 / MAX_SLOPE (shaders/pcss.glsl's ``receiver_gradient``)."""
    window = 2.0 * frames.radius
    scale = frames.depth_scale()[:, None, None]
    cos = (frames.direction @ normals.T).clamp(min=1.0 / rule.MAX_SLOPE)  # (N, P)
    return torch.stack([frames.right @ normals.T, frames.up @ normals.T], dim=-1) * window / (scale * cos[..., None])


def soft_visibility(depth: torch.Tensor, sigma: torch.Tensor, frames: LightFrames, u: torch.Tensor, v: torch.Tensor,
                    d: torch.Tensor, bias: torch.Tensor, gradient: torch.Tensor) -> torch.Tensor:
    """Soft visibility (N, P) of receivers (u, v, d) and hard-test ``bias``, each (N, P), with
    tangent-plane ``gradient`` (N, P, 2), in shadow maps ``depth`` (N, R, R) of lights with
    ``sigma`` (N,) (256-px units)."""
    res = depth.shape[-1]
    taps = torch.as_tensor(rule.pcss_taps(rule.PCSS_TAPS), dtype=d.dtype, device=d.device)
    search_taps = torch.as_tensor(rule.pcss_taps(rule.PCSS_SEARCH_TAPS), dtype=d.dtype, device=d.device)
    window = 2.0 * frames.radius
    alpha = (sigma.to(d.dtype) * rule.ANGULAR_SIGMA)[:, None]  # (N, 1)
    search = alpha * rule.PCSS_SEARCH
    gap = torch.zeros_like(d)
    blockers = torch.zeros_like(d)
    for o in search_taps:
        du, dv = o[0] * search, o[1] * search
        receiver = d + gradient[..., 0] * du + gradient[..., 1] * dv - bias
        z = shadow_depth(depth, u + du, v + dv)
        hit = (z < receiver) & (z < frames.empty_depth)  # an empty texel is never a blocker
        gap = gap + torch.where(hit, receiver - z, torch.zeros_like(z))
        blockers = blockers + hit.to(d.dtype)
    width = (alpha * (gap / blockers.clamp(min=1.0)) * frames.depth_scale()[:, None] / window).clamp(
        min=rule.PCSS_MIN_TEXELS / res)  # uv
    lit = torch.zeros_like(d)
    for o in taps:
        du, dv = o[0] * width, o[1] * width
        receiver = d + gradient[..., 0] * du + gradient[..., 1] * dv - bias
        z = shadow_depth(depth, u + du, v + dv)
        lit = lit + ((receiver <= z) | (z >= frames.empty_depth)).to(d.dtype)
    return torch.where(blockers == 0, torch.ones_like(d), lit / len(taps))


def twin_visibility(depth, sigma, frames, u, v, d, bias, normal, terms: int):
    """:func:`soft_visibility` with the arguments every soft-shadow method's twin takes
    (:meth:`viewer.gl.soft.SoftMethod.twin`)."""
    return soft_visibility(depth, sigma, frames, u, v, d, bias, receiver_gradient(frames, normal))
