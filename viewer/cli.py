"""``relight`` command line: thin wrappers that parse, call and print."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

from .cores import size_pools, work_threads
from .errors import InputError
from .video import partial_path as video_partial, partial_taken
from .lightfit import DEFAULT_METHOD, METHODS
from .resources import asset_dir, sample_scene_dir
from .scene_ops import load_sized_scene

COMMAND_GROUP = "relight.commands"
DEMO_ENVMAP = "envmaps/immenstadter_horn_256.hdr"
DEMO_LIGHTS = "envmaps/immenstadter_horn_256.lights.json"
DEMO_PHOTO = "photos/underpass.jpg"
DEMO_YAW = 180.0  # the map's sun is behind the figure at yaw 0; turned, it lights the front


def _engine_options(args, look):
    """The look's preset's engine options with the knobs given on the command line in place of its values."""
    from dataclasses import replace

    from .presets import DEFAULT_PRESET, preset

    given = {k: getattr(args, k) for k in ("soft", "shadow_resolution", "shadow_step", "terms", "prefilter") if getattr(args, k) is not None}
    try:
        return replace(preset(look.preset or DEFAULT_PRESET).options, **given)
    except InputError as exc:  # name the option
        option = next((f"--{k.replace('_', '-')}" for k in given if k.split("_")[-1] in exc.problem), None)
        raise InputError(None, f"{option}: {exc.problem}" if option else exc.problem) from None


def _lights_count(args, look) -> int:
    """``-n``, or the look's preset's count."""
    from .presets import DEFAULT_PRESET, preset

    if args.lights_count is None:
        return preset(look.preset or DEFAULT_PRESET).lights
    return _light_count_option(args.lights_count, args.method)


def _light_count_option(n: int, method: str | None) -> int:
    """``-n``, checked before a map is read: the engine's limit, and the method's."""
    from .lightfit.methods import check_light_count
    from .lights import MAX_LIGHTS

    if not 1 <= n <= MAX_LIGHTS:
        raise InputError(None, f"-n: the number of lights must be in [1, {MAX_LIGHTS}], got {n}")
    check_light_count(method or DEFAULT_METHOD, n)
    return n


def _add_engine_args(p):
    from .presets import DEFAULT_PRESET, PRESETS
    from .shadow_space import SOFT_METHODS

    p.add_argument("--preset", choices=tuple(PRESETS),
                   help=f"quality preset: lights and engine options from docs/results.md (default {DEFAULT_PRESET}); "
                        "the options below override its values")
    p.add_argument("--soft", choices=SOFT_METHODS,
                   help="soft shadows: contact-hardening (pcss, the presets') or the paper's convolutional shadow maps (csm)")
    p.add_argument("--shadow-resolution", type=int, help="texels of each shadow map (preset's; balanced 512)")
    p.add_argument("--shadow-step", type=int, help="depth-mesh decimation for shadow maps (0 = auto, the presets' choice)")
    p.add_argument("--terms", type=int, help="with --soft csm: Fourier terms M, 2M basis maps (default 4)")
    p.add_argument("--prefilter", choices=("pyramid", "exact"), help="with --soft csm: pre-filtering (default pyramid)")


def _auto_or(unit: str):
    """An option's parser: "auto" or a number of ``unit`` (its range is the look's to check, viewer.settings.Look)."""
    def parse(text: str):
        if text.strip().lower() == "auto":
            return "auto"
        try:
            return float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected 'auto' or a number of {unit}, got {text!r}") from None
    return parse


def _add_view_args(p, yaw_default=0.0):
    p.add_argument("--look", help="a saved look: the JSON of a frame saved in the viewer (S), its state file, or a look "
                   "object (docs/architecture.md); the options below override its values")
    p.add_argument("--yaw", "--rotate", dest="yaw", type=float,
                   help=f"rotate the lighting (and the map behind) about the vertical axis, degrees (default {yaw_default:g}); "
                        "a video starts there")
    p.add_argument("--tilt", type=float, help="tilt the lighting (degrees, default 0)")
    p.add_argument("--exposure", type=_auto_or("stops"),
                   help="exposure in stops, or auto (default): a photo's relit person keeps the photo's brightness "
                        "(0 stops for a scene without a photo)")
    p.add_argument("--tonemap", choices=("aces", "reinhard", "clamp"), help="tone curve (default aces)")
    p.add_argument("--background", choices=("environment", "photo", "color", "transparent"),
                   help="behind the person: the environment map seen through the photo's camera (default), the "
                        "photo's own background, a grey, or transparent (PNG and EXR with alpha)")
    p.add_argument("--backdrop-blur", type=_auto_or("degrees"),
                   help="the map behind the person blurred like a defocused background, degrees, or auto (default): "
                        "as much as the photo's own background is (0 for a scene without a photo)")
    p.add_argument("--max-size", type=int, default=2048,
                   help="longer side of the output in pixels at most (default 2048; a photo's bundle renders at "
                        "the photo's own size up to this)")
    ground = p.add_mutually_exclusive_group()
    ground.add_argument("--ground", action="store_const", const=True,
                        help="the person's shadow on the ground at the feet, over the background (a shadow catcher); "
                             "by default shown when the feet are in the frame and the map is behind the person")
    ground.add_argument("--no-ground", dest="ground", action="store_const", const=False, help="no shadow on the ground")
    p.add_argument("--visibility", choices=("soft", "refined", "hard", "none"),
                   help="shadows (default soft): soft (contact-hardening, or --soft csm), the refinement network on them "
                        "(refined), the shadow map (hard) or none")


def _beside_the_map(map_path: Path) -> Path | None:
    """``MAP.lights.json`` beside the map (what the viewer reads for that map) when its folder is
    writable, else None (the lights then stay in the fitting cache)."""
    import os

    folder = map_path.parent
    return map_path.with_suffix(".lights.json") if os.access(folder, os.W_OK | os.X_OK) else None


def _writable(path, folder: bool = False) -> Path:
    """``path`` if the program can write it, checked before any work is done: else one line naming
    it. ``folder``: the path is itself a folder to write into. Missing folders are made only when
    the output is written, so a command that fails leaves none behind: here the nearest existing
    folder above must be one the program may create them in."""
    import os

    path = Path(path)
    where = path if folder else path.parent
    if not folder and path.is_dir():
        raise InputError(path, "is a folder: give a file path")
    existing = where.absolute()
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise InputError(path, f"cannot write here ({existing} is a file, not a folder)")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(path, f"cannot write here ({existing} is not writable)")
    if existing != where.absolute():  # folders to make: a folder made and taken away again proves it can be done
        import tempfile

        try:
            os.rmdir(tempfile.mkdtemp(prefix=".relight-probe-", dir=existing))
        except OSError as exc:
            raise InputError(path, f"cannot write here ({exc.strerror or exc})") from None
    return path


NAME_MAX = 255 - 24  # bytes of a file name, leaving room for the temporary name it is written under


def _not_an_input(outputs, inputs):
    """Refuse outputs that would replace an input (a map, a light file, a photo) or land inside an
    input folder (a scene bundle): the user's files are never written over."""
    for out in outputs:
        out = Path(out)
        if len(os.fsencode(out.name)) > NAME_MAX:
            raise InputError(out, f"the file name is longer than {NAME_MAX} bytes")
        try:
            str(out).encode("utf-8")
        except UnicodeEncodeError:  # a byte that is not UTF-8, kept by Python as a surrogate
            raise InputError(out, "the path is not valid UTF-8 (the image and video writers take UTF-8 "
                                  "names): choose a UTF-8 name") from None
        if not out.name.isprintable():
            raise InputError(out, "the file name holds control characters (a newline?)")
        resolved = out.resolve()
        for given in inputs:
            if given is None:
                continue
            src = Path(given).resolve()
            if resolved == src or (src.is_dir() and src in resolved.parents):
                raise InputError(out, f"would write over the input {given}: give another output path")
        if out.is_dir():
            raise InputError(out, "is a folder: the output would replace it")


