"""``relight bench colour --set DIR ...``: whether the person stays themselves under new light.

Every photo of the folders given is inferred as ``relight infer`` does it and relit as ``relight
render`` relights it (automatic exposure, the default tone curve and yaw rule), then measured:

- **under a uniform white environment** (every direction the same white radiance; under it a
  surface shows its albedo's colour, which for a studio photo is the photo's own), over a
  transparent background: *drift*, the median over the person of the per-pixel distance in CIE
  1976 u'v' between the relit and the photo's colour (8-bit sRGB decoded to linear, D65), its 90th
  percentile, and *cast*, the distance between the two images' median u'v'; pixels 3 px inside the
  alpha >= 0.95 outline, relative luminance >= 0.02 in both, no channel >= 0.98 in either;
- **under one side key light** (``KEY``: direction [0.866, 0, 0.5], sigma 1, intensity 3, as a
  light file gives it, so at its own direction) over the photo's own background: the 90th
  percentile of the face skin's relit luminance against the photo's, in stops, the share of the
  face skin with a channel at 250 or above, and how far the photo's own backdrop moved (the median
  absolute difference of its 8-bit values away from the person);
- the same face figures under the studio and park maps (their automatic yaw);
- a contact sheet (``colour_<stem>.jpg``, in the output folder only): the photo, the person under
  white, under the studio map and under the key, cut at 100 % around the face, the hair and the
  clothes.

*Studio* photos are those on a plain, smooth backdrop (:func:`studio`: the photo's border within
``STUDIO_DELTA_E`` of its median colour, and no texture there): a seamless studio paper lit by
studio lamps (or snow under an overcast sky), whose light is near-neutral, so the photo's colours
are the person's own and the white environment must give them back. The targets hold on those;
the others are reported.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from viewer.files.imageio import srgb_to_linear, write_text
from viewer.gl import Engine, EngineOptions, create_headless_context
from viewer.lab.bench.face_metrics import face_skin
from viewer.lab.bench.photo_set import _crop_boxes, _srgb8, collect, contact_sheet, halves
from viewer.lighting.envmap import EnvMap, load_envmap
from viewer.lighting.lightfit import lights_for_map
from viewer.output.render import render_look
from viewer.photo.inference import infer_scene, load_networks
from viewer.resize import resize
from viewer.scene.area_lights import AreaLights, facing_yaw
from viewer.scene.look import AUTO, Look

MAPS = {"studio": "studio_small_03_1k", "park": "rooitou_park_1k"}
KEY = AreaLights(np.array([[0.866, 0.0, 0.5]], np.float32) / np.float32(np.hypot(0.866, 0.5)),
                 np.array([1.0], np.float32), np.full((1, 3), 3.0, np.float32))
EDGE = 3  # px inside the alpha >= CORE_ALPHA outline
CORE_ALPHA = 0.95
DARKEST = 0.02  # relative luminance below which a pixel's chromaticity is not judged
CLIPPED = 0.98  # a channel at this (encoded) value or above is clipped
SKIN_CLIPPED = 250  # 8-bit: a face skin pixel with a channel at this or above is blown out
BACKDROP_AWAY = 0.03  # of the frame's longer side: the backdrop this far from the person
# sRGB primaries to CIE XYZ (D65)
XYZ = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]])
STUDIO_DELTA_E = 6.0  # CIE76: the border's median distance to its median colour below this
STUDIO_TEXTURE = 0.3  # the border's median |Laplacian| of L* (blurred by 1 px) at 600 px, below this
TARGETS = {"drift": 0.005, "cast": 0.004, "key_p90_stops": 0.5, "key_skin_clipped": 0.005}


def uv(linear: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(CIE 1976 u'v' (..., 2), relative luminance Y) of linear sRGB."""
    xyz = np.asarray(linear, np.float64) @ XYZ.T
    d = np.maximum(xyz[..., 0] + 15.0 * xyz[..., 1] + 3.0 * xyz[..., 2], 1e-12)
    return np.stack([4.0 * xyz[..., 0] / d, 9.0 * xyz[..., 1] / d], axis=-1), xyz[..., 1]


