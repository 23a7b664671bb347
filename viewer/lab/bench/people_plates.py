"""Plates whose light is known and that show people (for ``relight bench plates``): the dataset's synthetic people
rendered by the ray tracer standing on a ground plane inside a map.

A plate of a map at a yaw: the map (turned as :func:`viewer.lab.data.reference.envmap_emitter` turns it,
the rotation the bench's true lights get) is the backdrop above the horizon; a ground plane of albedo
``GROUND_ALBEDO`` (grey, diffuse) ``EYE_HEIGHT`` below the camera hides its lower half; ``PEOPLE`` people of
the dataset (:func:`viewer.lab.data.people.make_person`, their seeds drawn from the plate's) stand on it
``DISTANCES`` metres ahead, side by side, facing the camera as the dataset turns them. The camera is level,
at eye height, ``FOCAL_35`` mm (60 degrees across the longer side), ``PLATE_SIZE`` pixels. Mitsuba 3's
``direct`` integrator (the dataset's truth: no light bounced), ``SPP`` samples a pixel; the people cast
their shadows on the ground. Then as :func:`viewer.lab.bench.plates.make_plate` makes a map's plate: its
linear radiance scaled to a median luminance of 0.18, sRGB, clipped, an 8-bit JPEG with the focal length
in its EXIF. What the plate's light is measured against is the map, as for the map's plates; the people
are what the light is read from (their faces and clothes shaded by it, their shadows on the ground).
"""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np

from viewer.files.imageio import atomic_path, linear_to_srgb

PLATE_SIZE = (960, 640)
FOCAL_35 = 31  # mm, 35-mm equivalent (an EXIF integer): 60.3 degrees across the longer side
EYE_HEIGHT = 1.6  # metres: the camera above the ground
GROUND_ALBEDO = 0.25
GROUND_HALF_SIZE = 2000.0  # metres: the plane's edge lies 0.05 degrees below the horizon
PEOPLE = 2
HEIGHTS = (1.55, 1.9)  # metres: each person's height is drawn in this range
DISTANCES = (4.5, 6.5)  # metres ahead of the camera, one person at each
SIDE = 1.1  # metres: each person this far left or right of the line of sight (alternating)
SPP = 48
JPEG_QUALITY = 90


def _standing(person, distance: float, side: float, height: float) -> np.ndarray:
    """The person's vertices ``height`` metres tall (the dataset scales each to fill its frame), their lowest
    point on the ground, ``distance`` metres ahead and ``side`` metres to the right of the camera (their turn kept)."""
    v = person.vertices.astype(np.float64)
    centre = 0.5 * (v.min(axis=0) + v.max(axis=0))
    v = (v - np.array([centre[0], v[:, 1].min(), centre[2]])) * (height / float(np.ptp(v[:, 1])))
    return (v + np.array([side, -EYE_HEIGHT, -distance])).astype(np.float32)


def render_people_plate(env, yaw: float, seed: int, size: tuple[int, int] = PLATE_SIZE, spp: int = SPP) -> np.ndarray:
    """(H, W, 3) float32 linear: the plate of the module (``env`` turned by ``yaw``, the people of ``seed``)."""
    from viewer.lab.data.people import make_person
    from viewer.lab.data.reference import SPECULAR_LEVELS, direct_scene, envmap_emitter, mi_mesh, mitsuba, specular_levels

    mi = mitsuba()
    w, h = size
    fov = math.degrees(2.0 * math.atan(36.0 / (2.0 * FOCAL_35)))
    sensor = {"type": "perspective", "fov": fov, "fov_axis": "x" if w >= h else "y",
              # looking along -z, y up (as the dataset's camera; Mitsuba's looks along +z, x to the left)
              "to_world": mi.ScalarTransform4f(np.diag([-1.0, 1.0, -1.0, 1.0]).tolist()),
              "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}, "pixel_format": "rgb"},
              "sampler": {"type": "independent", "sample_count": int(spp)}}
    items = direct_scene(sensor, envmap_emitter(mi, env, yaw), hide_emitters=False)
    lie = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]) * GROUND_HALF_SIZE  # the rectangle's +z up
    ground = np.eye(4)
    ground[:3, :3], ground[:3, 3] = lie, (0.0, -EYE_HEIGHT, 0.0)
    items["ground"] = {"type": "rectangle", "to_world": mi.ScalarTransform4f(ground.tolist()),
                       "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [GROUND_ALBEDO] * 3}}}
    rng = np.random.default_rng([int(seed), 61])
    for k in range(PEOPLE):
        person = make_person(int(rng.integers(0, 1 << 30)), 128)
        vertices = _standing(person, DISTANCES[k % len(DISTANCES)], SIDE * (1 if k % 2 else -1), float(rng.uniform(*HEIGHTS)))
        level = specular_levels(person.specular[person.faces[:, 0]])
        attributes = {"vertex_albedo": person.albedo, "vertex_roughness": person.roughness[:, None]}
        for s in np.unique(level):
            bsdf = mi.load_dict({"type": "principled", "base_color": {"type": "mesh_attribute", "name": "vertex_albedo"},
                                 "roughness": {"type": "mesh_attribute", "name": "vertex_roughness"},
                                 "specular": float(s / (SPECULAR_LEVELS - 1))})
            items[f"person{k}_{s}"] = mi_mesh(mi, f"person{k}_{s}", vertices, person.normals, person.faces[level == s], bsdf,
                                              attributes=attributes)
    return np.nan_to_num(np.array(mi.render(mi.load_dict(items), spp=spp, seed=int(seed)), dtype=np.float32)[..., :3])


def make_people_plate(env, yaw: float, seed: int, path: Path, size: tuple[int, int] = PLATE_SIZE, spp: int = SPP) -> float:
    """The plate of :func:`render_people_plate` written to ``path`` as a camera writes it (the module's
    last step); returns the scale its linear radiance was multiplied by (median luminance 0.18)."""
    from PIL import Image

    from viewer.lighting.envmap import LUMINANCE

    linear = render_people_plate(env, yaw, seed, size, spp)
    scale = 0.18 / max(float(np.median(linear @ LUMINANCE.astype(np.float32))), 1e-12)
    srgb = (np.clip(linear_to_srgb(linear * scale), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    image = Image.fromarray(srgb)
    exif = Image.Exif()
    exif.get_ifd(0x8769)[0xA405] = FOCAL_35
    buffer = io.BytesIO()
    image.save(buffer, "JPEG", quality=JPEG_QUALITY, exif=exif.tobytes())
    with atomic_path(path) as tmp:
        tmp.write_bytes(buffer.getvalue())
    return scale
