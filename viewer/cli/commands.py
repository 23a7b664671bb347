"""The ``relight`` commands: each parses nothing and decides little; it checks its outputs, sets
up its work (:mod:`viewer.cli.command_setup`) and calls the module that does it."""

from __future__ import annotations

import contextlib
import time
from pathlib import Path

import numpy as np

from viewer.cli.command_setup import (
    command_lights,
    command_look,
    engine_options,
    fitted_lights,
    light_count_option,
    prepare,
    rig_lights,
    warn_if_dark,
)
from viewer.cli.output_paths import beside_the_map, check_video, not_a_clip_range, not_an_input, writable
from viewer.errors import InputError
from viewer.files.ownership import file_is_ours, refuse_foreign
from viewer.output.video import partial_path as video_partial, partial_taken
from viewer.resources import asset_dir, sample_scene_dir
from viewer.scene.resampling import load_sized_scene

DEMO_ENVMAP = "envmaps/immenstadter_horn_256.hdr"
DEMO_LIGHTS = "envmaps/immenstadter_horn_256.lights.json"
DEMO_PHOTO = "photos/underpass.jpg"
DEMO_YAW = 180.0  # the map's sun is behind the figure at yaw 0; turned, it lights the front


def render_files(scene_path, lights_path, envmap_path, out_dir, name, args, look, png_name=None,
                 automatic_yaw: bool = False) -> list[Path]:
    from viewer.gl import Engine, create_headless_context
    from viewer.output.render import render_to_files

    scene, lights, env, look = prepare(scene_path, lights_path, envmap_path, args, look, automatic_yaw)
    engine = Engine(create_headless_context(), scene, engine_options(args, look))
    try:
        return render_to_files(engine, scene, lights, out_dir, name, look, environment=env, fixed=rig_lights(args),
                               png_name=png_name)
    finally:
        engine.release()


def cmd_demo(args) -> int:
    """The whole path: the sample scene, then the bundled real photo inferred (automatic mask),
    relit at its own size under the three bundled maps with refined shadows, and a sheet of the
    photo beside its relightings."""
    from dataclasses import replace

    from viewer.files.imageio import read_png, write_png
    from viewer.gl import Engine, create_headless_context
    from viewer.lighting.envmap import load_envmap
    from viewer.output.render import render_to_files
    from viewer.photo.frames import read_photo
    from viewer.photo.inference import infer
    from viewer.resize import resize

    assets = asset_dir()
    look = command_look(args, DEMO_YAW)
    writable(args.output, folder=True)
    written = render_files(sample_scene_dir(), assets / DEMO_LIGHTS, assets / DEMO_ENVMAP, args.output, "demo", args, look)
    print(f"rendered the sample scene under {DEMO_LIGHTS} (16 area lights):")
    for path in written:
        print(f"  wrote {path}")
    out = Path(args.output)
    photo = assets / DEMO_PHOTO
    t0 = time.perf_counter()
    ctx = create_headless_context()
    infer(photo, None, out / "photo_bundle", max_size=args.max_size, ctx=ctx)
    print(f"inferred the scene bundle of {DEMO_PHOTO} (automatic mask) in {time.perf_counter() - t0:.1f} s: "
          f"{out / 'photo_bundle'}")
    scene = load_sized_scene(out / "photo_bundle", None, args.max_size)
    engine = Engine(ctx, scene, engine_options(args, look))
    pictures = [resize(read_photo(photo, []), scene.output_size).astype(np.float32) / 255.0]  # upright, the output's size
    settings = replace(look, shadows="refined", background="environment")
    try:
        for env_path in sorted((assets / "envmaps").glob("*.hdr")):
            t0 = time.perf_counter()
            env = load_envmap(env_path)
            lights = command_lights(args, settings, None, env, env_path)  # those shipped beside each map
            files = render_to_files(engine, scene, lights, out, f"photo_{env_path.stem}", settings, environment=env.pixels,
                                    passes=False)
            pictures.append(read_png(files[0])[..., :3])
            print(f"  relit under {env_path.name} (refined shadows), {scene.output_size[0]}x{scene.output_size[1]}, "
                  f"in {time.perf_counter() - t0:.1f} s: {files[0]}")
    finally:
        engine.release()
    sheet = write_png(out / "photo_relit.png", np.concatenate(pictures, axis=1))
    print(f"wrote {sheet} (the photo, then relit under each bundled map)")
    return 0


