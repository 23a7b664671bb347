"""``relight bench spread``: a clip relit end to end three ways, compared (docs/video.md):
inferred, then relit (``relight infer CLIP -o B``, then ``relight render B``: one stage after the
other), by ``relight render CLIP`` (the
relighting following the inference, :mod:`viewer.photo.clip_follow`), and spread over Ray workers
(``relight render CLIP --ray local``).

For every clip, a part of it (``--end`` seconds) is relit end to end each way, each in fresh processes
from an empty cache (start-up, the lights' fit, the inference and the render all counted; a Ray
instance started for its run, its workers one a core). The ways alternate, ``repeats`` times;
reported per clip:

- the wall time of each run and the median of each way, frames a minute end to end, their ratio
  (in one run of the bench, under the same load: the load average is recorded before and after);
- the **warping error** of both relit clips frame pair by frame pair (as ``relight bench video``:
  the input's flow, pixels failing its forward-backward check left out): the mean over the pairs
  that straddle a join (the first frame of each of the inference's ranges after the first, and of
  each relit part after the first) against the mean over the other pairs; a join shows no seam
  when it is within 10 % of elsewhere;
- how far the spread clip is from the one process's, frame by frame (mean absolute difference, of
  255): the ranges begin a few frames early, so their steadied maps differ from one run's slightly;
  and the one stage after the other's (the same bytes, :mod:`viewer.photo.clip_follow`).
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from viewer.files.imageio import write_text

DEFAULT_SECONDS = 4.0
THEN, ONE, RAY = RUNS = ("inferred, then relit", "one process", "--ray local")
NAMES = {THEN: "then", ONE: "one", RAY: "ray"}  # in the output files' names


def _render(clip: Path, env_map: Path, out: Path, end: float, max_size: int, way: str, work: Path) -> dict:
    """One end-to-end run ``way`` in fresh processes, an empty cache: (wall seconds, the output lines,
    the clip bundle)."""
    import shutil

    cache = work / "cache"
    if cache.exists():
        shutil.rmtree(cache)
    out.unlink(missing_ok=True)
    relight = [sys.executable, "-m", "viewer.cli.main"]
    render = ["render", str(clip), "--env", str(env_map), "--end", str(end), "--max-size", str(max_size), "-o", str(out)]
    commands = [relight + render + (["--ray", "local"] if way == RAY else [])]
    if way == THEN:
        bundle = cache / "bundles" / f"{clip.stem}-clip-then"
        commands = [relight + ["infer", str(clip), "--end", str(end), "--max-size", str(max_size), "-o", str(bundle)],
                    relight + ["render", str(bundle), "--env", str(env_map), "--max-size", str(max_size), "-o", str(out)]]
    env = {**os.environ, "RELIGHT_CACHE": str(cache / "lights"), "RAY_USAGE_STATS_ENABLED": "0"}
    t0 = time.perf_counter()
    lines = []
    for command in commands:
        done = subprocess.run(command, capture_output=True, text=True, env=env)
        if done.returncode != 0:
            raise RuntimeError(f"{' '.join(command)} failed: {done.stderr.strip().splitlines()[-1:]}")
        lines += [line for line in done.stdout.splitlines() if line.strip()]
    seconds = time.perf_counter() - t0
    return {"seconds": round(seconds, 2), "lines": lines, "bundle": next(cache.glob("bundles/*-clip-*"))}


def _pair_errors(clip: Path, end: float, relit: dict[str, Path]) -> dict[str, list[float]]:
    """name -> the warping error of each frame pair (t-1, t), t from 1 (NaN where the flow holds nowhere)."""
    from viewer.files.clip_reader import clip_frames
    from viewer.lab.bench.video import WarpingError, _video_frames
    from viewer.resize import resize

    meter = WarpingError(list(relit))
    readers = {n: _video_frames(p) for n, p in relit.items()}
    errors: dict[str, list[float]] = {n: [] for n in relit}
    for frame in clip_frames(clip, 0.0, end):
        outs = {n: next(r) for n, r in readers.items()}
        if frame.index == 0:
            meter.add(resize(frame.rgb, outs[next(iter(outs))].shape[1::-1]), outs)
            continue
        before = {n: len(meter.sums[n]["all"]) for n in relit}
        meter.add(resize(frame.rgb, outs[next(iter(outs))].shape[1::-1]), outs)
        for n in relit:
            errors[n].append(meter.sums[n]["all"][-1] if len(meter.sums[n]["all"]) > before[n] else float("nan"))
    return errors


def _joins(bundle: Path) -> dict[str, list[int]]:
    """The frames the spread clip's pieces begin at (after the first): its ranges' and its parts'."""
    from viewer.output.clip_render import clip_parts
    from viewer.scene.clip_bundle import load_clip_bundle

    clip = load_clip_bundle(bundle)
    return {"ranges": [r[0] for r in clip.record.get("ranges", [])[1:]], "parts": [p.first for p in clip_parts(clip)[1:]]}


