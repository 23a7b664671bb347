"""The ``relight`` command line's options, declared once per command (the engine's and the view's
shared), and the commands other packages add (the lab's, through an entry-point group)."""

from __future__ import annotations

import argparse

from viewer.cli.batch_command import add_batch_parser
from viewer.cli.commands import DEMO_YAW, cmd_demo, cmd_fit_lights, cmd_infer, cmd_render
from viewer.cli.plate_commands import cmd_plate_light
from viewer.cli.shared_options import (
    add_clip_range_args,
    add_device_arg,
    add_engine_args,
    add_map_light_args,
    add_view_args,
)
from viewer.cli.view_command import cmd_view
from viewer.lighting.lightfit import DEFAULT_METHOD, METHODS
from viewer.plate.environment import MAP_HEIGHT

COMMAND_GROUP = "relight.commands"


def add_plate_args(p, what: str):
    """--plate and where the person stands on it (render and view; batch's are its looks')."""
    p.add_argument("--plate", help="a background photo to put the person into, lit by the plate's own light (or --env's), "
                                   f"standing on its ground with their shadow; {what} (docs/plates.md)")
    p.add_argument("--at", help="with --plate: where the feet stand, X,Y as fractions of the plate's width and height "
                                "(default 0.5,0.88; a negative X as --at=-0.1,0.9)")
    p.add_argument("--height", type=float, help="with --plate: the person's height as a fraction of the plate's (default: "
                                                "what a 1.7 m person at --at is, seen from the plate's camera: its height "
                                                "read from the people standing in it, else eye height)")
    p.add_argument("--horizon", type=float, help="with --plate: the horizon's height, a fraction of the plate's from its top "
                                                 "(default: read from the plate's vertical edges; 0.5 when it has none)")
    p.add_argument("--front", metavar="MASK.png", help="with --plate: what of the plate stands in front of the person (a barbell, "
                                                   "a post), white on black at the plate's shape: drawn over them (the plate's "
                                                   "own people in front are found without it)")


def build_parser(plugins: dict | None = None) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="relight", description="Relight full-body photos of people under HDR environment maps.")
    sub = parser.add_subparsers(dest="command", required=True)
    _add_demo(sub)
    _add_render(sub)
    _add_view(sub)
    _add_infer(sub)
    _add_fit_lights(sub)
    _add_plate_light(sub)
    add_batch_parser(sub)

    for name in sorted(plugins or {}):  # listed for --help; main() runs them with their own parser
        sub.add_parser(name, help=f"offline work (the lab, viewer/lab): see relight {name} --help")
    return parser


def _add_demo(sub) -> None:
    """``relight demo``: the whole path on the bundled sample."""
    p = sub.add_parser("demo", help="the whole path: the sample scene, then the bundled photo inferred and relit under "
                                    "the bundled maps")
    p.add_argument("-o", "--output", default="out", help="output folder (default out/)")
    add_map_light_args(p, repair=False)
    add_engine_args(p)
    add_view_args(p, yaw_default=DEMO_YAW)
    p.set_defaults(func=cmd_demo)


def _add_render(sub) -> None:
    """``relight render``: headless renders: a bundle or a clip to PNG + EXR or MP4."""
    p = sub.add_parser("render", help="headless: a scene bundle under an environment map (or a light file) to "
                       "PNG + EXR, or a turntable video to MP4")
    p.add_argument("scene", help="scene bundle directory; or a clip (mp4, mov, webm, avi, mkv) or its clip bundle, "
                                 "relit into an MP4 with the clip's frames, timing and audio")
    p.add_argument("lights", nargs="?", help="area-light file (.json, or the paper's .npy); "
                   "default: lights fitted to --env (cached)")
    p.add_argument("--env", "--envmap", dest="envmap",
                   help="environment map (.hdr/.exr): the background, and the lights when no light file is given")
    add_map_light_args(p)
    p.add_argument("-o", "--out", "--output", dest="output", default="out/render.png",
                   help="a .png (one frame; the HDR EXR goes beside it) or a .mp4 (turntable video); default out/render.png")
    p.add_argument("--frames", type=int, help="video frames (default 120 for a .mp4)")
    p.add_argument("--fps", type=float, default=30.0, help="video frame rate (default 30)")
    p.add_argument("--turn", type=float, help="degrees the lighting turns over the video (default 360 for a turntable, "
                                              "0 for a clip)")
    add_clip_range_args(p)
    add_device_arg(p)
    p.add_argument("--size", type=int,
                   help="the maps at this many pixels on the longer side (default: the bundle's; the output keeps the frame's size)")
    p.add_argument("--rig", help="placed lights added to the map's, fixed to the camera: a rig saved from the viewer (JSON)")
    p.add_argument("--layers", action="store_true", help="a clip: also each frame's layers for compositors, an EXR "
                   "sequence in NAME.layers/ beside NAME.mp4 (docs/video.md); with --plate: the person, the shadow and "
                   "the plate as layers of OUT.exr; a photo's: relight batch --layers")
    p.add_argument("--per-light", action="store_true", help="with --layers: each light's diffuse light as a layer")
    add_plate_args(p, "OUT.png and OUT.exr; a clip: OUT.mp4, the person placed once on its first frame")
    p.add_argument("--force", action="store_true", help="replace files at the output paths that relight did not write")
    p.add_argument("--ray", help="a clip: its frames spread over a Ray cluster's workers, in ranges (inferred) and parts "
                                 "(relit): auto (the cluster this machine belongs to), an address, or local (one started "
                                 "for this run)")
    p.add_argument("--workers", type=int, help="with --ray: the workers, one CPU each (default: the cluster's CPUs)")
    add_engine_args(p)
    add_view_args(p)
    p.set_defaults(func=cmd_render)


