"""The fourth campaign's classes, each from the campaign's seeded generator so that a new seed gives
new variants: clip bundles whose records lie (counts, rates, times, links out of the bundle), cache entries of a
clip damaged or foreign (made again, with a note), clips too small or too thin, scripts that name other files,
folders of images given as a scene, maps with a filter's negative ringing, plates refused from their header or
taken whole (a portrait twice as tall), animated images, the file system's root as the cache, and scenarios: two
renders racing to one output (the output wholly one run's, the other refused in one line naming it), and a render
killed outright (SIGKILL) whose rerun takes up what it left."""

from __future__ import annotations

import json
import os
import shutil
import signal
import struct
import time
import zlib
from fractions import Fraction
from functools import partial
from pathlib import Path

import numpy as np

from viewer.lab.bench.robustness.case import Case, Scenario, run_command, start_command
from viewer.lab.bench.robustness.first_campaign import Campaign

VARIANTS = 5
CLIP_SIZE = (160, 240)  # the campaign's clip: the bundled photo's person, a window moved a few pixels a frame
CLIP_FRAMES = 4
FPS = 10


def fourth_campaign(kit: Campaign) -> list[Scenario]:
    """The cases go to ``kit.cases``; returns the scenarios (run with the others)."""
    clip = _person_clip(kit.work / "clips" / "walk.mp4")
    cache = kit.work / "clip_cache" / "lights"
    code, _, err, _, _ = run_command(["render", clip, "--env", kit.env, "-o", kit.work / "clips" / "first.mp4"],
                                     env={**os.environ, "RELIGHT_CACHE": str(cache)})
    if code != 0:
        raise RuntimeError(f"the campaign's clip could not be relit: {err[-300:]}")
    entry = next((cache.parent / "bundles").glob("walk-clip-*"))
    for group in (clip_records, damaged_cache_entries, small_clips, scripts_and_sequences, plates_and_images, cache_roots):
        group(kit, clip, entry)
    return [Scenario("two writers (issue 62)", f"two renders of one {what} to one output at once ({k + 1})",
                     partial(_two_renders, kit, clip, entry, what, k)) for k, what in enumerate(("turntable", "clip"))] + \
        [Scenario("interrupted outputs (issue 62)", f"SIGKILL at {f:.0%} of a video's render, then the same again",
                  partial(_killed_then_again, kit, f)) for f in kit.rng.uniform(0.2, 0.9, 2)]


def _person_clip(path: Path) -> Path:
    """``CLIP_FRAMES`` frames of the bundled photo's person (H.264, ``FPS``), a window moved 3 pixels a frame."""

    from viewer.photo.frames import read_photo
    from viewer.resize import resize
    from viewer.resources import asset_dir

    photo = read_photo(asset_dir() / "photos" / "underpass.jpg", [])
    w, h = CLIP_SIZE
    scale = 1.05 * h / photo.shape[0]
    big = resize(photo, (round(photo.shape[1] * scale), round(photo.shape[0] * scale)))
    x0 = (big.shape[1] - w) // 2 - 4
    frames = [np.ascontiguousarray(big[:h, x0 + 3 * i:x0 + 3 * i + w]) for i in range(CLIP_FRAMES)]
    return _write_clip(path, frames)


def _write_clip(path: Path, frames: list) -> Path:
    import av

    path.parent.mkdir(parents=True, exist_ok=True)
    with av.open(str(path), "w") as c:
        stream = c.add_stream("libx264", rate=FPS)
        stream.height, stream.width = frames[0].shape[:2]
        stream.pix_fmt = "yuv420p"
        for i, rgb in enumerate(frames):
            frame = av.VideoFrame.from_ndarray(rgb, format="rgb24")
            frame.pts, frame.time_base = i * 100, Fraction(1, 1000)
            for packet in stream.encode(frame):
                c.mux(packet)
        for packet in stream.encode():
            c.mux(packet)
    return path


def _bundle_copy(kit: Campaign, entry: Path, name: str) -> Path:
    b = kit.work / "clip_bundles" / name
    shutil.copytree(entry, b, symlinks=True)
    return b


def _render_clip(kit: Campaign, group: str, name: str, scene, expect: str = "error", cache: str | None = None,
                 said: str | None = None) -> None:
    out = kit.target(".mp4")
    kit.cases.append(Case(group, name, ["render", str(scene), "--env", str(kit.env), "-o", out], expect, out, cache=cache,
                          said=said))