def _fitted_lights(env, n, method, refit=False):
    """Lights of ``env`` from the cache, or fitted now with a progress bar (a black map is reported
    by the caller on every run, cached or not: the fitter's own warning is left out)."""
    import warnings

    from .lightfit import lights_for_map
    from .lightfit.methods import STAGE_SHARES
    from .progress import StageBars

    name = Path(env.source).name if env.source else "the map"
    with StageBars(prefix=f"fitting {n} lights to {name}: ", shares=STAGE_SHARES.get(method or DEFAULT_METHOD)) as bars, warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*the map is black")
        lights, cached = lights_for_map(env, n, method, progress=bars, refit=refit)
    return lights, cached


def _prepare(scene_path, lights_path, envmap_path, args, look):
    """Scene (resampled to ``--size``), lights (a file, or fitted to the map) and map pixels."""
    from .envmap import load_envmap

    scene = load_sized_scene(scene_path, getattr(args, "size", None), getattr(args, "max_size", None))
    env = load_envmap(envmap_path, repair=getattr(args, "repair", False)) if envmap_path else None
    if lights_path is None and env is None:
        raise InputError(None, "give a light file or an environment map (--env) to fit lights to")
    return scene, _lights(args, look, lights_path, env, envmap_path), (env.pixels if env is not None else None)


