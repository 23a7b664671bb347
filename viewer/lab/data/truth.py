"""Ground truth of a synthetic person under an environment map (the paper's dataset section):
Mitsuba 3, ``principled`` BSDF, ``direct`` integrator (no indirect light).

Per (person, map, rotation):

- ``full``: the relit image (base colour = the person's albedo);
- ``diffuse_shadowed`` (the paper's Y_diff): the diffuse lobe with albedo 1, with shadows = the
  render with base colour 1 minus the render with base colour 0 (principled is linear in its base
  colour and, at metallic 0, its specular lobe does not depend on it);
- ``specular_shadowed``: the render with base colour 0 (the specular lobe alone, with shadows);
- ``diffuse`` and ``specular``: the same two lobes *without* shadows, at every pixel of the
  G-buffers: the principled BSDF evaluated by Mitsuba towards every sample of the map
  (:func:`viewer.lighting.lightfit.samples.map_samples`, 2048 samples, exact energy) and summed; no rays.

So, up to Monte Carlo noise, ``full = albedo * diffuse_shadowed + specular_shadowed`` everywhere and
``= albedo * diffuse + specular`` where nothing is shadowed, and ``diffuse_shadowed <= diffuse``
(tested). Every image is (H, W, 3) float32, zero where the person is not seen.
"""

from __future__ import annotations

import numpy as np

from viewer.lab.data.reference import SPECULAR_LEVELS, camera_sensor, direct_scene, envmap_emitter, mi_mesh, mitsuba, specular_levels
from viewer.lighting.envmap import EnvMap
from viewer.scene.area_lights import rotation_matrix
from viewer.scene.bundle import Scene

UNSHADOWED_SAMPLES = 2048
EVAL_CHUNK = 1 << 21  # pixel x sample pairs per BSDF evaluation


def _principled(mi, base, specular: float, roughness):
    return mi.load_dict({"type": "principled", "base_color": base, "roughness": roughness, "specular": float(specular)})


def render_person(person, env: EnvMap, yaw: float = 0.0, tilt: float = 0.0, spp: int = 64, seed: int = 0) -> dict:
    """``full``, ``diffuse_shadowed``, ``specular_shadowed`` and ``coverage`` (see the module doc)."""
    images = _renders(person, env, yaw, tilt, spp, seed, ("albedo", "white", "black"))
    return {
        "full": images["albedo"][..., :3],
        "diffuse_shadowed": np.maximum(images["white"][..., :3] - images["black"][..., :3], 0.0),
        "specular_shadowed": images["black"][..., :3],
        "coverage": images["albedo"][..., 3],
    }


def render_frame(person, env: EnvMap, yaw: float = 0.0, spp: int = 64, seed: int = 0, background: bool = False) -> np.ndarray:
    """(H, W, 4) float32: the person under ``env`` as a camera films them (RGB, and the coverage in
    alpha); with ``background`` the map seen behind them through the camera, as a photo of them there."""
    return _renders(person, env, yaw, 0.0, spp, seed, ("albedo",), hide_emitters=not background)["albedo"]


def _renders(person, env: EnvMap, yaw: float, tilt: float, spp: int, seed: int, names, hide_emitters: bool = True) -> dict:
    """The person rendered with each base colour of ``names`` (albedo, white, black): RGBA each."""
    mi = mitsuba()
    scene: Scene = person.scene
    face_level = specular_levels(person.specular[person.faces[:, 0]])
    attributes = {"vertex_albedo": person.albedo, "vertex_roughness": person.roughness[:, None]}
    bases = {
        "albedo": {"type": "mesh_attribute", "name": "vertex_albedo"},
        "white": {"type": "rgb", "value": [1.0, 1.0, 1.0]},
        "black": {"type": "rgb", "value": [0.0, 0.0, 0.0]},
    }
    roughness = {"type": "mesh_attribute", "name": "vertex_roughness"}
    emitter = envmap_emitter(mi, env, yaw, tilt)
    sensor = camera_sensor(mi, scene, spp)
    images = {}
    for name in names:
        base = bases[name]
        items = direct_scene(sensor, emitter, hide_emitters)
        for k in np.unique(face_level):
            bsdf = _principled(mi, base, k / (SPECULAR_LEVELS - 1), roughness)
            items[f"part{k}"] = mi_mesh(mi, f"specular{k}", person.vertices, person.normals, person.faces[face_level == k],
                                        bsdf, attributes=attributes)
        images[name] = np.array(mi.render(mi.load_dict(items), spp=spp, seed=seed), dtype=np.float32)
    return images


