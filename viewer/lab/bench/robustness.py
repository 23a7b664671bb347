"""``relight bench robustness``: the bad-input campaign, rerunnable. Hostile files and options are
made in a scratch folder (empty, truncated, random, wrongly encoded, deeply nested, huge-claiming,
out-of-range, escaping the bundle, folders where files belong), the real command line runs on
each in its own process, and every case is judged:

- clean exit: 0 when the case is valid, 2 with one ``relight: error:`` (or argparse's usage error)
  line when not; never a traceback, never killed by a timeout;
- nothing written on an error (the ``-o`` target absent or as it was), every input file unchanged;
- a successful render is not black unless the case says so (a black map, with its warning line).

Prints how many cases were tried and how many ended cleanly, and writes the cases to JSON.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from viewer.imageio import write_text
from viewer.resources import asset_dir, sample_scene_dir

TIMEOUT = 180.0


@dataclass
class Case:
    group: str
    name: str
    args: list[str]
    expect: str  # "ok", "black" (ok, with a warning line) or "error"
    output: str | None = None  # the -o target (absent or unchanged on an error)
    cache: str | None = None  # its own light cache (default: the campaign's)
    upright: tuple | None = None  # an inferred bundle's frame must come out this size (not sideways)
    result: dict = field(default_factory=dict)


def _exists(path) -> bool:
    try:
        return Path(path).exists()
    except OSError:  # a name the system refuses (too long): nothing is there
        return False


def _digest(path: Path) -> str | None:
    """A file's or folder's content hash; a pipe or a device is named, never read (it could block or never end)."""
    if not _exists(path):
        return None
    if not path.is_dir() and not path.is_file():
        return f"special:{path.resolve()}"
    if path.is_dir():
        return "dir:" + ",".join(sorted(p.name + ":" + (_digest(p) or "") for p in path.iterdir()))
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _truncations(data: bytes, name: str, write):
    """Files cut at several points (and emptied)."""
    for frac in (0.0, 0.01, 0.1, 0.5, 0.9):
        cut = int(len(data) * frac)
        yield f"{name} truncated to {cut} bytes", write(f"trunc{int(frac * 100)}_{name}", data[:cut])


def make_cases(work: Path) -> list[Case]:
    """The campaign's cases, their files made in ``work``."""
    rng = np.random.default_rng(17)
    assets = asset_dir()
    sample = sample_scene_dir()
    lights = assets / "envmaps" / "venice_sunset_256.lights.json"
    env = assets / "envmaps" / "venice_sunset_256.hdr"
    photo = assets / "photos" / "underpass.jpg"
    mask = assets / "photos" / "underpass.mask.png"
    out = work / "out"
    out.mkdir(parents=True, exist_ok=True)
    cases: list[Case] = []
    counter = iter(range(10**6))

    def write(name: str, data) -> Path:
        path = work / "files" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data if isinstance(data, bytes) else data.encode("utf-8"))
        return path

    def target(suffix=".png") -> str:
        return str(out / f"case{next(counter)}{suffix}")

    def render(group, name, *args, expect="error", suffix=".png"):
        o = target(suffix)
        cases.append(Case(group, name, ["render", *map(str, args), "--size", "96", "-o", o], expect, o))

    # ---------------------------------------------------------------- light files
    good = lights.read_bytes()
    light_json = json.loads(good)
    light_files = list(_truncations(good, "lights.json", write))
    light_files += [
        ("random bytes", write("random_lights.json", rng.bytes(4096))),
        ("not UTF-8", write("latin1_lights.json", good.replace(b'"relight-lights"', b'"relight-lights\xe9"'))),
        ("nested 100,000 deep", write("deep_lights.json", "[" * 100000 + "]" * 100000)),
        ("a JSON list", write("list_lights.json", "[1, 2, 3]")),
        ("a JSON string", write("string_lights.json", '"lights"')),
        ("another format", write("format_lights.json", json.dumps({**light_json, "format": "other"}))),
        ("no lights", write("empty_lights.json", json.dumps({**light_json, "lights": []}))),
        ("a missing key", write("key_lights.json", json.dumps({**light_json, "lights": [{"direction": [0, 0, 1]}]}))),
    ]
    for what, value in (("direction NaN", {"direction": [float("nan"), 0, 1]}), ("direction zero", {"direction": [0, 0, 0]}),
                        ("sigma negative", {"sigma": -1.0}), ("sigma 1e6", {"sigma": 1e6}), ("sigma Inf", {"sigma": float("inf")}),
                        ("intensity negative", {"intensity": [-1, 0, 0]}), ("intensity 1e30", {"intensity": [1e30, 1, 1]}),
                        ("intensity a string", {"intensity": "bright"}), ("direction of 2 values", {"direction": [0, 1]})):
        bad = json.loads(good)
        bad["lights"][0].update(value)
        light_files.append((what, write(f"light_{what.replace(' ', '_')}.json", json.dumps(bad))))
    light_files.append(("a folder", work / "files" / "folder_lights.json"))
    (work / "files" / "folder_lights.json").mkdir(parents=True, exist_ok=True)
    light_files.append(("missing", work / "files" / "missing_lights.json"))
    huge = work / "files" / "huge_lights.json"
    with open(huge, "wb") as f:  # sparse: claims 100 MB without using the disk
        f.truncate(100 << 20)
    light_files.append(("100 MB", huge))
    npy = work / "files" / "object.npy"
    np.save(npy, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    light_files.append(("a pickled .npy", npy))
    np.save(work / "files" / "shape.npy", np.zeros((3, 5)))
    light_files.append(("a .npy of the wrong shape", work / "files" / "shape.npy"))
    for what, path in light_files:
        render("light file", what, sample, path)
    render("light file", "the valid file", sample, lights, expect="ok")

    # ---------------------------------------------------------------- environment maps
    hdr = env.read_bytes()
    maps = list(_truncations(hdr, "map.hdr", write))
    maps += [
        ("random bytes", write("random.hdr", rng.bytes(8192))),
        ("header claims 800000x400000", write("huge.hdr", b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 400000 +X 800000\n" + bytes(64))),
        ("no resolution line", write("nores.hdr", b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n")),
        ("no signature", write("nosig.hdr", b"FORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 4\n" + bytes(32))),
        ("a PNG named .hdr", write("png.hdr", mask.read_bytes())),
        ("an unknown suffix", write("map.tga", hdr)),
        ("missing", work / "files" / "missing.hdr"),
    ]
    for what, path in maps:
        render("environment map", what, sample, "--env", path, "-n", "4", "--method", "median-cut")
    from viewer.envmap import EnvMap, load_envmap, save_envmap

    px = np.ones((32, 64, 3), np.float32)
    px[3, 5] = np.nan
    nan_map = work / "files" / "nan.exr"
    from viewer.imageio import write_exr

    write_exr(nan_map, px)
    render("environment map", "NaN pixels", sample, "--env", nan_map, "-n", "4", "--method", "median-cut")
    render("environment map", "NaN pixels with --repair", sample, "--env", nan_map, "-n", "4", "--method", "median-cut",
           "--repair", expect="ok")
    neg = px.copy()
    neg[3, 5] = -1.0
    write_exr(work / "files" / "negative.exr", neg)
    render("environment map", "negative pixels", sample, "--env", work / "files" / "negative.exr", "-n", "4", "--method", "median-cut")
    save_envmap(work / "files" / "black.hdr", EnvMap(np.zeros((32, 64, 3), np.float32)))
    render("environment map", "an all-black map", sample, "--env", work / "files" / "black.hdr", "-n", "4",
           "--method", "median-cut", expect="black")
    save_envmap(work / "files" / "tiny.hdr", EnvMap(np.full((1, 2, 3), 0.5, np.float32)))
    render("environment map", "a 2x1 map for 4 lights", sample, "--env", work / "files" / "tiny.hdr", "-n", "4",
           "--method", "median-cut")
    render("environment map", "a 2x1 map for 1 light", sample, "--env", work / "files" / "tiny.hdr", "-n", "1",
           "--method", "median-cut", expect="ok")
    exr_bytes = nan_map.read_bytes()
    for what, path in _truncations(exr_bytes, "map.exr", write):
        render("environment map", what, sample, "--env", path, "-n", "4", "--method", "median-cut")

    # ---------------------------------------------------------------- scene bundles
    def bundle(name: str, edit=None, files=None) -> Path:
        b = work / "bundles" / name
        shutil.copytree(sample, b, dirs_exist_ok=True)
        meta = json.loads((b / "scene.json").read_text())
        if edit is not None:
            edit(meta)
            (b / "scene.json").write_text(json.dumps(meta))
        for fname, data in (files or {}).items():
            (b / fname).write_bytes(data)
        return b

    outside = work / "files" / "outside.exr"
    shutil.copy(sample / "albedo.exr", outside)
    bundles = [
        ("map name ../ escapes", bundle("escape", lambda m: m["maps"].update(albedo="../../files/outside.exr"))),
        ("absolute map path", bundle("absolute", lambda m: m["maps"].update(albedo=str(outside)))),
        ("map in a sub-folder", bundle("subfolder", lambda m: m["maps"].update(albedo="sub/albedo.exr"))),
        ("map name not a string", bundle("notstring", lambda m: m["maps"].update(albedo=3))),
        ("another format", bundle("format", lambda m: m.update(format="x"))),
        ("a newer version", bundle("version", lambda m: m.update(version=99))),
        ("width that disagrees", bundle("width", lambda m: m.update(width=100))),
        ("camera missing", bundle("camera", lambda m: m.pop("camera"))),
        ("scene.json not UTF-8", bundle("latin1", files={"scene.json": b'{"format": "\xe9"}'})),
        ("scene.json nested deep", bundle("deep", files={"scene.json": b"[" * 100000 + b"]" * 100000})),
        ("scene.json a list", bundle("list", files={"scene.json": b"[]"})),
        ("albedo random bytes", bundle("albedo_random", files={"albedo.exr": rng.bytes(5000)})),
        ("albedo truncated", bundle("albedo_trunc", files={"albedo.exr": (sample / "albedo.exr").read_bytes()[:3000]})),
        ("mask random bytes", bundle("mask_random", files={"mask.png": rng.bytes(300)})),
    ]
    link = bundle("symlink")
    (link / "albedo.exr").unlink()
    os.symlink(outside, link / "albedo.exr")
    bundles.append(("a map symlinked out of the bundle", link))
    missing = bundle("missing_map")
    (missing / "normal.exr").unlink()
    bundles.append(("a map file missing", missing))
    nojson = bundle("no_json")
    (nojson / "scene.json").unlink()
    bundles.append(("no scene.json", nojson))
    bundles.append(("a file, not a folder", photo))
    bundles.append(("missing", work / "bundles" / "nowhere"))
    from viewer.imageio import read_exr, write_png

    for what, arr_edit, fname in (("normals NaN", lambda a: a.__setitem__((200, 200), np.nan), "normal.exr"),
                                  ("normals not unit", lambda a: a.__setitem__((slice(None), slice(None)), a * 3.0), "normal.exr"),
                                  ("depth Inf", lambda a: a.__setitem__((250, 250), np.inf), "depth.exr"),
                                  ("depth negative", lambda a: a.__setitem__((slice(None), slice(None)), -np.abs(a)), "depth.exr"),
                                  ("albedo NaN", lambda a: a.__setitem__((250, 250), np.nan), "albedo.exr")):
        b = bundle(what.replace(" ", "_"))
        arr = read_exr(b / fname)
        arr_edit(arr)
        write_exr(b / fname, arr)
        bundles.append((what, b))
    for what, value in (("an empty mask", 0.0), ("a full mask", 1.0)):
        b = bundle(what.replace(" ", "_"))
        write_png(b / "mask.png", np.full((512, 512), value, np.float32))
        bundles.append((what, b))
    for what, data in _truncations((sample / "scene.json").read_bytes(), "scene.json", lambda n, d: d):
        bundles.append((f"scene.json {what.split(' ', 1)[1]}", bundle(f"json_{len(data)}", files={"scene.json": data})))
    big = bundle("huge_json")
    with open(big / "scene.json", "r+b") as f:
        f.truncate(100 << 20)
    bundles.append(("scene.json of 100 MB", big))
    for what, path in bundles:  # (a full mask claims pixels that have no normals)
        render("scene bundle", what, path, lights)

    passwd = work / "files" / "passwd_lights.json"
    os.symlink("/etc/passwd", passwd)
    render("light file", "a link to /etc/passwd", sample, passwd)

    # ---------------------------------------------------------------- light cache entries
    from viewer.lightfit.cache import cache_path

    for what, data in (("not UTF-8", b'{"format": "\xe9"}'), ("truncated", good[: len(good) // 3]), ("empty", b""),
                       ("random bytes", rng.bytes(777)), ("nested deep", b"[" * 100000 + b"]" * 100000), ("a folder", None)):
        cache = work / "caches" / what.replace(" ", "_")
        entry = cache_path(load_envmap(env), 4, "median-cut", cache)
        entry.parent.mkdir(parents=True, exist_ok=True)
        if data is None:
            entry.mkdir()
        else:
            entry.write_bytes(data)
        o = str(out / f"fit{next(counter)}.json")
        cases.append(Case("light cache", f"a cache entry {what}", ["fit-lights", str(env), "-n", "4", "--method", "median-cut",
                                                                   "-o", o], "ok", o, cache=str(cache)))

    # ---------------------------------------------------------------- saved looks
    looks = [
        ("empty", write("empty_look.json", b"")),
        ("not UTF-8", write("latin1_look.json", b'{"look": {"view": "\xe9"}}')),
        ("nested deep", write("deep_look.json", "[" * 100000 + "]" * 100000)),
        ("a list", write("list_look.json", "[1]")),
        ("exposure 1e9", write("exp_look.json", json.dumps({"look": {"exposure": 1e9}}))),
        ("yaw NaN", write("nan_look.json", '{"look": {"yaw": NaN}}')),
        ("an unknown view", write("view_look.json", json.dumps({"look": {"view": "x-ray"}}))),
        ("an unknown preset", write("preset_look.json", json.dumps({"look": {"preset": "ultra"}}))),
        ("missing", work / "files" / "missing_look.json"),
    ]
    looks += [(f"look {what}", path) for what, path in
              _truncations(json.dumps({"look": {"yaw": 10.0, "exposure": 1.0}}).encode(), "look.json", write)][1:4]
    for what, path in looks:
        render("saved look", what, sample, lights, "--look", path)
    render("saved look", "an older state file's look", sample, lights, "--look",
           write("old_look.json", json.dumps({"look": {"yaw": 20, "exposure": 0.5, "shadows": "hard", "light": 99}})), expect="ok")

    # ---------------------------------------------------------------- options
    options = [
        ("--yaw nan", ["--yaw", "nan"]), ("--yaw inf", ["--yaw", "inf"]), ("--yaw 1e300", ["--yaw", "1e300"]),
        ("--tilt nan", ["--tilt", "nan"]), ("--exposure 1e9", ["--exposure", "1e9"]), ("--exposure nan", ["--exposure", "nan"]),
        ("--exposure bright", ["--exposure", "bright"]), ("--size 0", ["--size", "0"]), ("--size -5", ["--size", "-5"]),
        ("--size 100000", ["--size", "100000"]), ("--max-size 0", ["--max-size", "0"]), ("--terms 1", ["--terms", "1"]),
        ("--terms 99", ["--terms", "99"]), ("--shadow-resolution 100", ["--shadow-resolution", "100"]),
        ("--shadow-resolution 65536", ["--shadow-resolution", "65536"]), ("--shadow-step -1", ["--shadow-step", "-1"]),
        ("--preset ultra", ["--preset", "ultra"]), ("--visibility x", ["--visibility", "x"]),
        ("--background sky", ["--background", "sky"]), ("--background photo without one", ["--background", "photo"]),
        ("-n 0", ["--env", env, "-n", "0"]), ("-n -1", ["--env", env, "-n", "-1"]),
    ]
    for what, extra in options:
        o = target()
        last_size = [i for i, a in enumerate(extra) if a == "--size"]
        args = ["render", str(sample), str(lights), *map(str, extra)] + ([] if last_size else ["--size", "96"]) + ["-o", o]
        if extra[0] == "--env":
            args = ["render", str(sample), *map(str, extra), "--method", "median-cut", "--size", "96", "-o", o]
        expect = "ok" if what == "--background photo without one" else "error"
        cases.append(Case("option", what, args, expect, o))
    video_opts = [("--frames 0", ["--frames", "0"]), ("--frames -3", ["--frames", "-3"]), ("--fps 0", ["--fps", "0"]),
                  ("--fps nan", ["--fps", "nan"]), ("--fps -30", ["--fps", "-30"])]
    for what, extra in video_opts:
        render("option", what, sample, lights, *extra, suffix=".mp4")
    existing = work / "files" / "existing.png"
    existing.write_bytes(mask.read_bytes())
    for what, o in (("-o an existing folder", work / "files"), ("-o a .txt", work / "files" / "x.txt"),
                    ("-o under a file", work / "files" / "existing.png" / "x.png"), ("-o in /proc", Path("/proc/nope/x.png"))):
        cases.append(Case("option", what, ["render", str(sample), str(lights), "--size", "96", "-o", str(o)], "error", str(o)))
    cases.append(Case("option", "-o an existing PNG (replaced whole)", ["render", str(sample), str(lights), "--size", "96",
                                                                         "-o", str(existing)], "ok", str(existing)))
    for what, extra in (("fit-lights -n 0", ["-n", "0"]), ("fit-lights -n 100000", ["-n", "100000"]),
                        ("fit-lights -o .txt", ["-n", "4", "-o", str(out / "l.txt")])):
        o = extra[-1] if "-o" in extra else str(out / f"fit{next(counter)}.json")
        args = ["fit-lights", str(env), "--method", "median-cut", *extra] + ([] if "-o" in extra else ["-o", o])
        cases.append(Case("option", what, args, "error", o))

    # ---------------------------------------------------------------- outputs that would replace inputs (a review's cases)
    exr_map = work / "files" / "venice.exr"
    write_exr(exr_map, load_envmap(env).pixels)
    render("output over input", "the EXR beside -o is the map", sample, "--env", exr_map, "-n", "4", "--method", "median-cut")
    cases[-1].args[-1] = cases[-1].output = str(exr_map.with_suffix(".png"))
    inside = bundle("written_into")
    cases.append(Case("output over input", "-o inside the scene bundle", ["render", str(inside), str(lights), "--size", "96",
                                                                          "-o", str(inside / "depth.png")], "error", str(inside / "depth.png")))
    photo_home = bundle("photo_home")
    shutil.copy(photo, photo_home / "my_photo.jpg")
    shutil.copy(mask, photo_home / "my_mask.png")
    cases.append(Case("output over input", "infer -o the folder holding the photo", ["infer", str(photo_home / "my_photo.jpg"),
                      "--mask", str(photo_home / "my_mask.png"), "--size", "64", "--max-size", "256", "-o", str(photo_home)],
                      "error", str(photo_home)))
    for what, plot in (("--plot the light file's path", None), ("--plot a .txt", str(out / "plot.txt")),
                       ("--plot in /proc", "/proc/nope/p.png")):
        o = str(out / f"fit{next(counter)}.json")
        cases.append(Case("output over input", f"fit-lights {what}", ["fit-lights", str(env), "-n", "4", "--method", "median-cut",
                                                                      "-o", o, "--plot", plot or o], "error", o))
    for what, name in (("a 300-byte name", "a" * 300 + ".png"), ("a 240-byte name", "d" * 240 + ".png"),
                       ("a newline in the name", "x\nrelight: error: fake.png")):
        cases.append(Case("output over input", f"-o {what}", ["render", str(sample), str(lights), "--size", "96", "-o",
                                                               str(out / name)], "error", str(out / name)))
    sibling = out / "sibling"
    (sibling / "x.exr").mkdir(parents=True, exist_ok=True)
    cases.append(Case("output over input", "-o whose EXR is a folder", ["render", str(sample), str(lights), "--size", "96", "-o",
                                                                         str(sibling / "x.png")], "error", str(sibling / "x.png")))
    for what, extra in (("--fps 1e-9", ["--frames", "2", "--fps", "1e-9"]), ("--fps 1e9", ["--frames", "2", "--fps", "1e9"]),
                        ("--frames 1e12", ["--frames", "1000000000000"]), ("--turn 1e300", ["--frames", "2", "--turn", "1e300"]),
                        ("--turn nan", ["--frames", "2", "--turn", "nan"])):
        render("option", what, sample, lights, *extra, suffix=".mp4")
    render("option", "--terms 0 (named)", sample, lights, "--terms", "0")
    render("option", "-n 5000", sample, "--env", env, "-n", "5000", "--method", "median-cut")
    import sys as _sys

    _sys.set_int_max_str_digits(0)
    huge_int = json.loads(good)
    huge_int["lights"][0]["direction"] = [10**400, 0, 0]
    render("light file", "an integer of 400 digits", sample, write("bigint_lights.json", json.dumps(huge_int)))
    np.save(work / "files" / "many.npy", np.tile(np.array([[0, 0, 1, 1, 1, 1, 1]], np.float32), (2000, 1)))
    render("light file", "2000 lights", sample, work / "files" / "many.npy")
    np.save(work / "files" / "strings.npy", np.array([["a"] * 7]))
    render("light file", "a .npy of strings", sample, work / "files" / "strings.npy")
    fifo = work / "files" / "fifo.json"
    os.mkfifo(fifo)
    render("saved look", "a named pipe", sample, lights, "--look", fifo)
    zero = work / "files" / "zero.json"
    os.symlink("/dev/zero", zero)
    render("saved look", "a link to /dev/zero", sample, lights, "--look", zero)
    for what, edit in (("camera width Inf", lambda m: m["camera"].update(width=float("inf"))),
                       ("focal length 1e-300", lambda m: m["camera"].update(focal_mm=1e-300)),
                       ("sensor 1e300", lambda m: m["camera"].update(sensor_mm=1e300)),
                       ("a 300-byte map name", lambda m: m["maps"].update(albedo="a" * 300 + ".exr"))):
        render("scene bundle", what, bundle(what.replace(" ", "_")[:20], edit), lights)
    bright = np.full((32, 64, 3), 3e38, np.float32)
    write_exr(work / "files" / "bright.exr", bright)
    render("environment map", "every pixel 3e38", sample, "--env", work / "files" / "bright.exr", "-n", "4", "--method", "median-cut")
    from viewer.resources import network_dir

    for what, change in (("width -1", {"width": -1}), ("levels 0", {"levels": 0}), ("width 100000", {"width": 100000})):
        nets = work / "networks" / what.replace(" ", "_")
        shutil.copytree(network_dir(), nets)
        card = json.loads((nets / "inverse.json").read_text())
        card["model"].update(change)
        (nets / "inverse.json").write_text(json.dumps(card))
        o = str(out / f"bundle{next(counter)}")
        cases.append(Case("network card", what, ["infer", str(photo), "--mask", str(mask), "--size", "64", "--max-size", "256",
                                                  "--networks", str(nets), "-o", o], "error", o))

    # ---------------------------------------------------------------- photos (inference)
    jpg = photo.read_bytes()
    photos = list(_truncations(jpg, "photo.jpg", write))
    photos += [("random bytes", write("random.jpg", rng.bytes(20000))), ("an empty file", write("empty.jpg", b"")),
               ("a text file named .jpg", write("text.jpg", "hello")), ("missing", work / "files" / "missing.jpg")]
    from PIL import Image

    bomb = work / "files" / "bomb.png"
    Image.new("1", (40000, 40000)).save(bomb)  # 200 KB on disk, 1.6 G pixels claimed
    photos.append(("a 40000x40000 PNG", bomb))
    Image.open(photo).resize((2000, 1)).save(work / "files" / "sliver.png")
    photos.append(("a 2000x1 photo", work / "files" / "sliver.png"))
    for what, path in photos:
        o = str(out / f"bundle{next(counter)}")
        cases.append(Case("photo", what, ["infer", str(path), "--mask", str(mask), "--size", "64", "--max-size", "256", "-o", o],
                          "error", o))
    small_mask = work / "files" / "small_mask.png"
    Image.open(mask).resize((50, 60)).save(small_mask)
    for what, m in (("a mask of another size", small_mask), ("an all-zero mask", None), ("a mask that is random bytes", None),
                    ("the photo as its own mask", photo)):
        if what == "an all-zero mask":
            m = work / "files" / "zero_mask.png"
            Image.new("L", Image.open(mask).size, 0).save(m)
        elif what == "a mask that is random bytes":
            m = write("random_mask.png", rng.bytes(1000))
        o = str(out / f"bundle{next(counter)}")
        cases.append(Case("photo", what, ["infer", str(photo), "--mask", str(m), "--size", "64", "--max-size", "256", "-o", o],
                          "error", o))
    upright = Image.open(photo)
    stored = upright.transpose(Image.Transpose.ROTATE_90)  # as a phone stores it: turned, with orientation 6
    exif = stored.getexif()
    exif[0x0112] = 6
    sideways = work / "files" / "exif_rotated.jpg"
    stored.save(sideways, exif=exif.tobytes(), quality=92)
    o = str(out / f"bundle{next(counter)}")
    scale = 256 / max(upright.size)
    cases.append(Case("photo", "an EXIF-rotated photo (comes out upright)", ["infer", str(sideways), "--size", "64",
                                                                              "--max-size", "256", "-o", o], "ok", o,
                      upright=(round(upright.size[0] * scale), round(upright.size[1] * scale))))
    o = str(out / "folder_with_files")
    Path(o).mkdir(exist_ok=True)
    (Path(o) / "keep.txt").write_text("the user's")
    cases.append(Case("photo", "-o a folder holding other files", ["infer", str(photo), "--mask", str(mask), "--size", "64",
                                                                     "--max-size", "256", "-o", o], "error", o))
    return cases


def _judge(case: Case, proc, seconds: float, before: dict, work: Path) -> dict:
    err = proc.stderr or ""
    lines = [l for l in err.splitlines() if l.strip() and "%|" not in l]
    problems = []
    if "Traceback" in err:
        problems.append("traceback")
    if case.expect == "error":
        if proc.returncode != 2:
            problems.append(f"exit {proc.returncode}, expected 2")
        errors = [l for l in lines if "error:" in l]
        if len(errors) != 1:
            problems.append(f"{len(errors)} error lines")
        if case.output is not None and _digest(Path(case.output)) != before.get(case.output):
            problems.append("the -o target was written")
    else:
        if proc.returncode != 0:
            problems.append(f"exit {proc.returncode}, expected 0")
        elif case.upright is not None:
            frame = json.loads((Path(case.output) / "scene.json").read_text())["frame"]
            if abs(frame["width"] - case.upright[0]) > 1 or abs(frame["height"] - case.upright[1]) > 1:
                problems.append(f"frame {frame['width']}x{frame['height']}, expected {case.upright[0]}x{case.upright[1]} upright")
        elif case.output and case.output.endswith(".png"):
            from viewer.imageio import read_png

            img = read_png(case.output)
            bright = float(img[..., :3].mean())
            if case.expect == "ok" and bright < 0.01:
                problems.append("black output")
            if case.expect == "black" and not any("warning" in l for l in lines):
                problems.append("black output without a warning")
    changed = [p for p, d in before.items() if p != case.output and _digest(Path(p)) != d]
    if changed:
        problems.append(f"input changed: {changed[:2]}")
    return {"exit": proc.returncode, "seconds": round(seconds, 2), "clean": not problems, "problems": problems,
            "last_line": lines[-1][:300] if lines else ""}


def _inputs(case: Case) -> list[str]:
    """The files and folders a case reads (watched: they must come out unchanged)."""
    return [a for a in case.args if a != case.output and os.path.sep in a and _exists(a)]


def run_case(case: Case, work: Path) -> dict:
    watched = {p: _digest(Path(p)) for p in _inputs(case) + ([case.output] if case.output else [])}
    env = {**os.environ, "RELIGHT_CACHE": case.cache or str(work / "cache")}
    start = time.perf_counter()
    try:
        proc = subprocess.run([sys.executable, "-m", "viewer.cli", *case.args], capture_output=True, text=True,
                              timeout=TIMEOUT, env=env, errors="replace")
    except subprocess.TimeoutExpired:
        return {"exit": None, "seconds": TIMEOUT, "clean": False, "problems": [f"no answer in {TIMEOUT:.0f} s"], "last_line": ""}
    return _judge(case, proc, time.perf_counter() - start, watched, work)


def run_robustness_benchmark(work=None, output="out/bench_robustness.json", jobs: int = 2, progress=None) -> dict:
    import tempfile

    with tempfile.TemporaryDirectory(prefix="relight-robustness-") as tmp:
        work = Path(work or tmp)
        start = time.perf_counter()
        cases = make_cases(work)
        with ThreadPoolExecutor(max_workers=max(jobs, 1)) as pool:
            for case, result in zip(cases, pool.map(lambda c: run_case(c, work), cases)):
                case.result = result
                if progress is not None:
                    progress(case)
        groups: dict = {}
        for c in cases:
            g = groups.setdefault(c.group, {"tried": 0, "clean": 0})
            g["tried"] += 1
            g["clean"] += int(c.result["clean"])
        report = {"tried": len(cases), "clean": sum(c.result["clean"] for c in cases), "groups": groups,
                  "tracebacks": sum("traceback" in c.result["problems"] for c in cases),
                  "seconds": round(time.perf_counter() - start, 1),
                  "cases": [{k: v for k, v in asdict(c).items() if k != "args"} | {"command": " ".join(c.args[:1])} for c in cases]}
    write_text(output, json.dumps(report, indent=1) + "\n")
    return report
