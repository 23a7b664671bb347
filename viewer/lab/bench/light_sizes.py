"""The area lights' sizes against a ray tracer (``relight bench light-sizes``).

The sample person's depth mesh, white and diffuse, stands on a white ground plane; each map of the
folder lights it. Mitsuba renders the whole map (truth): the figure's shadowed diffuse and the
ground's share of light left (:mod:`viewer.lab.bench.ground`). The engine renders the map's 16
default (``instant``) lights with their sigmas as the product gives them (``product``), and the same
lights with other sigmas: each light's size on the map (:mod:`viewer.lighting.light_size`) times
0.5 and 2, and 0 (point lights). Errors: the figure's relative L1 of the shadowed diffuse over the
pixels the person covers, and the ground's mean |difference| of the light left where either puts
shadow (as the ground benchmark), with the engine's default soft shadows (PCSS).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from viewer.files.imageio import write_text
from viewer.gl import Engine, EngineOptions
from viewer.lab.bench.ground import IN_SHADOW, engine_ratio, plane_ratio
from viewer.lighting.envmap import LUMINANCE as LUMA, load_envmap
from viewer.lighting.light_size import region_sizes
from viewer.lighting.lightfit.fit import fit_lights
from viewer.resize import resize
from viewer.resources import sample_scene_dir
from viewer.scene.area_lights import AreaLights
from viewer.scene.bundle import load_scene
from viewer.scene.ground import ground_plane
from viewer.scene.look import Look
from viewer.scene.resampling import resample_scene

VARIANTS = ("product", "sizes x 0.5", "sizes x 1", "sizes x 2", "zero")


def figure_diffuse(ctx, scene, lights: AreaLights) -> np.ndarray:
    """(H, W) the engine's shadowed diffuse luminance of a white figure, sum_l I_l S_l V_l, at the scene's size."""

    eng = Engine(ctx, scene, EngineOptions())
    try:
        eng.set_lights(lights)
        eng.set_look(Look(background="color", shadows="soft"))
        eng.render()
        total = 0.0
        for k in range(len(lights)):
            planes = eng.output.read_light(k)
            total = total + float(lights.intensity[k] @ LUMA) * planes["diffuse"] * planes["visibility_soft"]
    finally:
        eng.release()
    return resize(np.asarray(total, np.float32), (scene.width, scene.height), "linear")


def variant_sigmas(lights: AreaLights, sizes: np.ndarray) -> dict[str, np.ndarray]:
    return {"product": lights.sigma, "sizes x 0.5": 0.5 * sizes, "sizes x 1": sizes, "sizes x 2": 2.0 * sizes,
            "zero": np.zeros_like(sizes)}


def run_light_sizes_benchmark(maps_dir, output: str, size: int = 256, spp: int = 256, n: int = 16) -> dict:
    from viewer.gl import create_headless_context
    from viewer.gl.context import describe
    from viewer.lab.data.reference import render_bundle_reference

    ctx = create_headless_context()
    scene = resample_scene(load_scene(sample_scene_dir()), size)
    plane = ground_plane(scene)
    rows = []
    for path in sorted(Path(maps_dir).glob("*.hdr")):
        env = load_envmap(path)
        lights = fit_lights(env, n, "instant")
        sizes = region_sizes(env, lights.direction)
        reference = render_bundle_reference(scene, env, spp=spp, images=("diffuse_shadowed",))
        truth_figure = reference["diffuse_shadowed"] @ LUMA
        on_figure = (reference["coverage"] > 0.99) & scene.mask
        truth_ground, seen = plane_ratio(scene, env, plane, spp)
        measured = {}  # sigmas -> errors: a variant equal to another (the product's are the sizes) is rendered once
        for name, sigma in variant_sigmas(lights, sizes).items():
            key = np.asarray(sigma, np.float32).tobytes()
            if key not in measured:
                variant = AreaLights(lights.direction, sigma, lights.intensity)
                figure = figure_diffuse(ctx, scene, variant)
                left, _ = engine_ratio(ctx, scene, variant, "pcss", 1)
                region = seen & ((truth_ground < IN_SHADOW) | (left < IN_SHADOW))
                measured[key] = (float(np.abs(figure - truth_figure)[on_figure].sum() / truth_figure[on_figure].sum()),
                                 float(np.abs(left - truth_ground)[region].mean()) if region.any() else 0.0)
            figure_error, ground_error = measured[key]
            brightest = np.argsort(-(lights.intensity @ LUMA))[:3]
            rows.append({"map": path.stem, "variant": name, "figure_rel_l1": figure_error, "ground_mae": ground_error,
                         "brightest_sigmas": [round(float(sigma[i]), 2) for i in brightest]})
            print(f"{path.stem:22s} {name:12s} figure {100 * figure_error:5.2f} %  ground {ground_error:.4f}  "
                  f"brightest lights' sigma {rows[-1]['brightest_sigmas']}", flush=True)
    medians = {v: {"figure_rel_l1": float(np.median([r["figure_rel_l1"] for r in rows if r["variant"] == v])),
                   "ground_mae": float(np.median([r["ground_mae"] for r in rows if r["variant"] == v]))} for v in VARIANTS}
    for v, m in medians.items():
        print(f"median over the maps, {v:12s}: figure {100 * m['figure_rel_l1']:5.2f} %  ground {m['ground_mae']:.4f}")
    out = {"machine": describe(ctx), "size": size, "spp": spp, "lights": n, "method": __doc__.split("\n\n", 1)[1].strip(),
           "medians": medians, "rows": rows}
    path = write_text(output, json.dumps(out, indent=1) + "\n")
    print(f"wrote {path}")
    return out
