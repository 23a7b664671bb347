"""The engine's hard shadows against ray-traced ground truth (Mitsuba 3) on the sample scene."""

from __future__ import annotations

import numpy as np

from viewer.gl import Engine, EngineOptions
from viewer.lab.bench.engine import bench_lights
from viewer.lab.bench.groundtruth import RayTracedVisibility
from viewer.lab.bench.shadows import weighted_error
from viewer.resources import sample_scene_dir
from viewer.scene.area_lights import AreaLights
from viewer.scene.bundle import load_scene


def test_hard_shadows_match_ray_tracing(ctx):
    scene = load_scene(sample_scene_dir())
    lights = bench_lights(16).rotated(180.0)
    lights = AreaLights(lights.direction, np.zeros(len(lights)), lights.intensity)
    tracer = RayTracedVisibility(scene)
    truth = [tracer.visibility(d) for d in lights.direction]
    assert 0.05 < np.mean([t[scene.mask].mean() for t in truth]) < 0.95  # there are shadows to get right
    errors = {}
    for res in (256, 1024):
        eng = Engine(ctx, scene, EngineOptions(shadow_resolution=res, shadow_step=1))
        eng.set_lights(lights)
        eng.render()
        errors[res] = weighted_error(scene, lights, [eng.output.read_light(i)["visibility_hard"] for i in range(len(lights))], truth)
        eng.release()
    assert errors[1024] < 0.015, errors  # measured ~0.01 (docs/engine.md, "Error against ground truth")
    assert errors[1024] < errors[256], errors  # a finer shadow map converges towards the truth
