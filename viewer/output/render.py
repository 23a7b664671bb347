"""Headless rendering to files: one scene, one light set, PNG + EXR (+ an optional passes sheet)."""

from __future__ import annotations

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from viewer.constants import TONEMAP_DESATURATION, TONEMAP_INPUT_MAX, TONEMAP_KNEE
from viewer.errors import InputError
from viewer.files.imageio import atomic_paths, linear_to_srgb, write_exr, write_png
from viewer.files.ownership import folder_lock
from viewer.scene.area_lights import AreaLights
from viewer.scene.bundle import Scene
from viewer.scene.look import AUTO, Look


def tonemap(rgb: np.ndarray, op: str) -> np.ndarray:
    """The display tone curves of shaders/tonemap.glsl, in numpy: ``rgb`` (..., 3) linear, exposed."""
    x = np.clip(np.asarray(rgb, np.float64), 0.0, TONEMAP_INPUT_MAX)
    if op == "neutral":
        peak = x.max(axis=-1, keepdims=True)
        d = 1.0 - TONEMAP_KNEE
        top = 1.0 - d * d / (np.maximum(peak, TONEMAP_KNEE) + d - TONEMAP_KNEE)
        g = 1.0 - 1.0 / (TONEMAP_DESATURATION * (peak - top) + 1.0)
        rolled = x * (top / np.maximum(peak, 1e-300)) * (1.0 - g) + top * g
        return np.where(peak <= TONEMAP_KNEE, x, rolled)
    if op == "aces":
        return np.clip((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)
    if op == "reinhard":
        return x / (1.0 + x)
    return np.clip(x, 0.0, 1.0)


def tonemap_curve(x: np.ndarray, op: str) -> np.ndarray:
    """The tone curve of grey values (luminance): :func:`tonemap` of ``x`` in every channel."""
    x = np.asarray(x, np.float64)
    return tonemap(np.repeat(x[..., None], 3, axis=-1), op)[..., 0]


METER = 90  # percentile of the metered region's luminance: its lit part (a key's shadow below it does not count)
METER_SKIN = 50  # work pixels at least to meter on (the face's skin, else all the skin, else the whole person)


def metered(scene: Scene) -> np.ndarray:
    """(H, W) bool of the work frame: what the automatic exposure meters. The face's skin (the
    frame's skin where its face is), else all the skin, else the whole person, whichever first has
    ``METER_SKIN`` pixels."""
    from viewer.resize import resize

    frame = scene.frame
    if frame is None or frame.skin is None:
        return scene.mask
    skin = scene.mask & (resize(frame.skin.astype(np.float32), (scene.width, scene.height)) > 0.5)
    if frame.face_box is not None:
        x, y, w, h = frame.face_box
        face = np.zeros_like(skin)
        face[int(y * scene.height):int(np.ceil((y + h) * scene.height)), int(x * scene.width):int(np.ceil((x + w) * scene.width))] = True
        if (skin & face).sum() >= METER_SKIN:
            return skin & face
    return skin if skin.sum() >= METER_SKIN else scene.mask


def photo_exposure(engine, scene: Scene, tonemap_op: str) -> float:
    """Exposure (stops) that shows the person's lit skin as bright as the photo shows it, as a
    photographer exposes for the key-lit face (0 for a scene without a photo): the ``METER``-th
    percentile of the relit luminance over the face's skin (:func:`metered`), tone-mapped,
    matches the photo's over the same pixels. A key light
    that leaves half the person in shadow exposes the lit half at the photo's level instead of
    lifting the shadow's (which blew the lit skin out), and a bright or dim map neither washes out
    black clothes nor sinks the person. Uses the engine's current work-resolution render."""
    from viewer.photo.detail import luminance

    if scene.photo is None or not scene.mask.any():
        return 0.0
    region = metered(scene)
    relit = luminance(engine.output.read_work_hdr()[region]).astype(np.float64)
    shown = luminance(scene.photo[region]).astype(np.float64)
    finite = np.isfinite(relit)
    if not finite.any():
        return 0.0
    r, p = float(np.percentile(relit[finite], METER)), float(np.percentile(shown[finite], METER))
    if not (r > 0 and p > 0):
        return 0.0
    # tone_curve(2^e r) = the photo's level up to the curve's knee (bisection: the curves increase monotonically);
    # a photo's level above it is a display value the camera gave, reached in proportion (not by inverting
    # the roll-off, which would lift a near-white face by stops)
    target = min(p, TONEMAP_KNEE)
    lo, hi = -30.0, 30.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if tonemap_curve(2.0 ** mid * r, tonemap_op) < target else (lo, mid)
    return float(np.clip(0.5 * (lo + hi) + np.log2(p / target), -20.0, 20.0))


UNSEEN_SHARE = 0.9  # of the person's pixels clipped to white (or black): the lights far too bright (dim) for the exposure


def warn_if_unseen(engine, scene: Scene, settings: Look, lit: bool) -> None:
    """One warning line when the person comes out white (lights far brighter than the exposure can
    show: light files allow intensities up to 1e20; a silhouette was all one got) or black though
    its lights are not all zero (``lit`` False: the command's own warning says so; a map of 1e-30
    everywhere, one lit texel in a black map): how many stops off, and what to do. Reads the
    engine's current render once."""
    from viewer.photo.detail import luminance
    from viewer.scene.look import EXPOSURE_LIMIT

    if not scene.mask.any():
        return
    lum = luminance(engine.output.read_work_hdr()[scene.mask]).astype(np.float64) * 2.0 ** settings.exposure
    shown = tonemap_curve(lum, settings.tonemap)
    if np.mean(shown >= 0.99) >= UNSEEN_SHARE:
        stops = float(np.log2(max(np.median(lum), 1e-30) / 0.18))
        lower = settings.exposure - stops
        advice = (f"try --exposure {lower:.0f}" if lower >= -EXPOSURE_LIMIT
                  else f"lower the lights' intensities (--exposure goes down to -{EXPOSURE_LIMIT:.0f} stops)")
        warnings.warn(f"the person comes out white: the lights are about {stops:.0f} stops brighter than exposure "
                      f"{settings.exposure:+.1f} shows; {advice}", stacklevel=2)
    if not lit or np.mean(shown < 1.0 / 255.0) < UNSEEN_SHARE:
        return
    peak = float(np.max(lum)) if lum.size else 0.0
    if not np.isfinite(peak) or peak <= 0.0:
        warnings.warn("the person comes out black: no light reaches it (are the lights all behind the camera, or the map "
                      "black?)", stacklevel=2)
        return
    stops = float(np.log2(0.18 / max(float(np.median(lum)), 1e-300)))
    higher = settings.exposure + stops
    advice = (f"try --exposure {higher:.0f}" if higher <= EXPOSURE_LIMIT
              else f"the lights are too dim to show (--exposure goes up to {EXPOSURE_LIMIT:.0f} stops): is the map nearly black?")
    warnings.warn(f"the person comes out black: the lights are about {stops:.0f} stops darker than exposure "
                  f"{settings.exposure:+.1f} shows; {advice}", stacklevel=2)


def _lit(lights: AreaLights, fixed: AreaLights | None) -> bool:
    """Whether any light, the map's or a placed one, gives light."""
    return bool(np.any(lights.intensity > 0) or (fixed is not None and np.any(fixed.intensity > 0)))


def resolve_exposure(engine, scene: Scene, settings: Look, soft_planes: bool = False) -> Look:
    """``settings`` with an "auto" exposure replaced by :func:`photo_exposure` of a render of
    them up to the display (which the exposure changes alone)."""
    if settings.exposure != AUTO:
        return settings
    engine.render(display=False, soft_planes=soft_planes)
    return replace(settings, exposure=photo_exposure(engine, scene, settings.tonemap))


def render_frame(engine, settings: Look, refiner=None, soft_planes: bool = False):
    """Render; in the refined shadow mode, also run the refinement network for these lights (once
    per lighting: ``refiner`` is a :class:`viewer.photo.refinement.Refiner`, made on first need).
    ``soft_planes``: see ``Engine.render``."""
    engine.render(soft_planes=soft_planes)
    if settings.shadows == "refined" and not engine.refined_current:
        from viewer.photo.refinement import Refiner, refine_engine

        refiner = refiner if refiner is not None else Refiner()
        refine_engine(engine, refiner)
        engine.render()
    return refiner


def render_look(engine, scene: Scene, lights: AreaLights, settings: Look, environment: np.ndarray | None = None,
                fixed: AreaLights | None = None, refiner=None, soft_planes: bool = False) -> tuple[Look, object]:
    """Render ``scene`` under ``lights`` (the map's, turned; the ``fixed`` placed lights) with the
    look ``settings``, the map ``environment`` behind (None: none given); returns (the look with an
    "auto" exposure resolved, the refiner :func:`render_frame` used). ``soft_planes``: see
    ``Engine.render``."""
    engine.set_environment(environment)
    engine.set_lights(lights, fixed)
    settings = settings.fitted(len(engine.lights))  # a look saved with more lights than these
    engine.set_look(settings)
    settings = resolve_exposure(engine, scene, settings, soft_planes)
    engine.set_look(settings)
    return settings, render_frame(engine, settings, refiner, soft_planes)


def render_to_files(engine, scene: Scene, lights: AreaLights, out_dir, name: str, settings: Look,
                    environment: np.ndarray | None = None, passes: bool = True, fixed: AreaLights | None = None,
                    png_name: str | None = None) -> list[Path]:
    """Render and write ``name.png`` (display; ``png_name``: the name as the user typed it, its case
    kept), ``name.exr`` (HDR) and ``name_passes.png`` (``fixed``: placed lights, ``Engine.set_lights``)."""
    out_dir = Path(out_dir)
    settings, _ = render_look(engine, scene, lights, settings, environment, fixed, soft_planes=passes)
    warn_if_unseen(engine, scene, settings, _lit(lights, fixed))
    transparent = engine.look.background == "transparent"
    display = (engine.output.read_display_rgba() if transparent else engine.output.read_display()).astype(np.float32) / 255.0
    hdr = engine.output.read_output_hdr()
    # the sheet shows both visibilities: rendered with the soft one whatever the shadows shown
    sheet = passes_sheet(engine, scene, display) if passes else None
    written = [out_dir / (png_name or f"{name}.png"), out_dir / f"{name}.exr"] + ([out_dir / f"{name}_passes.png"] if passes else [])
    out_dir.mkdir(parents=True, exist_ok=True)
    # all replaced together or none, and one render's set at a time (two renders to one -o at once:
    # the last to finish leaves its PNG, EXR and sheet, never a mix)
    with folder_lock(out_dir), atomic_paths(*written) as tmps:
        write_png(tmps[0], display)
        write_exr(tmps[1], hdr if transparent else hdr[..., :3])
        if sheet is not None:
            write_png(tmps[2], sheet)
    return written


def turntable_yaws(start: float, turn: float, frames: int) -> np.ndarray:
    """Yaw of each frame: ``frames`` equal steps over ``turn`` degrees from ``start``; a full turn
    leaves out the end, which is the first frame again, so the video loops seamlessly."""
    return start + turn * np.arange(frames) / frames if abs(turn) >= 360 else start + turn * np.arange(frames) / max(frames - 1, 1)


def render_turntable(engine, lights: AreaLights, path, settings: Look, frames: int, fps: float = 30.0, turn: float = 360.0,
                     environment: np.ndarray | None = None, progress=None, fixed: AreaLights | None = None) -> tuple[int, int]:
    """A relit video of the engine's scene, the lighting turning about the vertical axis (``frames`` frames over
    ``turn`` degrees, starting at ``settings.yaw``) written to ``path`` (H.264 MP4).
    ``progress(done, total)`` is called after every frame. Returns the video's (width, height)."""
    from viewer.output.video import VideoWriter

    if frames < 1:
        raise InputError(path, f"a video needs at least one frame, got {frames}")
    scene = engine.scene
    engine.set_environment(environment)
    refiner = None
    engine.set_lights(lights, fixed)
    settings = settings.fitted(len(engine.lights))
    engine.set_look(settings)
    settings = resolve_exposure(engine, scene, settings)  # one exposure for the whole turn
    width, height = engine.output_size
    with VideoWriter(path, width, height, fps=fps) as video:
        for i, yaw in enumerate(turntable_yaws(settings.yaw, turn, frames)):
            engine.set_look(replace(settings, yaw=float(yaw)))
            refiner = render_frame(engine, settings, refiner)
            if i == 0:
                warn_if_unseen(engine, scene, settings, _lit(lights, fixed))
            video.write(engine.output.read_display())
            if progress is not None:
                progress(i + 1, frames)
    return video.encoded_size


def passes_sheet(engine, scene: Scene, final: np.ndarray) -> np.ndarray:
    """A 2 x 4 picture of the inputs and intermediate passes, for looking rather than reading:
    albedo, normal, depth, specular | summed soft visibility, summed hard visibility, shading
    without shadows, ``final`` (the display image, float RGB or RGBA in [0, 1])."""
    m = scene.mask
    n = len(engine.lights)
    weights = engine.lights.intensity.mean(axis=1)
    soft = np.zeros(m.shape, np.float32)
    hard = np.zeros(m.shape, np.float32)
    shade = np.zeros(m.shape, np.float32)
    for i in range(n):
        out = engine.output.read_light(i)
        s = weights[i] * (out["diffuse"] + out["specular"])
        soft += s * out["visibility_soft"]
        hard += s * out["visibility_hard"]
        shade += s
    scale = max(float(np.percentile(shade[m], 99.5)), 1e-12) * 1.5 if m.any() else 1.0
    depth = scene.depth.copy()
    if m.any():
        lo, hi = depth[m].min(), depth[m].max()
        depth = np.where(m, 1.0 - (depth - lo) / max(hi - lo, 1e-9), 0.0)

    def grey(x):
        return np.repeat(np.clip(x, 0, 1)[..., None], 3, axis=-1)

    tiles = [
        linear_to_srgb(scene.albedo),
        np.where(m[..., None], scene.normal * 0.5 + 0.5, 0.0),
        grey(depth),
        grey(scene.specular),
        linear_to_srgb(grey(soft / scale)),
        linear_to_srgb(grey(hard / scale)),
        linear_to_srgb(grey(shade / scale)),
        final,
    ]
    if final.shape[-1] == 4:  # a transparent background, shown over grey
        final = tiles[-1] = final[..., :3] * final[..., 3:] + 0.5 * (1.0 - final[..., 3:])
    if final.shape[:2] != m.shape:  # the frame's image, shown at the maps' size
        from viewer.resize import resize

        tiles[-1] = resize(final.astype(np.float32), (m.shape[1], m.shape[0]))
    names = ["albedo", "normal", "depth", "specular", "soft shadows", "hard shadows (shadow map)",
             "shading, no shadows", "final"]
    tiles = [_label(t, name) for t, name in zip(tiles, names)]
    top = np.concatenate(tiles[:4], axis=1)
    bottom = np.concatenate(tiles[4:], axis=1)
    return np.concatenate([top, bottom], axis=0)


def _label(tile: np.ndarray, text: str) -> np.ndarray:
    """The tile with its name written in its top-left corner."""
    from PIL import Image, ImageDraw

    im = Image.fromarray((np.clip(tile, 0, 1) * 255 + 0.5).astype(np.uint8))
    draw = ImageDraw.Draw(im)
    box = draw.textbbox((4, 4), text)
    draw.rectangle((box[0] - 2, box[1] - 2, box[2] + 2, box[3] + 2), fill=(0, 0, 0))
    draw.text((4, 4), text, fill=(255, 255, 255))
    return np.asarray(im, dtype=np.float32) / 255.0
