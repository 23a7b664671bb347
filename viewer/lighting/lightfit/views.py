"""The simple scenes lights are fitted on and measured with, and their analytic visibility.

- **Sphere view** (the paper's Step 2): in :mod:`.sphere_lobes`, with its shading.
- **Plane views** (Step 3 and the error measurements): a camera (the paper's 50 mm lens on a 36 mm
  sensor) looks down at ``ELEVATION`` degrees onto an infinite plane carrying one object: the
  fitting scene has a unit sphere resting on the plane (the paper's "sphere on a plane"); the
  *held-out* scene, used only to measure, has a box rotated about the plane's normal. Each view is
  also a :class:`~viewer.scene.bundle.Scene` (white diffuse, depth and normals from the ray casting) so the
  torch twin and the GL engine render it exactly as they render a person.

Visibility is analytic. A point on the (convex) object sees direction d when n.d > 0 and d is above
the plane (a ray going down meets the infinite plane); a point on the plane sees d when d is above
the plane and the ray towards d misses the object (ray-sphere or ray-box slab test).

All geometry is in camera space (x right, y up, z towards the camera), the frame the environment
map's directions are given in (docs/conventions.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from viewer.scene.bundle import Scene
from viewer.scene.camera import Camera

ELEVATION = 35.0  # degrees between the view direction and the plane
SPHERE_DISTANCE = 7.0  # camera to sphere-centre distance, in sphere radii (the plane views)


@dataclass(frozen=True)
class Sphere:
    center: np.ndarray  # (3,)
    radius: float

    def intersect(self, origin: np.ndarray, direction: np.ndarray) -> np.ndarray:
        """Nearest ray parameter t > 0 per ray (inf for a miss), rays (P, 3) from the camera."""
        q = origin - self.center
        b = np.einsum("pk,pk->p", q, direction)
        c = np.einsum("pk,pk->p", q, q) - self.radius**2
        a = np.einsum("pk,pk->p", direction, direction)
        disc = b * b - a * c
        t = (-b - np.sqrt(np.maximum(disc, 0.0))) / a
        return np.where((disc > 0) & (t > 0), t, np.inf)

    def normal_at(self, points: np.ndarray) -> np.ndarray:
        return (points - self.center) / self.radius

    def blocks(self, points: torch.Tensor, dirs: torch.Tensor) -> torch.Tensor:
        """(P, T) bool: does the ray from each point (outside the sphere) towards each direction hit it."""
        q = torch.as_tensor(self.center, dtype=points.dtype) - points  # (P, 3)
        b = q @ dirs.T  # (P, T)
        c = (q * q).sum(dim=1, keepdim=True) - self.radius**2
        return (b > 0) & (b * b > c)


@dataclass(frozen=True)
class Box:
    center: np.ndarray  # (3,)
    axes: np.ndarray  # (3, 3) rows: the box's orthonormal axes
    half: np.ndarray  # (3,) half extents along them

    def intersect(self, origin: np.ndarray, direction: np.ndarray) -> np.ndarray:
        o = (origin - self.center) @ self.axes.T
        d = direction @ self.axes.T
        inv = 1.0 / np.where(np.abs(d) < 1e-12, 1e-12, d)
        t1, t2 = (-self.half - o) * inv, (self.half - o) * inv
        near = np.minimum(t1, t2).max(axis=1)
        far = np.maximum(t1, t2).min(axis=1)
        return np.where((far >= near) & (near > 0), near, np.inf)

    def normal_at(self, points: np.ndarray) -> np.ndarray:
        local = (points - self.center) @ self.axes.T / self.half
        k = np.abs(local).argmax(axis=1)
        n_local = np.zeros_like(local)
        n_local[np.arange(len(k)), k] = np.sign(local[np.arange(len(k)), k])
        return n_local @ self.axes

    def blocks(self, points: torch.Tensor, dirs: torch.Tensor) -> torch.Tensor:
        """(P, T) bool: does the ray from each point (outside the box) towards each direction hit it."""
        axes = torch.as_tensor(self.axes, dtype=points.dtype)
        o = (points - torch.as_tensor(self.center, dtype=points.dtype)) @ axes.T  # (P, 3) in box frame
        d = dirs @ axes.T  # (T, 3)
        d = torch.where(d.abs() < 1e-12, torch.full_like(d, 1e-12), d)
        inv = 1.0 / d
        near = torch.full((points.shape[0], dirs.shape[0]), -torch.inf, dtype=points.dtype)
        far = torch.full_like(near, torch.inf)
        for k in range(3):
            t1 = (-self.half[k] - o[:, k : k + 1]) * inv[None, :, k]
            t2 = (self.half[k] - o[:, k : k + 1]) * inv[None, :, k]
            near = torch.maximum(near, torch.minimum(t1, t2))
            far = torch.minimum(far, torch.maximum(t1, t2))
        return (far >= near) & (far > 0)


@dataclass(frozen=True)
class PlaneView:
    """An object on an infinite plane seen by a perspective camera; every pixel sees plane or object."""

    name: str
    scene: Scene  # white, matte, for the twin / engine
    points: np.ndarray  # (P, 3) float64, P = all pixels, row-major
    normal: np.ndarray  # (P, 3)
    on_object: np.ndarray  # (P,) bool
    plane_normal: np.ndarray  # (3,)
    occluder: Sphere | Box

    @property
    def resolution(self) -> int:
        return self.scene.width

    def visibility(self, dirs: torch.Tensor, rows: slice) -> torch.Tensor:
        """(p, T) float visibility of pixels ``rows`` towards directions (T, 3) (analytic)."""
        dtype = dirs.dtype
        pts = torch.as_tensor(self.points[rows], dtype=dtype)
        obj = torch.as_tensor(self.on_object[rows])
        above = (dirs @ torch.as_tensor(self.plane_normal, dtype=dtype)) > 0  # (T,)
        # plane points: offset along the normal so the ray does not start inside the object's touch point
        lifted = pts + 1e-4 * torch.as_tensor(self.normal[rows], dtype=dtype)
        blocked = self.occluder.blocks(lifted, dirs) & ~obj[:, None]
        return (above[None, :] & ~blocked).to(dtype)


def _plane_frame(elevation_deg: float):
    """Unit normal of the ground plane in camera space and a unit vector along it, away from the camera."""
    e = np.radians(elevation_deg)
    up = np.array([0.0, np.cos(e), np.sin(e)])
    forward = np.array([0.0, np.sin(e), -np.cos(e)])
    return up, forward


def plane_view(kind: str, resolution: int, elevation_deg: float = ELEVATION) -> PlaneView:
    """``kind`` 'sphere' (the fitting scene) or 'box' (held out): the object, unit-sized, on the
    plane, its centre ``SPHERE_DISTANCE`` radii from the camera, at the image centre."""
    up, forward = _plane_frame(elevation_deg)
    center = np.array([0.0, 0.0, -SPHERE_DISTANCE])  # object centre on the optical axis
    if kind == "sphere":
        occluder = Sphere(center, 1.0)
    elif kind == "box":
        # a 1.6 x 1.6 x 1.6 box resting on the plane, turned 30 degrees about the plane's normal
        side = np.cross(forward, up)
        a = np.radians(30.0)
        ax0 = np.cos(a) * side + np.sin(a) * forward
        ax2 = -np.sin(a) * side + np.cos(a) * forward
        occluder = Box(center - 0.2 * up, np.stack([ax0, up, ax2]), np.array([0.8, 0.8, 0.8]))
    else:
        raise ValueError(f"unknown plane view {kind!r} (use 'sphere' or 'box')")
    plane_offset = float(up @ center) - 1.0  # the plane touches the object's lowest point
    cam = Camera(resolution, resolution, distance=SPHERE_DISTANCE)
    f = cam.focal_px
    u = np.arange(resolution) + 0.5
    uu, vv = np.meshgrid(u, u)
    rays = np.stack([(uu - resolution / 2) / f, -(vv - resolution / 2) / f, -np.ones_like(uu)], axis=-1).reshape(-1, 3)
    origin = np.zeros_like(rays)
    denom = rays @ up
    t_plane = np.where(denom < -1e-9, plane_offset / np.where(denom < -1e-9, denom, -1.0), np.inf)
    t_obj = occluder.intersect(origin, rays)
    if not np.isfinite(np.minimum(t_plane, t_obj)).all():
        raise ValueError("a plane view's pixel sees the sky; lower the elevation")
    on_object = t_obj < t_plane
    t = np.minimum(t_plane, t_obj)
    points = rays * t[:, None]
    normal = np.where(on_object[:, None], occluder.normal_at(points), up[None, :])
    n = resolution
    scene = Scene(
        albedo=np.ones((n, n, 3), np.float32),
        specular=np.zeros((n, n), np.float32),
        roughness=np.ones((n, n), np.float32),
        normal=normal.reshape(n, n, 3).astype(np.float32),
        depth=t.reshape(n, n).astype(np.float32),  # rays have z = -1, so t is the depth
        mask=np.ones((n, n), bool),
        camera=cam,
    )
    return PlaneView(kind, scene, points, normal, on_object, up, occluder)
