"""Ray-traced ground truth with Mitsuba 3: direct lighting only (``direct`` integrator), the full
environment map as the emitter, Mitsuba's ``principled`` BSDF.

:func:`render_bundle_reference` renders a scene bundle's own geometry (its full-resolution depth
mesh, the surface the engine sees, with the bundle's normals as shading normals and its albedo,
specular and roughness maps as materials): the exact target for the engine's error, no network
involved. It returns

- ``full``: the relit image (principled BSDF; Mitsuba's diffuse lobe is Disney's, not Lambert's,
  which is part of the engine's error against it);
- ``diffuse_shadowed``: the shading of a white Lambertian surface (albedo 1), with shadows: the
  paper's Y_diff, the quantity the engine's ``diffuse`` x visibility sums approximate.

Frames: the project's environment-map convention (docs/conventions.md) differs from Mitsuba's
``envmap`` by a half turn about +y; :func:`envmap_emitter` applies it (tested by evaluating the
emitter). The camera is the project's (perspective, x right, y up, looking along -z), with a box
pixel filter: each pixel is the average over its footprint.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from viewer.lighting.envmap import EnvMap
from viewer.scene.area_lights import rotation_matrix
from viewer.scene.bundle import Scene
from viewer.scene.depth_mesh import depth_mesh

LLVM = Path("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1")
SPECULAR_LEVELS = 16  # per-face specular is quantized to this many materials (principled takes one float)


def mitsuba(variant: str | None = None):
    """Mitsuba with a vectorized variant: CUDA when asked and present, else LLVM (which needs LLVM
    19 on Debian 12: the default LLVM 15 aborts Dr.Jit), else the scalar one."""
    if "DRJIT_LIBLLVM_PATH" not in os.environ and LLVM.is_file():
        os.environ["DRJIT_LIBLLVM_PATH"] = str(LLVM)
    import mitsuba as mi

    if mi.variant() is None:
        for v in ([variant] if variant else []) + ["llvm_ad_rgb", "scalar_rgb"]:
            try:
                mi.set_variant(v)
                break
            except (ImportError, AttributeError):
                continue
    return mi


def specular_levels(specular) -> np.ndarray:
    """Specular values quantized to ``SPECULAR_LEVELS`` (level k stands for k / (levels - 1))."""
    return np.clip(np.rint(np.asarray(specular) * (SPECULAR_LEVELS - 1)), 0, SPECULAR_LEVELS - 1).astype(int)


def direct_scene(sensor: dict, emitter: dict, hide_emitters: bool = True) -> dict:
    """A Mitsuba scene dict with direct lighting only and the map hidden behind the geometry; add shapes."""
    return {"type": "scene", "integrator": {"type": "direct", "hide_emitters": hide_emitters}, "sensor": sensor, "light": emitter}


def _transform(mi, m: np.ndarray):
    full = np.eye(4)
    full[:3, :3] = m
    return mi.ScalarTransform4f(full.tolist())


def envmap_emitter(mi, env: EnvMap, yaw: float = 0.0, tilt: float = 0.0) -> dict:
    """Mitsuba's envmap for ``env`` turned by ``rotation_matrix(yaw, tilt)`` (L'(R d) = L(d), the
    rotation the lights get with ``AreaLights.rotated``)."""
    half_turn = np.diag([-1.0, 1.0, -1.0])  # Mitsuba's longitude zero is the project's +z, not -z
    to_world = rotation_matrix(yaw, tilt) @ half_turn
    return {"type": "envmap", "bitmap": mi.Bitmap(np.ascontiguousarray(env.pixels, dtype=np.float32)),
            "to_world": _transform(mi, to_world)}


def camera_sensor(mi, scene: Scene, spp: int) -> dict:
    cam = scene.camera
    w, h = cam.width, cam.height
    fov = np.degrees(2.0 * np.arctan(max(w, h) / 2.0 / cam.focal_px))
    return {
        "type": "perspective",
        "fov": float(fov),
        "fov_axis": "x" if w >= h else "y",
        # look along -z with y up; Mitsuba's camera looks along its local +z with x to the left
        "to_world": _transform(mi, np.diag([-1.0, 1.0, -1.0])),
        "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}, "pixel_format": "rgba"},
        "sampler": {"type": "independent", "sample_count": int(spp)},
    }


@dataclass(frozen=True)
class BundleMesh:
    vertices: np.ndarray  # (K, 3) camera space
    normals: np.ndarray  # (K, 3) the bundle's normals at the vertices' pixels (shading normals)
    uv: np.ndarray  # (K, 2) texture coordinates of the vertices' pixel centres (v = 0 at the top row)
    triangles: np.ndarray  # (T, 3)
    face_specular: np.ndarray  # (T,) the bundle's specular at each face's first vertex


def bundle_mesh(scene: Scene) -> BundleMesh:
    mesh = depth_mesh(scene, step=1)
    cam = scene.camera
    v = mesh.vertices.astype(np.float64)
    cx, cy = cam.center
    col = cx + cam.focal_px * v[:, 0] / -v[:, 2] - 0.5
    row = cy - cam.focal_px * v[:, 1] / -v[:, 2] - 0.5
    i = np.clip(np.rint(row).astype(int), 0, scene.height - 1)
    j = np.clip(np.rint(col).astype(int), 0, scene.width - 1)
    uv = np.stack([(j + 0.5) / scene.width, (i + 0.5) / scene.height], axis=1)
    spec = scene.specular[i, j]
    return BundleMesh(mesh.vertices, scene.normal[i, j], uv.astype(np.float32), mesh.triangles,
                      spec[mesh.triangles[:, 0]])


def mi_mesh(mi, name: str, vertices: np.ndarray, normals: np.ndarray, faces: np.ndarray, bsdf,
            texcoords: np.ndarray | None = None, attributes: dict | None = None):
    """A Mitsuba mesh of the ``faces`` subset (only the vertices they use), with shading normals,
    optional texture coordinates and per-vertex attributes (``vertex_<name>``: (V, C) arrays, read
    by ``mesh_attribute`` textures)."""
    used, local = np.unique(faces, return_inverse=True)
    props = mi.Properties()
    props["bsdf"] = bsdf
    out = mi.Mesh(name, vertex_count=len(used), face_count=len(faces), props=props, has_vertex_normals=True,
                  has_vertex_texcoords=texcoords is not None)
    params = mi.traverse(out)
    params["vertex_positions"] = mi.Float(np.asarray(vertices, np.float32)[used].ravel())
    params["vertex_normals"] = mi.Float(np.asarray(normals, np.float32)[used].ravel())
    if texcoords is not None:
        params["vertex_texcoords"] = mi.Float(np.asarray(texcoords, np.float32)[used].ravel())
    params["faces"] = mi.UInt32(local.reshape(-1, 3).astype(np.uint32).ravel())
    params.update()
    for key, values in (attributes or {}).items():
        values = np.asarray(values, np.float32)[used].reshape(len(used), -1)
        out.add_attribute(key, values.shape[1], mi.Float(values.ravel()))
    return out


def render_bundle_reference(scene: Scene, env: EnvMap, yaw: float = 0.0, tilt: float = 0.0, spp: int = 256,
                            seed: int = 0, images=("full", "diffuse_shadowed")) -> dict[str, np.ndarray]:
    """``images`` (default ``full`` and ``diffuse_shadowed``), each (H, W, 3) float32, of the
    bundle's depth mesh under ``env`` turned by (yaw, tilt), zero where no surface is seen (the map
    itself is hidden), and ``coverage`` (H, W): the fraction of each pixel the mesh covers (see the
    module docstring)."""
    mi = mitsuba()
    m = bundle_mesh(scene)
    albedo = mi.Bitmap(np.ascontiguousarray(np.clip(scene.albedo, 0.0, 1.0), dtype=np.float32))
    rough = mi.Bitmap(np.ascontiguousarray(scene.roughness[..., None], dtype=np.float32))
    level = specular_levels(m.face_specular)
    emitter = envmap_emitter(mi, env, yaw, tilt)
    sensor = camera_sensor(mi, scene, spp)
    outputs = {}
    for name in images:
        items = direct_scene(sensor, emitter)
        if name == "full":
            for k in np.unique(level):
                bsdf = mi.load_dict({
                    "type": "principled",
                    "base_color": {"type": "bitmap", "bitmap": albedo, "filter_type": "nearest", "raw": True},
                    "roughness": {"type": "bitmap", "bitmap": rough, "filter_type": "nearest", "raw": True},
                    "specular": float(k / (SPECULAR_LEVELS - 1)),
                })
                items[f"shape{k}"] = mi_mesh(mi, f"specular{k}", m.vertices, m.normals, m.triangles[level == k], bsdf, m.uv)
        else:
            white = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}})
            items["shape"] = mi_mesh(mi, "white", m.vertices, m.normals, m.triangles, white, m.uv)
        img = np.array(mi.render(mi.load_dict(items), spp=spp, seed=seed), dtype=np.float32)
        outputs[name] = img[..., :3]
        outputs["coverage"] = img[..., 3]
    return outputs
