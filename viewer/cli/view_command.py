"""``relight view``: the interactive viewer opened on a scene bundle, a photo (its bundle inferred once,
in the window, with progress) or a clip."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from viewer.cli.command_setup import (
    command_lights,
    command_look,
    engine_options,
    first_look,
    gl_threads,
    lights_count,
)
from viewer.cli.commands import DEMO_ENVMAP, plate_options_need_a_plate
from viewer.cli.output_paths import check_fps, not_a_clip_range
from viewer.errors import InputError
from viewer.resources import asset_dir, sample_scene_dir
from viewer.scene.resampling import load_sized_scene


def cmd_view(args) -> int:
    from viewer.files.clip_reader import is_clip
    from viewer.lighting.envmap import load_envmap
    from viewer.lighting.map_lights import lights_source
    from viewer.scene.bundle import PHOTO_SUFFIXES
    from viewer.scene.clip_bundle import is_clip_bundle

    clip = args.scene is not None and (is_clip(args.scene) or is_clip_bundle(args.scene))
    if not clip:
        not_a_clip_range(args, args.scene)
    assets = asset_dir()
    scene_path = args.scene or sample_scene_dir()
    photo = args.scene is not None and Path(args.scene).suffix.lower() in PHOTO_SUFFIXES
    if args.mask and not photo:
        raise InputError(args.scene, "--mask needs a photo: relight view PHOTO [--mask MASK]")
    env_path = Path(args.envmap) if args.envmap else (assets / DEMO_ENVMAP if args.lights is None else None)
    look = command_look(args)  # its yaw: first_look, once the lights are known
    plate_options_need_a_plate(args)
    if args.record_frames < 1:
        raise InputError(None, f"--record-frames must be at least 1, got {args.record_frames}")
    from viewer.lighting.placed_lights import load_rig

    rig = load_rig(args.rig) if args.rig else ()  # before any window: a bad file is one line
    check_fps(args)
    plate, plate_notes = None, []
    if args.plate:  # read, placed and its light made before any window: a bad plate is one line
        from viewer.cli.plate_commands import view_plate

        plate, plate_map = view_plate(args, plate_notes)  # a clip's person is placed once its first frame is inferred
        for note in plate_notes:
            print(f"note: {note}")
        if plate_map is not None:
            env_path = plate_map
    window = clip_bundle = None
    if clip:
        from viewer.cli.clip_commands import view_clip_bundle

        clip_bundle = view_clip_bundle(args)  # its inference shown in the window, made first
        window, scene_path = clip_bundle.window, clip_bundle.first
    elif photo:
        from viewer.app.window import Window

        # the window first: its GL context also serves the inference (a headless EGL context made
        # before the window's would make the window fail, ../shared/docs/STACK.md)
        window = Window(960, 720, f"relight - {Path(args.scene).name}")
        try:
            scene_path = _photo_bundle(args.scene, args.mask, args.device, window, args.max_size)
        except BaseException:
            window.release()
            raise
    try:
        scene = load_sized_scene(scene_path, args.size, args.max_size)
        env = load_envmap(env_path, repair=args.repair) if env_path is not None else None
        lights = command_lights(args, look, args.lights, env, env_path)
        if plate is not None and clip:  # every frame placed as the clip's first person is (relight render CLIP --plate)
            from viewer.app.plate_view import VIEW_LONGER
            from viewer.plate.placement import plate_transform

            anchor = scene.frame.alpha if scene.frame is not None else scene.mask.astype(np.float32)
            plate_transform(anchor, plate[1], plate[0].within(VIEW_LONGER).size, args.scene, cut_allowed=True)
            plate = (*plate[:5], anchor)
    except BaseException:
        if window is not None:
            window.release()
        raise
    look = first_look(args, look, lights, lights_source(args.lights, plate is not None and plate[3] == "plate"))
    if plate is not None:  # exposed in the plate's units; lit by the user's own light, as bright as the plate's makes them
        from viewer.cli.plate_commands import own_light_exposure
        from viewer.lighting.envmap import load_envmap as read_map
        from viewer.output.plate_render import plate_look
        from viewer.scene.look import AUTO

        own = plate[3] != "plate" and look.exposure == AUTO
        look = plate_look(look, own_light_exposure(read_map(plate[4]), scene, lights, env.pixels if env is not None else None,
                                                   look) if own else 0.0)
    from viewer.app import ViewerConfig, run_viewer

    config = ViewerConfig(scene=scene, lights=lights, environment=env.pixels if env is not None else None,
                          env_path=Path(env_path) if env_path is not None else None, method=args.method,
                          options=engine_options(args, look), look=look, out_dir=Path(args.out_dir),
                          record_frames=args.record_frames, fps=args.fps,
                          state_file=Path(args.state_file) if args.state_file else None,
                          bundled_maps=tuple(sorted((assets / "envmaps").glob("*.hdr"))), preset=look.preset,
                          window=window, rig=rig, max_size=args.max_size, device=args.device,
                          gl_threads=gl_threads(), clip=clip_bundle.bundle if clip_bundle else None, size=args.size,
                          plate=plate, plate_notes=tuple(plate_notes), lights_count=lights_count(args, look))
    return run_viewer(config)


def _photo_bundle(photo, mask, device, window, max_size: int) -> Path:
    """The scene bundle of a photo: inferred once (its stages shown in the window), then taken
    from the cache."""
    from viewer.photo.inference import STAGE_SHARES, STAGES, cached_bundle
    from viewer.progress import TimeLeft

    start = time.perf_counter()
    left = TimeLeft(STAGE_SHARES)
    name = Path(photo).name

    def progress(stage):
        print(f"  {stage} done ({time.perf_counter() - start:.1f} s)", flush=True)
        fraction = left.update(stage, 1, 1)
        words = left.words()
        k = STAGES.index(stage) + 1 if stage in STAGES else 0
        window.show_message(f"Preparing {name}", fraction, f"{stage} done ({k} of {len(STAGES)})" + (f", {words}" if words else ""))

    window.show_message(f"Preparing {name}", 0.0, "reading the photo, finding the person...")
    bundle, cached = cached_bundle(photo, mask, max_size=max_size, device=device, progress=progress, ctx=window.ctx)
    print(f"scene bundle of {photo}: {bundle} ({'from the cache' if cached else 'inferred now, cached for next time'}; "
          f"{time.perf_counter() - start:.1f} s)")
    return bundle
