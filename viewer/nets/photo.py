"""What the networks see of a photo: linear RGB exposed so the person's 99th percentile of
luminance maps to 0.9, clipped to [0, 1] and encoded as display sRGB, plus the mask.

A synthetic HDR image and a real photo (sRGB, decoded to linear first) go through the same
steps, so the networks meet at inference what they met in training. The exposure ``scale`` is
returned: quantities the networks predict in exposed units (the lights' intensities, shading)
are divided by it to get back to the photo's own linear units.
"""

from __future__ import annotations

import torch

from viewer.nets.silhouette import CHANNELS as SILHOUETTE_CHANNELS, silhouette_input
from viewer.twin.srgb import srgb_encode

EXPOSED_PERCENTILE = 0.99
EXPOSED_LEVEL = 0.9


def exposure_scale(image: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """(B, 1, 1, 1): the factor that maps the mask's 99th percentile of luminance to 0.9 (1 for an
    empty mask or a black person)."""
    lum = image.mean(dim=1, keepdim=True)
    scale = torch.ones(image.shape[0], 1, 1, 1, dtype=image.dtype, device=image.device)
    for i in range(image.shape[0]):
        values = lum[i][mask[i] > 0.5]
        if values.numel():
            top = torch.quantile(values.float(), EXPOSED_PERCENTILE)
            if top > 1e-8:
                scale[i] = EXPOSED_LEVEL / top
    return scale


INPUTS = ("photo", "mask", "silhouette")  # what a network may read, in this order


def in_channels(inputs) -> int:
    """Input channels of a network reading ``inputs`` (names from :data:`INPUTS`)."""
    return sum({"photo": 3, "mask": 1, "silhouette": SILHOUETTE_CHANNELS}[name] for name in inputs)


def reads_silhouette(model) -> bool:
    """Whether a network was trained with the silhouette prior (its card's ``inputs``; older cards
    have none: photo and mask only)."""
    return "silhouette" in model.config.get("inputs", ())


def photo_input(image: torch.Tensor, mask: torch.Tensor, background: bool = True,
                silhouette: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
    """``(x, scale)``: x (B, 4, H, W) the exposed sRGB photo and the mask, and with ``silhouette``
    the mask's silhouette prior (B, 7, H, W; :mod:`viewer.nets.silhouette`); ``background=False``
    blacks out everything but the person (the depth network's input)."""
    scale = exposure_scale(image, mask)
    srgb = srgb_encode((image * scale).clamp(0.0, 1.0))
    if not background:
        srgb = srgb * mask
    parts = [srgb, mask] + ([silhouette_input(mask)] if silhouette else [])
    return torch.cat(parts, dim=1), scale
