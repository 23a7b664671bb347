"""Hostile inputs stay one clear line: property-based (hypothesis) on every reader, and the whole
bad-input campaign of ``relight bench robustness`` on the real command line."""

from __future__ import annotations

import json
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from viewer.envmap import load_envmap
from viewer.errors import InputError
from viewer.imageio import read_json
from viewer.lights import load_lights
from viewer.photo_frame import read_mask
from viewer.settings import Look

ROOT = Path(__file__).resolve().parents[1]
GOOD_LIGHTS = json.loads((ROOT / "assets" / "envmaps" / "venice_sunset_256.lights.json").read_text())
HDR = (ROOT / "assets" / "envmaps" / "venice_sunset_256.hdr").read_bytes()
SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])

json_values = st.recursive(st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=8),
                           lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
                           max_leaves=20)


def _one_line(call):
    """``call()`` either succeeds or raises one InputError of one line."""
    try:
        return call()
    except InputError as exc:
        assert "\n" not in str(exc) and str(exc)
        return None


@SETTINGS
@given(data=st.binary(max_size=400))
def test_any_bytes_as_json_are_read_or_refused_in_one_line(tmp_path, data):
    path = tmp_path / "x.json"
    path.write_bytes(data)
    _one_line(lambda: read_json(path))


@SETTINGS
@given(value=json_values, edits=st.dictionaries(st.sampled_from(["direction", "sigma", "intensity"]), json_values, max_size=3))
def test_any_light_file_loads_or_is_refused_in_one_line(tmp_path, value, edits):
    path = tmp_path / "lights.json"
    for data in (value, {**GOOD_LIGHTS, "lights": [{**GOOD_LIGHTS["lights"][0], **edits}]}):
        path.write_text(json.dumps(data))
        lights = _one_line(lambda: load_lights(path))
        assert lights is None or len(lights) >= 1


@SETTINGS
@given(look=st.dictionaries(st.sampled_from(["yaw", "tilt", "exposure", "tonemap", "background", "shadows", "view", "light",
                                             "intensity", "preset", "visibility", "background_color"]), json_values, max_size=4))
def test_any_saved_look_loads_or_is_refused_in_one_line(look):
    _one_line(lambda: Look.from_json(look, where="look.json"))


@SETTINGS
@given(cut=st.integers(0, len(HDR)), flips=st.lists(st.tuples(st.integers(0, len(HDR) - 1), st.integers(0, 255)), max_size=6))
def test_any_damaged_radiance_map_loads_or_is_refused_in_one_line(tmp_path, cut, flips):
    data = bytearray(HDR[:cut])
    for i, b in flips:
        if i < len(data):
            data[i] = b
    path = tmp_path / "map.hdr"
    path.write_bytes(bytes(data))
    env = _one_line(lambda: load_envmap(path))
    assert env is None or env.pixels.shape[2] == 3


@SETTINGS
@given(data=st.binary(max_size=300))
def test_any_bytes_as_a_mask_are_refused_in_one_line(tmp_path, data):
    path = tmp_path / "mask.png"
    path.write_bytes(data)
    assert _one_line(lambda: read_mask(path, (40, 30), [])) is None


def test_the_bad_input_campaign_ends_cleanly(tmp_path):
    """Every case of ``relight bench robustness`` (over 150: hostile light files, maps, bundles,
    looks, caches, photos and options on the real CLI) exits 0 or 2 with one line, writes nothing
    on an error and leaves its inputs as they were."""
    from viewer.lab.bench.robustness import run_robustness_benchmark

    report = run_robustness_benchmark(work=tmp_path / "work", output=tmp_path / "robustness.json")
    failed = [(c["group"], c["name"], c["result"]["problems"], c["result"]["last_line"]) for c in report["cases"]
              if not c["result"]["clean"]]
    assert report["tried"] >= 150 and failed == [] and report["tracebacks"] == 0
    assert json.loads((tmp_path / "robustness.json").read_text())["clean"] == report["tried"]
