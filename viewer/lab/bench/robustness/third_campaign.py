"""The third campaign's classes, each from the campaign's seeded generator so that a new
seed gives new variants of the same class: a user's file at any path a command writes (the output
named, or one written beside it), files the program wrote there (replaced), a hand-written light
file beside a map, lights beside a map that was replaced since they were fitted (stale), and video
names FFmpeg would read as a protocol, pipes and devices given as input files (which would block
or never end), maps too dark to show (a warning, never a silent black image) and background colours
past what an EXR holds (refused, never a NaN EXR), inverted masks (refused) and EXR maps of other
channel sets (luminance and chroma read as colour; alpha or depth alone refused), photos in wide-gamut
colour profiles (read in sRGB), and batches asking for more workers than the memory holds or a Ray
head that is not there (one line at once)."""

from __future__ import annotations

import json
import shutil

import numpy as np

from viewer.files.imageio import write_exr, write_png
from viewer.lab.bench.robustness.case import Case
from viewer.lab.bench.robustness.first_campaign import Campaign
from viewer.lab.bench.robustness.second_campaign import _name
from viewer.lighting.envmap import EnvMap, load_envmap, save_envmap
from viewer.lighting.lightfit.cache import fit_record
from viewer.scene.area_lights import load_lights

VARIANTS = 5


def third_campaign(kit: Campaign) -> None:
    for group in (users_files_at_outputs, own_files_at_outputs, hand_written_lights, stale_lights, protocol_names,
                  pipes_and_devices, too_dark, out_of_range_colours, inverted_masks, exr_channel_sets, wide_gamut_photos,
                  cluster_and_workers, float_and_turned_photos):
        group(kit)


def _user_bytes(kit: Campaign, suffix: str) -> bytes:
    """What a user may have under a name the program would write: a real image of another program,
    or any bytes."""
    if kit.rng.random() < 0.5 and suffix in (".png", ".exr"):
        from PIL import Image

        tmp = kit.work / "files" / f"user{next(kit.counter)}{suffix}"
        tmp.parent.mkdir(parents=True, exist_ok=True)
        if suffix == ".png":
            Image.fromarray(kit.rng.integers(0, 255, (8, 8, 3), dtype=np.uint8)).save(tmp)
        else:
            import OpenEXR

            with open(tmp, "wb") as f:
                OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                             {"RGB": kit.rng.random((8, 8, 3)).astype(np.float32)}).write(f)
        return tmp.read_bytes()
    return kit.rng.bytes(int(kit.rng.integers(1, 3000)))


def users_files_at_outputs(kit: Campaign) -> None:
    """The user's file at the PNG, the EXR or the passes sheet a render writes, or at fit-lights' -o
    or --plot: refused in one line, every byte kept."""
    group = "a user's file at an output path"
    for k in range(VARIANTS):
        stem = kit.out / _name(kit, "")
        taken = [f"{stem.name}.png", f"{stem.name}.exr", f"{stem.name}_passes.png"][k % 3]
        user = stem.with_name(taken)
        user.write_bytes(_user_bytes(kit, user.suffix))
        kit.cases.append(Case(group, f"render -o {stem.name}.png, the user's {taken} there ({k + 1})",
                              ["render", str(kit.sample), str(kit.lights), "--size", "64", "-o", f"{stem}.png"], "error",
                              None, watch=[str(user)]))
    for k in range(VARIANTS):
        which = ("-o", "--plot")[k % 2]
        user = kit.out / _name(kit, ".json" if which == "-o" else ".png")
        user.write_bytes(_user_bytes(kit, user.suffix))
        args = ["fit-lights", str(kit.env), "-n", "4", which, str(user)]
        if which == "--plot":
            args += ["-o", str(kit.out / _name(kit, ".json"))]
        kit.cases.append(Case(group, f"fit-lights {which} at the user's {user.suffix} ({k + 1})", args, "error", None,
                              watch=[str(user)]))


def own_files_at_outputs(kit: Campaign) -> None:
    """Files the program wrote at the same paths (an earlier render): replaced, the command runs."""
    group = "the program's own files at the output paths"
    for k in range(VARIANTS):
        stem = kit.out / _name(kit, "")
        image = kit.rng.random((6, 6, 3)).astype(np.float32)
        write_png(f"{stem}.png", image)
        if k % 2:
            write_exr(f"{stem}.exr", image)
            write_png(f"{stem}_passes.png", image)
        kit.cases.append(Case(group, f"render again to {stem.name}.png ({k + 1})",
                              ["render", str(kit.sample), str(kit.lights), "--size", "64", "-o", f"{stem}.png"], "ok", f"{stem}.png"))


