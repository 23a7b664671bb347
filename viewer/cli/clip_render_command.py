"""``relight render CLIP``: a clip relit into an MP4 (its bundle inferred first, or followed while it is
inferred), on this machine or in parts over a Ray cluster, on a plate or not."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from viewer.cli.clip_commands import bundle_options, clip_bundle, progress_bar, say_bundle
from viewer.cli.command_setup import command_lights, engine_options, first_look, fitted_lights, lights_count, rig_lights
from viewer.cli.output_paths import INFERRED_ONLY, inferred_only, not_an_input, writable
from viewer.errors import InputError
from viewer.files.clip_reader import check_range, is_clip
from viewer.files.ownership import refuse_foreign
from viewer.output.video import audio_sidecar, partial_path, partial_taken


@dataclass(frozen=True)
class ClipJob:
    """A clip's render as the command's checks leave it: where it goes, its light, look and plate."""

    out: Path
    turn: float
    env: object  # the EnvMap of --env, or None
    plate: tuple | None  # clip_plate's (plate, placement, horizon)
    lights: object  # AreaLights
    look: object  # Look
    rig: object  # the user's placed lights, or None


def cmd_render_clip(args, look) -> int:
    job = _checked_job(args, look)
    pool = _ray_pool(args)
    result, bundle, seconds, followed = _relight(args, job, pool)
    _say_result(args, job, result, bundle, seconds, followed)
    return 0


def _check_output(args, look) -> Path:
    """The checks on the output and the options that need nothing read: one line each, before anything runs."""
    from viewer.output.clip_render import check_layers_folder, layers_folder, parts_folder

    out = Path(args.output)
    if out.suffix.lower() != ".mp4":
        raise InputError(out, "a clip is relit into a video: give a .mp4 output path")
    if args.frames is not None:
        raise InputError(None, "--frames sets a turntable's length: a clip keeps its own frames (choose a part with "
                               "--start and --end)")
    check_range(args.scene, args.start, args.end)
    if look.background == "transparent" and not args.plate:  # (on a plate the plate is the background: a window's state on one
        # says transparent)
        raise InputError(out, "an MP4 (H.264) holds no transparency: give the video another --background")
    writable(out)
    if not is_clip(args.scene) and inferred_only(args):
        raise InputError(args.scene, f"{INFERRED_ONLY} choose how a clip is inferred: give the clip itself, "
                                     "or infer its bundle with them")
    if args.per_light and not args.layers:
        raise InputError(None, "--per-light adds layers: give --layers too")
    if args.plate and args.layers:
        raise InputError(None, "--layers with --plate writes a photo's layers: a clip on a plate has none yet")
    if args.ray is None and args.workers is not None:
        raise InputError(None, "--workers: the workers of a Ray cluster: give --ray too")
    from viewer.scene.clip_bundle import read_record

    source = args.scene if is_clip(args.scene) else read_record(args.scene)["source"]["path"]
    sidecar = audio_sidecar(out, source)
    not_an_input([out, partial_path(out), sidecar], [args.scene, args.lights, args.envmap, args.look, getattr(args, "rig", None),
                                                     args.plate],
                 folders=[parts_folder(out)] + ([layers_folder(out)] if args.layers else []))
    refuse_foreign([out, sidecar], args.force)
    if args.layers:
        check_layers_folder(out)
    if partial_path(out).exists():
        raise partial_taken(out)
    return out


def _checked_job(args, look) -> ClipJob:
    """The output checked, the map, plate and lights read and the layers' room measured: all before
    hours of inference."""
    from viewer.lighting.envmap import load_envmap
    from viewer.lighting.map_lights import PLATE, lights_source
    from viewer.output.clip_render import check_layers_room, layer_lights

    out = _check_output(args, look)
    env = load_envmap(args.envmap, repair=args.repair) if args.envmap else None
    plate = clip_plate(args) if args.plate else None  # one line if it cannot be placed
    if plate is not None and args.lights is None and env is None:  # the plate's light, in its camera's frame
        from viewer.plate.environment import plate_light

        lights, _ = fitted_lights(plate_light(plate[0], horizon=plate[2])[0], lights_count(args, look), args.method)
        source = PLATE
    elif args.lights is None and env is None:
        raise InputError(None, "give a light file or an environment map (--env) to fit lights to")
    else:
        lights, source = command_lights(args, look, args.lights, env, args.envmap), lights_source(args.lights)
    look = first_look(args, look, lights, source)
    rig = rig_lights(args)
    if args.layers and is_clip(args.scene):  # the disk's room for them
        from viewer.files.clip_reader import expected_frames, probe_clip
        from viewer.photo.frames import MAX_SIZE, output_frame

        info = probe_clip(args.scene)
        check_layers_room(out, expected_frames(info, args.start, args.end),
                          output_frame((info.width, info.height), args.max_size or MAX_SIZE), layer_lights(lights, rig, args.per_light))
    return ClipJob(out, 0.0 if args.turn is None else args.turn, env, plate, lights, look, rig)


def _ray_pool(args):
    """The Ray workers of ``--ray``, started and counted; None without it."""
    if not args.ray:
        return None
    from viewer.batch.spread_clip import open_pool

    t0 = time.perf_counter()
    pool = open_pool(args.ray, args.workers)
    print(f"{pool.size} Ray worker{'s' if pool.size != 1 else ''} started in {time.perf_counter() - t0:.1f} s")
    return pool


def _relight(args, job: ClipJob, pool):
    """The clip's bundle inferred (or followed while a child infers it) and relit: (render_clip's
    result, the bundle, the seconds since the relighting could begin, whether it followed the inference)."""
    from viewer.gl import create_headless_context
    from viewer.output.clip_render import ClipPictures, parts_folder, render_clip
    from viewer.scene.clip_bundle import load_clip_bundle

    look, out = job.look, job.out
    env_pixels = job.env.pixels if job.env is not None else None
    ctx = follow = infer_bar = None
    try:
        t1 = time.perf_counter()
        planned = bundle_options(args.scene, args) if is_clip(args.scene) else None  # (the clip's bytes read once)
        if planned is not None and pool is None and not job.turn and _followable(planned[0]):
            infer_bar = progress_bar(0, f"inferring {Path(args.scene).name}", position=0)
            follow = _followed(args.scene, planned, infer_bar)  # inferred in a child, each frame relit here as soon as it is final
            bundle = follow(0)
        else:
            bundle = load_clip_bundle(clip_bundle(args.scene, args, pool=pool, planned=planned) if planned else args.scene)
            t1 = time.perf_counter()
        ctx = create_headless_context()
        if job.plate is not None:
            look, pictures = plate_pictures(ctx, bundle, job.plate, job.lights, look, job.env, job.rig, args, job.turn)
        else:
            pictures = ClipPictures(ctx, bundle, job.lights, look, env_pixels, job.rig, engine_options(args, look), job.turn,
                                    (args.size, args.max_size))
        with progress_bar(len(bundle.frames), f"relighting {out.name}", position=1 if follow is not None else None) as bar:
            def progress(done, total):
                bar.total = total
                bar.update(done - bar.n)

            share = None
            if pool is not None:
                from viewer.batch.spread_clip import parts_sharer

                task = parts_task(bundle, out, args, job.lights, look, job.rig, job.turn, job.plate, engine_options(args, look))
                share = parts_sharer(pool, task, parts_folder(out), progress)
            try:
                result = render_clip(pictures, out, progress=progress, layers=args.layers, per_light=args.per_light, share=share,
                                     follow=follow)
            except (InputError, OSError):
                said = follow.refusal() if follow is not None else None  # (the clip changed: its frames taken away)
                if said is not None:
                    raise said from None
                raise
        if follow is not None:
            infer_bar.close()
            record = follow.wait()
            say_bundle(args.scene, follow.target, record, record.get("seconds", time.perf_counter() - t1))
    finally:
        if ctx is not None:
            ctx.release()
        if pool is not None:
            pool.close()
        if follow is not None:
            follow.close()
        if infer_bar is not None:
            infer_bar.close()
    return result, bundle, time.perf_counter() - t1, follow is not None


def _say_result(args, job: ClipJob, result: dict, bundle, seconds: float, followed: bool) -> None:
    from viewer.output.clip_render import layer_name

    w, h = result["size"]
    print(f"wrote {job.out} ({result['frames']} frames, {w}x{h}, the source's timing; {seconds:.1f} s, "
          f"{60 * result['frames'] / max(seconds, 1e-9):.1f} frames a minute"
          + (", inferred and relit together" if followed else "")
          + (f"; {result['parts_reused']} parts kept from an earlier run" if result["parts_reused"] else "") + ")")
    if result["layers"] is not None:
        print(f"wrote {result['layers']}/ ({result['frames']} frames' layers, {layer_name(0)} ...)")
    print(f"note: {result['pitch']} (the first shot's; each shot's read on its first frame with the person)")
    if result["audio_note"]:
        print(f"note: {result['audio_note']}")
    sw, sh = bundle.source["width"], bundle.source["height"]
    if max(sw, sh) > max(w, h) + 1 and job.plate is None:
        from viewer.photo.frames import MAX_SIZE

        print(f"note: the clip is {sw}x{sh}: relit at {w}x{h} (--max-size {args.max_size or MAX_SIZE} on the longer side; "
              "a larger --max-size keeps more, at more time and memory)")


def _followable(target: Path) -> bool:
    """Whether the clip bundle at ``target`` is to be inferred with its relighting following it: not
    there whole (a run before inferred it all: read as it is), nor begun in ranges (``--ray``, a batch:
    finished range by range, so its frames are not final in order)."""
    from viewer.scene.clip_bundle import RECORD, read_record

    try:
        record = read_record(target) if (target / RECORD).is_file() else {}
    except InputError:
        return True  # (made again by the inference)
    return not record.get("complete") and not record.get("ranges")


def _followed(clip, planned: tuple, bar):
    """The clip's bundle inferred into the cache by a child process (:mod:`viewer.photo.clip_follow`;
    ``planned``: :func:`bundle_options`'), its frames counted on ``bar``, for a relighting that follows it."""
    from viewer.cores import work_threads
    from viewer.photo.clip_follow import FollowedInference

    target, options = planned

    def progress(done, total):
        bar.total = total
        bar.update(done - bar.n)

    return FollowedInference(clip, target, options, work_threads(), progress)


