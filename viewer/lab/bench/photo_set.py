"""``relight bench photos --set DIR ...``: the whole photo path on every photo of a set, per-photo
figures and a contact sheet of 100 % crops.

Every photo of the folders given (``.jpg``, ``.jpeg``, ``.png``; hand-made masks ``*.mask.png`` and
``*.auto-mask.png`` beside them are not photos) is inferred as ``relight infer`` does it (its time
per megapixel of the photo) and relit as ``relight batch`` relights it: the automatic yaw (the
map's brightest light on the camera's side) and the automatic exposure, under

- ``studio``: ``studio_small_03_1k`` (what a new user tries first: the lamp in front, 41 degrees up);
- ``park``: ``rooitou_park_1k`` (a hard low sun);
- ``front+fill``: one light from the front and 41 degrees above (sigma 1, intensity 3) and a dim
  fill (a second light from the camera, 10 degrees below, sigma 20, intensity 0.6): butterfly light.

Per photo and lighting: *holes* and *speckle* (:mod:`viewer.lab.bench.face_metrics`) on the face's
skin and on the limbs' skin. Per photo: *bleed* and *kept* on the final image (specular included)
rendered with a transparent background under ``potsdamer_platz_1k`` (overcast: nearly uniform; and the
bleed of the diffuse term alone, to tell the old background from a specular rim), kept
only meaningful on a plain backdrop (``plain``: the photo's border within ``PLAIN_DELTA_E`` of its
median; it counts the person's own clothes of the backdrop's colour, and *kept, enclosed* beside it
only what the person encloses: :func:`viewer.lab.bench.metrics.enclosed_backdrop`), *detail kept*
under the two maps, *light moved* between a sun from the left and from the right
(:mod:`viewer.lab.bench.metrics`), and *white shift*: how far the person's whites move in colour
under a neutral white light (:func:`white_shift`); under the key rig, what the light
scattered under the skin does to the face's edges (:func:`terminator`: sharper or softer, warmer);
*held*: the share of the person's pixels that are objects it holds or stands on, added to the
segmentation's person by :mod:`viewer.photo.held_objects` (0 where nothing is held).

The set is split in two halves by a hash of each file's name (``half`` "tune" or "held", every
other photo in the hash's order): constants
are chosen on "tune" and "held" is reported beside it, so a constant that only holds where it was
tuned shows. The contact sheet (``contact_<stem>.jpg`` per photo, in the output folder only, never in
the repository: the eval photos' terms forbid it) holds the photo and the person under four maps and
two rigs (a key from 60 degrees; the key and a rim), cut at 100 % around the face, the hair's edge,
the hands, the legs and the feet.
"""

from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path

import numpy as np

from viewer.files.imageio import linear_to_srgb, write_jpeg, write_text
from viewer.gl import Engine, EngineOptions, create_headless_context
from viewer.lab.bench.face_metrics import face_skin, holes, limb_skin, speckle
from viewer.lab.bench.metrics import bleed, border, cielab, detail_kept, enclosed_backdrop, kept_backdrop, light_moved, luminance
from viewer.lab.bench.photos import neutral_lights, sun_and_sky
from viewer.lighting.envmap import load_envmap
from viewer.lighting.lightfit import lights_for_map
from viewer.output.render import render_look
from viewer.photo.inference import infer_scene, load_networks
from viewer.scene.area_lights import AreaLights, facing_yaw
from viewer.scene.look import Look

PHOTO_SUFFIXES = (".jpg", ".jpeg", ".png")
MAPS = {"studio": "studio_small_03_1k", "park": "rooitou_park_1k"}
NEUTRAL = "potsdamer_platz_1k"
CONTACT_MAPS = ("studio_small_03_1k", "rooitou_park_1k", "venice_sunset_1k", "st_fagans_interior_1k")
WHITE_L, WHITE_C = 75.0, 15.0  # CIELAB: a photo pixel this light and at most this colourful is a white
PLAIN_DELTA_E = 10.0  # the border's median distance to its median colour (CIE76): below, a plain backdrop
CROP = 0.11  # of the person's height: the side of a contact-sheet crop (at 100 %)