def clip_records(kit: Campaign, clip: Path, entry: Path) -> None:
    """A clip bundle (given as the scene) whose record or frame records lie: refused in one line naming the file
    and the field, before any frame is relit; links inside it refused."""
    group = "a clip bundle's records (issue 62)"
    record = json.loads((entry / "clip.json").read_text())
    edits = [("frames", "abc"), ("frames", None), ("frames", CLIP_FRAMES + 1 + int(kit.rng.integers(0, 8))),
             ("frames", CLIP_FRAMES - 1), ("source.fps", "fast"), ("source.fps", 1e308), ("source.fps", -float(kit.rng.uniform(1, 60))),
             ("source.width", 0), ("first_frame_at", 1e300), ("first_frame_at", -1e9), ("version", 99), ("complete", "yes"),
             ("options.start", -1.0), ("source.rotation", 45)]
    for k, i in enumerate(kit.rng.permutation(len(edits))[:9]):
        field, value = edits[i]
        b = _bundle_copy(kit, entry, f"record_{k}")
        data = json.loads(json.dumps(record))
        target = data
        *parents, last = field.split(".")
        for p in parents:
            target = target[p]
        target[last] = value
        (b / "clip.json").write_text(json.dumps(data))  # (Python writes NaN and Infinity as JSON's readers take them)
        _render_clip(kit, group, f"clip.json {field} = {str(value)[:24]}", b)
    b = _bundle_copy(kit, entry, "nan_fps")
    (b / "clip.json").write_text((b / "clip.json").read_text().replace(f'"fps": {record["source"]["fps"]}', '"fps": NaN'))
    _render_clip(kit, group, "clip.json source.fps = NaN", b)
    for k, (seconds, what) in enumerate([(1e15, "1e15 s"), (-5.0, "-5 s"), (None, "the frame before's time")]):
        b = _bundle_copy(kit, entry, f"time_{k}")
        i = int(kit.rng.integers(1, CLIP_FRAMES))
        path = b / "frames" / f"{i:06d}.json"
        frame = json.loads(path.read_text())
        before = json.loads((b / "frames" / f"{i - 1:06d}.json").read_text())["seconds"]
        frame["seconds"] = before if seconds is None else seconds
        path.write_text(json.dumps(frame))
        _render_clip(kit, group, f"frame {i}'s time {what}", b)
    frame_edits = [("the record [1, 2]", [1, 2]), ("the record null", None), ("seconds true", {"seconds": True}),
                   ("index true", {"index": True}), ("pan [1e300, 0]", {"pan": [1e300, 0]}), ("pan of three", {"pan": [1, 2, 3]}),
                   ("shot -1", {"shot": -1}), ("shot 99", {"shot": 99}), ("state 'asleep'", {"state": "asleep"})]
    for k, i in enumerate(kit.rng.permutation(len(frame_edits))[:5]):
        what, edit = frame_edits[i]
        b = _bundle_copy(kit, entry, f"frame_{k}")
        path = b / "frames" / f"{int(kit.rng.integers(1, CLIP_FRAMES)):06d}.json"
        path.write_text(json.dumps({**json.loads(path.read_text()), **edit} if isinstance(edit, dict) else edit))
        _render_clip(kit, group, f"{path.name}: {what}", b)
    elsewhere = _bundle_copy(kit, entry, "elsewhere")
    for k, what in enumerate(("the frames folder", "a frame's bundle", "a frame's record", "clip.json")):
        b = _bundle_copy(kit, entry, f"link_{k}")
        i = int(kit.rng.integers(0, CLIP_FRAMES))
        name = {"the frames folder": "frames", "a frame's bundle": f"frames/{i:06d}", "a frame's record": f"frames/{i:06d}.json",
                "clip.json": "clip.json"}[what]
        target = b / name
        shutil.rmtree(target) if target.is_dir() else target.unlink()
        target.symlink_to(elsewhere / name)
        _render_clip(kit, group, f"{what} a link to a copy elsewhere", b)


