"""Procedural environment maps for training (viewer/lab/data/envmaps.py)."""

from __future__ import annotations

import numpy as np
import pytest

from viewer.lab.data.envmaps import KINDS, interior, key_light, outdoor, overcast, random_map, sky, studio
from viewer.lighting.envmap import pixel_directions, solid_angles
from viewer.lighting.median_cut import median_cut_lights


def test_same_seed_same_map_bit_for_bit():
    for seed in (0, 1, 7):
        a, b = random_map(seed, 64), random_map(seed, 64)
        assert a.kind == b.kind and np.array_equal(a.env.pixels, b.env.pixels)
    assert not np.array_equal(random_map(0, 64).env.pixels, random_map(1, 64).env.pixels)
    assert {random_map(s, 32).kind for s in range(30)} == set(KINDS)


@pytest.mark.parametrize("kind", [sky, outdoor])
@pytest.mark.parametrize("seed", range(6))
def test_sun_keeps_its_energy_and_place(seed, kind):
    m = kind(np.random.default_rng(seed), 128)
    sun = m.emitters[0]
    px = m.env.pixels.astype(np.float64)
    assert np.isfinite(px).all() and (px >= 0).all()
    # the sun's energy is all there: the map's energy = sky + sun
    h, w = px.shape[:2]
    omega = solid_angles(h, w)
    d = pixel_directions(h, w)
    near = d @ sun.direction >= np.cos(sun.radius + 2 * np.pi / w * 2)
    sun_energy = (px * near[..., None] * omega[:, None, None]).sum(axis=(0, 1))
    assert sun_energy == pytest.approx(sun.energy, rel=0.05)  # (plus the sky around it: small next to a sun)
    # and its brightest texel is within the sun's radius (plus a texel) of its direction
    i, j = np.unravel_index(np.argmax(px.sum(-1)), px.shape[:2])
    angle = np.degrees(np.arccos(np.clip(d[i, j] @ sun.direction, -1, 1)))
    assert angle <= np.degrees(sun.radius) + 360.0 / w


def test_tiny_sun_is_not_lost():
    rng = np.random.default_rng(3)
    for _ in range(20):
        m = sky(rng, 32)  # 11-degree texels: suns of 0.25-8 degrees are often below a sub-texel
        sun = m.emitters[0]
        assert m.env.energy().max() >= 0.99 * sun.energy.max()


def test_studio_and_overcast():
    st = studio(np.random.default_rng(5), 128)
    assert 2 <= len(st.emitters) <= 4
    lights = median_cut_lights(st.env, 8)
    strongest = lights.direction[np.argmax(lights.intensity.sum(1))]
    assert max(float(strongest @ e.direction) for e in st.emitters) > np.cos(np.radians(25))
    oc = overcast(np.random.default_rng(2), 128).env.pixels
    zenith, horizon = oc[0].mean(axis=0), oc[31].mean(axis=0)  # row 0: at the zenith; row 31: just above the horizon
    assert zenith / horizon == pytest.approx(np.full(3, 3.0), rel=0.06)  # CIE overcast: 3x brighter at the zenith
    assert oc[32:].max() < oc[31].min()  # the ground is dimmer than the sky


def test_outdoor_skyline_and_interior_windows():
    for seed in range(4):
        m = outdoor(np.random.default_rng(seed), 128)
        px = m.env.pixels
        assert np.isfinite(px).all() and (px >= 0).all()
        # the surroundings hide part of the sky just above the horizon: that band is not one gradient
        band = px[56:63].mean(axis=-1)  # rows 56-62: elevations 5-17 degrees
        assert band.std(axis=1).max() > 0.05 * band.mean()
        room = interior(np.random.default_rng(seed), 128)
        assert 1 <= len(room.emitters) <= 7 and np.isfinite(room.env.pixels).all()
        lights = median_cut_lights(room.env, 8)
        strongest = lights.direction[np.argmax(lights.intensity.sum(1))]
        assert max(float(strongest @ e.direction) for e in room.emitters) > np.cos(np.radians(30))


def test_suns_sit_low_more_often_than_high():
    elevations = [np.degrees(np.arcsin(sky(np.random.default_rng(s), 32).emitters[0].direction[1])) for s in range(200)]
    assert 3.0 <= min(elevations) and max(elevations) <= 75.0
    assert np.median(elevations) < 30.0 and np.mean(np.array(elevations) < 15.0) > 0.25


def test_the_outdoor_sun_is_never_behind_the_skyline():
    for seed in range(60):  # before the rule, 22 of 60 suns were drawn on a facade or a tree
        m = outdoor(np.random.default_rng(seed), 64)
        d = m.emitters[0].direction
        azimuth = np.arctan2(d[0], -d[2])
        assert np.arcsin(d[1]) - m.emitters[0].radius >= m.skyline(np.array([azimuth]))[0]


def test_key_lights_stand_where_a_photographer_puts_them():
    """The held-out key-light kind: a key 30-80 degrees off the camera's axis and 10-45 degrees up,
    a rim behind on the other side in about half the maps, nothing else (no fill), energy exact."""
    kinds = []
    for seed in range(24):
        m = key_light(np.random.default_rng(seed), 128)
        kinds.append(m.kind)
        key = m.emitters[0]
        towards_camera = np.array([0.0, 0.0, 1.0])
        flat = key.direction * [1, 0, 1] / np.linalg.norm(key.direction * [1, 0, 1])
        assert 30 - 1e-6 <= np.degrees(np.arccos(flat @ towards_camera)) <= 80 + 1e-6
        assert 10 - 1e-6 <= np.degrees(np.arcsin(key.direction[1])) <= 45 + 1e-6
        px = m.env.pixels.astype(np.float64)
        h, w = px.shape[:2]
        d = pixel_directions(h, w)
        near = np.zeros((h, w), bool)
        for e in m.emitters:
            near |= d @ e.direction >= np.cos(e.radius + 2 * np.pi / w * 2)
        assert px[~near].max() == 0.0  # no fill
        energy = (px * solid_angles(h, w)[:, None, None]).sum(axis=(0, 1))
        assert energy == pytest.approx(sum(e.energy for e in m.emitters), rel=1e-4)
        if m.kind == "key_rim":
            rim = m.emitters[1]
            assert rim.direction[2] < 0 and np.sign(rim.direction[0]) == -np.sign(key.direction[0])
    assert 6 <= kinds.count("key_rim") <= 18 and kinds.count("key") + kinds.count("key_rim") == 24
