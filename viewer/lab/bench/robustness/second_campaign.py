"""The second campaign's classes: a user's files beside the outputs, a bundle as a closed
box, bounded parsers, memory and time budgets. Each class makes its variants from a seeded random
generator (names, sizes, digit counts, cut points), so a new seed gives new cases of the same
classes; the bundle's names come from the bundle itself, so a new map name is covered as it ships."""

from __future__ import annotations

import json
import os
import shutil
import struct
from pathlib import Path

import numpy as np

from viewer.files.imageio import write_exr
from viewer.lab.bench.robustness.case import Case
from viewer.lab.bench.robustness.first_campaign import Campaign
from viewer.lighting.envmap import EnvMap, save_envmap
from viewer.lighting.placed_lights import PlacedLight, save_rig
from viewer.resources import network_dir
from viewer.scene.bundle import FRAME_FILES, MAP_FILES, OPTIONAL_FILES


def second_campaign(kit: Campaign, photo_bundle: Path) -> None:
    """``photo_bundle``: a bundle inferred from the bundled photo (it has a frame layer)."""
    for group in (users_files, parsers, budgets, too_bright):
        group(kit)
    closed_bundles(kit, photo_bundle)


def _name(kit: Campaign, suffix: str) -> str:
    letters = np.array(list("abcdefghijklmnopqrstuvwxyz_-"))
    return "".join(kit.rng.choice(letters, int(kit.rng.integers(3, 12)))) + suffix


def users_files(kit: Campaign) -> None:
    """Only what the program wrote is replaced: a user's file in or beside every kind of output."""
    group = "a user's files"
    for k in range(3):  # a folder holding a scene.json and the user's own file: refused, untouched
        folder = kit.out / f"project{k}"
        folder.mkdir()
        (folder / "scene.json").write_text(json.dumps({"format": "relight-scene"}))
        (folder / _name(kit, ".txt")).write_bytes(kit.rng.bytes(int(kit.rng.integers(1, 5000))))
        kit.cases.append(Case(group, f"infer -o a folder with a scene.json and the user's file ({k + 1})",
                              ["infer", str(kit.photo), "--mask", str(kit.mask), "--size", "64", "--max-size", "256", "-o",
                               str(folder)], "error", str(folder)))
    for k in range(2):  # the user's own NAME.partial.mp4 beside a video: kept, the command refused
        video = kit.out / _name(kit, ".mp4")
        partial = video.with_name(video.stem + ".partial.mp4")
        partial.write_bytes(kit.rng.bytes(2000))
        kit.cases.append(Case(group, f"a video whose .partial.mp4 is the user's ({k + 1})",
                              ["render", str(kit.sample), str(kit.lights), "--size", "64", "--frames", "3", "-o", str(video)],
                              "error", str(video), watch=[str(partial)]))
    for suffix in (".exr", ".png"):  # the rig is an input: the frame's PNG or EXR may not replace it
        rig = kit.out / ("rig" + suffix)
        save_rig(rig, [PlacedLight(azimuth=float(kit.rng.uniform(-90, 90)), elevation=30.0, intensity=2.0)])
        kit.cases.append(Case(group, f"--rig r{suffix} with -o r.png", ["render", str(kit.sample), str(kit.lights), "--size", "64",
                                                                         "--rig", str(rig), "-o", str(rig.with_suffix(".png"))],
                              "error", str(rig.with_suffix(".png")) if suffix == ".exr" else None))
    for typed in ("R.PNG", "mixed.Png"):  # the case typed is the case written
        o = kit.out / typed
        kit.cases.append(Case(group, f"-o {typed} keeps its case", ["render", str(kit.sample), str(kit.lights), "--size", "64",
                                                                    "-o", str(o)], "ok", str(o)))


def closed_bundles(kit: Campaign, photo_bundle: Path) -> None:
    """Every file a bundle holds, linked out of the bundle in turn: each the loader reads (listed,
    default-named, the frame's maps, scene.json itself) is refused before it is read; the others (a
    README, the photo's fitted lights) are not read, and the render goes on."""
    outside = kit.work / "files" / "outside"
    outside.mkdir(parents=True, exist_ok=True)
    for source in (kit.sample, photo_bundle):
        meta = json.loads((source / "scene.json").read_text())
        read = {"scene.json", *MAP_FILES.values(), *OPTIONAL_FILES.values(), *FRAME_FILES.values(),
                *meta.get("maps", {}).values(), *(meta.get("frame") or {}).get("maps", {}).values()}
        for f in sorted(p.name for p in source.iterdir() if p.is_file() and not p.name.startswith(".")):
            b = kit.work / "bundles" / f"linked_{source.name}_{f}"
            shutil.copytree(source, b)
            target = outside / f"{source.name}_{f}"
            shutil.copy(b / f, target)
            (b / f).unlink()
            os.symlink(target, b / f)
            o = kit.target()
            kit.cases.append(Case("a closed bundle", f"{source.name}'s {f} a link out of the bundle",
                                  ["render", str(b), str(kit.lights), "--size", "64", "-o", o],
                                  "error" if f in read else "ok", o))