def _lights(rows) -> AreaLights:
    d = np.array([r[0] for r in rows], np.float32)
    return AreaLights(d / np.linalg.norm(d, axis=1, keepdims=True), np.array([r[1] for r in rows], np.float32),
                      np.array([[r[2]] * 3 for r in rows], np.float32))


FRONT_FILL = _lights([((0.0, 0.656, 0.755), 1.0, 3.0), ((0.0, -0.17, 0.985), 20.0, 0.6)])
_KEY = (np.sin(np.radians(60)) * np.cos(np.radians(25)), np.sin(np.radians(25)), np.cos(np.radians(60)) * np.cos(np.radians(25)))
_RIM = (-np.sin(np.radians(150)) * np.cos(np.radians(20)), np.sin(np.radians(20)), np.cos(np.radians(150)) * np.cos(np.radians(20)))
RIGS = {"key 60": _lights([(_KEY, 2.0, 3.0), ((0.0, 0.3, 1.0), 20.0, 0.15)]),
        "key + rim": _lights([(_KEY, 2.0, 3.0), (_RIM, 2.0, 2.5), ((0.0, 0.3, 1.0), 20.0, 0.15)])}


def collect(dirs) -> list[Path]:
    photos = []
    for d in dirs:
        d = Path(d)
        files = [d] if d.is_file() else sorted(d.iterdir())
        photos += [p for p in files if p.suffix.lower() in PHOTO_SUFFIXES and not p.stem.endswith((".mask", ".auto-mask"))]
    return photos


def halves(photos: list[Path]) -> dict:
    """name -> "tune" or "held": the set ordered by a hash of each file's name, every other photo
    to each half (stable across runs, balanced, blind to what the photos show)."""
    ranked = sorted(photos, key=lambda p: hashlib.sha256(p.name.encode()).hexdigest())
    return {p.name: ("tune" if k % 2 == 0 else "held") for k, p in enumerate(ranked)}


def _srgb8(linear: np.ndarray) -> np.ndarray:
    return (np.clip(linear_to_srgb(np.clip(linear, 0, None)), 0, 1) * 255 + 0.5).astype(np.uint8)


def _plain(photo_srgb: np.ndarray) -> bool:
    edge = border(cielab(photo_srgb))
    return bool(np.median(np.linalg.norm(edge - np.median(edge, axis=0), axis=-1)) < PLAIN_DELTA_E)


def white_shift(relit8: np.ndarray, photo8: np.ndarray, alpha: np.ndarray) -> float | None:
    """The mean CIELAB chroma distance (a*, b*) between the photo and the relit image over the
    person's whites (the photo's pixels lighter than ``WHITE_L`` and less colourful than
    ``WHITE_C``, inside the matte away from its edge): a white that stays white under a neutral
    light keeps it near 0. None with fewer than 50 such pixels."""
    import cv2

    lab_p, lab_r = cielab(photo8), cielab(relit8)
    core = cv2.erode((alpha > 0.95).astype(np.uint8), np.ones((7, 7), np.uint8)) > 0
    whites = core & (lab_p[..., 0] > WHITE_L) & (np.linalg.norm(lab_p[..., 1:], axis=-1) < WHITE_C)
    if whites.sum() < 50:
        return None
    return float(np.linalg.norm(lab_r[whites][:, 1:] - lab_p[whites][:, 1:], axis=-1).mean())


