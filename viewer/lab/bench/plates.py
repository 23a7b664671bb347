"""``relight bench plates``: the light read from a plate against the map the plate was made from.

For each HDR map of a folder, three plates are made from the map itself: the plate camera
(``PLATE_SIZE`` pixels, a ``PLATE_FOCAL_35`` mm lens, level) looking into it at yaws 0, 120 and 240
degrees, linear radiance scaled so the plate's median luminance is 0.18, sRGB-encoded, clipped and
written as an 8-bit JPEG with the focal length in its EXIF (as a camera writes it). Each plate is
read back as the product reads any plate, and its light estimated
(:func:`viewer.plate.environment.plate_light`, then 16 area lights fitted to that map as to any map).
The person (the sample scene, and the bundled photo's bundle) is relit four ways, in the plate's
linear units:

- **truth**: under the true map's 16 lights, turned by the plate's yaw, scaled by the plate's scale
  (the full renderer: diffuse, specular, shadows);
- **estimate**: under the lights fitted to the estimated map (the same renderer);
- **uniform**: a uniform light of the plate's mean linear colour (Lambert, no shadows);
- **sh**: an order-2 spherical-harmonics light fitted to the plate's linear pixels placed on the
  sphere as the estimate places them (seen, edge-filled, mirrored; no clip gain) (Lambert,
  no shadows; :mod:`viewer.lighting.sh`).

Per plate: the RMSE of each against the truth over the person's pixels (the scene's mask at the
maps' resolution), and where the true map has a dominant light (its strongest fitted light, with
those within ``CLUSTER_DEG`` of it, holds ``DOMINANT_SHARE`` of the lights' luminance or more; both
:mod:`viewer.lighting.dominant`'s), the angle between it and the estimate's strongest light (grouped the same way)
(``direction_deg``), and the angle between the two maps' brightest directions after a 5-degree blur
(``brightest_deg``: a measure no fit's split of a sun moves), and each cue to a sun alone
(``cues``: the clear sky's, the people's shadows' and their shading's, the degrees off where it reads one). The JSON's ``summary``
holds the means over all plates (``estimate``, ``uniform``, ``sh``), ``direction_deg_median``,
``brightest_deg_median``, and the medians over
plates of each plate's ratio (``estimate_over_uniform_median``, ``estimate_over_sh_median``).
"""

from __future__ import annotations

import io
import json
import math
import re
import time
from pathlib import Path

import numpy as np

from viewer.errors import InputError
from viewer.files.imageio import atomic_path, linear_to_srgb, write_text
from viewer.lighting.dominant import brightest_direction
from viewer.resize import resize

PLATE_SIZE = (960, 640)  # pixels, landscape 3:2
PLATE_FOCAL_35 = 35.0  # mm, 35-mm equivalent (written in the plate's EXIF)
YAWS = (0.0, 120.0, 240.0)
JPEG_QUALITY = 90
LIGHTS = 16


def make_plate(env, yaw: float, path: Path, size: tuple[int, int] = PLATE_SIZE) -> float:
    """The plate of ``env`` at ``yaw`` written to ``path`` (JPEG, 8 bits, ``size`` pixels, the focal length
    in its EXIF); returns the scale its linear radiance was multiplied by (median luminance 0.18)."""
    from PIL import Image

    from viewer.lighting.envmap import LUMINANCE
    from viewer.scene.camera import Camera

    camera = Camera(size[0], size[1], focal_mm=PLATE_FOCAL_35, sensor_mm=36.0)
    linear = env.seen_through(camera, yaw)
    scale = 0.18 / max(float(np.median(linear @ LUMINANCE.astype(np.float32))), 1e-12)
    srgb = (np.clip(linear_to_srgb(linear * scale), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
    image = Image.fromarray(srgb)
    exif = Image.Exif()
    exif.get_ifd(0x8769)[0xA405] = int(PLATE_FOCAL_35)
    buffer = io.BytesIO()
    image.save(buffer, "JPEG", quality=JPEG_QUALITY, exif=exif.tobytes())
    with atomic_path(path) as tmp:
        tmp.write_bytes(buffer.getvalue())
    return scale


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return math.degrees(math.acos(float(np.clip(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)), -1.0, 1.0))))


