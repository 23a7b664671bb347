"""The options several commands share, declared once: the engine's (a preset and its knobs) and
what the user sees (a look and its fields)."""

from __future__ import annotations

import argparse

from viewer.scene.look import BACKGROUNDS, TONEMAPS, VISIBILITY_MODES


def add_engine_args(p, presets: bool = False):
    """The engine's options; ``presets``: several presets (``--preset A B``, dest ``presets``: a batch's looks)."""
    from viewer.gl.presets import DEFAULT_PRESET, PRESETS
    from viewer.gl.soft import soft_method_names

    p.add_argument("--preset", dest="presets" if presets else "preset", choices=tuple(PRESETS), nargs="+" if presets else None,
                   help=f"quality preset{'s (each look once with each)' if presets else ''}: lights and engine options from "
                        f"docs/results/results.md (default {DEFAULT_PRESET}); the options below override its values")
    p.add_argument("--soft", choices=soft_method_names(),
                   help="soft shadows: contact-hardening (pcss, the presets') or the paper's convolutional shadow maps (csm)")
    p.add_argument("--shadow-resolution", type=int, help="texels of each shadow map (preset's; balanced 512)")
    p.add_argument("--shadow-step", type=int, help="depth-mesh decimation for shadow maps (0 = auto, the presets' choice)")
    p.add_argument("--terms", type=int, help="with --soft csm: Fourier terms M, 2M basis maps (default 4)")
    p.add_argument("--prefilter", choices=("pyramid", "exact"), help="with --soft csm: pre-filtering (default pyramid)")


def auto_or(unit: str):
    """An option's parser: "auto" or a number of ``unit`` (its range is the look's to check, viewer.scene.look.Look)."""
    def parse(text: str):
        if text.strip().lower() == "auto":
            return "auto"
        try:
            return float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected 'auto' or a number of {unit}, got {text!r}") from None
    return parse


def add_map_light_args(p, repair: bool = True):
    """How a map's lights are found (viewer/lighting/map_lights.py): their count, the fitting method
    (its default decided here, once, for every command) and what to do with a damaged map."""
    from viewer.lighting.lightfit.methods import DEFAULT_METHOD, METHODS

    p.add_argument("-n", "--lights-count", type=int, help="lights fitted to each map (default: the preset's, balanced 16; "
                   "cached, or shipped beside the map)")
    p.add_argument("--method", choices=METHODS, default=DEFAULT_METHOD, help=f"fitting method (default {DEFAULT_METHOD})")
    if repair:
        p.add_argument("--repair", action="store_true", help="replace NaN/Inf map pixels with 0 (with a warning) instead of failing")


def add_ground_args(p):
    """``--ground`` / ``--no-ground``: the person's shadow on the ground (the view and the headless commands)."""
    ground = p.add_mutually_exclusive_group()
    ground.add_argument("--ground", action="store_const", const=True,
                        help="the person's shadow on the ground at the feet, over the background (a shadow catcher); "
                             "by default shown when the feet are in the frame and the map is behind the person")
    ground.add_argument("--no-ground", dest="ground", action="store_const", const=False, help="no shadow on the ground")


