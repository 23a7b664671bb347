"""Operations on scene bundles that keep them valid (used by benchmarks and tests)."""

from __future__ import annotations

import numpy as np

from .camera import Camera
from .scene import Scene


def resample_scene(scene: Scene, size: int) -> Scene:
    """Nearest-neighbour resample to ``size`` pixels on the longer side (maps stay valid: unit
    normals, binary mask); the camera keeps its lens, so the figure covers the same field of view."""
    h, w = scene.height, scene.width
    scale = size / max(h, w)
    nh, nw = max(int(round(h * scale)), 1), max(int(round(w * scale)), 1)
    rows = np.minimum(((np.arange(nh) + 0.5) / scale).astype(int), h - 1)
    cols = np.minimum(((np.arange(nw) + 0.5) / scale).astype(int), w - 1)

    def pick(a):
        return None if a is None else np.ascontiguousarray(a[rows][:, cols])

    cam = scene.camera
    return Scene(
        albedo=pick(scene.albedo), specular=pick(scene.specular), roughness=pick(scene.roughness),
        normal=pick(scene.normal), depth=pick(scene.depth), mask=pick(scene.mask),
        camera=Camera(nw, nh, cam.focal_mm, cam.sensor_mm, cam.distance),
        photo=pick(scene.photo), background=pick(scene.background),
    ).validate()
