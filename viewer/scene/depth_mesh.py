"""Mesh from a depth map: one vertex per masked pixel centre, two triangles per pixel quad.

A triangle is kept when its three vertices are inside the mask and none of its edges spans a depth
gap. A gap is a depth jump larger than ``max(gap_min, gap_slope * step * d / f)`` metres, i.e. a
surface steeper than ``atan(gap_slope)`` to the view ray (d / f is a pixel's footprint at depth d)
and at least ``gap_min`` deep. ``step`` > 1 decimates the grid (every step-th pixel) for shadow
passes. The GL engine and the torch twin both use this function, so they see the same triangles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from viewer.scene.bundle import Scene

GAP_MIN = 0.03  # metres
GAP_SLOPE = 8.0  # depth jump per pixel footprint (a surface at ~83 degrees to the view ray)


@dataclass(frozen=True)
class DepthMesh:
    vertices: np.ndarray  # (K, 3) float32 camera-space positions
    triangles: np.ndarray  # (T, 3) int32 indices into vertices
    step: int

    @property
    def n_triangles(self) -> int:
        return int(self.triangles.shape[0])


def depth_mesh(scene: Scene, step: int = 1, gap_min: float = GAP_MIN, gap_slope: float = GAP_SLOPE) -> DepthMesh:
    step = max(1, int(step))
    mask = scene.mask[::step, ::step]
    depth = scene.depth[::step, ::step]
    pts = scene.points()[::step, ::step]
    h, w = mask.shape
    idx = np.arange(h * w, dtype=np.int64).reshape(h, w)
    if h < 2 or w < 2:
        return DepthMesh(pts.reshape(-1, 3), np.zeros((0, 3), np.int32), step)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]  # quad corners: a b / c d
    m = mask.reshape(-1)
    z = depth.reshape(-1).astype(np.float64)
    footprint = z / scene.camera.focal_px * step
    limit = np.maximum(gap_min, gap_slope * footprint)

    def ok(i, j):
        return np.abs(z[i] - z[j]) <= np.minimum(limit[i], limit[j])

    tris = []
    for t0, t1, t2 in ((a, c, b), (b, c, d)):  # counter-clockwise seen from the camera
        t0, t1, t2 = t0.ravel(), t1.ravel(), t2.ravel()
        keep = m[t0] & m[t1] & m[t2] & ok(t0, t1) & ok(t1, t2) & ok(t0, t2)
        tris.append(np.stack([t0[keep], t1[keep], t2[keep]], axis=1))
    triangles = np.concatenate(tris, axis=0)
    used = np.unique(triangles)  # keep only referenced vertices (rasterizers shade whole ranges)
    remap = np.zeros(h * w, dtype=np.int64)
    remap[used] = np.arange(len(used))
    vertices = pts.reshape(-1, 3)[used]
    return DepthMesh(np.ascontiguousarray(vertices, dtype=np.float32), remap[triangles].astype(np.int32), step)


def resolve_step(step: int, scene: Scene) -> int:
    """The decimation actually used: ``step``, or for 0 (auto) 3 pixels per 512 image pixels
    (about 1.5 cm triangles on the sample scene; error vs time in docs/engine.md)."""
    if step < 0:
        raise ValueError(f"shadow_step must be >= 0, got {step}")
    return step if step > 0 else max(1, round(3 * max(scene.width, scene.height) / 512))


def caster_points(scene: Scene, mesh: DepthMesh) -> np.ndarray:
    """The points the shadow-map frames enclose (K, 3): the shadow mesh's vertices (every one belongs
    to a kept triangle, so a lone outlier pixel cannot stretch the frames), or the masked pixels'
    points when the mesh has no triangle."""
    return mesh.vertices if mesh.n_triangles else scene.points()[scene.mask]
