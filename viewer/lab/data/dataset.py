"""``relight dataset make``: synthetic people relit under environment maps, written to a directory.

Layout (all images EXR float32 unless noted; conventions as docs/scene-bundle.md)::

    DIR/maps/<name>.hdr, <name>.lights.json   the map pool and each map's fitted area lights
    DIR/samples/<index>/                       one person: a scene bundle (G-buffers) + meta.json
        lighting_<k>/full.exr                  relit image (Mitsuba principled + direct)
                     diffuse.exr specular.exr  the two lobes without shadows (albedo 1 for diffuse)
                     diffuse_shadowed.exr      Y_diff: the diffuse lobe with shadows
                     specular_shadowed.exr     the specular lobe with shadows
                     lights.json               the map's fitted lights, turned like the map
                     lighting.json             map name, kind and rotation
        sample.json                            written last: the sample is complete (resume skips it)
    DIR/manifest-<i>of<n>.json                 per shard: counts, resolution, maps, timing, memory

Training samples light people with procedural maps (:mod:`.envmaps`) from a pool of ``pool``
maps (default ``POOL``) made from the dataset seed; the held-out split uses the nine CC0 maps of
the folder given (``--maps``, by default ``$RELIGHT_DATA/hdri``: the shared CC0 maps) only, and they never appear in training. The ``key``
split lights people with ``pool`` key-light maps (:func:`.envmaps.key_light`: one small light, and
a rim light in half of them, no fill), which are not turned; made with the held-out split's seed it
holds the same people. Every other lighting turns its map by a random longitude, as in the paper; the
lights are fitted once per map (the cache of
:mod:`viewer.lighting.lightfit`) and turned with it (fitting commutes with rotation, docs/lights.md).
The ``clip`` split (:mod:`.clips`) makes clips of a person turning, filmed under one held-out map
with the truth under another. Everything is a function of (seed, index): a sample is reproduced bit for bit, and ``--shard i/n``
takes indices i, i + n, ... so machines can share a dataset without talking to each other.
"""

from __future__ import annotations

import json
import os
import resource
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from viewer.errors import InputError
from viewer.files.imageio import write_exr, write_text
from viewer.lighting.envmap import EnvMap, load_envmap, save_envmap
from viewer.scene.area_lights import AreaLights, load_lights
from viewer.scene.bundle import save_scene

POOL = 32  # procedural training maps per dataset
SPLITS = ("train", "heldout", "key", "clip")
KEY_KINDS = ("key", "key_rim")
MAP_WIDTH = 256
N_LIGHTS = 16


@dataclass(frozen=True)
class DatasetConfig:
    out: Path
    count: int
    res: int = 256
    seed: int = 0
    shard: tuple[int, int] = (0, 1)
    spp: int = 64
    lightings: int = 2  # maps per person
    pool: int = POOL  # procedural maps in the training pool
    split: str = "train"  # train (procedural maps) | heldout (the CC0 maps) | key (key lights, held out) | clip (clips.py)
    frames: int = 24  # the clip split: frames of each clip
    fps: float = 12.0  # ... and their rate
    held_out_dir: Path | None = None  # the held-out split's maps (the CLI's --maps)

    def __post_init__(self):
        i, n = self.shard
        if not (n >= 1 and 0 <= i < n):
            raise InputError(None, f"--shard must be i/n with 0 <= i < n, got {i}/{n}")
        if self.count < 1 or self.res < 32 or self.spp < 1 or self.lightings < 1 or self.pool < 1:
            raise InputError(None, "count, spp, lightings and pool must be >= 1 and res >= 32")
        if not 0 <= self.seed < 2**31:
            raise InputError(None, f"--seed must be in [0, 2^31), got {self.seed}")
        if self.split not in SPLITS:
            raise InputError(None, f"split must be one of {', '.join(SPLITS)}, got {self.split!r}")
        if self.split in ("heldout", "clip") and self.held_out_dir is None:
            raise InputError(None, f"the {self.split} split needs its folder of maps (--maps)")
        if not 2 <= self.frames <= 1000:
            raise InputError(None, f"--frames must be in [2, 1000], got {self.frames}")


@dataclass(frozen=True)
class PoolMap:
    name: str
    kind: str
    env: EnvMap
    lights: AreaLights


def parse_shard(text: str) -> tuple[int, int]:
    try:
        i, n = (int(v) for v in text.split("/"))
    except ValueError:
        raise InputError(None, f"--shard must look like i/n (e.g. 0/4), got {text!r}") from None
    return i, n


def map_pool(cfg: DatasetConfig, progress=None) -> list[PoolMap]:
    """The maps of this split, each with its fitted lights (fitted once, kept in DIR/maps/)."""
    from viewer.lab.data.envmaps import key_light, random_map
    from viewer.lighting.lightfit import lights_for_map

    maps_dir = Path(cfg.out) / "maps"
    maps_dir.mkdir(parents=True, exist_ok=True)
    if cfg.split == "train":
        made = []
        for k in range(cfg.pool):
            m = random_map(cfg.seed * 1000 + k, MAP_WIDTH)
            made.append((f"procedural_{cfg.seed}_{k:03d}", m.kind, m.env))
    elif cfg.split == "key":
        made = []
        for k in range(cfg.pool):
            m = key_light(np.random.default_rng([cfg.seed * 1000 + k, 0x4B3E]), MAP_WIDTH)
            made.append((f"key_{cfg.seed}_{k:03d}", m.kind, m.env))
    else:
        files = sorted(Path(cfg.held_out_dir).glob("*.hdr")) + sorted(Path(cfg.held_out_dir).glob("*.exr"))  # heldout, clip
        if not files:
            raise InputError(cfg.held_out_dir, "no .hdr/.exr maps for the held-out split")
        made = [(f.stem, "photographed", load_envmap(f).downsampled(MAP_WIDTH)) for f in files]
    pool = []
    for k, (name, kind, env) in enumerate(made):
        hdr, side = maps_dir / f"{name}.hdr", maps_dir / f"{name}.lights.json"
        if not hdr.is_file():
            save_envmap(hdr, env)
        env = load_envmap(hdr)  # what the samples are rendered with is what the file holds
        if side.is_file():
            lights = load_lights(side)
        else:
            lights, _ = lights_for_map(env, N_LIGHTS)
            lights.save(side, fit={"source": hdr.name, "method": "fast", "n": N_LIGHTS})
        pool.append(PoolMap(name, kind, env, lights))
        if progress is not None:
            progress("maps", k + 1, len(made))
    return pool


