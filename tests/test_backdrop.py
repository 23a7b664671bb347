"""The backdrop behind the relit person (viewer/scene/backdrop.py, shaders/envmap.glsl): the photo's own
background defocus is measured, the map is blurred by an angle on the sphere, and a map magnified
in a large frame shows no texel's square or crease."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from test_ground import person  # noqa: F401  (the sample person at 128 px, a fixture)

from viewer.errors import InputError
from viewer.gl import Engine, EngineOptions
from viewer.scene.area_lights import AreaLights
from viewer.scene.backdrop import blurred_map, photo_blur
from viewer.scene.bundle import FrameLayer
from viewer.scene.look import Look


def _checker_photo(blur: float):
    """A checkerboard background behind a person-sized box, the background blurred by ``blur`` px."""
    yy, xx = np.mgrid[:600, :600]
    img = np.full((600, 600, 3), 40, np.uint8)
    img[((yy // 40 + xx // 40) % 2) == 0] = 200
    if blur:
        img = cv2.GaussianBlur(img, (0, 0), blur)
    alpha = np.zeros((600, 600), np.float32)
    alpha[300:590, 250:350] = 1.0
    return img, alpha


@pytest.mark.parametrize("blur", [2.0, 4.0, 8.0])
def test_the_photos_background_defocus_is_measured(blur):
    img, alpha = _checker_photo(blur)
    assert abs(photo_blur(img, alpha) - blur) < 0.25 * blur
    sharp, _ = _checker_photo(0.0)
    assert photo_blur(sharp, alpha) < 1.0
    assert photo_blur(np.full((600, 600, 3), 90, np.uint8), alpha) == 0.0  # a plain wall: nothing to tell


def test_a_map_blurred_by_an_angle():
    rng = np.random.default_rng(3)
    env = rng.random((64, 128, 3)).astype(np.float32)
    assert blurred_map(env, 0.0) is env
    soft = blurred_map(env, math.radians(10.0))
    assert soft.shape == env.shape and np.isfinite(soft).all()
    assert abs(float(soft.mean()) - float(env.mean())) < 0.01 and soft.std() < 0.5 * env.std()
    seam = np.abs(soft[:, 0] - soft[:, -1]).mean()  # longitude wraps around: no seam at the map's edge
    assert seam < np.abs(np.diff(soft, axis=1)).mean() * 3
    huge = blurred_map(env, 10.0)  # beyond the bound: the bound's blur, still finite
    assert np.isfinite(huge).all() and huge.std() < soft.std()


def _background_row(ctx, scene, env, **look):
    eng = Engine(ctx, scene, EngineOptions(shadow_resolution=64))
    eng.set_lights(AreaLights(np.array([[0.0, 1.0, 0.0]]), np.array([4.0]), np.array([[1.0, 1.0, 1.0]])))
    eng.set_environment(env)
    eng.set_look(Look(exposure=0.0, tonemap="clamp", **look))
    eng.render()
    image = eng.output.read_display().astype(np.float32)
    eng.release()
    return image


def test_a_magnified_map_shows_no_texel_square(ctx, person):  # noqa: F811
    """A 16 x 8 map behind a 128-px person (a texel spans many pixels): the background's slope
    changes smoothly (a B-spline), where a bilinear lookup would crease at every texel edge."""
    env = np.zeros((8, 16, 3), np.float32)
    env[:, ::2] = 0.8
    empty = int(np.flatnonzero(~person.mask.any(axis=1))[0])  # a row above the person: background only
    row = _background_row(ctx, person, env, backdrop_blur=0.0)[empty, :, 0]
    slope = np.diff(row)
    crease = np.abs(np.diff(slope))
    assert np.abs(slope).max() > 0.5  # the stripes do show
    assert crease.max() <= 0.5 * np.abs(slope).max()


def test_the_backdrop_blur_softens_the_map_and_not_the_person(ctx, person):  # noqa: F811
    h, w = 32, 64
    env = np.zeros((h, w, 3), np.float32)
    env[:, ::4] = 1.0
    sharp = _background_row(ctx, person, env, backdrop_blur=0.0)
    soft = _background_row(ctx, person, env, backdrop_blur=20.0)
    m = person.mask
    assert np.array_equal(sharp[m], soft[m])
    assert soft[~m].std() < 0.7 * sharp[~m].std()
    up = lambda a: np.repeat(np.repeat(a, 2, axis=0), 2, axis=1)  # noqa: E731
    frame = FrameLayer(albedo=up(person.albedo), alpha=up(m.astype(np.float32)),
                                       photo=np.full(up(person.albedo).shape, 0.3, np.float32),
                                       background_blur=math.radians(20.0))
    from dataclasses import replace

    framed = replace(person, frame=frame)
    auto = _background_row(ctx, framed, env)  # "auto": the photo's own background blur
    twenty = _background_row(ctx, framed, env, backdrop_blur=20.0)
    assert np.abs(auto.astype(int) - twenty.astype(int)).max() <= 1
    with pytest.raises(InputError, match="backdrop blur"):
        Look(backdrop_blur=-1.0)
