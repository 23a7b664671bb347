"""``relight bench photos``: real photos relit at their own size, and the detail step measured.

For each photo of ``--photos`` (default the two shared ones), with the automatic mask:

- **mask**: the automatic matte's IoU and mean absolute difference against the hand-made mask
  beside the photo (``<stem>.mask.png``, evaluation only), the share of the photo in its soft
  band, and its time;
- **the matte in the output**: the person rendered with a transparent background
  under a neutral (white, uniform) map, as ``relight render --background transparent`` writes it:
  spill and cut of its alpha against the hand-made mask, bleed of its colours at the edge
  (:mod:`viewer.lab.bench.metrics`), and the same person composited on a plain pink backdrop by
  the hand-made mask, inferred again: the share of pink kept;
- **the photo's own lighting** before any detail step: the render of the network's maps under the
  lights fitted to the photo, against the photo's low-pass over the person (PSNR and SSIM, display
  sRGB), next to the same for the lights the inverse-rendering network guessed;
- **detail kept** (:func:`viewer.lab.bench.metrics.detail_kept`) of every detail method
  (:mod:`viewer.photo.detail`) and of the network's maps alone rendered at the maps' resolution and
  upsampled (what the product output before), under three maps;
- **light moved** (:func:`viewer.lab.bench.metrics.light_moved`): the person under a sun from the
  left and the same sun from the right (each with a dim sky);
- **time** of every inference stage, a full frame at the photo's size, and a slider update.

With ``--data`` (a held-out dataset, ``relight dataset make --split heldout``), every person's
lighting, written as an 8-bit sRGB photo, is inferred with its true mask and relit under its other
lighting: relit RMSE, SSIM and FLIP against the ray-traced truth with each detail method.

Writes ``photos.json`` and the figures ``photos_relit.jpg`` (photo, before, now, under each map) and
``photos_detail.jpg`` (a crop of the face, every method) into the output folder.
"""

from __future__ import annotations

import json
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from viewer.files.imageio import linear_to_srgb, write_jpeg, write_png, write_text
from viewer.gl import Engine, EngineOptions, create_headless_context
from viewer.gl.context import describe
from viewer.lab.bench.metrics import detail_kept, light_moved, metrics
from viewer.lighting.envmap import load_envmap
from viewer.lighting.lightfit import lights_for_map
from viewer.output.render import render_look
from viewer.photo import detail as detail_mod
from viewer.photo.frames import read_photo
from viewer.photo.inference import infer_scene, load_networks
from viewer.photo.shading_stages import with_detail
from viewer.resize import resize
from viewer.scene.area_lights import AreaLights
from viewer.scene.look import Look

FIGURE_MAPS = (("venice_sunset_1k", 200.0), ("studio_small_03_1k", 30.0), ("immenstadter_horn_1k", 180.0))
BEFORE = "before"  # the network's maps alone at the maps' resolution, upsampled: the output before this step
# the detail variants measured: label -> (viewer.photo.detail method, sharing scale; None = the default)
VARIANTS = {"network": ("network", None), "highpass": ("highpass", None), "quotient-plain": ("quotient", 0.0),
            "quotient": ("quotient", None)}
SUN = (0.8, 0.35, 0.49)  # a sun from the camera's right (x right, y up, z to the camera); mirrored for the left


def mask_iou(matte: np.ndarray, reference: np.ndarray) -> float:
    """Intersection over union of two masks thresholded at 50 %."""
    a, b = matte > 0.5, reference > 0.5
    union = (a | b).sum()
    return float((a & b).sum() / union) if union else 1.0


def read_reference_mask(path) -> np.ndarray:
    """A hand-made mask file as a boolean array (first channel > 127)."""
    from PIL import Image

    with Image.open(Path(path)) as im:
        arr = np.asarray(im)
    return (arr if arr.ndim == 2 else arr[..., 0]) > 127


