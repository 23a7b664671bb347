"""Relighting a scene under area lights in torch: the GL engine's image, differentiable.

For every area light l (direction, sigma, RGB intensity I_l): a hard shadow map of the depth mesh
and its convolutional shadow map give the hard and soft visibility of each masked pixel; Lambert
and Disney specular shading treat the light as directional, its angular size widening the specular
lobe (brdf.widened_alpha); the HDR image is the paper's composite

    HDR = sum_l V_l I_l (A S_diff_l + S_spec_l)

with the soft visibility V_l, zero outside the mask (docs/conventions.md).

Gradients: the image is differentiable with respect to every light's intensity, sigma (through the
CSM pre-filter and the specular widening) and direction (through the shading). The shadow maps and receiver coordinates use
the detached direction: the occluders' silhouettes in a rasterized shadow map do not move with the
light under autograd, so a gradient through the receivers alone would point the wrong way (the
paper likewise detaches direction and intensity when it learns sigma).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from viewer.scene import shadow_space as rule
from viewer.scene.area_lights import AreaLights
from viewer.scene.bundle import Scene
from viewer.scene.depth_mesh import DepthMesh, caster_points, depth_mesh, resolve_step
from viewer.twin import csm
from viewer.twin.brdf import diffuse_shading, specular_shading
from viewer.twin.shadow_geometry import light_frames, receiver_coordinates
from viewer.twin.shadow_map import shadow_maps


@dataclass(frozen=True)
class LightTensors:
    """Area lights as tensors (may require grad): direction (N, 3), sigma (N,), intensity (N, 3)."""

    direction: torch.Tensor
    sigma: torch.Tensor
    intensity: torch.Tensor

    def __len__(self) -> int:
        return int(self.direction.shape[0])


def as_light_tensors(lights, device, dtype=torch.float32) -> LightTensors:
    """Area lights from an :class:`AreaLights`, a :class:`LightTensors` or a (direction, sigma,
    intensity) tuple of tensors or arrays, on ``device``; tensors keep their autograd history."""
    if isinstance(lights, (AreaLights, LightTensors)):
        parts = (lights.direction, lights.sigma, lights.intensity)
    else:
        parts = tuple(lights)
        if len(parts) != 3:
            raise ValueError("lights must be AreaLights, LightTensors or a (direction, sigma, intensity) tuple")
    direction, sigma, intensity = (torch.as_tensor(p).to(device=device, dtype=dtype) for p in parts)
    return LightTensors(direction.reshape(-1, 3), sigma.reshape(-1), intensity.reshape(-1, 3))


@dataclass(frozen=True)
class SceneTensors:
    """A scene's masked pixels on a device and its decimated depth mesh, ready for repeated renders.

    Per masked pixel (P of them, row-major order): camera-space point, normal, albedo, specular,
    roughness; ``casters`` are what the shadow-map frames enclose (:func:`viewer.scene.depth_mesh.caster_points`).
    """

    height: int
    width: int
    pixel_index: torch.Tensor  # (P,) flat index of each masked pixel in the H x W image
    points: torch.Tensor  # (P, 3)
    normal: torch.Tensor  # (P, 3)
    albedo: torch.Tensor  # (P, 3)
    specular: torch.Tensor  # (P,)
    roughness: torch.Tensor  # (P,)
    mesh: DepthMesh
    casters: torch.Tensor  # (K, 3)

    @property
    def device(self) -> torch.device:
        return self.points.device

    @staticmethod
    def from_scene(scene: Scene, shadow_step: int = 0, device=None, dtype=torch.float32) -> SceneTensors:
        """``shadow_step`` 0 picks the GL engine's automatic decimation (:func:`viewer.scene.depth_mesh.resolve_step`)."""
        device = torch.device(device) if device is not None else torch.get_default_device()
        mask = scene.mask

        mesh = depth_mesh(scene, step=resolve_step(shadow_step, scene))

        def masked(arr):
            return torch.as_tensor(np.ascontiguousarray(arr[mask]), dtype=dtype, device=device)

        return SceneTensors(
            height=scene.height,
            width=scene.width,
            pixel_index=torch.as_tensor(np.flatnonzero(mask.reshape(-1)), device=device),
            points=masked(scene.points()),
            normal=masked(scene.normal),
            albedo=masked(scene.albedo),
            specular=masked(scene.specular),
            roughness=masked(scene.roughness),
            mesh=mesh,
            casters=torch.as_tensor(caster_points(scene, mesh), dtype=dtype, device=device),
        )

    def to_image(self, values: torch.Tensor) -> torch.Tensor:
        """Scatter values (..., P) of the masked pixels into images (..., H, W), zero outside the mask."""
        flat = torch.zeros(*values.shape[:-1], self.height * self.width, dtype=values.dtype, device=values.device)
        return flat.index_copy(-1, self.pixel_index, values).reshape(*values.shape[:-1], self.height, self.width)


