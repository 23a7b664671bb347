"""The first campaign's cases (185): hostile light files, maps, bundles, caches, looks, options,
outputs over inputs, network cards and photos, each a real command line."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
from PIL import Image

from viewer.files.imageio import read_exr, write_exr, write_png
from viewer.lab.bench.robustness.case import Case, truncations
from viewer.lighting.envmap import EnvMap, load_envmap, save_envmap
from viewer.lighting.lightfit.cache import cache_path
from viewer.resources import asset_dir, network_dir, sample_scene_dir


class Campaign:
    """The scratch folder, the bundled files the cases start from, and the cases made so far."""

    def __init__(self, work: Path, seed: int = 17):
        self.work = Path(work)
        self.rng = np.random.default_rng(seed)
        self.assets = asset_dir()
        self.sample = sample_scene_dir()
        self.lights = self.assets / "envmaps" / "venice_sunset_256.lights.json"
        self.env = self.assets / "envmaps" / "venice_sunset_256.hdr"
        self.photo = self.assets / "photos" / "underpass.jpg"
        self.mask = self.assets / "photos" / "underpass.mask.png"
        self.good = self.lights.read_bytes()
        self.out = self.work / "out"
        self.out.mkdir(parents=True, exist_ok=True)
        self.cases: list = []
        self.counter = iter(range(10**6))

    def write(self, name: str, data) -> Path:
        path = self.work / "files" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data if isinstance(data, bytes) else data.encode("utf-8"))
        return path

    def target(self, suffix=".png") -> str:
        return str(self.out / f"case{next(self.counter)}{suffix}")

    def render(self, group, name, *args, expect="error", suffix=".png"):
        o = self.target(suffix)
        self.cases.append(Case(group, name, ["render", *map(str, args), "--size", "96", "-o", o], expect, o))

    def bundle(self, name: str, edit=None, files=None) -> Path:
        """A copy of the sample bundle, its scene.json edited and files replaced."""
        b = self.work / "bundles" / name
        shutil.copytree(self.sample, b, dirs_exist_ok=True)
        meta = json.loads((b / "scene.json").read_text())
        if edit is not None:
            edit(meta)
            (b / "scene.json").write_text(json.dumps(meta))
        for fname, data in (files or {}).items():
            (b / fname).write_bytes(data)
        return b


def first_campaign(kit: Campaign) -> None:
    for group in (light_files, environment_maps, scene_bundles, light_cache, saved_looks, options, outputs_over_inputs,
                  photos):
        group(kit)


def light_files(kit: Campaign) -> None:
    """Light files."""
    light_json = json.loads(kit.good)
    light_files = list(truncations(kit.good, "lights.json", kit.write))
    light_files += [
        ("random bytes", kit.write("random_lights.json", kit.rng.bytes(4096))),
        ("not UTF-8", kit.write("latin1_lights.json", kit.good.replace(b'"relight-lights"', b'"relight-lights\xe9"'))),
        ("nested 100,000 deep", kit.write("deep_lights.json", "[" * 100000 + "]" * 100000)),
        ("a JSON list", kit.write("list_lights.json", "[1, 2, 3]")),
        ("a JSON string", kit.write("string_lights.json", '"lights"')),
        ("another format", kit.write("format_lights.json", json.dumps({**light_json, "format": "other"}))),
        ("no lights", kit.write("empty_lights.json", json.dumps({**light_json, "lights": []}))),
        ("a missing key", kit.write("key_lights.json", json.dumps({**light_json, "lights": [{"direction": [0, 0, 1]}]}))),
    ]
    for what, value in (("direction NaN", {"direction": [float("nan"), 0, 1]}), ("direction zero", {"direction": [0, 0, 0]}),
                        ("sigma negative", {"sigma": -1.0}), ("sigma 1e6", {"sigma": 1e6}), ("sigma Inf", {"sigma": float("inf")}),
                        ("intensity negative", {"intensity": [-1, 0, 0]}), ("intensity 1e30", {"intensity": [1e30, 1, 1]}),
                        ("intensity a string", {"intensity": "bright"}), ("direction of 2 values", {"direction": [0, 1]})):
        bad = json.loads(kit.good)
        bad["lights"][0].update(value)
        light_files.append((what, kit.write(f"light_{what.replace(' ', '_')}.json", json.dumps(bad))))
    light_files.append(("a folder", kit.work / "files" / "folder_lights.json"))
    (kit.work / "files" / "folder_lights.json").mkdir(parents=True, exist_ok=True)
    light_files.append(("missing", kit.work / "files" / "missing_lights.json"))
    huge = kit.work / "files" / "huge_lights.json"
    with open(huge, "wb") as f:  # sparse: claims 100 MB without using the disk
        f.truncate(100 << 20)
    light_files.append(("100 MB", huge))
    npy = kit.work / "files" / "object.npy"
    np.save(npy, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    light_files.append(("a pickled .npy", npy))
    np.save(kit.work / "files" / "shape.npy", np.zeros((3, 5)))
    light_files.append(("a .npy of the wrong shape", kit.work / "files" / "shape.npy"))
    for what, path in light_files:
        kit.render("light file", what, kit.sample, path)
    kit.render("light file", "the valid file", kit.sample, kit.lights, expect="ok")


def environment_maps(kit: Campaign) -> None:
    """Environment maps."""
    hdr = kit.env.read_bytes()
    maps = list(truncations(hdr, "map.hdr", kit.write))
    maps += [
        ("random bytes", kit.write("random.hdr", kit.rng.bytes(8192))),
        ("header claims 800000x400000", kit.write("huge.hdr", b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 400000 +X 800000\n" + bytes(64))),
        ("no resolution line", kit.write("nores.hdr", b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n")),
        ("no signature", kit.write("nosig.hdr", b"FORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 4\n" + bytes(32))),
        ("a PNG named .hdr", kit.write("png.hdr", kit.mask.read_bytes())),
        ("an unknown suffix", kit.write("map.tga", hdr)),
        ("missing", kit.work / "files" / "missing.hdr"),
    ]
    for what, path in maps:
        kit.render("environment map", what, kit.sample, "--env", path, "-n", "4", "--method", "median-cut")
    px = np.ones((32, 64, 3), np.float32)
    px[3, 5] = np.nan
    nan_map = kit.work / "files" / "nan.exr"
    write_exr(nan_map, px)
    kit.render("environment map", "NaN pixels", kit.sample, "--env", nan_map, "-n", "4", "--method", "median-cut")
    kit.render("environment map", "NaN pixels with --repair", kit.sample, "--env", nan_map, "-n", "4", "--method", "median-cut",
           "--repair", expect="ok")
    neg = px.copy()
    neg[3, 5] = -1.0
    write_exr(kit.work / "files" / "negative.exr", neg)
    kit.render("environment map", "a negative pixel (a filter's ringing): set to 0, said", kit.sample, "--env",
               kit.work / "files" / "negative.exr", "-n", "4", "--method", "median-cut", expect="warned")
    write_exr(kit.work / "files" / "negatives.exr", np.where((np.arange(64) % 2)[None, :, None] > 0, -1.0, 1.0).astype(np.float32)
              * np.ones((32, 64, 3), np.float32))  # half the map
    kit.render("environment map", "negative pixels on half the map", kit.sample, "--env", kit.work / "files" / "negatives.exr",
               "-n", "4", "--method", "median-cut")
    save_envmap(kit.work / "files" / "black.hdr", EnvMap(np.zeros((32, 64, 3), np.float32)))
    kit.render("environment map", "an all-black map", kit.sample, "--env", kit.work / "files" / "black.hdr", "-n", "4",
           "--method", "median-cut", expect="black")
    save_envmap(kit.work / "files" / "tiny.hdr", EnvMap(np.full((1, 2, 3), 0.5, np.float32)))
    kit.render("environment map", "a 2x1 map for 4 lights", kit.sample, "--env", kit.work / "files" / "tiny.hdr", "-n", "4",
           "--method", "median-cut")
    kit.render("environment map", "a 2x1 map for 1 light", kit.sample, "--env", kit.work / "files" / "tiny.hdr", "-n", "1",
           "--method", "median-cut", expect="ok")
    exr_bytes = nan_map.read_bytes()
    for what, path in truncations(exr_bytes, "map.exr", kit.write):
        kit.render("environment map", what, kit.sample, "--env", path, "-n", "4", "--method", "median-cut")


def scene_bundles(kit: Campaign) -> None:
    """Scene bundles."""
    outside = kit.work / "files" / "outside.exr"
    shutil.copy(kit.sample / "albedo.exr", outside)
    bundles = [
        ("map name ../ escapes", kit.bundle("escape", lambda m: m["maps"].update(albedo="../../files/outside.exr"))),
        ("absolute map path", kit.bundle("absolute", lambda m: m["maps"].update(albedo=str(outside)))),
        ("map in a sub-folder", kit.bundle("subfolder", lambda m: m["maps"].update(albedo="sub/albedo.exr"))),
        ("map name not a string", kit.bundle("notstring", lambda m: m["maps"].update(albedo=3))),
        ("another format", kit.bundle("format", lambda m: m.update(format="x"))),
        ("a newer version", kit.bundle("version", lambda m: m.update(version=99))),
        ("width that disagrees", kit.bundle("width", lambda m: m.update(width=100))),
        ("camera missing", kit.bundle("camera", lambda m: m.pop("camera"))),
        ("scene.json not UTF-8", kit.bundle("latin1", files={"scene.json": b'{"format": "\xe9"}'})),
        ("scene.json nested deep", kit.bundle("deep", files={"scene.json": b"[" * 100000 + b"]" * 100000})),
        ("scene.json a list", kit.bundle("list", files={"scene.json": b"[]"})),
        ("albedo random bytes", kit.bundle("albedo_random", files={"albedo.exr": kit.rng.bytes(5000)})),
        ("albedo truncated", kit.bundle("albedo_trunc", files={"albedo.exr": (kit.sample / "albedo.exr").read_bytes()[:3000]})),
        ("mask random bytes", kit.bundle("mask_random", files={"mask.png": kit.rng.bytes(300)})),
    ]
    link = kit.bundle("symlink")
    (link / "albedo.exr").unlink()
    os.symlink(outside, link / "albedo.exr")
    bundles.append(("a map symlinked kit.out of the bundle", link))
    missing = kit.bundle("missing_map")
    (missing / "normal.exr").unlink()
    bundles.append(("a map file missing", missing))
    nojson = kit.bundle("no_json")
    (nojson / "scene.json").unlink()
    bundles.append(("no scene.json", nojson))
    bundles.append(("a file, not a folder", kit.photo))
    bundles.append(("missing", kit.work / "bundles" / "nowhere"))
    for what, arr_edit, fname in (("normals NaN", lambda a: a.__setitem__((200, 200), np.nan), "normal.exr"),
                                  ("normals not unit", lambda a: a.__setitem__((slice(None), slice(None)), a * 3.0), "normal.exr"),
                                  ("depth Inf", lambda a: a.__setitem__((250, 250), np.inf), "depth.exr"),
                                  ("depth negative", lambda a: a.__setitem__((slice(None), slice(None)), -np.abs(a)), "depth.exr"),
                                  ("albedo NaN", lambda a: a.__setitem__((250, 250), np.nan), "albedo.exr")):
        b = kit.bundle(what.replace(" ", "_"))
        arr = read_exr(b / fname)
        arr_edit(arr)
        write_exr(b / fname, arr)
        bundles.append((what, b))
    for what, value in (("an empty mask", 0.0), ("a full mask", 1.0)):
        b = kit.bundle(what.replace(" ", "_"))
        write_png(b / "mask.png", np.full((512, 512), value, np.float32))
        bundles.append((what, b))
    for what, data in truncations((kit.sample / "scene.json").read_bytes(), "scene.json", lambda n, d: d):
        bundles.append((f"scene.json {what.split(' ', 1)[1]}", kit.bundle(f"json_{len(data)}", files={"scene.json": data})))
    big = kit.bundle("huge_json")
    with open(big / "scene.json", "r+b") as f:
        f.truncate(100 << 20)
    bundles.append(("scene.json of 100 MB", big))
    for what, path in bundles:  # (a full kit.mask claims pixels that have no normals)
        kit.render("scene bundle", what, path, kit.lights)

    passwd = kit.work / "files" / "passwd_lights.json"
    os.symlink("/etc/passwd", passwd)
    kit.render("light file", "a link to /etc/passwd", kit.sample, passwd)


def light_cache(kit: Campaign) -> None:
    """Light cache entries."""
    for what, data in (("not UTF-8", b'{"format": "\xe9"}'), ("truncated", kit.good[: len(kit.good) // 3]), ("empty", b""),
                       ("random bytes", kit.rng.bytes(777)), ("nested deep", b"[" * 100000 + b"]" * 100000), ("a folder", None)):
        cache = kit.work / "caches" / what.replace(" ", "_")
        entry = cache_path(load_envmap(kit.env), 4, "median-cut", cache)
        entry.parent.mkdir(parents=True, exist_ok=True)
        if data is None:
            entry.mkdir()
        else:
            entry.write_bytes(data)
        o = str(kit.out / f"fit{next(kit.counter)}.json")
        kit.cases.append(Case("light cache", f"a cache entry {what}", ["fit-lights", str(kit.env), "-n", "4", "--method", "median-cut",
                                                                   "-o", o], "ok", o, cache=str(cache)))


def saved_looks(kit: Campaign) -> None:
    """Saved looks."""
    looks = [
        ("empty", kit.write("empty_look.json", b"")),
        ("not UTF-8", kit.write("latin1_look.json", b'{"look": {"view": "\xe9"}}')),
        ("nested deep", kit.write("deep_look.json", "[" * 100000 + "]" * 100000)),
        ("a list", kit.write("list_look.json", "[1]")),
        ("exposure 1e9", kit.write("exp_look.json", json.dumps({"look": {"exposure": 1e9}}))),
        ("yaw NaN", kit.write("nan_look.json", '{"look": {"yaw": NaN}}')),
        ("an unknown view", kit.write("view_look.json", json.dumps({"look": {"view": "x-ray"}}))),
        ("an unknown preset", kit.write("preset_look.json", json.dumps({"look": {"preset": "ultra"}}))),
        ("missing", kit.work / "files" / "missing_look.json"),
    ]
    looks += [(f"look {what}", path) for what, path in
              truncations(json.dumps({"look": {"yaw": 10.0, "exposure": 1.0}}).encode(), "look.json", kit.write)][1:4]
    for what, path in looks:
        kit.render("saved look", what, kit.sample, kit.lights, "--look", path)
    kit.render("saved look", "an older state file's look", kit.sample, kit.lights, "--look",
           kit.write("old_look.json", json.dumps({"look": {"yaw": 20, "exposure": 0.5, "shadows": "hard", "light": 99}})), expect="ok")


def options(kit: Campaign) -> None:
    """Options."""
    options = [
        ("--yaw nan", ["--yaw", "nan"]), ("--yaw inf", ["--yaw", "inf"]), ("--yaw 1e300", ["--yaw", "1e300"]),
        ("--tilt nan", ["--tilt", "nan"]), ("--exposure 1e9", ["--exposure", "1e9"]), ("--exposure nan", ["--exposure", "nan"]),
        ("--exposure bright", ["--exposure", "bright"]), ("--size 0", ["--size", "0"]), ("--size -5", ["--size", "-5"]),
        ("--size 100000", ["--size", "100000"]), ("--max-size 0", ["--max-size", "0"]), ("--terms 1", ["--terms", "1"]),
        ("--terms 99", ["--terms", "99"]), ("--shadow-resolution 100", ["--shadow-resolution", "100"]),
        ("--shadow-resolution 65536", ["--shadow-resolution", "65536"]), ("--shadow-step -1", ["--shadow-step", "-1"]),
        ("--preset ultra", ["--preset", "ultra"]), ("--visibility x", ["--visibility", "x"]),
        ("--background sky", ["--background", "sky"]), ("--background kit.photo without one", ["--background", "photo"]),
        ("-n 0", ["--env", kit.env, "-n", "0"]), ("-n -1", ["--env", kit.env, "-n", "-1"]),
    ]
    for what, extra in options:
        o = kit.target()
        last_size = [i for i, a in enumerate(extra) if a == "--size"]
        args = ["render", str(kit.sample), str(kit.lights), *map(str, extra)] + ([] if last_size else ["--size", "96"]) + ["-o", o]
        if extra[0] == "--env":
            args = ["render", str(kit.sample), *map(str, extra), "--method", "median-cut", "--size", "96", "-o", o]
        expect = "ok" if what == "--background kit.photo without one" else "error"
        kit.cases.append(Case("option", what, args, expect, o))
    video_opts = [("--frames 0", ["--frames", "0"]), ("--frames -3", ["--frames", "-3"]), ("--fps 0", ["--fps", "0"]),
                  ("--fps nan", ["--fps", "nan"]), ("--fps -30", ["--fps", "-30"])]
    for what, extra in video_opts:
        kit.render("option", what, kit.sample, kit.lights, *extra, suffix=".mp4")
    existing = kit.work / "files" / "existing.png"
    existing.write_bytes(kit.mask.read_bytes())
    folder = kit.work / "a_folder"  # its own: the files folder gains light files beside maps as cases run
    folder.mkdir()
    (folder / "keep.txt").write_text("the user's")
    for what, o in (("-o an existing folder", folder), ("-o a .txt", kit.work / "files" / "x.txt"),
                    ("-o under a file", kit.work / "files" / "existing.png" / "x.png"), ("-o in /proc", Path("/proc/nope/x.png"))):
        kit.cases.append(Case("option", what, ["render", str(kit.sample), str(kit.lights), "--size", "96", "-o", str(o)], "error", str(o)))
    kit.cases.append(Case("option", "-o a PNG the user made (refused, kept: issue 43)", ["render", str(kit.sample), str(kit.lights),
                                                                                        "--size", "96", "-o", str(existing)],
                          "error", str(existing)))
    for what, extra in (("fit-lights -n 0", ["-n", "0"]), ("fit-lights -n 100000", ["-n", "100000"]),
                        ("fit-lights -o .txt", ["-n", "4", "-o", str(kit.out / "l.txt")])):
        o = extra[-1] if "-o" in extra else str(kit.out / f"fit{next(kit.counter)}.json")
        args = ["fit-lights", str(kit.env), "--method", "median-cut", *extra] + ([] if "-o" in extra else ["-o", o])
        kit.cases.append(Case("option", what, args, "error", o))


def outputs_over_inputs(kit: Campaign) -> None:
    """Outputs that would replace inputs (a review's cases)."""
    exr_map = kit.work / "files" / "venice.exr"
    write_exr(exr_map, load_envmap(kit.env).pixels)
    kit.render("output over input", "the EXR beside -o is the map", kit.sample, "--env", exr_map, "-n", "4", "--method", "median-cut")
    kit.cases[-1].args[-1] = kit.cases[-1].output = str(exr_map.with_suffix(".png"))
    inside = kit.bundle("written_into")
    depth_png = str(inside / "depth.png")
    kit.cases.append(Case("output over input", "-o inside the scene bundle",
                          ["render", str(inside), str(kit.lights), "--size", "96", "-o", depth_png], "error", depth_png))
    photo_home = kit.bundle("photo_home")
    shutil.copy(kit.photo, photo_home / "my_photo.jpg")
    shutil.copy(kit.mask, photo_home / "my_mask.png")
    kit.cases.append(Case("output over input", "infer -o the folder holding the photo", ["infer", str(photo_home / "my_photo.jpg"),
                      "--mask", str(photo_home / "my_mask.png"), "--size", "64", "--max-size", "256", "-o", str(photo_home)],
                      "error", str(photo_home)))
    for what, plot in (("--plot the light file's path", None), ("--plot a .txt", str(kit.out / "plot.txt")),
                       ("--plot in /proc", "/proc/nope/p.png")):
        o = str(kit.out / f"fit{next(kit.counter)}.json")
        kit.cases.append(Case("output over input", f"fit-lights {what}", ["fit-lights", str(kit.env), "-n", "4", "--method", "median-cut",
                                                                      "-o", o, "--plot", plot or o], "error", o))
    for what, name in (("a 300-byte name", "a" * 300 + ".png"), ("a 240-byte name", "d" * 240 + ".png"),
                       ("a newline in the name", "x\nrelight: error: fake.png")):
        kit.cases.append(Case("output over input", f"-o {what}", ["render", str(kit.sample), str(kit.lights), "--size", "96", "-o",
                                                               str(kit.out / name)], "error", str(kit.out / name)))
    sibling = kit.out / "sibling"
    (sibling / "x.exr").mkdir(parents=True, exist_ok=True)
    kit.cases.append(Case("output over input", "-o whose EXR is a folder", ["render", str(kit.sample), str(kit.lights), "--size", "96",
                                                                            "-o",
                                                                         str(sibling / "x.png")], "error", str(sibling / "x.png")))
    for what, extra in (("--fps 1e-9", ["--frames", "2", "--fps", "1e-9"]), ("--fps 1e9", ["--frames", "2", "--fps", "1e9"]),
                        ("--frames 1e12", ["--frames", "1000000000000"]), ("--turn 1e300", ["--frames", "2", "--turn", "1e300"]),
                        ("--turn nan", ["--frames", "2", "--turn", "nan"])):
        kit.render("option", what, kit.sample, kit.lights, *extra, suffix=".mp4")
    kit.render("option", "--terms 0 (named)", kit.sample, kit.lights, "--terms", "0")
    kit.render("option", "-n 5000", kit.sample, "--env", kit.env, "-n", "5000", "--method", "median-cut")
    huge_int = json.loads(kit.good)
    huge_int["lights"][0]["direction"] = ["DIGITS", 0, 0]  # written as text: no interpreter-wide digit limit change
    kit.render("light file", "an integer of 400 digits", kit.sample,
               kit.write("bigint_lights.json", json.dumps(huge_int).replace('"DIGITS"', "1" + "0" * 400)))
    np.save(kit.work / "files" / "many.npy", np.tile(np.array([[0, 0, 1, 1, 1, 1, 1]], np.float32), (2000, 1)))
    kit.render("light file", "2000 lights", kit.sample, kit.work / "files" / "many.npy")
    np.save(kit.work / "files" / "strings.npy", np.array([["a"] * 7]))
    kit.render("light file", "a .npy of strings", kit.sample, kit.work / "files" / "strings.npy")
    fifo = kit.work / "files" / "fifo.json"
    os.mkfifo(fifo)
    kit.render("saved look", "a named pipe", kit.sample, kit.lights, "--look", fifo)
    zero = kit.work / "files" / "zero.json"
    os.symlink("/dev/zero", zero)
    kit.render("saved look", "a link to /dev/zero", kit.sample, kit.lights, "--look", zero)
    for what, edit in (("camera width Inf", lambda m: m["camera"].update(width=float("inf"))),
                       ("focal length 1e-300", lambda m: m["camera"].update(focal_mm=1e-300)),
                       ("sensor 1e300", lambda m: m["camera"].update(sensor_mm=1e300)),
                       ("a 300-byte map name", lambda m: m["maps"].update(albedo="a" * 300 + ".exr"))):
        kit.render("scene bundle", what, kit.bundle(what.replace(" ", "_")[:20], edit), kit.lights)
    bright = np.full((32, 64, 3), 3e38, np.float32)
    write_exr(kit.work / "files" / "bright.exr", bright)
    kit.render("environment map", "every pixel 3e38", kit.sample, "--env", kit.work / "files" / "bright.exr", "-n", "4", "--method",
               "median-cut")
    for what, change in (("width -1", {"width": -1}), ("levels 0", {"levels": 0}), ("width 100000", {"width": 100000})):
        nets = kit.work / "networks" / what.replace(" ", "_")
        shutil.copytree(network_dir(), nets)
        card = json.loads((nets / "inverse.json").read_text())
        card["model"].update(change)
        (nets / "inverse.json").write_text(json.dumps(card))
        o = str(kit.out / f"bundle{next(kit.counter)}")
        kit.cases.append(Case("network card", what, ["infer", str(kit.photo), "--mask", str(kit.mask), "--size", "64", "--max-size", "256",
                                                  "--networks", str(nets), "-o", o], "error", o))


def photos(kit: Campaign) -> None:
    """Photos (inference)."""
    jpg = kit.photo.read_bytes()
    photos = list(truncations(jpg, "photo.jpg", kit.write))
    photos += [("random bytes", kit.write("random.jpg", kit.rng.bytes(20000))), ("an empty file", kit.write("empty.jpg", b"")),
               ("a text file named .jpg", kit.write("text.jpg", "hello")), ("missing", kit.work / "files" / "missing.jpg")]
    bomb = kit.work / "files" / "bomb.png"
    Image.new("1", (40000, 40000)).save(bomb)  # 200 KB on disk, 1.6 G pixels claimed
    photos.append(("a 40000x40000 PNG", bomb))
    Image.open(kit.photo).resize((2000, 1)).save(kit.work / "files" / "sliver.png")
    photos.append(("a 2000x1 photo", kit.work / "files" / "sliver.png"))
    for what, path in photos:
        o = str(kit.out / f"bundle{next(kit.counter)}")
        kit.cases.append(Case("photo", what, ["infer", str(path), "--mask", str(kit.mask), "--size", "64", "--max-size", "256", "-o", o],
                          "error", o))
    small_mask = kit.work / "files" / "small_mask.png"
    Image.open(kit.mask).resize((50, 60)).save(small_mask)
    for what, m in (("a kit.mask of another size", small_mask), ("an all-zero mask", None), ("a kit.mask that is random bytes", None),
                    ("the kit.photo as its own mask", kit.photo)):
        if what == "an all-zero mask":
            m = kit.work / "files" / "zero_mask.png"
            Image.new("L", Image.open(kit.mask).size, 0).save(m)
        elif what == "a kit.mask that is random bytes":
            m = kit.write("random_mask.png", kit.rng.bytes(1000))
        o = str(kit.out / f"bundle{next(kit.counter)}")
        kit.cases.append(Case("photo", what, ["infer", str(kit.photo), "--mask", str(m), "--size", "64", "--max-size", "256", "-o", o],
                          "error", o))
    upright = Image.open(kit.photo)
    stored = upright.transpose(Image.Transpose.ROTATE_90)  # as a phone stores it: turned, with orientation 6
    exif = stored.getexif()
    exif[0x0112] = 6
    sideways = kit.work / "files" / "exif_rotated.jpg"
    stored.save(sideways, exif=exif.tobytes(), quality=92)
    o = str(kit.out / f"bundle{next(kit.counter)}")
    scale = 256 / max(upright.size)
    kit.cases.append(Case("photo", "an EXIF-rotated kit.photo (comes kit.out upright)", ["infer", str(sideways), "--size", "64",
                                                                              "--max-size", "256", "-o", o], "ok", o,
                      upright=(round(upright.size[0] * scale), round(upright.size[1] * scale))))
    o = str(kit.out / "folder_with_files")
    Path(o).mkdir(exist_ok=True)
    (Path(o) / "keep.txt").write_text("the user's")
    kit.cases.append(Case("photo", "-o a folder holding other files", ["infer", str(kit.photo), "--mask", str(kit.mask), "--size", "64",
                                                                     "--max-size", "256", "-o", o], "error", o))