def _lights(args, look, lights_path, env, env_path):
    """The light file given, or the map's lights by the one rule (:mod:`viewer.map_lights`), the
    fit in this process with its progress bars; said on a line when they come from the map."""
    from .lights import load_lights
    from .map_lights import map_lights

    if lights_path is not None:
        lights = load_lights(lights_path)
    else:
        n = _lights_count(args, look)
        lights, how = map_lights(env, env_path, n, args.method or DEFAULT_METHOD,
                                 lambda e: _fitted_lights(e, n, args.method))
        print(f"{len(lights)} lights for {env_path}: {HOW[how]}")
    _warn_if_dark(lights, lights_path or env_path)
    return lights


HOW = {"bundled": "those shipped beside the map", "cached": "from the cache", "fitted": "fitted now"}


def _warn_if_dark(lights, source):
    """Every run with lights that give no light says so (a black map's lights come from the cache too)."""
    if not np.any(lights.intensity > 0):
        print(f"relight: warning: {source}: every light has zero intensity, so the person renders black "
              "(is the map black?)", file=sys.stderr, flush=True)


# the look's fields and the options that set them (each default None: given or not)
_LOOK_OPTIONS = (("yaw", "yaw"), ("tilt", "tilt"), ("exposure", "exposure"), ("tonemap", "tonemap"),
                 ("background", "background"), ("shadows", "visibility"), ("preset", "preset"),
                 ("ground", "ground"), ("backdrop_blur", "backdrop_blur"))


def _settings(args, yaw_default: float = 0.0):
    """The look of a command: a saved one (``--look FILE``: a frame saved by the viewer, its state
    file, or a bare look object) or the defaults, with every option given on the command line in
    its place (the preset among them: what the engine options and the lights' count follow)."""
    from .settings import AUTO, Look

    base = _read_look(args.look) if getattr(args, "look", None) else Look(yaw=yaw_default, exposure=AUTO)
    given = {field: getattr(args, option) for field, option in _LOOK_OPTIONS if getattr(args, option, None) is not None}
    try:
        look = base.replace(**given)
    except InputError as exc:  # name the option, not the field
        option = next((o for f, o in _LOOK_OPTIONS if exc.problem.startswith(f.replace("tonemap", "tone map"))), None)
        raise InputError(None, f"--{option}: {exc.problem}" if option else exc.problem) from None
    return look


def _read_look(path):
    """The look in a JSON file (``{"look": {...}}`` as the viewer saves it, or the look itself)."""
    from .imageio import read_json
    from .settings import Look

    data = read_json(path, "JSON look file")
    return Look.from_json(data.get("look", data) if isinstance(data, dict) else data, where=path)


def _rig_lights(args):
    """The placed lights of ``--rig`` as area lights (fixed to the camera), or None."""
    from .placed_lights import load_rig, to_area_lights

    return to_area_lights(load_rig(args.rig)) if getattr(args, "rig", None) else None


def _render(scene_path, lights_path, envmap_path, out_dir, name, args, look, png_name=None) -> list[Path]:
    from .gl import Engine, create_headless_context
    from .render import render_to_files

    scene, lights, env = _prepare(scene_path, lights_path, envmap_path, args, look)
    engine = Engine(create_headless_context(), scene, _engine_options(args, look))
    try:
        return render_to_files(engine, scene, lights, out_dir, name, look, environment=env, fixed=_rig_lights(args),
                               png_name=png_name)
    finally:
        engine.release()


