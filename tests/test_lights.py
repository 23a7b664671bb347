"""Area lights: JSON round trip, rotation, validation."""

from __future__ import annotations

import json

import numpy as np
import pytest

from viewer.errors import InputError
from viewer.scene.area_lights import AreaLights, load_lights, rotation_matrix


def sample_lights():
    d = np.array([[0, 1, 0], [1, 0, 0], [0, 0, 1.0]], np.float32)
    return AreaLights(d, [0.0, 2.5, 20.0], [[1, 2, 3], [0, 0, 0], [1e5, 1e5, 1e5]])


def test_json_round_trip(tmp_path):
    lights = sample_lights()
    back = load_lights(lights.save(tmp_path / "l.json"))
    np.testing.assert_array_equal(back.to_array(), lights.to_array())


def test_rotation_about_vertical_axis():
    lights = sample_lights().rotated(90.0)
    np.testing.assert_allclose(lights.direction[0], [0, 1, 0], atol=1e-6)  # the zenith stays
    np.testing.assert_allclose(lights.direction[2], [1, 0, 0], atol=1e-6)  # +z goes to +x
    np.testing.assert_allclose(lights.direction[1], [0, 0, -1], atol=1e-6)
    back = lights.rotated(-90.0)
    np.testing.assert_allclose(back.direction, sample_lights().direction, atol=1e-6)
    tilted = sample_lights().rotated(0.0, 90.0)
    np.testing.assert_allclose(tilted.direction[0], [0, 0, 1], atol=1e-6)
    r = rotation_matrix(33, -12)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda d: d["lights"][0].update(direction=[0, 2, 0]), "not a unit vector"),
        (lambda d: d["lights"][1].update(sigma=-1), "sigma must be >= 0"),
        (lambda d: d["lights"][2].update(intensity=[1, -1, 0]), "non-negative"),
        (lambda d: d["lights"][2].update(intensity=[1, float("nan"), 0]), "NaN or Inf"),
        (lambda d: d.update(lights=[]), "contains no lights"),
        (lambda d: d["lights"][0].pop("sigma"), "malformed"),
        (lambda d: d.update(format="x"), "not a light file"),
    ],
)
def test_bad_light_files_are_named(tmp_path, edit, message):
    data = sample_lights().to_json()
    edit(data)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(InputError) as err:
        load_lights(path)
    assert "bad.json" in str(err.value) and message in str(err.value)


def test_facing_yaw_turns_the_brightest_light_to_the_camera():
    from viewer.cli.command_setup import first_look
    from viewer.cli.parser import build_parser
    from viewer.lighting.map_lights import MAP, PLACED, PLATE
    from viewer.scene.area_lights import AreaLights, facing_yaw
    from viewer.scene.look import Look

    rng = np.random.default_rng(5)
    for _ in range(20):
        d = rng.normal(size=(6, 3))
        lights = AreaLights(d / np.linalg.norm(d, axis=1, keepdims=True), rng.uniform(0, 10, 6), rng.uniform(0, 5, (6, 3)))
        k = int(np.argmax(lights.intensity.sum(axis=1)))
        x, y, z = lights.rotated(facing_yaw(lights)).direction[k]
        assert abs(x) < 1e-5 and z > 0.0 and y == pytest.approx(lights.direction[k, 1], abs=1e-6)
    dark = AreaLights(np.array([[0.0, 0.0, -1.0]]), [1.0], [[0.0, 0.0, 0.0]])
    assert facing_yaw(dark) == 0.0
    # the viewer's first look: a map's lights facing, unless a yaw was asked for; the plate's own light and
    # the user's own lights as they are
    behind = AreaLights(np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]), [1.0, 1.0], [[5.0, 5.0, 5.0], [1.0, 1.0, 1.0]])
    parser = build_parser()
    assert abs(first_look(parser.parse_args(["view"]), Look(), behind, MAP).yaw) == pytest.approx(180.0)
    assert first_look(parser.parse_args(["view", "--yaw", "30"]), Look(yaw=30.0), behind, MAP).yaw == 30.0
    assert first_look(parser.parse_args(["view"]), Look(), behind, PLACED).yaw == 0.0
    assert first_look(parser.parse_args(["view"]), Look(), behind, PLATE).yaw == 0.0
    assert first_look(parser.parse_args(["view", "--yaw", "30"]), Look(yaw=30.0), behind, PLACED).yaw == 30.0


def test_where_lights_come_from(tmp_path, monkeypatch):
    """A light file is a map's lights when its fit record names the map (relight fit-lights, the bundled
    maps' files); written by hand, a bundle's lights of its own photo or the paper's .npy, it is the user's;
    no light file: the map's, found by the one rule; the plate's own light first."""
    from viewer.cli.main import main
    from viewer.lighting.map_lights import MAP, PLACED, PLATE, lights_source
    from viewer.resources import asset_dir

    monkeypatch.setenv("RELIGHT_CACHE", str(tmp_path / "cache"))
    assert lights_source() == MAP and lights_source(None, plate=True) == PLATE
    assert lights_source(asset_dir() / "envmaps" / "venice_sunset_256.lights.json") == MAP
    studio = asset_dir() / "envmaps" / "studio_small_03_256.hdr"
    assert main(["fit-lights", str(studio), "-n", "4", "--method", "median-cut", "-o", str(tmp_path / "fitted.json")]) == 0
    assert lights_source(tmp_path / "fitted.json") == MAP
    own = AreaLights(np.array([[0.6, 0.3, 0.74]]) / np.linalg.norm([0.6, 0.3, 0.74]), [2.0], [[5.0, 5.0, 5.0]])
    own.save(tmp_path / "own.json")
    own.save(tmp_path / "photo.json", fit={"source": "photo.jpg", "method": "inverse-rendering network"})
    np.save(tmp_path / "paper.npy", own.to_array())
    for name in ("own.json", "photo.json", "paper.npy"):
        assert lights_source(tmp_path / name) == PLACED, name
