"""``relight batch``: its options, and the looks resolved once in this process (each map read and its
lights found once: beside the map, in the cache, or fitted now) before the batch hands the renders
to its workers (viewer/batch)."""

from __future__ import annotations

import sys
from pathlib import Path

from viewer.cli.shared_options import add_device_arg, add_engine_args, add_map_light_args, add_view_args, auto_or
from viewer.errors import InputError


def add_batch_parser(sub) -> None:

    p = sub.add_parser("batch", help="relight folders of photos under several looks: every photo inferred once, every "
                       "map fitted once, renders on worker processes or a Ray cluster, a manifest, resumable")
    p.add_argument("photos", nargs="+", help="photos and clips, folders of them, or globs (quoted); a clip is relit into "
                   "CLIP/LOOK.mp4 with its middle frame as CLIP/LOOK.png")
    p.add_argument("--env", "--envmap", dest="envmaps", nargs="+", default=[], help="environment maps: one look each")
    p.add_argument("--lights", dest="light_files", nargs="+", default=[], help="area-light files: one look each (no map behind)")
    p.add_argument("--yaw", dest="yaws", nargs="+", type=auto_or("degrees"),
                   help="yaws of every look, degrees, or auto (default): a map's brightest light turned to the camera, "
                        "a light file of your own as written, a plate's light as seen")
    p.add_argument("--rig", dest="rigs", nargs="+", default=[], help="rigs (placed lights saved by the viewer): each look "
                   "once with each rig")
    p.add_argument("--plate", dest="plates", nargs="+", default=[], help="background photos: one look each, the person put "
                   "into the plate and lit by its light, PHOTO/on_PLATE.png and .exr (docs/plates.md)")
    p.add_argument("--at", help="plate looks: where the feet stand, X,Y as fractions of the plate (default 0.5,0.88)")
    p.add_argument("--height", type=float, help="plate looks: the person's height, a fraction of the plate's (default: "
                                                "a 1.7 m person seen from eye height)")
    p.add_argument("--horizon", type=float, help="plate looks: the horizon's height, a fraction of the plate's (default: each "
                                                 "plate's own, read from its vertical edges)")
    add_map_light_args(p, repair=False)
    p.add_argument("-o", "--output", required=True, help="the batch's folder: PHOTO/LOOK.png and .exr, manifest.jsonl")
    p.add_argument("--workers", type=int, help="worker processes (default: one per idle core, as many as the memory holds)")
    p.add_argument("--threads", type=int, help="threads of each worker (default: the idle cores shared among the workers)")
    p.add_argument("--ray", help="run on a Ray cluster: auto (the one this machine belongs to), an address, or local "
                   "(a Ray instance started for this batch)")
    p.add_argument("--gpus-per-worker", type=float, default=0.0,
                   help="with --ray: GPUs each actor asks for (e.g. 0.25: four actors share a GPU); Ray places them on "
                        "nodes that have them, and their GL contexts render there (default 0: CPU nodes)")
    p.add_argument("--layers", action="store_true", help="also PHOTO/LOOK.layers.exr for compositors (docs/batch.md)")
    p.add_argument("--per-light", action="store_true", help="with --layers: each light's diffuse light as a layer")
    add_device_arg(p)
    add_engine_args(p, presets=True)
    add_view_args(p, yaws=False)
    p.set_defaults(func=cmd_batch)


def cmd_batch(args) -> int:
    from viewer.batch.plan import check_sources, collect_photos, look_specs
    from viewer.batch.run import run_batch
    from viewer.cli.output_paths import writable

    photos, missing = collect_photos(args.photos)
    photos = [p.resolve() for p in photos]  # workers elsewhere (Ray) read and write the same paths, not relative ones
    for line in missing:
        print(f"relight: warning: {line}", file=sys.stderr)
    if not photos:
        raise InputError(None, "no photos or clips to relight: give photos, clips, folders or globs")
    from viewer.files.clip_reader import is_clip

    if args.layers and any(is_clip(p) for p in photos):
        print("relight: warning: --layers: the clips get their relit MP4 and middle frame, no layers (a layers file is a "
              "photo's)", file=sys.stderr)
    if not args.envmaps and not args.light_files and not args.plates:
        raise InputError(None, "give the looks: --env MAP [MAP ...], --lights FILE [FILE ...] and/or --plate PHOTO [PHOTO ...]")
    if args.plates:
        from viewer.cli.plate_commands import at_option
        from viewer.plate.placement import check_place_options

        # a malformed --at or --horizon is one line before any work; each plate places the person on its own horizon
        check_place_options(at_option(args.at), args.horizon)
    elif any(v is not None for v in (args.at, args.height, args.horizon)):
        raise InputError(None, "--at, --height and --horizon place the person on a plate: give --plate PHOTO")
    if args.gpus_per_worker < 0 or (args.gpus_per_worker and not args.ray):
        raise InputError(None, "--gpus-per-worker: a share of a GPU (0 or more) for each Ray actor: give --ray too")
    if args.per_light and not args.layers:
        raise InputError(None, "--per-light adds layers: give --layers too")
    if (args.workers is not None and args.workers < 1) or (args.threads is not None and args.threads < 1):
        raise InputError(None, "--workers and --threads must be at least 1")
    if args.ray:
        from viewer.batch.pools import reachable

        reachable(args.ray)  # before the batch's folder, lock and manifest are made
    workers, threads = worker_count(args)
    specs = look_specs(*([Path(p).resolve() for p in paths] for paths in (args.envmaps, args.light_files)),
                       args.yaws, [Path(p).resolve() for p in args.rigs], args.presets, [Path(p).resolve() for p in args.plates])
    check_sources(specs)
    folder = Path(args.output).resolve()
    writable(folder, folder=True)
    looks = resolve_looks(specs, args)

    def make_pool():
        from viewer.batch.pools import LocalPool, RayPool

        if args.ray:  # the cluster's cores, not this machine's: one thread an actor unless told
            return RayPool(args.ray, args.workers, args.threads or 1, gpus=args.gpus_per_worker)
        return LocalPool(workers, threads)

    from viewer.lighting.lightfit.cache import bundles_dir
    from viewer.nets.device import compute_device

    # the bundles' folder as this process sees it: workers on other machines need it shared (docs/batch.md)
    # the device resolved here ("auto": this machine's), as the items' keys hold it
    settings = {"max_size": args.max_size, "layers": args.layers, "per_light": args.per_light, "device": compute_device(args.device),
                "bundles": str(bundles_dir().resolve()),
                **({"cut_allowed": args.height is not None} if args.plates else {})}
    summary = run_batch(photos, looks, folder, make_pool, settings)
    for item, error in summary.failures:
        print(f"relight: {item}: {error}", file=sys.stderr)
    print(summary.line(folder / "manifest.jsonl"))
    if summary.sheet is not None:
        print(f"wrote {summary.sheet}")
    return 1 if summary.failed else 0


