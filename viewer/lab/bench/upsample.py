"""``relight bench upsample``: the work frame's shading brought to the output frame, against a
reference whose work frame is the output frame.

Every photo of ``--photos`` is inferred (automatic matte) at several work sizes (the person
``--sizes`` pixels tall in the maps, shadow maps and per-light shading; the frame composite
upsamples to the output frame) and once with the work frame as large as the output frame (the
reference: nothing upsampled). Each is relit under two lightings (a bundled map turned to light the
person from the side, and a small key light over a dim sky, whose sharp shadow edges show blocks
first) in the hard and the default soft shadow mode, with the penumbra's smallest width
(``EngineOptions.pcss_min_texels``) at 0 (before: a sharp shadow's edge stepped from shadow-map
texel to texel) and at its default now, and compared with the reference (with the same
setting: what the upsampling loses) over the person:
RMSE of the display image (sRGB, [0, 1]) and of its gradients (a staircase shows as gradient error
along the shadow's edge). The time of a full frame at the output frame (the lighting turned) and
of a sigma step are measured for each work size (medians of ``--repeats``). Writes
``upsample.json`` and ``upsample.jpg`` (100 % crops of the key light's shadow edge).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from viewer.files.imageio import write_jpeg, write_text
from viewer.gl import Engine, EngineOptions, create_headless_context
from viewer.gl.context import describe
from viewer.lighting.envmap import load_envmap
from viewer.lighting.lightfit import lights_for_map
from viewer.lighting.placed_lights import PlacedLight, to_area_lights
from viewer.output.render import render_look
from viewer.photo.frames import WORK_PERSON
from viewer.photo.inference import infer_scene, load_networks
from viewer.resources import asset_dir
from viewer.scene.area_lights import AreaLights
from viewer.scene.look import Look

MAP = "venice_sunset_256"  # a bundled map, turned so its sun lights the person from the side
KEY = PlacedLight(azimuth=60.0, elevation=35.0, size=1.0, intensity=6.0)  # a hard key light
SIZES = (384, WORK_PERSON, 768, 1024)
SHADOWS = ("soft", "hard")
EDGES = (0.0, EngineOptions().pcss_min_texels)  # the penumbra's smallest sigma (texels): before, now (the default)


def _gradient(image: np.ndarray) -> np.ndarray:
    return np.concatenate([np.diff(image, axis=0)[:, :-1], np.diff(image, axis=1)[:-1]], axis=-1)


def lightings() -> dict:
    """name -> (map pixels or None, the map's lights, placed lights or None, yaw)."""
    env = load_envmap(asset_dir() / "envmaps" / f"{MAP}.hdr")
    lights = lights_for_map(env, 16)[0]
    sky = AreaLights(lights.direction, lights.sigma, lights.intensity * 0.05)
    return {"map": (env.pixels, lights, None, 200.0), "key light": (None, sky, to_area_lights([KEY]), 0.0)}


def render(engine, scene, lighting, shadows: str, exposure=None) -> tuple[np.ndarray, float]:
    """(display RGBA (H, W, 4) in [0, 1], the exposure used) of ``scene`` under ``lighting``."""
    env, lights, fixed, yaw = lighting
    look = Look(exposure="auto" if exposure is None else exposure, shadows=shadows, yaw=yaw, background="transparent")
    look, _ = render_look(engine, scene, lights, look, env, fixed)
    return engine.output.read_display_rgba().astype(np.float32) / 255.0, look.exposure_stops


def _times(engine, lighting, repeats: int) -> dict:
    """Median ms of a full frame (the lighting turned a little) and of a sigma step of the brightest light."""
    _, lights, fixed, yaw = lighting
    out = {}
    for name in ("turn", "sigma"):
        times = []
        for i in range(repeats):
            changed = lights
            if name == "sigma":
                k = lights.brightest
                changed = lights.with_sigma(k, float(lights.sigma[k]) * (1.0 + 0.05 * (i % 2 + 1)))
            engine.set_lights(changed, fixed)  # turned by the look's yaw, in the engine
            engine.set_look(engine.looks.asked.replace(yaw=yaw + (0.5 * (i % 2 + 1) if name == "turn" else 0.0)))
            t0 = time.perf_counter()
            engine.render()
            engine.ctx.finish()
            times.append(time.perf_counter() - t0)
        out[f"{name}_ms"] = 1000 * float(np.median(times))
    return out


def run_upsample_benchmark(photos, output_dir="out/bench-upsample", sizes=SIZES, repeats: int = 5, progress=None) -> dict:
    photos = Path(photos)
    paths = sorted(photos.glob("*.jpg"))
    if not paths:
        from viewer.errors import InputError

        raise InputError(photos, "no .jpg photos found")
    ctx = create_headless_context()
    nets = load_networks("cpu")
    lit = lightings()
    result: dict = {"machine": describe(ctx), "default_size": WORK_PERSON, "photos": []}
    crops = []
    start = time.perf_counter()
    for path in paths:
        reference = infer_scene(path, networks=nets, ctx=ctx, size=4096)["scene"]
        row: dict = {"photo": path.name, "frame": list(reference.output_size), "sizes": []}
        refs = {}  # each edge setting against the reference with the same setting: what upsampling loses
        for edge in EDGES:
            engine = Engine(ctx, reference, EngineOptions(pcss_min_texels=edge))
            try:
                for name, lighting in lit.items():
                    for shadows in SHADOWS:
                        refs[edge, name, shadows] = render(engine, reference, lighting, shadows)
            finally:
                engine.release()
        for size in sizes:
            scene = infer_scene(path, networks=nets, ctx=ctx, size=size)["scene"]
            entry: dict = {"size": size, "work": [scene.width, scene.height], "cases": []}
            for edge in EDGES:
                engine = Engine(ctx, scene, EngineOptions(pcss_min_texels=edge))
                try:
                    for name, lighting in lit.items():
                        for shadows in SHADOWS:
                            ref, exposure = refs[edge, name, shadows]
                            img, _ = render(engine, scene, lighting, shadows, exposure)
                            both = (ref[..., 3] > 0.5) & (img[..., 3] > 0.5)
                            err = img[..., :3] - ref[..., :3]
                            grad = _gradient(img[..., :3]) - _gradient(ref[..., :3])
                            entry["cases"].append({"lighting": name, "shadows": shadows, "min_texels": edge,
                                                   "rmse": float(np.sqrt((err[both] ** 2).mean())),
                                                   "gradient_rmse": float(np.sqrt((grad[both[:-1, :-1]] ** 2).mean()))})
                            if size == WORK_PERSON and name == "key light" and shadows == "soft":
                                crops.append((path.name, edge, img, ref))
                    if edge == EngineOptions().pcss_min_texels:  # the times at the default
                        entry.update(_times(engine, lit["map"], repeats))
                finally:
                    engine.release()
            row["sizes"].append(entry)
            if progress is not None:
                progress(f"{path.name}: work size {size}")
        result["photos"].append(row)
    result["seconds"] = round(time.perf_counter() - start, 1)
    out = Path(output_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_text(out / "upsample.json", json.dumps(result, indent=1) + "\n")
    _figure(crops, out / "upsample.jpg")
    return result


def _figure(crops, path):
    """Per photo, a 100 % crop (320 px) where the key light's shadow edge changes most between the
    work frame and the reference: before, now, reference."""
    from viewer.output.render import _label

    rows = []
    for name in dict.fromkeys(c[0] for c in crops):
        mine = {edge: (img, ref) for n, edge, img, ref in crops if n == name}
        before, now = mine[EDGES[0]][0], mine[EDGES[1]][0]
        ref = mine[EDGES[1]][1]
        diff = np.abs(before[..., :3] - ref[..., :3]).sum(-1) * (ref[..., 3] > 0.5)
        import cv2

        heat = cv2.boxFilter(diff, -1, (161, 161))
        cy, cx = np.unravel_index(np.argmax(heat), heat.shape)
        box = (slice(max(cy - 160, 0), max(cy - 160, 0) + 320), slice(max(cx - 160, 0), max(cx - 160, 0) + 320))

        def tile(img, text, box=box):
            rgb = img[..., :3] * img[..., 3:] + 0.5 * (1 - img[..., 3:])
            return _label(rgb[box], text)

        rows.append(np.concatenate([tile(before, f"{name}: work {WORK_PERSON}, before"),
                                    tile(now, f"work {WORK_PERSON}, now"), tile(ref, "reference: work = frame")], axis=1))
    width = min(r.shape[1] for r in rows)
    height = min(r.shape[0] for r in rows)
    write_jpeg(path, np.concatenate([r[:height, :width] for r in rows], axis=0))


def table(result: dict) -> str:
    lines = []
    for row in result["photos"]:
        lines.append(f"{row['photo']}: frame {row['frame'][0]}x{row['frame'][1]}")
        for e in row["sizes"]:
            lines.append(f"  work {e['size']} ({e['work'][0]}x{e['work'][1]}): full frame {e['turn_ms']:.0f} ms, "
                         f"sigma step {e['sigma_ms']:.0f} ms")
            for c in e["cases"]:
                lines.append(f"    {c['lighting']:9s} {c['shadows']:5s} min {c['min_texels']:.2f} texels: rmse {c['rmse']:.4f} "
                             f"gradient {c['gradient_rmse']:.4f}")
    return "\n".join(lines)
