"""Where a map's area lights come from: the one rule the command line and the window share.

In order: a light file the user gave; the lights shipped beside the map (``MAP.lights.json``, as
the bundled maps have) when they were fitted to that very map (its content's hash), for the same count by the method asked or one at
least as accurate; the fitting cache; a fit now (the caller's: in process with progress bars on
the command line, in a niced child process in the window).

Where a look's lights come from also decides the yaw it starts with (:func:`start_yaw`): a map's are
turned with the map behind to face the camera; the plate's own light and the lights the user placed
stay as they are.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from viewer.errors import InputError
from viewer.files.imageio import read_json
from viewer.lighting.envmap import EnvMap
from viewer.lighting.lightfit.cache import FIT_VERSION, cached_lights, map_hash
from viewer.lighting.lightfit.methods import serves
from viewer.scene.area_lights import AreaLights, facing_yaw, load_lights

LIGHTS_SUFFIX = ".lights.json"  # a map's lights beside it: MAP.lights.json
MAP, PLATE, PLACED = "map", "plate", "placed"  # where a look's lights come from (lights_source, start_yaw)


def lights_beside(map_path) -> Path:
    """Where a map's lights are kept beside it (``MAP.lights.json``)."""
    return Path(map_path).with_suffix(LIGHTS_SUFFIX)


def sidecar_lights(env: EnvMap, env_path: Path, n: int, method: str) -> AreaLights | None:
    """Lights shipped beside a map (``<map>.lights.json``) when they were fitted to this very map
    (the hash of ``env``'s content in their fit record: a map replaced or edited since, or another
    map of the same name and another suffix, is not served by them), for the same count, by the
    method asked or one at least as accurate (:func:`viewer.lighting.lightfit.methods.serves`), by
    the fitters' current version (``FIT_VERSION``; a file without one is version 1)."""
    side = lights_beside(env_path)
    if not side.is_file():
        return None
    try:
        fit = read_json(side, "light file").get("fit") or {}
    except (InputError, AttributeError):
        return None
    if fit.get("map") != map_hash(env):
        return None  # fitted to another map, or the map changed since
    if fit.get("n") != n or not serves(str(fit.get("method")), method) or fit.get("version", 1) != FIT_VERSION:
        return None  # another count or method, or fitted before the fitters last changed
    try:
        return load_lights(side)
    except InputError:
        return None


def map_lights(env: EnvMap, env_path, n: int, method: str,
               fit: Callable[[EnvMap], tuple[AreaLights, bool]]) -> tuple[AreaLights, str]:
    """The lights of the map ``env`` (read from ``env_path``) and where they came from: "bundled"
    (beside the map), "cached" or "fitted" (``fit(env)`` returns the lights and whether they came
    from the cache after all: another process may have fitted them meanwhile)."""
    side = sidecar_lights(env, env_path, n, method)
    if side is not None:
        return side, "bundled"
    cached = cached_lights(env, n, method)  # a corrupt entry: warned, and fitted again
    if cached is not None:
        return cached, "cached"
    lights, was_cached = fit(env)
    return lights, "cached" if was_cached else "fitted"


def lights_source(light_file=None, plate: bool = False) -> str:
    """Where a look's lights come from: PLATE, the plate's own light (``plate``); MAP, a map's (no
    ``light_file``: found for the map by :func:`map_lights`; or a light file fitted to a map, whose fit
    record names the map's content, as ``relight fit-lights`` writes it and the lights shipped beside a
    map have it); PLACED, the user's own (any other light file: written by hand, a scene bundle's lights
    of its own photo, the paper's .npy)."""
    if plate:
        return PLATE
    if light_file is None:
        return MAP
    data = None if Path(light_file).suffix.lower() == ".npy" else read_json(light_file, "light file")
    fit = data.get("fit") if isinstance(data, dict) else None
    return MAP if isinstance(fit, dict) and "map" in fit else PLACED


def start_yaw(lights: AreaLights, source: str) -> float:
    """The yaw a look starts with when none is given (``--yaw``, a saved look), by where its ``lights``
    come from (:func:`lights_source`): a map's are turned with the map behind so that their brightest
    light falls on the camera's side (:func:`viewer.scene.area_lights.facing_yaw`: a photo is not lit
    from behind); the plate's own light stays as its camera saw it and the user's own lights where
    they were put (0). A rig's lights and those placed in the window are fixed to the camera: no yaw
    turns them."""
    return facing_yaw(lights) if source == MAP else 0.0