def sample_dir(cfg: DatasetConfig, index: int) -> Path:
    return Path(cfg.out) / "samples" / f"{index:06d}"


def make_sample(cfg: DatasetConfig, index: int, pool: list[PoolMap]) -> dict:
    """Write sample ``index`` (see the module docstring); returns its record."""
    from viewer.lab.data.people import make_person
    from viewer.lab.data.truth import render_person, unshadowed_shading

    start = time.perf_counter()
    seed = cfg.seed * 1_000_003 + index
    rng = np.random.default_rng([seed, 0x11647])
    out = sample_dir(cfg, index)
    person = make_person(seed, cfg.res)
    save_scene(person.scene, out)
    write_text(out / "meta.json", json.dumps(person.meta(), indent=1) + "\n")
    t_person = time.perf_counter() - start
    lightings = []
    for k in range(cfg.lightings):
        pm = pool[int(rng.integers(len(pool)))]
        yaw = float(rng.uniform(0.0, 360.0))
        if pm.kind in KEY_KINDS:
            yaw = 0.0  # a key light stands where the photographer put it, relative to the camera
        r = render_person(person, pm.env, yaw=yaw, spp=cfg.spp, seed=(seed + k) % 2**32)  # Mitsuba's seed is 32-bit
        diffuse, specular = unshadowed_shading(person.scene, pm.env, yaw=yaw)
        d = out / f"lighting_{k}"
        for name, img in (("full", r["full"]), ("diffuse", diffuse), ("specular", specular),
                          ("diffuse_shadowed", r["diffuse_shadowed"]), ("specular_shadowed", r["specular_shadowed"])):
            write_exr(d / f"{name}.exr", img)
        pm.lights.rotated(yaw).save(d / "lights.json", fit={"source": pm.name, "yaw": yaw})
        write_text(d / "lighting.json", json.dumps({"map": pm.name, "kind": pm.kind, "yaw": yaw}) + "\n")
        lightings.append({"map": pm.name, "kind": pm.kind, "yaw": yaw})
    record = {"index": index, "seed": seed, "res": cfg.res, "spp": cfg.spp, "split": cfg.split, "lightings": lightings,
              "seconds": round(time.perf_counter() - start, 3), "person_seconds": round(t_person, 3)}
    tmp = out / ".sample.json.tmp"
    tmp.write_text(json.dumps(record, indent=1) + "\n")
    os.replace(tmp, out / "sample.json")  # last: the sample is complete
    return record


def make_dataset(cfg: DatasetConfig, progress=None) -> dict:
    """Make this shard's samples (skipping finished ones) and write its manifest."""
    start = time.perf_counter()
    from viewer.lab.data.clips import make_clip

    pool = map_pool(cfg, progress)
    if cfg.split == "clip" and len(pool) < 2:
        raise InputError(cfg.held_out_dir, "the clip split needs two maps or more (one to film under, one for the truth)")
    i, n = cfg.shard
    indices = list(range(i, cfg.count, n))
    made, skipped, seconds = 0, 0, []
    for done, index in enumerate(indices, 1):
        t0 = time.perf_counter()
        if cfg.split == "clip":  # a clip's frames are checked against its plan, kept or made (make_clip)
            fresh = make_clip(cfg, index, pool, progress)["frames_made"] > 0
        elif (sample_dir(cfg, index) / "sample.json").is_file():
            fresh = False
        else:
            make_sample(cfg, index, pool)
            fresh = True
        if fresh:
            seconds.append(time.perf_counter() - t0)
            made += 1
        else:
            skipped += 1
        if progress is not None:
            progress("clips" if cfg.split == "clip" else "samples", done, len(indices))
    manifest = {
        "format": "relight-dataset", "version": 1, "config": {**asdict(cfg), "out": str(cfg.out), "held_out_dir": str(cfg.held_out_dir)},
        "shard": f"{i}/{n}", "samples_in_shard": len(indices), "made": made, "skipped_finished": skipped,
        "relit_pairs_made": made * (cfg.frames if cfg.split == "clip" else cfg.lightings),
        "maps": [{"name": p.name, "kind": p.kind} for p in pool],
        "seconds_total": round(time.perf_counter() - start, 1),
        "seconds_per_sample_median": round(float(np.median(seconds)), 3) if seconds else None,
        "peak_memory_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, 1),
    }
    path = Path(cfg.out) / f"manifest-{i}of{n}.json"
    write_text(path, json.dumps(manifest, indent=1) + "\n")
    manifest["path"] = str(path)
    return manifest
