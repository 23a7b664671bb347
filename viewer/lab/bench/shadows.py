"""``relight bench shadows``: error against a ground-truth reference versus run time for the
engine's quality knobs (shadow-map size, mesh decimation, CSM Fourier terms, prefilter method).

Error metric: the relative L1 error of the shadowed diffuse shading of a white figure,
    E = sum_l sum_p I_l S_l(p) |V_l(p) - V*_l(p)| / sum_l sum_p I_l S_l(p),
S_l the Lambert shading of light l (n.l / pi) and I_l its mean intensity, i.e. the image error the
visibility causes. The reference V* is ray-traced hard visibility of the full-resolution depth mesh
(Mitsuba 3) for the shadow-map knobs and for the Fourier terms (CSM at sigma -> 0 should reach the
hard result), and the exact Gaussian prefilter for the pyramid. Times are medians of full-frame
recomputes (a rotation of the lighting) on this machine's OpenGL.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from viewer.files.imageio import atomic_path, write_text
from viewer.lab.bench.engine import _median_ms, bench_lights, frame_seconds
from viewer.resources import sample_scene_dir
from viewer.scene.area_lights import AreaLights

YAWS = (0.0, 120.0, 240.0)  # the lighting is measured at these rotations and averaged


def _frame_ms(engine, ctx, lights: AreaLights, repeats: int) -> float:
    """Median full recompute: the lighting rotated a little further each frame."""
    engine.set_lights(lights)
    engine.render()
    return _median_ms([frame_seconds(engine, ctx, lights.rotated(3.0 * (i + 1))) for i in range(repeats)])


def _visibilities(engine, lights: AreaLights, channel: str) -> list[np.ndarray]:
    engine.set_lights(lights)
    engine.render()
    return [engine.output.read_light(i)[channel] for i in range(len(lights))]


def weighted_error(scene, lights: AreaLights, vis, ref) -> float:
    num = den = 0.0
    for i, d in enumerate(lights.direction):
        w = float(lights.intensity[i].mean()) * np.maximum(scene.normal @ d, 0.0) / np.pi * scene.mask
        num += float((w * np.abs(vis[i] - ref[i])).sum())
        den += float(w.sum())
    return num / max(den, 1e-30)


def run_shadow_benchmark(repeats: int = 3, output="out/bench_shadows.json", n_lights: int = 16) -> dict:
    from viewer.gl import Engine, EngineOptions, create_headless_context
    from viewer.gl.context import describe
    from viewer.lab.bench.groundtruth import RayTracedVisibility
    from viewer.scene.bundle import load_scene

    ctx = create_headless_context()
    scene = load_scene(sample_scene_dir())
    base = bench_lights(n_lights)
    light_sets = [base.rotated(y) for y in YAWS]
    hard_sets = [AreaLights(l.direction, np.zeros(len(l)), l.intensity) for l in light_sets]
    tracer = RayTracedVisibility(scene)
    truth = [[tracer.visibility(d) for d in l.direction] for l in light_sets]
    default = EngineOptions()
    report = {"machine": describe(ctx), "scene": "assets/sample_scene (512x512)",
              "lights": f"{n_lights} median-cut lights of the bundled map at yaws {YAWS}",
              "default": {"shadow_resolution": default.shadow_resolution, "shadow_step": default.shadow_step, "terms": default.terms,
                          "prefilter": default.prefilter},
              "knobs": {}}
    print(f"shadow quality vs time on {describe(ctx)} (error: relative L1 of the shadowed diffuse shading)")

    def measure(knob, value, options, lights_for_error, channel, reference):
        engine = Engine(ctx, scene, options)
        err = float(np.mean([weighted_error(scene, ls, _visibilities(engine, ls, channel), ref)
                             for ls, ref in zip(lights_for_error, reference)]))
        ms = _frame_ms(engine, ctx, light_sets[0], repeats)
        engine.release()
        report["knobs"].setdefault(knob, []).append({"value": value, "error": err, "frame_ms": ms})
        print(f"  {knob:>18} = {value!s:<8} error {err:7.4f}   full frame {ms:7.1f} ms")

    for res in (256, 512, 1024, 2048):
        measure("shadow_resolution", res, replace(default, shadow_resolution=res), hard_sets, "visibility_hard", truth)
    for step in (1, 2, 3, 4):
        measure("shadow_step", step, replace(default, shadow_step=step), hard_sets, "visibility_hard", truth)
    tiny = [AreaLights(l.direction, np.full(len(l), 0.1), l.intensity) for l in light_sets]
    for terms in (2, 4, 8, 16):
        measure("terms", terms, replace(default, terms=terms, hard_sigma=0.0), tiny, "visibility_soft", truth)
    exact_engine = Engine(ctx, scene, replace(default, prefilter="exact"))
    exact = [_visibilities(exact_engine, ls, "visibility_soft") for ls in light_sets]
    exact_engine.release()
    for method in ("exact", "pyramid"):
        measure("prefilter", method, replace(default, prefilter=method), light_sets, "visibility_soft", exact)

    if output:
        path = Path(output)
        path.parent.mkdir(parents=True, exist_ok=True)
        write_text(path, json.dumps(report, indent=2) + "\n")
        _plot(report, path.with_suffix(".png"))
        print(f"wrote {path} and {path.with_suffix('.png')}")
    return report


def _plot(report: dict, path: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    knobs = report["knobs"]
    fig, axes = plt.subplots(1, len(knobs), figsize=(4.2 * len(knobs), 3.6))
    for ax, (knob, rows) in zip(np.atleast_1d(axes), knobs.items()):
        t = [r["frame_ms"] for r in rows]
        e = [r["error"] for r in rows]
        ax.plot(t, e, "o-")
        for r in rows:
            ax.annotate(str(r["value"]), (r["frame_ms"], r["error"]), textcoords="offset points", xytext=(4, 4), fontsize=8)
        ax.set_title(knob)
        ax.set_xlabel("full frame (ms), 16 lights")
        ax.set_ylabel("shading error (rel. L1)")
        ax.grid(alpha=0.3)
    fig.suptitle(f"Error vs time, {report['machine']}", fontsize=9)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
