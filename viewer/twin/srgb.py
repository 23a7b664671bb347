"""The sRGB encoding in torch (differentiable): the numpy one is :func:`viewer.files.imageio.linear_to_srgb`."""

from __future__ import annotations

import torch

from viewer.files.imageio import SRGB_KNEE


def srgb_encode(x: torch.Tensor) -> torch.Tensor:
    """The sRGB encoding of linear values (negative ones taken as 0), extended above 1 by the same
    power law; its gradient stays finite at 0 (the power's branch is clamped where it is not used)."""
    x = x.clamp(min=0.0)
    return torch.where(x <= SRGB_KNEE, 12.92 * x, 1.055 * x.clamp(min=SRGB_KNEE) ** (1.0 / 2.4) - 0.055)