def terminator(on: np.ndarray, off: np.ndarray, skin: np.ndarray) -> dict | None:
    """How the light scattered under the skin changes the face under a key light (``on`` and
    ``off``: linear renders with and without it), on the 10 % of the face's skin with the steepest
    edges without it: ``sharpness``, the mean relative luminance gradient |grad Y| / Y there, on
    over off (below 1: softer edges), and ``warmth``, the mean red over blue there, on over off
    (above 1: warmer edges). None on a face of under 50 skin pixels."""
    import cv2

    if skin.sum() < 50:
        return None

    def grad(img):
        y = np.maximum(luminance(img), 1e-4).astype(np.float32)
        g = np.hypot(cv2.Sobel(y, cv2.CV_32F, 1, 0), cv2.Sobel(y, cv2.CV_32F, 0, 1)) / 8.0
        return g / y

    g_on, g_off = grad(on)[skin], grad(off)[skin]
    edges = g_off >= np.percentile(g_off, 90)
    rb = lambda img: (img[..., 0] / np.maximum(img[..., 2], 1e-6))[skin][edges]  # noqa: E731
    return {"sharpness": _round(float(g_on[edges].mean()) / max(float(g_off[edges].mean()), 1e-9)),
            "warmth": _round(float(rb(on).mean()) / max(float(rb(off).mean()), 1e-9))}


def _render(eng, scene, lights, env, yaw, **look) -> tuple[np.ndarray, np.ndarray]:
    """(linear HDR RGB(A) of the output frame, display sRGB uint8) of one look."""
    look.setdefault("exposure", "auto")
    settings = Look(yaw=yaw, **look)
    render_look(eng, scene, lights, settings, env)
    rgba = look.get("background") == "transparent"
    return eng.output.read_output_hdr()[..., :4 if rgba else 3].copy(), eng.output.read_display()


def _round(v):
    return None if v is None else round(float(v), 4)


def lights_loader():
    """A map's fitted lights and pixels by its path, (AreaLights, pixels), each map loaded and
    fitted once."""
    loaded = {}

    def load(path: Path):
        if path not in loaded:
            env = load_envmap(path)
            loaded[path] = (lights_for_map(env)[0], env.pixels)
        return loaded[path]

    return load


def relit_person(eng, scene, light_cache, maps_dir: Path, **look) -> tuple[np.ndarray, np.ndarray]:
    """(the relit person's colour, not premultiplied, (H, W, 3); its alpha (H, W)) at the output
    frame, rendered over a transparent background under the neutral map (``NEUTRAL``) at its
    automatic yaw: what bleed is measured on."""
    neutral, env = light_cache(maps_dir / f"{NEUTRAL}.hdr")
    rgba, _ = _render(eng, scene, neutral, env, facing_yaw(neutral), background="transparent", **look)
    a = rgba[..., 3]
    return rgba[..., :3] / np.maximum(a, 1e-6)[..., None], a


def _crop_boxes(scene, skin_record, landmarks) -> dict:
    """name -> (x, y, side) of the contact sheet's crops in the output frame."""
    alpha = scene.frame.alpha
    h, w = alpha.shape
    ys, xs = np.nonzero(alpha > 0.5)
    height = float(ys.max() - ys.min() + 1) if len(ys) else float(h)
    side = max(int(CROP * height), 48)
    boxes = {}

    def at(name, x, y, s=side):
        boxes[name] = (int(np.clip(x - s / 2, 0, max(w - s, 0))), int(np.clip(y - s / 2, 0, max(h - s, 0))), min(s, w, h))

    if skin_record is not None:
        oy, ox = np.nonzero(skin_record["oval"])
        s = int(max(np.ptp(oy), np.ptp(ox)) * 1.6)
        at("face", ox.mean(), oy.mean(), s)
        at("hair", ox.mean() + 0.5 * np.ptp(ox), oy.min(), s)
    pts = {i: (x * w, y * h) for i, (x, y) in landmarks.items()}
    for name, ids in (("hand", (19, 20, 15, 16)), ("leg", (25, 26)), ("foot", (29, 30, 27, 28))):
        seen = [pts[i] for i in ids if i in pts]
        if seen:
            at(name, *seen[0])
    return boxes