def cmd_demo(args) -> int:
    """The whole path: the sample scene, then the bundled real photo inferred (automatic mask),
    relit at its own size under the three bundled maps with refined shadows, and a sheet of the
    photo beside its relightings."""
    from dataclasses import replace

    from .envmap import load_envmap
    from .gl import Engine, create_headless_context
    from .imageio import read_png, write_png
    from .inference import infer
    from .lights import load_lights
    from .photo_frame import read_photo, resize
    from .render import render_to_files

    assets = asset_dir()
    look = _settings(args, DEMO_YAW)
    _writable(args.output, folder=True)
    written = _render(sample_scene_dir(), assets / DEMO_LIGHTS, assets / DEMO_ENVMAP, args.output, "demo", args, look)
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
    engine = Engine(ctx, scene, _engine_options(args, look))
    pictures = [resize(read_photo(photo, []), scene.output_size).astype(np.float32) / 255.0]  # upright, the output's size
    settings = replace(look, shadows="refined", background="environment")
    try:
        for env_path in sorted((assets / "envmaps").glob("*.hdr")):
            t0 = time.perf_counter()
            files = render_to_files(engine, scene, load_lights(env_path.with_suffix(".lights.json")), out,
                                    f"photo_{env_path.stem}", settings, environment=load_envmap(env_path).pixels, passes=False)
            pictures.append(read_png(files[0])[..., :3])
            print(f"  relit under {env_path.name} (refined shadows), {scene.output_size[0]}x{scene.output_size[1]}, "
                  f"in {time.perf_counter() - t0:.1f} s: {files[0]}")
    finally:
        engine.release()
    sheet = write_png(out / "photo_relit.png", np.concatenate(pictures, axis=1))
    print(f"wrote {sheet} (the photo, then relit under each bundled map)")
    return 0


MAX_FRAMES = 100_000  # an hour at 30 fps
FPS_RANGE = (0.1, 1000.0)


def _check_video(args):
    """--frames, --fps and --turn within what a video can be, named when not."""
    if args.frames is not None and not 1 <= args.frames <= MAX_FRAMES:
        raise InputError(None, f"--frames must be in [1, {MAX_FRAMES}], got {args.frames}")
    _check_fps(args)
    if not (np.isfinite(args.turn) and abs(args.turn) <= 36000):
        raise InputError(None, f"--turn must be a finite number of degrees within +-36000, got {args.turn}")


def _check_fps(args):
    """--fps within what a video (or the viewer's recording) can be, named when not."""
    if not (np.isfinite(args.fps) and FPS_RANGE[0] <= args.fps <= FPS_RANGE[1]):
        raise InputError(None, f"--fps must be in [{FPS_RANGE[0]:g}, {FPS_RANGE[1]:g}], got {args.fps}")


def cmd_render(args) -> int:
    look = _settings(args)
    out = Path(args.output)
    suffix = out.suffix.lower()
    if suffix not in (".png", ".mp4"):
        raise InputError(out, "give a .png path for one frame (the EXR goes beside it) or a .mp4 path for a turntable video")
    _writable(out)
    outputs = [out] if suffix == ".mp4" else [out, out.with_suffix(".exr"), out.with_name(f"{out.stem}_passes.png")]
    _not_an_input(outputs + ([video_partial(out)] if suffix == ".mp4" else []), [args.scene, args.lights, args.envmap, args.look, getattr(args, "rig", None)])
    if suffix == ".mp4":
        _check_video(args)
        if look.background == "transparent":  # H.264 has no alpha: it came out black (the option or a --look)
            raise InputError(out, "an MP4 (H.264) holds no transparency: render a PNG (and its EXR) with "
                                  "--background transparent, or give the video another --background")
        if video_partial(out).exists():
            raise partial_taken(out)
    if suffix == ".png":
        if args.frames is not None:
            raise InputError(out, "--frames makes a video: give a .mp4 output path")
        for path in _render(args.scene, args.lights, args.envmap, out.parent, out.stem, args, look, png_name=out.name):
            print(f"wrote {path}")
        return 0

    from tqdm import tqdm

    from .gl import Engine, create_headless_context
    from .render import render_turntable

    frames = 120 if args.frames is None else args.frames
    scene, lights, env = _prepare(args.scene, args.lights, args.envmap, args, look)
    engine = Engine(create_headless_context(), scene, _engine_options(args, look))
    start = time.perf_counter()
    try:
        with tqdm(total=frames, unit="frame", desc=f"rendering {out.name}", leave=False) as bar:
            width, height = render_turntable(engine, scene, lights, out, look, frames, fps=args.fps, turn=args.turn,
                                             environment=env, progress=lambda done, total: bar.update(1),
                                             fixed=_rig_lights(args))
    finally:
        engine.release()
    seconds = time.perf_counter() - start
    print(f"wrote {out} ({frames} frames, {width}x{height}, {args.fps:g} fps, "
          f"{args.turn:g} degrees; {seconds:.1f} s, {1000 * seconds / frames:.0f} ms per frame)")
    return 0


