"""Shadow-map geometry in torch: the light frames and the receivers' shadow-map coordinates.

Torch twin of :mod:`viewer.scene.shadow_space`, batched over lights, on any device and differentiable
with respect to the light directions. The numpy module states the rules; the formulas here are the
same (tests compare the two), see its docstring for the frame of a light's orthographic shadow map.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from viewer.scene import shadow_space as rule


@dataclass(frozen=True)
class LightFrames:
    """Shadow-map frames of N lights: (right, up, direction) bases, shared bounding sphere, depth ranges.

    ``empty_depth`` is what a texel that no triangle covers holds (1 - depth pad).
    """

    right: torch.Tensor  # (N, 3)
    up: torch.Tensor  # (N, 3)
    direction: torch.Tensor  # (N, 3) unit, towards the light
    center: torch.Tensor  # (3,) bounding-sphere centre
    radius: torch.Tensor  # () bounding-sphere radius
    lo: torch.Tensor  # (N,) padded range of dot(p, l) over the points
    hi: torch.Tensor  # (N,)
    empty_depth: float

    def __len__(self) -> int:
        return int(self.direction.shape[0])

    def matrix(self) -> torch.Tensor:
        """(N, 4, 4) taking homogeneous camera-space points to (u, v, z, 1), as ``LightFrame.matrix``."""
        n = len(self)
        s = 1.0 / (2.0 * self.radius)
        k = 1.0 / (self.hi - self.lo)
        rows = [
            torch.cat([self.right * s, (0.5 - self.right @ self.center * s)[:, None]], dim=1),
            torch.cat([self.up * s, (0.5 - self.up @ self.center * s)[:, None]], dim=1),
            torch.cat([-self.direction * k[:, None], (self.hi * k)[:, None]], dim=1),
        ]
        last = torch.zeros(n, 4, dtype=self.right.dtype, device=self.right.device)
        last[:, 3] = 1.0
        return torch.stack(rows + [last], dim=1)

    def texel_world(self, resolution: int) -> torch.Tensor:
        """World-space width of one shadow-map texel."""
        return 2.0 * self.radius / resolution

    def depth_scale(self) -> torch.Tensor:
        """(N,) metres per unit of normalised depth."""
        return self.hi - self.lo


def bounding_sphere(points: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Centre and radius around (K, 3) points, as :func:`viewer.scene.shadow_space.bounding_sphere`."""
    c = 0.5 * (points.amin(dim=0) + points.amax(dim=0))
    r = ((points - c) ** 2).sum(dim=1).max().sqrt().clamp(min=1e-6)
    return c, r


def light_frames(points: torch.Tensor, directions: torch.Tensor, resolution: int, terms: int = 4) -> LightFrames:
    """Frames of the lights ``directions`` (N, 3) for the points ``points`` (K, 3) they enclose.

    Same construction as :func:`viewer.scene.shadow_space.light_frames`: the reference axis for ``right``
    is +y unless the light is within ~25 degrees of it, then +x; the depth range leaves
    ``depth_pad(terms)`` free at both ends.
    """
    dtype, device = points.dtype, points.device
    c, r = bounding_sphere(points)
    l = directions.to(dtype)
    l = l / l.norm(dim=1, keepdim=True)
    ey = torch.tensor([0.0, 1.0, 0.0], dtype=dtype, device=device)
    ex = torch.tensor([1.0, 0.0, 0.0], dtype=dtype, device=device)
    ref = torch.where((l[:, 1:2].abs() < 0.9), ey, ex)
    right = torch.linalg.cross(ref, l)
    right = right / right.norm(dim=1, keepdim=True)
    up = torch.linalg.cross(l, right)
    proj = points @ l.T  # (K, N)
    reach = rule.NORMAL_OFFSET_TEXELS * 2.0 * r / resolution  # receivers pushed along normals
    lo, hi = proj.amin(dim=0) - reach, proj.amax(dim=0) + reach
    pad = rule.depth_pad(terms)
    extent = torch.maximum(hi - lo, rule.MIN_DEPTH_EXTENT * r) / (1.0 - 2.0 * pad)
    hi = hi + pad * extent
    return LightFrames(right, up, l, c, r, hi - extent, hi, 1.0 - pad)


def receiver_coordinates(points: torch.Tensor, normals: torch.Tensor, frames: LightFrames, resolution: int):
    """Shadow-map coordinates (u, v, d) and the hard-test bias of receivers, each (N, P).

    The rule of :func:`viewer.scene.shadow_space.receiver_coordinates`: the receiver is pushed along its
    normal by NORMAL_OFFSET_TEXELS texels, and the bias is HARD_SHADOW_THRESHOLD + SLOPE_BIAS_TEXELS
    texel min(tan(theta), MAX_SLOPE) / depth range. The only departure is a 1e-12 floor under the
    square root of sin^2(theta), which keeps the gradient finite at normal incidence (a bias change
    below 1e-9).
    """
    texel = frames.texel_world(resolution)
    q = points + normals * (rule.NORMAL_OFFSET_TEXELS * texel)  # (P, 3)
    m = frames.matrix()  # (N, 4, 4)
    uvd = torch.einsum("nij,pj->nip", m[:, :3, :3], q) + m[:, :3, 3:]  # (N, 3, P)
    c = (frames.direction @ normals.T).abs()  # (N, P)
    tan = (torch.sqrt((1.0 - c * c).clamp(min=1e-12)) / c.clamp(min=1e-6)).clamp(max=rule.MAX_SLOPE)
    bias = rule.HARD_SHADOW_THRESHOLD + rule.SLOPE_BIAS_TEXELS * texel * tan / frames.depth_scale()[:, None]
    return uvd[:, 0], uvd[:, 1], uvd[:, 2], bias
