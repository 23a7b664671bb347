"""The test cases of ``relight bench report`` and their ray-traced references.

A case is a scene bundle under a list of lightings (a map and a yaw). Its reference is the exact
direct-lighting render of the bundle's own depth mesh and materials under the whole turned map
(Mitsuba 3, :func:`viewer.lab.data.reference.render_bundle_reference`); a lighting that is a record of
a synthetic dataset also has that dataset's full-geometry ground truth (its ``full.exr``). The
references are cached on disk (beside the light cache, ``references/``), keyed by the bundle's
maps, the map's pixels, the yaw and the samples per pixel, so a second report costs no ray tracing.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from viewer.errors import InputError
from viewer.files.imageio import read_exr, write_exr
from viewer.lighting.envmap import EnvMap, load_envmap
from viewer.lighting.lightfit.cache import cache_dir, map_hash
from viewer.scene.bundle import Scene, load_scene

REFERENCE_VERSION = 1  # bump when the reference renderer changes its images


@dataclass(frozen=True)
class Lighting:
    map_name: str  # the map's file stem
    yaw: float  # degrees, the lighting (map and lights) turned about +y
    truth: Path | None = None  # the dataset's full-geometry relit image (full.exr) of this lighting


@dataclass
class Case:
    name: str
    group: str  # "sample", "photo" or "held-out"
    scene: Scene
    lightings: list[Lighting] = field(default_factory=list)


def find_maps(*folders) -> dict[str, Path]:
    """{stem: path} of the .hdr / .exr maps in ``folders`` (earlier folders win)."""
    maps: dict[str, Path] = {}
    for folder in folders:
        for path in sorted(Path(folder).glob("*.hdr")) + sorted(Path(folder).glob("*.exr")):
            maps.setdefault(path.stem, path)
    if not maps:
        raise InputError(folders[0] if folders else None, "no .hdr/.exr environment maps found")
    return maps


def sample_case(scene: Scene, maps, yaws) -> Case:
    return Case("sample scene", "sample", scene, [Lighting(m, float(y)) for m in maps for y in yaws])


def photo_case(photo: Path, mask: Path, maps, yaw: float, size: int = 512) -> Case:
    """The bundled photo's inferred bundle (``relight infer``, cached) under every map."""
    from viewer.photo.inference import cached_bundle

    bundle, _ = cached_bundle(photo, mask, size=size)
    return Case(f"photo {photo.stem}", "photo", load_scene(bundle), [Lighting(m, float(yaw)) for m in maps])


def heldout_cases(data: Path, maps, people: int, seed: int = 0) -> list[Case]:
    """The first ``people`` people of a held-out dataset (``relight dataset make --split heldout``),
    each under every map at one random yaw, plus its own records' lightings (with their truth)."""
    folder = Path(data) / "samples"
    samples = sorted(p for p in folder.iterdir() if (p / "scene.json").is_file()) if folder.is_dir() else []
    if not samples:
        raise InputError(data, "no samples: expected a dataset made by `relight dataset make`")
    rng = np.random.default_rng(seed)
    cases = []
    for sample in samples[:people]:
        yaw = float(rng.uniform(0.0, 360.0))
        lightings = [Lighting(m, yaw) for m in maps]
        for record in sorted(sample.glob("lighting_*")):
            info = json.loads((record / "lighting.json").read_text())
            if info.get("tilt", 0.0):
                continue  # the report turns lightings about +y only
            lightings.append(Lighting(info["map"], float(info["yaw"]), record / "full.exr"))
        cases.append(Case(f"held-out {sample.name}", "held-out", load_scene(sample), lightings))
    return cases


class MapStore:
    """Environment maps by name, loaded once, with their content hashes."""

    def __init__(self, paths: dict[str, Path]):
        self.paths = dict(paths)
        self._maps: dict[str, EnvMap] = {}
        self._hashes: dict[str, str] = {}

    def add(self, paths: dict[str, Path]):
        for name, path in paths.items():
            self.paths.setdefault(name, path)

    def __getitem__(self, name: str) -> EnvMap:
        if name not in self._maps:
            if name not in self.paths:
                raise InputError(None, f"environment map {name!r} not found among {', '.join(sorted(self.paths))}")
            self._maps[name] = load_envmap(self.paths[name])
        return self._maps[name]

    def hash(self, name: str) -> str:
        if name not in self._hashes:
            self._hashes[name] = map_hash(self[name])
        return self._hashes[name]


def scene_hash(scene: Scene) -> str:
    h = hashlib.sha256()
    for a in (scene.albedo, scene.specular, scene.roughness, scene.normal, scene.depth, scene.mask):
        h.update(np.ascontiguousarray(a).tobytes())
    h.update(json.dumps([scene.camera.width, scene.camera.height, scene.camera.focal_px]).encode())
    return h.hexdigest()[:20]


def reference_dir() -> Path:
    return cache_dir().with_name("references")


def reference(scene: Scene, key: str, maps: MapStore, lighting: Lighting, spp: int, seed: int = 0) -> np.ndarray:
    """(H, W, 3) the ray-traced relit image of the bundle's depth mesh (cached)."""
    from viewer.lab.data.reference import render_bundle_reference

    name = f"{key}-{maps.hash(lighting.map_name)}-y{lighting.yaw:.4f}-s{spp}-r{seed}-v{REFERENCE_VERSION}.exr"
    path = reference_dir() / name
    if path.is_file():
        return read_exr(path)[..., :3]
    img = render_bundle_reference(scene, maps[lighting.map_name], yaw=lighting.yaw, spp=spp, seed=seed,
                                  images=("full",))["full"]
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".tmp.exr")
    write_exr(tmp, img)
    tmp.replace(path)
    return img


def interior(mask: np.ndarray) -> np.ndarray:
    """The mask less its one-pixel border: silhouette pixels are partly covered in the reference
    (box filter) and whole in the engine's G-buffer image, an error no knob changes."""
    m = np.pad(mask, 1)
    out = mask.copy()
    for di in (0, 1, 2):
        for dj in (0, 1, 2):
            out &= m[di:di + mask.shape[0], dj:dj + mask.shape[1]]
    return out