def cmd_view(args) -> int:
    from .envmap import load_envmap
    from .scene import PHOTO_SUFFIXES

    assets = asset_dir()
    scene_path = args.scene or sample_scene_dir()
    photo = args.scene is not None and Path(args.scene).suffix.lower() in PHOTO_SUFFIXES
    if args.mask and not photo:
        raise InputError(args.scene, "--mask needs a photo: relight view PHOTO [--mask MASK]")
    env_path = Path(args.envmap) if args.envmap else (assets / DEMO_ENVMAP if args.lights is None else None)
    look = _settings(args)  # its yaw: _first_look, once the lights are known
    if args.record_frames < 1:
        raise InputError(None, f"--record-frames must be at least 1, got {args.record_frames}")
    from .placed_lights import load_rig

    rig = load_rig(args.rig) if args.rig else ()  # before any window: a bad file is one line
    _check_fps(args)
    window = None
    if photo:
        from .app.window import Window

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
        lights = _lights(args, look, args.lights, env, env_path)
    except BaseException:
        if window is not None:
            window.release()
        raise
    look = _first_look(args, look, lights)
    from .app import ViewerConfig, run_viewer

    config = ViewerConfig(scene=scene, lights=lights, environment=env.pixels if env is not None else None,
                          env_path=Path(env_path) if env_path is not None else None, method=args.method,
                          options=_engine_options(args, look), look=look, out_dir=Path(args.out_dir),
                          record_frames=args.record_frames, fps=args.fps,
                          state_file=Path(args.state_file) if args.state_file else None,
                          bundled_maps=tuple(sorted((assets / "envmaps").glob("*.hdr"))), preset=look.preset,
                          window=window, rig=rig, max_size=args.max_size, device=args.device,
                          gl_threads=_gl_threads())
    return run_viewer(config)


def _gl_threads() -> int:
    """llvmpipe's threads in this process (sized at the start, viewer/cores.py; a user's own value kept)."""
    import os

    try:
        return max(int(os.environ.get("LP_NUM_THREADS", "2")), 1)
    except ValueError:
        return 2


def _first_look(args, look, lights):
    """The viewer's first look: the brightest light turned to the camera's side (a photo must not
    open lit from behind) unless a yaw was given (``--yaw``, or a saved ``--look``)."""
    from .lights import facing_yaw

    if args.yaw is not None or getattr(args, "look", None):
        return look
    return look.replace(yaw=facing_yaw(lights))


def _photo_bundle(photo, mask, device, window, max_size: int) -> Path:
    """The scene bundle of a photo: inferred once (its stages shown in the window), then taken
    from the cache."""
    from .inference import cached_bundle

    start = time.perf_counter()

    def progress(stage):
        print(f"  {stage} done ({time.perf_counter() - start:.1f} s)", flush=True)
        window.show_message(f"Preparing {Path(photo).name}: {stage} done")

    window.show_message(f"Preparing {Path(photo).name}: reading the photo, finding the person...")
    bundle, cached = cached_bundle(photo, mask, max_size=max_size, device=device, progress=progress, ctx=window.ctx)
    print(f"scene bundle of {photo}: {bundle} ({'from the cache' if cached else 'inferred now, cached for next time'}; "
          f"{time.perf_counter() - start:.1f} s)")
    return bundle


