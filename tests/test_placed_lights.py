"""The user's own lights (viewer/lighting/placed_lights.py): directions, colour temperature, rigs as JSON,
undo and redo, and how a session renders them with the map's lights."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from viewer.errors import InputError
from viewer.lighting.placed_lights import (
    MIN_SEPARATION,
    History,
    PlacedLight,
    free_spot,
    kelvin_to_rgb,
    level,
    load_rig,
    rig,
    save_rig,
    to_area_lights,
)
from viewer.scene.shadow_space import ANGULAR_SIGMA


def test_directions_follow_the_light_table():
    assert np.allclose(PlacedLight(0.0, 0.0).direction, [0, 0, 1])  # on the camera's side
    assert np.allclose(PlacedLight(90.0, 0.0).direction, [1, 0, 0])  # the image's right
    assert np.allclose(PlacedLight(0.0, 90.0).direction, [0, 1, 0], atol=1e-12)
    p = PlacedLight.aimed([-0.3, 0.5, -0.8], size=4.0)
    assert np.allclose(p.direction, np.array([-0.3, 0.5, -0.8]) / np.linalg.norm([-0.3, 0.5, -0.8]))


def test_colour_temperature():
    warm, daylight, cold = kelvin_to_rgb(2700.0), kelvin_to_rgb(6500.0), kelvin_to_rgb(10000.0)
    for c in (warm, daylight, cold):
        assert c @ [0.2126, 0.7152, 0.0722] == pytest.approx(1.0) and (c >= 0).all()
    assert warm[0] > warm[1] > warm[2] and cold[2] > cold[1] and cold[2] > cold[0]
    assert np.abs(daylight - 1.0).max() < 0.06  # a 6500 K black body is nearly D65 white


def test_area_lights_of_placed_lights():
    lights = to_area_lights([PlacedLight(30.0, 20.0, 6.0, 2.0, 5000.0)])
    assert lights.sigma[0] == pytest.approx(math.radians(6.0) / ANGULAR_SIGMA)
    assert lights.intensity[0] @ [0.2126, 0.7152, 0.0722] == pytest.approx(2.0, rel=1e-5)
    assert len(to_area_lights([])) == 0


def test_rigs_save_load_and_refuse_bad_files(tmp_path):
    three = rig("three-point", 4.0)
    assert len(three) == 3 and three[0].intensity == 4.0 and three[1].intensity == pytest.approx(1.4)
    path = save_rig(tmp_path / "rig.json", three)
    assert load_rig(path) == three
    bad = tmp_path / "bad.json"
    for content, message in (('{"format": "relight-lights", "lights": []}', "not a rig"),
                             ('{"format": "relight-rig", "lights": [{"azimuth": 10, "kelvin": 50}]}', "kelvin"),
                             ('{"format": "relight-rig", "lights": [{"azimuth": 10, "colour": 1}]}', "light 0"),
                             ("not json", "rig")):
        bad.write_text(content)
        with pytest.raises(InputError, match=message) as info:
            load_rig(bad)
        assert str(bad) in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(InputError, match="unknown rig"):
        rig("spotlight", 1.0)


def test_history_undo_and_redo():
    h, a, b, c = History(), (), (PlacedLight(),), (PlacedLight(), PlacedLight(10.0))
    h.record(a)
    h.record(b)  # now at c
    assert h.undo(c) == b and h.undo(b) == a and h.undo(a) is None
    assert h.redo(a) == b and h.redo(b) == c and h.redo(c) is None
    h.undo(c)
    h.record(b)  # a new change drops the redo stack
    assert h.redo(b) is None


def test_session_renders_placed_lights_fixed_to_the_camera(ctx):
    from viewer.app.session import Session
    from viewer.lab.scenes import plane_and_box
    from viewer.scene.area_lights import AreaLights

    scene = plane_and_box(48)
    env = AreaLights(np.array([[0.0, 0.6, 0.8]]), [2.0], [[1.0, 1.0, 1.0]])
    s = Session(ctx, scene, env, None)
    s.set_placed(rig("key and fill", 1.0))
    s.update(yaw=90.0)
    lights = s.rendered_lights()
    assert len(lights) == 3
    assert np.allclose(lights.direction[1:], [p.direction for p in s.placed], atol=1e-6)  # not turned with the map
    assert not np.allclose(lights.direction[0], env.direction[0])  # the map's light turned
    eng = s.render()
    assert len(eng.lights) == 3 and eng.output.read_hdr().max() > 0
    assert s.undo() and s.placed == () and s.redo() and len(s.placed) == 2
    s.release()
    json.dumps([p.__dict__ for p in s.placed])  # plain values: the state file takes them


def test_your_lights_keep_their_share_when_the_map_changes_and_their_own_intensity(ctx):
    from viewer.app.session import Session
    from viewer.lab.scenes import plane_and_box
    from viewer.scene.area_lights import AreaLights

    bright = AreaLights(np.array([[0.0, 0.6, 0.8]]), [2.0], [[40.0, 40.0, 40.0]])
    dim = AreaLights(np.array([[0.6, 0.6, 0.0], [0.0, 1.0, 0.0]]), [2.0, 4.0], [[0.3, 0.3, 0.3], [0.1, 0.1, 0.1]])
    s = Session(ctx, plane_and_box(32), bright, None)
    assert level(bright) == pytest.approx(10.0, rel=1e-5) and level(dim) == pytest.approx(0.1, rel=1e-5)
    s.set_placed(rig("key", level(bright)))
    s.set_placed(rig("key and rim", level(bright)))
    s.set_lights(dim, new_map=True)  # a dusk map: the key keeps its share of the light, undo with it
    assert s.placed[0].intensity == pytest.approx(level(dim), rel=1e-5)
    assert s.undo() and s.placed[0].intensity == pytest.approx(level(dim), rel=1e-5)
    s.keep_absolute = True
    s.set_lights(bright, new_map=True)
    assert s.placed[0].intensity == pytest.approx(level(dim), rel=1e-5)  # kept as it was
    # the map's intensity and yours are two controls: the map's at 0 leaves your key lit
    s.update(intensity=0.0, placed_intensity=2.0)
    lights = s.rendered_lights()
    assert np.all(lights.intensity[:1] == 0.0)
    assert lights.intensity[1] @ [0.2126, 0.7152, 0.0722] == pytest.approx(2.0 * level(dim), rel=1e-4)
    s.release()


def test_new_lights_do_not_land_on_the_ones_already_placed():
    placed = ()
    for _ in range(8):
        azimuth, elevation = free_spot(placed)
        new = PlacedLight(azimuth, elevation)
        for p in placed:
            angle = np.degrees(np.arccos(np.clip(p.direction @ new.direction, -1.0, 1.0)))
            assert angle >= MIN_SEPARATION
        placed += (new,)
    # a light the user moved near a spot: that spot is skipped
    assert free_spot((PlacedLight(50.0, 25.0),)) == (-45.0, 30.0)


def test_image_pixel_under_the_cursor():
    from viewer.app.interaction import image_pixel

    rect = (100.0, 50.0, 200.0, 400.0)  # the image drawn 200 x 400 at (100, 50)
    assert image_pixel((100.0, 50.0), rect, (64, 128)) == (0, 0)
    assert image_pixel((299.9, 449.9), rect, (64, 128)) == (63, 127)
    assert image_pixel((200.0, 250.0), rect, (64, 128)) == (32, 64)
    assert image_pixel((99.0, 60.0), rect, (64, 128)) is None and image_pixel((150.0, 450.0), rect, (64, 128)) is None


def test_the_map_thumbnail_maps_points_and_directions_both_ways():
    """The thumbnail's point of a light and the light aimed from that point agree under any turn of
    the lighting, and the point shows what the map turned by the yaw shows there."""
    from viewer.app.thumbnail import MapThumbnail
    from viewer.lighting.envmap import EnvMap

    rng = np.random.default_rng(5)
    d = rng.normal(size=(50, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    for yaw, tilt in ((0.0, 0.0), (37.0, 0.0), (-120.0, 25.0)):
        uv = MapThumbnail.points(d, yaw, tilt)
        assert uv.min() >= 0.0 and uv.max() <= 1.0
        back = np.array([MapThumbnail.direction_at(u, v, yaw, tilt) for u, v in uv])
        np.testing.assert_allclose(back, d, atol=1e-9)
    # with no tilt the picture (the map shifted by uv_range) is EnvMap.rotated(yaw)
    env = EnvMap(rng.random((8, 16, 3)).astype(np.float32))
    (u0, _), _ = MapThumbnail.uv_range(90.0)
    column = int(round(u0 * 16))
    np.testing.assert_array_equal(np.roll(env.pixels, -column, axis=1), env.rotated(90.0).pixels)


def test_the_map_thumbnail_is_made_without_the_exact_downsample():
    """The panel's picture of a map is block means (made on the fit's thread): what the exact
    solid-angle downsample shows, to a few levels of 255, a 1e5 sun kept a bright disc."""
    from viewer.app.thumbnail import WIDTH, map_thumbnail, thumbnail_pixels
    from viewer.lighting.envmap import EnvMap, load_envmap
    from viewer.resources import asset_dir

    env = load_envmap(asset_dir() / "envmaps" / "studio_small_03_256.hdr")
    big = EnvMap(np.repeat(np.repeat(env.pixels, 4, axis=0), 4, axis=1))  # 1024 x 512
    quick, exact = map_thumbnail(big), thumbnail_pixels(big.downsampled(WIDTH))
    assert quick.shape == exact.shape == (WIDTH // 2, WIDTH, 3)
    assert np.abs(quick.astype(int) - exact).mean() < 2.0
    sun = big.pixels.copy()
    sun[100:104, 500:504] = 1e5 * sun.mean()
    pic = map_thumbnail(EnvMap(sun))
    assert pic[25, 125].min() > 240 and np.median(pic) < 200
    for h in (500, 383, 129, 1):  # sizes blocks do not divide: still a 2:1 picture
        odd = map_thumbnail(EnvMap(np.full((h, 2 * h, 3), 0.5, np.float32)))
        assert odd.shape[1] == 2 * odd.shape[0] and WIDTH <= odd.shape[1] < 2 * WIDTH + 2 or h < WIDTH // 2