def studio(photo8: np.ndarray) -> bool:
    """Whether the photo's backdrop is a studio's: plain (its border's median CIE76 distance to its
    median colour under ``STUDIO_DELTA_E``) and smooth (the median |Laplacian| of its lightness,
    the photo brought to 600 px, under ``STUDIO_TEXTURE``: no street, wall or stairs)."""
    import cv2

    from viewer.lab.bench.metrics import border, cielab

    s = 600.0 / max(photo8.shape[:2])
    small = resize(photo8, (round(photo8.shape[1] * s), round(photo8.shape[0] * s)), "area") if s < 1 else photo8
    lab = cielab(np.ascontiguousarray(small))
    edge = border(lab)
    lap = np.abs(cv2.Laplacian(cv2.GaussianBlur(lab[..., 0], (0, 0), 1.0), cv2.CV_32F))
    return bool(np.median(np.linalg.norm(edge - np.median(edge, axis=0), axis=-1)) < STUDIO_DELTA_E
                and np.median(border(lap[..., None])) < STUDIO_TEXTURE)


def colour_drift(relit8: np.ndarray, photo8: np.ndarray, alpha: np.ndarray) -> dict | None:
    """drift (median), its 90th percentile and cast between the relit and the photo's colours over
    the person (both 8-bit sRGB, the same frame; see the module's docstring). None with fewer than
    50 pixels to judge."""
    import cv2

    core = cv2.erode((alpha >= CORE_ALPHA).astype(np.uint8), np.ones((2 * EDGE + 1, 2 * EDGE + 1), np.uint8)) > 0
    p, r = photo8.astype(np.float64) / 255.0, relit8[..., :3].astype(np.float64) / 255.0
    (up, yp), (ur, yr) = uv(srgb_to_linear(p)), uv(srgb_to_linear(r))
    ok = core & (yp >= DARKEST) & (yr >= DARKEST) & (p.max(-1) < CLIPPED) & (r.max(-1) < CLIPPED)
    if ok.sum() < 50:
        return None
    d = np.linalg.norm(ur[ok] - up[ok], axis=-1)
    shift = np.median(ur[ok], axis=0) - np.median(up[ok], axis=0)
    return {"drift": round(float(np.median(d)), 5), "drift_p90": round(float(np.percentile(d, 90)), 5),
            "cast": round(float(np.linalg.norm(shift)), 5), "cast_uv": [round(float(v), 5) for v in shift],
            "pixels": int(ok.sum())}


def face_light(relit8: np.ndarray, photo8: np.ndarray, skin: np.ndarray) -> dict:
    """The face skin's relit brightness against the photo's: the 90th percentile of its relative
    luminance, relit over photo, in stops, and the share of it with a channel at ``SKIN_CLIPPED``
    or above."""
    yr = uv(srgb_to_linear(relit8[..., :3].astype(np.float64) / 255.0))[1][skin]
    yp = uv(srgb_to_linear(photo8.astype(np.float64) / 255.0))[1][skin]
    stops = np.log2(max(float(np.percentile(yr, 90)), 1e-6) / max(float(np.percentile(yp, 90)), 1e-6))
    return {"p90_stops": round(float(stops), 3),
            "clipped": round(float((relit8[..., :3][skin] >= SKIN_CLIPPED).any(axis=-1).mean()), 5)}


def backdrop_moved(relit8: np.ndarray, photo8: np.ndarray, alpha: np.ndarray) -> float | None:
    """The median absolute 8-bit difference between the relit picture's backdrop (``--background
    photo``) and the photo's, away from the person."""
    import cv2

    r = max(1, int(BACKDROP_AWAY * max(alpha.shape)))
    away = cv2.dilate((alpha > 0.02).astype(np.uint8), np.ones((2 * r + 1, 2 * r + 1), np.uint8)) == 0
    if away.sum() < 50:
        return None
    return round(float(np.median(np.abs(relit8[..., :3][away].astype(np.float64) - photo8[away]))), 2)


def _display(eng, scene, lights, env, look: Look) -> np.ndarray:
    render_look(eng, scene, lights, look, env)
    if look.background == "transparent":
        return eng.output.read_display_rgba()
    return eng.output.read_display()


