"""One synthetic person per seed: body shape, pose, outfit and turn drawn from the seed alone,
placed in the project's camera, with its G-buffers (albedo, specular, roughness, camera-space
normal, depth, mask) as a scene bundle and its camera-space mesh for the ray tracer.

The mesh is subdivided (``SUBDIVISIONS`` midpoint levels: ~4 mm between vertices, finer than a
pixel at 256^2) and the materials are evaluated at its vertices; the G-buffers interpolate those
vertex values exactly as the ray tracer does (``mesh_attribute`` textures), so the two agree to the
pixel. Specular is the exception at region borders: the ray tracer takes one specular value per
face (its first vertex's), the G-buffer interpolates it across a one-triangle band."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from viewer.lab.data.accessories import bag_mesh, sample_accessories
from viewer.lab.data.geometry import subdivide, vertex_normals
from viewer.lab.data.humans import build_body, dress, fold, place_in_camera, rasterize, sample_phenotype, sample_pose, seat
from viewer.lab.data.materials import Outfit, make_materials, sample_outfit
from viewer.scene.bundle import Scene
from viewer.scene.camera import Camera

TURN_RANGE = (-60.0, 60.0)  # degrees the person is turned from facing the camera
FILL_RANGE = (0.8, 0.92)  # of the image height the figure spans (a full body, as in the paper)
SUBDIVISIONS = 2
SITTING = 0.1  # of the people sit


@dataclass(frozen=True)
class Person:
    seed: int
    scene: Scene  # the G-buffers
    vertices: np.ndarray  # (V, 3) camera space, metres (the subdivided mesh)
    faces: np.ndarray  # (F, 3), counter-clockwise seen from outside
    normals: np.ndarray  # (V, 3) smooth shading normals
    albedo: np.ndarray  # (V, 3) linear
    specular: np.ndarray  # (V,)
    roughness: np.ndarray  # (V,)
    outfit: Outfit
    phenotype: dict
    pose_style: str
    pose: dict
    turn: float
    fill: float

    def meta(self) -> dict:
        """What the person was made from (JSON-ready)."""
        from dataclasses import asdict

        return {"seed": self.seed, "phenotype": self.phenotype, "pose_style": self.pose_style, "pose": self.pose,
                "turn_degrees": self.turn, "fill": self.fill,
                "outfit": asdict(self.outfit)}


def person_draws(seed: int) -> tuple[dict, str, dict, Outfit, float, float]:
    """Everything random about the person of ``seed``: (phenotype, pose style, pose, outfit, turn
    in degrees, fill of the image height). Sitting (``SITTING`` of the people) and the accessories
    come from a second stream, so the rest of a seed's person is the one earlier datasets hold."""
    rng = np.random.default_rng([int(seed), 0xB0D1])
    phenotype = sample_phenotype(rng)
    style, pose = sample_pose(rng)
    outfit = sample_outfit(rng)
    turn, fill = float(rng.uniform(*TURN_RANGE)), float(rng.uniform(*FILL_RANGE))
    extra = np.random.default_rng([int(seed), 0xACCE])
    if extra.uniform() < SITTING:
        style, pose = "sitting", seat(pose, extra)
    outfit = replace(outfit, accessories=sample_accessories(extra, seated=style == "sitting"))
    return phenotype, style, pose, outfit, turn, fill


def make_person(seed: int, size: int = 256, turn: float | None = None) -> Person:
    """The person of ``seed`` in a ``size`` x ``size`` image; the same seed gives the same person
    bit for bit. ``turn``: degrees from facing the camera, instead of the seed's (a person turning
    in a clip: the same body, pose and clothes at every frame)."""
    phenotype, style, pose, outfit, drawn, fill = person_draws(seed)
    turn = drawn if turn is None else float(turn)
    verts, faces, fields, heads, rest = build_body(phenotype, pose)
    verts = dress(verts, faces, fields, heads, rest, outfit)
    cam = Camera(size, size)
    pos, _, scale = place_in_camera(verts, cam, cam.distance, turn, fill)
    pos, faces, at = subdivide(pos, faces, {"normal": vertex_normals(pos, faces), "fields": fields}, SUBDIVISIONS)
    normals = at["normal"] / np.maximum(np.linalg.norm(at["normal"], axis=1, keepdims=True), 1e-12)
    pos, normals = fold(pos, faces, normals, at["fields"], heads, rest, outfit, scale, int(seed) % (1 << 30))
    n = len(pos)
    albedo_v, spec_v, rough_v, _ = make_materials(at["fields"][:, None, :], np.ones((n, 1), bool), heads, rest, outfit)
    albedo_v, spec_v, rough_v = albedo_v[:, 0], spec_v[:, 0], rough_v[:, 0]
    bag = bag_mesh(outfit.accessories, pos, normals, at["fields"], heads, scale)
    if bag is not None:  # a mesh of its own, after the body's
        faces = np.concatenate([faces, bag[1] + n])
        pos, normals, albedo_v, spec_v, rough_v = (np.concatenate([x, y]) for x, y in zip((pos, normals, albedo_v, spec_v, rough_v),
                                                                                       (bag[0], bag[2], bag[3], bag[4], bag[5])))
        n = len(pos)
    material = np.concatenate([albedo_v, rough_v[:, None], spec_v[:, None], np.zeros((n, 3))], axis=1)
    depth, normal, mask, attrs = rasterize(cam, pos, normals, material, faces)
    m = mask[..., None]
    scene = Scene(albedo=np.where(m, np.clip(attrs[..., :3], 0, 1), 0).astype(np.float32),
                  specular=np.where(mask, np.clip(attrs[..., 4], 0, 1), 0).astype(np.float32),
                  roughness=np.where(mask, np.clip(attrs[..., 3], 0, 1), 0).astype(np.float32),
                  normal=normal, depth=depth.astype(np.float32), mask=mask, camera=cam).validate()
    return Person(int(seed), scene, pos.astype(np.float32), faces.astype(np.int32), normals.astype(np.float32),
                  albedo_v.astype(np.float32), spec_v.astype(np.float32), rough_v.astype(np.float32), outfit,
                  phenotype, style, pose, turn, fill)