def hand_written_lights(kit: Campaign) -> None:
    """A light file the user wrote beside a map (no mark, no fit record): fit-lights keeps it (the
    lights go to the cache) and render --env MAP does not read it."""
    group = "a hand-written light file beside a map"
    for k in range(VARIANTS):
        folder = kit.out / f"maps_hand{k}"
        folder.mkdir()
        env = shutil.copyfile(kit.env, folder / _name(kit, ".hdr"))
        mine = env.with_suffix(".lights.json")
        d = kit.rng.normal(size=3)
        mine.write_text(json.dumps({"format": "relight-lights", "note": _name(kit, ""), "lights": [
            {"direction": list(d / np.linalg.norm(d)), "sigma": float(kit.rng.uniform(0, 5)), "intensity": [1.0, 1.0, 1.0]}]}))
        if k % 2:
            kit.cases.append(Case(group, f"fit-lights beside the user's light file ({k + 1})",
                                  ["fit-lights", str(env), "-n", "4"], "ok", None, watch=[str(mine)]))
        else:
            o = kit.target()
            kit.cases.append(Case(group, f"render --env beside the user's light file ({k + 1})",
                                  ["render", str(kit.sample), "--env", str(env), "-n", "4", "--size", "64", "-o", o], "ok", o,
                                  watch=[str(mine)], not_said="shipped beside the map"))


def stale_lights(kit: Campaign) -> None:
    """Lights fitted beside a map, then the map replaced (another bundled map, the same map edited,
    one pixel changed, flipped): render --env MAP fits the map it is given, never the old lights."""
    group = "stale lights beside a map"
    maps = sorted((kit.assets / "envmaps").glob("*.hdr"))
    for k in range(VARIANTS):
        folder = kit.out / f"maps_stale{k}"
        folder.mkdir()
        env_path = folder / _name(kit, ".hdr")
        first = load_envmap(kit.env)
        save_envmap(env_path, first)
        lights = load_lights(kit.lights)
        lights = type(lights)(lights.direction[:4], lights.sigma[:4], lights.intensity[:4])
        lights.save(env_path.with_suffix(".lights.json"), fit=fit_record(env_path, "instant", 4, load_envmap(env_path)))
        pixels = first.pixels.copy()
        how = ("another map", "brighter", "one pixel", "flipped", "another map")[k % 5]
        if how == "another map":
            save_envmap(env_path, load_envmap(maps[int(kit.rng.integers(len(maps)))] if len(maps) > 1 else kit.env))
            if np.array_equal(load_envmap(env_path).pixels, pixels):
                save_envmap(env_path, type(first)(pixels[::-1].copy(), first.source))
        else:
            if how == "brighter":
                pixels *= float(kit.rng.uniform(1.5, 4))
            elif how == "one pixel":
                y, x = int(kit.rng.integers(pixels.shape[0])), int(kit.rng.integers(pixels.shape[1]))
                pixels[y, x] += 10.0
            else:
                pixels = pixels[:, ::-1].copy()
            save_envmap(env_path, type(first)(pixels, first.source))
        o = kit.target()
        kit.cases.append(Case(group, f"render --env a map replaced since its lights were fitted: {how} ({k + 1})",
                              ["render", str(kit.sample), "--env", str(env_path), "-n", "4", "--size", "64", "-o", o], "ok", o,
                              not_said="shipped beside the map"))


def protocol_names(kit: Campaign) -> None:
    """Video names FFmpeg would read as a protocol (``v1:final.mp4``, ``turntable-12:30.mp4``):
    written as files."""
    group = "a video named like a URL"
    for k in range(VARIANTS):
        name = (f"{_name(kit, '')}:{_name(kit, '.mp4')}" if k % 2
                else f"{_name(kit, '')}-{int(kit.rng.integers(24))}:{int(kit.rng.integers(60)):02d}.mp4")
        o = str(kit.out / name)
        kit.cases.append(Case(group, f"render -o {name} ({k + 1})", ["render", str(kit.sample), str(kit.lights), "--size", "64",
                                                                    "--frames", "2", "-o", o], "ok", o))


