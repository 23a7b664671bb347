"""Temporal stability of turntables (``relight bench temporal``): the paper's dRMSE at steps 1, 2
and 4 and the flicker ratio (viewer/output/temporal.py) of 128-frame turns of the sample scene under two
bundled maps, for engine settings against the converged engine (shadow maps 2048, full-resolution
mesh, 8 Fourier terms), with the time per frame of each setting."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from viewer.files.imageio import write_text
from viewer.gl import Engine, EngineOptions, create_headless_context
from viewer.gl.context import describe
from viewer.output.render import turntable_yaws
from viewer.output.temporal import drmse, flicker_ratio
from viewer.resources import asset_dir, sample_scene_dir
from viewer.scene.area_lights import load_lights
from viewer.scene.bundle import load_scene
from viewer.scene.look import Look
from viewer.scene.resampling import resample_scene

FRAMES = 128
SIZE = 256
MAPS = ("immenstadter_horn_256", "studio_small_03_256")
SETTINGS = {
    "default (soft, 512 maps)": (EngineOptions(), "soft"),
    "soft, 256 shadow maps": (EngineOptions(shadow_resolution=256), "soft"),
    "soft, M = 2": (EngineOptions(terms=2), "soft"),
    "hard shadows (drag preview mode)": (EngineOptions(), "hard"),
}
REFERENCE = EngineOptions(shadow_resolution=2048, shadow_step=1, terms=8)


def _turn(ctx, scene, lights, options, visibility):
    eng = Engine(ctx, scene, options)
    frames, times = [], []
    for yaw in turntable_yaws(0.0, 360.0, FRAMES):
        eng.set_lights(lights)
        eng.set_look(Look(yaw=float(yaw), background="color", shadows=visibility))
        t = time.perf_counter()
        eng.render()
        ctx.finish()
        times.append(time.perf_counter() - t)
        frames.append(eng.output.read_display().astype(np.float32) / 255.0)
    eng.release()
    return np.stack(frames), float(np.median(times) * 1000)


def run_temporal_benchmark(output="out/bench_temporal.json") -> dict:
    ctx = create_headless_context()
    scene = resample_scene(load_scene(sample_scene_dir()), SIZE)
    rows = []
    for name in MAPS:
        lights = load_lights(asset_dir() / "envmaps" / f"{name}.lights.json")
        ref, ref_ms = _turn(ctx, scene, lights, REFERENCE, "soft")
        rows.append({"map": name, "setting": "reference", "ms_per_frame": ref_ms, "flicker": flicker_ratio(ref),
                     "drmse": {1: 0.0, 2: 0.0, 4: 0.0}})
        for label, (options, visibility) in SETTINGS.items():
            seq, ms = _turn(ctx, scene, lights, options, visibility)
            row = {"map": name, "setting": label, "ms_per_frame": ms, "flicker": flicker_ratio(seq), "drmse": drmse(seq, ref)}
            rows.append(row)
            d = row["drmse"]
            print(f"{name:24s} {label:34s} dRMSE {d[1]:.4f} {d[2]:.4f} {d[4]:.4f}  flicker {row['flicker']:.3f} "
                  f"(reference {rows[-1 - list(SETTINGS).index(label) - 1]['flicker']:.3f})  {ms:.0f} ms/frame", flush=True)
    result = {"machine": {"renderer": describe(ctx)}, "frames": FRAMES, "size": SIZE,
              "reference": "engine with shadow maps 2048, mesh step 1, M = 8 (pyramid prefilter)", "rows": rows}
    path = Path(output)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text(path, json.dumps(result, indent=1) + "\n")
    print(f"wrote {path}")
    return result