def plate_options_need_a_plate(args):
    """One line for --at, --height, --horizon or --front given without --plate."""
    if not args.plate:
        for option in ("at", "height", "horizon", "front"):
            if getattr(args, option, None) is not None:
                what = "marks what stands in front of the person on a plate" if option == "front" else "places the person on a plate"
                raise InputError(None, f"--{option} {what}: give --plate PHOTO")


def cmd_render(args) -> int:
    """``relight render``: one run at a time writes an output (:mod:`viewer.files.output_lock`), held from before
    the first check of what is there to the last file written: every file it writes, so that another render's
    ``-o`` that is one of them (``x_passes.png`` beside ``x.png``, a video's ``x.partial.mp4``) is refused too."""
    from viewer.files.output_lock import ExclusiveLock

    out = writable(args.output)
    with contextlib.ExitStack() as held:
        for path in rendered_files(out):
            held.enter_context(ExclusiveLock(path))
        return _render(args)


def rendered_files(out: Path) -> list[Path]:
    """The files ``relight render -o out`` writes: a frame's PNG, its EXR and passes sheet; a video and its partial."""
    if out.suffix.lower() == ".mp4":
        return [out, video_partial(out)]
    return [out, out.with_suffix(".exr"), out.with_name(f"{out.stem}_passes.png")]


def _render(args) -> int:
    from viewer.files.clip_reader import is_clip
    from viewer.scene.clip_bundle import is_clip_bundle

    look = command_look(args)
    plate_options_need_a_plate(args)
    if is_clip(args.scene) or is_clip_bundle(args.scene):
        from viewer.cli.clip_render_command import cmd_render_clip

        check_video(args)
        return cmd_render_clip(args, look)
    not_a_clip_range(args, args.scene)
    if args.ray or args.workers is not None:
        raise InputError(args.scene, "--ray and --workers spread a clip's frames over workers: this is not a clip "
                                     "(relight batch --ray spreads photos)")
    if args.plate:
        from viewer.cli.plate_commands import cmd_render_plate

        return cmd_render_plate(args, look)
    if args.layers or args.per_light:
        raise InputError(None, "--layers writes a clip's layers (an EXR sequence): for a photo's, use relight batch --layers")
    out = Path(args.output)
    suffix = out.suffix.lower()
    if suffix not in (".png", ".mp4"):
        raise InputError(out, "give a .png path for one frame (the EXR goes beside it) or a .mp4 path for a turntable video")
    writable(out)
    outputs = [out] if suffix == ".mp4" else rendered_files(out)
    not_an_input(outputs + ([video_partial(out)] if suffix == ".mp4" else []), [args.scene, args.lights, args.envmap, args.look,
                                                                                getattr(args, "rig", None)])
    refuse_foreign(outputs, args.force)
    if suffix == ".mp4":
        check_video(args)
        if look.background == "transparent":  # H.264 has no alpha: it came out black (the option or a --look)
            raise InputError(out, "an MP4 (H.264) holds no transparency: render a PNG (and its EXR) with "
                                  "--background transparent, or give the video another --background")
        if video_partial(out).exists():
            raise partial_taken(out)
    if suffix == ".png":
        if args.frames is not None:
            raise InputError(out, "--frames makes a video: give a .mp4 output path")
        for path in render_files(args.scene, args.lights, args.envmap, out.parent, out.stem, args, look, png_name=out.name,
                                 automatic_yaw=True):
            print(f"wrote {path}")
        return 0

    from tqdm import tqdm

    from viewer.gl import Engine, create_headless_context
    from viewer.output.render import render_turntable

    frames = 120 if args.frames is None else args.frames
    turn = 360.0 if args.turn is None else args.turn
    scene, lights, env, look = prepare(args.scene, args.lights, args.envmap, args, look, automatic_yaw=True)
    engine = Engine(create_headless_context(), scene, engine_options(args, look))
    start = time.perf_counter()
    try:
        with tqdm(total=frames, unit="frame", desc=f"rendering {out.name}", leave=False) as bar:
            width, height = render_turntable(engine, lights, out, look, frames, fps=args.fps, turn=turn,
                                             environment=env, progress=lambda done, total: bar.update(1),
                                             fixed=rig_lights(args))
    finally:
        engine.release()
    seconds = time.perf_counter() - start
    print(f"wrote {out} ({frames} frames, {width}x{height}, {args.fps:g} fps, "
          f"{turn:g} degrees; {seconds:.1f} s, {1000 * seconds / frames:.0f} ms per frame)")
    return 0