def damaged_cache_entries(kit: Campaign, clip: Path, entry: Path) -> None:
    """The cache's bundle of a clip damaged or foreign: moved aside (nothing in it removed) and made again, with a
    warning; the clip relit."""
    group = "a clip's damaged cache entry (issue 62)"
    damages = ["a frame's albedo.exr truncated", "clip.json garbage", "clip.json a link", "a user's file in the entry",
               "a frame's record truncated", "the frames folder a link", "the entry a link"]
    for k, what in enumerate(kit.rng.permutation(damages)[:VARIANTS].tolist()):
        cache = kit.work / f"clip_cache_{k}" / "lights"
        (cache.parent / "bundles").mkdir(parents=True)
        b = cache.parent / "bundles" / entry.name
        shutil.copytree(entry, b, symlinks=True)
        i = int(kit.rng.integers(0, CLIP_FRAMES))
        if what == "a frame's albedo.exr truncated":
            f = b / "frames" / f"{i:06d}" / "albedo.exr"
            f.write_bytes(f.read_bytes()[: int(f.stat().st_size * kit.rng.uniform(0.05, 0.9))])
        elif what == "clip.json garbage":
            (b / "clip.json").write_bytes(kit.rng.bytes(int(kit.rng.integers(1, 400))))
        elif what == "clip.json a link":
            other = kit.work / "files" / f"linked_clip_{k}.json"
            other.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy(b / "clip.json", other)
            (b / "clip.json").unlink()
            (b / "clip.json").symlink_to(other)
        elif what == "a user's file in the entry":
            (b / "notes.txt").write_text("mine\n")
        elif what == "a frame's record truncated":
            f = b / "frames" / f"{i:06d}.json"
            f.write_bytes(f.read_bytes()[: int(kit.rng.integers(1, 20))])
        elif what == "the frames folder a link":
            moved = kit.work / "files" / f"frames_{k}"
            shutil.move(b / "frames", moved)
            (b / "frames").symlink_to(moved)
        else:  # the entry a link to a whole copy elsewhere
            moved = kit.work / "files" / f"entry_{k}"
            shutil.move(b, moved)
            b.symlink_to(moved)
        _render_clip(kit, group, what, clip, expect="ok", cache=str(cache), said="did not check out")


def small_clips(kit: Campaign, clip: Path, entry: Path) -> None:
    """Clips too small or too thin to relight (the optical flow's limits): one line before any frame is inferred."""
    group = "clips too small or thin (issue 62)"
    for k in range(3):
        w, h = [(2, 2), (int(kit.rng.integers(2, 6)) * 2, 2000), (2000, 4), (30, 30), (16, 2)][int(kit.rng.integers(0, 5))]
        frames = [np.full((h, w, 3), int(kit.rng.integers(0, 255)), np.uint8)] * 3
        path = _write_clip(kit.work / "clips" / f"small_{k}_{w}x{h}.mp4", frames)
        _render_clip(kit, group, f"a {w}x{h} clip", path)


def scripts_and_sequences(kit: Campaign, clip: Path, entry: Path) -> None:
    """An FFmpeg concat script named as a video (its frames another file's: refused), and a folder of frames
    given as a scene (image sequences are not read: said)."""
    group = "scripts and image sequences (issue 62)"
    script = kit.work / "clips" / "script.mp4"
    script.write_text(f"ffconcat version 1.0\nfile '{clip}'\n")
    _render_clip(kit, group, "an ffconcat script named .mp4", script)
    folder = kit.work / "clips" / "frames"
    folder.mkdir()
    from PIL import Image

    for i in range(int(kit.rng.integers(2, 6))):
        Image.fromarray(kit.rng.integers(0, 255, (24, 16, 3), dtype=np.uint8)).save(folder / f"{i:04d}.png")
    _render_clip(kit, group, "a folder of frames given as the scene", folder)