def pipes_and_devices(kit: Campaign) -> None:
    """A named pipe nobody writes to, or a device, given as the photo, the mask, the map, the light
    file, the look or the rig: refused at once in one line (opening the pipe blocked for ever)."""
    import os

    group = "a pipe or a device as an input"
    roles = ("photo", "mask", "map", "lights", "look", "rig")
    for k in range(2 * VARIANTS):
        role = roles[k % len(roles)]
        suffix = {"photo": ".jpg", "mask": ".png", "map": (".hdr", ".exr")[k % 2], "lights": ".json", "look": ".json", "rig": ".json"}[role]
        if k % 3 == 2:
            special = ("/dev/zero", "/dev/null", "/dev/urandom")[int(kit.rng.integers(3))]
        else:
            special = str(kit.work / "files" / _name(kit, suffix))
            os.makedirs(os.path.dirname(special), exist_ok=True)
            os.mkfifo(special)
        o = kit.target()
        args = {"photo": ["infer", special, "--size", "64", "-o", str(kit.out / f"bundle_fifo{k}")],
                "mask": ["infer", str(kit.photo), "--mask", special, "--size", "64", "-o", str(kit.out / f"bundle_fifo{k}")],
                "map": ["render", str(kit.sample), "--env", special, "--size", "64", "-o", o],
                "lights": ["render", str(kit.sample), special, "--size", "64", "-o", o],
                "look": ["render", str(kit.sample), str(kit.lights), "--look", special, "--size", "64", "-o", o],
                "rig": ["render", str(kit.sample), str(kit.lights), "--rig", special, "--size", "64", "-o", o]}[role]
        kit.cases.append(Case(group, f"{special.split('/')[-1] if special.startswith('/dev') else 'a named pipe'} as the {role} ({k + 1})",
                              args, "error", o if args[0] == "render" else args[-1]))


def too_dark(kit: Campaign) -> None:
    """Maps dim beyond any exposure (1e-20 to 1e-35 everywhere), or black but for one texel: the
    person renders black, and a warning line says why."""
    group = "a map too dark to show"
    for k in range(VARIANTS):
        h = int(kit.rng.choice([16, 32, 64]))
        if k % 2:
            pixels = np.zeros((h, 2 * h, 3), np.float32)
            pixels[int(kit.rng.integers(h)), int(kit.rng.integers(2 * h))] = float(10.0 ** kit.rng.uniform(-12, -4))
            what = "black but one texel"
        else:
            pixels = np.full((h, 2 * h, 3), float(10.0 ** -kit.rng.uniform(20, 35)), np.float32)
            what = f"{pixels.flat[0]:.0e} everywhere"
        env = save_envmap(kit.work / "files" / _name(kit, ".hdr"), EnvMap(pixels))
        o = kit.target()
        kit.cases.append(Case(group, f"a map {what} ({k + 1})", ["render", str(kit.sample), "--env", str(env), "-n", "4",
                                                                 "--size", "64", "-o", o], "black", o))


def out_of_range_colours(kit: Campaign) -> None:
    """A saved look whose background colour is past what a half-float EXR holds, negative or not a
    number: refused in one line (an EXR of NaN was written)."""
    group = "a background colour out of range"
    for k in range(VARIANTS):
        value = (float(10.0 ** kit.rng.uniform(5, 300)), -float(kit.rng.uniform(0.01, 10)), 65505.0 + float(kit.rng.uniform(0, 1e4)),
                 float(10.0 ** kit.rng.uniform(39, 300)), "grey")[k % 5]
        look = kit.work / "files" / _name(kit, ".json")
        look.write_text(json.dumps({"background": "color", "background_color": [value, 0.1, 0.1]}))
        o = kit.target()
        kit.cases.append(Case(group, f"background_color {value!r} ({k + 1})", ["render", str(kit.sample), str(kit.lights), "--look",
                                                                               str(look), "--size", "64", "-o", o], "error", o))


def inverted_masks(kit: Campaign) -> None:
    """The bundled mask inverted (white on the background), softened, noised or thresholded at a
    generated level: refused in one line, never a relit background."""
    from PIL import Image, ImageFilter

    group = "an inverted mask"
    with Image.open(kit.mask) as im:
        mask = np.asarray(im.convert("L"), np.float32)
    for k in range(VARIANTS):
        m = 255.0 - mask
        if k % 3 == 1:
            m = np.asarray(Image.fromarray(m.astype(np.uint8)).filter(ImageFilter.GaussianBlur(float(kit.rng.uniform(0.5, 3)))), np.float32)
        elif k % 3 == 2:
            m = np.where(m > kit.rng.uniform(60, 200), 255.0, 0.0)
        path = kit.work / "files" / _name(kit, ".png")
        Image.fromarray(np.clip(m, 0, 255).astype(np.uint8)).save(path)
        kit.cases.append(Case(group, f"--mask inverted ({k + 1})", ["infer", str(kit.photo), "--mask", str(path), "--size", "64",
                                                                   "--max-size", "256", "-o", str(kit.out / f"bundle_inv{k}")],
                              "error", str(kit.out / f"bundle_inv{k}")))