def parsers(kit: Campaign) -> None:
    """Numbers, headers and names the readers must bound before they allocate or decode."""
    group = "bounded parsers"
    digits = [int(d) for d in kit.rng.integers(41, 6000, 4)]
    rig = kit.write("rig.json", json.dumps({"format": "relight-rig", "lights": [{"azimuth": 10.0, "intensity": 1.0}]}))
    for d, (kind, path, key) in zip(digits, (("light file", kit.lights, "sigma"), ("look", None, "yaw"),
                                             ("rig", rig, "azimuth"), ("scene.json", kit.sample / "scene.json", "focal_mm"))):
        number = "9" * d if d % 2 else "0." + "3" * d
        if kind == "look":
            text = json.dumps({"look": {"yaw": "N"}})
        else:
            text = path.read_text()
            text = text.replace(f'"{key}": ', f'"{key}": "N", "_was": ', 1)
        text = text.replace('"N"', number)
        if kind == "scene.json":
            b = kit.bundle(f"digits_{d}", files={"scene.json": text.encode()})
            kit.render(group, f"scene.json with a number of {d} digits", b, kit.lights)
        elif kind == "look":
            kit.render(group, f"a look with a number of {d} digits", kit.sample, kit.lights, "--look",
                       kit.write(f"digits_{d}_look.json", text))
        elif kind == "rig":
            kit.render(group, f"a rig with a number of {d} digits", kit.sample, kit.lights, "--rig",
                       kit.write(f"digits_{d}_rig.json", text))
        else:
            kit.render(group, f"a light file with a number of {d} digits", kit.sample, kit.write(f"digits_{d}_lights.json", text))
    for rows in (int(r) for r in kit.rng.integers(10**6, 10**12, 2, dtype=np.int64)):  # a .npy header claiming rows
        path = kit.work / "files" / f"rows_{rows}.npy"
        np.save(path, np.zeros((2, 7), np.float32))
        path.write_bytes(_npy_claiming(path.read_bytes(), rows))
        kit.render(group, f"a .npy header claiming {rows} lights", kit.sample, path)
    for w in (24000, int(kit.rng.integers(16385, 60000))):  # an EXR map whose header claims w x w/2
        path = kit.work / "files" / f"claims_{w}.exr"
        write_exr(path, np.ones((16, 32, 3), np.float32))
        raw = bytearray(path.read_bytes())
        start = raw.find(b"dataWindow")
        value = raw.find(b"\0", raw.find(b"\0", start) + 1) + 1 + 4
        struct.pack_into("<iiii", raw, value, 0, 0, w - 1, w // 2 - 1)
        path.write_bytes(bytes(raw))
        kit.render(group, f"an EXR map claiming {w}x{w // 2}", kit.sample, "--env", path, "-n", "4", "--method", "median-cut")
    hdr = kit.env.read_bytes()
    head, rest = hdr.split(b"\n\n", 1)
    for lines, width in ((int(kit.rng.integers(3000, 9000)), 20), (1, int(kit.rng.integers(70_000, 200_000)))):
        comments = b"".join(b"\n# " + b"c" * width for _ in range(lines))
        path = kit.write(f"long_header_{lines}_{width}.hdr", head + comments + b"\n\n" + rest)
        kit.render(group, f"a .hdr header of {len(comments) // 1024} KB ({lines} lines)", kit.sample, "--env", path, "-n", "4",
                   "--method", "median-cut", expect="ok")
    kit.render(group, "a .hdr header without its end", kit.sample, "--env",
               kit.write("endless.hdr", b"#?RADIANCE\n" + b"# x\n" * 5_000_000), "-n", "4", "--method", "median-cut")
    for byte in (int(b) for b in kit.rng.integers(0x80, 0x100, 2)):  # names that are not UTF-8
        name = bytes([byte])
        map_path = Path(os.fsdecode(os.fsencode(kit.work / "files") + b"/m" + name + b".hdr"))
        shutil.copy(kit.env, map_path)
        kit.render(group, f"a map named with the byte {byte:#x}", kit.sample, "--env", map_path, "-n", "4", "--method",
                   "median-cut", expect="ok")
        o = os.fsdecode(os.fsencode(kit.out) + b"/o" + name + b".png")
        kit.cases.append(Case(group, f"-o named with the byte {byte:#x}", ["render", str(kit.sample), str(kit.lights), "--size",
                                                                         "64", "-o", o], "error", o))
    albedo = (kit.sample / "albedo.exr").read_bytes()
    for cut in sorted(int(c) for c in kit.rng.integers(400, len(albedo) - 1, 3)):  # OpenEXR's own lines folded into ours
        kit.render(group, f"albedo.exr cut at {cut} bytes (one line, OpenEXR's words in it)",
                   kit.bundle(f"exr_cut_{cut}", files={"albedo.exr": albedo[:cut]}), kit.lights)


def _npy_claiming(raw: bytes, rows: int) -> bytes:
    """A .npy file whose header claims ``rows`` rows, its header length kept (padding adjusted)."""
    header_len = struct.unpack("<H", raw[8:10])[0]
    header = raw[10:10 + header_len].decode("latin1").replace("(2, 7)", f"({rows}, 7)")
    header = header.rstrip("\n").rstrip(" ")
    header = header + " " * (header_len - len(header) - 1) + "\n"
    return raw[:10] + header.encode("latin1") + raw[10 + header_len:]


def budgets(kit: Campaign) -> None:
    """Sizes inside the documented limits run within the memory budget; sizes past it are refused in
    one line before anything large is allocated."""
    group = "memory and time"
    big = kit.work / "files" / "map_16384.hdr"
    tile = np.asarray(kit.rng.random((64, 128, 3)) ** 3 * 4, np.float32)
    tile[5:8, 20:23] = 5e3  # a sun
    save_envmap(big, EnvMap(np.tile(tile, (128, 128, 1))))  # 16384x8192, the largest map read
    o = str(kit.out / "lights_16384.json")
    kit.cases.append(Case(group, "fit-lights on a 16384x8192 map", ["fit-lights", str(big), "-n", "16", "-o", o], "ok", o))
    o = kit.target()
    kit.cases.append(Case(group, "render --size 8192 with the frame at 16384", ["render", str(kit.sample), str(kit.lights),
                                                                               "--size", "8192", "--max-size", "16384", "-o", o],
                          "error", o))
    for n, method, expect in ((257, "fast", "error"), (65, "paper", "error"), (256, "instant", "ok")):
        o = str(kit.out / f"lights_{n}_{method}.json")
        kit.cases.append(Case(group, f"fit-lights -n {n} --method {method}", ["fit-lights", str(kit.env), "-n", str(n), "--method",
                                                                              method, "-o", o], expect, o))
    for width, levels in ((256, 8), (int(kit.rng.integers(32, 257)), int(kit.rng.integers(6, 9)))):
        nets = kit.work / "networks" / f"card_{width}_{levels}"
        shutil.copytree(network_dir(), nets)
        card = json.loads((nets / "inverse.json").read_text())
        card["model"].update(width=width, levels=levels)
        (nets / "inverse.json").write_text(json.dumps(card))
        o = str(kit.out / f"bundle_card_{width}_{levels}")
        kit.cases.append(Case(group, f"a network card of width {width} and {levels} levels",
                              ["infer", str(kit.photo), "--mask", str(kit.mask), "--size", "64", "--max-size", "256",
                               "--networks", str(nets), "-o", o], "error", o))
    wide = json.loads(kit.good)
    for light in wide["lights"]:
        light["sigma"] = 256.0
    kit.render(group, "--soft csm --prefilter exact with the widest lights", kit.sample,
               kit.write("widest_lights.json", json.dumps(wide)), "--soft", "csm", "--prefilter", "exact", expect="ok")
    from PIL import Image

    photo = kit.work / "files" / "photo_16000.png"
    Image.new("RGB", (16000, 10000), (90, 80, 70)).save(photo)
    o = str(kit.out / "bundle_16000")
    kit.cases.append(Case(group, "infer a 16000x10000 photo at --max-size 16384", ["infer", str(photo), "--max-size", "16384",
                                                                                  "-o", o], "error", o))


def too_bright(kit: Campaign) -> None:
    """Lights inside the allowed range (intensities up to 1e20) but far brighter than any exposure
    shows: the white person comes with a warning line that says what to change."""
    for scale in (float(10 ** kit.rng.uniform(14, 19)), 2.0 ** 12):
        bright = json.loads(kit.good)
        for light in bright["lights"]:
            light["intensity"] = [v * scale for v in light["intensity"]]
        kit.render("too bright", f"every light {scale:.3g} times brighter", kit.sample,
                   kit.write(f"bright_{scale:.3g}_lights.json", json.dumps(bright)), expect="warned")
