"""``relight bench engine``: per-pass GL engine times for full recompute (rotation), sigma change
and intensity change, at several output sizes and light counts, and the torch twin on the same frame;
both soft-shadow methods (the default contact-hardening PCSS and the paper's CSM) at 512^2 and 16
lights; the cost of a sigma change against sigma; and how much the sigma slider changes the image.

Times are wall-clock medians over repeats with ``ctx.finish()`` around each pass (GL timer queries
are meaningless on llvmpipe). Results go to stdout and a JSON file.
"""

from __future__ import annotations

import json
import platform
import time
from dataclasses import replace

import numpy as np

from viewer.files.imageio import write_text
from viewer.gl.soft import soft_method
from viewer.resources import asset_dir, sample_scene_dir
from viewer.scene.area_lights import AreaLights
from viewer.scene.depth_mesh import resolve_step

ENVMAP = "envmaps/immenstadter_horn_256.hdr"


def bench_lights(n: int) -> AreaLights:
    """N lights from the bundled environment map (median cut), so sigma and intensity spreads are
    those of a real map."""
    from viewer.lighting.envmap import load_envmap
    from viewer.lighting.median_cut import median_cut_lights

    return median_cut_lights(load_envmap(asset_dir() / ENVMAP), n)


def _median_ms(values) -> float:
    return float(np.median(values) * 1000.0) if len(values) else 0.0


def frame_seconds(engine, ctx, lights: AreaLights) -> float:
    """Wall time of one frame: set the lights, render, and wait for the GL work to finish."""
    ctx.finish()
    t0 = time.perf_counter()
    engine.set_lights(lights)
    engine.render()
    ctx.finish()
    return time.perf_counter() - t0


def _time_engine(engine, ctx, lights: AreaLights, repeats: int) -> dict:
    engine.set_lights(lights)
    engine.render()
    ctx.finish()
    results = {}
    brightest = int(np.argmax(lights.intensity.max(axis=1)))
    changes = {
        "full": lambda i: lights.rotated(7.0 * (i + 1)),
        "sigma": lambda i: lights.rotated(7.0 * repeats).with_sigma(brightest,
                                                                    float(lights.sigma.max() * (1.5 if i % 2 == 0 else 1.0) + 1.0)),
        "intensity": lambda i: lights.rotated(7.0 * repeats).with_sigma(brightest,
                                                                        float(lights.sigma.max() + 1.0)).scaled(1.0 + 0.1 * (i + 1)),
    }
    for kind, make in changes.items():
        engine.set_lights(make(-1))  # settle on this series' base state before timing it
        engine.render()
        per_pass: dict[str, list[float]] = {}
        totals, profiled = [], []
        for i in range(2 * repeats):  # alternate: plain frames (total) and profiled frames (per pass)
            engine.kit.profile = i % 2 == 1
            for v in engine.kit.timings.values():
                v.clear()
            (profiled if engine.kit.profile else totals).append(frame_seconds(engine, ctx, make(i)))
            if engine.kit.profile:
                for name, ts in engine.kit.timings.items():
                    per_pass.setdefault(name, []).append(sum(ts))
        results[kind] = {"total_ms": _median_ms(totals), "profiled_total_ms": _median_ms(profiled),
                         "passes_ms": {k: _median_ms(v) for k, v in per_pass.items()}}
    return results