def exr_channel_sets(kit: Campaign) -> None:
    """EXR maps of other channel sets than RGB: luminance and chroma (Y, RY, BY) read as colour; alpha
    alone, depth alone or unknown names refused in one line (alpha alone lit the person white)."""
    import OpenEXR

    group = "an EXR map's channel set"
    rgb = load_envmap(kit.env).pixels
    y = rgb @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    for k in range(VARIANTS):
        kind = ("Y RY BY", "A", "Z", "Y RY BY", "depth")[k % 5]
        if kind == "Y RY BY":
            safe = np.maximum(y, 1e-6)
            channels = {"Y": y, "RY": (rgb[..., 0] - y) / safe, "BY": (rgb[..., 2] - y) / safe}
        else:
            channels = {kind: np.full(y.shape, float(kit.rng.uniform(0.5, 5)), np.float32)}
        path = kit.work / "files" / _name(kit, ".exr")
        with open(path, "wb") as f:
            OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                         {n: np.ascontiguousarray(v, np.float32) for n, v in channels.items()}).write(f)
        o = kit.target()
        kit.cases.append(Case(group, f"a map of channels {kind} ({k + 1})", ["render", str(kit.sample), "--env", str(path), "-n", "4",
                                                                             "--size", "64", "-o", o],
                              "ok" if kind == "Y RY BY" else "error", o))


def wide_gamut_photos(kit: Campaign) -> None:
    """The bundled photo in Adobe RGB or Display P3 (profiles written from their primaries, a
    generated gamma), as PNG or JPEG, its profile embedded: inferred (read in sRGB, with a note)."""
    import io

    from PIL import Image, ImageCms

    from viewer.lab.icc_profiles import ADOBE_RGB, DISPLAY_P3, matrix_trc_profile

    group = "a photo in a wide-gamut colour profile"
    with Image.open(kit.photo) as im:
        photo = im.convert("RGB")
        photo.thumbnail((300, 450))
    for k in range(VARIANTS):
        name, primaries, white, _ = (ADOBE_RGB, DISPLAY_P3)[k % 2]
        space = (name, primaries, white, float(kit.rng.uniform(1.8, 2.6)))
        icc = matrix_trc_profile(space)
        wide = ImageCms.profileToProfile(photo, ImageCms.createProfile("sRGB"), ImageCms.ImageCmsProfile(io.BytesIO(icc)),
                                         outputMode="RGB")
        path = kit.work / "files" / _name(kit, (".png", ".jpg")[k % 2])
        wide.save(path, icc_profile=icc)
        o = str(kit.out / f"bundle_icc{k}")
        kit.cases.append(Case(group, f"{name}, gamma {space[3]:.2f}, {path.suffix} ({k + 1})",
                              ["infer", str(path), "--size", "64", "--max-size", "256", "-o", o], "ok", o))


def cluster_and_workers(kit: Campaign) -> None:
    """``batch --ray HOST:PORT`` where no head answers (generated ports) and ``--workers`` past what
    the memory holds (generated counts): one line at once, no batch folder made."""
    group = "a batch's cluster and workers"
    for k in range(VARIANTS):
        o = str(kit.out / f"batch_bad{k}")
        if k % 2:
            extra = ["--ray", f"127.0.0.1:{int(kit.rng.integers(1, 1000))}"]
        else:
            extra = ["--workers", str(int(kit.rng.integers(10_000, 100_000)))]
        kit.cases.append(Case(group, f"batch {' '.join(extra)} ({k + 1})", ["batch", str(kit.photo), "--env", str(kit.env), "-o", o,
                                                                          *extra], "error", o))


def float_and_turned_photos(kit: Campaign) -> None:
    """A 32-bit floating-point TIFF (generated values) as the photo: refused in one line ("no person
    found" before); the photo turned by 90, 180 or 270 degrees with no EXIF to say so: inferred, with
    a warning line that the person lies sideways or upside down."""
    from PIL import Image

    group = "a float or a turned photo"
    with Image.open(kit.photo) as im:
        photo = im.convert("RGB")
        photo.thumbnail((300, 450))
    for k in range(VARIANTS):
        path = kit.work / "files" / _name(kit, ".tif")
        grey = np.asarray(photo.convert("L"), np.float32) / 255.0 * float(kit.rng.uniform(0.5, 100))
        Image.fromarray(grey, mode="F").save(path)
        bundle = str(kit.out / f"bundle_float{k}")
        kit.cases.append(Case(group, f"a float TIFF ({k + 1})", ["infer", str(path), "--size", "64", "--max-size", "256", "-o", bundle],
                              "error", bundle))
    for k in range(VARIANTS):
        angle = int(kit.rng.choice([90, 180, 270]))
        path = kit.work / "files" / _name(kit, ".jpg")
        photo.rotate(angle, expand=True).save(path)
        kit.cases.append(Case(group, f"the photo turned {angle} degrees, no EXIF ({k + 1})",
                              ["infer", str(path), "--size", "64", "--max-size", "256", "-o", str(kit.out / f"bundle_turned{k}")],
                              "ok", str(kit.out / f"bundle_turned{k}"), said="if the photo lost its rotation"))
