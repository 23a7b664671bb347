"""``relight bench video --truth DIR``: relit clips against the ray tracer's truth.

For every clip of a dataset made by ``relight dataset make --split clip`` (a person turning, filmed
under one map; the truth: the same frames under a second map), the input MP4 is inferred both ways,
as a clip (``--temporal on``) and frame by frame (``off``: each frame exactly as a photo is, the
still-photo path), and every frame relit under the truth's map at the truth's yaw, as ``relight
render CLIP`` does. Reported per clip and mode:

- the **relit RMSE per frame** over the person's pixels (the truth's coverage above 0.5), linear RGB
  premultiplied by the coverage (the product's person layer and the ray tracer's RGBA alike), after
  one scale per clip and mode (least squares over all its frames: a photo fixes no absolute
  brightness; one scale, not one per frame, so a brightness that wavers from frame to frame counts),
  divided by the truth's RMS over the same pixels (relative: 0.1 is 10 % of the signal); the mean over
  the frames and the worst frame;
- the **warping error** of the relit clips and of the input (:mod:`viewer.lab.bench.video`).

The target: the clip's mean relative RMSE within 10 % of the still path's (on <= 1.1 x off).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from viewer.files.imageio import linear_to_srgb, read_exr


def _relit_frames(ctx, bundle_dir: Path, clip: dict, env, lights, video: Path) -> list[np.ndarray | None]:
    """Each frame's person relit under the truth's map (H, W, 4: premultiplied RGB and coverage; None
    where no person was found), and the relit clip as a camera would show it in ``video``."""
    from viewer.files.ownership import file_is_ours
    from viewer.gl import EngineOptions
    from viewer.output.clip_render import ClipPictures
    from viewer.output.video import VideoWriter
    from viewer.scene.clip_bundle import load_clip_bundle
    from viewer.scene.look import AUTO, Look

    bundle = load_clip_bundle(bundle_dir)
    pictures = ClipPictures(ctx, bundle, lights, Look(yaw=clip["truth"]["yaw"], exposure=AUTO), env.pixels, None, EngineOptions())
    frames = []
    if file_is_ours(video):  # an earlier run's (a file the program did not write is refused by the writer)
        video.unlink()
    try:
        with VideoWriter(video, *pictures.size, fps=clip["fps"]) as writer:
            for i in range(len(bundle.frames)):
                writer.write(pictures.picture(i), seconds=bundle.frames[i].seconds)
                frames.append(pictures.person_hdr(i))
    finally:
        pictures.release()
    return frames


def relit_video(path: Path, out_dir: Path, mode: str) -> Path:
    """Where the dataset clip in ``path`` relit in ``mode`` (on, off) goes in ``out_dir``."""
    return Path(out_dir) / f"truth-{path.name}_{mode}.mp4"


def relit_rmse(relit: list[np.ndarray | None], truth: list[np.ndarray]) -> dict:
    """Per-frame relative RMSE over the truth's person (see the module doc), one scale for the clip."""
    masks = [t[..., 3] > 0.5 for t in truth]
    pairs = [((r[..., :3] if r is not None else np.zeros_like(t[..., :3]))[m].astype(np.float64), t[..., :3][m].astype(np.float64))
             for r, t, m in zip(relit, truth, masks, strict=True)]
    num = sum(float((p * t).sum()) for p, t in pairs)
    den = sum(float((p * p).sum()) for p, _ in pairs)
    scale = num / den if den > 0 else 0.0
    per = [float(np.sqrt(np.mean((scale * p - t) ** 2)) / max(np.sqrt(np.mean(t ** 2)), 1e-12)) if len(t) else float("nan")
           for p, t in pairs]
    return {"mean": float(np.nanmean(per)), "worst": float(np.nanmax(per)), "per_frame": [round(v, 5) for v in per],
            "scale": scale}


def measure_truth_clip(path: Path, out_dir: Path, maps_dir: Path) -> dict:
    """One dataset clip inferred both ways and relit under its truth's map (the module doc's figures)."""
    from viewer.gl import create_headless_context
    from viewer.lab.bench.video import clip_warping_errors, infer_mode, map_and_lights
    from viewer.lab.data.clips import frame_file, read_clip

    clip = read_clip(path)
    truth = [read_exr(frame_file(path, "truth", k)) for k in range(clip["frames"])]
    env, lights = map_and_lights(maps_dir / f"{clip['truth']['map']}.hdr")
    name = f"truth-{path.name}"
    figures: dict = {"clip": name, "input_map": clip["input"]["map"], "truth_map": clip["truth"]["map"], "frames": clip["frames"],
                     "res": clip["res"], "modes": {}}
    videos = {}
    ctx = create_headless_context()
    try:
        for mode in ("off", "on"):
            bundle_dir, record, seconds = infer_mode(path / "input.mp4", out_dir, name, mode, ctx)
            videos[mode] = relit_video(path, out_dir, mode)
            relit = _relit_frames(ctx, bundle_dir, clip, env, lights, videos[mode])
            figures["modes"][mode] = {"rmse": relit_rmse(relit, truth), "infer_seconds": round(seconds, 1),
                                      "states": record["states"]}
    finally:
        ctx.release()
    errors = clip_warping_errors(path / "input.mp4", 0.0, None, videos)["all"]
    figures["warping_error"] = {k: round(v, 6) for k, v in errors.items()}
    on, off = figures["modes"]["on"]["rmse"]["mean"], figures["modes"]["off"]["rmse"]["mean"]
    figures["rmse_on_over_off"] = round(on / max(off, 1e-12), 3)
    return figures