def people(ctx) -> list[tuple[str, object]]:
    """The people the plates' light is measured on: the sample scene and the bundled photo's bundle."""
    from viewer.photo.inference import cached_bundle
    from viewer.resources import asset_dir, sample_scene_dir
    from viewer.scene.bundle import load_scene

    photo, _ = cached_bundle(asset_dir() / "photos" / "underpass.jpg", ctx=ctx)
    return [("sample scene", load_scene(sample_scene_dir())), ("bundled photo", load_scene(photo))]


def relit(engine, lights, yaw: float) -> np.ndarray:
    """The person under ``lights`` turned by ``yaw`` at the maps' resolution, linear (H, W, 3)."""
    from viewer.scene.look import Look

    engine.set_lights(lights)
    engine.set_look(Look(yaw=yaw))
    engine.render()
    return engine.output.read_work_hdr()[..., :3]


def lambert(scene, irradiance: np.ndarray) -> np.ndarray:
    """albedo E / pi over the scene's mask (``irradiance`` (H, W, 3) or (3,))."""
    return np.where(scene.mask[..., None], scene.albedo * irradiance / math.pi, 0.0).astype(np.float32)


def person_rmse(image: np.ndarray, truth: np.ndarray, mask: np.ndarray) -> float:
    return float(np.sqrt(np.mean((image[mask] - truth[mask]) ** 2)))


def _measured(plate_path: Path, scale: float, map_name: str, yaw: float, truth: tuple, persons: list, progress,
              what: str = "") -> dict:
    """A plate's row (the module's measures): the plate at ``plate_path`` read and its light estimated, the
    persons relit by it, by the uniform and SH lights and by the true lights (``truth``: the map's lights and
    its brightest direction) turned by ``yaw`` and scaled by ``scale``."""
    from viewer.cli.command_setup import fitted_lights
    from viewer.lighting import sh
    from viewer.lighting.dominant import DOMINANT_SHARE, strongest_group
    from viewer.lighting.envmap import EnvMap
    from viewer.lighting.lightfit.methods import DEFAULT_METHOD
    from viewer.plate.environment import placed_plate, plate_light
    from viewer.plate.loader import read_plate
    from viewer.scene.area_lights import AreaLights, rotation_matrix

    true_lights, true_brightest = truth
    plate = read_plate(plate_path, [])
    t0 = time.perf_counter()
    estimate, record = plate_light(plate)
    light_seconds = time.perf_counter() - t0
    est_lights, _ = fitted_lights(EnvMap(estimate.pixels, str(plate_path)), LIGHTS, DEFAULT_METHOD)
    scaled = AreaLights(true_lights.direction, true_lights.sigma, true_lights.intensity * scale)
    mean = plate.linear.reshape(-1, 3).mean(axis=0)
    coeffs = sh.project(placed_plate(plate))
    row = {"map": map_name, "yaw": yaw, "scale": scale, "plate_light_seconds": round(light_seconds, 3),
           "estimate_record": record, "people": {}}
    for name, scene, engine in persons:
        truth_image = relit(engine, scaled, yaw)
        guess = relit(engine, est_lights, 0.0)
        mask = scene.mask
        row["people"][name] = {
            "estimate": person_rmse(guess, truth_image, mask),
            "uniform": person_rmse(lambert(scene, math.pi * mean), truth_image, mask),
            "sh": person_rmse(lambert(scene, sh.irradiance(coeffs, scene.normal)), truth_image, mask)}
    for key in ("estimate", "uniform", "sh"):
        row[key] = float(np.mean([p[key] for p in row["people"].values()]))
    true_dir, share = strongest_group(true_lights)
    if share >= DOMINANT_SHARE:
        turned = rotation_matrix(yaw, 0.0) @ true_dir
        row["dominant_share"] = round(share, 3)
        row["direction_deg"] = round(angle_deg(turned, strongest_group(est_lights)[0]), 2)
        row["brightest_deg"] = round(angle_deg(rotation_matrix(yaw, 0.0) @ true_brightest, brightest_direction(estimate.pixels)), 2)
        row["cues"] = _cues(plate, rotation_matrix(yaw, 0.0) @ true_brightest)
    progress(f"{map_name} yaw {yaw:.0f}{' ' + what if what else ''}: person RMSE estimate {row['estimate']:.4f}, "
             f"uniform {row['uniform']:.4f}, sh {row['sh']:.4f}"
             + (f"; dominant light {row['direction_deg']:.0f} deg off, brightest {row['brightest_deg']:.0f}"
                if "direction_deg" in row else ""))
    return row