WORKER_PHOTO_PIXELS = 12e6  # a 12-MP photo: what a worker's memory is sized for
WORKER_MAP_PIXELS = 1e6  # a photo bundle's maps (the person's longer side 512 pixels in its work frame)


def worker_count(args) -> tuple[int, int]:
    """(workers, threads each): one single-threaded worker per idle core (measured: two workers of one
    thread made 36-37 photo-looks a minute here, one of two threads 23-25; docs/batch.md), as many as the
    memory budget holds (a worker infers a 12-MP photo, or renders a bundle's maps of about a megapixel,
    into a frame of --max-size), or as given."""
    from viewer.cores import work_threads
    from viewer.memory_needs import infer_bytes, memory_budget, render_bytes

    cores = work_threads()
    frame = args.max_size * args.max_size * 2 // 3
    per_worker = max(infer_bytes(WORKER_PHOTO_PIXELS, frame), render_bytes(WORKER_MAP_PIXELS, frame))
    fits = max(1, int(memory_budget() // per_worker))
    if args.workers is not None and args.workers > fits and not args.ray:
        raise InputError(None, f"--workers {args.workers}: this machine's memory holds {fits} (each needs about "
                               f"{per_worker / 2**20:.0f} MB at --max-size {args.max_size}); give at most {fits}")
    workers = args.workers or max(1, min(cores, fits))
    return workers, args.threads or max(1, cores // workers)


def resolve_looks(specs, args) -> list:
    """Each look's lights (a map's found once per count), yaw, rig, look and engine options; a map
    or light file that cannot be used fails its own looks, with its line."""
    from viewer.batch.run import ResolvedLook
    from viewer.cli.command_setup import command_lights, command_look, engine_options, fitted_lights, lights_count
    from viewer.cli.plate_commands import plate_place
    from viewer.files.ownership import file_sha256
    from viewer.lighting.envmap import load_envmap
    from viewer.lighting.map_lights import lights_source, start_yaw
    from viewer.lighting.placed_lights import load_rig, to_area_lights
    from viewer.output.plate_render import plate_look
    from viewer.plate.environment import plate_light
    from viewer.plate.loader import read_plate

    base = command_look(args)
    found: dict = {}  # (source, n) -> (lights, sha) or the error line
    places: dict = {}  # plate -> where the person stands on it (its own horizon unless --horizon)
    looks = []
    for spec in specs:
        look = base.replace(preset=spec.preset) if spec.preset else base
        try:
            n = lights_count(args, look)
            source = spec.envmap or spec.lights_file or spec.plate
            if (source, n) not in found:
                try:
                    if spec.plate is not None:  # the plate's own light, estimated and fitted once
                        plate = read_plate(spec.plate, [])
                        places[spec.plate] = plate_place(plate, args)
                        lights = fitted_lights(plate_light(plate, horizon=places[spec.plate][1])[0], n, args.method)[0]
                    else:
                        env = load_envmap(spec.envmap) if spec.envmap is not None else None
                        lights = command_lights(args, look, spec.lights_file, env, spec.envmap)  # the one rule, as render's
                    found[(source, n)] = (lights, file_sha256(source))
                except InputError as exc:
                    found[(source, n)] = str(exc)
            if isinstance(found[(source, n)], str):
                looks.append(ResolvedLook(spec, error=found[(source, n)]))
                continue
            lights, sha = found[(source, n)]
            # "auto": the yaw these lights start with, by where they come from (as render's); no map behind a
            # light file's look: the engine falls back to the photo's background
            source = lights_source(spec.lights_file, spec.plate is not None)
            look = look.replace(yaw=start_yaw(lights, source) if spec.yaw == "auto" else float(spec.yaw))
            if spec.plate is not None:
                look = plate_look(look)
            rig = to_area_lights(load_rig(spec.rig)).to_array() if spec.rig is not None else None
            looks.append(ResolvedLook(spec, look.to_json(), _options(engine_options(args, look)), lights.to_array(), rig, sha,
                                      file_sha256(spec.rig) if spec.rig is not None else "",
                                      place=places[spec.plate][0] if spec.plate is not None else None,
                                      horizon=places[spec.plate][1] if spec.plate is not None else None))
        except InputError as exc:
            looks.append(ResolvedLook(spec, error=str(exc)))
    return looks


def _options(options) -> dict:
    from dataclasses import asdict

    return asdict(options)
