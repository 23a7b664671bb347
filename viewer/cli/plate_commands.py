"""The plate commands: ``relight plate-light PLATE -o MAP.exr`` (the light read from a background photo,
as an HDR map, :mod:`viewer.plate.environment`, to inspect, edit and use as any map) and ``relight
render BUNDLE --plate PLATE -o OUT.png`` (the person relit by that light and composited into the
plate, standing on its ground with their shadow: :mod:`viewer.output.plate_composite`)."""

from __future__ import annotations

import json
import math
import time
import warnings
from pathlib import Path

import numpy as np

from viewer.cli.output_paths import not_an_input, writable
from viewer.errors import InputError
from viewer.files.ownership import refuse_foreign

MIN_MAP_HEIGHT, MAX_MAP_HEIGHT = 8, 4096  # plate-light's --height: a map of 16x8 to 8192x4096


def cmd_plate_light(args) -> int:
    """``relight plate-light``: one run at a time writes an output (:mod:`viewer.files.output_lock`)."""
    from viewer.files.output_lock import ExclusiveLock

    with ExclusiveLock(writable(Path(args.output))):
        return _plate_light(args)


def _plate_light(args) -> int:
    from viewer.lighting.dominant import map_dominant_light
    from viewer.lighting.envmap import save_envmap
    from viewer.plate.environment import plate_light
    from viewer.plate.horizon import horizon_tilt, plate_horizon
    from viewer.plate.loader import read_plate

    out = Path(args.output)
    if out.suffix.lower() != ".exr":
        raise InputError(out, "the plate's light is written as an OpenEXR map: give a .exr output path")
    writable(out)
    not_an_input([out], [args.plate])
    refuse_foreign([out], args.force)
    if not MIN_MAP_HEIGHT <= args.height <= MAX_MAP_HEIGHT:
        raise InputError(None, f"--height is the map's height in pixels, from {MIN_MAP_HEIGHT} to {MAX_MAP_HEIGHT}; got {args.height}")
    notes: list = []
    start = time.perf_counter()
    plate = read_plate(args.plate, notes)
    horizon = plate_horizon(plate)[0]
    env, record = plate_light(plate, args.height, horizon=horizon)
    # where the light comes from: the map's brightest direction and the share near it (no fit to wait for),
    # levelled by the camera's tilt its horizon gives
    pitch = math.degrees(horizon_tilt(horizon, plate.size[1], plate.focal_px))
    found, said = map_dominant_light(env.pixels, pitch)
    notes += [record["sun"], said]
    seconds = time.perf_counter() - start
    save_envmap(out, env)
    record["dominant_light"] = None if found is None else dict(zip(("azimuth_deg", "elevation_deg", "share"), found))
    for note in notes:
        print(f"note: {note}")
    print(f"{out}: the light of {args.plate} ({plate.size[0]}x{plate.size[1]}, {record['focal_35mm']:g} mm from "
          f"{record['focal_from']}, {record['field_of_view_deg']:.0f} degrees across), {env.width}x{env.height}, "
          f"in {seconds:.2f} s")
    if args.record:
        print(json.dumps(record))
    return 0


def at_option(text: str | None) -> tuple[float, float] | None:
    """``--at X,Y``: two numbers (fractions of the plate's width and height)."""
    if text is None:
        return None
    try:
        x, y = (float(v) for v in str(text).split(","))
    except ValueError:
        raise InputError(None, f"--at takes X,Y (the feet, fractions of the plate's width and height), got {text!r}") from None
    return x, y


def plate_place(plate, args, notes: list | None = None) -> tuple[list[float], float]:
    """Where the person stands on ``plate`` by ``--at``, ``--height`` and ``--horizon`` of ``args``
    (:func:`viewer.plate.placement.place_on_plate`): ([x, y, height], the horizon)."""
    from viewer.plate.placement import place_on_plate

    place, horizon = place_on_plate(plate, at_option(args.at), args.height, args.horizon, notes)
    return [place.x, place.y, place.height], horizon