def sun_and_sky(direction) -> AreaLights:
    """A sun (sigma 1, intensity 3) from ``direction`` over a dim sky (16 lights of the upper
    hemisphere, 0.05 each): the light-moved test's lighting."""
    from viewer.lighting.lightfit.fit import fibonacci_sphere

    sky = fibonacci_sphere(32)
    sky = sky[sky[:, 1] > 0]
    d = np.asarray(direction, np.float32)
    dirs = np.concatenate([d[None] / np.linalg.norm(d), sky]).astype(np.float32)
    sigma = np.concatenate([[1.0], np.full(len(sky), 8.0)]).astype(np.float32)
    inten = np.concatenate([[[3.0, 3.0, 3.0]], np.full((len(sky), 3), 0.05)]).astype(np.float32)
    return AreaLights(dirs, sigma, inten)


def _with_detail(result: dict, label: str) -> object:
    """The inferred scene with the detail albedo of the variant ``label`` (the frame's and the maps')."""
    sc = result["scene"]
    if label == BEFORE:
        albedo = np.where(sc.mask[..., None], resize(result["network_albedo_frame"], (sc.width, sc.height)), 0)
        return replace(sc, albedo=np.clip(albedo, 0, 1).astype(np.float32), frame=None).validate()
    method, shared = VARIANTS[label]
    return with_detail(sc, result["network_albedo_frame"], result["shading"], result["record"]["framing"]["side"],
                       result["foreground"], method, shared)[0]


def _render(engine, scene, lights, settings, env_pixels, frame_size) -> tuple[np.ndarray, np.ndarray]:
    """(display (H, W, 3) in [0, 1], person HDR (H, W, 3)) at the frame's size (a scene without a
    frame layer renders at its maps' size and is upsampled, as its output would be shown)."""
    render_look(engine, scene, lights, settings, env_pixels)
    display = engine.output.read_display().astype(np.float32) / 255.0
    hdr = engine.output.read_hdr()
    return resize(display, frame_size), resize(hdr, frame_size)


def _psnr_ssim(render: np.ndarray, target: np.ndarray, valid: np.ndarray) -> dict:
    from skimage.metrics import structural_similarity

    a, b = np.clip(linear_to_srgb(render), 0, 1), np.clip(linear_to_srgb(target), 0, 1)
    mse = float(np.mean((a[valid] - b[valid]) ** 2))
    rows, cols = np.flatnonzero(valid.any(axis=1)), np.flatnonzero(valid.any(axis=0))
    box = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
    am, bm = np.where(valid[..., None], a, 0)[box], np.where(valid[..., None], b, 0)[box]
    return {"psnr_db": float(10 * np.log10(1.0 / max(mse, 1e-12))),
            "ssim": float(structural_similarity(bm, am, data_range=1.0, channel_axis=-1, win_size=7))}


def _median_ms(fn, repeats: int = 5) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times) * 1000)


