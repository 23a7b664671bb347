"""The inverse-rendering network (the paper's Stage 1): outputs, light tensors and losses.

One encoder, two image decoders and the lights head (:class:`viewer.nets.unet.UNet`):

- ``normal`` (3): camera-space normal, normalized;
- ``material`` (5): albedo (3), specular (1), roughness (1), each through a sigmoid;
- ``lights`` (N x 7 from the bottleneck): the input photo's N area lights. Direction = the
  normalized raw 3-vector plus a Fibonacci-sphere point (so the lights start spread over the
  sphere, as the light fitting does), sigma = 20 sigmoid (the fitting's range), intensity =
  softplus, in the photo's exposed units (:mod:`viewer.nets.photo`).

The input is the photo *with its background* and the mask (the paper's background-aware input).

Losses (the paper's Equations 1-5 and 7, each an L1 mean over the mask, targets in exposed units):
texture (albedo, specular, roughness, normal), diffuse and specular shading (the sum over lights
of the twin's per-light shading against the ray-traced unshadowed lobes), diffuse and full
shadow-less reconstructions, and the sigma loss: the ray-traced shadowed diffuse shading against
the twin's convolutional-shadow-map visibility of the *true* depth and normals times Lambert
shading, with the predicted directions and intensities detached so only sigma learns from it.

The paper's VGG loss needs ImageNet weights, which cannot be fetched here. It is replaced by a
Laplacian-pyramid L1 (``LAPLACIAN_LEVELS`` band-pass levels, each level's L1 weighted equally):
like VGG features it compares local structure at several scales (edges, texture, highlight shapes)
rather than pixel values alone, and it needs no pretrained weights. Its effect is measured in
docs/networks.md (training with ``perceptual_weight`` 0.1 and 0).
"""

from __future__ import annotations

import torch
from torch.nn import functional as F

from viewer.lighting.light_size import SIGMA_MAX
from viewer.lighting.lightfit.fit import fibonacci_sphere
from viewer.nets.photo import photo_input, reads_silhouette
from viewer.twin.brdf import diffuse_shading, specular_shading

N_LIGHTS = 16
PERCEPTUAL_WEIGHT = 0.1  # the paper's lambda_vgg, for the Laplacian-pyramid replacement
SIGMA_WEIGHT = 0.01  # the paper's lambda_sigma
CHROMA_WEIGHT = 1.0  # the albedo's chromaticity L1 (plain L1 lets clothes come out grey)
LAPLACIAN_LEVELS = 4
SIGMA_SHADOW_RESOLUTION = 128  # shadow maps of the sigma loss (sigma is in 256-texel units anyway)
OUTPUTS = {"normal": 3, "material": 5}


def vectors(n_lights: int = N_LIGHTS) -> dict[str, int]:
    return {"lights": 7 * n_lights}