def add_view_args(p, yaw_default: float | None = None, yaws: bool = True, window: bool = False):
    """What the user sees, declared once for every command; ``yaws`` False: no ``--yaw`` here (a batch
    takes several); ``window``: the viewer's (what it starts with; no transparent background, no tone
    map: the panel sets them)."""
    start = "initial " if window else ""
    p.add_argument("--look", help="a saved look: the JSON of a frame saved in the viewer (S), its state file, or a look "
                   f"object (docs/architecture.md){' to start from' if window else ''}; the options below override its values")
    if yaws:
        p.add_argument("--yaw", "--rotate", dest="yaw", type=float,
                       help=f"{start}rotation of the lighting (and the map behind) about the vertical axis, degrees (default "
                            + (f"{yaw_default:g}" if yaw_default is not None else
                               "automatic: a map's brightest light on the camera's side, a light file of your own as "
                               "written") + ")" + ("" if window else "; a video starts there"))
    p.add_argument("--tilt", type=float, help=f"{start}tilt of the lighting (degrees, default 0)")
    p.add_argument("--exposure", type=auto_or("stops"),
                   help=f"{start}exposure in stops, or auto (default): a photo's relit person keeps the photo's brightness "
                        "(0 stops for a scene without a photo)")
    if not window:
        p.add_argument("--tonemap", choices=TONEMAPS, help="tone curve (default neutral: the photo's tones as they are up "
                       "to a knee, highlights rolled off keeping their hue; aces: the filmic curve, per channel)")
    p.add_argument("--background", choices=tuple(b for b in BACKGROUNDS if not (window and b == "transparent")),
                   help=f"behind the person{' at first' if window else ''}: the environment map seen through the photo's "
                        "camera (default), the photo's own background, a grey"
                        + ("" if window else ", or transparent (PNG and EXR with alpha)"))
    p.add_argument("--backdrop-blur", type=auto_or("degrees"),
                   help="the map behind the person blurred like a defocused background, degrees, or auto (default): "
                        "as much as the photo's own background is (0 for a scene without a photo)")
    p.add_argument("--max-size", type=int, default=2048,
                   help="longer side of the output (saved frames and videos) in pixels at most (default 2048; a photo's "
                        "bundle renders at the photo's own size up to this)")
    add_ground_args(p)
    skin = p.add_mutually_exclusive_group()
    skin.add_argument("--skin", action="store_const", const=True,
                      help="light scattered under a photo's skin: soft, warm terminators and shadow edges on faces and "
                           "limbs (the default)")
    skin.add_argument("--no-skin", dest="skin", action="store_const", const=False,
                      help="skin shaded as a surface, without the light scattered under it (to compare"
                           + ("; the panel's skin box turns it back on)" if window else ")"))
    p.add_argument("--visibility", choices=VISIBILITY_MODES,
                   help="shadows (default soft): soft (contact-hardening, or --soft csm), the shadow map (hard), none, "
                        "or the refinement network on the soft ones (refined)")


def add_device_arg(p) -> None:
    """``--device``: where a photo's or a clip's networks run (:mod:`viewer.nets.device`)."""
    from viewer.nets.device import DEFAULT_DEVICE, DEVICES

    p.add_argument("--device", default=DEFAULT_DEVICE, help=f"where a photo's networks run: {', '.join(DEVICES)} or cuda:N "
                   f"(default {DEFAULT_DEVICE}: CUDA where torch has it, else the CPU)")


def point_arg(text: str) -> tuple[float, float]:
    """X,Y: two fractions in [0, 1] (a point on the frame)."""
    try:
        x, y = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"give X,Y as two fractions of the frame, e.g. 0.4,0.5; got {text!r}") from None
    if not (0.0 <= x <= 1.0 and 0.0 <= y <= 1.0):
        raise argparse.ArgumentTypeError(f"X and Y are fractions of the frame's width and height, in [0, 1]; got {text!r}")
    return x, y


def add_clip_range_args(p) -> None:
    """--start and --end: the part of a clip to work on, seconds."""
    p.add_argument("--start", type=float, default=0.0, help="a clip: seconds from its start to begin at (default 0)")
    p.add_argument("--end", type=float, help="a clip: seconds from its start to stop at (default: its end)")
    p.add_argument("--temporal", choices=("on", "off"), help="a clip: on (default) estimates the photo's lighting and the "
                   "exposure once per shot; off relights every frame exactly as a photo (its own estimates), for comparison")
    p.add_argument("--person", type=point_arg, metavar="X,Y",
                   help="a clip: the person to relight, a point on them in the first frame anyone is in (fractions of its "
                        "width and height); default: the largest and most central, followed through the clip")
    p.add_argument("--people", choices=("one", "all"),
                   help="a clip: one (default) relights the person chosen (others are left in the old scene's place); "
                        "all relights everyone")
