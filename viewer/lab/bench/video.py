"""``relight bench video``: a filmed person relit, measured (docs/video.md).

For every clip of the folders given, a part of it (``--end`` seconds, default 2) is inferred into a
clip bundle and relit under each map, as ``relight render CLIP`` does, in a child process of its own
(its peak memory is the clip's alone). Reported per clip:

- the **warping error** (Lai et al. 2018, "Learning Blind Video Temporal Consistency"): optical
  flow (OpenCV's DIS, medium preset, :mod:`viewer.photo.flow`) computed on the *input* frames,
  resized to the output's size, from frame t to t-1; pixels failing a forward-backward check (the
  two flows disagree by more than 1 pixel plus 5 % of their length) are left out; the mean over t of
  the mean over kept pixels of the squared RGB distance (summed over channels, values in [0, 1])
  between output frame t and output frame t-1 warped by that flow; and the **Warp-SSIM** (the mean
  SSIM, 7-pixel windows, over the same pixels, of frame t against frame t-1 so carried: 1 when nothing
  changes but the motion), as video relighting papers report both. Reported for the input clip
  itself, and for each relit clip, inferred both ways (``--temporal off``: every frame relit as a
  photo is; on: the photo's lighting and the exposure estimated once per shot);
- throughput end to end (decode to relit MP4), frames a minute, with the stages' shares (each
  frame's inference stages from its bundle's record; the render);
- **feet over the map's sky** (:func:`feet_over_the_sky`): frames whose person's feet stand where the
  relit frame shows the map's sky, not its ground (a person floating), and the camera height read;
- **pieces of matte that come and go** between consecutive frames, not explained by the motion
  (:class:`MattePieces`): a piece of the old background kept in one frame and not the next, or of the
  person lost in one, both ways;
- the child's peak resident memory.
The shared clips are evaluation only: their figures go in the docs, their frames never.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from viewer.files.imageio import atomic_path, write_text
from viewer.photo.flow import backward_flow, dis_flow, grey, warp

DEFAULT_SECONDS = 2.0
RETRIES = 2  # a child that dies (a native crash) is run again: its clip bundles go on from their last frame


REGIONS = ("all", "person", "background")


class WarpingError:
    """The warping error of several outputs of one input clip, fed frame by frame (:meth:`add`):
    the flow is computed once per frame on the input, each output is judged by it. Besides the
    whole frame, over the person (the matte above 0.5 in both frames, carried by the flow) and over
    the background (below 0.05 in both)."""

    def __init__(self, names):
        self.flow = dis_flow()
        self.names = list(names)
        self.sums = {n: {r: [] for r in REGIONS} for n in self.names}
        self.ssims = {n: {r: [] for r in REGIONS} for n in self.names}
        self._previous = None

    def add(self, source: np.ndarray, outputs: dict, alpha: np.ndarray | None = None) -> tuple | None:
        """``source``: the input frame at the outputs' size (uint8 RGB); ``outputs``: name -> uint8 RGB;
        ``alpha``: the person's matte at that size (None: the whole frame only). Returns the input's
        backward flow to the frame before and where it holds (None for the first frame), which
        :class:`MattePieces` judges by too."""
        from skimage.metrics import structural_similarity

        current = grey(source)
        frames = {n: outputs[n].astype(np.float32) / 255.0 for n in self.names}
        flow = None
        if self._previous is not None:
            previous_grey, previous, previous_alpha = self._previous
            back, held = flow = backward_flow(self.flow, current, previous_grey)
            regions = {"all": held}
            if alpha is not None and previous_alpha is not None:
                carried = warp(previous_alpha, back)
                regions.update(person=held & (alpha > 0.5) & (carried > 0.5), background=held & (alpha < 0.05) & (carried < 0.05))
            for n in self.names:
                carried_frame = warp(previous[n], back)
                diff = ((frames[n] - carried_frame) ** 2).sum(axis=2)
                _, similar = structural_similarity(frames[n], carried_frame, data_range=1.0, channel_axis=-1, win_size=7, full=True)
                similar = similar.mean(axis=2)
                for r, where in regions.items():
                    if where.any():
                        self.sums[n][r].append(float(diff[where].mean()))
                        self.ssims[n][r].append(float(similar[where].mean()))
        self._previous = (current, frames, alpha)
        return flow

    def result(self, region: str = "all", ssim: bool = False) -> dict:
        """name -> the warping error over ``region`` (``ssim``: the Warp-SSIM, the mean SSIM of each
        frame against the frame before carried by the flow, 1 for a still picture)."""
        return {n: float(np.mean(v[region])) if v[region] else float("nan") for n, v in (self.ssims if ssim else self.sums).items()}


def _video_frames(path):
    import av

    from viewer.files.imageio import ffmpeg_file

    with av.open(ffmpeg_file(path)) as c:
        for frame in c.decode(video=0):
            yield frame.to_ndarray(format="rgb24")


def clip_warping_errors(clip, start: float, end: float, relit: dict, alpha=None, mattes: dict | None = None) -> dict:
    """Warping errors (region -> name -> error) of the input clip (``start`` to ``end`` seconds)
    and of each relit MP4 (name -> path), the input resized to the relit size; frames lost in the
    input are left out of the pairs they are in. ``alpha(index)``: frame index's matte (or None).
    ``mattes``: name -> its ``alpha`` of another bundle, whose :class:`MattePieces` are counted along
    the same flow (under "pieces")."""
    from viewer.files.clip_reader import clip_frames
    from viewer.resize import resize

    names = ["input", *relit]
    meter = WarpingError(names)
    pieces = {n: MattePieces() for n in mattes or {}}
    readers = {n: _video_frames(p) for n, p in relit.items()}
    for frame in clip_frames(clip, start, end):
        outs = {n: next(r) for n, r in readers.items()}
        if frame.rgb is None:
            meter._previous = None
            for counter in pieces.values():
                counter.add(frame.index, None, None)
            continue
        h, w = next(iter(outs.values())).shape[:2]
        source = resize(frame.rgb, (w, h))
        matte = alpha(frame.index) if alpha is not None else None
        flow = meter.add(source, {"input": source, **outs}, resize(matte, (w, h)) if matte is not None else None)
        for n, counter in pieces.items():
            own = mattes[n](frame.index)
            counter.add(frame.index, flow, resize(own, (w, h)) if own is not None else None)
    return {r: meter.result(r) for r in REGIONS} | {f"ssim {r}": meter.result(r, ssim=True) for r in REGIONS} | \
        {"pieces": {n: counter.result() for n, counter in pieces.items()}}


PIECE = 0.0002  # of the frame's area: a piece of matte this large that comes or goes between two frames counts
SLIVER = 5  # pixels: what a square this wide does not hold (an outline that moved a pixel or two) is no piece


class MattePieces:
    """Pieces of matte that come or go between consecutive frames, not explained by the input's
    motion, fed frame by frame (:meth:`add`, with the flow :meth:`WarpingError.add` found): where
    the flow holds, the frame's matte (above 0.5) against the frame before's carried along it, the
    difference opened by a square of ``SLIVER`` pixels (an outline that moved a pixel or two is no
    piece), its connected pieces of at least ``PIECE`` of the frame. A piece of the old background kept in one frame and not the next (or of
    the person lost in one) is such a piece: counted where it comes and again where it goes."""

    def __init__(self):
        self._before = None  # the frame before's matte
        self.pieces, self.pairs, self.frames = 0, 0, []

    def add(self, index: int, flow: tuple | None, alpha: np.ndarray | None) -> None:
        """Frame ``index``: the input's backward flow to the frame before and where it holds (None: no
        frame before), and the matte ``alpha`` at the flow's size; None for a frame with no one (or
        lost): the next pair starts afresh."""
        import cv2

        if alpha is None:
            self._before = None
            return
        if self._before is not None and flow is not None:
            back, held = flow
            carried = warp(self._before.astype(np.float32), back)
            changed = (held & ((alpha > 0.5) != (carried > 0.5))).astype(np.uint8)
            changed = cv2.morphologyEx(changed, cv2.MORPH_OPEN, np.ones((SLIVER, SLIVER), np.uint8))
            count, _, stats, _ = cv2.connectedComponentsWithStats(changed, connectivity=8)
            found = int((stats[1:, cv2.CC_STAT_AREA] >= PIECE * alpha.size).sum()) if count > 1 else 0
            self.pieces, self.pairs = self.pieces + found, self.pairs + 1
            if found:
                self.frames.append(index)
        self._before = alpha

    def result(self) -> dict:
        return {"pieces": self.pieces, "pairs": self.pairs, "frames_with_pieces": self.frames}


def _one_clip(clip: str, out_dir: str, maps: list, start: float, end: float, max_size: int, queue) -> None:
    """The child process: infer and relight one clip, report its figures on ``queue``."""
    import resource

    try:
        queue.put(_measure_clip(Path(clip), Path(out_dir), [Path(m) for m in maps], start, end, max_size)
                  | {"peak_rss_gb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2 ** 20, 3)})
    except BaseException as exc:  # noqa: BLE001 -- reported to the parent, which names the clip
        queue.put({"error": f"{type(exc).__name__}: {exc}"})


def map_and_lights(path: Path):
    """(the map at ``path``, its 16 lights as the product fits them: beside the map, cached, or fitted now)."""
    from viewer.cli.command_setup import fitted_lights
    from viewer.lighting.envmap import load_envmap
    from viewer.lighting.lightfit.methods import DEFAULT_METHOD
    from viewer.lighting.map_lights import map_lights

    env = load_envmap(path)
    return env, map_lights(env, path, 16, DEFAULT_METHOD, lambda e: fitted_lights(e, 16, DEFAULT_METHOD))[0]


def infer_mode(clip: Path, out_dir: Path, name: str, mode: str, ctx, **request) -> tuple[Path, dict, float]:
    """``clip`` inferred with ``--temporal mode`` into ``out_dir/bundles/<name>-<mode>`` (``request``: the
    rest of its :class:`viewer.photo.clip_cache.ClipRequest`): (the bundle's folder, its record, seconds)."""
    from viewer.photo.clip_cache import ClipRequest
    from viewer.photo.clip_inference import infer_clip

    bundle_dir = out_dir / "bundles" / f"{name}-{mode}"
    t0 = time.perf_counter()
    record = infer_clip(clip, bundle_dir, ClipRequest(temporal=mode, **request), ctx=ctx)
    return bundle_dir, record, time.perf_counter() - t0


def feet_over_the_sky(bundle) -> dict:
    """Whether the person stands on the new ground: of the frames with the person whose feet are in the
    picture (:func:`viewer.scene.ground.contacts` on the frame's matte), those where the map behind their
    lowest foot, as the relit frame shows it (the shot's lens, horizon and camera turn,
    :class:`viewer.output.clip_frames.ClipFrames`; the look's own tilt 0), is sky: a person floating."""
    from viewer.files.imageio import read_png
    from viewer.output.clip_frames import ClipFrames, below_horizon
    from viewer.scene.ground import contacts

    frames = ClipFrames(bundle)
    feet, over = 0, []
    for entry in bundle.frames:
        if entry.state != "person":
            continue
        matte = read_png(bundle.scene_path(entry.index) / "frame_alpha.png")
        found = contacts((matte[..., 0] if matte.ndim == 3 else matte) > 0.5)
        if not found:
            continue
        feet += 1
        x, y = max(found, key=lambda c: c[1])
        size = matte.shape[1::-1]
        tilt = frames.camera_turn(entry.index, entry.index)[1]  # (the yaw turns no ray up or down)
        if below_horizon(x + 0.5, y + 1.0, size, tilt, frames.background_camera(entry.index).focal_at(size)) <= 0.0:
            over.append(entry.index)
    return {"frames_with_feet": feet, "over_the_sky": len(over), "frames_over_the_sky": over[:50],
            "camera_height_m": round(frames.camera_height(frames.people[0]), 2) if frames.people else 0.0}


def _measure_clip(clip: Path, out_dir: Path, maps: list[Path], start: float, end: float, max_size: int) -> dict:
    """One clip inferred both ways (``--temporal off`` and on) and relit under every map."""
    from viewer.files.imageio import read_png
    from viewer.gl import EngineOptions, create_headless_context
    from viewer.output.clip_render import ClipPictures, render_clip
    from viewer.photo.frames import WORK_PERSON, output_frame
    from viewer.scene.area_lights import facing_yaw
    from viewer.scene.clip_bundle import load_clip_bundle
    from viewer.scene.look import AUTO, Look

    lit = [(m.stem, *map_and_lights(m)) for m in maps]
    figures: dict = {"clip": clip.name, "modes": {}}
    relit = {}
    ctx = create_headless_context()
    try:
        for mode in ("off", "on"):
            bundle_dir, record, infer_seconds = infer_mode(clip, out_dir, clip.stem, mode, ctx, start=start, end=end,
                                                           size=WORK_PERSON, max_size=max_size)
            bundle = load_clip_bundle(bundle_dir)
            stages: dict[str, float] = {}
            for entry in bundle.frames:
                if entry.state == "person":
                    for k, v in json.loads((bundle.scene_path(entry.index) / "inference.json").read_text())["seconds"].items():
                        stages[k] = stages.get(k, 0.0) + v
            render_seconds = {}
            for name, env, lights in lit:
                out = out_dir / f"{clip.stem}_{name}_{mode}.mp4"
                out.unlink(missing_ok=True)
                t1 = time.perf_counter()
                look = Look(yaw=facing_yaw(lights), exposure=AUTO)
                render_clip(ClipPictures(ctx, bundle, lights, look, env.pixels, None, EngineOptions()), out)
                render_seconds[name] = round(time.perf_counter() - t1, 2)
                relit[f"{mode} {name}"] = out
            n, kept = record["frames"], record["frames_kept_from_earlier_run"]
            figures["modes"][mode] = {
                "infer_seconds": round(infer_seconds, 2), "frames_kept": kept, "render_seconds": render_seconds,
                "shots": record.get("shots"), "states": record["states"],
                "stage_seconds_per_frame": {k: round(v / max(record["states"]["person"], 1), 3) for k, v in stages.items()},
                "frames_per_minute": round(60 * n / (infer_seconds + render_seconds[lit[0][0]]), 2) if not kept else None}
            figures.update(frames=n, fps=bundle.source["fps"],
                           size=list(output_frame((bundle.source["width"], bundle.source["height"]), max_size)))
    finally:
        ctx.release()
    bundles = {mode: load_clip_bundle(out_dir / "bundles" / f"{clip.stem}-{mode}") for mode in ("off", "on")}

    def matte_of(bundle):
        def alpha(index):  # frame index's matte in ``bundle`` (None: no one there)
            entry = bundle.frames[index] if index < len(bundle.frames) else None
            if entry is None or entry.state != "person":
                return None
            matte = read_png(bundle.scene_path(index) / "frame_alpha.png")
            return matte[..., 0] if matte.ndim == 3 else matte
        return alpha

    mattes = {mode: matte_of(b) for mode, b in bundles.items()}
    figures["feet"] = {mode: feet_over_the_sky(b) for mode, b in bundles.items()}
    # the regions: each frame's own matte (frame by frame); the pieces: each mode's
    errors = clip_warping_errors(clip, start, end, relit, mattes["off"], mattes)
    figures["matte_pieces"] = errors["pieces"]
    figures["warping_error"] = {k: round(v, 6) for k, v in errors["all"].items()}
    figures["warp_ssim"] = {r: {k: round(v, 4) for k, v in errors[f"ssim {r}"].items()} for r in REGIONS}
    figures["ratio_to_input"] = {k: round(v / max(errors["all"]["input"], 1e-12), 3) for k, v in errors["all"].items() if k != "input"}
    for region in ("person", "background"):
        e = errors[region]
        figures[f"warping_error_{region}"] = {k: round(v, 6) for k, v in e.items()}
        figures[f"ratio_to_input_{region}"] = {k: round(v / max(e["input"], 1e-12), 3) for k, v in e.items() if k != "input"}
    return figures


def run_video_benchmark(clips: list[Path], maps: list[Path], out_dir, start: float = 0.0, end: float = DEFAULT_SECONDS,
                        max_size: int = 2048, output=None) -> dict:
    """Every clip measured in a child process of its own (sequentially: the machine's cores are the
    clip's), figures to ``output`` (JSON) as each clip ends."""
    import multiprocessing

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    output = Path(output) if output is not None else out_dir / "video.json"
    result = {"clips": [], "maps": [m.stem for m in maps], "start": start, "end": end, "max_size": max_size,
              "modes": {"off": "frame by frame (--temporal off)", "on": "one photo lighting and exposure per shot"},
              "machine": _machine()}
    spawn = multiprocessing.get_context("spawn")
    for clip in clips:
        for attempt in range(1 + RETRIES):
            queue = spawn.Queue()
            child = spawn.Process(target=_one_clip, args=(str(clip), str(out_dir), [str(m) for m in maps], start, end, max_size,
                                                          queue))
            child.start()
            figures = _wait(child, queue)
            child.join()
            if "ended" not in figures:
                break
            print(f"{clip.name}: {figures['error']}; {'again, going on from its last frame' if attempt < RETRIES else 'giving up'}",
                  flush=True)
        figures.setdefault("clip", clip.name)
        figures["attempts"] = attempt + 1
        if clip.stem == SYNTHETIC and "error" not in figures:
            figures["strip"] = str(frame_strip(clip, out_dir, maps[0].stem))
        result["clips"].append(figures)
        print(_line(figures), flush=True)
        write_text(output, json.dumps(result, indent=1) + "\n")
    return result


SYNTHETIC = "synthetic_panning"  # the clip made from the bundled photo (what the docs may show frames of)


def synthetic_clip(out_dir) -> Path:
    """The bundled photo's person through a window panning 2 px a frame, 4 s at 10 frames a second,
    320x480 (:func:`viewer.lab.bench.clip_memory.panning_clip`)."""
    from viewer.lab.bench.clip_memory import panning_clip

    path = Path(out_dir) / f"{SYNTHETIC}.mp4"
    return path if path.is_file() else panning_clip(path, 4.0, fps=10.0)


def frame_strip(clip: Path, out_dir, map_name: str, count: int = 6) -> Path:
    """A JPEG of ``count`` frames across the clip: the input, then the relit clip frame by frame
    (off) and as a clip (on) under ``map_name``, a row each, labelled."""
    from PIL import Image, ImageDraw

    from viewer.resize import resize

    out_dir = Path(out_dir)
    rows = [("input", list(_video_frames(clip)))] + [
        (f"{mode} ({map_name})", list(_video_frames(out_dir / f"{clip.stem}_{map_name}_{mode}.mp4"))) for mode in ("off", "on")]
    n = min(len(frames) for _, frames in rows)
    picks = [round(k * (n - 1) / max(count - 1, 1)) for k in range(count)]
    h, w = rows[1][1][0].shape[:2]
    sheet = Image.new("RGB", (w * count, (h + 16) * len(rows)), (24, 24, 24))
    draw = ImageDraw.Draw(sheet)
    for r, (label, frames) in enumerate(rows):
        draw.text((4, r * (h + 16) + 2), label, fill=(230, 230, 230))
        for c, i in enumerate(picks):
            sheet.paste(Image.fromarray(resize(frames[i], (w, h))), (c * w, r * (h + 16) + 16))
    path = out_dir / f"{clip.stem}_strip.jpg"
    with atomic_path(path) as tmp:
        sheet.save(tmp, format="JPEG", quality=88)
    return path


def _wait(child, queue) -> dict:
    """The child's figures, or what ended it when it died without any (a native crash)."""
    import queue as queues

    while True:
        try:
            return queue.get(timeout=5)
        except queues.Empty:
            if not child.is_alive():
                return {"error": f"the child process ended with code {child.exitcode} before reporting", "ended": child.exitcode}


def _machine() -> dict:
    import os
    import platform

    return {"cpus": os.cpu_count(), "load": [round(x, 2) for x in os.getloadavg()], "python": platform.python_version()}


def _line(f: dict) -> str:
    if "error" in f:
        return f"{f['clip']}: failed: {f['error']}"
    ratios = ", ".join(f"{k} {v:.2f}x (person {f['ratio_to_input_person'].get(k, float('nan')):.2f}x)"
                       for k, v in f["ratio_to_input"].items())
    rates = ", ".join(f"{mode} {m['frames_per_minute']:.1f}" for mode, m in f["modes"].items() if m["frames_per_minute"])
    pieces = ", ".join(f"{mode} {p['pieces']} in {len(p['frames_with_pieces'])} of {p['pairs']} frame pairs"
                       for mode, p in f.get("matte_pieces", {}).items())
    similar = ", ".join(f"{k} {v:.3f}" for k, v in f.get("warp_ssim", {}).get("all", {}).items())
    feet = ", ".join(f"{mode} {v['over_the_sky']} of {v['frames_with_feet']}" for mode, v in f.get("feet", {}).items())
    return (f"{f['clip']}: {f['frames']} frames {f['size'][0]}x{f['size'][1]}; "
            f"warping error input {f['warping_error']['input']:.5f}, relit {ratios} of it; Warp-SSIM {similar}; "
            f"matte pieces coming and going: {pieces}; feet over the map's sky: {feet}; "
            f"frames a minute {rates or '(bundles reused)'}; peak {f['peak_rss_gb']:.2f} GB")


def video_table(result: dict) -> str:
    """The docs' table of a run: per clip, the warping errors as ratios to the input's (whole frame,
    person, background), under each map, frame by frame (off) and as a clip (on); frames a minute."""
    maps = result["maps"]
    head = ["clip", "frames, size", "input's warping error (all / person / background)"]
    for m in maps:
        head += [f"{m}: off / on, all", "person", "background"]
    head += ["frames a minute, off / on", "peak memory"]
    rows = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for f in result["clips"]:
        if "error" in f:
            rows.append(f"| {f['clip']} | failed: {f['error']} |")
            continue
        w = f["warping_error"]
        cells = [f["clip"], f"{f['frames']}, {f['size'][0]}x{f['size'][1]}",
                 f"{w['input']:.6f} / {f['warping_error_person']['input']:.6f} / {f['warping_error_background']['input']:.6f}"]
        for m in maps:
            for key in ("ratio_to_input", "ratio_to_input_person", "ratio_to_input_background"):
                r = f[key]
                cells.append(f"{r.get(f'off {m}', float('nan')):.2f}x / **{r.get(f'on {m}', float('nan')):.2f}x**")
        rates = [f["modes"][mode]["frames_per_minute"] for mode in ("off", "on")]
        cells.append(" / ".join(f"{r:.1f}" if r else "-" for r in rates))
        cells.append(f"{f['peak_rss_gb']:.2f} GB")
        rows.append("| " + " | ".join(cells) + " |")
    return "\n".join(rows)