def _photo_row(path: Path, ctx, nets, maps, methods, progress) -> tuple[dict, dict]:
    """Every measurement of one photo, and its pictures for the figures."""
    row: dict = {"photo": path.name}
    notes: list = []
    photo = read_photo(path, notes)
    reference = path.with_name(path.stem + ".mask.png")
    t0 = time.perf_counter()
    result = infer_scene(path, None, networks=nets, ctx=ctx)
    if reference.is_file():
        matte = result["scene"].frame.alpha
        hand = resize(read_reference_mask(reference).astype(np.float32), (matte.shape[1], matte.shape[0])) > 0.5
        # mean |alpha - hand-made mask| (%) also counts a soft band too wide; soft band: 2 % < alpha < 98 %
        row["mask"] = {"iou": mask_iou(matte, hand), "mean_abs_percent": float(np.abs(matte - hand).mean() * 100),
                       "soft_band_percent": float(((matte > 0.02) & (matte < 0.98)).mean() * 100),
                       "seconds": result["stages"].times["mask"]}
    row["inference_seconds"] = dict(result["stages"].times)
    row["inference_seconds_total"] = round(time.perf_counter() - t0, 3)
    rec = result["record"]
    row["sizes"] = rec["sizes"]
    row["photo_lighting"] = rec["photo_lighting"]
    scene = result["scene"]
    frame_size = scene.output_size
    # the photo's own lighting, before any detail step: fitted lights against the network's guess
    valid, target = result["valid"], result["target"]
    row["explains_photo"] = {"fitted": _psnr_ssim(result["explained"], target, valid)}
    base = _with_detail(result, BEFORE)
    eng = Engine(ctx, base, EngineOptions())
    try:
        eng.set_lights(result["network_lights"])
        row["explains_photo"]["network"] = _psnr_ssim(eng.render().output.read_work_hdr(), target, valid)
    finally:
        eng.release()
    if progress is not None:
        progress(f"{path.name}: inferred")
    photo_frame = resize(photo, frame_size).astype(np.float32) / 255.0
    matte = scene.frame.alpha > 0.5
    pictures = {"photo": photo_frame, "matte": matte}
    row["matte"] = _matte_in_output(path, photo, frame_size, ctx, nets, result, reference)
    row["matte_seconds"] = result["record"]["matte"]["seconds"]
    row["background_blur"] = result["record"]["background_blur"]
    row["gloss"] = result["record"]["gloss"]
    if progress is not None:
        progress(f"{path.name}: the matte in the output")
    row["methods"] = {}
    settings = Look(exposure="auto", shadows="soft", background="environment")
    for method in (BEFORE, *methods):
        sc = base if method == BEFORE else _with_detail(result, method)
        eng = Engine(ctx, sc, EngineOptions())
        entry: dict = {"detail_kept": {}}
        try:
            for (name, yaw), (env, lights) in zip(FIGURE_MAPS, maps):
                display, _ = _render(eng, sc, lights, replace(settings, yaw=yaw), env.pixels, frame_size)
                entry["detail_kept"][name] = detail_kept(display, photo_frame, matte)
                pictures[method, name] = display
            suns = [_render(eng, sc, sun_and_sky(d), replace(settings, exposure=0.0, background="color"), None, frame_size)[1]
                    for d in (SUN, (-SUN[0], SUN[1], SUN[2]))]
            entry["light_moved"] = light_moved(suns[0], suns[1], matte)
            if method not in (BEFORE, "network", "highpass"):
                entry["own_lights"] = _own_lights(eng, sc, result["lights"])
            if method == detail_mod.DEFAULT:
                entry["times_ms"] = _frame_times(eng, result["lights"], maps[0])
        finally:
            eng.release()
        entry["detail_kept_mean"] = float(np.mean(list(entry["detail_kept"].values())))
        row["methods"][method] = entry
        if progress is not None:
            progress(f"{path.name}: {method}")
    return row, pictures


def neutral_lights() -> AreaLights:
    """16 equal lights over the sphere: a uniform white map, whose light has no colour nor direction."""
    from viewer.lighting.lightfit.fit import fibonacci_sphere

    dirs = fibonacci_sphere(16).astype(np.float32)
    return AreaLights(dirs, np.full(16, 12.0, np.float32), np.full((16, 3), 1.0 / 16, np.float32))


def transparent_render(ctx, scene, specular: bool = True) -> np.ndarray:
    """(H, W, 4): the relit person under :func:`neutral_lights` over a transparent background, as
    the EXR of ``relight render --background transparent`` holds it, its colour divided by the
    matte (linear HDR, not premultiplied) and the matte; ``specular`` False: the diffuse term alone
    (the person's own colours lit, without the white sheen a uniform sky puts on every outline)."""
    eng = Engine(ctx, scene, EngineOptions())
    try:
        look = Look(exposure=0.0, background="transparent", ground=False, specular=specular)
        eng.set_lights(neutral_lights())
        eng.set_look(look)
        eng.render()
        hdr = eng.output.read_output_hdr()
        alpha = hdr[..., 3:]
        return np.concatenate([hdr[..., :3] / np.maximum(alpha, 1e-6), alpha], axis=-1)
    finally:
        eng.release()


