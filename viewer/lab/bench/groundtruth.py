"""Ground-truth visibility by ray tracing (Mitsuba 3): the oracle for the engine's shadow maps.

A receiver (camera pixel) is lit by a directional light when the ray from it towards the light
misses the full-resolution depth mesh. Rays start a small distance along the normal (and the light
direction) to avoid hitting the receiver's own triangles.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from viewer.scene.bundle import Scene
from viewer.scene.depth_mesh import depth_mesh

RAY_OFFSET = 2e-3  # metres along the normal and the light direction


def _mitsuba():
    llvm = Path("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1")
    if "DRJIT_LIBLLVM_PATH" not in os.environ and llvm.is_file():
        os.environ["DRJIT_LIBLLVM_PATH"] = str(llvm)  # the system's default LLVM 15 aborts Dr.Jit
    import mitsuba as mi

    if mi.variant() is None:
        mi.set_variant("llvm_ad_rgb")
    return mi


class RayTracedVisibility:
    """Exact hard visibility of a scene's depth mesh for any light direction."""

    def __init__(self, scene: Scene):
        mi = _mitsuba()
        self._mi = mi
        mesh = depth_mesh(scene, step=1)
        m = mi.Mesh("depth_mesh", vertex_count=len(mesh.vertices), face_count=max(mesh.n_triangles, 1))
        params = mi.traverse(m)
        params["vertex_positions"] = mi.Float(mesh.vertices.ravel())
        faces = mesh.triangles if mesh.n_triangles else np.zeros((1, 3), np.int32)
        params["faces"] = mi.UInt32(faces.astype(np.uint32).ravel())
        params.update()
        self._scene = mi.load_dict({"type": "scene", "mesh": m})
        self.mask = scene.mask
        self._points = scene.points()[scene.mask].astype(np.float64)
        self._normals = scene.normal[scene.mask].astype(np.float64)

    def visibility(self, direction) -> np.ndarray:
        """(H, W) float32: 1 lit, 0 shadowed (0 where the light is below the horizon, and outside
        the mask)."""
        mi = self._mi
        d = np.asarray(direction, dtype=np.float64)
        d = d / np.linalg.norm(d)
        o = self._points + RAY_OFFSET * (self._normals + d)
        n = len(o)
        ray = mi.Ray3f(mi.Point3f(*(mi.Float(o[:, k].astype(np.float32)) for k in range(3))),
                       mi.Vector3f(*(mi.Float(np.full(n, d[k], np.float32)) for k in range(3))))
        lit = ~np.array(self._scene.ray_test(ray), dtype=bool)
        lit &= (self._normals @ d) > 0
        out = np.zeros(self.mask.shape, np.float32)
        out[self.mask] = lit
        return out
