"""The depth network's inputs, targets and losses (the paper's Section 3.2, NOTES.md).

The network sees the person (:func:`viewer.nets.photo.photo_input` without the background) and the mask, and
outputs a sigmoid in [0, 1]: depth normalized by ``DEPTH_RANGE`` metres around the mask's median
(0.5 = the median). At inference the prediction is shifted so its median over the mask sits at the
camera distance and scaled back to metres (:func:`metric_depth`); the absolute distance of a
person in a single photo is not observable, so the loss ignores it: L1 between the prediction
and the target after each has its own median over the mask removed, plus the slope term, L1
between their finite differences where both pixels are in the mask and no depth gap lies between.
"""

from __future__ import annotations

import torch

from viewer.nets.photo import photo_input, reads_silhouette

DEPTH_RANGE = 1.0  # metres spanned by normalized depth 0..1 (a standing person is well under 1 m deep)
SLOPE_WEIGHT = 0.01  # the paper's lambda_slope
GAP = 0.03 / DEPTH_RANGE  # normalized depth jump treated as a gap (viewer.scene.depth_mesh.GAP_MIN)


def predict(model, photo: torch.Tensor, mask: torch.Tensor, distance: float) -> torch.Tensor:
    """Metric depth (B, 1, H, W) of the person in a linear photo (B, 3, H, W) with its mask, the
    mask's median at ``distance``."""
    x, _ = photo_input(photo * mask, mask, background=False, silhouette=reads_silhouette(model))
    return metric_depth(torch.sigmoid(model(x)["depth"]), mask, distance)


def masked_median(x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """(B, 1, 1, 1) median of x over each image's mask (0 for an empty mask)."""
    out = torch.zeros(x.shape[0], 1, 1, 1, dtype=x.dtype, device=x.device)
    for i in range(x.shape[0]):
        v = x[i][mask[i] > 0.5]
        if v.numel():
            out[i] = v.median()
    return out


def depth_target(depth: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Normalized depth in [0, 1] from metres (B, 1, H, W)."""
    return ((depth - masked_median(depth, mask)) / DEPTH_RANGE + 0.5).clamp(0.0, 1.0) * mask


def metric_depth(pred: torch.Tensor, mask: torch.Tensor, distance: float) -> torch.Tensor:
    """Metres from the network's output: median over the mask at ``distance``."""
    return (pred - masked_median(pred, mask)) * DEPTH_RANGE + distance


def depth_loss(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> dict[str, torch.Tensor]:
    m = (mask > 0.5).to(pred.dtype)
    n = m.sum().clamp_min(1.0)
    p = pred - masked_median(pred, mask)
    t = target - masked_median(target, mask)
    l1 = ((p - t).abs() * m).sum() / n
    slope = pred.new_zeros(())
    for dim in (2, 3):
        dp, dt = torch.diff(pred, dim=dim), torch.diff(target, dim=dim)
        both = torch.minimum(m.narrow(dim, 0, m.shape[dim] - 1), m.narrow(dim, 1, m.shape[dim] - 1))
        valid = both * (dt.abs() < GAP).to(pred.dtype)
        slope = slope + ((dp - dt).abs() * valid).sum() / valid.sum().clamp_min(1.0)
    return {"l1": l1, "slope": slope, "total": l1 + SLOPE_WEIGHT * slope}