def measure_photo(path: Path, part: str, ctx, nets, lightings: dict, out_dir: Path | None) -> dict:
    """One photo's row (see the module's docstring)."""
    t = time.perf_counter()
    result = infer_scene(path, networks=nets, ctx=ctx)
    infer_s = time.perf_counter() - t
    scene = result["scene"]
    photo8, alpha = _srgb8(scene.frame.photo), scene.frame.alpha
    found = face_skin(photo8, alpha)
    skin, rec = found if found is not None else (None, None)
    has_skin = skin is not None and skin.sum() >= 50
    row = {"photo": path.name, "half": part, "studio_backdrop": studio(photo8), "frame": [alpha.shape[1], alpha.shape[0]],
           "infer_s": round(infer_s, 2), "face_pixels": int(skin.sum()) if skin is not None else 0}
    eng = Engine(ctx, scene, EngineOptions())
    tiles = {}
    try:
        white_lights, white_env = lightings["white"]
        tiles["white"] = _display(eng, scene, white_lights, white_env, Look(exposure=AUTO, background="transparent"))
        row["white"] = colour_drift(tiles["white"], photo8, alpha)
        tiles["key"] = _display(eng, scene, KEY, None, Look(exposure=AUTO, background="photo"))
        row["key"] = {**(face_light(tiles["key"], photo8, skin) if has_skin else {}),
                      "backdrop_moved": backdrop_moved(tiles["key"], photo8, alpha)}
        for name in MAPS:
            lights, env = lightings[name]
            tiles[name] = _display(eng, scene, lights, env, Look(yaw=facing_yaw(lights), exposure=AUTO))
            row[name] = {**(face_light(tiles[name], photo8, skin) if has_skin else {}),
                         "drift": colour_drift(tiles[name], photo8, alpha)}
    finally:
        eng.release()
    if out_dir is not None:
        boxes = _crop_boxes(scene, rec, {})
        if rec is None:  # no face found: the head's place unknown, the middle of the person
            ys, xs = np.nonzero(alpha > 0.5)
            s = max(int(0.11 * np.ptp(ys)), 48)
            boxes = {"middle": (int(xs.mean() - s / 2), int(ys.mean() - s / 2), s)}
        else:
            x, y, s = boxes["face"]
            boxes["clothes"] = (x, min(y + 2 * s, alpha.shape[0] - s), s)
        sheet = contact_sheet(out_dir / f"colour_{path.stem}.jpg", photo8, {k: tiles[k] for k in ("white", "studio", "key")}, boxes)
        row["contact_sheet"] = sheet.name if sheet else None
    return row


def summary(rows: list[dict]) -> dict:
    """Over the studio photos and over all: the worst and the median of each figure."""
    figures = {"drift": lambda r: r["white"]["drift"], "drift_p90": lambda r: r["white"]["drift_p90"],
               "cast": lambda r: r["white"]["cast"], "key_p90_stops": lambda r: r["key"].get("p90_stops"),
               "key_skin_clipped": lambda r: r["key"].get("clipped"), "key_backdrop_moved": lambda r: r["key"]["backdrop_moved"],
               "studio_map_p90_stops": lambda r: r["studio"].get("p90_stops"),
               "park_p90_stops": lambda r: r["park"].get("p90_stops"), "infer_s": lambda r: r["infer_s"]}
    out = {}
    for group in ("studio", "all"):
        chosen = [r for r in rows if group == "all" or r["studio_backdrop"]]
        g = {"photos": [r["photo"] for r in chosen]}
        for name, get in figures.items():
            vals = []
            for r in chosen:
                try:
                    v = get(r)
                except (KeyError, TypeError):
                    v = None
                if v is not None:
                    vals.append(v)
            if vals:
                worst = max(vals, key=abs) if name.endswith("stops") else max(vals)
                g[name] = {"worst": worst, "median": round(float(np.median(vals)), 5), "min": min(vals), "max": max(vals)}
        out[group] = g
    return out


def run_colour(dirs, maps_dir, out_dir="out/bench-colour", progress=print) -> dict:
    """Measure every photo of ``dirs``; write ``colour.json`` and the contact sheets into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    photos = collect(dirs)
    ctx = create_headless_context()
    nets = load_networks()
    white = EnvMap(np.ones((64, 128, 3), np.float32))
    lightings = {"white": (lights_for_map(white)[0], white.pixels)}
    for name, m in MAPS.items():
        env = load_envmap(Path(maps_dir) / f"{m}.hdr")
        lightings[name] = (lights_for_map(env)[0], env.pixels)
    parts = halves(photos)
    rows = []
    t = time.perf_counter()
    for k, path in enumerate(photos):
        row = measure_photo(path, parts[path.name], ctx, nets, lightings, out_dir)
        rows.append(row)
        w, key = row["white"] or {}, row["key"]
        progress(f"[{k + 1}/{len(photos)}] {path.name}{' (studio)' if row['studio_backdrop'] else ''}: drift {w.get('drift')} "
                 f"p90 {w.get('drift_p90')} cast {w.get('cast')}; key: face p90 {key.get('p90_stops')} stops, "
                 f"clipped {key.get('clipped')}, backdrop moved {key['backdrop_moved']} levels")
    result = {"photos": rows, "summary": summary(rows), "targets": TARGETS, "seconds": round(time.perf_counter() - t, 1),
              "command": "relight bench colour --set " + " ".join(str(d) for d in dirs)}
    write_text(out_dir / "colour.json", json.dumps(result, indent=1))
    return result