def _cues(plate, truth: np.ndarray) -> dict:
    """Each cue to a sun alone, on ``plate``: the degrees between the sun it reads and ``truth`` (the true map's
    brightest direction, turned as the plate), or None where it reads none: the clear sky's
    (:mod:`viewer.plate.sky`), the plate's people's shadows' (:mod:`viewer.plate.shadows`) and their
    shading's (:mod:`viewer.plate.people_shading`, at the elevation the product takes)."""
    from viewer.plate.horizon import horizon_tilt, plate_horizon
    from viewer.plate.people_shading import sun_from_shading
    from viewer.plate.shadows import sun_from_shadows
    from viewer.plate.sky import plate_sky

    horizon = plate_horizon(plate)[0]
    sky, shadow, shading = plate_sky(plate, horizon)[0], sun_from_shadows(plate, horizon)[0], sun_from_shading(plate)[0]
    if shading is not None:  # its azimuth, at the elevation the product takes
        shading = shading.direction_at(horizon_tilt(horizon, plate.size[1], plate.focal_px))
    return {"sky": None if sky is None else round(angle_deg(sky.direction, truth), 2),
            "shadows": None if shadow is None else round(angle_deg(shadow.direction, truth), 2),
            "shading": None if shading is None else round(angle_deg(shading, truth), 2)}


def _summary(rows: list) -> dict:
    """The means over ``rows`` of the three ways, the medians of the directions' errors over those with a
    dominant light and of each plate's ratios."""
    summary = {key: float(np.mean([r[key] for r in rows])) for key in ("estimate", "uniform", "sh")}
    for key in ("direction_deg", "brightest_deg"):
        found = [r[key] for r in rows if key in r]
        summary[f"{key}_median"] = float(np.median(found)) if found else None
    for cue in ("sky", "shadows", "shading"):  # each cue alone, on the plates with a dominant light: how often it reads one, how far off
        read = [r["cues"][cue] for r in rows if "cues" in r and r["cues"][cue] is not None]
        summary[f"{cue}_cue"] = {"plates": sum("cues" in r for r in rows), "read": len(read),
                                 "deg_median": float(np.median(read)) if read else None}
    summary["estimate_over_uniform"] = summary["estimate"] / summary["uniform"]
    summary["estimate_over_sh"] = summary["estimate"] / summary["sh"]
    # the targets are medians over plates of each plate's ratio (a hidden studio softbox swamps a mean)
    summary["estimate_over_uniform_median"] = float(np.median([r["estimate"] / r["uniform"] for r in rows]))
    summary["estimate_over_sh_median"] = float(np.median([r["estimate"] / r["sh"] for r in rows]))
    return summary