def _matte_in_output(path: Path, photo: np.ndarray, frame_size, ctx, nets, result: dict, reference: Path) -> dict:
    """Spill, cut and bleed of the output's matte and colours; kept on a pink backdrop."""
    from viewer.files.imageio import srgb_to_linear
    from viewer.lab.bench.metrics import bleed, kept_backdrop, on_backdrop, spill_cut
    from viewer.photo.frames import read_mask

    rgba = transparent_render(ctx, result["scene"])
    linear_photo = srgb_to_linear(resize(photo, frame_size).astype(np.float32) / 255.0)
    diffuse = transparent_render(ctx, result["scene"], specular=False)
    out = {"bleed": bleed(diffuse[..., :3], diffuse[..., 3], linear_photo),
           "bleed_with_specular": bleed(rgba[..., :3], rgba[..., 3], linear_photo)}
    if not reference.is_file():
        return out
    hand = np.clip(resize(read_mask(reference, photo.shape[:2], []), frame_size), 0, 1)
    out.update(spill_cut(rgba[..., 3], hand))
    pink = on_backdrop(resize(photo, frame_size), hand)
    with tempfile.TemporaryDirectory() as tmp:
        backdrop_path = write_png(Path(tmp) / f"{path.stem}-pink.png", pink / 255.0)
        on_pink = infer_scene(backdrop_path, networks=nets, ctx=ctx)["scene"]
    pink_rgba = transparent_render(ctx, on_pink)
    out["backdrop"] = {"kept": kept_backdrop(pink_rgba[..., 3], pink, hand), **spill_cut(pink_rgba[..., 3], hand),
                       "bleed": bleed(pink_rgba[..., :3], pink_rgba[..., 3], srgb_to_linear(pink.astype(np.float32) / 255.0))}
    return out


def _own_lights(eng, scene, lights) -> dict:
    """The output relit under the photo's own fitted lights against the photo, over the solid
    matte (alpha > 0.99): PSNR (display sRGB) and mean relative error (linear)."""
    eng.set_lights(lights)
    eng.set_look(Look(exposure=0.0, background="photo"))
    hdr = eng.render().output.read_hdr()
    m = scene.frame.alpha > 0.99
    a, b = np.clip(linear_to_srgb(hdr[m]), 0, 1), np.clip(linear_to_srgb(scene.frame.photo[m]), 0, 1)
    return {"psnr_db": float(10 * np.log10(1.0 / max(float(np.mean((a - b) ** 2)), 1e-12))),
            "relative_error": float(np.abs(hdr[m] - scene.frame.photo[m]).mean() / max(float(scene.frame.photo[m].mean()), 1e-12))}


def _frame_times(eng, lights, env_lights) -> dict:
    """Medians (ms) at the frame's size: the lighting turned (every pass), one light's intensity,
    one light's sigma (the sliders)."""
    env, lights = env_lights
    eng.set_environment(env.pixels)
    eng.set_lights(lights)
    state = {"yaw": eng.looks.asked.yaw, "k": 0}

    def turn():  # the engine turns the lights by the look's yaw
        state["yaw"] += 7.0
        eng.set_look(eng.looks.asked.replace(yaw=state["yaw"]))
        eng.render()
        eng.output.read_display()

    def intensity():
        state["k"] += 1
        eng.set_lights(AreaLights(lights.direction, lights.sigma, lights.intensity * (1.0 + 0.01 * state["k"])))
        eng.render()
        eng.ctx.finish()

    def sigma():  # the brightest light that shades the person (a light behind everyone does no work)
        state["k"] += 1
        s = lights.sigma.copy()
        shading = [i for i in np.argsort(-lights.intensity.sum(axis=1)) if eng.light_active(int(i))]
        s[int(shading[0])] = 2.0 + state["k"] % 7
        eng.set_lights(AreaLights(lights.direction, s, lights.intensity))
        eng.render()
        eng.ctx.finish()

    turn()
    return {"turn": _median_ms(turn), "intensity_slider": _median_ms(intensity), "sigma_slider": _median_ms(sigma),
            "output": list(eng.output_size)}


