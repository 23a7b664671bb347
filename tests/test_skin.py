"""Light scattered under the skin (viewer/gl/skin_pass.py, shaders/skin_scatter.frag.glsl): the
kernel is skin's profile, uniform light stays uniform, a shadow's edge softens on skin (red the
furthest) and nothing off the skin changes, values stay finite under a sun, and the bundle keeps
the skin's share and scale."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from viewer.gl import Engine, EngineOptions
from viewer.gl.skin_pass import SKIN_PROFILE, scatter_kernel
from viewer.scene.area_lights import AreaLights
from viewer.scene.bundle import FrameLayer, Scene, load_scene, save_scene
from viewer.scene.camera import Camera
from viewer.scene.look import Look

SIZE, UP = 48, 4  # work pixels, frame pixels per work pixel


def _scene(split: bool, skin: np.ndarray | None, skin_mm: float = 0.5) -> Scene:
    """A flat square facing the camera (``split``: its left half turned 45 degrees to the left, its
    right half to the right, so a light from the right leaves the left half dark: a step in D at the
    middle column) with a frame layer UP times finer whose skin share is ``skin``."""
    h = w = SIZE
    normal = np.zeros((h, w, 3), np.float32)
    normal[...] = (0.0, 0.0, 1.0)
    if split:
        normal[:, : w // 2] = (-np.sqrt(0.5), 0.0, np.sqrt(0.5))
        normal[:, w // 2:] = (np.sqrt(0.5), 0.0, np.sqrt(0.5))
    mask = np.ones((h, w), bool)
    mask[:2], mask[-2:], mask[:, :2], mask[:, -2:] = False, False, False, False
    albedo = np.repeat(np.where(mask, 0.5, 0.0)[..., None], 3, axis=-1).astype(np.float32)
    up = lambda a: np.repeat(np.repeat(a, UP, axis=0), UP, axis=1)  # noqa: E731
    frame = FrameLayer(albedo=up(albedo), alpha=up(mask.astype(np.float32)), photo=up(albedo),
                       skin=None if skin is None else (skin * up(mask)).astype(np.float32), skin_mm=skin_mm)
    return Scene(albedo=albedo, specular=np.zeros((h, w), np.float32), roughness=np.full((h, w), 0.5, np.float32),
                 normal=normal, depth=np.where(mask, 4.0, 4.0).astype(np.float32), mask=mask,
                 camera=Camera(w, h, focal_mm=400.0), frame=frame).validate()


def _render(ctx, scene, lights, skin=True) -> tuple[np.ndarray, Engine]:
    eng = Engine(ctx, scene, EngineOptions(shadow_resolution=256, shadow_step=1))
    eng.set_lights(lights)
    eng.set_look(Look(background="color", exposure=0.0, skin=skin, shadows="none"))
    eng.render()
    return eng.output.read_output_hdr()[..., :3].copy(), eng


def test_the_kernel_is_skins_profile():
    """Each channel sums to 1, the kernel is symmetric, red reaches furthest and blue least."""
    offsets, weights = scatter_kernel()
    assert np.allclose(weights.sum(axis=0), 1.0, atol=1e-6) and (weights >= 0).all()
    np.testing.assert_allclose(offsets, -offsets[::-1], atol=1e-6)
    np.testing.assert_allclose(weights, weights[::-1], atol=1e-7)
    spread = (weights * offsets[:, None] ** 2).sum(axis=0)  # mm^2, each channel's variance
    assert spread[0] > 3 * spread[1] > 3 * spread[2]
    red = sum(v * rgb[0] for v, rgb in SKIN_PROFILE)  # the profile's own red variance
    assert spread[0] == pytest.approx(red, rel=0.15)


def test_uniform_light_on_skin_stays_uniform(ctx):
    """A flat square all skin under one frontal light: scattering moves light between equal pixels,
    so the picture is the one without it."""
    lights = AreaLights(np.array([[0.0, 0.0, 1.0]], np.float32), np.array([1.0], np.float32), np.ones((1, 3), np.float32))
    scene = _scene(False, np.ones((SIZE * UP, SIZE * UP), np.float32))
    on, eng = _render(ctx, scene, lights, True)
    assert eng.kit.counters["skin_scatter"] == 1
    eng.release()
    off, eng = _render(ctx, scene, lights, False)
    eng.release()
    inner = slice(4 * UP, -4 * UP)
    np.testing.assert_allclose(on[inner, inner], off[inner, inner], rtol=1e-4)


def test_an_edge_softens_on_skin_red_furthest_and_nothing_off_skin_changes(ctx):
    """The split square lit from the right: a step in the light at the middle column. With skin on
    its top half, the top's step is softened (light reaches into the dark side, red further than
    blue), the bottom half (no skin) is exactly the picture without scattering, and the light's
    total over each skin row is kept."""
    n = SIZE * UP
    skin = np.zeros((n, n), np.float32)
    skin[: n // 2] = 1.0
    lights = AreaLights(np.array([[1.0, 0.0, 0.2]], np.float32) / np.float32(np.sqrt(1.04)), np.array([0.5], np.float32),
                        np.full((1, 3), 3.0, np.float32))
    scene = _scene(True, skin, skin_mm=0.5)  # 0.5 mm a frame pixel: red's widest Gaussian is 5.4 pixels
    on, eng = _render(ctx, scene, lights, True)
    eng.release()
    off, eng = _render(ctx, scene, lights, False)
    eng.release()
    bottom = slice(n // 2 + 2 * UP, n - 3 * UP)
    np.testing.assert_array_equal(on[bottom], off[bottom])
    row = n // 4
    middle = n // 2
    dark = off[row, middle - 3 * UP: middle - 2]  # the unlit side near the step: nothing without scattering
    assert dark.max() < 1e-3 * off[row].max()
    lit_in = on[row, middle - 3 * UP: middle - 2]
    assert lit_in[:, 0].sum() > 0.02 * off[row, middle + 2 * UP].sum()  # red scattered into the dark side
    assert lit_in[:, 0].sum() > 3 * lit_in[:, 2].sum()  # red further than blue
    cols = slice(3 * UP, n - 3 * UP)
    assert on[row, cols].sum(axis=0) == pytest.approx(off[row, cols].sum(axis=0), rel=0.02)


def test_a_sun_stays_finite(ctx):
    """1e5 times brighter than a sky: the scattered light is finite and bounded by the brightest unscattered pixel."""
    n = SIZE * UP
    lights = AreaLights(np.array([[np.sqrt(0.5), 0.0, np.sqrt(0.5)], [0.0, 0.0, 1.0]], np.float32), np.array([0.0, 20.0], np.float32),
                        np.array([[1e5, 1e5, 1e5], [1.0, 1.0, 1.0]], np.float32))
    scene = _scene(True, np.ones((n, n), np.float32))
    on, eng = _render(ctx, scene, lights, True)
    eng.release()
    off, eng = _render(ctx, scene, lights, False)
    eng.release()
    assert np.isfinite(on).all() and on.max() <= off.max() * (1 + 1e-4) and on.min() >= 0


def test_switching_skin_redoes_only_the_scatter_and_the_frame(ctx):
    n = SIZE * UP
    lights = AreaLights(np.array([[0.0, 0.0, 1.0]], np.float32), np.array([1.0], np.float32), np.ones((1, 3), np.float32))
    _, eng = _render(ctx, _scene(True, np.ones((n, n), np.float32)), lights, True)

    def delta(**look):
        start = dict(eng.kit.counters)
        eng.set_look(eng.look.replace(**look))
        eng.render()
        return {k: v - start.get(k, 0) for k, v in eng.kit.counters.items() if v - start.get(k, 0)}

    assert delta(skin=False) == {"frame_composite": 1}  # D as it is: nothing to scatter
    assert delta(exposure=1.0) == {"frame_composite": 1}
    assert delta(skin=True) == {"skin_scatter": 1, "frame_composite": 1}
    eng.release()


def test_a_frame_without_skin_or_too_small_has_no_scatter(ctx):
    lights = AreaLights(np.array([[0.0, 0.0, 1.0]], np.float32), np.array([1.0], np.float32), np.ones((1, 3), np.float32))
    n = SIZE * UP
    for scene in (_scene(False, None), _scene(False, np.zeros((n, n), np.float32)),
                  _scene(False, np.ones((n, n), np.float32), skin_mm=10.0)):  # 2.7 mm is a quarter of a pixel
        _, eng = _render(ctx, scene, lights, True)
        assert eng.picture.scatter is None and "skin_scatter" not in eng.kit.counters
        eng.release()


def test_the_bundle_keeps_the_skin(tmp_path):
    n = SIZE * UP
    skin = np.tile(np.linspace(0, 1, n, dtype=np.float32), (n, 1))
    scene = _scene(False, skin, skin_mm=1.25)
    loaded = load_scene(save_scene(scene, tmp_path / "b"))
    assert loaded.frame.skin_mm == 1.25
    assert np.abs(loaded.frame.skin - scene.frame.skin).max() <= 1 / 255 + 1e-6
    plain = load_scene(save_scene(replace(scene, frame=replace(scene.frame, skin=None, skin_mm=0.0)), tmp_path / "c"))
    assert plain.frame.skin is None and plain.frame.skin_mm == 0.0


def test_a_bad_skin_map_is_one_line_naming_it(tmp_path):
    """A frame_skin.png of another size than the frame: one InputError naming the file."""
    from PIL import Image

    from viewer.errors import InputError

    n = SIZE * UP
    bundle = save_scene(_scene(False, np.ones((n, n), np.float32)), tmp_path / "b")
    Image.fromarray(np.zeros((n // 2, n), np.uint8)).save(bundle / "frame_skin.png")
    with pytest.raises(InputError) as err:
        load_scene(bundle)
    assert "frame_skin.png" in str(err.value) and "does not match" in str(err.value)