def parts_task(bundle, out: Path, args, lights, look, rig, turn: float, plate: tuple | None, options) -> dict:
    """What every worker's share of the relit parts holds (:meth:`viewer.batch.worker.Worker.render_parts`):
    the render's arguments as plain data, paths absolute (a worker on another node reads the same)."""
    from dataclasses import asdict

    from viewer.photo.frames import MAX_SIZE

    task = {"bundle": str(Path(bundle.path).resolve()), "output": str(out.resolve()), "lights": lights.to_array().tolist(),
            "envmap": str(Path(args.envmap).resolve()) if args.envmap else None, "repair": bool(getattr(args, "repair", False)),
            "rig": rig.to_array().tolist() if rig is not None else None, "look": look.to_json(), "options": asdict(options),
            "sizes": [args.size, args.max_size], "turn": turn, "layers": bool(args.layers), "per_light": bool(args.per_light)}
    if plate is not None:
        place = plate[1]
        task.update(plate=str(Path(args.plate).resolve()), place=[place.x, place.y, place.height], horizon=plate[2],
                    cut_allowed=args.height is not None, plate_size=args.max_size or MAX_SIZE,
                    front=str(Path(args.front).resolve()) if getattr(args, "front", None) else None)
    return task


def clip_plate(args) -> tuple:
    """``--plate`` for a clip: (the plate, no longer on its longer side than ``--max-size``, where the
    person stands on it, its horizon); its notes said."""
    from viewer.cli.plate_commands import plate_place
    from viewer.photo.frames import MAX_SIZE
    from viewer.plate.loader import read_plate
    from viewer.plate.placement import Placement

    notes: list = []
    whole = read_plate(args.plate, notes, getattr(args, "front", None))
    place, horizon = plate_place(whole, args, notes)  # on the whole plate, as a batch places it
    plate = whole.within(args.max_size or MAX_SIZE)  # every frame is the plate's size: a video's frame, not a 12-MP still
    if plate is not whole:
        notes.append(f"the plate brought to {plate.size[0]}x{plate.size[1]} (--max-size), the video's frame")
    for note in notes:
        print(f"note: {note}")
    return plate, Placement(*place), horizon


def plate_pictures(ctx, bundle, plate: tuple, lights, look, env, rig, args, turn):
    """(the look, the frames) of a clip put into ``plate`` (:func:`clip_plate`'s): the plate's look, the
    exposure the plate's (its own light) or matched to it (the user's, on the clip's first person)."""
    from viewer.cli.plate_commands import own_light_exposure
    from viewer.output.plate_clip import PlatePictures
    from viewer.output.plate_render import plate_look
    from viewer.scene.look import AUTO

    auto = 0.0
    if (args.envmap or args.lights) and look.exposure == AUTO:
        from viewer.output.clip_frames import ClipFrames

        frames = ClipFrames(bundle)
        scene = frames.scene(frames.people[0], (args.size, args.max_size))
        from viewer.plate.environment import plate_light

        auto = own_light_exposure(plate_light(plate[0], horizon=plate[2])[0], scene, lights, env.pixels if env is not None else None, look)
    look = plate_look(look, auto)
    pictures = PlatePictures(ctx, bundle, lights, look, env.pixels if env is not None else None, rig, engine_options(args, look),
                             turn, (args.size, args.max_size), plate=plate[0], place=plate[1], horizon=plate[2],
                             cut_allowed=args.height is not None)
    return look, pictures
