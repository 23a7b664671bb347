"""``RelightDataset``: the samples of ``relight dataset make`` as a ``torch.utils.data.Dataset``.

Each item is one (person, lighting) pair, a dict of float32 tensors, images channels-first:
``image`` (3, H, W) the relit person (zero outside the mask), ``background`` (3, H, W) the turned
map seen through the camera behind them (:meth:`viewer.lighting.envmap.EnvMap.seen_through`; the photo is
``image + (1 - mask) * background``), ``mask`` (1, H, W), ``albedo``, ``normal`` (3, H, W),
``specular``, ``roughness``, ``depth`` (1, H, W), ``diffuse``, ``specular_shading``,
``diffuse_shadowed`` (3, H, W), ``body`` (5, H, W: a body prior, :func:`body_channels`, made on
first use) and ``lights`` (N, 7): direction, sigma, RGB intensity (``fields``
picks which images are read: a network that needs three of them reads three); with
``visibility=R``, also ``hard`` and ``soft`` (N, H, W): the GL engine's shadow-map and
convolutional-shadow-map visibility of the true depth under those lights (R-texel shadow maps,
cached on disk).

Augmentations (``augment=True``, random per item from a seeded generator): a horizontal mirror
(images flipped, normals' and lights' x negated, as the mirrored scene would render) and an
exposure scale (relit image, shading and light intensities scaled together: the lighting is only
known up to scale from a photo).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset

from viewer.files.imageio import read_exr
from viewer.lighting.envmap import EnvMap, load_envmap
from viewer.nets.refine import SHADOW_RESOLUTION
from viewer.scene.area_lights import load_lights
from viewer.scene.bundle import load_scene

EXPOSURE_RANGE = (0.5, 2.0)
FIELDS = ("image", "background", "mask", "albedo", "normal", "specular", "roughness", "depth", "diffuse",
          "specular_shading", "diffuse_shadowed")


class RelightDataset(Dataset):
    """The finished samples of one dataset directory, or of several (a list: shards or datasets
    made on different machines)."""

    def __init__(self, root, augment: bool = False, seed: int = 0, visibility: int | None = None,
                 fields: tuple[str, ...] | None = None):
        roots = [Path(r) for r in (root if isinstance(root, (list, tuple)) else [root])]
        samples = sorted(p.parent for r in roots for p in (r / "samples").glob("*/sample.json"))
        self.items = [(s, k) for s in samples for k in range(len(json.loads((s / "sample.json").read_text())["lightings"]))]
        if not self.items:
            raise FileNotFoundError(f"{', '.join(map(str, roots))}: no finished samples (samples/*/sample.json)")
        self.augment = augment
        self.rng = np.random.default_rng(seed)
        self._maps: dict[Path, EnvMap] = {}
        self.visibility = visibility
        self.fields = tuple(fields) if fields is not None else FIELDS  # what to read (lights always)
        self._gl = None  # a headless GL context, made when visibility is first needed

    def _background(self, sample: Path, k: int, camera) -> np.ndarray:
        lighting = json.loads((sample / f"lighting_{k}" / "lighting.json").read_text())
        path = sample.parents[1] / "maps" / f"{lighting['map']}.hdr"
        if path not in self._maps:
            self._maps[path] = load_envmap(path)
        return self._maps[path].seen_through(camera, lighting["yaw"], lighting.get("tilt", 0.0))

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, i: int) -> dict:
        sample, k = self.items[i]
        scene = load_scene(sample)
        d = sample / f"lighting_{k}"
        area_lights = load_lights(d / "lights.json")
        lights = area_lights.to_array()
        read = {
            "image": lambda: read_exr(d / "full.exr"), "background": lambda: self._background(sample, k, scene.camera),
            "mask": lambda: scene.mask[..., None].astype(np.float32), "albedo": lambda: scene.albedo,
            "normal": lambda: scene.normal, "specular": lambda: scene.specular[..., None],
            "roughness": lambda: scene.roughness[..., None], "depth": lambda: scene.depth[..., None],
            "diffuse": lambda: read_exr(d / "diffuse.exr"), "specular_shading": lambda: read_exr(d / "specular.exr"),
            "diffuse_shadowed": lambda: read_exr(d / "diffuse_shadowed.exr"),
            "body": lambda: body_channels(sample, scene.height),
        }
        item = {key: read[key]() for key in self.fields}
        if self.visibility:
            if self._gl is None:
                from viewer.gl import create_headless_context

                self._gl = create_headless_context()
            hard, soft = cached_visibility(self._gl, d, scene, area_lights, self.visibility)
            item["hard"], item["soft"] = np.moveaxis(hard, 0, -1), np.moveaxis(soft, 0, -1)
        if self.augment:
            if self.rng.uniform() < 0.5:
                item = {key: np.ascontiguousarray(v[:, ::-1]) for key, v in item.items()}
                if "normal" in item:
                    item["normal"] = item["normal"] * np.array([-1.0, 1.0, 1.0], np.float32)
                if "body" in item:  # its first channel is a normal's x
                    item["body"] = item["body"] * np.array([-1.0, 1.0, 1.0, 1.0, 1.0], np.float32)
                lights[:, 0] = -lights[:, 0]
            scale = np.float32(np.exp(self.rng.uniform(*np.log(EXPOSURE_RANGE))))
            for key in ("image", "background", "diffuse", "specular_shading", "diffuse_shadowed"):
                if key in item:
                    item[key] = item[key] * scale
            lights[:, 4:7] *= scale
        out = {key: torch.from_numpy(np.ascontiguousarray(np.moveaxis(np.asarray(v, np.float32), -1, 0))) for key, v in item.items()}
        out["lights"] = torch.from_numpy(lights.astype(np.float32))
        return out


def body_channels(sample: Path, size: int) -> np.ndarray:
    """(H, W, 5): the sample's body prior (:mod:`viewer.lab.data.body_prior`) as network input:
    its normal, its depth about its median in ``DEPTH_RANGE`` units, and its mask (0 outside)."""
    from viewer.lab.data.body_prior import cached_body_prior
    from viewer.nets.depth import DEPTH_RANGE

    prior = cached_body_prior(sample, size)
    m = prior["mask"].astype(bool)
    depth = np.where(m, (prior["depth"].astype(np.float32) - (np.median(prior["depth"][m]) if m.any() else 0.0)) / DEPTH_RANGE, 0.0)
    return np.concatenate([prior["normal"].astype(np.float32), depth[..., None], m[..., None]], axis=-1).astype(np.float32)


def cached_visibility(ctx, lighting_dir: Path, scene, lights, resolution: int = SHADOW_RESOLUTION) -> tuple[np.ndarray, np.ndarray]:
    """(hard, soft) visibility (N, H, W) of one dataset lighting from the GL engine (the same
    passes the refined mode reads at run time), computed once and kept as ``visibility_<R>.npz``."""
    from viewer.gl import Engine, EngineOptions
    from viewer.photo.refinement import light_visibility

    path = Path(lighting_dir) / f"visibility_{resolution}.npz"
    if path.is_file():
        with np.load(path) as z:
            return z["hard"].astype(np.float32), z["soft"].astype(np.float32)
    eng = Engine(ctx, scene, EngineOptions(shadow_resolution=resolution))
    try:
        eng.set_lights(lights)
        hard, soft = light_visibility(eng)
    finally:
        eng.release()
    tmp = path.with_name(f".{path.stem}.tmp.npz")
    np.savez_compressed(tmp, hard=hard.astype(np.uint8), soft=soft.astype(np.float16))
    os.replace(tmp, path)
    return hard, soft.astype(np.float16).astype(np.float32)