def run_engine_benchmark(sizes=(512, 1024), light_counts=(8, 16, 32), repeats: int = 5, output="out/bench_engine.json",
                         twin: bool = True, twin_device: str = "cpu") -> dict:
    from viewer.gl import Engine, EngineOptions, create_headless_context
    from viewer.gl.context import describe
    from viewer.scene.bundle import load_scene
    from viewer.scene.resampling import resample_scene

    ctx = create_headless_context()
    base = load_scene(sample_scene_dir())  # 512^2
    report = {"machine": {"renderer": describe(ctx), "cpu": platform.processor() or platform.machine(),
                          "python": platform.python_version()}, "twin_device": twin_device,
              "options": {}, "repeats": repeats, "runs": []}
    print(f"GL engine benchmark on {describe(ctx)}; medians of {repeats} runs")
    print(f"{'size':>5} {'lights':>6} {'full ms':>8} {'sigma ms':>9} {'intens ms':>9} {'twin ms':>8}  passes (full)")
    for size in sizes:
        scene = resample_scene(base, size)
        options = EngineOptions(shadow_step=resolve_step(0, scene), profile=True)
        report["options"][str(size)] = {"shadow_resolution": options.shadow_resolution, "shadow_step": options.shadow_step,
                                        "soft": options.soft, "terms": options.terms, "prefilter": options.prefilter}
        for n in light_counts:
            lights = bench_lights(n)
            engine = Engine(ctx, scene, options)
            res = _time_engine(engine, ctx, lights, repeats)
            engine.release()
            run = {"size": size, "lights": n, **res}
            if twin:
                run["twin_full_ms"] = _time_twin(scene, lights, options, repeats=2, device=twin_device)
                run["twin_over_gl"] = run["twin_full_ms"] / max(res["full"]["total_ms"], 1e-9)
            report["runs"].append(run)
            passes = " ".join(f"{k}={v:.1f}" for k, v in res["full"]["passes_ms"].items())
            twin_ms = f"{run['twin_full_ms']:8.0f}" if twin else f"{'-':>8}"
            print(f"{size:>5} {n:>6} {res['full']['total_ms']:8.1f} {res['sigma']['total_ms']:9.1f} "
                  f"{res['intensity']['total_ms']:9.1f} {twin_ms}  {passes}")
    report["soft_methods"] = _soft_methods(ctx, base, repeats)
    report["sigma_sweep"] = _sigma_sweep(ctx, base, repeats)
    report["slider"] = _slider_effect(ctx, base)
    report["skin"] = _skin_cost(ctx, repeats)
    if output:
        path = write_text(output, json.dumps(report, indent=2) + "\n")
        print(f"wrote {path}")
    return report


def _skin_cost(ctx, repeats: int, lights_count: int = 16) -> dict:
    """The light scattered under the skin (viewer/gl/skin_pass.py): the bundled photo's frame at its
    own size and at twice it, a frame after a change of the lights' intensity (composite, mipmaps,
    the scatter and the frame composite) with the scatter on and off (``--no-skin``), and the
    scatter pass's own time (profiled frames); medians."""
    from viewer.gl import Engine, EngineOptions
    from viewer.photo.inference import infer_scene
    from viewer.scene.look import Look

    scene = infer_scene(asset_dir() / "photos" / "underpass.jpg", ctx=ctx)["scene"]
    out = {"photo": "assets/photos/underpass.jpg",
           "skin_share": float((scene.frame.skin > 0.5).mean()) if scene.frame.skin is not None else 0.0,
           "frames": []}
    lights = bench_lights(lights_count)
    for factor in (1, 2):
        frame = scene.frame.resized((scene.frame.width * factor, scene.frame.height * factor))
        sized = replace(scene, frame=frame)
        row = {"frame": [frame.width, frame.height], "skin_mm_per_pixel": round(frame.skin_mm, 4)}
        for on in (True, False):
            engine = Engine(ctx, sized, EngineOptions(profile=True))
            engine.set_look(Look(exposure=0.0, background="color", skin=on))
            times = []
            for i in range(repeats + 1):
                times.append(frame_seconds(engine, ctx, lights.scaled(1.0 + 0.01 * i)))
            label = "on" if on else "off"
            row[f"frame_ms_{label}"] = _median_ms(times[1:])
            if on:
                row["skin_scatter_ms"] = _median_ms(engine.kit.timings.get("skin_scatter", [0.0])[1:] or [0.0])
            engine.release()
        out["frames"].append(row)
        print(f"skin scatter at {frame.width}x{frame.height}: a frame {row['frame_ms_on']:.1f} ms on, "
              f"{row['frame_ms_off']:.1f} ms off; the pass {row['skin_scatter_ms']:.1f} ms")
    return out


SWEEP_SIGMAS = (0.5, 2.0, 8.0, 20.0, 50.0)
SOFT_SETTINGS = {"pcss": {"soft": "pcss"}, "csm": {"soft": "csm"}}  # label: EngineOptions fields
SLIDER = (1.5, 27.0)  # the brightest light's sigma at the two ends of the measured slider range