def _heldout(data: Path, ctx, nets, methods, limit, progress) -> dict:
    """Relit error of each detail method on held-out pairs (input lighting -> the other one)."""
    from PIL import Image

    from viewer.lab.data.loader import RelightDataset
    from viewer.nets.photo import exposure_scale
    from viewer.scene.area_lights import load_lights

    ds = RelightDataset(data, fields=("image", "background", "mask"))
    by_sample: dict = {}
    for i, (s, _) in enumerate(ds.items):
        by_sample.setdefault(s, []).append(i)
    pairs = [(idx[k], idx[(k + 1) % len(idx)]) for idx in by_sample.values() for k in range(min(len(idx), 2))]
    pairs = pairs[:limit] if limit else pairs
    rows: dict = {m: [] for m in methods}
    with tempfile.TemporaryDirectory() as tmp:
        for n, (src, tgt) in enumerate(pairs):
            item, target = ds[src], ds[tgt]
            sample, k_tgt = ds.items[tgt]
            image = (item["image"] + (1 - item["mask"]) * item["background"])
            s_in = float(exposure_scale(image[None], item["mask"][None]))
            srgb = linear_to_srgb(np.clip(s_in * image.permute(1, 2, 0).numpy(), 0, 1))
            photo, mask = Path(tmp) / f"{n}.png", Path(tmp) / f"{n}.mask.png"
            Image.fromarray((srgb * 255 + 0.5).astype(np.uint8)).save(photo)
            m = item["mask"][0].numpy() > 0.5
            Image.fromarray((m * 255).astype(np.uint8)).save(mask)
            result = infer_scene(photo, mask, networks=nets, ctx=ctx)
            lights = load_lights(sample / f"lighting_{k_tgt}" / "lights.json")
            s_t = float(exposure_scale(target["image"][None], target["mask"][None]))
            truth = s_t * target["image"].permute(1, 2, 0).numpy()
            tm = target["mask"][0].numpy() > 0.5
            for method in rows:
                sc = _with_detail(result, method)
                eng = Engine(ctx, sc, EngineOptions())
                try:
                    eng.set_lights(lights)
                    eng.set_look(Look(exposure=0.0, shadows="soft", background="color"))
                    relit = resize(eng.render().output.read_hdr(), (truth.shape[1], truth.shape[0]))
                finally:
                    eng.release()
                rows[method].append(metrics(s_t * relit, truth, tm, flip=True))
            if progress is not None:
                progress(f"held-out pair {n + 1}/{len(pairs)}")
    out = {"pairs": len(pairs), "people": len({ds.items[a][0] for a, _ in pairs}), "resolution": int(ds[0]["image"].shape[-1])}
    base = rows["network"]
    for method, values in rows.items():
        out[method] = {k: {"mean": float(np.mean([v[k] for v in values])), "std": float(np.std([v[k] for v in values]))}
                       for k in values[0]}
        # against the network's albedo alone, pair by pair: mean difference and its standard error
        for k in values[0]:
            d = np.array([v[k] for v in values]) - np.array([b[k] for b in base])
            out[method][k]["vs_network"] = {"mean": float(d.mean()),
                                            "stderr": float(d.std(ddof=1) / np.sqrt(len(d))) if len(d) > 1 else 0.0,
                                             "better_pairs": int((d < 0).sum() if k != "ssim" else (d > 0).sum())}
    return out