def cmd_infer(args) -> int:
    from viewer.files.clip_reader import is_clip
    from viewer.files.kinds import regular_file
    from viewer.photo.frames import check_photo_file

    if is_clip(args.photo):
        from viewer.cli.clip_commands import cmd_infer_clip

        return cmd_infer_clip(args)
    not_a_clip_range(args, args.photo)
    check_photo_file(args.photo)  # before torch is loaded: a wrong file is one line at once
    if args.mask is not None:
        regular_file(args.mask, "mask")
    from viewer.photo.inference import STAGE_SHARES, bundle_target, infer, load_networks
    from viewer.progress import TimeLeft

    target = bundle_target(args.output)
    writable(target.parent, folder=True)
    for given in (args.photo, args.mask, args.networks):
        if given is not None and target in Path(given).resolve().parents:
            raise InputError(args.output, f"holds the input {given}: the bundle written there would replace it; "
                                          "give another folder")
    t0 = time.perf_counter()
    left = TimeLeft(STAGE_SHARES)

    def said(stage):
        left.update(stage, 1, 1)
        words = left.words()
        print(f"  {stage} done" + (f", {words}" if words else ""), flush=True)

    nets = load_networks(args.device, args.networks)
    record = infer(args.photo, args.mask, args.output, size=args.size, max_size=args.max_size, device=args.device,
                   networks=nets, progress=said)
    print("  " + ", ".join(f"{k} {v:.2f} s" for k, v in record["seconds"].items()))
    for note in record["notes"]:
        print(f"note: {note}")
    sizes, fit = record["sizes"], record["photo_lighting"]
    print(f"the photo's own lighting: {fit['lights']} lights explain the photo to {fit['psnr_db']:.1f} dB (PSNR over the person)")
    print(f"wrote scene bundle {args.output}: frame {sizes['frame'][0]}x{sizes['frame'][1]} (the photo's own size, "
          f"at most --max-size), maps {sizes['work'][0]}x{sizes['work'][1]}, mask {'from ' + args.mask if args.mask else 'automatic'}; "
          f"{time.perf_counter() - t0:.1f} s")
    return 0


def cmd_fit_lights(args) -> int:
    from viewer.lighting.envmap import load_envmap
    out = Path(args.output) if args.output else beside_the_map(Path(args.map))
    mine = None  # a light file beside the map that the user wrote: kept, the lights go to the cache
    if not args.output and out is not None and out.exists() and not args.force and not file_is_ours(out):
        out, mine = None, out
    if out is not None and out.suffix.lower() != ".json":
        raise InputError(out, "the light file is JSON: give a .json output path")
    if out is not None:
        writable(out)
    if args.plot:
        if Path(args.plot).suffix.lower() != ".png":
            raise InputError(args.plot, "the plot is a PNG: give a .png path")
        writable(args.plot)
        if out is not None and Path(args.plot).resolve() == out.resolve():
            raise InputError(args.plot, "is the light file's path too: give the plot its own")
    not_an_input([p for p in (out, args.plot) if p], [args.map])
    refuse_foreign([p for p in (out, args.plot) if p], args.force)
    n = light_count_option(args.n, args.method)
    env = load_envmap(args.map, repair=args.repair)
    start, timing = time.perf_counter(), {}
    lights, cached = fitted_lights(env, n, args.method, refit=args.refit, timing=timing)
    seconds = time.perf_counter() - start
    how = "from the cache" if cached else (f"fitted in {timing.get('fit', seconds):.1f} s, {seconds:.1f} s with loading the fitter"
                                           if seconds - timing.get("fit", seconds) >= 0.05 else f"fitted in {seconds:.1f} s")
    if out is None:
        why = (f"{mine} is not a file relight wrote: kept; -o writes a light file, --force replaces it" if mine
               else "the map's folder is not writable; -o writes a light file")
        print(f"{len(lights)} area lights ({args.method}, {how}) -> the fitting cache ({why})")
    else:
        from viewer.lighting.lightfit.cache import fit_record

        lights.save(out, fit=fit_record(args.map, args.method, args.n, env))
        print(f"{len(lights)} area lights ({args.method}, {how}) -> {out}")
    warn_if_dark(lights, args.map)
    if args.plot:
        from viewer.lighting.lightfit.plot import plot_lights

        print(f"wrote {plot_lights(env, lights, args.plot)}")
    return 0
