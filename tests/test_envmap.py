"""Environment maps (viewer.lighting.envmap) and median-cut area lights (viewer.lighting.median_cut)."""

from pathlib import Path

import numpy as np
import pytest

from viewer.errors import InputError
from viewer.files.imageio import write_exr
from viewer.lighting.envmap import (
    EnvMap,
    direction_to_uv,
    load_envmap,
    pixel_directions,
    save_envmap,
    solid_angles,
)
from viewer.lighting.median_cut import median_cut_lights
from viewer.resources import asset_dir
from viewer.scene.area_lights import load_lights, rotation_matrix

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"
HORN = SHARED / "hdri" / "immenstadter_horn_1k.hdr"
BUNDLED = asset_dir() / "envmaps" / "immenstadter_horn_256"


def random_normals(n=100, seed=0):
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def irradiance_lights(lights, normals):
    """(N, 3) Lambert irradiance sum_l max(0, n.l) I_l."""
    return np.clip(normals @ lights.direction.T.astype(np.float64), 0, None) @ lights.intensity.astype(np.float64)


def irradiance_map(env, normals):
    """(N, 3) exact texel integral sum_texels L max(0, n.d) solid angle."""
    h, w = env.height, env.width
    dirs = pixel_directions(h, w).reshape(-1, 3)
    flux = (env.pixels.astype(np.float64) * solid_angles(h, w)[:, None, None]).reshape(-1, 3)
    return np.clip(normals @ dirs.T, 0, None) @ flux