SHEET_CELL = 320  # pixels of a contact sheet's cell: its crops at 100 % (tools/colour_figure.py reads this layout)
SHEET_LABEL = 120  # pixels of its label column


def contact_sheet(out: Path, photo8: np.ndarray, tiles: dict, boxes: dict) -> Path | None:
    """A contact sheet at ``out``: a row per picture (``photo8`` first, then ``tiles``: label -> uint8
    RGB or RGBA, the frame's size), a column per crop of ``boxes`` (name -> (x, y, side)), at 100 %:
    a crop larger than the cell shows its middle, a small one each pixel as a square of pixels, an
    RGBA one over the sheet's mid grey. None without crops."""
    from PIL import Image, ImageDraw

    if not boxes:
        return None
    cell = SHEET_CELL
    rows = [("photo", photo8)] + list(tiles.items())
    sheet = Image.new("RGB", (cell * len(boxes) + SHEET_LABEL, cell * len(rows)), (128, 128, 128))
    draw = ImageDraw.Draw(sheet)
    for r, (label, image) in enumerate(rows):
        draw.text((4, r * cell + 4), label, fill=(255, 255, 255))
        for c, (x, y, s) in enumerate(boxes.values()):
            crop = np.ascontiguousarray(image[y:y + s, x:x + s])
            if crop.shape[-1] == 4:
                a = crop[..., 3:].astype(np.float32) / 255.0
                crop = (crop[..., :3] * a + 128 * (1 - a) + 0.5).astype(np.uint8)
            tile = Image.fromarray(crop)
            if s > cell:
                o = (s - cell) // 2
                tile = tile.crop((o, o, o + cell, o + cell))
            elif 2 * s <= cell:
                k = cell // s
                tile = tile.resize((k * s, k * s), Image.NEAREST)
            sheet.paste(tile, (SHEET_LABEL + c * cell, r * cell))
    for c, name in enumerate(boxes):
        draw.text((SHEET_LABEL + c * cell + 4, 4), name, fill=(255, 255, 0))
    return write_jpeg(out, np.asarray(sheet).astype(np.float32) / 255.0, quality=90)