def run_plates_benchmark(maps_dir, output, progress=print, timing_runs: int = 3, photos: list | None = None,
                         people_plates: bool = True) -> dict:
    """Every map of ``maps_dir`` (.hdr, .exr) measured as the module says, the commands timed
    (:func:`timings`, ``timing_runs`` each), with ``people_plates`` also the plates of each map at each yaw
    that show people (:mod:`viewer.lab.bench.people_plates`: ``people_plates`` rows and ``summary.people_plates``),
    and with ``photos`` each one's person put back into their own photo (:func:`identity`); the JSON at ``output``."""
    from viewer.gl import Engine, create_headless_context
    from viewer.lab.bench.people_plates import make_people_plate
    from viewer.lab.bench.video import map_and_lights
    from viewer.lighting.envmap import SUFFIXES

    output = Path(output)
    plates_dir = output.parent / "plates"
    plates_dir.mkdir(parents=True, exist_ok=True)
    maps = sorted(p for p in Path(maps_dir).iterdir() if p.suffix.lower() in SUFFIXES and not p.name.startswith("."))
    if not maps:
        raise InputError(maps_dir, "holds no environment map (.hdr, .exr) to make plates of")
    ctx = create_headless_context()
    t_start = time.perf_counter()
    rows, with_people = [], []
    persons = []
    try:
        for name, scene in people(ctx):
            persons.append((name, scene, Engine(ctx, scene)))
        for index, path in enumerate(maps):
            env, true_lights = map_and_lights(path)
            truth = (true_lights, brightest_direction(env.pixels))
            for yaw in YAWS:
                plate_path = plates_dir / f"{path.stem}_{int(yaw):03d}.jpg"
                rows.append(_measured(plate_path, make_plate(env, yaw, plate_path), path.name, yaw, truth, persons, progress))
                if people_plates:
                    shown = plates_dir / f"{path.stem}_{int(yaw):03d}_people.jpg"
                    scale = make_people_plate(env, yaw, 1000 * index + int(yaw), shown)
                    with_people.append(_measured(shown, scale, path.name, yaw, truth, persons, progress, "with people"))
    finally:
        for _, _, engine in persons:
            engine.release()
        ctx.release()
    summary = _summary(rows)
    result = {"summary": summary, "plates": rows, "maps": [p.name for p in maps], "yaws": list(YAWS),
              "plate": {"size": list(PLATE_SIZE), "focal_35mm": PLATE_FOCAL_35, "jpeg_quality": JPEG_QUALITY},
              "seconds": round(time.perf_counter() - t_start, 1)}
    if with_people:
        result["people_plates"] = with_people
        summary["people_plates"] = _summary(with_people)
    progress("timing plate-light on a 12-MP plate and a 2048-px composite (fresh processes, empty light caches)")
    result["timing"] = timings(maps[0], plates_dir, timing_runs)
    summary["plate_light_seconds_12mp"] = result["timing"]["plate_light_12mp"]["median"]
    summary["composite_seconds_2048"] = result["timing"]["composite_2048"]["median"]
    if photos:
        progress(f"each of {len(photos)} photos' person put back into their own photo, lit by the light read from it")
        result["identity"] = identity(photos, plates_dir / "identity", progress)
        summary["identity_median_stops"] = result["identity"]["median_stops"]
        summary["identity_median_rmse_levels"] = result["identity"]["median_rmse_levels"]
    shown = figure(result, maps_dir, plates_dir, output.with_suffix(".jpg"))
    result["figure"] = shown.name if shown is not None else None
    write_text(output, json.dumps(result, indent=1) + "\n")
    return result


SECONDS = re.compile(r"([0-9.]+) s\)?$")  # the seconds a command prints last on its line