def _seams(errors: list[float], joins: list[int]) -> dict:
    """The mean warping error over the pairs ending at ``joins`` against the mean over the others."""
    at = [errors[j - 1] for j in joins if 0 < j <= len(errors) and np.isfinite(errors[j - 1])]
    rest = [e for t, e in enumerate(errors, start=1) if t not in joins and np.isfinite(e)]
    if not at or not rest:
        return {"joins": len(at)}
    return {"joins": len(at), "at_joins": round(float(np.mean(at)), 6), "elsewhere": round(float(np.mean(rest)), 6),
            "ratio": round(float(np.mean(at)) / max(float(np.mean(rest)), 1e-12), 3)}


def _difference(a: Path, b: Path) -> dict:
    """Mean absolute difference (of 255) between two clips' frames: the mean and the largest frame's."""
    from viewer.lab.bench.video import _video_frames

    diffs = [float(np.abs(x.astype(np.int16) - y.astype(np.int16)).mean()) for x, y in zip(_video_frames(a), _video_frames(b))]
    return {"mean": round(float(np.mean(diffs)), 3), "largest_frame": round(float(np.max(diffs)), 3), "frames": len(diffs)}


def run_spread_benchmark(clips: list[Path], env_map: Path, out_dir, end: float = DEFAULT_SECONDS, max_size: int = 1280,
                         repeats: int = 1, ways: tuple = RUNS, progress=print) -> dict:
    """Every clip relit each of ``ways`` (of :data:`RUNS`, "one process" among them), alternated ``repeats`` times."""
    if ONE not in ways or not set(ways) <= set(RUNS):
        raise ValueError(f"ways: {ONE!r} and any of {RUNS[::2]}, got {ways}")
    ways = tuple(r for r in RUNS if r in ways)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    result = {"map": env_map.name, "end": end, "max_size": max_size, "repeats": repeats, "cores": os.cpu_count(), "clips": []}
    for clip in clips:
        figures: dict = {"clip": clip.name, "runs": {r: [] for r in ways}, "load": []}
        outs = {r: out_dir / f"{clip.stem}_{NAMES[r]}.mp4" for r in ways}
        with tempfile.TemporaryDirectory(prefix="bench-spread-") as work:
            for k in range(repeats):
                for run in ways if k % 2 == 0 else ways[::-1]:  # alternated: a load that drifts falls on each
                    load = os.getloadavg()[0]
                    done = _render(clip, env_map, outs[run], end, max_size, run, Path(work) / NAMES[run])
                    figures["runs"][run].append(done["seconds"])
                    figures["load"].append(round(load, 2))
                    progress(f"{clip.name}, {run}: {done['seconds']:.1f} s (load {load:.1f})")
                    frames = json.loads((done["bundle"] / "clip.json").read_text())["frames"]
                    if run == RAY:
                        joins = _joins(done["bundle"])
            parts = _joins(done["bundle"])["parts"]  # (any way's bundle: the parts follow the clip's rate and length)
        median = {r: statistics.median(v) for r, v in figures["runs"].items()}
        errors = _pair_errors(clip, end, outs)
        figures.update(frames=frames, median_seconds=median,
                       frames_per_minute={r: round(60 * frames / s, 1) for r, s in median.items()},
                       time_over_one={r: round(median[r] / median[ONE], 3) for r in ways if r != ONE},
                       warping_error={r: round(float(np.nanmean(e)), 6) for r, e in errors.items()},
                       difference={r: _difference(outs[ONE], outs[r]) for r in ways if r != ONE},
                       same_bytes={r: outs[ONE].read_bytes() == outs[r].read_bytes() for r in ways if r != ONE})
        figures["seams"] = {"one process's parts": _seams(errors[ONE], parts)}
        if RAY in ways:
            figures.update(joins=joins)
            figures["seams"].update(ranges=_seams(errors[RAY], joins["ranges"]), parts=_seams(errors[RAY], joins["parts"]))
        result["clips"].append(figures)
        progress(table_line(figures))
        write_text(out_dir / "spread.json", json.dumps(result, indent=1) + "\n")
    return result


def table_line(f: dict) -> str:
    fpm, line = f["frames_per_minute"], f"{f['clip']}: {f['frames']} frames; one process {f['frames_per_minute'][ONE]} frames a minute"
    if THEN in fpm:
        line += (f"; inferred, then relit {fpm[THEN]} ({f['time_over_one'][THEN]:.2f} x the time, "
                 f"{'the same bytes' if f['same_bytes'][THEN] else 'not the same bytes'})")
    if RAY in fpm:
        r = f["seams"]["ranges"]
        seam = f"warping error at the ranges' joins {r['ratio']:.2f} x elsewhere" if "ratio" in r else "no range join"
        line += (f"; --ray local {fpm[RAY]} ({f['time_over_one'][RAY]:.2f} x the time); {seam}, at the parts' "
                 f"{f['seams']['parts'].get('ratio', float('nan')):.2f} x; the two clips differ by "
                 f"{f['difference'][RAY]['mean']:.2f} of 255")
    return line