def run_photos_benchmark(photos, maps_dir, data=None, out_dir="out/bench-photos",
                         methods=tuple(VARIANTS), limit: int | None = None, progress=None) -> dict:
    photos_dir = Path(photos)
    paths = sorted(p for p in photos_dir.glob("*.jpg") if not p.name.endswith(".mask.png"))
    if not paths:
        from viewer.errors import InputError

        raise InputError(photos_dir, "no .jpg photos found")
    maps_dir = Path(maps_dir)
    out_dir = Path(out_dir)
    start = time.perf_counter()
    ctx = create_headless_context()
    nets = load_networks("cpu")
    maps = []
    for name, _ in FIGURE_MAPS:
        env = load_envmap(maps_dir / f"{name}.hdr")  # the full map behind the person, lights fitted at 256
        maps.append((env, lights_for_map(env.downsampled(256), 16)[0]))
    rows, pictures = [], []
    for path in paths:
        row, pics = _photo_row(path, ctx, nets, maps, methods, progress)
        rows.append(row)
        pictures.append(pics)
    result = {"machine": describe(ctx), "photos": rows, "maps": [m for m, _ in FIGURE_MAPS], "methods": list(methods),
              "default": detail_mod.DEFAULT}
    if data is not None:
        result["heldout"] = _heldout(Path(data), ctx, nets, methods, limit, progress)
    result["seconds"] = round(time.perf_counter() - start, 1)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_text(out_dir / "photos.json", json.dumps(result, indent=1) + "\n")
    _figures(pictures, rows, out_dir)
    return result


def _label(tile: np.ndarray, text: str) -> np.ndarray:
    from viewer.output.render import _label as label

    return label(tile, text)


def _figures(pictures: list, rows: list, out_dir: Path):
    """photos_relit.jpg: per photo two rows (photo, then before / now under each map), 480 px tall;
    photos_detail.jpg: a crop around the face of the photo, before, and every method, 320 px."""
    height = 480
    blocks = []
    for pics, row in zip(pictures, rows):
        h, w = pics["photo"].shape[:2]
        size = (int(round(w * height / h)), height)
        lines = []
        for method, label in ((BEFORE, "before"), (detail_mod.DEFAULT, "now")):
            first = _label(resize(pics["photo"], size), "photo") if method == BEFORE else np.ones((height, size[0], 3), np.float32)
            tiles = [first]
            for name, _ in FIGURE_MAPS:
                kept = row["methods"][method]["detail_kept"][name]
                tiles.append(_label(resize(pics[method, name], size), f"{label}: {name.split('_1k')[0]}, detail kept {kept:.2f}"))
            lines.append(np.concatenate(tiles, axis=1))
        blocks.append(np.concatenate(lines, axis=0))
    width = max(b.shape[1] for b in blocks)
    blocks = [np.pad(b, ((0, 8), (0, width - b.shape[1]), (0, 0)), constant_values=1.0) for b in blocks]
    write_jpeg(out_dir / "photos_relit.jpg", np.concatenate(blocks, axis=0))
    crops = []
    name = FIGURE_MAPS[0][0]
    for pics, row in zip(pictures, rows):
        matte = pics["matte"]
        rows_m = np.flatnonzero(matte.any(axis=1))
        side = max(int(0.2 * (rows_m[-1] - rows_m[0] + 1)), 16)  # the head: the top fifth of the person
        y0 = int(rows_m[0])
        band = np.flatnonzero(matte[y0:y0 + side].any(axis=0))
        x0 = int(np.clip((band[0] + band[-1]) // 2 - side // 2, 0, max(matte.shape[1] - side, 0)))
        methods = [BEFORE, *row["methods"].keys() - {BEFORE}]
        tiles = [_label(pics["photo"][y0:y0 + side, x0:x0 + side], "photo")]
        tiles += [_label(pics[m, name][y0:y0 + side, x0:x0 + side], m) for m in sorted(methods, key=str)]
        crops.append(np.concatenate([resize(t, (320, 320)) for t in tiles], axis=1))
    write_jpeg(out_dir / "photos_detail.jpg", np.concatenate(crops, axis=0))