def _soft_methods(ctx, scene, repeats: int, lights_count: int = 16) -> dict:
    """Full, sigma and intensity frame times at 512^2 (the sample) for each soft-shadow method, in one run."""
    from viewer.gl import Engine, EngineOptions

    lights = bench_lights(lights_count)
    out = {}
    print(f"soft-shadow methods, {scene.width}^2, {lights_count} lights (ms): full / sigma / intensity")
    for label, fields in SOFT_SETTINGS.items():
        engine = Engine(ctx, scene, EngineOptions(**fields, profile=True))
        res = _time_engine(engine, ctx, lights, repeats)
        engine.release()
        out[label] = res
        print(f"{label:>7} {res['full']['total_ms']:8.1f} {res['sigma']['total_ms']:8.1f} {res['intensity']['total_ms']:8.1f}  "
              + " ".join(f"{k}={v:.1f}" for k, v in res["full"]["passes_ms"].items()))
    return out


def _slider_effect(ctx, scene) -> dict:
    """How much the displayed image (8-bit grey levels, inside the mask) changes when the brightest
    of 16 lights goes from sigma SLIDER[0] to SLIDER[1], for each soft-shadow method."""
    from viewer.gl import Engine, EngineOptions

    lights = bench_lights(16)
    k = lights.brightest
    out = {"sigmas": list(SLIDER), "light": k}
    print(f"sigma slider {SLIDER[0]:g} -> {SLIDER[1]:g} on the brightest light: mean / 99th percentile |change| "
          "(grey levels in the mask), pixels changed by more than 2")
    for label, fields in SOFT_SETTINGS.items():
        engine = Engine(ctx, scene, EngineOptions(**fields))
        shown = []
        for sigma in SLIDER:
            engine.set_lights(lights.with_sigma(k, sigma))
            engine.render()
            shown.append(engine.output.read_display().astype(np.float64))  # uint8 sRGB
        engine.release()
        d = np.abs(shown[1] - shown[0])[scene.mask]
        out[label] = {"mean": float(d.mean()), "p99": float(np.percentile(d, 99)), "changed_over_2": float((d.max(axis=-1) > 2).mean())}
        print(f"{label:>7} {out[label]['mean']:.2f} / {out[label]['p99']:.1f}, {100 * out[label]['changed_over_2']:.1f} %")
    return out


def _sigma_sweep(ctx, scene, repeats: int) -> dict:
    """Time of one light's sigma change against sigma: the CSM with the pyramid and the exact
    Gaussian pre-filter (the pyramid's cost must not grow with sigma), and PCSS."""
    from viewer.gl import Engine, EngineOptions

    lights = bench_lights(16).rotated(180.0)
    target = int(np.argmax(lights.intensity.max(axis=1)))
    sweep = {}
    print("sigma change of one light (ms), 512^2, 16 lights:")
    print(f"{'sigma':>7} " + " ".join(f"{s:>8}" for s in SWEEP_SIGMAS))
    for method, fields in (("pyramid", {"soft": "csm", "prefilter": "pyramid"}), ("exact", {"soft": "csm", "prefilter": "exact"}),
                           ("pcss", {"soft": "pcss"})):
        engine = Engine(ctx, scene, EngineOptions(**fields))
        engine.set_lights(lights)
        engine.render()
        row = []
        for sigma in SWEEP_SIGMAS:
            times = [frame_seconds(engine, ctx, lights.with_sigma(target, sigma * (1.0 + 0.01 * (i % 2))))
                     for i in range(repeats)]
            row.append(_median_ms(times))
        engine.release()
        sweep[method] = dict(zip(map(str, SWEEP_SIGMAS), row))
        print(f"{method:>7} " + " ".join(f"{t:8.1f}" for t in row))
    return sweep


def _time_twin(scene, lights: AreaLights, options, repeats: int = 2, device: str = "cpu") -> float:
    """The torch twin's full frame on ``device`` (a warm-up frame first, so CUDA's start-up and
    kernel compilation are not timed; the wait for the device is)."""
    import torch

    from viewer.twin import render as twin_render

    def frame():
        twin_render(scene, lights, shadow_resolution=options.shadow_resolution, shadow_step=options.shadow_step,
                    terms=options.terms, soft=soft_method(options.soft).twin, device=device)
        if device.startswith("cuda"):
            torch.cuda.synchronize(device)

    times = []
    with torch.no_grad():
        if device != "cpu":
            frame()
        for _ in range(repeats):
            t0 = time.perf_counter()
            frame()
            times.append(time.perf_counter() - t0)
    return _median_ms(times)
