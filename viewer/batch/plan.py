"""What a batch does: photos (files, folders, globs) x looks (environment maps at yaws, light files,
each with a rig and a preset where given) -> items, each with its output names and a key hashed from
the content of everything it depends on. Plain data; nothing here renders."""

from __future__ import annotations

import glob
import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from viewer.errors import InputError
from viewer.files.kinds import PHOTO_SUFFIXES

KEY_VERSION = "batch-1"  # outputs of an older batch code are made again


def collect_photos(paths) -> tuple[list[Path], list[str]]:
    """The photos and clips named by ``paths`` (files, folders: their photos and clips, sorted; globs),
    each once, and one line per path that named none. ``*.mask.png`` files (hand-made masks beside
    photos) are not photos, and neither are, in a folder or a glob, images and videos this program
    wrote (a batch's contact sheet and outputs, when a batch writes into the folder it reads:
    ``viewer.files.ownership``)."""
    from viewer.files.ownership import file_is_ours

    photos, missing = [], []
    for given in paths:
        p = Path(given)
        if p.is_dir():
            found = sorted(q for q in p.iterdir() if q.is_file() and is_input(q) and not file_is_ours(q))
        elif p.is_file():
            found = [p]
        else:
            found = sorted(Path(q) for q in glob.glob(str(given))
                           if Path(q).is_file() and is_input(Path(q)) and not file_is_ours(Path(q)))
        if not found:
            missing.append(f"{given}: no photo or clip there (PNG, JPEG, TIFF, WebP, BMP; MP4, MOV, WebM, AVI, MKV)")
        photos += [q for q in found if q.resolve() not in {r.resolve() for r in photos}]
    return photos, missing


def is_input(path: Path) -> bool:
    """A photo or a clip, by its name."""
    from viewer.files.clip_reader import is_clip

    return is_photo(path) or is_clip(path)


def is_photo(path: Path) -> bool:
    name = path.name.lower()
    return path.suffix.lower() in PHOTO_SUFFIXES and not name.endswith((".mask.png", "-mask.png"))


@dataclass(frozen=True)
class LookSpec:
    """One look of the batch: where the lights come from (a map, a light file, or a plate's own light),
    the yaw ("auto": as ``relight render`` starts, viewer.lighting.map_lights.start_yaw), the rig
    added, the preset."""

    name: str
    envmap: Path | None
    lights_file: Path | None
    yaw: float | str
    rig: Path | None
    preset: str | None
    plate: Path | None = None  # a plate look: the person put into this photo, lit by its light (docs/plates.md)


@dataclass
class Item:
    """One photo or clip under one look, and what it writes."""

    photo: Path  # a photo, or a clip (viewer.files.clip_reader.is_clip)
    look: LookSpec
    name: str  # "<photo>/<look>": the outputs' stem under the batch folder
    outputs: tuple[Path, ...] = ()
    key: str = ""
    settings: dict = field(default_factory=dict)


def look_specs(envmaps, light_files, yaws, rigs, presets, plates=()) -> list[LookSpec]:
    """Every look: (maps, then light files, then plates) x yaws x rigs (or none) x presets (or the
    default), named by what varies: ``<map>`` (a plate's: ``on_<plate>``), ``_y<yaw>`` when yaws were
    given, ``_<rig>``, ``_<preset>``."""
    sources = [(Path(m), None, None) for m in envmaps] + [(None, Path(f), None) for f in light_files] \
        + [(None, None, Path(q)) for q in plates]
    names_used: dict[str, int] = {}
    looks = []
    for envmap, lights_file, plate in sources:
        for yaw in (yaws or ["auto"]):
            for rig in (rigs or [None]):
                for preset in (presets or [None]):
                    stem = folder_name((envmap or lights_file).name.split(".")[0], "look") if plate is None \
                        else "on_" + folder_name(plate.name.split(".")[0], "plate")
                    name = stem + (f"_y{_yaw_text(yaw)}" if yaws else "") + (f"_{Path(rig).stem}" if rig else "") \
                        + (f"_{preset}" if preset else "")
                    base, count = name, 1
                    while name in names_used:  # two maps of one name in different folders (or x and x-2)
                        count += 1
                        name = f"{base}-{count}"
                    names_used[name] = 1
                    looks.append(LookSpec(name, envmap, lights_file, yaw, Path(rig) if rig else None, preset, plate))
    return looks


def _yaw_text(yaw) -> str:
    return "auto" if yaw == "auto" else f"{float(yaw):g}"


def folder_name(stem: str, empty: str = "photo") -> str:
    """A stem as a name inside the batch's folder: never ``.``, ``..`` or hidden (a photo named
    ``...jpg`` wrote into the output's parent), never empty (``empty`` then)."""
    name = stem.lstrip(".")
    return name if name else empty


def photo_names(photos: list[Path], reserved: tuple = ()) -> dict[Path, str]:
    """A folder name per photo: its stem (:func:`folder_name`; a name of ``reserved``, the batch's own
    files, with ``-photo`` after it), or that and a short hash of its path where two photos share it."""
    names = {p: folder_name(p.stem) for p in photos}
    names = {p: f"{n}-photo" if n in reserved else n for p, n in names.items()}
    counts: dict[str, int] = {}
    for n in names.values():
        counts[n] = counts.get(n, 0) + 1
    return {p: n if counts[n] == 1 else f"{n}-{hashlib.sha256(str(p.resolve()).encode()).hexdigest()[:6]}"
            for p, n in names.items()}


def item_key(photo_key: str, source_sha: str, rig_sha: str, lights: np.ndarray, settings: dict) -> str:
    """The content hash an item's outputs are made from: its photo's bundle key (the photo's bytes,
    the networks, the pipeline: viewer.photo.bundle_version.bundle_key), the map's or light file's bytes,
    the rig's, the lights themselves (the fit's method and count), the look and the options, and
    this code's key version."""
    from viewer.photo.bundle_version import PIPELINE

    h = hashlib.sha256()
    h.update(json.dumps({"photo": photo_key, "source": source_sha, "rig": rig_sha, "settings": settings,
                         "version": [KEY_VERSION, PIPELINE]}, sort_keys=True).encode())
    h.update(np.ascontiguousarray(lights, np.float32).tobytes())
    return h.hexdigest()


def clip_bundle_key(digest: str, max_size: int, version: str) -> str:
    """What a batch's clip bundle is made from: the clip's bytes (``digest``), the whole clip inferred
    as one (temporal on) at ``max_size``, the inference ``version``."""
    from viewer.photo.clip_cache import ClipRequest, clip_key

    return clip_key(digest, ClipRequest(max_size=max_size).options(), version)


def cache_path(clip: Path, bundles, max_size: int, digest: str) -> Path:
    """Where a batch keeps the bundle of ``clip`` (in the cache's ``bundles`` folder): the one
    ``relight render CLIP`` makes with the same options (:func:`clip_bundle_key`)."""
    from viewer.photo.clip_cache import ClipRequest, cached_clip_path

    return cached_clip_path(clip, bundles, ClipRequest(max_size=max_size), digest)


def check_sources(looks: list[LookSpec]) -> None:
    """Every rig and light file named exists (a bad map fails its own items later, not the batch)."""
    for look in looks:
        for path in (look.rig, look.lights_file, look.plate):
            if path is not None and not path.is_file():
                raise InputError(path, "not found")