def cmd_render_plate(args, look) -> int:
    """``relight render BUNDLE --plate PLATE -o OUT.png``: the person relit by the plate's light (or
    ``--env``'s) and composited into it, standing on its ground with their shadow; OUT.exr beside it
    (linear; with ``--layers``, the person and the shadow as layers too)."""
    from viewer.cli.command_setup import engine_options, first_look, fitted_lights, lights_count, prepare, rig_lights
    from viewer.gl import Engine, create_headless_context
    from viewer.lighting.map_lights import PLATE
    from viewer.output.plate_render import plate_look, render_on_plate
    from viewer.plate.environment import plate_light
    from viewer.plate.loader import read_plate
    from viewer.plate.placement import Placement, PlateSpot, person_lens_mismatch
    from viewer.scene.look import AUTO
    from viewer.scene.resampling import load_sized_scene

    out = Path(args.output)
    if out.suffix.lower() != ".png":
        raise InputError(out, "a composite onto a plate is a picture: give a .png output path (its EXR goes beside it)")
    writable(out)
    outputs = [out, out.with_suffix(".exr")]
    not_an_input(outputs, [args.scene, args.plate, args.envmap, args.lights, args.front])
    refuse_foreign(outputs, args.force)
    at_option(args.at)  # a malformed --at is one line before any work
    notes: list = []
    start = time.perf_counter()  # the plate read, its light, the render and the composite: process start excluded
    plate = read_plate(args.plate, notes, args.front)
    place, horizon = plate_place(plate, args, notes)
    place = Placement(*place)
    own = args.envmap or args.lights
    auto = 0.0  # the exposure unless given: the plate's units under its own light
    if own:  # the user's own light; the plate only the backdrop, and its light the level
        scene, lights, pixels, look = prepare(args.scene, args.lights, args.envmap, args, look, automatic_yaw=True)
        if look.exposure == AUTO:
            auto = own_light_exposure(plate_light(plate, horizon=horizon)[0], scene, lights, pixels, look)
        light_from = f"{own}" + (f", exposed {auto:+.2f} stops to the plate's light" if look.exposure == AUTO else "")
    else:  # the plate's light, in its camera's frame (--yaw turns it as any map's)
        scene = load_sized_scene(args.scene, getattr(args, "size", None), getattr(args, "max_size", None))
        env, record = plate_light(plate, horizon=horizon)
        notes.append(record["sun"])
        lights, _ = fitted_lights(env, lights_count(args, look), args.method)
        look = first_look(args, look, lights, PLATE)
        light_from = f"the plate ({record['field_of_view_deg']:.0f} degrees seen, the rest filled)"
    lens = person_lens_mismatch(scene.frame, place, plate)
    if lens:
        warnings.warn(f"{plate.source}: {lens}", stacklevel=2)
    engine = Engine(create_headless_context(), scene, engine_options(args, look))
    try:
        spot = PlateSpot(plate, place, horizon, args.scene, cut_allowed=args.height is not None)
        matched = render_on_plate(engine, scene, lights, plate_look(look, auto), spot, out, outputs[1],
                                  layers_in_exr=args.layers, fixed=rig_lights(args))
    finally:
        engine.release()
    seconds = time.perf_counter() - start
    for note in notes:
        print(f"note: {note}")
    print(f"wrote {out} and {out.with_suffix('.exr')} ({plate.size[0]}x{plate.size[1]}; lit by {light_from}; the feet at "
          f"{place.x:g},{place.y:g}, {place.height:.2f} of the plate's height; the plate's defocus there "
          f"{matched['defocus_px']:.1f} px and grain {np.mean(matched['grain_levels']):.1f} levels given to the person; "
          f"{seconds:.1f} s)")
    return 0


def own_light_exposure(plate_env, scene, lights, pixels, look) -> float:
    """The stops that give a person lit by the user's map (``pixels``, else ``lights``, a light file's)
    the diffuse light the plate's own light (``plate_env``) gives them (:mod:`viewer.plate.exposure`)."""
    from viewer.lighting.envmap import EnvMap
    from viewer.plate.exposure import person_exposure

    return person_exposure(plate_env, EnvMap(pixels) if pixels is not None else lights, scene, look)


def view_plate(args, notes: list) -> tuple[tuple, Path | None]:
    """``relight view ... --plate PLATE``: :func:`viewer.app.plate_view.plate_setting` of the options."""
    from viewer.app.plate_view import plate_setting

    return plate_setting(args.plate, at_option(args.at), args.height, args.horizon, args.envmap or args.lights, notes,
                         front=args.front)
