"""Small synthetic scene bundles with exact geometry and known answers: the tests' and the contact-shadow
benchmark's (viewer.lab.bench.contact)."""

from __future__ import annotations

import numpy as np

from viewer.scene.bundle import Scene
from viewer.scene.camera import Camera


def plane_and_box(size: int = 96, box: bool = True, albedo: float = 0.5, specular: float = 0.5,
                  roughness: float = 0.5, plane_depth: float = 4.0, box_depth: float = 3.6,
                  box_half: float = 0.18) -> Scene:
    """A plane facing the camera at ``plane_depth`` with an optional box face (a square at
    ``box_depth``, half-width ``box_half`` metres) in front of it; the whole image is masked."""
    cam = Camera(size, size)
    depth = np.full((size, size), plane_depth, np.float32)
    if box:
        pts = cam.unproject(np.full((size, size), box_depth, np.float32))
        inside = (np.abs(pts[..., 0]) < box_half) & (np.abs(pts[..., 1]) < box_half)
        depth[inside] = box_depth
    normal = np.zeros((size, size, 3), np.float32)
    normal[..., 2] = 1.0
    return _uniform_scene(cam, depth, normal, np.ones((size, size), bool), albedo, specular, roughness)


def sphere(size: int = 96, radius: float = 0.3, distance: float = 4.0, focal_mm: float = 200.0, albedo: float = 0.5,
           specular: float = 0.5, roughness: float = 0.5) -> Scene:
    """A sphere of ``radius`` metres ``distance`` metres in front of a long-lens camera (nearly
    orthographic, as the engine's fixed view vector assumes), with exact depth and normals; the mask
    is the sphere's disc."""
    cam = Camera(size, size, focal_mm=focal_mm, distance=distance)
    d = cam.view_directions()  # unit rays from the camera at the origin
    centre = np.array([0.0, 0.0, -distance])
    b = d @ centre
    disc = b * b - (distance * distance - radius * radius)
    mask = disc > 0.0
    t = np.where(mask, b - np.sqrt(np.maximum(disc, 0.0)), distance)
    points = d * t[..., None]
    normal = np.where(mask[..., None], (points - centre) / radius, 0.0).astype(np.float32)
    depth = np.where(mask, -points[..., 2], distance + radius).astype(np.float32)
    return _uniform_scene(cam, depth, normal, mask, albedo, specular, roughness)


def _uniform_scene(cam: Camera, depth, normal, mask, albedo: float, specular: float, roughness: float) -> Scene:
    """A validated bundle of this geometry with the same material everywhere."""
    h, w = depth.shape
    return Scene(
        albedo=np.full((h, w, 3), albedo, np.float32),
        specular=np.full((h, w), specular, np.float32),
        roughness=np.full((h, w), roughness, np.float32),
        normal=normal,
        depth=depth,
        mask=mask,
        camera=cam,
    ).validate()
