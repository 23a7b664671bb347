"""The shadow refinement network (the paper's Stage 2, Equation 13): per area light, hard and soft
visibility from the shadow maps of the depth mesh, a constant map of the light's sigma and the
depth go in; the final visibility comes out (a sigmoid).

Input channels, per light: hard visibility (0/1), convolutional-shadow-map visibility, sigma /
``SIGMA_MAX`` everywhere, and depth normalized as the depth network's target (0.5 = the median);
all zero outside the mask. The loss is the paper's: L1 between the ray-traced shadowed diffuse
shading and the sum over lights of refined visibility times Lambert shading (true normals, the
map's fitted lights), in the photo's exposed units.

Training runs the network on the ``REFINED_LIGHTS`` lights that shade each image most and keeps the
convolutional-shadow-map visibility of the others in the sum (so the loss still compares whole
images); inference refines every light. The visibility of the true depth mesh under the true
lights comes from the GL engine and is cached beside each lighting (``visibility_<R>.npz``).
"""

from __future__ import annotations

import torch

from viewer.lighting.light_size import SIGMA_MAX
from viewer.nets import depth as depth_net
from viewer.nets.inverse import masked_l1
from viewer.twin.brdf import diffuse_shading

REFINED_LIGHTS = 4
SHADOW_RESOLUTION = 512  # the engine's default shadow maps
OUTPUTS = {"visibility": 1}
IN_CHANNELS = 4


def refine_input(hard: torch.Tensor, soft: torch.Tensor, sigma: torch.Tensor, depth: torch.Tensor,
                 mask: torch.Tensor) -> torch.Tensor:
    """(B N, 4, H, W) from hard and soft visibility (B, N, H, W), sigma (B, N), depth and mask (B, 1, H, W)."""
    b, n, h, w = hard.shape
    d = depth_net.depth_target(depth, mask).expand(b, n, h, w)
    s = (sigma / SIGMA_MAX)[..., None, None].expand(b, n, h, w)
    x = torch.stack([hard, soft, s, d], dim=2) * mask[:, None]
    return x.reshape(b * n, 4, h, w)


def refined_visibility(model, hard, soft, sigma, depth, mask) -> torch.Tensor:
    """(B, N, H, W) in [0, 1]."""
    b, n, h, w = hard.shape
    return torch.sigmoid(model(refine_input(hard, soft, sigma, depth, mask))["visibility"]).reshape(b, n, h, w)


def lambert_per_light(normal: torch.Tensor, lights: torch.Tensor) -> torch.Tensor:
    """(B, N, 3, H, W): Lambert shading of each light (the (B, N, 7) light tensors) on (B, 3, H, W) normals."""
    out = []
    for i in range(normal.shape[0]):
        d = diffuse_shading(normal[i].permute(1, 2, 0), lights[i, :, :3])  # (N, H, W)
        out.append(d[:, None] * lights[i, :, 4:7, None, None])
    return torch.stack(out)


def refine_loss(model, batch: dict, scale: torch.Tensor, refined: int = REFINED_LIGHTS) -> dict[str, torch.Tensor]:
    """The refinement loss (see the module docstring) and, for comparison, the same L1 with the
    hard and with the convolutional-shadow-map visibility (the paper's SM / CSM ablation)."""
    mask = batch["mask"]
    shading = lambert_per_light(batch["normal"], batch["lights"]) * scale[:, :, None]  # (B, N, 3, H, W)
    target = scale * batch["diffuse_shadowed"]
    hard, soft = batch["hard"], batch["soft"]
    weight = (shading.mean(dim=2) * mask).sum(dim=(2, 3))  # (B, N): how much each light shades the image
    top = weight.topk(min(refined, hard.shape[1]), dim=1).indices  # (B, K)

    def pick(x):
        return x.gather(1, top.reshape(*top.shape, *([1] * (x.dim() - 2))).expand(-1, -1, *x.shape[2:]))

    v = refined_visibility(model, pick(hard), pick(soft), pick(batch["lights"][..., 3]), batch["depth"], mask)
    vis = soft.scatter(1, top[..., None, None].expand(-1, -1, *soft.shape[2:]), v)
    pred = (vis[:, :, None] * shading).sum(dim=1)
    with torch.no_grad():
        sm = masked_l1((hard[:, :, None] * shading).sum(dim=1), target, mask)
        csm = masked_l1((soft[:, :, None] * shading).sum(dim=1), target, mask)
    total = masked_l1(pred, target, mask)
    return {"total": total, "sm": sm, "csm": csm}