def measure_photo(path: Path, part: str, ctx, nets, maps_dir: Path, light_cache, out_dir: Path | None, progress=print) -> dict:
    """One photo's row (see the module's docstring)."""
    from viewer.photo.segmentation import find_person

    t = time.perf_counter()
    result = infer_scene(path, networks=nets, ctx=ctx)
    infer_s = time.perf_counter() - t
    scene = result["scene"]
    w0, h0 = result["record"]["photo_size"]
    photo = scene.frame.photo
    alpha = scene.frame.alpha
    photo8 = _srgb8(photo)
    row = {"photo": path.name, "half": part, "photo_size": [w0, h0], "frame": [alpha.shape[1], alpha.shape[0]],
           "infer_s": round(infer_s, 2), "infer_s_per_mp": round(infer_s / (w0 * h0 / 1e6), 3),
           "face_record": result["record"].get("face"),
           "held": _round(result["record"]["matte"].get("held_px", 0) / max(int((scene.frame.alpha > 0.5).sum()), 1))}
    found = face_skin(photo8, alpha)
    skin, rec = found if found is not None else (None, None)
    row["face"] = None if rec is None else {k: v for k, v in rec.items() if k != "oval"}
    limbs = limb_skin(photo, alpha, skin, rec["oval"]) if skin is not None and skin.sum() >= 50 else None
    row["limb_pixels"] = None if limbs is None else int(limbs.sum())
    eng = Engine(ctx, scene, EngineOptions())
    tiles = {}
    try:
        lightings = {name: (light_cache(maps_dir / f"{m}.hdr")) for name, m in MAPS.items()}
        lightings["front+fill"] = (FRONT_FILL, None)
        figures = {}
        for name, (lights, env) in lightings.items():
            yaw = facing_yaw(lights) if env is not None else 0.0
            hdr, display = _render(eng, scene, lights, env, yaw)
            figures[name] = {"yaw": round(yaw, 1),
                             "holes": _round(holes(hdr, photo, skin)) if skin is not None else None,
                             "speckle_face": _round(speckle(hdr, photo, skin)) if skin is not None else None,
                             "speckle_limbs": _round(speckle(hdr, photo, limbs)) if limbs is not None else None}
            if env is not None:
                figures[name]["detail_kept"] = _round(detail_kept(display.astype(np.float32) / 255, photo8.astype(np.float32) / 255,
                                                                  alpha > 0.5))
        row["lightings"] = figures
        person, a = relit_person(eng, scene, light_cache, maps_dir)
        row["bleed"] = _round(bleed(person, a, photo))
        row["bleed_diffuse"] = _round(bleed(*relit_person(eng, scene, light_cache, maps_dir, specular=False), photo))
        row["plain_backdrop"] = _plain(photo8)
        row["kept"] = _round(kept_backdrop(a, photo8, a > 0.5))
        row["kept_enclosed"] = _round(kept_backdrop(a, photo8, a > 0.5, enclosed_backdrop(a, photo8)))
        if skin is not None:
            keyed = [_render(eng, scene, RIGS["key 60"], None, 0.0, background="color", exposure=0.0, skin=on)[0]
                     for on in (True, False)]
            row["terminator"] = terminator(keyed[0], keyed[1], skin)
        white = _render(eng, scene, neutral_lights(), None, 0.0, background="color")[1]
        row["white_shift"] = _round(white_shift(white, photo8, alpha))
        sides = [_render(eng, scene, sun_and_sky((sx, 0.35, 0.49)), None, 0.0, background="color")[0] for sx in (-0.8, 0.8)]
        row["light_moved"] = _round(light_moved(sides[0], sides[1], alpha > 0.5))
        if out_dir is not None:
            for m in CONTACT_MAPS:
                lights, env = light_cache(maps_dir / f"{m}.hdr")
                tiles[m.replace("_1k", "")] = _render(eng, scene, lights, env, facing_yaw(lights))[1]
            for name, rig in RIGS.items():
                tiles[name] = _render(eng, scene, rig, None, 0.0, background="color")[1]
    finally:
        eng.release()
    if out_dir is not None:
        try:
            landmarks = find_person(photo8, path).landmarks
        except Exception:  # noqa: BLE001 -- a photo the pose model misses still has its face crops
            landmarks = {}
        sheet = contact_sheet(out_dir / f"contact_{path.stem}.jpg", photo8, tiles, _crop_boxes(scene, rec, landmarks))
        row["contact_sheet"] = sheet.name if sheet else None
    progress(f"  {path.name}: " + ", ".join(f"{k} holes {v['holes']} speckle {v['speckle_face']}/{v['speckle_limbs']}"
                                            for k, v in row["lightings"].items()) + f"; bleed {row['bleed']} kept {row['kept']}")
    return row


def summary(rows: list[dict]) -> dict:
    """Per half: the worst and the mean of each figure over its photos."""
    out = {}
    for part in ("tune", "held", "all"):
        chosen = [r for r in rows if part == "all" or r["half"] == part]
        figures = {}
        for light in ("studio", "park", "front+fill"):
            for key in ("holes", "speckle_face", "speckle_limbs"):
                vals = [r["lightings"][light][key] for r in chosen if r["lightings"][light][key] is not None]
                if vals:
                    figures[f"{key} {light}"] = {"max": max(vals), "mean": round(float(np.mean(vals)), 4)}
        for key in ("bleed", "bleed_diffuse", "white_shift", "light_moved", "infer_s_per_mp"):
            vals = [r.get(key) for r in chosen if r.get(key) is not None]
            if vals:
                figures[key] = {"max": max(vals), "min": min(vals), "mean": round(float(np.mean(vals)), 4)}
        for key in ("kept", "kept_enclosed"):
            vals = [r[key] for r in chosen if r["plain_backdrop"] and r.get(key) is not None]
            if vals:
                figures[f"{key} (plain backdrops)"] = {"max": max(vals), "mean": round(float(np.mean(vals)), 4)}
        out[part] = {"photos": len(chosen), **figures}
    return out