def relative_error(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def spot_map(h, i, j, value=1e4, background=1e-3):
    px = np.full((h, 2 * h, 3), background, np.float32)
    px[i, j] = value
    return EnvMap(px, "spot")


@pytest.fixture(scope="module")
def horn():
    if not HORN.is_file():
        pytest.skip(f"shared data not found: {HORN}")
    return load_envmap(HORN)


# ----------------------------------------------------------------- directions
def test_known_directions():
    uv = direction_to_uv([[0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 0, 1], [0, 1, 0], [0, -1, 0]])
    np.testing.assert_allclose(uv[:4], [[0.5, 0.5], [0.75, 0.5], [0.25, 0.5], [0.0, 0.5]], atol=1e-12)
    np.testing.assert_allclose(uv[4:, 1], [0.0, 1.0], atol=1e-12)  # the poles (any u)
    h, w = 64, 128
    d = pixel_directions(h, w)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-12)
    # pixels around the image centre look along -z, around u = 3W/4 on the equator along +x
    scale = np.cos(np.pi / (2 * h)) ** 2
    np.testing.assert_allclose(d[h // 2 - 1 : h // 2 + 1, w // 2 - 1 : w // 2 + 1].mean(axis=(0, 1)) / scale, [0, 0, -1], atol=1e-9)
    np.testing.assert_allclose(d[h // 2 - 1 : h // 2 + 1, 3 * w // 4 - 1 : 3 * w // 4 + 1].mean(axis=(0, 1)) / scale, [1, 0, 0], atol=1e-9)
    assert (d[0, :, 1] >= np.cos(np.pi / h)).all() and (d[-1, :, 1] <= -np.cos(np.pi / h)).all()


@pytest.mark.parametrize("h", [4, 64, 512])
def test_pixel_direction_pixel_round_trip(h):
    w = 2 * h
    uv = direction_to_uv(pixel_directions(h, w)) * [w, h]
    jj, ii = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    np.testing.assert_allclose(uv[..., 0], jj, atol=1e-9)
    np.testing.assert_allclose(uv[..., 1], ii, atol=1e-9)


@pytest.mark.parametrize("h", [1, 4, 128, 512])
def test_solid_angles_sum_to_4pi(h):
    omega = solid_angles(h, 2 * h)
    assert omega.shape == (h,) and (omega > 0).all()
    assert omega.sum() * 2 * h == pytest.approx(4 * np.pi, rel=1e-12)
    np.testing.assert_allclose(omega, omega[::-1], rtol=1e-9)


# ----------------------------------------------------------------- resampling
@pytest.mark.parametrize("max_width", [32, 20, 6, 2])
def test_downsample_preserves_energy(max_width):
    env = EnvMap(np.random.default_rng(1).gamma(0.5, 3.0, size=(64, 128, 3)), "random")
    small = env.downsampled(max_width)
    assert small.width == max_width and small.height == max_width // 2
    np.testing.assert_allclose(small.energy(), env.energy(), rtol=1e-6)
    flat = EnvMap(np.full((64, 128, 3), 0.7, np.float32)).downsampled(max_width)  # area averaging
    np.testing.assert_allclose(flat.pixels, 0.7, rtol=1e-6)


def test_downsample_shared_map(horn):
    small = horn.downsampled(256)
    assert small.pixels.shape == (128, 256, 3)
    np.testing.assert_allclose(small.energy(), horn.energy(), rtol=1e-6)
    assert small.downsampled(256) is small


def test_rotation_moves_radiance_from_d_to_R_d():
    h, i, j = 32, 9, 13
    env = spot_map(h, i, j)
    d = pixel_directions(h, 2 * h)[i, j]
    for yaw, tilt in [(360 * 5 / 64, 0.0), (-90.0, 0.0), (33.0, 20.0), (0.0, -50.0)]:
        rotated = env.rotated(yaw, tilt)
        k = np.unravel_index(np.argmax(rotated.pixels[..., 0]), (h, 2 * h))
        angle = np.arccos(np.clip(pixel_directions(h, 2 * h)[k] @ (rotation_matrix(yaw, tilt) @ d), -1, 1))
        assert angle < 1.5 * np.pi / h, (yaw, tilt)
        if tilt == 0.0:  # a yaw by whole texels is an exact column shift
            assert np.array_equal(np.sort(rotated.pixels, axis=None), np.sort(env.pixels, axis=None))


def test_yaw_by_whole_texels_matches_bilinear_resampling():
    env = EnvMap(np.random.default_rng(2).random((16, 32, 3)), "random")
    shifted = env.rotated(360 * 3 / 32)
    resampled = env.rotated(360 * 3 / 32 + 1e-7)  # not a whole shift: the general path
    np.testing.assert_allclose(shifted.pixels, resampled.pixels, atol=1e-4)


def test_rotated_map_gives_rotated_lights(horn):
    env = horn.downsampled(256)
    normals = random_normals()
    lights = median_cut_lights(env, 16)
    for texels in (37, 128, -90):
        yaw = 360.0 * texels / env.width
        from_rotated_map = irradiance_lights(median_cut_lights(env.rotated(yaw), 16), normals)
        rotated_lights = irradiance_lights(lights.rotated(yaw), normals)
        # the brief's bound is 5 %; median cut starts at the darkest column, so whole-texel yaws are exact
        assert relative_error(from_rotated_map, rotated_lights) < 1e-5


# ----------------------------------------------------------------- files and validation
def test_nan_map_is_refused_and_repaired(tmp_path):
    px = np.ones((8, 16, 3), np.float32)
    px[2, 3, 1] = np.nan
    px[5, 7] = np.inf
    path = write_exr(tmp_path / "holes.exr", px)
    with pytest.raises(InputError, match=r"holes\.exr.*2 pixel"):
        load_envmap(path)
    with pytest.warns(UserWarning, match=r"holes\.exr.*2 NaN/Inf"):
        env = load_envmap(path, repair=True)
    assert env.pixels[2, 3, 1] == 0 and (env.pixels[5, 7] == 0).all() and env.pixels.sum() == 8 * 16 * 3 - 4
    assert len(median_cut_lights(env, 4)) == 4


@pytest.mark.parametrize(
    "name, pixels, message",
    [
        ("square.exr", np.ones((8, 8, 3), np.float32), "2:1"),
        ("tall.hdr", np.ones((16, 8, 3), np.float32), "2:1"),
        ("negative.exr", -np.ones((4, 8, 3), np.float32), "negative"),
    ],
)
def test_bad_maps_are_refused(tmp_path, name, pixels, message):
    path = tmp_path / name
    if name.endswith(".exr"):
        write_exr(path, pixels)
    else:
        import cv2

        cv2.imwrite(str(path), pixels)
    with pytest.raises(InputError, match=rf"{name}.*{message}"):
        load_envmap(path)


def test_missing_unreadable_and_unsupported_files(tmp_path):
    with pytest.raises(InputError, match="nothere.hdr.*not found"):
        load_envmap(tmp_path / "nothere.hdr")
    (tmp_path / "garbage.hdr").write_bytes(b"not an image")
    with pytest.raises(InputError, match="garbage.hdr"):
        load_envmap(tmp_path / "garbage.hdr")
    with pytest.raises(InputError, match="map.png.*unsupported"):
        load_envmap(tmp_path / "map.png")


def test_tiny_map_end_to_end(tmp_path):
    px = np.random.default_rng(3).random((4, 8, 3)).astype(np.float32) * 5
    env = load_envmap(save_envmap(tmp_path / "tiny.hdr", EnvMap(px, "tiny")))
    assert env.pixels.shape == (4, 8, 3) and env.source.endswith("tiny.hdr")
    assert (np.abs(env.pixels - px) <= 0.01 * px.max(axis=2, keepdims=True)).all()  # RGBE: a shared exponent
    exr = load_envmap(save_envmap(tmp_path / "tiny.exr", env))
    np.testing.assert_array_equal(exr.pixels, env.pixels)
    for n in (1, 3, 16, 32):
        lights = median_cut_lights(env.rotated(45, 10).downsampled(8), n)
        assert len(lights) == n
        np.testing.assert_allclose(lights.intensity.sum(axis=0), env.rotated(45, 10).energy(), rtol=1e-5)
        assert len(load_lights(lights.save(tmp_path / f"tiny{n}.json"))) == n
    assert len(median_cut_lights(env.downsampled(4), 8)) == 8
    with pytest.raises(InputError, match="33 lights"):
        median_cut_lights(env, 33)


# ----------------------------------------------------------------- median cut
def test_single_bright_texel_gets_one_light_with_nearly_all_energy():
    h, i, j = 64, 20, 90
    env = spot_map(h, i, j)
    lights = median_cut_lights(env, 8)
    share = lights.intensity[:, 1] / lights.intensity[:, 1].sum()
    k = int(np.argmax(share))
    assert share[k] > 0.999
    angle = np.arccos(np.clip(lights.direction[k] @ pixel_directions(h, 2 * h)[i, j], -1, 1))
    assert angle < np.pi / h
    assert lights.sigma[k] < 1.0  # a point-like source casts a nearly hard shadow


def test_zero_map_gives_valid_zero_lights():
    lights = median_cut_lights(EnvMap(np.zeros((16, 32, 3), np.float32)), 5)
    assert len(lights) == 5 and (lights.intensity == 0).all()
    lights.validate()


def test_median_cut_irradiance_matches_the_map(horn):
    normals = random_normals(seed=4)
    exact = irradiance_map(horn, normals)
    lights = median_cut_lights(horn, 16)
    assert len(lights) == 16 and (lights.sigma >= 0).all() and (lights.sigma <= 20).all()
    np.testing.assert_allclose(lights.intensity.sum(axis=0), horn.energy(), rtol=1e-5)
    assert relative_error(irradiance_lights(lights, normals), exact) < 0.10


def test_bundled_environment_carries_its_fitted_lights(horn):
    import json

    from viewer.lab.bench.lightfit_evaluate import shading_errors
    from viewer.lighting.lightfit.problem import build_problem
    from viewer.lighting.lightfit.settings import FitSettings

    env = load_envmap(BUNDLED.with_suffix(".hdr"))
    assert env.pixels.shape == (128, 256, 3)
    np.testing.assert_allclose(env.energy(), horn.energy(), rtol=0.01)  # RGBE storage
    path = BUNDLED.with_suffix(".lights.json")
    bundled = load_lights(path)
    record = json.loads(path.read_text())["fit"]
    from viewer.lighting.lightfit.cache import FIT_VERSION, map_hash

    assert len(bundled) == 16 and record == {"source": BUNDLED.with_suffix(".hdr").name, "map": map_hash(env), "method": "fast",
                                             "n": 16, "version": FIT_VERSION}
    problem = build_problem(env, FitSettings(sphere_resolution=32, plane_resolution=48, shadow_resolution=64, samples=256))
    fitted, initial = shading_errors(problem, bundled), shading_errors(problem, median_cut_lights(env, 16))
    assert fitted["sphere"] < initial["sphere"] and fitted["plane"] < initial["plane"]
