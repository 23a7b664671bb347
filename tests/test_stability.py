"""Stiff and extreme inputs: every output finite, visibility in [0, 1], no energy created."""

from __future__ import annotations

import numpy as np
import pytest

from viewer.gl import Engine, EngineOptions
from viewer.lab.scenes import plane_and_box
from viewer.scene.area_lights import AreaLights


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return (v / np.linalg.norm(v, axis=-1, keepdims=True)).astype(np.float32)


EXTREME_LIGHTS = AreaLights(
    unit([[0.3, 0.4, 1.0], [1.0, 0.0, 0.01], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [-0.5, -0.2, 0.8], [0.2, -1.0, 0.05]]),
    [0.0, 50.0, 3.0, 0.0, 50.0, 10.0],  # hard, huge, ..., a light below the horizon
    [[1e5, 1e5, 1e5], [1e-6, 1e-6, 1e-6], [1.0, 1.0, 1.0], [2.0, 1.0, 0.5], [1.0, 2.0, 3.0], [1.0, 1.0, 1.0]],
)


def check_outputs(eng, n):
    hdr = eng.output.read_hdr()
    assert np.isfinite(hdr).all() and hdr.min() >= 0.0
    disp = eng.output.read_display()
    assert disp.dtype == np.uint8
    for i in range(n):
        out = eng.output.read_light(i)
        for name, v in out.items():
            assert np.isfinite(v).all(), name
        for name in ("visibility_soft", "visibility_hard"):
            assert out[name].min() >= 0.0 and out[name].max() <= 1.0, name
    return hdr


@pytest.mark.parametrize("roughness, specular", [(0.0, 1.0), (1.0, 1.0), (0.5, 0.0), (0.0, 0.0)])
def test_extreme_materials_and_lights(ctx, roughness, specular):
    sc = plane_and_box(64, roughness=roughness, specular=specular)
    eng = Engine(ctx, sc, EngineOptions(shadow_resolution=128, shadow_step=1))
    eng.set_lights(EXTREME_LIGHTS)
    eng.render()
    check_outputs(eng, len(EXTREME_LIGHTS))
    eng.release()


def test_depth_cliffs_and_spikes(ctx):
    sc = plane_and_box(64)
    rng = np.random.default_rng(1)
    spikes = rng.random(sc.depth.shape) < 0.02
    sc.depth = np.where(spikes, sc.depth * rng.uniform(0.2, 3.0, sc.depth.shape), sc.depth).astype(np.float32)
    sc.depth[:, 40:] += 2.0  # a 2 m cliff
    sc.validate()
    eng = Engine(ctx, sc, EngineOptions(shadow_resolution=128, shadow_step=1))
    eng.set_lights(EXTREME_LIGHTS)
    eng.render()
    check_outputs(eng, len(EXTREME_LIGHTS))
    eng.release()


@pytest.mark.parametrize("size, step", [(1, 1), (2, 1), (64, 3)])
def test_one_pixel_mask_and_tiny_images(ctx, size, step):
    sc = plane_and_box(max(size, 2) if size > 1 else 1, box=False)
    sc.mask[:] = False
    sc.mask[sc.height // 2, sc.width // 2] = True
    sc.validate()
    eng = Engine(ctx, sc, EngineOptions(shadow_resolution=64, shadow_step=step))
    eng.set_lights(EXTREME_LIGHTS)
    eng.render()
    hdr = check_outputs(eng, len(EXTREME_LIGHTS))
    assert hdr[sc.mask].max() > 0  # the single pixel is lit, not black
    eng.release()


def test_white_lambertian_plane_never_exceeds_analytic_value(ctx):
    sc = plane_and_box(32, box=False, albedo=1.0, specular=0.0)
    eng = Engine(ctx, sc, EngineOptions(shadow_resolution=64, shadow_step=1))
    rng = np.random.default_rng(3)
    dirs = unit(rng.normal(size=(40, 3)))
    dirs[0] = [0, 0, 1]
    for d in dirs:
        for sigma in (0.0, 20.0):
            eng.set_lights(AreaLights(d[None], [sigma], [[1, 1, 1]]))
            eng.render()
            hdr = eng.output.read_hdr()
            analytic = max(float(d[2]), 0.0) / np.pi
            assert hdr.max() <= analytic * (1 + 1e-6) + 1e-9, (d, sigma)
    for sigma in (0.0, 20.0):  # a lone flat plane facing the light is fully lit, hard or soft
        eng.set_lights(AreaLights(dirs[:1], [sigma], [[1, 1, 1]]))
        eng.render()
        np.testing.assert_allclose(eng.output.read_hdr(), 1 / np.pi, rtol=1e-6)
    eng.release()


def test_huge_image(ctx):
    sc = plane_and_box(2048)
    eng = Engine(ctx, sc, EngineOptions(shadow_resolution=256))
    eng.set_lights(EXTREME_LIGHTS)
    eng.render()
    hdr = eng.output.read_hdr()
    assert np.isfinite(hdr).all() and hdr.max() > 0
    eng.release()
