"""``relight bench batch``: a catalogue's throughput. A set of distinct photos (the photos given, then
mirrored and cropped until there are ``count``: each a new file, so each is inferred) x maps,
run by ``relight batch`` with one worker, two workers and a local Ray cluster, each from an empty
inference cache and an empty folder; photo-looks a minute, the seconds of each stage (inference per
photo, render per item, from the manifest) and where the time went. Results to stdout and JSON."""

from __future__ import annotations

import contextlib
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from viewer.files.imageio import atomic_path, write_text

BATCH_MAPS = ("rooitou_park_1k.hdr", "studio_small_03_1k.hdr", "dikhololo_night_1k.hdr")
CONFIGS = (("1 worker, 2 threads", ["--workers", "1", "--threads", "2"]),
           ("2 workers, 1 thread each", ["--workers", "2", "--threads", "1"]),
           ("Ray (local cluster, 2 CPUs), 2 actors", ["--ray", "auto", "--threads", "1"]))


def catalogue(sources: list[Path], folder: Path, count: int) -> list[Path]:
    """``count`` distinct photos made from ``sources``: the n-th use of a source is mirrored when n
    is odd and cropped by 3 % per side for every two uses before it."""
    from PIL import Image, ImageOps

    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for k in range(count):
        src, use = sources[k % len(sources)], k // len(sources)
        with Image.open(src) as im:
            im = ImageOps.exif_transpose(im).convert("RGB")
            crop = (use // 2) * 3
            dx, dy = im.width * crop // 100, im.height * crop // 100
            im = im.crop((dx, dy, im.width - dx, im.height - dy))
            if use % 2:
                im = ImageOps.mirror(im)
            path = folder / f"{k:02d}-{src.stem}-crop{crop}{'-mirrored' if use % 2 else ''}.jpg"
            with atomic_path(path) as tmp:
                im.save(tmp, format="JPEG", quality=95)
        out.append(path)
    return out


@contextlib.contextmanager
def local_ray_cluster(cpus: int = 2):
    """A local Ray cluster (``ray start --head``) for the block: yields the environment that joins
    it; stopped after. Its folder is short: Ray's sockets live there, and a socket's path has at
    most 107 characters (pytest's folders are longer)."""
    ray = Path(sys.executable).with_name("ray")
    temp = tempfile.mkdtemp(prefix="ray", dir="/tmp")
    env = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0"}
    try:
        started = subprocess.run([str(ray), "start", "--head", "--num-cpus", str(cpus), "--include-dashboard", "false",
                                  "--temp-dir", temp], capture_output=True, text=True, env=env, timeout=180)
        if started.returncode != 0:
            raise RuntimeError(f"ray start failed: {started.stdout}{started.stderr}")
        yield {**env, "RAY_ADDRESS": "auto"}
    finally:
        subprocess.run([str(ray), "stop", "--force"], capture_output=True, env=env, timeout=180)
        shutil.rmtree(temp, ignore_errors=True)


def run_batch_benchmark(sources: list[Path], maps: list[Path], count: int = 20, max_size: int = 2048,
                        output="out/bench_batch.json") -> dict:
    report = {"machine": {"cpu": platform.processor() or platform.machine(), "cores": os.cpu_count(),
                          "load_before": os.getloadavg()[0]},
              "photos": count, "maps": [m.name for m in maps], "max_size": max_size, "runs": []}
    with tempfile.TemporaryDirectory(prefix="bench-batch-") as work:
        work = Path(work)
        catalogue(sources, work / "photos", count)
        for label, options in CONFIGS:
            cache, out = work / label.split()[0] / "cache" / "lights", work / label.split()[0] / "out"
            with local_ray_cluster() if "--ray" in options else contextlib.nullcontext(dict(os.environ)) as env:
                t0 = time.perf_counter()
                res = subprocess.run([sys.executable, "-m", "viewer.cli.main", "batch", str(work / "photos"), "--env",
                                      *map(str, maps), "-o", str(out), "--max-size", str(max_size), *options],
                                     capture_output=True, text=True, env={**env, "RELIGHT_CACHE": str(cache)})
                seconds = time.perf_counter() - t0
            events = [json.loads(line) for line in (out / "manifest.jsonl").read_text().splitlines()]
            done = [e for e in events if e["event"] == "done"]
            inferred = [e for e in events if e["event"] == "inferred"]
            run = {"config": label, "options": options, "exit": res.returncode, "seconds": round(seconds, 1),
                   "items": len(done), "failed": sum(e["event"] == "failed" for e in events),
                   "per_minute": round(60.0 * len(done) / seconds, 2),
                   "infer_s": _stats([e["seconds"] for e in inferred]),
                   "render_s": _stats([e["times"]["total"] for e in done]),
                   "render_stages_s": {k: _stats([e["times"][k] for e in done if k in e["times"]])
                                       for k in ("scene", "render", "layers")},
                   "summary": res.stdout.strip().splitlines()[-2:] if res.stdout else [], "stderr_tail": res.stderr[-500:]}
            report["runs"].append(run)
            print(f"{label:40s} {run['items']:3d} items in {seconds:6.1f} s: {run['per_minute']:5.1f} photo-looks a minute; "
                  f"inference {run['infer_s']['median']:.1f} s a photo, render {run['render_s']['median']:.2f} s an item "
                  f"(medians)", flush=True)
    report["machine"]["load_after"] = os.getloadavg()[0]
    if output:
        print(f"wrote {write_text(output, json.dumps(report, indent=2) + chr(10))}")
    return report


def _stats(values) -> dict:
    v = np.asarray(values, float)
    if not len(v):
        return {"n": 0, "median": 0.0, "total": 0.0}
    return {"n": int(len(v)), "median": round(float(np.median(v)), 3), "total": round(float(v.sum()), 1),
            "min": round(float(v.min()), 3), "max": round(float(v.max()), 3)}
