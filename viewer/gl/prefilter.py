"""How a light's convolutional shadow map is pre-filtered: exact Gaussian or resolution pyramid.

``exact`` blurs the full-resolution basis maps with the paper's kernel (2 ceil(3 sigma) + 1 taps),
so its cost grows with sigma. ``pyramid`` (the default) blurs a mip level instead: level L of the
box-filtered mip chain already carries a blur of variance (4^L - 1) / 12 base texels, bilinear
reconstruction from it adds (4^L - 1) / 6 more than at level 0, and the residual Gaussian at that
level makes up the rest, so the total matches sigma^2. L is the largest level at which the residual
is still about a texel or more, which bounds the kernel to <= 13 taps whatever sigma is.
The error this adds against ``exact`` is measured by ``relight bench engine`` and tested.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

METHODS = ("pyramid", "exact")


@dataclass(frozen=True)
class BlurPlan:
    level: int  # mip level the separable Gaussian runs on
    sigma: float  # residual sigma in texels of that level
    radius: int  # taps on each side

    @property
    def norm(self) -> float:
        if self.radius == 0 or self.sigma <= 0:
            return 1.0
        return 1.0 / sum(math.exp(-0.5 * i * i / (self.sigma * self.sigma)) for i in range(-self.radius, self.radius + 1))


def blur_plan(sigma_px: float, resolution: int, method: str = "pyramid") -> BlurPlan:
    """Plan for a Gaussian of ``sigma_px`` shadow-map texels on a map of ``resolution`` texels."""
    if method not in METHODS:
        raise ValueError(f"unknown prefilter method {method!r} (choose from {', '.join(METHODS)})")
    # at most the map's width (what viewer.scene.area_lights.MAX_SIGMA allows): bounds the exact kernel's cost
    sigma_px = min(max(float(sigma_px), 0.0), float(resolution))
    if method == "exact" or sigma_px < 2.0:
        return BlurPlan(0, sigma_px, int(math.ceil(3.0 * sigma_px)) if sigma_px > 1e-3 else 0)
    max_level = max(int(math.log2(max(resolution, 1))) - 1, 0)
    level = min(int(math.floor(math.log2(sigma_px))), max_level)
    scale = 2.0**level
    residual = math.sqrt(max(sigma_px * sigma_px - (4.0**level - 1.0) / 4.0, 0.0)) / scale
    return BlurPlan(level, residual, int(math.ceil(3.0 * residual)) if residual > 1e-3 else 0)