def run_photo_set(dirs, maps_dir, out_dir="out/bench-photo-set", before=None, progress=print) -> dict:
    """Measure every photo of ``dirs``; write ``photo_set.json`` and the contact sheets into
    ``out_dir``; ``before``: an earlier run's photo_set.json, kept beside this one's figures."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    maps_dir = Path(maps_dir)
    photos = collect(dirs)
    ctx = create_headless_context()
    nets = load_networks()
    light_cache = lights_loader()
    rows = []
    parts = halves(photos)
    t = time.perf_counter()
    for k, path in enumerate(photos):
        progress(f"[{k + 1}/{len(photos)}] {path.name} ({parts[path.name]} half)")
        rows.append(measure_photo(path, parts[path.name], ctx, nets, maps_dir, light_cache, out_dir, progress))
    result = {"photos": rows, "summary": summary(rows), "seconds": round(time.perf_counter() - t, 1),
              "command": "relight bench photos --set " + " ".join(str(d) for d in dirs)}
    if before:
        result["before"] = json.loads(Path(before).read_text())
    write_text(out_dir / "photo_set.json", json.dumps(result, indent=1))
    return result


def _cell(row: dict | None, get) -> str:
    try:
        v = get(row)
    except (KeyError, TypeError, ValueError):  # a figure the row lacks (no face: no skin)
        return "-"
    return "-" if v is None else f"{v:.3f}".rstrip("0").rstrip(".") if isinstance(v, float) else str(v)


COLUMNS = (("holes studio", lambda r: r["lightings"]["studio"]["holes"]),
           ("holes park", lambda r: r["lightings"]["park"]["holes"]),
           ("holes front+fill", lambda r: r["lightings"]["front+fill"]["holes"]),
           ("speckle face", lambda r: max(v["speckle_face"] for v in r["lightings"].values() if v["speckle_face"] is not None)),
           ("speckle limbs", lambda r: max(v["speckle_limbs"] for v in r["lightings"].values() if v["speckle_limbs"] is not None)),
           ("bleed", lambda r: r["bleed"]),
           ("bleed, diffuse term", lambda r: r.get("bleed_diffuse")),
           ("kept (plain)", lambda r: r["kept"] if r["plain_backdrop"] else None),
           ("kept, enclosed (plain)", lambda r: r["kept_enclosed"] if r["plain_backdrop"] else None),
           ("white shift", lambda r: r.get("white_shift")),
           ("detail kept", lambda r: r["lightings"]["studio"]["detail_kept"]),
           ("light moved", lambda r: r["light_moved"]),
           ("infer s/MP", lambda r: r["infer_s_per_mp"]),
           ("held (of the person)", lambda r: r["held"]),
           ("key: sharpness / warmth with skin", lambda r: f"{r['terminator']['sharpness']:.2f} / {r['terminator']['warmth']:.2f}"))


def set_table(result: dict) -> str:
    """The per-photo figures as a Markdown table, "before -> now" where an earlier run is given."""
    before = {r["photo"]: r for r in result.get("before", {}).get("photos", [])}
    lines = ["| photo | half | " + " | ".join(c for c, _ in COLUMNS) + " |", "|---|---|" + "---|" * len(COLUMNS)]
    for row in sorted(result["photos"], key=lambda r: (r["half"], r["photo"])):
        old = before.get(row["photo"])
        cells = [(_cell(old, get) + " -> " if old else "") + _cell(row, get) for _, get in COLUMNS]
        lines.append(f"| {row['photo'][:40]} | {row['half']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