def cmd_infer(args) -> int:
    from .inference import STAGE_SHARES, bundle_target, infer, load_networks
    from .progress import TimeLeft

    target = bundle_target(args.output)
    _writable(target.parent, folder=True)
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
    from .envmap import load_envmap
    out = Path(args.output) if args.output else _beside_the_map(Path(args.map))
    if out is not None and out.suffix.lower() != ".json":
        raise InputError(out, "the light file is JSON: give a .json output path")
    if out is not None:
        _writable(out)
    if args.plot:
        if Path(args.plot).suffix.lower() != ".png":
            raise InputError(args.plot, "the plot is a PNG: give a .png path")
        _writable(args.plot)
        if out is not None and Path(args.plot).resolve() == out.resolve():
            raise InputError(args.plot, "is the light file's path too: give the plot its own")
    _not_an_input([p for p in (out, args.plot) if p], [args.map])
    n = _light_count_option(args.n, args.method)
    env = load_envmap(args.map, repair=args.repair)
    start = time.perf_counter()
    lights, cached = _fitted_lights(env, n, args.method, refit=args.refit)
    seconds = time.perf_counter() - start
    how = "from the cache" if cached else f"fitted in {seconds:.1f} s"
    if out is None:
        print(f"{len(lights)} area lights ({args.method}, {how}) -> the fitting cache (the map's folder is not "
              "writable; -o writes a light file)")
    else:
        lights.save(out, fit={"source": Path(args.map).name, "method": args.method, "n": args.n})
        print(f"{len(lights)} area lights ({args.method}, {how}) -> {out}")
    _warn_if_dark(lights, args.map)
    if args.plot:
        from .lightfit.plot import plot_lights

        print(f"wrote {plot_lights(env, lights, args.plot)}")
    return 0