def truth_strip(path: Path, out_dir: Path, count: int = 4) -> Path:
    """A picture of a dataset clip and its relit frames: input, truth, on, off in rows (frames in columns)."""
    from viewer.files.imageio import write_jpeg
    from viewer.lab.bench.video import _video_frames
    from viewer.lab.data.clips import frame_file, read_clip
    from viewer.resize import resize

    clip = read_clip(path)
    picks = np.linspace(0, clip["frames"] - 1, count).round().astype(int)
    rows = []
    inputs = list(_video_frames(path / "input.mp4"))
    rows.append([inputs[k] for k in picks])
    truth = [read_exr(frame_file(path, "truth", k)) for k in picks]  # at the input's exposure, no background
    rows.append([(np.clip(linear_to_srgb(t[..., :3]), 0, 1) * 255 + 0.5).astype(np.uint8) for t in truth])
    for mode in ("on", "off"):
        frames = list(_video_frames(relit_video(path, out_dir, mode)))
        rows.append([frames[k] for k in picks])
    h, w = rows[0][0].shape[:2]
    picture = np.concatenate([np.concatenate([resize(f, (w, h)) for f in row], axis=1) for row in rows], axis=0)
    out = out_dir / f"truth-{path.name}_strip.jpg"
    write_jpeg(out, picture / 255.0)
    return out


def run_truth_benchmark(data_dir, out_dir, output=None, progress=print) -> dict:
    """Every finished clip of the dataset ``data_dir`` measured (its maps from the dataset's own
    ``maps/``), figures to ``output`` (JSON) as each clip ends, a strip of each clip's frames beside it."""
    from viewer.errors import InputError
    from viewer.files.imageio import write_text
    from viewer.lab.bench.video import _machine

    clips = sorted(p for p in (Path(data_dir) / "clips").glob("*") if (p / "clip.json").is_file())
    if not clips:
        raise InputError(data_dir, "no finished clips: make them with relight dataset make --split clip")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    output = Path(output) if output is not None else out_dir / "truth.json"
    result = {"data": str(data_dir), "clips": [], "machine": _machine()}
    for path in clips:
        figures = measure_truth_clip(path, out_dir, Path(data_dir) / "maps")
        figures["strip"] = str(truth_strip(path, out_dir))
        result["clips"].append(figures)
        on, off = (figures["modes"][m]["rmse"]["mean"] for m in ("on", "off"))
        progress(f"{figures['clip']}: relit RMSE (relative) on {on:.4f}, off {off:.4f} ({figures['rmse_on_over_off']:.3f}x)")
        modes = [c["modes"] for c in result["clips"]]
        result["summary"] = {m: float(np.mean([x[m]["rmse"]["mean"] for x in modes])) for m in ("on", "off")}
        result["summary"]["on_over_off"] = result["summary"]["on"] / max(result["summary"]["off"], 1e-12)
        write_text(output, json.dumps(result, indent=1) + "\n")
    return result


def truth_table(result: dict) -> str:
    """The docs' table: per clip, the relit RMSE (relative, mean and worst frame) as a clip and frame by
    frame, their ratio, and the warping errors."""
    rows = ["| clip (input map -> truth map) | frames | RMSE on: mean / worst | off: mean / worst | on / off | "
            "warping error input / on / off |", "|---|---|---|---|---|---|"]
    for f in result["clips"]:
        on, off, w = f["modes"]["on"]["rmse"], f["modes"]["off"]["rmse"], f["warping_error"]
        rows.append(f"| {f['clip']} ({f['input_map']} -> {f['truth_map']}) | {f['frames']}, {f['res']}px | "
                    f"**{on['mean']:.4f}** / {on['worst']:.4f} | {off['mean']:.4f} / {off['worst']:.4f} | "
                    f"**{f['rmse_on_over_off']:.3f}x** | {w['input']:.5f} / {w['on']:.5f} / {w['off']:.5f} |")
    s = result.get("summary")
    if s:
        rows.append(f"| mean | | **{s['on']:.4f}** | {s['off']:.4f} | **{s['on_over_off']:.3f}x** | |")
    return "\n".join(rows)
