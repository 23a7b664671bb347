"""The 'refined' shadow mode: the engine shows the visibility it is given, falls back to the soft
visibility when the lights move, and the refinement network fills it from the engine's passes."""

from __future__ import annotations

import numpy as np
import pytest

from viewer.gl import Engine, EngineOptions
from viewer.photo.refinement import Refiner, light_visibility, refine_engine
from viewer.resources import asset_dir, sample_scene_dir
from viewer.scene.area_lights import load_lights
from viewer.scene.bundle import load_scene
from viewer.scene.resampling import resample_scene


@pytest.fixture
def engine(ctx):
    scene = resample_scene(load_scene(sample_scene_dir()), 96)
    eng = Engine(ctx, scene, EngineOptions(shadow_resolution=256))
    eng.set_lights(load_lights(asset_dir() / "envmaps" / "venice_sunset_256.lights.json"))
    yield eng
    eng.release()


def _image(eng, mode):
    eng.set_visibility(mode)
    return eng.render().output.read_hdr()[..., :3].copy()


def test_refined_mode_composites_the_given_visibility(engine):
    soft_img, none_img = _image(engine, "soft"), _image(engine, "none")
    hard, soft = light_visibility(engine)
    assert np.array_equal(_image(engine, "refined"), soft_img)  # nothing set yet: the soft visibility
    engine.set_refined_visibility(soft)
    assert engine.refined_current
    assert np.allclose(_image(engine, "refined"), soft_img, atol=1e-5)
    engine.set_refined_visibility(np.ones_like(soft))
    assert np.allclose(_image(engine, "refined"), none_img, atol=1e-5)
    engine.set_refined_visibility(hard)
    assert np.allclose(_image(engine, "refined"), _image(engine, "hard"), atol=1e-5)
    lights = engine.lights
    engine.set_lights(lights.with_sigma(0, float(lights.sigma[0]) + 1.0))  # the shadows change
    assert not engine.refined_current
    assert np.allclose(_image(engine, "refined"), _image(engine, "soft"), atol=1e-6)
    with pytest.raises(ValueError, match="NaN"):
        engine.set_refined_visibility(np.full_like(soft, np.nan))
    with pytest.raises(ValueError, match="must be"):
        engine.set_refined_visibility(soft[:3])


def test_refinement_network_fills_the_refined_mode(engine, tiny_networks):
    refiner = Refiner(tiny_networks / "refine.safetensors")
    vis = refine_engine(engine, refiner)
    mask = engine.scene.mask
    assert vis.shape == (len(engine.lights), *mask.shape)
    assert np.all(np.isfinite(vis)) and vis.min() >= 0 and vis.max() <= 1 and np.all(vis[:, ~mask] == 0)
    img = _image(engine, "refined")
    assert engine.refined_current and np.all(np.isfinite(img)) and img[mask].mean() > 0


def test_missing_refinement_network_is_a_clear_error(tmp_path):
    from viewer.errors import InputError

    with pytest.raises(InputError, match="not installed"):
        Refiner(tmp_path / "refine.safetensors")