def light_tensors(raw: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(direction (B, N, 3) unit, sigma (B, N), intensity (B, N, 3)) from the head's (B, 7 N)."""
    b = raw.shape[0]
    r = raw.reshape(b, -1, 7)
    anchor = torch.as_tensor(fibonacci_sphere(r.shape[1]), dtype=raw.dtype, device=raw.device)
    d = r[..., :3] + anchor
    direction = d / d.norm(dim=-1, keepdim=True).clamp_min(1e-6)
    sigma = SIGMA_MAX * torch.sigmoid(r[..., 3])
    intensity = F.softplus(r[..., 4:7])
    return direction, sigma, intensity


def maps(out: dict, base_normal: torch.Tensor | None = None) -> dict[str, torch.Tensor]:
    """The network's image outputs as maps: normal (B, 3, H, W) unit, albedo (B, 3, H, W),
    specular and roughness (B, 1, H, W) in [0, 1]. With ``base_normal`` (a network reading the
    silhouette prior) the normal decoder's output is a correction added to the prior's normal, so
    the network starts from it instead of learning to copy it."""
    n = out["normal"] if base_normal is None else out["normal"] + base_normal
    m = torch.sigmoid(out["material"])
    return {"normal": n / n.norm(dim=1, keepdim=True).clamp_min(1e-6), "albedo": m[:, :3], "specular": m[:, 3:4],
            "roughness": m[:, 4:5]}


def predict(model, photo: torch.Tensor, mask: torch.Tensor):
    """``(maps, (direction, sigma, intensity), scale)`` of a linear photo (B, 3, H, W) with its
    background and its mask (B, 1, H, W): :func:`maps`, the lights with intensities in the photo's
    own linear units (the exposure undone), and the exposure ``scale`` (B, 1, 1, 1) the network saw."""
    silhouette = reads_silhouette(model)
    x, scale = photo_input(photo, mask, silhouette=silhouette)
    out = model(x)
    direction, sigma, intensity = light_tensors(out["lights"])
    return maps(out, prior_normal(x) if silhouette else None), (direction, sigma, intensity / scale.reshape(-1, 1, 1)), scale


def prior_normal(x: torch.Tensor) -> torch.Tensor:
    """(B, 3, H, W): the silhouette prior's inflation normal from a network input that holds it
    (channels 4 and 5 after the photo and mask: :func:`viewer.nets.photo.photo_input`)."""
    xy = x[:, 4:6]
    return torch.cat([xy, (1.0 - (xy * xy).sum(dim=1, keepdim=True)).clamp_min(0.0).sqrt()], dim=1)


def shading(normal, specular, roughness, direction, intensity) -> tuple[torch.Tensor, torch.Tensor]:
    """Unshadowed diffuse (albedo 1) and specular shading, (B, 3, H, W) each: the sum over the
    lights of the twin's per-light shading times the light's intensity."""
    diff, spec = [], []
    for i in range(normal.shape[0]):
        n = normal[i].permute(1, 2, 0)  # (H, W, 3)
        d = diffuse_shading(n, direction[i])  # (N, H, W)
        s = specular_shading(n, direction[i], specular[i, 0], roughness[i, 0])
        diff.append(torch.einsum("nhw,nc->chw", d, intensity[i]))
        spec.append(torch.einsum("nhw,nc->chw", s, intensity[i]))
    return torch.stack(diff), torch.stack(spec)


def masked_l1(a: torch.Tensor, b: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    m = mask.expand_as(a)
    return ((a - b).abs() * m).sum() / m.sum().clamp_min(1.0)


def chromaticity(rgb: torch.Tensor, eps: float = 1e-3) -> torch.Tensor:
    """(B, 3, H, W) colour with its brightness divided out: rgb / (r + g + b)."""
    return rgb / rgb.sum(dim=1, keepdim=True).clamp_min(eps)


def chroma_l1(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor, eps: float = 1e-3) -> torch.Tensor:
    """L1 between the chromaticities of two albedos over the mask (where the target is not black):
    blind to brightness, so it asks for the hue and saturation that a plain L1, dominated by
    brightness, lets drift to grey."""
    m = mask * (target.sum(dim=1, keepdim=True) > eps)
    return masked_l1(chromaticity(pred, eps), chromaticity(target, eps), m)


def laplacian_l1(a: torch.Tensor, b: torch.Tensor, mask: torch.Tensor, levels: int = LAPLACIAN_LEVELS) -> torch.Tensor:
    """L1 between the Laplacian pyramids of the masked images (mean over levels)."""
    x, y = a * mask, b * mask
    total = a.new_zeros(())
    for _ in range(levels):
        xd, yd = F.avg_pool2d(x, 2), F.avg_pool2d(y, 2)
        xu = F.interpolate(xd, size=x.shape[-2:], mode="bilinear", align_corners=False)
        yu = F.interpolate(yd, size=y.shape[-2:], mode="bilinear", align_corners=False)
        total = total + ((x - xu) - (y - yu)).abs().mean()
        x, y = xd, yd
    return total / levels


def sigma_loss(batch: dict, scale: torch.Tensor, direction, sigma, intensity, items: int = 1) -> torch.Tensor:
    """The paper's Equation 7 on the first ``items`` images of the batch: the twin's soft
    visibility of the true depth mesh (detached directions) times Lambert shading with the true
    normals (detached directions and intensities), against the ray-traced shadowed diffuse shading."""
    from viewer.scene.bundle import Scene
    from viewer.scene.camera import Camera
    from viewer.twin import SceneTensors, render

    total = scale.new_zeros(())
    count = 0
    for i in range(min(items, batch["image"].shape[0])):
        mask = batch["mask"][i, 0].detach().cpu().numpy() > 0.5
        if mask.sum() < 16:
            continue
        h, w = mask.shape
        scene = Scene(albedo=batch["albedo"][i].permute(1, 2, 0).cpu().numpy(), specular=batch["specular"][i, 0].cpu().numpy(),
                      roughness=batch["roughness"][i, 0].cpu().numpy(), normal=batch["normal"][i].permute(1, 2, 0).cpu().numpy(),
                      depth=batch["depth"][i, 0].cpu().numpy(), mask=mask, camera=Camera(w, h))
        st = SceneTensors.from_scene(scene, device=direction.device)
        r = render(st, (direction[i].detach(), sigma[i], intensity[i].detach()), shadow_resolution=SIGMA_SHADOW_RESOLUTION)
        pred = torch.einsum("nhw,nc->chw", r.soft_visibility * r.diffuse, intensity[i].detach())
        target = scale[i] * batch["diffuse_shadowed"][i]
        total = total + masked_l1(pred[None], target[None], batch["mask"][i:i + 1])
        count += 1
    return total / max(count, 1)


def inverse_loss(out: dict, batch: dict, scale: torch.Tensor, perceptual_weight: float = PERCEPTUAL_WEIGHT,
                 sigma_items: int = 1, base_normal: torch.Tensor | None = None) -> dict[str, torch.Tensor]:
    """Every Stage-1 loss term and their weighted total (see the module docstring). ``scale``: the
    exposure of each input photo (:func:`viewer.nets.photo.photo_input`); ``base_normal``: the
    silhouette prior's normal, when the network reads it (:func:`maps`)."""
    mask = batch["mask"]
    pred = maps(out, base_normal)
    direction, sigma, intensity = light_tensors(out["lights"])
    s_diff, s_spec = shading(pred["normal"], pred["specular"], pred["roughness"], direction, intensity)
    t_diff, t_spec = scale * batch["diffuse"], scale * batch["specular_shading"]
    albedo = batch["albedo"]
    r_diff_hat, r_diff = pred["albedo"] * s_diff, albedo * t_diff
    r_full_hat, r_full = r_diff_hat + s_spec, r_diff + t_spec
    terms = {
        "albedo": masked_l1(pred["albedo"], albedo, mask),
        "albedo_chroma": chroma_l1(pred["albedo"], albedo, mask),
        "specular": masked_l1(pred["specular"], batch["specular"], mask),
        "roughness": masked_l1(pred["roughness"], batch["roughness"], mask),
        "normal": masked_l1(pred["normal"], batch["normal"], mask),
        "diffuse_shading": masked_l1(s_diff, t_diff, mask),
        "specular_shading": masked_l1(s_spec, t_spec, mask),
        "diffuse_recon": masked_l1(r_diff_hat, r_diff, mask),
        "full_recon": masked_l1(r_full_hat, r_full, mask),
    }
    terms["perceptual"] = (laplacian_l1(pred["albedo"], albedo, mask) + laplacian_l1(s_spec, t_spec, mask)
                           + laplacian_l1(r_full_hat, r_full, mask))
    terms["sigma"] = sigma_loss(batch, scale, direction, sigma, intensity, sigma_items) if sigma_items else mask.new_zeros(())
    total = sum(terms[k] for k in ("albedo", "specular", "roughness", "normal", "diffuse_shading", "specular_shading",
                                   "diffuse_recon", "full_recon"))
    terms["total"] = (total + CHROMA_WEIGHT * terms["albedo_chroma"] + perceptual_weight * terms["perceptual"]
                      + SIGMA_WEIGHT * terms["sigma"])
    with torch.no_grad():
        cos = (pred["normal"] * batch["normal"]).sum(dim=1, keepdim=True).clamp(-1.0, 1.0)
        m = mask > 0.5
        terms["normal_degrees"] = torch.rad2deg(torch.acos(cos))[m].mean() if m.any() else mask.new_zeros(())
    return terms