def timings(map_path: Path, folder: Path, runs: int = 3) -> dict:
    """The two timed steps of a plate (its light read, the composite), each in ``runs`` fresh processes (process start excluded:
    the seconds each command prints, from reading the plate to its files written), each with an empty
    light cache: ``relight plate-light`` of a 4000x3000 plate and ``relight render --plate`` of the
    bundled photo's bundle into a 2048x1365 plate, both made of ``map_path`` at yaw 0."""
    import os
    import subprocess
    import sys
    import tempfile

    from viewer.lighting.envmap import load_envmap
    from viewer.photo.inference import cached_bundle
    from viewer.resources import asset_dir

    env = load_envmap(map_path)
    big, wide = folder / "timing_12mp.jpg", folder / "timing_2048.jpg"
    make_plate(env, 0.0, big, (4000, 3000))
    make_plate(env, 0.0, wide, (2048, 1365))
    bundle, _ = cached_bundle(asset_dir() / "photos" / "underpass.jpg")
    commands = {"plate_light_12mp": ["plate-light", str(big), "-o", str(folder / "timing_light.exr")],
            "composite_2048": ["render", str(bundle), "--plate", str(wide), "--at", "0.5,0.9", "-o", str(folder / "timing_on.png")]}
    out = {}
    for name, args in commands.items():
        seconds = []
        for _ in range(runs):
            with tempfile.TemporaryDirectory() as cache:
                done = subprocess.run([sys.executable, "-m", "viewer.cli.main", *args, "--force"], capture_output=True, text=True,
                                      env={**os.environ, "RELIGHT_CACHE": cache})
            lines = [line for line in done.stdout.splitlines() if SECONDS.search(line.strip())]
            if done.returncode != 0 or not lines:
                raise RuntimeError(f"{' '.join(args[:2])}: {done.stderr.strip()[-500:]}")
            seconds.append(float(SECONDS.search(lines[-1].strip()).group(1)))
        out[name] = {"runs": seconds, "median": float(np.median(seconds)), "args": args}
    return out


FIGURE_PLATES = (("kiara_1_dawn_1k.hdr", 120.0), ("potsdamer_platz_1k.hdr", 240.0), ("rooitou_park_1k.hdr", 240.0),
                 ("studio_small_03_1k.hdr", 0.0))  # a good estimate, another, the sun behind the camera, a studio's lamps unseen


def figure(result: dict, maps_dir, plates_dir, path: Path) -> Path | None:
    """Rows of (the plate, the true map turned to its yaw, the map estimated from the plate), each map
    at the plate's exposure (the same scale), for the plates of ``FIGURE_PLATES`` measured in ``result``."""

    from viewer.files.imageio import write_jpeg
    from viewer.lighting.envmap import EnvMap, load_envmap
    from viewer.plate.environment import plate_light
    from viewer.plate.loader import read_plate

    rows = []
    for name, yaw in FIGURE_PLATES:
        row = next((r for r in result["plates"] if r["map"] == name and r["yaw"] == yaw), None)
        if row is None:
            continue
        plate = read_plate(Path(plates_dir) / f"{Path(name).stem}_{int(yaw):03d}.jpg", [])
        truth = EnvMap(load_envmap(Path(maps_dir) / name).rotated(yaw).pixels * row["scale"]).downsampled(512).pixels
        estimate = plate_light(plate)[0].pixels
        tiles = [resize(plate.srgb.astype(np.float32) / 255.0, (384, 256), "area")]
        tiles += [np.clip(linear_to_srgb(resize(m, (512, 256), "area")), 0.0, 1.0) for m in (truth, estimate)]
        rows.append(np.concatenate(tiles, axis=1))
    if not rows:
        return None
    return write_jpeg(path, np.concatenate(rows, axis=0))


def heldout_maps(folder: Path, count: int, first_seed: int = 9000) -> Path:
    """``count`` procedural maps (:func:`viewer.lab.data.envmaps.random_map`, 1024 wide, two of a kind at
    most, seeds from ``first_seed``) written into ``folder``: maps the estimate was never tuned on."""
    from viewer.lab.data.envmaps import random_map
    from viewer.lighting.envmap import save_envmap

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    kinds: dict[str, int] = {}
    seed = first_seed
    while sum(kinds.values()) < count and seed < first_seed + 100 * count:
        made = random_map(seed, 1024)
        if kinds.get(made.kind, 0) < 2:
            kinds[made.kind] = kinds.get(made.kind, 0) + 1
            save_envmap(folder / f"procedural_{seed}_{made.kind}.hdr", made.env)
        seed += 1
    return folder


IDENTITY_ALPHA = 0.9  # the person's pixels compared: their photo's matte at least this