def _add_view(sub) -> None:
    """``relight view``: the interactive viewer."""
    p = sub.add_parser("view", help="the interactive viewer: drag to turn the lighting, tune each light, record video")
    p.add_argument("scene", nargs="?", help="scene bundle directory, or a photo (its bundle is inferred once and cached; "
                   "default: the bundled sample), or a clip or its clip bundle, played with a timeline")
    p.add_argument("--mask", help="the photo's person mask (default: found automatically)")
    add_device_arg(p)
    p.add_argument("--env", "--envmap", dest="envmap", help="environment map (.hdr/.exr; default: a bundled map)")
    p.add_argument("--lights", help="area-light file to use instead of fitting lights to the map")
    add_map_light_args(p)
    p.add_argument("--rig", help="placed lights to start with: a rig saved from the viewer's panel (JSON)")
    add_plate_args(p, "drag the person to move them, the wheel scales them, S saves the composite")
    add_view_args(p, window=True)
    p.add_argument("--size", type=int, help="the maps at this many pixels on the longer side (default: the bundle's)")
    p.add_argument("--out-dir", default="relight-captures", help="where S (frames) and R / L (videos) write (default relight-captures/)")
    p.add_argument("--record-frames", type=int, default=120, help="frames of a 360 degree recording (default 120)")
    p.add_argument("--fps", type=float, default=30.0, help="frame rate of recordings (default 30)")
    p.add_argument("--state-file", help="write the viewer's state, widget positions and frame times to this JSON "
                   "after every change (for scripts and tests)")
    add_clip_range_args(p)
    add_engine_args(p)
    p.set_defaults(func=cmd_view, window=True)


def _add_infer(sub) -> None:
    """``relight infer``: photo or clip -> scene bundle."""
    p = sub.add_parser("infer", help="photo -> scene bundle (the networks' maps, the photo's own lighting, its detail)")
    p.add_argument("photo", help="photo (PNG/JPEG, sRGB; EXIF rotation applied), or a clip (mp4, mov, webm, avi, mkv; "
                                 "its rotation applied): a clip bundle, one scene bundle per frame, resumable")
    p.add_argument("--mask", help="person mask (PNG, person where > 50 %%, grey levels kept as a soft edge), the photo's "
                   "size; default: found automatically (MediaPipe)")
    p.add_argument("-o", "--output", required=True, help="scene bundle directory to write")
    p.add_argument("--size", type=int, default=512, help="pixels of the person's longer side in the maps, where the shadow "
                   "work runs (default 512)")
    p.add_argument("--max-size", type=int, default=2048, help="longer side of the bundle's frame: the photo's own size up "
                   "to this (default 2048)")
    add_device_arg(p)
    p.add_argument("--networks", help="folder of network weights (default: the shipped ones in assets/networks)")
    add_clip_range_args(p)
    p.set_defaults(func=cmd_infer)


def _add_fit_lights(sub) -> None:
    """``relight fit-lights``: an environment map -> N area lights."""
    p = sub.add_parser("fit-lights", help="fit N area lights to an environment map (cached by map content)")
    p.add_argument("map", help="equirectangular environment map (.hdr or .exr)")
    p.add_argument("-n", type=int, default=16, help="number of area lights (default 16)")
    p.add_argument("-o", "--output", help="light file to write (default MAP.lights.json beside the map, which the viewer "
                                          "reads for that map; the fitting cache only where the map's folder is read-only)")
    p.add_argument("--method", choices=METHODS, default=DEFAULT_METHOD,
                   help="instant (the default, ~1 s): median cut + short refinement on small views; fast: the same on "
                        "the full views (~5 s); paper: the paper's optimization; "
                        "median-cut: initialization only")
    p.add_argument("--plot", help="also draw the lights on the map into this PNG")
    p.add_argument("--refit", action="store_true", help="ignore the cache and fit again")
    p.add_argument("--force", action="store_true", help="replace files at -o and --plot that relight did not write")
    p.add_argument("--repair", action="store_true", help="replace NaN/Inf map pixels with 0 (with a warning) instead of failing")
    p.set_defaults(func=cmd_fit_lights)


def _add_plate_light(sub) -> None:
    """``relight plate-light``: a plate's light as an environment map."""
    p = sub.add_parser("plate-light", help="the light of a background photo (a plate) as an HDR environment map (.exr), "
                                           "to inspect, edit and give as --env")
    p.add_argument("plate", help="the plate: a photo (JPEG, PNG, TIFF; 8 or 16 bit); its EXIF focal length gives its field of view")
    p.add_argument("-o", "--output", required=True, help="the map to write (.exr, linear, in the plate's own units)")
    p.add_argument("--height", type=int, default=MAP_HEIGHT, help=f"the map's height in pixels (its width is twice it; "
                                                                     f"default {MAP_HEIGHT})")
    p.add_argument("--record", action="store_true", help="also print how the map was made (JSON)")
    p.add_argument("--force", action="store_true", help="replace a file at -o that relight did not write")
    p.set_defaults(func=cmd_plate_light)


def command_plugins() -> dict:
    """Commands other installed code adds to ``relight`` (the ``relight.commands`` entry points:
    the lab's dataset, train and bench), by name; none is imported until it runs."""
    from importlib.metadata import entry_points

    return {ep.name: ep for ep in entry_points(group=COMMAND_GROUP)}
