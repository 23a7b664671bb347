"""How a command's options become what it works on: the look (a saved one and the options given),
the engine's options and the lights' count (the look's preset and the knobs given), the scene
resampled as asked, and its lights by the one rule of :mod:`viewer.lighting.map_lights`."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from viewer.errors import InputError
from viewer.scene.resampling import load_sized_scene


def engine_options(args, look):
    """The look's preset's engine options with the knobs given on the command line in place of its values."""
    from dataclasses import replace

    from viewer.gl.presets import DEFAULT_PRESET, preset

    given = {k: getattr(args, k) for k in ("soft", "shadow_resolution", "shadow_step", "terms", "prefilter") if getattr(args,
                                                                                                                        k) is not None}
    try:
        return replace(preset(look.preset or DEFAULT_PRESET).options, **given)
    except InputError as exc:  # name the option
        option = next((f"--{k.replace('_', '-')}" for k in given if k.split("_")[-1] in exc.problem), None)
        raise InputError(None, f"{option}: {exc.problem}" if option else exc.problem) from None


def lights_count(args, look) -> int:
    """``-n``, or the look's preset's count."""
    from viewer.gl.presets import DEFAULT_PRESET, preset

    if args.lights_count is None:
        return preset(look.preset or DEFAULT_PRESET).lights
    return light_count_option(args.lights_count, args.method)


def light_count_option(n: int, method: str) -> int:
    """``-n``, checked before a map is read: the engine's limit, and the method's."""
    from viewer.lighting.lightfit.methods import check_light_count
    from viewer.scene.area_lights import MAX_LIGHTS

    if not 1 <= n <= MAX_LIGHTS:
        raise InputError(None, f"-n: the number of lights must be in [1, {MAX_LIGHTS}], got {n}")
    check_light_count(method, n)
    return n


def fitted_lights(env, n, method, refit=False, timing: dict | None = None):
    """Lights of ``env`` from the cache, or fitted now with a progress bar (a black map is reported
    by the caller on every run, cached or not: the fitter's own warning is left out); ``timing``:
    :func:`viewer.lighting.lightfit.cache.lights_for_map`'s."""
    import warnings

    from viewer.lighting.lightfit import lights_for_map
    from viewer.lighting.lightfit.methods import STAGE_SHARES
    from viewer.progress import StageBars

    name = Path(env.source).name if env.source else "the map"
    with StageBars(prefix=f"fitting {n} lights to {name}: ",
                   shares=STAGE_SHARES.get(method)) as bars, warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*the map is black")
        lights, cached = lights_for_map(env, n, method, progress=bars, refit=refit, timing=timing)
    return lights, cached


def prepare(scene_path, lights_path, envmap_path, args, look, automatic_yaw: bool = False):
    """Scene (resampled to ``--size``), lights (a file, or the map's by the one rule), map pixels
    and the look (``automatic_yaw``: its yaw chosen by :func:`first_look` for where these lights came from)."""
    from viewer.lighting.envmap import load_envmap
    from viewer.lighting.map_lights import lights_source

    scene = load_sized_scene(scene_path, getattr(args, "size", None), getattr(args, "max_size", None))
    env = load_envmap(envmap_path, repair=getattr(args, "repair", False)) if envmap_path else None
    if lights_path is None and env is None:
        raise InputError(None, "give a light file or an environment map (--env) to fit lights to")
    lights = command_lights(args, look, lights_path, env, envmap_path)
    if automatic_yaw:
        look = first_look(args, look, lights, lights_source(lights_path))
    return scene, lights, (env.pixels if env is not None else None), look


def command_lights(args, look, lights_path, env, env_path):
    """The light file given, or the map's lights by the one rule (:mod:`viewer.lighting.map_lights`), the
    fit in this process with its progress bars; said on a line when they come from the map, and a floor
    laid under a map with no ground said on another (:mod:`viewer.lighting.floor`)."""
    from viewer.lighting.map_lights import map_lights
    from viewer.scene.area_lights import load_lights

    if lights_path is not None:
        lights = load_lights(lights_path)
    else:
        n = lights_count(args, look)
        lights, how = map_lights(env, env_path, n, args.method, lambda e: fitted_lights(e, n, args.method))
        print(f"{len(lights)} lights for {env_path}: {HOW[how]}")
    warn_if_dark(lights, lights_path or env_path)
    if env is not None and look.background == "environment":  # (behind the person only: another background shows none)
        from viewer.lighting.floor import floor_note

        note = floor_note(env.pixels)  # (the engine lays it behind the person: viewer.gl.look_state)
        if note:
            print(f"note: {env_path}: {note}")
    return lights


HOW = {"bundled": "those shipped beside the map", "cached": "from the cache", "fitted": "fitted now"}


def warn_if_dark(lights, source):
    """Every run with lights that give no light says so (a black map's lights come from the cache too)."""
    if not np.any(lights.intensity > 0):
        print(f"relight: warning: {source}: every light has zero intensity, so the person renders black "
              "(is the map black?)", file=sys.stderr, flush=True)


# the look's fields and the options that set them (each default None: given or not)
LOOK_OPTIONS = (("yaw", "yaw"), ("tilt", "tilt"), ("exposure", "exposure"), ("tonemap", "tonemap"),
                ("background", "background"), ("shadows", "visibility"), ("preset", "preset"),
                ("ground", "ground"), ("backdrop_blur", "backdrop_blur"), ("skin", "skin"))


def command_look(args, yaw_default: float = 0.0):
    """The look of a command: a saved one (``--look FILE``: a frame saved by the viewer, its state
    file, or a bare look object, whose missing fields are the command's defaults) or the defaults,
    with every option given on the command line in its place (the preset among them: what the
    engine options and the lights' count follow)."""
    from viewer.scene.look import AUTO, Look

    base = Look(yaw=yaw_default, exposure=AUTO)
    base = read_look(args.look, base) if getattr(args, "look", None) else base
    given = {field: getattr(args, option) for field, option in LOOK_OPTIONS if getattr(args, option, None) is not None}
    try:
        look = base.replace(**given)
    except InputError as exc:  # name the option, not the field
        option = next((o for f, o in LOOK_OPTIONS if exc.problem.startswith(f.replace("tonemap", "tone map"))), None)
        raise InputError(None, f"--{option}: {exc.problem}" if option else exc.problem) from None
    return look


def look_fields(path):
    """The look's object in a JSON file (``{"look": {...}}`` as the viewer saves it, or the look itself)."""
    from viewer.files.imageio import read_json

    data = read_json(path, "JSON look file")
    return data.get("look", data) if isinstance(data, dict) else data


def read_look(path, base=None):
    """The look in a JSON file (:func:`look_fields`), the fields it lacks ``base``'s."""
    from viewer.scene.look import Look

    return Look.from_json(look_fields(path), where=path, base=base)


def rig_lights(args):
    """The placed lights of ``--rig`` as area lights (fixed to the camera), or None."""
    from viewer.lighting.placed_lights import load_rig, to_area_lights

    return to_area_lights(load_rig(args.rig)) if getattr(args, "rig", None) else None


def first_look(args, look, lights, source: str):
    """The look of ``render`` and ``view`` (a photo's, a clip's, on a plate; ``batch``'s yaw "auto" is
    the same rule): unless a yaw was given (``--yaw``, or a saved ``--look`` that holds one), the yaw
    that lights from ``source`` start with (:func:`viewer.lighting.map_lights.start_yaw`: a map's
    brightest light on the camera's side, the user's own lights and a plate's own light as they are)."""
    from viewer.lighting.map_lights import start_yaw

    saved = getattr(args, "look", None)
    if args.yaw is not None or (saved and "yaw" in look_fields(saved)):
        return look
    return look.replace(yaw=start_yaw(lights, source))


def gl_threads() -> int:
    """llvmpipe's threads in this process (sized at the start, viewer/cores.py; a user's own value kept)."""
    import os

    try:
        return max(int(os.environ.get("LP_NUM_THREADS", "2")), 1)
    except ValueError:
        return 2
