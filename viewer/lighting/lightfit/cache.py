"""Fitted lights cached by map content, so the viewer never fits the same map twice.

A cache entry is a light file (``viewer.scene.area_lights`` JSON, with a ``fit`` record of the source map,
method, N and fitting time) named ``<hash>-n<N>-<method>-v<FIT_VERSION>.json``, the hash being the
SHA-256 of the decoded map (shape and float32 pixels: the same map saved as .hdr or .exr, or under
another name, hits the same entry; a map edited by one pixel does not). The directory is
``$RELIGHT_CACHE`` if set, else ``$XDG_CACHE_HOME/relight/lights``, else ``~/.cache/relight/lights``.

Entries are written to a temporary file in the same directory and renamed into place, so an
interrupted fit (Ctrl-C) or a crash never leaves a partial entry; a corrupt entry is refitted.
"""

from __future__ import annotations

import hashlib
import os
import time
import warnings
from pathlib import Path

import numpy as np

from viewer.errors import InputError
from viewer.lighting.envmap import EnvMap
from viewer.lighting.lightfit.methods import DEFAULT_METHOD
from viewer.scene.area_lights import AreaLights, load_lights

FIT_VERSION = 2  # bump when a change to the fitters changes their results


def fit_record(source, method: str, n: int, env: EnvMap | None = None, **more) -> dict:
    """What a light file says of its fit (its ``fit``): the map's file name, the hash of the map's
    content (``map``, :func:`map_hash` of ``env``), the method, the count and the fitters' version (a
    light file beside a map serves a request only for that very map and from the current fitters,
    :func:`viewer.lighting.map_lights.sidecar_lights`), and ``more``."""
    return {"source": Path(source).name if source else None, **({"map": map_hash(env)} if env is not None else {}),
            "method": method, "n": n, **more, "version": FIT_VERSION}


def cache_dir() -> Path:
    """The lights' cache folder (absolute: ``RELIGHT_CACHE=.`` is the working folder); the file system's root is
    refused in one line (the bundles' cache goes beside it, :func:`bundles_dir`, and a root has no beside)."""
    if os.environ.get("RELIGHT_CACHE"):
        path = Path(os.environ["RELIGHT_CACHE"]).expanduser().absolute()
        if path.parent == path:
            raise InputError(path, "RELIGHT_CACHE names the file system's root: give relight's cache a folder of its own")
        return path
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base).absolute() / "relight" / "lights"


def bundles_dir() -> Path:
    """Where inferred bundles are cached: ``bundles`` beside the lights' cache folder (:func:`cache_dir`)."""
    return cache_dir().with_name("bundles")


def map_hash(env: EnvMap) -> str:
    h = hashlib.sha256()
    h.update(np.asarray(env.pixels.shape, dtype=np.int64).tobytes())
    h.update(np.ascontiguousarray(env.pixels, dtype=np.float32).tobytes())
    return h.hexdigest()[:24]


def cache_path(env: EnvMap, n: int, method: str, directory=None) -> Path:
    return Path(directory or cache_dir()) / f"{map_hash(env)}-n{n}-{method}-v{FIT_VERSION}.json"


def cached_lights(env: EnvMap, n: int, method: str, directory=None) -> AreaLights | None:
    """The lights of ``env`` in the cache, or None (none there, or a corrupt entry: warned)."""
    path = cache_path(env, n, method, directory)
    if not path.is_file():
        return None
    try:
        return load_lights(path)
    except InputError as exc:
        warnings.warn(f"ignoring a corrupt cache entry ({exc}); fitting again", stacklevel=3)
        return None


def lights_for_map(env: EnvMap, n: int = 16, method: str = DEFAULT_METHOD, directory=None, progress=None,
                   refit: bool = False, timing: dict | None = None) -> tuple[AreaLights, bool]:
    """The fitted lights of ``env`` and whether they came from the cache (else they are fitted now);
    ``timing``, when given, gets the fit's own seconds (``"fit"``: torch's import left out)."""
    path = cache_path(env, n, method, directory)
    usable = not path.exists() or path.is_file()
    if not usable:
        warnings.warn(f"{path}: the cache entry is not a file; fitting without the cache (remove it to cache again)", stacklevel=2)
    cached = None if refit else cached_lights(env, n, method, directory)
    if cached is not None:
        return cached, True
    from viewer.lighting.lightfit.fit import fit_lights  # torch: imported only when fitting

    start = time.perf_counter()
    lights = fit_lights(env, n, method, progress=progress)
    record = fit_record(env.source, method, n, env, seconds=round(time.perf_counter() - start, 3))
    if timing is not None:
        timing["fit"] = record["seconds"]
    if usable:
        try:
            lights.save(path, fit=record)
        except OSError as exc:  # a read-only cache costs the next run a refit, nothing more
            warnings.warn(f"{path}: cannot cache the lights ({exc.strerror or exc})", stacklevel=2)
    return lights, False
