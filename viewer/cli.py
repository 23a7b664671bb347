"""``relight`` command line: thin wrappers that parse, call and print."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .errors import InputError
from .resources import asset_dir, sample_scene_dir

DEMO_ENVMAP = "envmaps/immenstadter_horn_256.hdr"
DEMO_LIGHTS = "envmaps/immenstadter_horn_256.lights.json"
DEMO_YAW = 180.0  # the map's sun is behind the figure at yaw 0; turned, it lights the front


def _engine_options(args):
    from .gl import EngineOptions

    return EngineOptions(shadow_resolution=args.shadow_resolution, shadow_step=args.shadow_step, terms=args.terms,
                         prefilter=args.prefilter)


def _add_engine_args(p):
    p.add_argument("--shadow-resolution", type=int, default=512, help="texels of each shadow map (default 512)")
    p.add_argument("--shadow-step", type=int, default=0, help="depth-mesh decimation for shadow maps (default 0 = auto)")
    p.add_argument("--terms", type=int, default=4, help="CSM Fourier terms (default 4 = 8 basis maps)")
    p.add_argument("--prefilter", choices=("pyramid", "exact"), default="pyramid", help="CSM pre-filtering (default pyramid)")


def _add_view_args(p, yaw_default=0.0):
    p.add_argument("--yaw", type=float, default=yaw_default, help=f"rotate the lighting about the vertical axis (degrees, default {yaw_default})")
    p.add_argument("--tilt", type=float, default=0.0, help="tilt the lighting (degrees)")
    p.add_argument("--exposure", type=float, default=0.0, help="exposure in stops (default 0)")
    p.add_argument("--tonemap", choices=("aces", "reinhard", "clamp"), default="aces")
    p.add_argument("--background", choices=("environment", "photo", "color"), default="environment")
    p.add_argument("--visibility", choices=("soft", "hard", "none"), default="soft",
                   help="shadows from the convolutional shadow map (soft), the shadow map (hard) or none")


def _render(scene_path, lights_path, envmap_path, out_dir, name, args) -> list[Path]:
    from .envmap import load_envmap
    from .gl import Engine, create_headless_context
    from .lights import load_lights
    from .render import RenderSettings, render_to_files
    from .scene import load_scene

    scene = load_scene(scene_path)
    lights = load_lights(lights_path)
    env = load_envmap(envmap_path).pixels if envmap_path else None
    ctx = create_headless_context()
    engine = Engine(ctx, scene, _engine_options(args))
    settings = RenderSettings(yaw=args.yaw, tilt=args.tilt, exposure=args.exposure, tonemap=args.tonemap,
                              background=args.background, visibility=args.visibility)
    try:
        return render_to_files(engine, scene, lights, out_dir, name, settings, environment=env)
    finally:
        engine.release()


def cmd_demo(args) -> int:
    assets = asset_dir()
    written = _render(sample_scene_dir(), assets / DEMO_LIGHTS, assets / DEMO_ENVMAP, args.output, "demo", args)
    print(f"rendered the sample scene under {DEMO_LIGHTS} (16 area lights):")
    for path in written:
        print(f"  wrote {path}")
    return 0


def cmd_render(args) -> int:
    out = Path(args.output)
    if out.suffix.lower() != ".png":
        raise InputError(out, "the display image is written as PNG: give a .png path (the EXR goes beside it)")
    written = _render(args.scene, args.lights, args.envmap, out.parent, out.stem, args)
    for path in written:
        print(f"wrote {path}")
    return 0


def cmd_bench(args) -> int:
    from .bench.engine import run_engine_benchmark

    if args.what == "engine":
        run_engine_benchmark(sizes=args.sizes, light_counts=args.lights, repeats=args.repeats,
                             output=args.output or "docs/bench_engine.json", twin=not args.no_twin)
    else:
        from .bench.shadows import run_shadow_benchmark

        run_shadow_benchmark(repeats=args.repeats, output=args.output or "docs/bench_shadows.json")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="relight", description="Relight full-body photos of people under HDR environment maps.")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("demo", help="render the bundled sample scene under the bundled environment's lights")
    p.add_argument("-o", "--output", default="out", help="output folder (default out/)")
    _add_engine_args(p)
    _add_view_args(p, yaw_default=DEMO_YAW)
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("render", help="render a scene bundle under a light file to PNG + EXR")
    p.add_argument("scene", help="scene bundle directory")
    p.add_argument("lights", help="area-light file (.json)")
    p.add_argument("--envmap", help="environment map (.hdr/.exr) drawn as the background")
    p.add_argument("-o", "--output", default="out/render.png", help="display PNG path; the EXR goes beside it")
    _add_engine_args(p)
    _add_view_args(p)
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("bench", help="benchmarks that print figures and save JSON")
    p.add_argument("what", choices=("engine", "shadows"),
                   help="engine: per-pass times; shadows: error against ray-traced ground truth vs time per knob")
    p.add_argument("--sizes", type=int, nargs="+", default=[512, 1024])
    p.add_argument("--lights", type=int, nargs="+", default=[8, 16, 32])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--no-twin", action="store_true", help="skip timing the torch twin")
    p.add_argument("-o", "--output", help="JSON path (default docs/bench_<what>.json)")
    p.set_defaults(func=cmd_bench)
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except InputError as exc:
        print(f"relight: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("relight: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