def build_parser(plugins: dict | None = None) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="relight", description="Relight full-body photos of people under HDR environment maps.")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("demo", help="the whole path: the sample scene, then the bundled photo inferred and relit under "
                                    "the bundled maps")
    p.add_argument("-o", "--output", default="out", help="output folder (default out/)")
    _add_engine_args(p)
    _add_view_args(p, yaw_default=DEMO_YAW)
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("render", help="headless: a scene bundle under an environment map (or a light file) to "
                       "PNG + EXR, or a turntable video to MP4")
    p.add_argument("scene", help="scene bundle directory")
    p.add_argument("lights", nargs="?", help="area-light file (.json, or the paper's .npy); "
                   "default: lights fitted to --env (cached)")
    p.add_argument("--env", "--envmap", dest="envmap",
                   help="environment map (.hdr/.exr): the background, and the lights when no light file is given")
    p.add_argument("-n", "--lights-count", type=int, help="lights to fit to --env (default: the preset's, balanced 16)")
    p.add_argument("--method", choices=METHODS, default=DEFAULT_METHOD, help=f"fitting method (default {DEFAULT_METHOD})")
    p.add_argument("--repair", action="store_true", help="replace NaN/Inf map pixels with 0 (with a warning) instead of failing")
    p.add_argument("-o", "--out", "--output", dest="output", default="out/render.png",
                   help="a .png (one frame; the HDR EXR goes beside it) or a .mp4 (turntable video); default out/render.png")
    p.add_argument("--frames", type=int, help="video frames (default 120 for a .mp4)")
    p.add_argument("--fps", type=float, default=30.0, help="video frame rate (default 30)")
    p.add_argument("--turn", type=float, default=360.0, help="degrees the lighting turns over the video (default 360)")
    p.add_argument("--size", type=int, help="the maps at this many pixels on the longer side (default: the bundle's; the output keeps the frame's size)")
    p.add_argument("--rig", help="placed lights added to the map's, fixed to the camera: a rig saved from the viewer (JSON)")
    _add_engine_args(p)
    _add_view_args(p)
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("view", help="the interactive viewer: drag to turn the lighting, tune each light, record video")
    p.add_argument("scene", nargs="?", help="scene bundle directory, or a photo (its bundle is inferred once and cached; "
                   "default: the bundled sample)")
    p.add_argument("--mask", help="the photo's person mask (default: found automatically)")
    p.add_argument("--device", default="cpu", help="device for a photo's inference (default cpu)")
    p.add_argument("--env", "--envmap", dest="envmap", help="environment map (.hdr/.exr; default: a bundled map)")
    p.add_argument("--lights", help="area-light file to use instead of fitting lights to the map")
    p.add_argument("-n", "--lights-count", type=int, help="lights fitted to the map (default: the preset's, balanced 16; cached)")
    p.add_argument("--method", choices=METHODS, default=DEFAULT_METHOD, help=f"fitting method (default {DEFAULT_METHOD})")
    p.add_argument("--repair", action="store_true", help="replace NaN/Inf map pixels with 0 (with a warning) instead of failing")
    p.add_argument("--rig", help="placed lights to start with: a rig saved from the viewer's panel (JSON)")
    p.add_argument("--look", help="start from a saved look (a frame's JSON saved with S, or a state file); the "
                   "options below override its values")
    p.add_argument("--yaw", "--rotate", dest="yaw", type=float,
                   help="initial rotation of the lighting, degrees (default: the brightest light turned toward the camera)")
    p.add_argument("--tilt", type=float, help="initial tilt of the lighting, degrees (default 0)")
    p.add_argument("--exposure", type=_auto_or("stops"),
                   help="initial exposure, stops, or auto (default): a photo keeps its own brightness")
    ground = p.add_mutually_exclusive_group()
    ground.add_argument("--ground", action="store_const", const=True,
                        help="the person's shadow on the ground at the feet, over the background (a shadow catcher); "
                             "by default shown when the feet are in the frame and the map is behind the person")
    ground.add_argument("--no-ground", dest="ground", action="store_const", const=False, help="no shadow on the ground")
    p.add_argument("--backdrop-blur", type=_auto_or("degrees"),
                   help="the map behind the person blurred, degrees, or auto (default): as the photo's own background")
    p.add_argument("--visibility", choices=("soft", "refined", "hard", "none"), help="initial shadow mode (default soft)")
    p.add_argument("--size", type=int, help="the maps at this many pixels on the longer side (default: the bundle's)")
    p.add_argument("--max-size", type=int, default=2048, help="longer side of saved frames and videos at most (default 2048)")
    p.add_argument("--out-dir", default="relight-captures", help="where S (frames) and R / L (videos) write (default relight-captures/)")
    p.add_argument("--record-frames", type=int, default=120, help="frames of a 360 degree recording (default 120)")
    p.add_argument("--fps", type=float, default=30.0, help="frame rate of recordings (default 30)")
    p.add_argument("--state-file", help="write the viewer's state, widget positions and frame times to this JSON "
                   "after every change (for scripts and tests)")
    _add_engine_args(p)
    p.set_defaults(func=cmd_view)

    p = sub.add_parser("infer", help="photo -> scene bundle (the networks' maps, the photo's own lighting, its detail)")
    p.add_argument("photo", help="photo (PNG/JPEG, sRGB; EXIF rotation applied)")
    p.add_argument("--mask", help="person mask (PNG, person where > 50 %%, grey levels kept as a soft edge), the photo's "
                   "size; default: found automatically (MediaPipe)")
    p.add_argument("-o", "--output", required=True, help="scene bundle directory to write")
    p.add_argument("--size", type=int, default=512, help="pixels of the person's longer side in the maps, where the shadow "
                   "work runs (default 512)")
    p.add_argument("--max-size", type=int, default=2048, help="longer side of the bundle's frame: the photo's own size up "
                   "to this (default 2048)")
    p.add_argument("--device", default="cpu", help="cpu or cuda (default cpu)")
    p.add_argument("--networks", help="folder of network weights (default: the shipped ones in assets/networks)")
    p.set_defaults(func=cmd_infer)

    p = sub.add_parser("fit-lights", help="fit N area lights to an environment map (cached by map content)")
    p.add_argument("map", help="equirectangular environment map (.hdr or .exr)")
    p.add_argument("-n", type=int, default=16, help="number of area lights (default 16)")
    p.add_argument("-o", "--output", help="light file to write (default MAP.lights.json beside the map, which the viewer "
                                          "reads for that map; the fitting cache only where the map's folder is read-only)")
    p.add_argument("--method", choices=METHODS, default=DEFAULT_METHOD,
                   help="instant (the default, ~1 s): median cut + short refinement on small views; fast: the same on "
                        "the full views (~17 s); paper: the paper's optimization; "
                        "median-cut: initialization only")
    p.add_argument("--plot", help="also draw the lights on the map into this PNG")
    p.add_argument("--refit", action="store_true", help="ignore the cache and fit again")
    p.add_argument("--repair", action="store_true", help="replace NaN/Inf map pixels with 0 (with a warning) instead of failing")
    p.set_defaults(func=cmd_fit_lights)

    for name in sorted(plugins or {}):  # listed for --help; main() runs them with their own parser
        sub.add_parser(name, help=f"offline work (the lab, viewer/lab): see relight {name} --help")
    return parser


