"""Each area light's size from its part of the map (viewer.lighting.light_size): a Gaussian light
gives back its own sigma, the studio map's lamp keeps its width, a sun stays sharp, and odd inputs
(empty cells, black and uniform maps, stacked lights) give finite sizes in range."""

import numpy as np
import pytest
from conftest import SHARED_DATA
from hypothesis import given, settings, strategies as st

from viewer.lab.bench.contact import gaussian_light
from viewer.lighting.envmap import EnvMap, load_envmap, pixel_directions
from viewer.lighting.light_size import SIGMA_MAX, region_sizes
from viewer.lighting.lightfit.fit import fit_lights
from viewer.lighting.median_cut import median_cut_lights
from viewer.scene.shadow_space import ANGULAR_SIGMA

HDRI = SHARED_DATA / "hdri"
TOWARDS = np.array([0.5, 0.6, 0.62]) / np.linalg.norm([0.5, 0.6, 0.62])


@pytest.mark.parametrize("sigma", [1.0, 3.0, 8.0])
def test_a_gaussian_light_gets_its_own_sigma_back(sigma):
    env = gaussian_light(sigma * ANGULAR_SIGMA, direction=TOWARDS)
    size = region_sizes(env, np.stack([TOWARDS, -TOWARDS]))
    assert size[0] == pytest.approx(sigma, rel=0.08)


def test_a_disc_keeps_its_width_whatever_the_dim_room_around_it():
    """A lamp 3 degrees in radius, the room 1e-4 as bright (5 % of the lamp's cell's energy, spread over
    a third of the sphere): the lamp's light is sized by the lamp, not by the room."""
    d = pixel_directions(512, 1024)
    lamp = np.degrees(np.arccos(np.clip(d @ TOWARDS, -1, 1))) < 3.0
    px = np.where(lamp[..., None], 1e4, 1.0).astype(np.float32) * np.ones(3, np.float32)
    size = region_sizes(EnvMap(px), np.stack([TOWARDS, -TOWARDS, [0.0, -1.0, 0.0]]))
    r50 = np.radians(3.0) / np.sqrt(2.0)  # half a uniform disc's area lies within R / sqrt(2)
    assert size[0] == pytest.approx(r50 / np.sqrt(2 * np.log(2)) / ANGULAR_SIGMA, rel=0.12)
    assert size[1] > 10 * size[0]  # the rest of the room: a broad, soft light


def test_the_studio_lamp_and_a_sun():
    """The issue's case: the studio map's lamp (2.6 degrees) was fitted as point lights; now every
    light on it has a size, most smaller than the whole lamp's; the park's sun stays the sharpest."""
    studio = load_envmap(HDRI / "studio_small_03_1k.hdr")
    lights = fit_lights(studio, 16, "instant")
    lum = studio.pixels @ np.array([0.2126, 0.7152, 0.0722])
    lamp = pixel_directions(*lum.shape)[np.unravel_index(lum.argmax(), lum.shape)]
    on_lamp = np.degrees(np.arccos(np.clip(lights.direction @ lamp, -1, 1))) < 6.0
    whole = region_sizes(studio, np.stack([lamp, -lamp]))[0]
    assert on_lamp.sum() >= 3 and 0.5 < whole < 1.5
    assert (lights.sigma[on_lamp] > 0.05).all() and 0.2 < np.median(lights.sigma[on_lamp]) < whole
    assert lights.sigma[on_lamp].max() < 1.5 * whole  # a light at the lamp's edge also owns some of the room
    park = load_envmap(HDRI / "rooitou_park_1k.hdr")
    lights = fit_lights(park, 16, "instant")
    sun = int(np.argmax(lights.intensity.sum(axis=1)))
    assert lights.sigma[sun] < 0.5 and lights.sigma[sun] == lights.sigma.min()


def test_median_cut_regions_are_sized_the_same_way():
    env = gaussian_light(4.0 * ANGULAR_SIGMA, width=256, direction=TOWARDS)
    lights = median_cut_lights(env, 1)
    assert lights.sigma[0] == pytest.approx(4.0, rel=0.1)


def test_odd_cases():
    d = np.array([[0.0, 1.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    black = EnvMap(np.zeros((16, 32, 3), np.float32))
    assert (region_sizes(black, d) == 0).all()
    uniform = EnvMap(np.ones((16, 32, 3), np.float32))
    sizes = region_sizes(uniform, d)
    assert sizes[1] == sizes[0] > 0  # the second of two stacked lights owns no texel: the first's size
    assert region_sizes(uniform, d[:1])[0] == SIGMA_MAX  # one light for the whole sky: as soft as they get


def test_a_light_that_owns_one_texel_is_a_texel_wide():
    """A one-texel sun on a 256-wide map (1.4 degrees a texel) is not a point: about a texel's
    spread (1.4 / sqrt(12) degrees), above the engine's hard-shadow threshold."""
    px = np.full((128, 256, 3), 1e-3, np.float32)
    px[40, 100] = 1e6
    sun = pixel_directions(128, 256)[40, 100]
    size = region_sizes(EnvMap(px), np.stack([sun, -sun]))[0]
    texel = np.radians(360.0 / 256) * np.cos(np.radians(90 - 180 * 40.5 / 128)) ** 0.5 / np.sqrt(12)
    assert size == pytest.approx(texel / ANGULAR_SIGMA, rel=0.25) and size > 0.05


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 40), h=st.sampled_from([2, 4, 16, 64]))
def test_sizes_are_finite_and_in_range(seed, n, h):
    rng = np.random.default_rng(seed)
    px = (rng.pareto(1.0, (h, 2 * h, 3)) * rng.choice([0.0, 1.0], (h, 2 * h, 1))).astype(np.float32)
    directions = rng.normal(size=(n, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    sizes = region_sizes(EnvMap(px), directions)
    assert sizes.shape == (n,) and np.isfinite(sizes).all() and (sizes >= 0).all() and (sizes <= SIGMA_MAX).all()


def test_a_light_spread_over_a_cap_has_the_size_the_map_rule_gives():
    """cap_sigma (the photo's own basis lights) is cell_sigma's rule for light spread evenly over a
    cap: measured on a fine grid of the cap's directions, the two agree."""
    import math

    from viewer.lighting.light_size import SIGMA_MAX, cap_sigma, cell_sigma

    radius = math.acos(1.0 - 2.0 / 48)  # the photo lighting's 48 cells
    rng = np.random.default_rng(0)
    z = 1.0 - rng.random(200_000) * (1.0 - math.cos(radius))  # uniform over the cap's solid angle
    phi = rng.random(z.size) * 2 * math.pi
    r = np.sqrt(1 - z * z)
    dirs = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    tiny = np.full(z.size, 1e-12)  # texels too small to add their own width
    assert abs(cell_sigma(dirs, np.ones(z.size), tiny) - cap_sigma(radius)) < 0.02 * cap_sigma(radius)
    assert cap_sigma(math.pi) == SIGMA_MAX and cap_sigma(0.0) == 0.0