def without_person(plate, alpha: np.ndarray):
    """``plate`` with the person (their matte ``alpha``, the plate's size or the frame's) filled from what
    is around them (OpenCV's Telea inpainting at 512 pixels, taken only inside the grown matte): the
    background a plate of that place would show, so that the light read from it does not see the person."""
    import cv2

    from viewer.plate.loader import Plate

    w, h = plate.size
    hole = resize(np.asarray(alpha, np.float32), (w, h), "linear") > 0.1
    hole = cv2.dilate(hole.astype(np.uint8), np.ones((9, 9), np.uint8)) > 0
    k = min(1.0, 512.0 / max(w, h))
    small = (max(round(w * k), 1), max(round(h * k), 1))
    filled = cv2.inpaint(resize(plate.srgb, small, "area"),
                         (resize(hole.astype(np.uint8), small, "nearest") > 0).astype(np.uint8),
                         5, cv2.INPAINT_TELEA)
    srgb = np.where(hole[..., None], resize(filled, (w, h), "linear"), plate.srgb)
    return Plate(np.ascontiguousarray(srgb, np.uint8), plate.focal_35, plate.focal_source, plate.source)


def identity(photos: list[Path], folder: Path, progress=print) -> dict:
    """Each photo's person put back into their own photo, lit by the light read from it without them
    (:func:`without_person`), standing where they stood, as ``relight render --plate`` composites: the
    photo is the truth. Per photo: the person's exposure error (log2 of the composite's mean luminance
    over the photo's, over the matte above ``IDENTITY_ALPHA``) and RMSE (sRGB levels); the median error
    and the median of its size."""

    from viewer.cli.command_setup import fitted_lights
    from viewer.files.imageio import read_png, srgb_to_linear
    from viewer.gl import Engine, create_headless_context
    from viewer.lighting.envmap import LUMINANCE
    from viewer.lighting.lightfit.methods import DEFAULT_METHOD
    from viewer.output.plate_render import plate_look, render_on_plate
    from viewer.photo.inference import cached_bundle
    from viewer.plate.environment import plate_light
    from viewer.plate.loader import read_plate
    from viewer.plate.placement import Placement, PlateSpot, feet
    from viewer.scene.bundle import load_scene
    from viewer.scene.look import Look

    folder.mkdir(parents=True, exist_ok=True)
    rows = []
    ctx = create_headless_context()
    try:
        for photo in photos:
            bundle, _ = cached_bundle(photo, ctx=ctx)
            scene = load_scene(bundle)
            alpha = scene.frame.alpha
            fx, fy, tall, _ = feet(alpha, photo, cut_allowed=True)
            h, w = alpha.shape
            place = Placement(fx / w, fy / h, tall / h)
            plate = read_plate(photo, [])
            empty = without_person(plate, alpha)  # the place without them: its light, and what they are put into
            lights, _ = fitted_lights(plate_light(empty)[0], LIGHTS, DEFAULT_METHOD)
            engine = Engine(ctx, scene)
            out = folder / f"{Path(photo).stem}_in_itself.png"
            try:
                render_on_plate(engine, scene, lights, plate_look(Look(yaw=0.0)), PlateSpot(empty, place, cut_allowed=True), out,
                                out.with_suffix(".exr"))
            finally:
                engine.release()
            made = read_png(out)
            person = resize(alpha, plate.size, "linear") >= IDENTITY_ALPHA
            mine = float((srgb_to_linear(made[person]) @ LUMINANCE).mean())
            truth = float((plate.linear[person] @ LUMINANCE).mean())
            row = {"photo": Path(photo).name, "stops": round(math.log2(max(mine, 1e-9) / max(truth, 1e-9)), 3),
                   "rmse_levels": round(float(np.sqrt(((made[person] - plate.srgb[person] / 255.0) ** 2).mean())) * 255.0, 2)}
            rows.append(row)
            progress(f"{row['photo']}: the person in their own photo {row['stops']:+.2f} stops, RMSE {row['rmse_levels']:.1f} levels")
    finally:
        ctx.release()
    stops = [r["stops"] for r in rows]
    return {"photos": rows, "median_stops": float(np.median(stops)) if stops else None,
            "median_abs_stops": float(np.median(np.abs(stops))) if stops else None,
            "median_rmse_levels": float(np.median([r["rmse_levels"] for r in rows])) if rows else None}
