"""``relight bench timings``: the headline timings, each compared with the last recorded one (the
committed ``docs/results/bench_timings.json``, or ``--last``), saying which moved.

Measured on this machine, medians of ``repeats`` runs, with the load average beside them (a busy
machine moves every timing: compare runs at the same load):

- ``torch_import``: a fresh Python importing torch (what every command that fits or infers pays once);
- ``fit_instant_1k``: the instant light fit of a 1k map, 16 lights, in-process;
- ``fit_lights_command``: ``relight fit-lights MAP -n 16`` end to end, a fresh cache;
- ``render_balanced``: one frame of the bundled sample at the balanced preset, the lights moved each time;
- ``infer_photo``: the bundled photo inferred (``relight infer``, its own size up to 768 px), one run.

A timing moved when it is more than ``MOVED`` away from the last one, either way."""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

MOVED = 0.15  # of the last timing
FIT_MAP = "kiara_1_dawn_1k.hdr"  # of the shared maps ($RELIGHT_DATA/hdri)


def _median_seconds(run, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return round(statistics.median(times), 3)


def _command(args: list[str], env: dict | None = None) -> None:
    subprocess.run([sys.executable, *args], check=True, capture_output=True, env={**os.environ, **(env or {})})


def measure(maps: Path, repeats: int = 3) -> dict:
    """The headline timings (module docstring), in seconds."""
    import numpy as np

    from viewer.gl import Engine, create_headless_context
    from viewer.gl.presets import PRESETS
    from viewer.lighting.envmap import load_envmap
    from viewer.lighting.lightfit.fit import fit_lights
    from viewer.resources import asset_dir, sample_scene_dir
    from viewer.scene.area_lights import load_lights
    from viewer.scene.bundle import load_scene

    env_path = maps / FIT_MAP
    env = load_envmap(env_path)
    out: dict = {"torch_import": _median_seconds(lambda: _command(["-c", "import torch"]), repeats),
                 "fit_instant_1k": _median_seconds(lambda: fit_lights(env, 16, "instant"), repeats)}
    with tempfile.TemporaryDirectory(prefix="relight-timings-") as tmp:
        def fit_command():
            cache = tempfile.mkdtemp(dir=tmp)  # a fresh cache each run: the fit is made, not read
            _command(["-m", "viewer.cli.main", "fit-lights", str(env_path), "-n", "16", "-o", f"{cache}/lights.json"],
                     {"RELIGHT_CACHE": cache})

        out["fit_lights_command"] = _median_seconds(fit_command, repeats)
        out["infer_photo"] = _median_seconds(lambda: _command(
            ["-m", "viewer.cli.main", "infer", str(asset_dir() / "photos" / "underpass.jpg"), "--max-size", "768",
             "-o", f"{tmp}/bundle"], {"RELIGHT_CACHE": f"{tmp}/cache"}), 1)
    ctx = create_headless_context()
    scene = load_scene(sample_scene_dir())
    lights = load_lights(asset_dir() / "envmaps" / "venice_sunset_256.lights.json")
    engine = Engine(ctx, scene, PRESETS["balanced"].options)
    yaws = iter(np.linspace(0.0, 360.0, 4 * repeats + 2))
    try:
        def frame():
            engine.set_lights(lights.rotated(float(next(yaws))))
            engine.render()
            engine.output.read_display()

        frame()  # the programs compiled and the resources made: not a frame's time
        out["render_balanced"] = _median_seconds(frame, 4 * repeats)
    finally:
        engine.release()
    return out


def compare(now: dict, last: dict | None) -> dict:
    """Each timing against the last one: ``{name: {"now", "last", "ratio", "moved"}}`` (no last: not compared)."""
    rows = {}
    for name, seconds in now.items():
        before = (last or {}).get(name)
        ratio = round(seconds / before, 3) if before else None
        rows[name] = {"now": seconds, "last": before, "ratio": ratio,
                      "moved": None if ratio is None else ("slower" if ratio > 1 + MOVED else "faster" if ratio < 1 - MOVED else "")}
    return rows


def run_timings_benchmark(maps: Path, output, last_path=None, repeats: int = 3) -> dict:
    from viewer.files.imageio import write_text

    last = None
    if last_path is not None and Path(last_path).is_file():
        last = json.loads(Path(last_path).read_text(encoding="utf-8")).get("seconds")
    seconds = measure(Path(maps), repeats)
    result = {"seconds": seconds, "compared": compare(seconds, last), "last": str(last_path) if last else None,
              "load": list(os.getloadavg()), "cpus": os.cpu_count(), "repeats": repeats,
              "when": time.strftime("%Y-%m-%d %H:%M")}
    write_text(output, json.dumps(result, indent=1) + "\n")
    return result


def table(result: dict) -> str:
    lines = [f"headline timings (medians of {result['repeats']}; load {result['load'][0]:.2f} on {result['cpus']} CPUs)"
             + (f", against {result['last']}" if result["last"] else ", nothing recorded to compare with")]
    for name, row in result["compared"].items():
        was = f" (was {row['last']:.3f} s, x{row['ratio']:.2f}{': ' + row['moved'] if row['moved'] else ''})" if row["last"] else ""
        lines.append(f"  {name:>20}: {row['now']:.3f} s{was}")
    moved = [n for n, r in result["compared"].items() if r["moved"]]
    lines.append(f"moved by more than {100 * MOVED:.0f} %: {', '.join(moved) if moved else 'none'}")
    return "\n".join(lines)
