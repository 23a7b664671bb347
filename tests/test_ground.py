"""The ground shadow (Look.ground, viewer/gl/ground_pass.py): the person's shadow on a level ground
at the feet darkens the background where the person blocks the light, and only there; it runs
only while shown and only when the lights change."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from viewer.gl import Engine, EngineOptions
from viewer.lights import AreaLights
from viewer.resources import sample_scene_dir
from viewer.scene import FrameLayer, load_scene
from viewer.scene_ops import resample_scene
from viewer.settings import Look

SUN = np.array([0.5, 0.6, 0.45]) / np.linalg.norm([0.5, 0.6, 0.45])  # above, right, in front


@pytest.fixture(scope="module")
def person():
    return resample_scene(load_scene(sample_scene_dir()), 128)


def sun_and_sky(sigma: float = 1.0) -> AreaLights:
    return AreaLights(np.array([SUN, [0.0, 1.0, 0.0]]), np.array([sigma, 12.0]), np.array([[6.0, 6.0, 6.0], [0.4, 0.45, 0.6]]))


def engine(ctx, scene, lights, **look):
    eng = Engine(ctx, scene, EngineOptions(shadow_resolution=256))
    eng.set_lights(lights)
    eng.set_look(Look(background="color", background_color=(0.5, 0.5, 0.5), **look))
    eng.render()
    return eng


def test_the_shadow_falls_away_from_the_sun_on_the_background_only(ctx, person):
    off = engine(ctx, person, sun_and_sky())
    before = off.read_display().astype(int)
    assert off.counters["ground_shadow"] == 0  # left out while not shown
    off.release()
    eng = engine(ctx, person, sun_and_sky(), ground=True)
    after = eng.read_display().astype(int)
    occ = eng.read_ground_shadow()
    assert occ.shape == (64, 64, 3) and np.all(np.isfinite(occ)) and occ.min() >= 0.0 and occ.max() <= 1.0 + 1e-6
    assert occ.max() > 0.5  # the sun is most of the ground's light
    mask = person.mask
    assert np.array_equal(after[mask], before[mask])  # the person is not the ground
    darker = (before - after).max(axis=-1) > 8
    assert darker[~mask].sum() > 50
    rows, cols = np.nonzero(darker & ~mask)
    feet_row = np.nonzero(mask.any(axis=1))[0].max()
    feet_col = np.nonzero(mask[feet_row])[0].mean()
    assert rows.min() > person.height // 2  # on the ground, below the horizon
    assert cols.mean() < feet_col  # the sun is on the right: the shadow goes left
    assert np.all(after[: person.height // 2] == before[: person.height // 2])  # nothing above the horizon changes
    eng.release()


def test_lights_below_the_ground_cast_nothing_on_it(ctx, person):
    under = AreaLights(np.array([[0.3, -0.5, 0.8]]) / np.linalg.norm([0.3, -0.5, 0.8]), np.array([1.0]), np.array([[3.0, 3.0, 3.0]]))
    eng = engine(ctx, person, under, ground=True)
    assert np.all(eng.read_ground_shadow() == 0.0)
    eng.release()


def test_a_larger_light_softens_the_shadow_on_the_ground(ctx, person):
    def partial(sigma):
        eng = engine(ctx, person, AreaLights(SUN[None], np.array([sigma]), np.array([[5.0, 5.0, 5.0]])), ground=True)
        occ = eng.read_ground_shadow()[..., 0]
        eng.release()
        return ((occ > 0.05) & (occ < 0.95)).sum() / max((occ > 0.05).sum(), 1)

    assert partial(12.0) > partial(0.0) + 0.1


def test_the_ground_is_redone_only_when_the_lights_change(ctx, person):
    eng = engine(ctx, person, sun_and_sky(), ground=True)

    def runs(action):
        start = eng.counters["ground_shadow"]
        action()
        eng.render()
        return eng.counters["ground_shadow"] - start

    assert runs(lambda: eng.set_display(exposure=1.0)) == 0
    assert runs(lambda: eng.set_lights(sun_and_sky().scaled(2.0))) == 1
    assert runs(lambda: eng.set_lights(sun_and_sky(4.0))) == 1
    assert runs(lambda: eng.set_look(eng.look.replace(ground=False))) == 0
    assert runs(lambda: eng.set_lights(sun_and_sky().rotated(30.0))) == 0  # stale, but not shown
    assert runs(lambda: eng.set_look(eng.look.replace(ground=True))) == 1
    eng.set_look(eng.look.replace(shadows="none"))
    eng.render()
    assert np.all(eng.read_ground_shadow() == 0.0)  # no shadows shown: none on the ground either
    eng.release()


def test_a_photo_frame_and_its_exr_carry_the_ground_shadow(ctx, person):
    up = lambda a: np.repeat(np.repeat(a, 2, axis=0), 2, axis=1)  # noqa: E731
    photo = np.full(up(person.albedo).shape, 0.4, np.float32)
    sc = replace(person, frame=FrameLayer(albedo=up(person.albedo), alpha=up(person.mask.astype(np.float32)), photo=photo))
    out = {}
    for ground in (False, True):
        eng = engine(ctx, sc, sun_and_sky(), ground=ground, compare=0.0)
        eng.set_look(eng.look.replace(background="photo"))
        eng.render()
        out[ground] = (eng.read_display().astype(int), eng.read_output_hdr()[..., :3])
        eng.release()
    (d0, h0), (d1, h1) = out[False], out[True]
    matte = up(person.mask)
    assert np.array_equal(d1[matte], d0[matte])
    assert ((d0 - d1).max(axis=-1) > 8)[~matte].sum() > 200
    assert np.all(h1 <= h0 + 1e-6) and (h0 - h1).max() > 0.1  # the EXR: the photo's background darkened


def test_the_ground_shadow_against_mitsuba(tmp_path):
    """relight bench ground at a small size: the ray-traced ground under a low sun and under the
    bundled map; contact-hardening soft shadows are closer to it than hard ones, within bounds."""
    from viewer.lab.bench.ground import run_ground_benchmark

    rows = run_ground_benchmark(str(tmp_path / "ground.json"), size=128, spp=32, repeats=1)["rows"]
    err = {(r["lighting"], r["method"]): r["mae"] for r in rows}
    for lighting, bound in (("low sun", 0.2), ("mountain map", 0.06)):
        assert err[(lighting, "pcss")] < err[(lighting, "hard")]
        assert err[(lighting, "pcss")] < bound
    assert all(r["shadow_pixels_truth"] > 50 and r["shadow_pixels_engine"] > 50 for r in rows)
    assert (tmp_path / "ground.json").is_file()