@dataclass(frozen=True)
class Rendering:
    """Everything the twin computes for N lights on an H x W scene (zero outside the mask)."""

    shadow_maps: torch.Tensor  # (N, R, R) normalised depth, the frames' empty_depth where empty
    hard_visibility: torch.Tensor  # (N, H, W) in {0, 1}
    soft_visibility: torch.Tensor  # (N, H, W) in [0, 1], convolutional shadow map
    diffuse: torch.Tensor  # (N, H, W) Lambert shading per unit intensity
    specular: torch.Tensor  # (N, H, W) Disney specular shading per unit intensity
    image: torch.Tensor  # (H, W, 3) linear HDR


def _default_device(scene, lights) -> torch.device:
    if isinstance(scene, SceneTensors):
        return scene.device
    first = lights.direction if isinstance(lights, LightTensors) else (
        lights[0] if isinstance(lights, (tuple, list)) else None)
    return first.device if isinstance(first, torch.Tensor) else torch.get_default_device()


def render(scene: Scene | SceneTensors, lights, shadow_resolution: int = 512, shadow_step: int = 0,
           terms: int = 4, device=None, soft=None) -> Rendering:
    """Relight ``scene`` under area ``lights`` (see :func:`as_light_tensors` for the accepted forms).

    ``shadow_resolution`` R of the per-light shadow maps, ``shadow_step`` decimation of the depth
    mesh they rasterize (ignored for a prepared :class:`SceneTensors`), ``terms`` Fourier terms M of
    the convolutional shadow map; ``soft`` the soft shadows: a soft-shadow method's twin
    (:meth:`viewer.gl.soft.SoftMethod.twin`, its signature), by default the paper's CSM
    (:func:`viewer.twin.csm.twin_visibility`). ``device`` defaults to the prepared scene's, else to the light
    tensors', else torch's default device (a prepared scene stays on its own device). Directions
    need not be unit: they are normalised here.
    """
    if device is None:
        device = _default_device(scene, lights)
    st = scene if isinstance(scene, SceneTensors) else SceneTensors.from_scene(scene, shadow_step, device)
    lt = as_light_tensors(lights, st.device, st.points.dtype)
    direction = lt.direction / lt.direction.norm(dim=1, keepdim=True)

    frames = light_frames(st.casters, direction.detach(), shadow_resolution, terms)
    depth = shadow_maps(st.mesh, frames, shadow_resolution)
    u, v, d, bias = receiver_coordinates(st.points, st.normal, frames, shadow_resolution)
    hard = csm.hard_visibility(depth, u, v, d, bias)
    visibility = (soft or csm.twin_visibility)(depth, lt.sigma, frames, u, v, d, bias, st.normal, terms)

    diffuse = diffuse_shading(st.normal, direction)  # (N, P)
    specular = specular_shading(st.normal, direction, st.specular, st.roughness, lt.sigma * rule.ANGULAR_SIGMA)
    radiance = torch.einsum("np,nc,pc->pc", visibility * diffuse, lt.intensity, st.albedo) + torch.einsum(
        "np,nc->pc", visibility * specular, lt.intensity)
    return Rendering(
        shadow_maps=depth,
        hard_visibility=st.to_image(hard),
        soft_visibility=st.to_image(visibility),
        diffuse=st.to_image(diffuse),
        specular=st.to_image(specular),
        image=st.to_image(radiance.T).permute(1, 2, 0),
    )