def unshadowed_shading(scene: Scene, env: EnvMap, yaw: float = 0.0, tilt: float = 0.0,
                       samples: int = UNSHADOWED_SAMPLES) -> tuple[np.ndarray, np.ndarray]:
    """(diffuse, specular) without shadows at every masked pixel of ``scene``: the principled lobes
    (albedo 1 for the diffuse one) evaluated towards each map sample and weighted by its flux."""
    from viewer.lighting.lightfit.samples import map_samples

    mi = mitsuba()
    import drjit as dr

    smp = map_samples(env, budget=samples)
    dirs = smp.direction @ rotation_matrix(yaw, tilt).T  # the map turned: its samples turn with it
    flux = np.asarray(smp.flux, np.float64)
    rows, cols = np.nonzero(scene.mask)
    n = scene.normal[rows, cols].astype(np.float64)
    view = -scene.points()[rows, cols].astype(np.float64)
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    rough = scene.roughness[rows, cols]
    level = specular_levels(scene.specular[rows, cols])
    diffuse = np.zeros((len(rows), 3))
    specular = np.zeros((len(rows), 3))
    ctx = mi.BSDFContext()
    s_count = len(dirs)
    per_chunk = max(1, EVAL_CHUNK // s_count)
    for k in np.unique(level):
        idx = np.nonzero(level == k)[0]
        for start in range(0, len(idx), per_chunk):
            sel = idx[start:start + per_chunk]
            p = len(sel)
            frame = mi.Frame3f(_vec(mi, np.repeat(n[sel], s_count, axis=0)))
            si = dr.zeros(mi.SurfaceInteraction3f, p * s_count)
            si.sh_frame = frame
            si.n = frame.n
            si.wi = frame.to_local(_vec(mi, np.repeat(view[sel], s_count, axis=0)))
            # roughness per pixel from a 1 x p texture: each pair looks up its pixel's texel
            texel = (np.repeat(np.arange(p), s_count).astype(np.float32) + 0.5) / p
            si.uv = mi.Point2f(mi.Float(texel), mi.Float(np.full(p * s_count, 0.5, np.float32)))
            wo = frame.to_local(_vec(mi, np.tile(dirs, (p, 1))))
            rough_tex = {"type": "bitmap", "bitmap": mi.Bitmap(rough[sel].astype(np.float32).reshape(1, p, 1)), "raw": True,
                         "filter_type": "nearest"}
            lobes = {}
            for base in (1.0, 0.0):
                bsdf = _principled(mi, {"type": "rgb", "value": [base] * 3}, k / (SPECULAR_LEVELS - 1), rough_tex)
                value = bsdf.eval(ctx, si, wo)  # f * cos(theta_o)
                lobes[base] = np.stack([np.array(value.x), np.array(value.y), np.array(value.z)], -1).reshape(p, s_count, 3)
            diffuse[sel] = np.einsum("psc,sc->pc", lobes[1.0] - lobes[0.0], flux)
            specular[sel] = np.einsum("psc,sc->pc", lobes[0.0], flux)
    h, w = scene.mask.shape
    out_d = np.zeros((h, w, 3), np.float32)
    out_s = np.zeros((h, w, 3), np.float32)
    out_d[rows, cols] = np.maximum(diffuse, 0.0)
    out_s[rows, cols] = np.maximum(specular, 0.0)
    return out_d, out_s


def _vec(mi, a: np.ndarray):
    a = np.asarray(a, np.float32)
    return mi.Vector3f(mi.Float(a[:, 0]), mi.Float(a[:, 1]), mi.Float(a[:, 2]))