def _png_header(path: Path, width: int, height: int) -> Path:
    """A PNG whose header claims ``width`` x ``height`` and whose data is cut short: read from its header only."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(b"\x00" * 64)))
    return path


def plates_and_images(kit: Campaign, clip: Path, entry: Path) -> None:
    """Plates over the pixel limit refused from their header (before any decoding); a portrait plate twice as tall
    as wide taken (only a landscape 2:1 is a panorama); an animated GIF plate read as its first frame, said."""
    from PIL import Image

    group = "plates' sizes and kinds (issue 62)"
    for k in range(2):
        side = int(kit.rng.integers(9000, 20000))
        plate = _png_header(kit.work / "files" / f"huge_plate_{k}.png", side, side + int(kit.rng.integers(0, 500)))
        kit.cases.append(Case(group, f"a {side}-pixel-square plate (its header)", ["render", str(kit.sample), str(kit.lights),
                              "--plate", str(plate), "-o", kit.target()], "error", None))
    w = int(kit.rng.integers(200, 500))
    portrait = kit.work / "files" / "portrait_plate.jpg"
    Image.fromarray(np.tile(np.linspace(40, 200, 2 * w, dtype=np.uint8)[:, None, None], (1, w, 3))).save(portrait)
    o = kit.target()
    kit.cases.append(Case(group, f"a {w}x{2 * w} portrait plate", ["render", str(kit.sample), str(kit.lights), "--plate",
                          str(portrait), "--size", "96", "-o", o], "ok", o))
    gif = kit.work / "files" / "animated.gif"
    frames = [Image.fromarray(np.full((160, 240, 3), 60 + 40 * i, np.uint8)) for i in range(3)]
    frames[0].save(gif, save_all=True, append_images=frames[1:], duration=100)
    o = kit.target()
    kit.cases.append(Case(group, "an animated GIF plate", ["render", str(kit.sample), str(kit.lights), "--plate", str(gif),
                          "--size", "96", "-o", o], "ok", o, not_said="Traceback"))


def cache_roots(kit: Campaign, clip: Path, entry: Path) -> None:
    """``RELIGHT_CACHE`` the file system's root: one line (the bundles' cache goes beside it, and a root has none)."""
    _render_clip(kit, "the cache's place (issue 62)", "RELIGHT_CACHE=/", clip, cache="/")


def _frames_of(path: Path) -> list[np.ndarray]:
    import av

    with av.open(str(path)) as c:
        return [f.to_ndarray(format="rgb24") for f in c.decode(video=0)]


def _two_renders(kit: Campaign, clip: Path, entry: Path, what: str, k: int, work: Path):
    """Two renders of one turntable (or one clip, its bundle cached) under two maps to one output at once: the
    output is wholly one run's (its frames those of that run alone), the other refused in one line naming the
    process that holds it (or both done, one after the other)."""
    folder = work / "scenarios" / f"two_renders_{what}_{k}"
    folder.mkdir(parents=True)
    maps = [kit.env, kit.assets / "envmaps" / "immenstadter_horn_256.hdr"]
    env = {**os.environ, "RELIGHT_CACHE": str(folder / "cache" / "lights")}
    if what == "clip":
        (folder / "cache" / "bundles").mkdir(parents=True)
        shutil.copytree(entry, folder / "cache" / "bundles" / entry.name)

    def args(i: int, out: Path) -> list:
        return (["render", clip, "--env", maps[i], "-o", out] if what == "clip" else
                ["render", kit.sample, "--env", maps[i], "--size", "96", "--frames", "24", "-o", out])

    alone, peak = [], 0
    for i in (0, 1):
        code, _, err, _, p = run_command(args(i, folder / f"alone_{i}.mp4"), env=env)
        if code != 0:
            return [f"render {i} alone failed: {err[-200:]}"], p, code
        alone.append(_frames_of(folder / f"alone_{i}.mp4"))
        peak = max(peak, p)
    out = folder / "out.mp4"
    procs = []
    for i in (0, 1):
        procs.append(start_command(args(i, out), folder / f".peak_{i}", env=env))
        time.sleep(float(kit.rng.uniform(0.0, 0.5)))
    results = [(p.wait(timeout=300), p.stderr.read().decode("utf-8", "replace")) for p in procs]
    for p in procs:
        p.stdout.close()
        p.stderr.close()
    problems = [f"exit {code}: {err[-200:]!r}" for code, err in results if code not in (0, 2) or "Traceback" in err]
    refused = [err for code, err in results if code == 2]
    if any("is being written by another relight (process" not in err for err in refused):
        problems.append(f"refused without naming the other: {refused[0][-200:]!r}")
    if not any(code == 0 for code, _ in results):
        problems.append("neither render finished")
    elif out.exists():
        frames = _frames_of(out)
        mine = [i for i in (0, 1) if len(frames) == len(alone[i]) and all(np.array_equal(a, b) for a, b in zip(frames, alone[i]))]
        if not mine:
            problems.append("the output's frames are not wholly one run's")
    else:
        problems.append("a render said it wrote the output, which is not there")
    leftovers = sorted(p.name for p in folder.iterdir() if p.name not in ("alone_0.mp4", "alone_1.mp4", "out.mp4", "cache")
                       and not p.name.startswith(".peak_"))
    if leftovers:
        problems.append(f"files left: {leftovers}")
    return problems, peak, max(code for code, _ in results)


def _killed_then_again(kit: Campaign, fraction: float, work: Path):
    """A turntable render killed outright (SIGKILL: no handler runs) at ``fraction`` of its time, then the same
    command again: it takes up what the killed run left (its partial video and its lock) and finishes."""
    folder = work / "scenarios" / f"killed_{fraction:.3f}"
    folder.mkdir(parents=True)
    out = folder / "v.mp4"
    args = ["render", kit.sample, str(kit.lights), "--size", "96", "--frames", "24", "-o", out]
    code, _, err, seconds, peak = run_command(args)
    if code != 0:
        return [f"the first render failed: {err[-200:]}"], peak, code
    proc = start_command([*args[:-2], "--yaw", "90", "-o", out], folder / ".peak")
    time.sleep(seconds * fraction)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.communicate()
    code, _, err, _, peak2 = run_command([*args[:-2], "--yaw", "90", "-o", out])
    problems = [] if code == 0 and "Traceback" not in err else [f"the rerun: exit {code}: {err[-200:]!r}"]
    leftovers = sorted(p.name for p in folder.iterdir() if p.name not in ("v.mp4", ".peak"))
    if leftovers:
        problems.append(f"files left: {leftovers}")
    return problems, max(peak, peak2), code