def command_plugins() -> dict:
    """Commands other installed code adds to ``relight`` (the ``relight.commands`` entry points:
    the lab's dataset, train and bench), by name; none is imported until it runs."""
    from importlib.metadata import entry_points

    return {ep.name: ep for ep in entry_points(group=COMMAND_GROUP)}


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    print(f"relight: warning: {message}", file=sys.stderr if file is None else file, flush=True)


def main(argv=None) -> int:
    import warnings

    argv = list(sys.argv[1:] if argv is None else argv)
    with warnings.catch_warnings():  # a warning is one line, like an error; the hook is put back after
        warnings.showwarning = _one_line_warning
        return _main(argv)


def _main(argv: list) -> int:
    try:
        plugins = command_plugins()
        if argv and argv[0] in plugins:
            return plugins[argv[0]].load()(argv[1:])
        args = build_parser(plugins).parse_args(argv)
        size_pools(work_threads())  # the cores idle now, not the machine's count (viewer/cores.py)
        return args.func(args)
    except InputError as exc:
        print(f"relight: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # the system refused a read or a write the checks could not foresee
        where = exc.filename if exc.filename is not None else None
        print(f"relight: error: {InputError(where, exc.strerror or str(exc))}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        print(_interrupted(exc), file=sys.stderr)
        return 130
    except Exception as exc:
        # native code that runs Python code (a module's initialisation) may turn the interruption
        # into its own exception ("ImportError: initialization failed", caused by the KeyboardInterrupt)
        cause = _interruption(exc)
        if cause is None:
            raise
        print(_interrupted(cause), file=sys.stderr)
        return 130


def _interruption(exc: BaseException) -> KeyboardInterrupt | None:
    """The KeyboardInterrupt an exception was raised from or while handling, if any."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def _interrupted(exc: KeyboardInterrupt) -> str:
    """The one line for an interruption: Ctrl-C, or the signal :func:`run` turned into one (its name
    in the exception), and what the work left where (its notes)."""
    by = f" ({exc.args[0]})" if exc.args and isinstance(exc.args[0], str) and exc.args[0].startswith("SIG") else ""
    return f"relight: interrupted{by}" + "".join(f"; {note}" for note in getattr(exc, "__notes__", ()))


def run() -> None:
    """The ``relight`` program: :func:`main`, then the exit handlers, then out at once. Python's own
    teardown of torch's and MediaPipe's modules took 1.2 s after a photo was inferred (the viewer
    took that long to go after Q); by then every output is written and closed. SIGTERM and SIGHUP
    interrupt like Ctrl-C (the viewer's window sets its own SIGTERM while it is open)."""
    import atexit
    import os
    import signal

    from .stop_signals import route_to_main_thread

    def stop(signum, _frame):  # SIGTERM and SIGHUP end the work as Ctrl-C does: temporary files removed, old outputs kept
        raise KeyboardInterrupt(signal.Signals(signum).name)

    for sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, stop)
    route_to_main_thread()  # never inside native code: llvmpipe's shader compiler crashed on one
    try:
        code = main()
    except KeyboardInterrupt as exc:  # before main's own handling began
        print(_interrupted(exc), file=sys.stderr)
        code = 130
    atexit._run_exitfuncs()  # what registered for the exit (logging's flush, ...) still runs
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


if __name__ == "__main__":
    run()
