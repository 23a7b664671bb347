"""One synthetic person per seed: body shape, pose, outfit and turn drawn from the seed alone,
placed in the project's camera, with its G-buffers (albedo, specular, roughness, camera-space
normal, depth, mask) as a scene bundle and its camera-space mesh for the ray tracer."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..camera import Camera
from ..scene import Scene
from .geometry import vertex_normals
from .humans import build_body, dress, place_in_camera, rasterize, sample_phenotype, sample_pose
from .materials import Outfit, make_materials, sample_outfit

TURN_RANGE = (-60.0, 60.0)  # degrees the person is turned from facing the camera
FILL_RANGE = (0.8, 0.92)  # of the image height the figure spans (a full body, as in the paper)


@dataclass(frozen=True)
class Person:
    seed: int
    scene: Scene  # the G-buffers
    vertices: np.ndarray  # (V, 3) camera space, metres
    faces: np.ndarray  # (F, 3)
    fields: np.ndarray  # (V, 8) per-vertex rest-pose fields (materials are functions of them)
    heads: dict  # rest-pose bone heads
    rest: np.ndarray  # (V, 3) rest-pose vertices
    outfit: Outfit
    phenotype: dict
    pose_style: str
    pose: dict
    turn: float

    def meta(self) -> dict:
        """What the person was made from (JSON-ready)."""
        from dataclasses import asdict

        return {"seed": self.seed, "phenotype": self.phenotype, "pose_style": self.pose_style, "pose": self.pose,
                "turn_degrees": self.turn, "outfit": asdict(self.outfit)}


def make_person(seed: int, size: int = 256) -> Person:
    """The person of ``seed`` in a ``size`` x ``size`` image; the same seed gives the same person
    bit for bit."""
    rng = np.random.default_rng([int(seed), 0xB0D1])
    phenotype = sample_phenotype(rng)
    style, pose = sample_pose(rng)
    outfit = sample_outfit(rng)
    turn = float(rng.uniform(*TURN_RANGE))
    fill = float(rng.uniform(*FILL_RANGE))
    verts, faces, fields, heads, rest = build_body(phenotype, pose)
    verts = dress(verts, faces, fields, heads, rest, outfit)
    cam = Camera(size, size)
    pos, _, _ = place_in_camera(verts, cam, cam.distance, turn, fill)
    depth, normal, mask, attrs = rasterize(cam, pos, vertex_normals(pos, faces), fields, faces)
    albedo, spec, rough, _ = make_materials(attrs, mask, heads, rest, outfit)
    scene = Scene(albedo=albedo, specular=spec, roughness=rough, normal=normal, depth=depth.astype(np.float32), mask=mask,
                  camera=cam).validate()
    return Person(int(seed), scene, pos, faces, fields, heads, rest, outfit, phenotype, style, pose, turn)
