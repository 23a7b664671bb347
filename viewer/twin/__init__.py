"""The torch twin of the GL engine: the same relighting mathematics, differentiable, on CPU or CUDA.

Used for light fitting and training, and as the oracle of the GL engine's parity tests.
Modules: :mod:`.brdf` (per-light shading), :mod:`.shadow_geometry` (light frames, receivers),
:mod:`.shadow_map` (rasterized shadow maps), :mod:`.csm` (convolutional shadow maps, hard test),
:mod:`.relight` (the composite image).
"""

from viewer.twin.brdf import diffuse_shading, specular_shading
from viewer.twin.csm import (
    fourier_basis,
    gaussian_filter,
    gaussian_kernels,
    hard_visibility,
    reconstruct_visibility,
    sample_bilinear,
    soft_visibility,
)
from viewer.twin.relight import LightTensors, Rendering, SceneTensors, as_light_tensors, render
from viewer.twin.shadow_geometry import LightFrames, light_frames, receiver_coordinates
from viewer.twin.shadow_map import project_vertices, rasterize_depth, shadow_maps

__all__ = [
    "LightFrames",
    "LightTensors",
    "Rendering",
    "SceneTensors",
    "as_light_tensors",
    "diffuse_shading",
    "fourier_basis",
    "gaussian_filter",
    "gaussian_kernels",
    "hard_visibility",
    "light_frames",
    "project_vertices",
    "rasterize_depth",
    "receiver_coordinates",
    "reconstruct_visibility",
    "render",
    "sample_bilinear",
    "shadow_maps",
    "soft_visibility",
    "specular_shading",
]
