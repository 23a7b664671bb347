"""The mask's silhouette as a geometry prior the networks can read.

A mask says more than where the person is: at its outline the surface turns away from the camera,
so the normal there is known exactly (in the image plane, pointing out of the mask), and a pixel's
distance to the outline says how deep inside a limb or the torso it lies. A U-Net sees that only
within its receptive field; these channels hand it over directly.

The *inflation* is the surface of tubes of radius ``RADIUS`` (a fraction of the image height, about a
forearm's half-width for a full-body framing) swept along the outline: at distance ``d`` from the
outline its height is ``sqrt(2 R d - d^2)`` (capped at ``R`` inside), so its normal is tangent to
the image plane at the outline and faces the camera deep inside. Distances come from OpenCV's exact
Euclidean distance transform (``cv2.distanceTransform``, ``DIST_MASK_PRECISE``), a well-kept C
implementation, rather than a hand-written one.

Channels (each zero outside the mask): the inflation's camera-space normal x and y (z follows from
them), and the distance to the outline in image heights, scaled by ``DISTANCE_SCALE``.
"""

from __future__ import annotations

import numpy as np
import torch

CHANNELS = 3
RADIUS = 0.03  # of the image height
SMOOTH = 0.006  # of the image height: Gaussian sigma of the outline's direction (1.5 px at 256)
DISTANCE_SCALE = 10.0  # distance / image height x 10: about 1 at the middle of the torso


def silhouette_maps(mask: np.ndarray) -> np.ndarray:
    """(H, W, 3) float32: the inflation normal's x and y and the scaled distance to the outline of
    a boolean mask (module docstring)."""
    import cv2

    mask = np.asarray(mask, dtype=bool)
    h = mask.shape[0]
    out = np.zeros(mask.shape + (CHANNELS,), np.float32)
    if not mask.any():
        return out
    # distance from a pixel centre inside to the nearest pixel outside, minus half a pixel: the outline
    d = cv2.distanceTransform(mask.astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE).astype(np.float64) - 0.5
    # the outline pixel itself sits a quarter pixel in (not on the tangent plane); a mask without
    # an outline in the image (all person) has no distance beyond the image
    d = np.clip(d, 0.25, float(h))
    r = RADIUS * h
    inside = np.minimum(d, r)
    height = np.sqrt(np.clip(2.0 * r * inside - inside**2, 0.0, None))
    # slope of the tube's profile along the inward direction (the distance's gradient)
    slope = np.where(d < r, (r - inside) / np.maximum(height, 1e-6), 0.0)
    # the inward direction: the distance's gradient, smoothed (a staircase outline makes it jitter)
    inward = np.where(mask, d, 0.0).astype(np.float32)
    padded = np.pad(cv2.GaussianBlur(inward, (0, 0), SMOOTH * h), 1, mode="edge")  # (np.gradient needs 2 a side)
    gy, gx = (g[1:-1, 1:-1] for g in np.gradient(padded))  # rows down, columns right
    g = np.sqrt(gx**2 + gy**2)
    ux, uy = gx / np.maximum(g, 1e-9), gy / np.maximum(g, 1e-9)  # unit inward direction in the image
    # normal = (-dz/dx, -dz/dy, 1) in camera axes (y up: rows run down, so the row term flips)
    nx, ny = -slope * ux, slope * uy
    norm = np.sqrt(nx**2 + ny**2 + 1.0)
    out[..., 0] = np.where(mask, nx / norm, 0.0)
    out[..., 1] = np.where(mask, ny / norm, 0.0)
    out[..., 2] = np.where(mask, DISTANCE_SCALE * d / h, 0.0)
    return out


def silhouette_input(mask: torch.Tensor) -> torch.Tensor:
    """(B, 3, H, W) silhouette channels of a mask batch (B, 1, H, W)."""
    maps = [silhouette_maps(m[0].detach().cpu().numpy() > 0.5) for m in mask]
    return torch.from_numpy(np.stack(maps)).permute(0, 3, 1, 2).to(device=mask.device, dtype=mask.dtype)
